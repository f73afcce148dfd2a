!> One case with an adaptive embedded pair (dop853, vern9): its steps
!> under the step control (ellroll_step_control), and everything taken from
!> the pair's dense output inside a step (output samples, the maxima of
!> Theta, where a model limit is crossed, the couple of rolling resistance's
!> work), so that no result depends on where the steps fall. The batches and the flow to a limit
!> (ellroll_flow_to_limit) use the same pieces.
module ellroll_adaptive_run
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero
  use ellroll_status, only: status_pending, status_completed, status_no_fit, status_rim, status_unstable, status_slip
  use ellroll_cases, only: case_t, output_plan_t, field_reaction, field_energy, field_base_acceleration
  use ellroll_results, only: case_result_t
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, observe, limit_status, &
      ball_derivative, normalize_normal
  use ellroll_events, only: event_search_t, peak_search_t, max_event_trials
  use ellroll_excitation, only: excitation_none, longest_step
  use ellroll_turns, only: turn_resolved
  use ellroll_integrators, only: embedded_pair_t
  use ellroll_ball_lanes, only: lanes
  use ellroll_ball_steppers, only: pair_ball_step, pair_ball_dense
  use ellroll_case_run, only: run_state_t, limit_search_t, sample_due, stop_asked, track, track_step_end, note_nutation, &
      accumulate, record_sample, record_geometry_sample, reach_stop, settled, add_step_resistance, track_rolling_resistance, &
      track_pair_step
  use ellroll_step_works, only: step_works
  use ellroll_quantities, only: q_displacement
  use ellroll_running, only: unset
  use ellroll_step_peaks, only: step_screen_t, note_screen, screen_step, add_step_peaks, may_peak_inside, &
      peak_quantities, dense_observation, peak_count, peak_values, time_beyond_inside, add_clearance_crossing
  use ellroll_step_control, only: step_control_t, judged_norm, round_off_step, cannot_follow, next_step
  use ellroll_params, only: p_dt
  use ellroll_nutation_peaks, only: nutation_peak_t, nutation_peak_inside, locate_nutation_peak, beyond_rim
  implicit none
  private

  public :: adaptive_loop, attempt_step
  public :: project_with_rate, stop_in_step, record_samples_until
  public :: reaction_inside, locate_crossing, end_at_crossing, screen_and_peaks, project_lanes

contains

  !> An embedded pair with its step-size control (step_control_t): accept
  !> when the error norm <= 1, never a step above dt (the largest step
  !> allowed). Output samples, limit crossings and the maxima of Theta come
  !> from the dense output, so that they do not depend on where the steps
  !> fall; a sample computes only what the stored fields need. The steps are
  !> the fused ones of the ball (ellroll_ball_steppers). A case that may
  !> slide rolls here from t_start (its rolling pieces) and, where the
  !> friction needed passes mu N (located as slip = 'end' ends the case),
  !> returns slipped with res%status slip, res%t_final the switch's time and
  !> y the state there (f is not set).
  subroutine adaptive_loop(pair, cs, plan, run, y, f, res, t_start, slipped)
    class(embedded_pair_t), intent(inout) :: pair
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    real(wp), intent(inout) :: y(state_size), f(state_size)
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in), optional :: t_start
    logical, intent(out), optional :: slipped
    real(wp) :: y_new(state_size), f_new(state_size), t, h, h_max
    real(wp) :: t_stop                    ! t_end, then, settling, latest_end
    type(observation_t) :: obs
    type(nutation_peak_t) :: peak
    type(step_control_t) :: control
    type(step_screen_t) :: screen
    integer :: status, round_off_attempts
    logical :: peak_inside, done, screened
    real(wp) :: passed                    ! where a slip inside a step is known
    real(wp) :: works(2)                  ! the friction's (0) and the couple's over the step

    t = 0
    if (present(t_start)) t = t_start
    if (present(slipped)) slipped = .false.
    round_off_attempts = 0
    h_max = min(cs%param(p_dt), longest_step(run%ball%excitation))
    control%order = pair%control_order()
    call pair%initial_step(run%ball, t, y, f, h_max, h, res%n_rhs)
    t_stop = cs%t_end
    do
      call reach_stop(cs, run, t, t_stop, done)       ! (past t_end, settle: on until the ball is at rest)
      if (done) exit
      if (stop_asked(res%n_steps + res%n_rejected)) then
        res%status = status_pending
        return
      end if
      h = next_step(t, h, t_stop, control%after_rejection, run%ball%excitation)
      if (round_off_step(t, h, cs%t_end)) round_off_attempts = round_off_attempts + 1
      if (cannot_follow(h, round_off_attempts, res%n_steps + res%n_rejected)) then
        res%status = status_unstable
        res%t_final = t
        return
      end if
      if (run%ball%nonsmooth()) call run%ball%begin_step(y)
      call attempt_step(pair, control, run, t, y, f, h, y_new, f_new, obs, status, res)
      if (pair%error_norm > 1) then
        res%n_rejected = res%n_rejected + 1
        cycle
      end if
      if (status /= status_completed) then
        call end_in_step(status)
        return
      end if
      peak_inside = nutation_peak_inside(y, f, y_new, f_new, h)
      if (peak_inside) then
        call locate_nutation_peak(pair, run%ball, peak, res%n_rhs)
        peak_inside = peak%found
        if (beyond_rim(peak)) then
          call end_in_step(status_rim, peak%t - t)
          return
        end if
      end if
      screened = run%ball%reaction_limited() .or. may_peak_inside(run%ball, h, y, f, y_new, f_new, &
                                                                   run%stats%clear_maximum(1, peak_quantities))
      call screen_and_peaks(pair, run, y, f, obs%friction_needed, obs%reaction_normal, screened, status, passed, &
                            screen, res%n_rhs, run%stats%clear_maximum(1, peak_quantities), peak_values(obs))
      if (status /= status_completed) then
        call end_in_step(status, passed)
        return
      end if
      call add_clearance_crossing(pair, run%ball, obs%fit_clearance, 1.0_wp, res%n_rhs, run%stats)
      if (screened) then
        call note_screen(screen, 6, obs)
        call add_step_peaks(pair, run%ball, screen, res%n_rhs, run%stats)
      end if
      call record_samples_until(pair, run, plan, t + h, obs, res)
      if (peak_inside) call note_nutation(run, res, peak%tan_nutation, peak%lateral, peak%normal_z)
      call track_pair_step(run, y, f, y_new, f_new, t + h, peak_inside, peak, pair%atol, pair%rtol)
      if (run%ball%rolling_resistance > 0) then
        ! the couple's power varies inside the long step: its work by the
        ! Gauss-Legendre rule on the dense output, not the step ends' trapezoid
        call step_works(pair, run%ball, t, h, works, res%n_rhs)
        call add_step_resistance(run, res, t + h, works(2), obs)
      end if
      if (.not. round_off_step(t, h, cs%t_end)) round_off_attempts = 0
      t = t + h
      y = y_new
      f = f_new
      res%n_steps = res%n_steps + 1
      call track_accepted_end(pair, run, res, t, obs)
      call control%accept(h, pair%error_norm, h_max)
      if (t_stop > cs%t_end) then
        if (settled(run, t)) then
          res%t_final = t
          return
        end if
      end if
    end do
    res%t_final = t_stop
  contains
    !> The case ends inside the last attempt at the limit (status) met first
    !> (stop_in_step); where it may slide, a slip hands the state over.
    subroutine end_in_step(status, invalid)
      integer, intent(in) :: status
      real(wp), intent(in), optional :: invalid
      if (.not. present(slipped)) then
        call stop_in_step(pair, run, plan, status, res, invalid)
        return
      end if
      call stop_in_step(pair, run, plan, status, res, invalid, y)
      slipped = res%status == status_slip
    end subroutine end_in_step
  end subroutine adaptive_loop

  !> One attempt of size h from (t, y, f), its RHS calls counted in
  !> res. Rejected (pair%error_norm > 1, a non-finite norm made huge): h is
  !> shrunk by the step control. Accepted: the new state projected, f and the derived
  !> outputs there, and the model's limit status. An attempt in which an
  !> event of the model happens (event_crossed) is cut there first
  !> (shorten_to_event) and, accepted, ends where the model acted
  !> (apply_event): an event, not a discontinuity inside a step for the
  !> step control to shrink around. A rolling that turned there at a rate
  !> the couple takes a tenth of the step or more to stop (turn_resolved)
  !> goes on from there along its new direction.
  !> What the accepted step of the pair to t (its end's observation obs)
  !> adds to the summary (track_step_end), its time beyond the capacity
  !> taken on its dense output (time_beyond_inside), where one is set.
  subroutine track_accepted_end(pair, run, res, t, obs)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    real(wp) :: before, r_start, inside
    associate (stats => run%stats, q => q_displacement)
      if (.not. stats%threshold(1, q) < unset) then
        call track_step_end(run, res, t, obs)
        return
      end if
      before = stats%time_beyond(1, q)
      r_start = stats%value_before(1, q)
      call track_step_end(run, res, t, obs)
      call time_beyond_inside(pair, run%ball, stats%threshold(1, q), r_start, stats%value_before(1, q), inside, &
                              res%n_rhs)
      stats%time_beyond(1, q) = before + inside
    end associate
  end subroutine track_accepted_end

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
    if (ieee_is_finite(pair%error_norm) .and. run%ball%nonsmooth()) then
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
      if (turn_resolved(run%ball, t + h, y_new, f_new, h, pair%atol + pair%rtol)) then
        call run%ball%begin_step(y_new)          ! the rolling turned in 3D: on along its new direction
      else
        call run%ball%apply_event(event, y_new)
      end if
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

  !> Every lane's attempt's end y_raw back onto the model's manifold, with
  !> its rate from the end stage (project_with_rate).
  pure subroutine project_lanes(y_raw, rate, y_new, f_new)
    real(wp), dimension(lanes, state_size), intent(in) :: y_raw, rate
    real(wp), dimension(lanes, state_size), intent(out) :: y_new, f_new
    real(wp), dimension(state_size) :: y_lane, f_lane, rate_lane
    integer :: l
    do l = 1, lanes
      y_lane = y_raw(l, :)
      rate_lane = rate(l, :)
      call project_with_rate(y_lane, rate_lane, f_lane)
      y_new(l, :) = y_lane
      f_new(l, :) = f_lane
    end do
  end subroutine project_lanes

  !> The last attempt (in pair) crossed a limit (status): bisect on its dense
  !> output, record the output samples before the crossing, and end the
  !> case at the last valid point. invalid: the offset from the step's
  !> start known to be past the limit (default: its end). at: the state at
  !> the last valid point (the case's end), where asked for.
  subroutine stop_in_step(pair, run, plan, status, res, invalid, at)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: run
    type(output_plan_t), intent(in) :: plan
    integer, intent(in) :: status
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in), optional :: invalid
    real(wp), intent(inout), optional :: at(state_size)
    type(limit_search_t) :: search
    call locate_crossing(pair, run, status, search, res%n_rhs, invalid)
    call record_samples_until(pair, run, plan, pair%t_old + search%valid, search%last_trial, res)
    if (search%found_valid) then
      call add_clearance_crossing(pair, run%ball, search%last_valid%fit_clearance, search%valid / pair%h, res%n_rhs, &
                                  run%stats)
      call track_piece(pair, run, search%valid, search%last_valid, res)
    end if
    call end_at_crossing(pair, run, search, res)
    res%n_steps = res%n_steps + 1
    if (present(at) .and. search%found_valid) call dense_point(pair, run, search%valid / pair%h, at, res%n_rhs)
  end subroutine stop_in_step

  !> What the piece [t_old, t_old + part] of the last attempt (in pair), at
  !> whose end (obs) the case stops, adds: a maximum of Theta inside it, and
  !> the couple of rolling resistance's work over it (step_works on that
  !> part of the step).
  subroutine track_piece(pair, run, part, obs, res)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: part
    type(observation_t), intent(in) :: obs
    type(case_result_t), intent(inout) :: res
    type(nutation_peak_t) :: peak
    real(wp) :: works(2)
    logical :: inside
    if (.not. part > 0) return
    call locate_nutation_peak(pair, run%ball, peak, res%n_rhs, part / pair%h, inside)
    if (inside .and. peak%found) then
      call run%maxima%add_located(peak%t, peak%tan_nutation, pair%atol + pair%rtol * peak%tan_nutation)
      call note_nutation(run, res, peak%tan_nutation, peak%lateral, peak%normal_z)
    end if
    if (run%ball%rolling_resistance > 0) then
      call step_works(pair, run%ball, pair%t_old, part, works, res%n_rhs)
      call add_step_resistance(run, res, pair%t_old + part, works(2), obs)
      call track_rolling_resistance(run, res, pair%t_old + part, obs)
    end if
  end subroutine track_piece

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
      call dense_observation(pair, run%ball, offset / pair%h, .true., obs, n_rhs)
      call search%record(offset, limit_status(run%ball, [obs%normal, obs%omega], obs), obs)
    end do
  end subroutine locate_crossing

  !> With a limit of the reaction (mu > 0, or a cup that moves:
  !> reaction_limited): whether the path inside the last attempt (in pair),
  !> from (y, f) at its start to its end (friction_end needed and normal
  !> force normal_end there), both inside, passes the limit. The friction
  !> needed and N are smooth along the path, and where a slip or a lift-off
  !> only grazes the limit the friction's maximum or N's minimum is narrow:
  !> a step can begin and end inside and pass the limit between. Both are
  !> evaluated on the dense output at 1e-3, 1/4, 1/2, 3/4 and 1 - 1e-3 of
  !> the step (a step in a harmonically shaken cup is half a period at most:
  !> longest_step); each maximum of the friction (mu > 0) and each minimum
  !> of N (a moving cup: in a fixed one N >= m g n_z) among these and the
  !> ends that lies inside is refined, in time order, by successive
  !> parabolas (peak_search_t) to 1e-6 of the step. (One within 1e-3 of the
  !> step from an end shows as a rise to it at the end.) status:
  !> status_completed, or the limit met where the dense output passes it,
  !> at offset from the step's start (for locate_crossing). Its RHS calls
  !> count in n_rhs. screen: the peak quantities at the points evaluated
  !> (ellroll_step_peaks), where asked for.
  subroutine reaction_inside(pair, run, y, f, friction_end, normal_end, status, offset, n_rhs, screen)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: y(state_size), f(state_size), friction_end, normal_end
    integer, intent(out) :: status
    real(wp), intent(out) :: offset
    integer(i8), intent(inout) :: n_rhs
    type(step_screen_t), intent(inout), optional :: screen
    real(wp), parameter :: resolution = 1.0e-6_wp, near_end = 1.0e-3_wp
    real(wp), parameter :: theta(0:6) = [0.0_wp, near_end, 0.25_wp, 0.5_wp, 0.75_wp, 1 - near_end, 1.0_wp]
    type(observation_t) :: obs
    real(wp) :: friction(0:6), lowered(0:6)       ! lowered: -N, whose maxima are N's minima
    logical :: slips, lifts
    integer :: i
    status = status_completed
    offset = 0
    slips = run%ball%mu > 0
    lifts = run%ball%excitation%kind /= excitation_none
    call observe(run%ball, pair%t_old, y, f, obs)
    if (present(screen)) call note_screen(screen, 0, obs)
    friction(0) = obs%friction_needed
    lowered(0) = -obs%reaction_normal
    friction(6) = friction_end
    lowered(6) = -normal_end
    do i = 1, 5
      if (trial(theta(i), friction(i), lowered(i))) return
      if (present(screen)) call note_screen(screen, i, obs)
    end do
    do i = 1, 5
      if (slips .and. friction(i) >= friction(i - 1) .and. friction(i) >= friction(i + 1)) then
        if (peak_passes(theta(i - 1:i + 1), friction(i - 1:i + 1), .true.)) return
      end if
      if (lifts .and. lowered(i) >= lowered(i - 1) .and. lowered(i) >= lowered(i + 1)) then
        if (peak_passes(theta(i - 1:i + 1), lowered(i - 1:i + 1), .false.)) return
      end if
    end do
  contains
    !> The friction needed and -N at theta; true where the dense output passes a limit there.
    logical function trial(at, friction_at, lowered_at)
      real(wp), intent(in) :: at
      real(wp), intent(out) :: friction_at, lowered_at
      call dense_observation(pair, run%ball, at, .true., obs, n_rhs)
      friction_at = obs%friction_needed
      lowered_at = -obs%reaction_normal
      status = limit_status(run%ball, [obs%normal, obs%omega], obs)
      trial = status /= status_completed
      if (trial) offset = at * pair%h
    end function trial

    !> The maximum of the friction (of_friction) or of -N bracketed at the
    !> offsets at(2) (values: theirs), refined until it passes a limit
    !> (true) or the bracket is resolution wide.
    logical function peak_passes(at, values, of_friction) result(passes)
      real(wp), intent(in) :: at(3), values(3)
      logical, intent(in) :: of_friction
      type(peak_search_t) :: search
      real(wp) :: x, fx, other
      call search%start(at(1), at(2), at(3), values(1), values(2), values(3), resolution)
      passes = .false.
      do while (.not. search%done())
        x = search%trial()
        if (of_friction) then
          passes = trial(x, fx, other)
        else
          passes = trial(x, other, fx)
        end if
        if (passes) return
        call search%report(x, fx)
      end do
    end function peak_passes
  end subroutine reaction_inside

  !> The path inside the last attempt (in pair) from (y, f) checked against
  !> the reaction's limits where it has them (reaction_inside: status,
  !> offset), and where asked for (screened) the screen of its peak
  !> quantities (ellroll_step_peaks) at the interior points, those
  !> reaction_inside evaluates where it runs.
  subroutine screen_and_peaks(pair, run, y, f, friction_end, normal_end, screened, status, offset, screen, n_rhs, &
                              above, finish)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: y(state_size), f(state_size), friction_end, normal_end
    logical, intent(in) :: screened
    integer, intent(out) :: status
    real(wp), intent(out) :: offset
    type(step_screen_t), intent(inout) :: screen
    integer(i8), intent(inout) :: n_rhs
    !> the running maxima of the peak quantities and their values at the
    !> step's end (screen_step's bound)
    real(wp), intent(in) :: above(peak_count), finish(peak_count)
    status = status_completed
    offset = 0
    screen%none = .false.          ! (a batch's screen serves lane after lane)
    if (run%ball%reaction_limited()) then
      call reaction_inside(pair, run, y, f, friction_end, normal_end, status, offset, n_rhs, screen)
    else if (screened) then
      call screen_step(pair, run%ball, y, f, screen, n_rhs, above, finish)
    end if
  end subroutine screen_and_peaks

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
        call dense_observation(pair, run%ball, theta, plan%fields(field_reaction), obs, res%n_rhs)
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
end module ellroll_adaptive_run
