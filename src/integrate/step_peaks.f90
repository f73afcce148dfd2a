!> The largest values inside an embedded pair's accepted rolling step of the
!> quantities whose maxima the summary gives (displacement, horizontal
!> force, N, friction needed: peak_quantities), on the step's dense output,
!> so that a maximum is never below the output samples that the same dense
!> output gives between the step ends. A screen first (the quantities at
!> screen_theta of the step, those of reaction_inside where it ran); a
!> peak is refined by successive parabolas (peak_search_t) only where the
!> screen shows one inside the step that may pass the running maximum.
module ellroll_step_peaks
  use ellroll_kinds, only: wp, i8
  use ellroll_norms, only: norm_of, in_mass_units
  use ellroll_quantities, only: quantity_count, q_displacement, q_horizontal_force_scaled, q_reaction_normal, &
      q_friction_needed, q_fit_clearance
  use ellroll_running, only: running_t, running_lanes_t, add_inside
  use ellroll_events, only: peak_search_t
  use ellroll_integrators, only: embedded_pair_t
  use ellroll_embedded_pair, only: width
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, observe, ball_derivative, &
      normalize_normal
  use ellroll_ball_steppers, only: pair_ball_dense
  use ellroll_ellipsoid, only: contact_point
  implicit none
  private

  public :: step_screen_t, screen_theta, note_screen, note_screen_end, screen_step, add_step_peaks, &
            peak_count, peak_quantities, peak_values, worth_refining, peak_resolution, may_peak_inside, &
            dense_observation, time_beyond_inside, clearance_crossing, add_clearance_crossing

  integer, parameter :: peak_count = 4
  !> The quantities (ellroll_quantities) whose maxima are located inside steps.
  integer, parameter :: peak_quantities(peak_count) = [q_displacement, q_horizontal_force_scaled, &
                                                       q_reaction_normal, q_friction_needed]
  !> Where the screen looks, as fractions of the step (reaction_inside's:
  !> a peak within 1e-3 of the step from an end shows as a fall to it).
  real(wp), parameter :: near_end = 1.0e-3_wp
  real(wp), parameter :: screen_theta(0:6) = [0.0_wp, near_end, 0.25_wp, 0.5_wp, 0.75_wp, 1 - near_end, 1.0_wp]
  !> The cheap bound's margin (may_peak_inside), of the range of the values
  !> screened (a force's range over a step is its motion's part; its rates
  !> are the interpolant's, O(h^3) off).
  real(wp), parameter :: bound_margin = 0.25_wp, bound_turn = 0.5_wp
  !> A peak is located to this fraction of the step.
  real(wp), parameter :: peak_resolution = 1.0e-6_wp

  !> The quantities at screen_theta (a column per peak quantity), and the
  !> fit clearance there (ellroll_quantities).
  type :: step_screen_t
    real(wp) :: q(0:6, peak_count) = 0
    real(wp) :: clearance(0:6) = 0
    !> the rates' bound (rates_may_peak) shows no peak to refine: the
    !> interior points are not screened, nothing is refined
    logical :: none = .false.
  end type step_screen_t

  !> The largest value found inside a step of each peak quantity above the
  !> running maximum given (found), its time, and whether the cup's
  !> curvature there is clear (fit_clearance > 0).
  type :: step_peaks_t
    logical :: found(peak_count) = .false.
    logical :: clear(peak_count) = .false.
    real(wp) :: value(peak_count) = 0, t(peak_count) = 0
  end type step_peaks_t

contains

  !> The observation obs at screen_theta(i) into the screen (the norms as
  !> the step ends' quantities are formed: ellroll_case_run's step_quantities).
  pure subroutine note_screen(screen, i, obs)
    type(step_screen_t), intent(inout) :: screen
    integer, intent(in) :: i
    type(observation_t), intent(in) :: obs
    screen%q(i, :) = peak_values(obs)
    screen%clearance(i) = obs%fit_clearance
  end subroutine note_screen

  !> The step end's quantities (a row of ellroll_quantities, a batch lane's)
  !> into the screen's end.
  pure subroutine note_screen_end(screen, q)
    type(step_screen_t), intent(inout) :: screen
    real(wp), intent(in) :: q(quantity_count)
    screen%q(6, :) = q(peak_quantities)
    screen%clearance(6) = q(q_fit_clearance)
  end subroutine note_screen_end

  pure function peak_values(obs) result(q)
    type(observation_t), intent(in) :: obs
    real(wp) :: q(peak_count)
    q = [norm_of(obs%center(1), obs%center(2)), obs%horizontal_force_scaled, obs%reaction_normal, obs%friction_needed]
  end function peak_values

  !> The screen of the last attempt (in pair) from (y, f) at its start, its
  !> interior points on the dense output (what reaction_inside evaluates
  !> where it runs); the end's column is the caller's. Given the running
  !> maxima (above) and the step end's values (finish), the interior points
  !> are screened only where rates_may_peak does not rule a peak out.
  subroutine screen_step(pair, ball, y, f, screen, n_rhs, above, finish)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size), f(state_size)
    type(step_screen_t), intent(inout) :: screen
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(in), optional :: above(peak_count), finish(peak_count)
    type(observation_t) :: obs
    real(wp) :: start(peak_count)
    integer :: i
    call observe(ball, pair%t_old, y, f, obs)
    call note_screen(screen, 0, obs)
    screen%none = .false.
    if (present(above) .and. present(finish)) then
      start = screen%q(0, :)                ! (a contiguous row: no array temporary)
      screen%none = .not. rates_may_peak(pair, ball, start, finish, above, n_rhs)
      if (screen%none) return
    end if
    do i = 1, 5
      call dense_observation(pair, ball, screen_theta(i), .true., obs, n_rhs)
      call note_screen(screen, i, obs)
    end do
  end subroutine screen_step

  !> A bound on the screen without its RHS calls: whether the screen of the
  !> last attempt (in pair; start and finish: the step ends' peak values)
  !> may find a peak to refine above `above` (find_step_peaks). At each
  !> interior point the state is the screen's own (the dense output,
  !> projected: the displacement is the screen's value), the rate the
  !> interpolant's derivative in place of the RHS there: the forces then
  !> differ from the screen's by the interpolant's error in the rate, which
  !> vanishes at the step's ends (the interpolant takes f there), taken as
  !> at most 4 theta (1 - theta) times the values' size over the step times
  !> rate_floor + rate_per_tolerance (rtol + atol): measured on seeded
  !> fixed-cup cases (rtol 1e-4 to 1e-12, both pairs, with and without
  !> rolling resistance), the error is below a hundredth of that.
  !> A point whose parabola through its neighbours could pass, the values
  !> moved by that bound each the unfavourable way, is taken to hold one
  !> (parabola_rise: worth_refining's margin bounded without its tests).
  logical function rates_may_peak(pair, ball, start, finish, above, n_rhs) result(may)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in), dimension(peak_count) :: start, finish, above
    integer(i8), intent(inout) :: n_rhs
    real(wp), parameter :: rate_floor = 1.0e-3_wp, rate_per_tolerance = 1.0e5_wp, round_off = 1.0e-9_wp
    type(observation_t) :: obs
    real(wp) :: q(0:6, peak_count), error(0:6), y(state_size), rate(width), f(state_size), length, theta, size, best
    real(wp) :: v1, v2, v3
    logical :: prepared
    integer :: i, j
    q(0, :) = start
    q(6, :) = finish
    error = 0
    do i = 1, 5
      theta = screen_theta(i)
      call pair_ball_dense(pair, ball, theta, y, prepared)
      if (prepared) n_rhs = n_rhs + pair%dense_calls()
      length = sqrt(y(1)**2 + y(2)**2 + y(3)**2)
      call normalize_normal(y)
      call pair%dense_rate(theta, rate)
      f = rate(:state_size) / pair%h
      f(1:3) = f(1:3) / length
      call observe(ball, pair%t_old + theta * pair%h, y, f, obs)
      q(i, :) = peak_values(obs)
      error(i) = 4 * theta * (1 - theta)
    end do
    ! (a figure undefined at a point, as the friction ratio where N <= 0: the screen decides)
    may = .true.
    if (.not. all(abs(q) < sqrt(huge(1.0_wp)))) return
    do j = 1, peak_count
      size = maxval(abs(q(:, j)))
      best = max(above(j), q(0, j), q(6, j)) - round_off * size
      if (peak_quantities(j) == q_displacement) then
        size = 0                     ! (the screen's own state)
      else
        size = (rate_floor + rate_per_tolerance * (pair%rtol + pair%atol)) * size
      end if
      do i = 1, 5
        v1 = q(i - 1, j) - size * error(i - 1)
        v2 = q(i, j) + size * error(i)
        v3 = q(i + 1, j) - size * error(i + 1)
        if (v2 + 2 * parabola_rise(i, v1, v2, v3) > best) return
      end do
    end do
    may = .false.
  end function rates_may_peak

  !> An upper bound on how far the top of the parabola through the screen's
  !> points i - 1, i, i + 1 (values v1, v2, v3) rises above v2 where v2 is
  !> the largest of the three (parabola_top; 0 where it is not): its vertex
  !> lies between the outer points, on the side of the lower rise.
  pure real(wp) function parabola_rise(i, v1, v2, v3) result(rise)
    integer, intent(in) :: i
    real(wp), intent(in) :: v1, v2, v3
    real(wp) :: left, right
    left = screen_theta(i) - screen_theta(i - 1)
    right = screen_theta(i + 1) - screen_theta(i)
    rise = max(0.0_wp, (v2 - v3) * left**2 / (right * (right + 2 * left)), &
               (v2 - v1) * right**2 / (left * (left + 2 * right)))
  end function parabola_rise

  !> A cheap bound, without RHS calls or the dense output: whether the step
  !> of size h from (t, y0, f0) to (y1, f1) may hold a value of a peak
  !> quantity above `above` (running maxima) between its ends. The screen
  !> on the cubic Hermite interpolant of the state (the rates its
  !> derivative's) has a local maximum that worth_refining takes to pass
  !> above (or the larger step end) less bound_margin of their range. For a
  !> fixed cup (the steps whose reaction is not screened: reaction_limited).
  pure function may_peak_inside(ball, h, y0, f0, y1, f1, above) result(may)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: h, above(peak_count)
    real(wp), dimension(:), intent(in) :: y0, f0, y1, f1     ! (assumed shape: a batch passes lanes' rows)
    logical :: may
    type(step_screen_t) :: screen
    real(wp) :: y(state_size), rate(state_size), s, q(0:6), length
    integer :: i, j
    ! a step over which the ball turns by more than bound_turn rad: the
    ! interpolant does not follow its forces, the bound is not taken
    may = .true.
    if (h * max(norm2(y0(4:6)), norm2(y1(4:6))) > bound_turn) return
    do i = 0, 6
      s = screen_theta(i)
      y = (1 + 2 * s) * (1 - s)**2 * y0 + s * (1 - s)**2 * h * f0 + s**2 * (3 - 2 * s) * y1 &
          + s**2 * (s - 1) * h * f1
      rate = 6 * s * (s - 1) * (y0 - y1) / h + (1 - s) * (1 - 3 * s) * f0 + s * (3 * s - 2) * f1
      length = sqrt(y(1)**2 + y(2)**2 + y(3)**2)
      y(1:3) = y(1:3) / length
      rate(1:3) = rate(1:3) / length
      screen%q(i, :) = fixed_cup_values(ball, y, rate)
    end do
    may = .false.
    do j = 1, peak_count
      q = screen%q(:, j)
      do i = 1, 5
        may = worth_refining(q, i, max(above(j), q(0), q(6)) - bound_margin * (maxval(q) - minval(q)))
        if (may) return
      end do
    end do
  end function may_peak_inside

  !> The peak quantities of the state y (unit normal) with rate in a fixed
  !> cup, as observe forms them but in N (a bound's values: no care for a
  !> light ball's underflow).
  pure function fixed_cup_values(ball, y, rate) result(q)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size), rate(state_size)
    real(wp) :: q(peak_count)
    real(wp) :: n(3), p(3), inv_s, force(3), normal, tangent, ratio, denominator
    n = y(1:3)
    call contact_point(ball%cup, n, p, inv_s)
    p = p + ball%radius * n
    force = ball%mass * ball%radius * [rate(5) * n(3) - rate(6) * n(2) + y(5) * rate(3) - y(6) * rate(2), &
                                       rate(6) * n(1) - rate(4) * n(3) + y(6) * rate(1) - y(4) * rate(3), &
                                       rate(4) * n(2) - rate(5) * n(1) + y(4) * rate(2) - y(5) * rate(1)]
    force(3) = force(3) + ball%mass * ball%g
    normal = dot_product(force, n)
    tangent = norm2(force - normal * n)
    ! (a ratio past huge where N is near zero: huge, a value the screen leaves
    ! undecided, not an overflow)
    denominator = max(abs(normal), tiny(1.0_wp))
    ratio = huge(1.0_wp)
    if (denominator > tangent / huge(1.0_wp)) ratio = tangent / denominator
    q = [hypot(p(1), p(2)), in_mass_units(hypot(force(1), force(2)), ball%mass), normal, ratio]
  end function fixed_cup_values

  !> The peaks inside the last attempt (in pair), whose screen is complete,
  !> that pass the running maxima of one case (stats) or of lane l's (lane
  !> stats) into them.
  subroutine add_step_peaks(pair, ball, screen, n_rhs, stats, lane_stats, l)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    type(step_screen_t), intent(in) :: screen
    integer(i8), intent(inout) :: n_rhs
    type(running_t), intent(inout), optional :: stats
    type(running_lanes_t), intent(inout), optional :: lane_stats
    integer, intent(in), optional :: l
    type(step_peaks_t) :: peaks
    integer :: j
    if (screen%none) return
    ! (the maxima over the points clear of the cup's curvature are the
    ! lower: those a case ended at a model limit gives)
    if (present(stats)) then
      call find_step_peaks(pair, ball, screen, stats%clear_maximum(1, peak_quantities), peaks, n_rhs)
    else
      call find_step_peaks(pair, ball, screen, lane_stats%clear_maximum(l, peak_quantities), peaks, n_rhs)
    end if
    do j = 1, peak_count
      if (.not. peaks%found(j)) cycle
      if (present(stats)) then
        call add_inside(stats, peak_quantities(j), peaks%value(j), peaks%t(j), peaks%clear(j))
      else
        call add_inside(lane_stats, l, peak_quantities(j), peaks%value(j), peaks%t(j), peaks%clear(j))
      end if
    end do
  end subroutine add_step_peaks

  !> The peaks inside the last attempt (in pair) of each quantity whose
  !> screen has a local maximum inside the step that, by the parabola
  !> through it and its neighbours with twice its rise as margin, may pass
  !> above (the running maximum, or the larger step end): each located to
  !> resolution of the step; found where it passes.
  subroutine find_step_peaks(pair, ball, screen, above, peaks, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    type(step_screen_t), intent(in) :: screen
    real(wp), intent(in) :: above(peak_count)
    type(step_peaks_t), intent(out) :: peaks
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: best, q(0:6)
    integer :: j, i
    do j = 1, peak_count
      q = screen%q(:, j)
      best = max(above(j), q(0), q(6))
      do i = 1, 5
        if (worth_refining(q, i, best)) call refine(j, i, best)
      end do
    end do
  contains
    !> The peak of quantity j bracketed by the screen's points around i.
    subroutine refine(j, i, best)
      integer, intent(in) :: j, i
      real(wp), intent(inout) :: best
      type(peak_search_t) :: search
      type(observation_t) :: obs
      real(wp) :: x, fx, top_clearance
      call search%start(screen_theta(i - 1), screen_theta(i), screen_theta(i + 1), screen%q(i - 1, j), &
                        screen%q(i, j), screen%q(i + 1, j), peak_resolution)
      top_clearance = screen%clearance(i)
      do while (.not. search%done())
        x = search%trial()
        ! (the displacement needs the state only, the forces its rate)
        call dense_observation(pair, ball, x, peak_quantities(j) /= q_displacement, obs, n_rhs)
        fx = pick(peak_values(obs), j)
        if (fx >= search%fb) top_clearance = obs%fit_clearance
        call search%report(x, fx)
      end do
      if (search%fb > best) then
        best = search%fb
        peaks%found(j) = .true.
        peaks%value(j) = search%fb
        peaks%t(j) = pair%t_old + search%b * pair%h
        peaks%clear(j) = top_clearance > 0
      end if
    end subroutine refine
  end subroutine find_step_peaks

  !> Whether the screen's values q of a quantity have a local maximum at
  !> point i whose parabola through its neighbours, with twice its rise
  !> over q(i) as margin, passes best.
  pure logical function worth_refining(q, i, best)
    real(wp), intent(in) :: q(0:6), best
    integer, intent(in) :: i
    real(wp) :: vertex
    worth_refining = .false.
    ! (huge: a figure undefined there, as the friction ratio where N <= 0)
    if (.not. all(abs(q(i - 1:i + 1)) < sqrt(huge(1.0_wp)))) return
    if (.not. (q(i) >= q(i - 1) .and. q(i) >= q(i + 1))) return
    vertex = parabola_top(screen_theta(i - 1:i + 1), q(i - 1:i + 1))
    worth_refining = q(i) + 2 * (vertex - q(i)) > best
  end function worth_refining

  pure real(wp) function pick(values, j)
    real(wp), intent(in) :: values(peak_count)
    integer, intent(in) :: j
    pick = values(j)
  end function pick

  !> The largest value of the parabola through (x(k), v(k)), v(2) >= v(1),
  !> v(3): v(2) where it is flat or not concave.
  pure real(wp) function parabola_top(x, v) result(top)
    real(wp), intent(in) :: x(3), v(3)
    real(wp) :: d1, d2, curvature, slope
    top = v(2)
    d1 = (v(2) - v(1)) / (x(2) - x(1))
    d2 = (v(3) - v(2)) / (x(3) - x(2))
    curvature = (d2 - d1) / (x(3) - x(1))          ! half the second derivative
    if (.not. curvature < 0) return
    ! the slope at x(2) of the parabola; its vertex lies -slope / (2 curvature) from x(2)
    slope = d1 + curvature * (x(2) - x(1))
    top = v(2) - slope**2 / (4 * curvature)
  end function parabola_top

  !> Where the clearance of the cup's curvature (fit_clearance) changes sign
  !> in the last attempt (in pair) between its start (clear_start: > 0
  !> there) and theta_end of the step: the point on the path's clear side,
  !> located on the dense output by bisection to 2^-50 of that part, its
  !> time t and peak values (peak_values, with the rate there). A case that
  !> ends at a model limit takes its peaks over the path clear of the
  !> curvature: the forces grow steeply towards the limit, and this point,
  !> unlike the last clear step end, does not move with the steps' round-off.
  subroutine clearance_crossing(pair, ball, clear_start, theta_end, t, values, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    logical, intent(in) :: clear_start
    real(wp), intent(in) :: theta_end
    real(wp), intent(out) :: t, values(peak_count)
    integer(i8), intent(inout) :: n_rhs
    integer, parameter :: halvings = 50
    type(observation_t) :: obs
    real(wp) :: clear_side, other_side, middle
    integer :: k
    clear_side = merge(0.0_wp, theta_end, clear_start)
    other_side = merge(theta_end, 0.0_wp, clear_start)
    do k = 1, halvings
      middle = (clear_side + other_side) / 2
      call dense_observation(pair, ball, middle, .false., obs, n_rhs)
      if (obs%fit_clearance > 0) then
        clear_side = middle
      else
        other_side = middle
      end if
    end do
    call dense_observation(pair, ball, clear_side, .true., obs, n_rhs)
    t = pair%t_old + clear_side * pair%h
    values = peak_values(obs)
  end subroutine clearance_crossing

  !> Where the clearance changes sign in the last attempt (in pair) between
  !> the last step end (clear or not: the statistics' clear_last) and theta_end
  !> of the step (clearance_end there): clearance_crossing, into the maxima
  !> clear of the cup's curvature of one case (stats) or of lane l's
  !> (lane_stats). Nothing where it keeps its sign.
  subroutine add_clearance_crossing(pair, ball, clearance_end, theta_end, n_rhs, stats, lane_stats, l)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: clearance_end, theta_end
    integer(i8), intent(inout) :: n_rhs
    type(running_t), intent(inout), optional :: stats
    type(running_lanes_t), intent(inout), optional :: lane_stats
    integer, intent(in), optional :: l
    real(wp) :: t, values(peak_count)
    logical :: clear_start
    integer :: j
    if (present(stats)) then
      clear_start = stats%clear_last(1)
    else
      clear_start = lane_stats%clear_last(l)
    end if
    if (clear_start .eqv. clearance_end > 0) return
    call clearance_crossing(pair, ball, clear_start, theta_end, t, values, n_rhs)
    do j = 1, peak_count
      if (present(stats)) then
        call add_inside(stats, peak_quantities(j), values(j), t, .true.)
      else
        call add_inside(lane_stats, l, peak_quantities(j), values(j), t, .true.)
      end if
    end do
  end subroutine add_clearance_crossing

  !> Every derived output at t_old + theta h of the last attempt, from its
  !> dense output, the normal projected to unit length, with f there (one
  !> more RHS call) when with_rate: as the output samples are formed.
  subroutine dense_observation(pair, ball, theta, with_rate, obs, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: theta
    logical, intent(in) :: with_rate
    type(observation_t), intent(out) :: obs
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: y(state_size), f(state_size), t
    logical :: prepared
    call pair_ball_dense(pair, ball, theta, y, prepared)
    if (prepared) n_rhs = n_rhs + pair%dense_calls()
    call normalize_normal(y)
    t = pair%t_old + theta * pair%h
    f = 0
    if (with_rate) then
      call ball_derivative(ball, t, y, f)
      n_rhs = n_rhs + 1
    end if
    call observe(ball, t, y, f, obs)
  end subroutine dense_observation

  !> The time within the pair's last accepted step that the centre's
  !> horizontal distance from the cup's axis spends beyond c, from its dense
  !> output: the distance at beyond_parts - 1 inner points (r_start and r_end
  !> at the step's ends), each crossing between two of them located by
  !> bisection to 2^-40 of the part, and a part wholly beyond counted whole.
  !> A pair's step is long (0.05 to 0.2 s on a shaken isolator): the step
  !> ends alone cut a dip's corners or miss it whole (1.1e-2 s of 19.19 s
  !> at vern9's rtol 1e-12, where 1 ms samples agree to 1e-8).
  subroutine time_beyond_inside(pair, ball, c, r_start, r_end, time, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: c, r_start, r_end
    real(wp), intent(out) :: time
    integer(i8), intent(inout) :: n_rhs
    integer, parameter :: beyond_parts = 8, halvings = 40
    real(wp) :: r(0:beyond_parts), low, high, middle
    integer :: j, k
    r(0) = r_start
    r(beyond_parts) = r_end
    do j = 1, beyond_parts - 1
      r(j) = distance(real(j, wp) / beyond_parts)
    end do
    time = 0
    do j = 1, beyond_parts
      if (r(j - 1) > c .and. r(j) > c) then
        time = time + 1.0_wp / beyond_parts
      else if ((r(j - 1) > c) .neqv. (r(j) > c)) then
        low = real(j - 1, wp) / beyond_parts       ! (the crossing between low and high)
        high = real(j, wp) / beyond_parts
        do k = 1, halvings
          middle = (low + high) / 2
          if ((distance(middle) > c) .eqv. (r(j - 1) > c)) then
            low = middle
          else
            high = middle
          end if
        end do
        middle = (low + high) / 2
        time = time + merge(real(j, wp) / beyond_parts - middle, middle - real(j - 1, wp) / beyond_parts, r(j) > c)
      end if
    end do
    time = time * pair%h
  contains
    real(wp) function distance(theta)
      real(wp), intent(in) :: theta
      type(observation_t) :: obs
      call dense_observation(pair, ball, theta, .false., obs, n_rhs)
      distance = norm_of(obs%center(1), obs%center(2))
    end function distance
  end subroutine time_beyond_inside
end module ellroll_step_peaks
