!> The maxima of Theta inside an embedded pair's step (dop853, vern9): whether
!> a step holds one (nutation_peak_inside, from its ends), where on its dense
!> output (locate_nutation_peak), and whether it lies past the rim. The
!> one-case loop, the batches and the flow to a limit take them alike.
module ellroll_nutation_peaks
  use ellroll_kinds, only: wp, i8
  use ellroll_norms, only: norm_of
  use ellroll_rolling_ball, only: rolling_ball_t, state_size
  use ellroll_integrators, only: embedded_pair_t, max_equations
  use ellroll_ball_steppers, only: pair_ball_dense
  implicit none
  private

  public :: nutation_peak_t, nutation_peak_inside, locate_nutation_peak, beyond_rim, rest_turn, tan_nutation

  !> What a step does at a still state (rest_turn): none, reaches one with
  !> Theta rising (a maximum if Theta falls when the ball leaves it), leaves
  !> one with Theta falling or rising.
  integer, parameter, public :: rest_none = 0, rest_reached_rising = 1, rest_left_falling = 2, &
                                rest_left_rising = 3, rest_reached_falling = 4

  type :: nutation_peak_t
    real(wp) :: t = 0, tan_nutation = 0
    real(wp) :: lateral = 0, normal_z = 1     !< of the unit normal there
    logical :: found = .true.                 !< the dense output holds it (locate_nutation_peak)
  end type nutation_peak_t

contains


  !> Whether Theta has a maximum in the step from (y, f) to (y_new, f_new):
  !> d tan(Theta)/dt, of the sign of (n_x n_x' + n_y n_y') n_z - (n_x^2 +
  !> n_y^2) n_z', goes from >= 0 to < 0 (half-open, so that a maximum at a
  !> step's end is found once).
  pure logical function nutation_peak_inside(y, f, y_new, f_new, h)
    real(wp), intent(in) :: y(:), f(:), y_new(:), f_new(:)     ! (assumed shape: a batch passes lanes' rows)
    real(wp), intent(in) :: h
    real(wp) :: state(state_size), rate(state_size), s, trend, before, factor
    integer :: i
    nutation_peak_inside = nutation_trend(y, f, lateral_factor(y)) >= 0 .and. &
                           nutation_trend(y_new, f_new, lateral_factor(y_new)) < 0
    if (nutation_peak_inside) return
    ! a maximum and the next minimum (or a minimum and the next maximum)
    ! inside one long step: d tan(Theta)/dt rises at both ends, or falls at
    ! both, and changes sign twice between; screened on the cubic Hermite
    ! interpolant of the step's ends (no RHS call), located on the dense output
    before = nutation_trend(y, f, lateral_factor(y))
    do i = 1, 4
      s = 0.25_wp * i
      if (i == 4) then
        trend = nutation_trend(y_new, f_new, lateral_factor(y_new))
      else
        state = (1 + 2 * s) * (1 - s)**2 * y(:state_size) + s * (1 - s)**2 * h * f(:state_size) &
                + s**2 * (3 - 2 * s) * y_new(:state_size) + s**2 * (s - 1) * h * f_new(:state_size)
        rate = 6 * s * (s - 1) * (y(:state_size) - y_new(:state_size)) / h + (1 - s) * (1 - 3 * s) * f(:state_size) &
               + s * (3 * s - 2) * f_new(:state_size)
        factor = lateral_factor(state)
        trend = nutation_trend(state, rate, factor)
        ! a sign the interpolant's rate does not resolve (a step whose change
        ! is near round-off: a short one, a ball all but at rest) says nothing
        if (.not. abs(trend) > hermite_noise(state, y, y_new, h, factor)) cycle
      end if
      nutation_peak_inside = before >= 0 .and. trend < 0
      if (nutation_peak_inside) return
      before = trend
    end do
  end function nutation_peak_inside

  !> The step's turn at a still state (is_still: the ball at rest, held by
  !> rolling resistance, or where a stop inside a step left it, turning):
  !> rest_none, rest_reached_rising, ... . Theta is flat while the ball
  !> rests, and a rest or a turn is a maximum of Theta where Theta rises into
  !> it and falls out of it (as three samples find a flat top).
  pure integer function rest_turn(y, f, y_new, f_new, still, still_new)
    real(wp), intent(in) :: y(:), f(:), y_new(:), f_new(:)
    logical, intent(in) :: still, still_new     !< at the step's start, at its end
    rest_turn = rest_none
    if (still) then
      if (still_new) return
      rest_turn = rest_left_rising
      if (nutation_trend(y_new, f_new, lateral_factor(y_new)) < 0) rest_turn = rest_left_falling
    else if (still_new) then
      rest_turn = rest_reached_falling
      if (nutation_trend(y, f, lateral_factor(y)) > 0) rest_turn = rest_reached_rising
    end if
  end function rest_turn

  !> A bound on the round-off of nutation_trend at the Hermite interpolant's
  !> point state (between y and y_new, a step of h), where the rate's part
  !> (y - y_new) / h carries each difference's rounding, eps (|y_i| +
  !> |y_new_i|), divided by h; four times its first-order size.
  pure real(wp) function hermite_noise(state, y, y_new, h, factor)
    real(wp), intent(in) :: state(:), y(:), y_new(:), h, factor
    real(wp) :: spread(3)
    spread = (6 * epsilon(1.0_wp) / h) * (abs(y(1:3)) + abs(y_new(1:3)))   ! (6 s (1 - s) <= 3/2, times 4)
    hermite_noise = ((factor * abs(state(1))) * (factor * spread(1)) + (factor * abs(state(2))) * (factor * spread(2))) &
                    * abs(state(3)) + ((factor * state(1))**2 + (factor * state(2))**2) * spread(3)
  end function hermite_noise

  !> Of the sign of d tan(Theta)/dt at the state y with rate y' (any scale
  !> of either: the part of y' along y cancels, so |n| need not be 1), times
  !> factor^2: the lateral components and their rates taken times factor, a
  !> power of two (lateral_factor), so that the products of a tiny motion's
  !> do not underflow.
  pure real(wp) function nutation_trend(y, rate, factor)
    real(wp), intent(in) :: y(:), rate(:), factor
    nutation_trend = ((factor * y(1)) * (factor * rate(1)) + (factor * y(2)) * (factor * rate(2))) * y(3) &
                     - ((factor * y(1))**2 + (factor * y(2))**2) * rate(3)
  end function nutation_trend

  !> 1, or where the lateral components of y are below 2^-400 (their
  !> products would lose digits), the power of two that takes the larger to
  !> [1/2, 1) (a subnormal's towards it): the trend's sign and ratios are the
  !> same, its round-off not that of the subnormal range.
  pure real(wp) function lateral_factor(y)
    real(wp), intent(in) :: y(:)
    real(wp) :: larger
    larger = max(abs(y(1)), abs(y(2)))
    lateral_factor = 1
    ! (at most 2^1000: a subnormal's exponent goes to -1073, and 2^1073 overflows)
    if (larger < scale(1.0_wp, -400) .and. larger > 0) lateral_factor = scale(1.0_wp, min(-exponent(larger), 1000))
  end function lateral_factor

  !> The maximum of Theta inside the last attempt (in pair): the root of
  !> d tan(Theta)/dt on its dense output and the interpolant's derivative (a
  !> simple root: its time is well conditioned), by regula falsi with the
  !> Illinois modification (superlinear, the bracket kept) to a bracket of
  !> 4 units of round-off in theta: about 10 evaluations where bisection
  !> takes 52. upto: over the part [0, upto] of the step only, where a
  !> maximum at its end counts (inside: whether it lies inside).
  subroutine locate_nutation_peak(pair, ball, peak, n_rhs, upto, inside)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    type(nutation_peak_t), intent(out) :: peak
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(in), optional :: upto
    logical, intent(out), optional :: inside
    integer, parameter :: max_iterations = 100
    real(wp), parameter :: resolution = 4 * epsilon(1.0_wp)
    !> of the case's first step: a maximum before it is the start's
    real(wp), parameter :: start_fraction = 1.0e-12_wp
    real(wp) :: low, high, middle, trend_low, trend_high, trend, y(state_size), lateral, factor, lower_end
    integer :: i, kept_side
    logical :: prepared, between_ends
    call pair_ball_dense(pair, ball, 0.0_wp, y, prepared)        ! prepares the interpolant
    lower_end = tan_nutation(y)
    if (prepared) n_rhs = n_rhs + pair%dense_calls()
    factor = lateral_factor(y)       ! (one for the step: the trends' ratios are the secant's)
    low = 0
    high = 1
    if (present(upto)) high = upto
    trend_low = trend_at(low)
    trend_high = trend_at(high)
    if (present(inside)) inside = trend_low >= 0 .and. trend_high < 0
    ! the ends without a maximum between them (nutation_peak_inside's screen):
    ! the first of 16 parts of the step whose trend falls through zero, if any
    peak%found = .true.
    between_ends = .not. present(upto) .and. .not. (trend_low >= 0 .and. trend_high < 0)
    if (between_ends) then
      peak%found = .false.
      do i = 1, 16
        trend = trend_at(i / 16.0_wp)
        if (trend_low >= 0 .and. trend < 0) then
          peak%found = .true.
          high = i / 16.0_wp
          trend_high = trend
          exit
        end if
        low = i / 16.0_wp
        trend_low = trend
      end do
      if (.not. peak%found) return
    end if
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
    ! a maximum at the case's start (a release from rest: Theta turns at
    ! t = 0, where the dense output's rate is round-off, 4e-20 with vern9)
    ! has no rise before it: not counted, as three samples of fixed steps
    ! never count it
    if (.not. (pair%t_old > 0 .or. low > start_fraction)) then
      peak%found = .false.
      return
    end if
    middle = 0.5_wp * (low + high)
    call pair_ball_dense(pair, ball, middle, y, prepared)
    y(1:3) = y(1:3) / sqrt(y(1)**2 + y(2)**2 + y(3)**2)
    lateral = norm_of(y(1), y(2))
    peak%t = pair%t_old + middle * pair%h
    peak%tan_nutation = lateral / y(3)
    peak%lateral = lateral
    peak%normal_z = y(3)
    ! a maximum of Theta within the tolerance on the normal's components,
    ! atol, or a maximum and a minimum between the step's ends whose swing
    ! is within the step's tolerance, are not resolved (the ball leaving a
    ! rest at the bottom, whose law has a kink at the rest's threshold: 1e-18 rad)
    if (.not. peak%tan_nutation > pair%atol) peak%found = .false.
    if (between_ends) then
      call pair_ball_dense(pair, ball, 1.0_wp, y, prepared)
      lower_end = min(lower_end, tan_nutation(y))
      if (.not. peak%tan_nutation - lower_end > pair%atol + pair%rtol * peak%tan_nutation) peak%found = .false.
    end if
  contains
    real(wp) function trend_at(theta)
      real(wp), intent(in) :: theta
      real(wp) :: state(state_size), rate(max_equations)
      call pair_ball_dense(pair, ball, theta, state, prepared)
      call pair%dense_rate(theta, rate)
      trend_at = nutation_trend(state, rate(:state_size), factor)
    end function trend_at
  end subroutine locate_nutation_peak

  !> tan Theta at the state y (|n| need not be 1).
  pure real(wp) function tan_nutation(y)
    real(wp), intent(in) :: y(:)
    tan_nutation = norm_of(y(1), y(2)) / y(3)
  end function tan_nutation

  !> Whether a maximum of Theta inside a step lies at or past the rim
  !> (n_z <= 0): the step's ends are inside, the path between is not. Its
  !> time is where the step's dense output is known to be past the rim.
  pure logical function beyond_rim(peak)
    type(nutation_peak_t), intent(in) :: peak
    beyond_rim = .not. peak%normal_z > 0
  end function beyond_rim
end module ellroll_nutation_peaks
