!> The exact flow of the model followed to where it meets a limit: from a
!> fixed-step method's state, with the reference pair at its tight
!> tolerances (follow_flow_to_limit), so that a case's end time has the
!> method's error up to that state only. The reference method and
!> tolerances are also those of the error figures (error_estimate).
module ellroll_flow_to_limit
  use ellroll_kinds, only: wp, i8
  use ellroll_status, only: status_completed, status_no_fit, status_rim
  use ellroll_cases, only: output_plan_t
  use ellroll_results, only: case_result_t
  use ellroll_rolling_ball, only: observation_t, state_size, ball_derivative, observe
  use ellroll_step_peaks, only: clearance_crossing, peak_count, peak_quantities
  use ellroll_running, only: add_inside
  use ellroll_errors, only: error_t
  use ellroll_integrators, only: embedded_pair_t, new_pair
  use ellroll_case_run, only: run_state_t, limit_search_t, track, stop_asked
  use ellroll_excitation, only: longest_step
  use ellroll_step_control, only: step_control_t, next_step, smallest_step_ulps
  use ellroll_adaptive_run, only: attempt_step, locate_crossing, record_samples_until, end_at_crossing, reaction_inside
  use ellroll_nutation_peaks, only: nutation_peak_t, nutation_peak_inside, locate_nutation_peak, beyond_rim
  implicit none
  private

  public :: follow_flow_to_limit, reference_method, reference_rtol, reference_atol

  !> Method and tolerances of a reference solution: the run behind the error
  !> figures (error_estimate), and the exact flow followed from a fixed-step
  !> method's last state to the limit its step met. Verner's pair reaches
  !> these tolerances in fewer RHS calls and less time than DOP853, with a
  !> smaller error (bench/pairs.py).
  character(len=*), parameter :: reference_method = 'vern9'
  real(wp), parameter :: reference_rtol = 1.0e-12_wp, reference_atol = 1.0e-14_wp

  !> The most steps the flow to a limit takes before it gives up (met =
  !> .false.). Its span, at most 2 checkpoints and 2 steps of the method,
  !> takes at most 90 steps on the tests' cases and 54 on input/ (measured).
  !> Where the ball's radius is within about 1e-4 of two equal principal
  !> radii of the cup (a sphere, the bottom of a cup with a = b), det L's
  !> round-off makes the steps creep (docs/accuracy.md, "Near-fit balls on
  !> equal radii"): the cap bounds the time and the memory (untracked).
  integer, parameter :: max_flow_steps = 2000

  !> What the flow's steps add to the summary, held until the flow is known
  !> to meet a limit: its step ends after the method's last state, and the
  !> points where its path's clearance of the cup's curvature changes sign
  !> (their peak values: clearance_crossing).
  type :: held_t
    integer :: n = 0
    type(observation_t), allocatable :: obs(:)
    real(wp), allocatable :: t(:), crossing_t(:), crossing_values(:, :)
  end type held_t

contains

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
  !> samples. So too where it takes max_flow_steps steps without meeting a
  !> limit, or the run is asked to stop (the caller's fixed steps then fail
  !> at once: stopping). Its RHS calls count in the case's n_rhs (n_rejected
  !> is the adaptive method's own).
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
    type(held_t) :: held
    logical :: clear
    real(wp) :: t_at, y_at(state_size), f_at(state_size), y_new(state_size), f_new(state_size), h, passed, h_max
    integer :: status, n_accepted
    integer(i8) :: n_attempts
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
    call observe(run%ball, t_at, y_at, f_at, obs)
    clear = obs%fit_clearance > 0
    control%order = pair%control_order()
    h_max = min(t_until - t_from, longest_step(run%ball%excitation))
    call pair%initial_step(run%ball, t_at, y_at, f_at, h_max, h, res%n_rhs)
    allocate (held%obs(64), held%t(64), held%crossing_t(0), held%crossing_values(peak_count, 0))
    n_accepted = 0
    n_attempts = 0
    do while (t_at < t_until)
      if (t_until - t_at <= 16 * spacing(t_until)) exit
      n_attempts = n_attempts + 1
      if (stop_asked(n_attempts) .or. n_accepted >= max_flow_steps) exit
      if (h <= 16 * spacing(t_until)) then          ! the fit limit's singularity (above)
        met = .true.
        call release(held, run, res)
        res%status = status_no_fit
        res%t_final = t_at
        return
      end if
      h = next_step(t_at, h, t_until, control%after_rejection, run%ball%excitation)
      if (.not. (h > smallest_step_ulps * spacing(t_until))) exit       ! (NaN: no step either)
      if (run%ball%nonsmooth()) call run%ball%begin_step(y_at)
      call attempt_step(pair, control, run, t_at, y_at, f_at, h, y_new, f_new, obs, status, res)
      if (pair%error_norm > 1) cycle
      if (status /= status_completed) then
        call end_in_attempt()
        return
      end if
      passed = -1
      if (nutation_peak_inside(y_at, f_at, y_new, f_new, h)) then
        call locate_nutation_peak(pair, run%ball, peak, res%n_rhs)
        if (beyond_rim(peak)) then
          status = status_rim
          passed = peak%t - t_at
        end if
      end if
      if (passed < 0 .and. run%ball%reaction_limited()) &
        call reaction_inside(pair, run, y_at, f_at, obs%friction_needed, obs%reaction_normal, status, passed, res%n_rhs)
      if (status /= status_completed) then        ! the path passed a limit inside the step
        call end_in_attempt(passed)
        return
      end if
      n_accepted = n_accepted + 1
      call note_crossing(obs%fit_clearance, 1.0_wp)
      t_at = t_at + h
      y_at = y_new
      f_at = f_new
      ! the summary takes these only once the flow is known to meet a limit
      if (t_at > t_tracked) then
        call hold_step_end(held, t_at, obs)
        call record_samples_until(pair, run, plan, t_at, obs, res)
      end if
      call control%accept(h, pair%error_norm, h_max)
    end do
    res%n_recorded = n_recorded          ! the flow stayed inside: its samples are not the case's
  contains
    !> The limit met in the last attempt (at its end, or known past it at
    !> offset invalid) located, and the case ended there.
    subroutine end_in_attempt(invalid)
      real(wp), intent(in), optional :: invalid
      met = .true.
      call locate_crossing(pair, run, status, search, res%n_rhs, invalid)
      if (search%found_valid) call note_crossing(search%last_valid%fit_clearance, search%valid / pair%h)
      call release(held, run, res)
      call record_samples_until(pair, run, plan, pair%t_old + search%valid, search%last_trial, res)
      call end_at_crossing(pair, run, search, res)
    end subroutine end_in_attempt

    !> Where the path's clearance of the cup's curvature changes sign in the
    !> last attempt up to theta_end of it (its clearance there: clearance_end),
    !> kept for the summary's peaks (as add_clearance_crossing): also before
    !> t_tracked, where the method's steps end on either side of it.
    subroutine note_crossing(clearance_end, theta_end)
      real(wp), intent(in) :: clearance_end, theta_end
      real(wp) :: t, values(peak_count)
      if (clear .eqv. clearance_end > 0) return
      call clearance_crossing(pair, run%ball, clear, theta_end, t, values, res%n_rhs)
      clear = clearance_end > 0
      held%crossing_t = [held%crossing_t, t]
      held%crossing_values = reshape([held%crossing_values, values], [peak_count, size(held%crossing_t)])
    end subroutine note_crossing
  end subroutine follow_flow_to_limit

  pure subroutine hold_step_end(held, t, obs)
    type(held_t), intent(inout) :: held
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    if (held%n == size(held%t)) then
      held%obs = [held%obs, held%obs]
      held%t = [held%t, held%t]
    end if
    held%n = held%n + 1
    held%obs(held%n) = obs
    held%t(held%n) = t
  end subroutine hold_step_end

  !> What the flow held into the summary.
  pure subroutine release(held, run, res)
    type(held_t), intent(in) :: held
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    integer :: i, j
    do i = 1, held%n
      call track(run, res, held%t(i), held%obs(i))
    end do
    do i = 1, size(held%crossing_t)
      do j = 1, peak_count
        call add_inside(run%stats, peak_quantities(j), held%crossing_values(j, i), held%crossing_t(i), .true.)
      end do
    end do
  end subroutine release
end module ellroll_flow_to_limit
