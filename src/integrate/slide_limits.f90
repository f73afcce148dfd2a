!> Where a case that may slide meets a model limit: an embedded pair's
!> step whose path passes a lift-off inside it (lift_inside), or whose
!> partial steps towards a limit leave its tolerance (within_tolerance_to_limit),
!> and the end of the case where the method's partial steps first meet the
!> limit (end_at_limit).
module ellroll_slide_limits
  use ellroll_kinds, only: wp, i8
  use ellroll_status, only: status_completed, status_unstable, status_rim
  use ellroll_excitation, only: excitation_none
  use ellroll_events, only: crossing_search_t, peak_search_t, max_event_trials
  use ellroll_results, only: case_result_t
  use ellroll_rolling_ball, only: observation_t, limit_status, normalize_normal
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, observe_sliding, at_sliding_rim
  use ellroll_integrators, only: integrator_t, embedded_pair_t
  use ellroll_case_run, only: run_state_t
  use ellroll_step_peaks, only: step_screen_t, screen_theta, note_screen
  use ellroll_slide_regime, only: regime_state_t, slide_tally_t, limit_time_ulps, take, track_balance, add_sliding, &
      switch_crossed
  implicit none
  private

  public :: lift_inside, within_tolerance_to_limit, end_at_limit

  !> A fixed step's partial step towards a limit is the method's own growth
  !> where it and its two halves differ by more than this (its normal, and
  !> its energy against the energy at its start).
  real(wp), parameter :: halves_tolerance = 0.1_wp

contains

  !> In a cup that moves, whether the path of an embedded pair's accepted
  !> sliding step from (t, now) of size h (its dense output), which ends
  !> inside at new, passes a limit between: a lift-off where N dips below
  !> zero and comes back within the step. N is screened at 1e-3, 1/4, 1/2,
  !> 3/4 and 1 - 1e-3 of the step and its minima refined as a rolling
  !> step's (reaction_inside: peak_search_t to 1e-6 of the step). Where the path
  !> passes a limit, the step is cut to where it is known past it (h, new
  !> and status that step's). screen: the peak quantities at those points
  !> (ellroll_step_peaks; evaluated for them alone in a fixed cup).
  subroutine lift_inside(pair, rolling, sb, t, h, now, new, status, n_rhs, screen)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t
    real(wp), intent(inout) :: h
    type(regime_state_t), intent(in) :: now
    type(regime_state_t), intent(inout) :: new
    integer, intent(inout) :: status
    integer(i8), intent(inout) :: n_rhs
    type(step_screen_t), intent(out) :: screen
    real(wp), parameter :: resolution = 1.0e-6_wp
    type(peak_search_t) :: search
    type(observation_t) :: obs
    real(wp) :: lowered(0:6), x, fx, passed     ! lowered: -N, whose maxima are N's minima
    real(wp) :: state(slide_state_size), rate(slide_state_size), slip_speed
    integer :: i
    associate (theta => screen_theta)
    call note_screen(screen, 0, now%obs)
    if (sb%ball%excitation%kind == excitation_none) then     ! (a fixed cup: N >= m g n_z)
      do i = 1, 5
        call pair%dense(sb, theta(i), state, n_rhs)
        call normalize_normal(state)
        call observe_sliding(sb, t + theta(i) * h, state, obs, slip_speed, rate)
        n_rhs = n_rhs + 1
        call note_screen(screen, i, obs)
      end do
      return
    end if
    lowered(0) = -now%obs%reaction_normal
    lowered(6) = -new%obs%reaction_normal
    passed = -1
    do i = 1, 5
      if (past(theta(i), lowered(i))) exit
      call note_screen(screen, i, obs)
    end do
    do i = 1, 5
      if (passed >= 0) exit
      if (.not. (lowered(i) >= lowered(i - 1) .and. lowered(i) >= lowered(i + 1))) cycle
      call search%start(theta(i - 1), theta(i), theta(i + 1), lowered(i - 1), lowered(i), lowered(i + 1), resolution)
      do while (.not. search%done())
        x = search%trial()
        if (past(x, fx)) exit
        call search%report(x, fx)
      end do
    end do
    if (passed < 0) return
    h = passed * h
    call take(pair, rolling, sb, t, h, now, new, status, n_rhs)
    end associate
  contains
    !> -N at theta from the dense output; true (passed set) where a limit is passed there.
    logical function past(at, lowered_at)
      real(wp), intent(in) :: at
      real(wp), intent(out) :: lowered_at
      integer :: met
      call pair%dense(sb, at, state, n_rhs)
      call normalize_normal(state)
      if (at_sliding_rim(state)) then
        met = status_rim
        lowered_at = 0
      else
        call observe_sliding(sb, t + at * h, state, obs, slip_speed, rate)
        n_rhs = n_rhs + 1
        lowered_at = -obs%reaction_normal
        met = limit_status(rolling%ball, state(1:6), obs)
      end if
      past = met /= status_completed
      if (past) passed = at
    end function past
  end subroutine lift_inside

  !> An embedded pair's step from (t, now) of size h, within its tolerance,
  !> that meets a limit (status): the partial steps towards the limit are
  !> searched (end_at_limit's bisection) for the last one within the
  !> tolerance and short of the limit. Where the tolerance, not the limit,
  !> ends that search (near the rim V_z's 1 / n_z takes a partial step's
  !> error past it), the step is cut to a partial step within it (the first
  !> at least half as long as the shortest that is not: h, new and status
  !> that step's), and the pair's steps go on from there towards the limit,
  !> so that the limit is located where the path meets it, at any
  !> tolerance. Otherwise the step is left as it is, for end_at_limit.
  subroutine within_tolerance_to_limit(pair, rolling, sb, t, h, now, new, status, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t
    real(wp), intent(inout) :: h
    type(regime_state_t), intent(in) :: now
    type(regime_state_t), intent(inout) :: new
    integer, intent(inout) :: status
    integer(i8), intent(inout) :: n_rhs
    type(crossing_search_t) :: search
    type(regime_state_t) :: x
    real(wp) :: trial
    integer :: k, met
    logical :: valid, at_limit           ! at_limit: the shortest partial step known invalid meets a limit
    at_limit = .true.
    call search%start(h, limit_time_ulps * spacing(t + h))
    do k = 1, max_event_trials
      if (search%done()) exit
      if (.not. at_limit .and. search%valid >= search%invalid / 2) exit
      trial = search%trial()
      call take(pair, rolling, sb, t, trial, now, x, met, n_rhs)
      valid = met == status_completed .and. pair%error_norm <= 1
      if (.not. valid) at_limit = met /= status_completed
      call search%report(trial, valid)
    end do
    if (at_limit .or. .not. search%valid > 0) then
      call take(pair, rolling, sb, t, h, now, new, status, n_rhs)    ! (the pair holds the step again)
      return
    end if
    h = search%valid
    call take(pair, rolling, sb, t, h, now, new, status, n_rhs)
  end subroutine within_tolerance_to_limit

  !> Whether the integrator's last step is within its tolerance (a fixed
  !> step always is).
  pure logical function within_tolerance(integrator) result(within)
    class(integrator_t), intent(in) :: integrator
    within = .true.
    select type (integrator)
    class is (embedded_pair_t)
      within = integrator%error_norm <= 1
    end select
  end function within_tolerance

  !> Whether a fixed-step method's step h from (t, now) to x agrees with
  !> the same method's two half steps (normal and energy within
  !> halves_tolerance; an embedded pair's own estimate judges its steps).
  !> Next to the rim a partial step's stages meet V_z's 1 / n_z and its end
  !> can be far off without meeting any limit.
  logical function agrees_with_halves(integrator, rolling, sb, t, h, now, x, n_rhs) result(agrees)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: now, x
    integer(i8), intent(inout) :: n_rhs
    type(regime_state_t) :: middle, halves
    integer :: status
    agrees = .true.
    select type (integrator)
    class is (embedded_pair_t)
      return
    end select
    agrees = .false.
    call take(integrator, rolling, sb, t, h / 2, now, middle, status, n_rhs)
    if (status /= status_completed) return
    call take(integrator, rolling, sb, t + h / 2, h / 2, middle, halves, status, n_rhs)
    if (status /= status_completed) return
    agrees = norm2(halves%obs%normal - x%obs%normal) <= halves_tolerance .and. &
             abs(halves%obs%energy - x%obs%energy) <= halves_tolerance * abs(now%obs%energy)
  end function agrees_with_halves

  !> The step h from (t, now) met a limit: the case ends where the method's
  !> partial steps from now first meet it (to limit_time_ulps of t), with
  !> its status; the last valid state (not only short of the limit: within
  !> an embedded pair's tolerance, or, towards the rim, agreeing with a
  !> fixed step's halves: there a partial step's stages can pass it and come
  !> back far off) adds to the summary.
  subroutine end_at_limit(integrator, run, rolling, sb, t, h, now, tally, res, switch_first, before, at_before)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    !> (where asked) the regime switches before the limit, at the last valid
    !> state (at_before, a piece `before` from now): nothing is ended or added
    logical, intent(out), optional :: switch_first
    real(wp), intent(out), optional :: before
    type(regime_state_t), intent(out), optional :: at_before
    type(crossing_search_t) :: search
    type(regime_state_t) :: x, last_valid
    real(wp) :: trial
    integer :: status, crossed, k
    logical :: valid
    call take(integrator, rolling, sb, t, h, now, x, crossed, res%n_rhs)
    last_valid = now
    call search%start(h, limit_time_ulps * spacing(t + h))
    do k = 1, max_event_trials
      if (search%done()) exit
      trial = search%trial()
      call take(integrator, rolling, sb, t, trial, now, x, status, res%n_rhs)
      valid = status == status_completed
      if (valid) valid = within_tolerance(integrator)
      if (valid .and. crossed == status_rim) valid = agrees_with_halves(integrator, rolling, sb, t, trial, now, x, &
                                                                         res%n_rhs)
      if (valid) then
        last_valid = x
      else if (status /= status_completed) then
        crossed = status
      end if
      call search%report(trial, valid)
    end do
    if (present(switch_first)) then
      switch_first = search%valid > 0
      if (switch_first) switch_first = switch_crossed(sb, now, last_valid)
      if (switch_first) then
        before = search%valid
        at_before = last_valid
        return
      end if
    end if
    if (search%valid > 0) then
      call add_sliding(sb, search%valid, now, last_valid, tally)
      call track_balance(run, res, t + search%valid, last_valid, tally)
    end if
    if (crossed == status_completed) crossed = status_unstable
    res%status = crossed
    res%t_final = t + search%valid
  end subroutine end_at_limit
end module ellroll_slide_limits
