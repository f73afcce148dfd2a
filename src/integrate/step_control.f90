!> The step-size control of an embedded pair (step_control_t) and the
!> judgements of an attempt it rests on: its error norm as the control takes
!> it, round-off steps, when a case cannot follow the model, and the last
!> step clipped to the end. The one-case loop, the flow to a limit and the
!> batch's lanes share them.
module ellroll_step_control
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_cases, only: max_steps
  use ellroll_integrators, only: tolerance_ratio_cap
  use ellroll_excitation, only: excitation_t, step_to_sample
  implicit none
  private

  public :: judged_norm, round_off_step, cannot_follow, next_step, smallest_step_ulps

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

  !> A step of at most smallest_step_ulps eps |t| (16 to 32 units in the
  !> last place of t, or of t_end before t reaches it; follow_flow_to_limit:
  !> 16 units of its end) or not a number is round-off: Hairer's "step size
  !> too small". Such steps
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

contains

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

  !> Whether a step h from t, in a case that ends at t_end, is round-off:
  !> at most smallest_step_ulps eps max(|t|, t_end), or not a number. (Near
  !> t = 0, eps |t| bounds no step: pure relative control of a component
  !> that is zero but for round-off accepts steps of 1e-101 s there, for ever.)
  pure logical function round_off_step(t, h, t_end)
    real(wp), intent(in) :: t, h, t_end
    if (ieee_is_nan(h)) then            ! (tested first: an ordered comparison with NaN traps)
      round_off_step = .true.
    else
      round_off_step = h <= (smallest_step_ulps * epsilon(1.0_wp)) * max(abs(t), t_end)
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

  !> The step to attempt from t: last_step_clipped's, ending at the cup's
  !> record's next sample where it would pass it (step_to_sample).
  pure real(wp) function next_step(t, h, t_end, after_rejection, excitation) result(step)
    real(wp), intent(in) :: t, h, t_end
    logical, intent(in) :: after_rejection
    type(excitation_t), intent(in) :: excitation
    step = step_to_sample(excitation, t, last_step_clipped(t, h, t_end, after_rejection))
  end function next_step

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
end module ellroll_step_control
