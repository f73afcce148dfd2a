!> One case with an adaptive embedded pair (dop853, vern9): step-size
!> control, and everything taken from the pair's dense output inside a step
!> (output samples, the maxima of Theta, where a model limit is crossed), so
!> that no result depends on where the steps fall. The batches use the same
!> pieces per lane.
module ellroll_adaptive_run
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero
  use ellroll_status, only: status_pending, status_completed, status_no_fit, status_rim, status_unstable
  use ellroll_cases, only: case_t, output_plan_t, field_reaction, field_energy, field_base_acceleration, max_steps
  use ellroll_results, only: case_result_t
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, observe, limit_status, &
      ball_derivative, normalize_normal
  use ellroll_events, only: event_search_t, max_event_trials
  use ellroll_errors, only: error_t
  use ellroll_integrators, only: embedded_pair_t, new_pair, max_equations, tolerance_ratio_cap
  use ellroll_ball_steppers, only: pair_ball_step, pair_ball_dense
  use ellroll_case_run, only: run_state_t, limit_search_t, sample_due, stop_asked, track, track_step_end, note_nutation, &
      accumulate, record_sample, record_geometry_sample
  use ellroll_params, only: p_dt
  implicit none
  private

  public :: nutation_peak_t, adaptive_loop, last_step_clipped
  public :: project_with_rate, nutation_peak_inside, locate_nutation_peak, stop_in_step, record_samples_until
  public :: follow_flow_to_limit, reference_rtol, reference_atol, reference_method, beyond_rim, slip_inside, &
            round_off_step, cannot_follow, judged_norm

  !> Step-size control of an embedded pair: Hairer's safety factor, a
  !> rejected step shrunk at most 3-fold, and after an accepted step
  !> Gustafsson's PI controller for explicit Runge-Kutta methods (k_I = 0.3/k,
  !> k_P = 0.4/k, k the pair's control_order: 8 for DOP853, 9 for Verner's):
  !>   h_new = h 0.9 err^-(k_I + k_P) err_prev^k_P.
  !> Where stability, not accuracy, limits the step (loose tolerances on the
  !> paper's case), the plain controller (h 0.9 err^(-1/8)) overshoots and
  !> every third attempt is rejected; this one damps that oscillation and
  !> needs 8-21 % fewer RHS calls for the same error from 1e-4 to 1e-10 m.
  !> The error norms are taken no smaller than where they are partly
  !> round-off: err >= 2.6e-7 (where 0.9 err^(-1/8) reaches the ratio 6) and
  !> err_prev >= 1e-4 (Hairer's floor), so that two evaluations of a step
  !> differing by round-off (a case alone and in a SIMD batch) choose the
  !> same next step where the norms are that small. With the floors (and err
  !> <= 1, err_prev in [1e-4, 1]) the ratio after an accepted step lies in
  !> [0.57, 3.4] for k = 8 ([0.60, 2.9] for k = 9): no clamp is needed.
  real(wp), parameter :: adaptive_safety = 0.9_wp, adaptive_min_factor = 0.333_wp
  real(wp), parameter :: error_norm_floor = 2.6e-7_wp, log_previous_floor = log(1.0e-4_wp)

  !> Method and tolerances of a reference solution: the run behind the error
  !> figures (error_estimate), and the exact flow followed from a fixed-step
  !> method's last state to the limit its step met. Verner's pair reaches
  !> these tolerances in fewer RHS calls and less time than DOP853, with a
  !> smaller error (bench/pairs.py).
  character(len=*), parameter :: reference_method = 'vern9'
  real(wp), parameter :: reference_rtol = 1.0e-12_wp, reference_atol = 1.0e-14_wp

  !> A step of at most smallest_step_ulps eps |t| (16 to 32 units in the
  !> last place of t; follow_flow_to_limit: 16 units of its end) or not a
  !> number is round-off: Hairer's "step size too small". Such steps
  !> still take the state on where its motion outruns the clock: next to the
  !> fit limit's square-root singularity (fit_margin 0) some 20-50 of them
  !> reach the limit, across a ramp of 1e-9 s in a record at t = 1000 s at
  !> rtol 1e-14 some 3,000 (liftoff there). An adaptive case that makes
  !> max_round_off_attempts attempts of round-off steps without an accepted
  !> step beyond them (about 0.1 s), that is to attempt a step
  !> of 0, or that has made max_steps attempts in all (the most steps any
  !> case takes), cannot follow the model: it ends 'unstable' at its last
  !> accepted step.
  real(wp), parameter :: smallest_step_ulps = 16
  integer, parameter :: max_round_off_attempts = 100000

  type, public :: step_control_t
    integer :: order = 8                    !< the pair's control_order
    logical :: after_rejection = .false.
    real(wp) :: log_previous_norm = log_previous_floor    !< log err of the last accepted step
  contains
    procedure :: reject => step_control_reject
    procedure :: accept => step_control_accept
  end type step_control_t

  !> A maximum of the nutation angle located inside a step.
  type :: nutation_peak_t
    real(wp) :: t = 0, tan_nutation = 0
    real(wp) :: lateral = 0, normal_z = 1     !< of the unit normal there
  end type nutation_peak_t

contains

  !> An embedded pair with its step-size control (step_control_t): accept
  !> when the error norm <= 1, never a step above dt (the largest step
  !> allowed). Output samples, limit crossings and the maxima of Theta come
  !> from the dense output, so that they do not depend on where the steps
  !> fall; a sample computes only what the stored fields need. The steps are
  !> the fused ones of the ball (ellroll_ball_steppers).
  subroutine adaptive_loop(pair, cs, plan, run, y, f, res)
    class(embedded_pair_t), intent(inout) :: pair
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    real(wp), intent(inout) :: y(state_size), f(state_size)
    type(case_result_t), intent(inout) :: res
    real(wp) :: y_new(state_size), f_new(state_size), t, h, h_max
    type(observation_t) :: obs
    type(nutation_peak_t) :: peak
    type(step_control_t) :: control
    integer :: status, round_off_attempts
    logical :: peak_inside
    real(wp) :: passed                    ! where a slip inside a step is known

    t = 0
    round_off_attempts = 0
    h_max = cs%param(p_dt)
    control%order = pair%control_order()
    call pair%initial_step(run%ball, t, y, f, h_max, h, res%n_rhs)
    do while (t < cs%t_end)
      if (stop_asked(res%n_steps + res%n_rejected)) then
        res%status = status_pending
        return
      end if
      h = last_step_clipped(t, h, cs%t_end, control%after_rejection)
      if (round_off_step(t, h)) round_off_attempts = round_off_attempts + 1
      if (cannot_follow(h, round_off_attempts, res%n_steps + res%n_rejected)) then
        res%status = status_unstable
        res%t_final = t
        return
      end if
      call run%ball%begin_step(y)
      call attempt_step(pair, control, run, t, y, f, h, y_new, f_new, obs, status, res)
      if (pair%error_norm > 1) then
        res%n_rejected = res%n_rejected + 1
        cycle
      end if
      if (status /= status_completed) then
        call stop_in_step(pair, run, plan, status, res)
        return
      end if
      peak_inside = nutation_peak_inside(y, f, y_new, f_new)
      if (peak_inside) then
        call locate_nutation_peak(pair, run%ball, peak, res%n_rhs)
        if (beyond_rim(peak)) then
          call stop_in_step(pair, run, plan, status_rim, res, peak%t - t)
          return
        end if
      end if
      if (run%ball%mu > 0) then
        call slip_inside(pair, run, y, f, obs%friction_needed, status, passed, res%n_rhs)
        if (status /= status_completed) then
          call stop_in_step(pair, run, plan, status, res, passed)
          return
        end if
      end if
      call record_samples_until(pair, run, plan, t + h, obs, res)
      if (peak_inside) then
        call run%maxima%add_peak(peak%t)
        call note_nutation(run, res, peak%tan_nutation, peak%lateral, peak%normal_z)
      end if
      if (.not. round_off_step(t, h)) round_off_attempts = 0
      t = t + h
      y = y_new
      f = f_new
      res%n_steps = res%n_steps + 1
      call track_step_end(run, res, t, obs)
      call control%accept(h, pair%error_norm, h_max)
    end do
    res%t_final = cs%t_end
  end subroutine adaptive_loop

  !> One attempt of size h from (t, y, f), its RHS calls counted in
  !> res. Rejected (pair%error_norm > 1, a non-finite norm made huge): h is
  !> shrunk by the step control. Accepted: the new state projected, f and the derived
  !> outputs there, and the model's limit status. An attempt in which an
  !> event of the model happens (event_crossed) is cut there first
  !> (shorten_to_event) and, accepted, ends where the model acted
  !> (apply_event): an event, not a discontinuity inside a step for the
  !> step control to shrink around.
  subroutine attempt_step(pair, control, run, t, y, f, h, y_new, f_new, obs, status, res)
    class(embedded_pair_t), intent(inout) :: pair
    type(step_control_t), intent(inout) :: control
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, y(state_size), f(state_size)
    real(wp), intent(inout) :: h
    real(wp), intent(out) :: y_new(state_size), f_new(state_size)
    type(observation_t), intent(out) :: obs
    integer, intent(out) :: status
    type(case_result_t), intent(inout) :: res
    integer :: event
    status = status_completed
    call pair_ball_step(pair, run%ball, t, y, f, h, y_new)
    res%n_rhs = res%n_rhs + pair%attempt_calls()
    event = 0
    if (ieee_is_finite(pair%error_norm)) then
      event = run%ball%event_crossed(y, y_new)
      if (event /= 0) call shorten_to_event(pair, run, event, t, y, f, h, y_new, res)
    end if
    pair%error_norm = judged_norm(pair%error_norm, h, is_zero(pair%atol))
    if (pair%error_norm > 1) then
      call control%reject(h, pair%error_norm)
      return
    end if
    call project_with_rate(y_new, pair%k(:state_size, pair%end_stage()), f_new)
    if (event /= 0) then
      call run%ball%apply_event(event, y_new)
      call ball_derivative(run%ball, t + h, y_new, f_new)
      res%n_rhs = res%n_rhs + 1
    end if
    call observe(run%ball, t + h, y_new, f_new, obs)
    status = limit_status(run%ball, y_new, obs)
  end subroutine attempt_step

  !> The attempt of size h from (t, y, f), which ended at y_new past an
  !> event of the model (event_crossed), cut to end where the event's
  !> function changes sign (event_search_t on trial attempts); pair holds
  !> the attempt of the shortened h.
  subroutine shorten_to_event(pair, run, event, t, y, f, h, y_new, res)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(in) :: run
    integer, intent(in) :: event
    real(wp), intent(in) :: t, y(state_size), f(state_size)
    real(wp), intent(inout) :: h
    real(wp), intent(inout) :: y_new(state_size)
    type(case_result_t), intent(inout) :: res
    type(event_search_t) :: search
    real(wp) :: offset
    integer :: k
    call search%begin(run%ball, event, y_new, h)
    do k = 1, max_event_trials
      if (search%done()) exit
      offset = search%trial()
      call pair_ball_step(pair, run%ball, t, y, f, offset, y_new)
      res%n_rhs = res%n_rhs + pair%attempt_calls()
      call search%report_state(run%ball, offset, y_new, .true.)
    end do
    h = search%high
    call pair_ball_step(pair, run%ball, t, y, f, h, y_new)
    res%n_rhs = res%n_rhs + pair%attempt_calls()
  end subroutine shorten_to_event

  !> The error norm of an attempt of size h as the step control takes it:
  !> huge where it is not finite, or, under pure relative control, where
  !> some component's error reached tolerance_ratio_cap times its tolerance
  !> (it has none: the norm is then at least h cap / sqrt(6.06), and h times
  !> it would accept a short enough step of any error).
  pure real(wp) function judged_norm(error_norm, h, pure_relative)
    real(wp), intent(in) :: error_norm, h
    logical, intent(in) :: pure_relative
    judged_norm = error_norm
    if (.not. ieee_is_finite(error_norm)) then
      judged_norm = huge(1.0_wp)
    else if (pure_relative .and. error_norm >= abs(h) * (tolerance_ratio_cap / 4)) then
      judged_norm = huge(1.0_wp)
    end if
  end function judged_norm

  !> Whether a step h from t is round-off: at most smallest_step_ulps eps |t|,
  !> or not a number.
  pure logical function round_off_step(t, h)
    real(wp), intent(in) :: t, h
    if (ieee_is_nan(h)) then            ! (tested first: an ordered comparison with NaN traps)
      round_off_step = .true.
    else
      round_off_step = h <= (smallest_step_ulps * epsilon(1.0_wp)) * abs(t)
    end if
  end function round_off_step

  !> Whether a case about to attempt a step h ends 'unstable', after these
  !> attempts of round-off steps since its last accepted step beyond them
  !> and these attempts in all; a step of 0 (or not a number) is no step.
  pure logical function cannot_follow(h, round_off_attempts, attempts)
    real(wp), intent(in) :: h
    integer, intent(in) :: round_off_attempts
    integer(i8), intent(in) :: attempts
    cannot_follow = round_off_attempts > max_round_off_attempts .or. real(attempts, wp) >= max_steps
    if (ieee_is_nan(h)) then
      cannot_follow = .true.
    else if (h <= 0) then
      cannot_follow = .true.
    end if
  end function cannot_follow

  !> The step from t, shortened to end exactly at t_end when it would end
  !> at or within round-off of it (1e-12 t_end), or after a rejection
  !> (after_rejection) when it would end past it: a rejected step within
  !> 1e-12 t_end of t_end (a singular point of the equations there) would
  !> otherwise be stretched back to t_end and tried again, unchanged, for ever.
  pure real(wp) function last_step_clipped(t, h, t_end, after_rejection) result(step)
    real(wp), intent(in) :: t, h, t_end
    logical, intent(in) :: after_rejection
    step = h
    if (after_rejection) then
      step = min(h, t_end - t)
    else if (t + h >= t_end - 1.0e-12_wp * t_end) then
      step = t_end - t
    end if
  end function last_step_clipped

  !> h: the step to retry after a rejected attempt of size h with this
  !> error norm (> 1); the next accepted step will not grow.
  pure subroutine step_control_reject(self, h, error_norm)
    class(step_control_t), intent(inout) :: self
    real(wp), intent(inout) :: h
    real(wp), intent(in) :: error_norm
    h = h * max(adaptive_min_factor, adaptive_safety / error_root(error_norm, self%order))
    self%after_rejection = .true.
  end subroutine step_control_reject

  !> h: the step after an accepted one of size h with this error norm
  !> (<= 1), at most h_max; no growth right after a rejection.
  pure subroutine step_control_accept(self, h, error_norm, h_max)
    class(step_control_t), intent(inout) :: self
    real(wp), intent(inout) :: h
    real(wp), intent(in) :: error_norm, h_max
    real(wp) :: log_norm, factor
    real(wp) :: integral_gain, proportional_gain
    integral_gain = 0.3_wp / self%order
    proportional_gain = 0.4_wp / self%order
    log_norm = log(max(error_norm, error_norm_floor))
    factor = adaptive_safety * exp(proportional_gain * self%log_previous_norm &
                                   - (integral_gain + proportional_gain) * log_norm)
    if (self%after_rejection) factor = min(1.0_wp, factor)
    h = min(h * factor, h_max)
    self%after_rejection = .false.
    self%log_previous_norm = max(log_norm, log_previous_floor)
  end subroutine step_control_accept

  !> x^(1/order); for order 8 by three square roots (a fraction of the cost
  !> of x**0.125).
  pure real(wp) function error_root(x, order)
    real(wp), intent(in) :: x
    integer, intent(in) :: order
    if (order == 8) then
      error_root = sqrt(sqrt(sqrt(x)))
    else
      error_root = x**(1.0_wp / order)
    end if
  end function error_root

  !> The end point of an accepted attempt (raw: y, its f: f_raw) projected
  !> onto the unit normal, and f there: n' is homogeneous of degree one in
  !> |n|, so f at the projected point is f_raw with n' divided by |n|.
  pure subroutine project_with_rate(y, f_raw, f)
    real(wp), intent(inout) :: y(state_size)
    real(wp), intent(in) :: f_raw(state_size)
    real(wp), intent(out) :: f(state_size)
    real(wp) :: length
    length = sqrt(y(1) * y(1) + y(2) * y(2) + y(3) * y(3))
    y(1:3) = y(1:3) / length
    f = f_raw
    f(1:3) = f(1:3) / length
  end subroutine project_with_rate

  !> Whether Theta has a maximum in the step from (y, f) to (y_new, f_new):
  !> d tan(Theta)/dt, of the sign of (n_x n_x' + n_y n_y') n_z - (n_x^2 +
  !> n_y^2) n_z', goes from >= 0 to < 0 (half-open, so that a maximum at a
  !> step's end is found once).
  pure logical function nutation_peak_inside(y, f, y_new, f_new)
    real(wp), intent(in) :: y(:), f(:), y_new(:), f_new(:)     ! (assumed shape: a batch passes lanes' rows)
    nutation_peak_inside = nutation_trend(y, f) >= 0 .and. nutation_trend(y_new, f_new) < 0
  end function nutation_peak_inside

  !> Of the sign of d tan(Theta)/dt at the state y with rate y' (any scale
  !> of either: the part of y' along y cancels, so |n| need not be 1).
  pure real(wp) function nutation_trend(y, rate)
    real(wp), intent(in) :: y(:), rate(:)
    nutation_trend = (y(1) * rate(1) + y(2) * rate(2)) * y(3) - (y(1)**2 + y(2)**2) * rate(3)
  end function nutation_trend

  !> The maximum of Theta inside the last attempt (in pair): the root of
  !> d tan(Theta)/dt on its dense output and the interpolant's derivative (a
  !> simple root: its time is well conditioned), by regula falsi with the
  !> Illinois modification (superlinear, the bracket kept) to a bracket of
  !> 4 units of round-off in theta: about 10 evaluations where bisection
  !> takes 52.
  subroutine locate_nutation_peak(pair, ball, peak, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    type(nutation_peak_t), intent(out) :: peak
    integer(i8), intent(inout) :: n_rhs
    integer, parameter :: max_iterations = 100
    real(wp), parameter :: resolution = 4 * epsilon(1.0_wp)
    real(wp) :: low, high, middle, trend_low, trend_high, trend, y(state_size), lateral
    integer :: i, kept_side
    logical :: prepared
    call pair_ball_dense(pair, ball, 0.0_wp, y, prepared)        ! prepares the interpolant
    if (prepared) n_rhs = n_rhs + pair%dense_calls()
    low = 0
    high = 1
    trend_low = trend_at(low)
    trend_high = trend_at(high)
    ! a root at an end, where round-off decided the step's test: that end
    if (trend_low < 0) then
      high = low
    else if (trend_high >= 0) then
      low = high
    end if
    kept_side = 0
    do i = 1, max_iterations
      if (high - low <= resolution) exit
      ! round-off may put the secant's root on an end, and the Illinois
      ! halving may take both ends' trends to zero (a motion of 1e-9 m): halve instead
      if (trend_low > trend_high) then
        middle = (low * trend_high - high * trend_low) / (trend_high - trend_low)
      else
        middle = low
      end if
      if (.not. (middle > low .and. middle < high)) middle = 0.5_wp * (low + high)
      trend = trend_at(middle)
      if (trend >= 0) then
        low = middle
        trend_low = trend
        if (kept_side == 1) trend_high = 0.5_wp * trend_high      ! Illinois: the other end stayed twice
        kept_side = 1
      else
        high = middle
        trend_high = trend
        if (kept_side == -1) trend_low = 0.5_wp * trend_low
        kept_side = -1
      end if
    end do
    middle = 0.5_wp * (low + high)
    call pair_ball_dense(pair, ball, middle, y, prepared)
    y(1:3) = y(1:3) / sqrt(y(1)**2 + y(2)**2 + y(3)**2)
    lateral = sqrt(y(1)**2 + y(2)**2)
    peak%t = pair%t_old + middle * pair%h
    peak%tan_nutation = lateral / y(3)
    peak%lateral = lateral
    peak%normal_z = y(3)
  contains
    real(wp) function trend_at(theta)
      real(wp), intent(in) :: theta
      real(wp) :: state(state_size), rate(max_equations)
      call pair_ball_dense(pair, ball, theta, state, prepared)
      call pair%dense_rate(theta, rate)
      trend_at = nutation_trend(state, rate(:state_size))
    end function trend_at
  end subroutine locate_nutation_peak

  !> The last attempt (in pair) crossed a limit (status): bisect on its dense
  !> output, record the output samples before the crossing, and end the
  !> case at the last valid point. invalid: the offset from the step's
  !> start known to be past the limit (default: its end).
  subroutine stop_in_step(pair, run, plan, status, res, invalid)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: run
    type(output_plan_t), intent(in) :: plan
    integer, intent(in) :: status
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in), optional :: invalid
    type(limit_search_t) :: search
    call locate_crossing(pair, run, status, search, res%n_rhs, invalid)
    call record_samples_until(pair, run, plan, pair%t_old + search%valid, search%last_trial, res)
    call end_at_crossing(pair, run, search, res)
    res%n_steps = res%n_steps + 1
  end subroutine stop_in_step

  !> Bisect the dense output of the last attempt (in pair), which crossed a
  !> limit (status) at its end or at the offset invalid, for where the
  !> crossing lies.
  subroutine locate_crossing(pair, run, status, search, n_rhs, invalid)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(in) :: run
    integer, intent(in) :: status
    type(limit_search_t), intent(out) :: search
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(in), optional :: invalid
    type(observation_t) :: obs
    real(wp) :: offset
    if (present(invalid)) then
      call search%begin(pair%t_old, invalid, status)
    else
      call search%begin(pair%t_old, pair%h, status)
    end if
    do while (.not. search%done())
      offset = search%trial()
      call dense_state(pair, run, offset / pair%h, .true., obs, n_rhs)
      call search%record(offset, limit_status(run%ball, [obs%normal, obs%omega], obs), obs)
    end do
  end subroutine locate_crossing

  !> Whether a maximum of Theta inside a step lies at or past the rim
  !> (n_z <= 0): the step's ends are inside, the path between is not. Its
  !> time is where the step's dense output is known to be past the rim.
  pure logical function beyond_rim(peak)
    type(nutation_peak_t), intent(in) :: peak
    beyond_rim = .not. peak%normal_z > 0
  end function beyond_rim

  !> With a friction limit (mu > 0): whether the path inside the last
  !> attempt (in pair), from (y, f) at its start to its end (friction_end
  !> needed there), both inside, passes the limit. The friction needed is
  !> smooth along the path, and where a slip only grazes the limit its
  !> maximum is narrow: a step can begin and end below the limit and pass it
  !> between. The friction is evaluated on the dense output at 1e-3, 1/4,
  !> 1/2, 3/4 and 1 - 1e-3 of the step; each maximum among these and the
  !> ends that lies inside (in time order) is refined by successive
  !> parabolas (golden sections where a parabola's vertex falls outside its
  !> bracket) to 1e-6 of the step. (A maximum within 1e-3 of the step from
  !> an end shows as a rise to it at the end.) status: status_completed, or
  !> the limit met where the dense output passes it, at offset from the
  !> step's start (for locate_crossing). Its RHS calls count in n_rhs.
  subroutine slip_inside(pair, run, y, f, friction_end, status, offset, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: y(state_size), f(state_size), friction_end
    integer, intent(out) :: status
    real(wp), intent(out) :: offset
    integer(i8), intent(inout) :: n_rhs
    real(wp), parameter :: golden = 0.381966011250105_wp, resolution = 1.0e-6_wp, near_end = 1.0e-3_wp
    real(wp), parameter :: theta(0:6) = [0.0_wp, near_end, 0.25_wp, 0.5_wp, 0.75_wp, 1 - near_end, 1.0_wp]
    integer, parameter :: max_trials = 60
    type(observation_t) :: obs
    real(wp) :: value(0:6)
    integer :: i
    status = status_completed
    offset = 0
    call observe(run%ball, pair%t_old, y, f, obs)
    value(0) = obs%friction_needed
    value(6) = friction_end
    do i = 1, 5
      if (trial(theta(i), value(i))) return
    end do
    do i = 1, 5
      if (value(i) >= value(i - 1) .and. value(i) >= value(i + 1)) then
        if (maximum_passes(theta(i - 1), theta(i), theta(i + 1), value(i - 1), value(i), value(i + 1))) return
      end if
    end do
  contains
    !> The friction needed at theta; true where the dense output passes a limit there.
    logical function trial(at, friction)
      real(wp), intent(in) :: at
      real(wp), intent(out) :: friction
      call dense_state(pair, run, at, .true., obs, n_rhs)
      friction = obs%friction_needed
      status = limit_status(run%ball, [obs%normal, obs%omega], obs)
      trial = status /= status_completed
      if (trial) offset = at * pair%h
    end function trial

    !> The maximum bracketed by a < b < c (fb >= fa, fc), refined until it
    !> passes a limit (true) or the bracket is resolution wide.
    logical function maximum_passes(a0, b0, c0, fa0, fb0, fc0) result(passes)
      real(wp), intent(in) :: a0, b0, c0, fa0, fb0, fc0
      real(wp) :: a, b, c, fa, fb, fc, x, fx, numerator, denominator
      integer :: k
      a = a0
      b = b0
      c = c0
      fa = fa0
      fb = fb0
      fc = fc0
      passes = .false.
      do k = 1, max_trials
        if (c - a <= resolution) exit
        ! the vertex of the parabola through the bracket
        numerator = (b - a)**2 * (fb - fc) - (b - c)**2 * (fb - fa)
        denominator = (b - a) * (fb - fc) - (b - c) * (fb - fa)
        x = -1
        if (.not. is_zero(denominator)) x = b - 0.5_wp * numerator / denominator
        if (.not. (x > a .and. x < c) .or. abs(x - b) < 0.25_wp * resolution) then
          if (c - b > b - a) then
            x = b + golden * (c - b)
          else
            x = b - golden * (b - a)
          end if
        end if
        passes = trial(x, fx)
        if (passes) return
        if (fx >= fb) then
          if (x > b) then
            a = b
            fa = fb
          else
            c = b
            fc = fb
          end if
          b = x
          fb = fx
        else if (x > b) then
          c = x
          fc = fx
        else
          a = x
          fa = fx
        end if
      end do
    end function maximum_passes
  end subroutine slip_inside

  !> The case ends at the last valid point of a located crossing.
  pure subroutine end_at_crossing(pair, run, search, res)
    class(embedded_pair_t), intent(in) :: pair
    type(run_state_t), intent(inout) :: run
    type(limit_search_t), intent(in) :: search
    type(case_result_t), intent(inout) :: res
    res%status = search%crossed
    res%t_final = pair%t_old + search%valid
    if (search%found_valid) call accumulate(run, res, res%t_final, search%last_valid)
  end subroutine end_at_crossing

  !> The exact flow from a fixed-step method's state y_from at t_from,
  !> followed with reference_method at reference_rtol, reference_atol up to t_until at
  !> most, to where it first meets a model limit. met: a limit was met, the
  !> case ends there (res%status, res%t_final), the flow's step ends after
  !> t_tracked (the method's last state) are added to the summary, and so are
  !> the output samples after t_tracked up to the end (run%next_sample, the
  !> first of them, from the flow's dense output). Where the flow's steps
  !> fall to the resolution of t, it has reached a singular point of the
  !> equations, and their only one is det L = 0, where the ball stops
  !> fitting: the fit limit's square-root singularity, so sharp there that
  !> the margin is crossed within about 1e-15 s of it. The case ends with
  !> 'no_fit' at the flow's last step. The flow can stay inside up to
  !> t_until: met = .false., and nothing is added to the summary or the
  !> samples. Its RHS calls count in the case's n_rhs (n_rejected is the
  !> adaptive method's own).
  subroutine follow_flow_to_limit(run, plan, t_from, y_from, t_tracked, t_until, res, met)
    type(run_state_t), intent(inout) :: run
    type(output_plan_t), intent(in) :: plan
    real(wp), intent(in) :: t_from, y_from(state_size), t_tracked, t_until
    type(case_result_t), intent(inout) :: res
    logical, intent(out) :: met
    class(embedded_pair_t), allocatable :: pair
    type(error_t) :: err
    type(step_control_t) :: control
    type(limit_search_t) :: search
    type(nutation_peak_t) :: peak
    type(observation_t) :: obs
    type(observation_t), allocatable :: untracked(:)
    real(wp), allocatable :: untracked_t(:)
    real(wp) :: t_at, y_at(state_size), f_at(state_size), y_new(state_size), f_new(state_size), h, passed
    integer :: status, n_untracked
    integer(i8) :: n_recorded
    met = .false.
    n_recorded = res%n_recorded
    call new_pair(reference_method, pair, err)      ! (a row of the method table: it cannot fail)
    pair%rtol = reference_rtol
    pair%atol = reference_atol
    t_at = t_from
    y_at = y_from
    call ball_derivative(run%ball, t_at, y_at, f_at)
    res%n_rhs = res%n_rhs + 1
    control%order = pair%control_order()
    call pair%initial_step(run%ball, t_at, y_at, f_at, t_until - t_from, h, res%n_rhs)
    allocate (untracked(64), untracked_t(64))
    n_untracked = 0
    do while (t_at < t_until)
      if (t_until - t_at <= 16 * spacing(t_until)) exit
      if (h <= 16 * spacing(t_until)) then          ! the fit limit's singularity (above)
        met = .true.
        call track_untracked()
        res%status = status_no_fit
        res%t_final = t_at
        return
      end if
      h = last_step_clipped(t_at, h, t_until, control%after_rejection)
      if (.not. (h > smallest_step_ulps * spacing(t_until))) return     ! (NaN: no step either)
      call run%ball%begin_step(y_at)
      call attempt_step(pair, control, run, t_at, y_at, f_at, h, y_new, f_new, obs, status, res)
      if (pair%error_norm > 1) cycle
      if (status /= status_completed) then
        met = .true.
        call track_untracked()
        call locate_crossing(pair, run, status, search, res%n_rhs)
        call record_samples_until(pair, run, plan, pair%t_old + search%valid, search%last_trial, res)
        call end_at_crossing(pair, run, search, res)
        return
      end if
      passed = -1
      if (nutation_peak_inside(y_at, f_at, y_new, f_new)) then
        call locate_nutation_peak(pair, run%ball, peak, res%n_rhs)
        if (beyond_rim(peak)) then
          status = status_rim
          passed = peak%t - t_at
        end if
      end if
      if (passed < 0 .and. run%ball%mu > 0) &
        call slip_inside(pair, run, y_at, f_at, obs%friction_needed, status, passed, res%n_rhs)
      if (status /= status_completed) then        ! the path passed a limit inside the step
        met = .true.
        call track_untracked()
        call locate_crossing(pair, run, status, search, res%n_rhs, passed)
        call record_samples_until(pair, run, plan, pair%t_old + search%valid, search%last_trial, res)
        call end_at_crossing(pair, run, search, res)
        return
      end if
      t_at = t_at + h
      y_at = y_new
      f_at = f_new
      ! the summary takes these only once the flow is known to meet a limit
      if (t_at > t_tracked) then
        if (n_untracked == size(untracked)) then
          untracked = [untracked, untracked]
          untracked_t = [untracked_t, untracked_t]
        end if
        n_untracked = n_untracked + 1
        untracked(n_untracked) = obs
        untracked_t(n_untracked) = t_at
        call record_samples_until(pair, run, plan, t_at, obs, res)
      end if
      call control%accept(h, pair%error_norm, t_until - t_from)
    end do
    res%n_recorded = n_recorded          ! the flow stayed inside: its samples are not the case's
  contains
    subroutine track_untracked()
      integer :: i
      do i = 1, n_untracked
        call track(run, res, untracked_t(i), untracked(i))
      end do
    end subroutine track_untracked
  end subroutine follow_flow_to_limit

  !> Record every output sample in (t_old, t_until] of the last attempt (in
  !> pair), from its dense output; a sample at the step's end is obs_end. A
  !> sample computes only what the stored fields need: the geometry of the
  !> state, or every derived output (with f there when the reaction is stored).
  subroutine record_samples_until(pair, run, plan, t_until, obs_end, res)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: run
    type(output_plan_t), intent(in) :: plan
    real(wp), intent(in) :: t_until
    type(observation_t), intent(in) :: obs_end
    type(case_result_t), intent(inout) :: res
    type(observation_t) :: obs
    real(wp) :: t_sample, theta, y(state_size)
    logical :: complete, prepared
    complete = any(plan%fields([field_energy, field_reaction, field_base_acceleration]))
    do while (sample_due(run, plan, t_until))
      t_sample = real(run%next_sample - 1, wp) * plan%interval
      theta = (t_sample - pair%t_old) / pair%h
      if (abs(t_sample - (pair%t_old + pair%h)) <= 1.0e-14_wp * max(1.0_wp, t_sample)) then
        call record_sample(res, run%next_sample, obs_end)          ! the step's own end point
      else if (complete) then
        call dense_state(pair, run, theta, plan%fields(field_reaction), obs, res%n_rhs)
        call record_sample(res, run%next_sample, obs)
      else
        call pair_ball_dense(pair, run%ball, theta, y, prepared)
        if (prepared) res%n_rhs = res%n_rhs + pair%dense_calls()
        call record_geometry_sample(res, run%next_sample, run%ball, y)
      end if
      run%next_sample = run%next_sample + 1
    end do
  end subroutine record_samples_until

  !> The state at t_old + theta h of the last attempt, from its dense
  !> output, the normal projected to unit length.
  subroutine dense_point(pair, run, theta, y, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(state_size)
    integer(i8), intent(inout) :: n_rhs
    logical :: prepared
    call pair_ball_dense(pair, run%ball, theta, y, prepared)
    if (prepared) n_rhs = n_rhs + pair%dense_calls()
    call normalize_normal(y)
  end subroutine dense_point

  !> Every derived output at t_old + theta h of the last attempt, from its
  !> dense output, with f there (one more RHS call) when with_rate (the
  !> limits and the stored reaction need it).
  subroutine dense_state(pair, run, theta, with_rate, obs, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: theta
    logical, intent(in) :: with_rate
    type(observation_t), intent(out) :: obs
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: y(state_size), f(state_size), t
    call dense_point(pair, run, theta, y, n_rhs)
    t = pair%t_old + theta * pair%h
    f = 0
    if (with_rate) then
      call ball_derivative(run%ball, t, y, f)
      n_rhs = n_rhs + 1
    end if
    call observe(run%ball, t, y, f, obs)
  end subroutine dense_state
end module ellroll_adaptive_run
