!> Batches of up to `lanes` cases, one per SIMD lane
!> (ellroll_ball_lanes): the steps, the observations, the summary and
!> the embedded pairs' dense-output stages of all lanes at once; what happens to one
!> lane alone (its interpolant, a crossed limit, a maximum of Theta) is the
!> one-case code on that lane. A lane's cup may move: the cups'
!> accelerations at each stage's time come from ellroll_excitation_lanes.
module ellroll_batch_run
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero
  use ellroll_status, only: status_pending, status_completed, status_no_fit, status_rim, status_unstable
  use ellroll_cases, only: case_t, output_plan_t, steps_per_sample, make_ball
  use ellroll_results, only: case_result_t
  use ellroll_figures, only: fig_rolling_resistance_energy
  use ellroll_quantities, only: q_friction_needed, q_energy, q_reaction_normal, q_fit_clearance
  use ellroll_rolling_ball, only: observation_t, state_size, event_rest, law_exact
  use ellroll_lane_laws, only: choose_lane_laws, exact_lane_ends
  use ellroll_errors, only: error_t
  use ellroll_integrators, only: integrator_t, embedded_pair_t, new_integrator, method_info_t, method_info, max_pair_stages
  use ellroll_ball_steppers, only: lanes_fixed_step, lanes_pair_attempt, lanes_pair_dense_stages
  use ellroll_ball_lanes, only: lanes, ball_lanes_t, lane_outputs_t, set_lane, lanes_observe, runs_in_lanes, &
      lanes_rolling_stops, lanes_at_rest, keep_accepted
  use ellroll_excitation_lanes, only: excitation_lanes_t
  use ellroll_excitation, only: longest_step
  use ellroll_lane_records, only: block_samples, lane_summary_t, lane_sample_block_t
  use ellroll_case_run, only: run_state_t, start_case, finish_case, sample_due, stop_asked, track_cup_motion, &
      track_rolling_resistance, settled, regular_steps, last_fixed_step, fixed_step_time, track_pair_step
  use ellroll_fixed_step_run, only: end_at_limit, checkpoint_steps, step_through_event
  use ellroll_nutation_peaks, only: nutation_peak_t, nutation_peak_inside, locate_nutation_peak, beyond_rim
  use ellroll_adaptive_run, only: stop_in_step, record_samples_until, screen_and_peaks, project_lanes
  use ellroll_step_peaks, only: step_screen_t, note_screen_end, add_step_peaks, may_peak_inside, peak_quantities, &
      add_clearance_crossing
  use ellroll_step_control, only: step_control_t, next_step, round_off_step, cannot_follow, judged_norm
  use ellroll_params, only: p_atol, p_dt, p_rtol, p_velocity_x
  implicit none
  private

  public :: lanes, batchable, lane_result_stands, simulate_batch

  !> A batch's lanes: each lane's case state, the lanes' model and cups'
  !> motions, summary, state and derivative, which lanes still run, how
  !> many hold a case and the case that idle lanes copy.
  type :: batch_t
    type(run_state_t) :: run(lanes)
    type(ball_lanes_t) :: balls
    type(excitation_lanes_t) :: cups
    type(lane_summary_t) :: summary
    real(wp), dimension(lanes, state_size) :: y, f
    logical :: active(lanes) = .false.
    integer :: n = 0, donor = 0
  end type batch_t

contains

  !> Whether a case runs in a batch (simulate_batch): its method batches
  !> (the method table), its model runs in lanes (runs_in_lanes), it has
  !> no reference run and it does not start sliding (&initial velocity); a
  !> property of the case alone, so that every run and every shard takes the
  !> same path for it. A case that may slide rolls in its lane as with slip
  !> = 'end' (status slip where its friction reaches mu N): lane_result_stands.
  pure logical function batchable(cs)
    type(case_t), intent(in) :: cs
    type(method_info_t) :: method
    method = method_info(cs%method)
    batchable = method%batches .and. .not. cs%error_estimate
    if (batchable .and. cs%slide) batchable = ieee_is_nan(cs%param(p_velocity_x))
    if (batchable) batchable = runs_in_lanes(make_ball(cs), fixed_steps=.not. method%adaptive)
  end function batchable

  !> Whether a batched case's result (res) is its own: a case that may slide
  !> (slip = 'slide') and did not complete its lane (it slipped, or met a
  !> limit that sliding would have met otherwise) is the one-case path's to
  !> run again from t = 0, so its whole result is that path's, bitwise.
  pure logical function lane_result_stands(cs, res)
    type(case_t), intent(in) :: cs
    type(case_result_t), intent(in) :: res
    lane_result_stands = .not. cs%slide .or. res%status == status_completed .or. res%status == status_pending
  end function lane_result_stands

  !> Up to `lanes` batchable cases of one method advanced together, one per
  !> SIMD lane (ellroll_ball_lanes): steps, f, the summary's quantities, the
  !> stored outputs and the limits for all lanes at once, each lane with its
  !> own step; maxima of Theta, dense output and the search for a crossed
  !> limit per lane with the one-case code. Each step equals simulate_case's
  !> to round-off: RK4's results agree to round-off, an embedded pair's
  !> until a step decision falls within it and the two runs part, then to
  !> the tolerance (tested); whatever the other lanes hold, bitwise the same.
  !> wall_time is the batch's time shared equally among its cases.
  subroutine simulate_batch(cases, plan, results)
    type(case_t), intent(in) :: cases(:)
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: results(:)
    type(batch_t) :: b
    class(integrator_t), allocatable :: method
    class(embedded_pair_t), allocatable :: pairs(:)
    type(error_t) :: err
    ! one lane's row, contiguous, for the one-case routines (explicit-shape arguments)
    real(wp), dimension(state_size) :: y_lane, f_lane
    integer(i8) :: clock_start, clock_end, clock_rate
    integer :: l

    b%n = size(cases)
    if (b%n == 0) return
    associate (run => b%run, balls => b%balls, summary => b%summary, y => b%y, f => b%f, active => b%active, &
               n => b%n, donor => b%donor)
      call system_clock(clock_start, clock_rate)
      do l = 1, n
        call start_case(cases(l), plan, run(l), results(l), y_lane, f_lane)
        y(l, :) = y_lane
        f(l, :) = f_lane
        call set_lane(balls, l, run(l)%ball)
        call b%cups%set(l, run(l)%ball%excitation)
        call summary%load(l, run(l))
        active(l) = results(l)%status == status_completed .and. cases(l)%t_end > 0
      end do
      active(n + 1:) = .false.
      ! a lone case: its lane alone computed (the idle lanes' work is a
      ! batch of 1's whole cost otherwise)
      if (n == 1) balls%width = 1
      ! idle lanes compute a valid case's steps alongside, never a state outside the model
      donor = findloc(active, .true., dim=1)
      if (donor > 0) then
        do l = 1, lanes
          if (active(l)) cycle
          call set_lane(balls, l, run(donor)%ball)
          call b%cups%set(l, run(donor)%ball%excitation)
          y(l, :) = y(donor, :)
          f(l, :) = f(donor, :)
        end do
        call new_integrator(trim(cases(1)%method), method, err)    ! (batchable: a row of the table)
        select type (method)
        class is (embedded_pair_t)
          allocate (pairs(lanes), mold=method)
          call adaptive_lanes(b, pairs, cases, plan, results)
        class default
          call fixed_step_lanes(b, method, cases, plan, results)
        end select
        where (active(:n)) results(:n)%status = status_pending      ! the run was asked to stop
      end if

      call system_clock(clock_end)
      do l = 1, n
        call finish_case(cases(l), run(l), results(l))
        results(l)%wall_time = real(clock_end - clock_start, wp) / real(clock_rate, wp) / n
      end do
    end associate
  end subroutine simulate_batch

  !> A fixed-step method with each case's dt (fixed_step_loop across lanes):
  !> with rolling resistance, each lane's mode for the step from its start
  !> (lanes_rolling_mode), a step in which its rolling stops taken again
  !> through the rest event on the one-case code (rest_events), and a case
  !> that settles runs past t_end until the ball is at rest (n_last).
  subroutine fixed_step_lanes(b, integrator, cases, plan, results)
    type(batch_t), intent(inout) :: b
    class(integrator_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cases(:)
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(inout) :: results(:)
    type(lane_outputs_t) :: out
    type(lane_sample_block_t), allocatable :: samples    ! (139 kB: on the heap; a thread's stack may be 256 KiB)
    real(wp), dimension(lanes, state_size) :: y_new, f_new, f_start, y_checkpoint, y_older_checkpoint
    real(wp), dimension(lanes, 3) :: base_end
    real(wp) :: h(lanes), t
    integer(i8) :: n_steps(lanes), n_last(lanes), every(lanes), step
    ! each lane's next step that is a multiple of its every, and its last
    ! step with an output sample ((n_samples - 1) every)
    integer(i8) :: due(lanes), last_sample(lanes)
    logical :: accepted(lanes), inside(lanes), sample_now(lanes), passed(lanes)
    integer :: i, l
    real(wp), dimension(state_size) :: y_lane, f_lane, checkpoint_lane, y_new_lane, f_new_lane
    associate (run => b%run, balls => b%balls, summary => b%summary, y => b%y, f => b%f, active => b%active, &
               n => b%n, donor => b%donor)
      do l = 1, lanes
        i = merge(l, donor, active(l))
        h(l) = cases(i)%param(p_dt)
        n_steps(l) = regular_steps(cases(i))
        n_last(l) = last_fixed_step(cases(i), run(i))
        every(l) = steps_per_sample(cases(i), plan)
        if (l <= n) active(l) = active(l) .and. n_last(l) > 0
      end do
      due = every
      last_sample = (plan%n_samples - 1) * every
      allocate (samples)
      samples%fields = plan%fields
      base_end = 0
      step = 0
      y_checkpoint = y
      y_older_checkpoint = y
      do while (any(active))
        step = step + 1
        if (stop_asked(step)) exit
        call step_lanes(b, integrator, step, h, f_start, y_new, f_new, inside, out, base_end, results)
        if (balls%resists) call rest_events(b, integrator, real(step - 1, wp) * h, h, f_start, y_new, f_new, inside, out, &
                                            base_end, results)
        accepted = active .and. inside .and. out%status == status_completed
        passed = .false.
        if (any(active .and. .not. accepted)) call meet_limits()
        if (.not. balls%resists) call summary%add(out, step * h, accepted)
        if (b%cups%moving) call track_cups(b, out, base_end, step * h, accepted)
        if (balls%resists) call track_resistance(b, out, y_new, f_new, step * h, accepted, results)
        if (any(plan%fields)) then
          ! the steps that are multiples of every (sample_due) counted up, not divided out
          sample_now = accepted .and. step == due .and. step <= last_sample
          where (step == due) due = due + every
          if (any(sample_now)) call samples%add(out, y_new, balls%radius, base_end, sample_now)
        end if
        do l = 1, n
          if (.not. active(l)) cycle
          if (.not. passed(l)) results(l)%n_rhs = results(l)%n_rhs + 4
          results(l)%n_steps = step
          t = step * h(l)
          call run(l)%maxima%add(t, out%tan_nutation(l))
          if (step == n_last(l) .or. (step >= n_steps(l) .and. n_last(l) > n_steps(l) .and. settled(run(l), t))) then
            call samples%flush(l, results(l))
            results(l)%t_final = fixed_step_time(cases(l), step, t)
            call summary%store(l, run(l), results(l))
            active(l) = .false.
          else if (samples%count(l) == block_samples) then
            call samples%flush(l, results(l))
          end if
        end do
        call keep_accepted(y, f, y_new, f_new, accepted)
        if (mod(step, checkpoint_steps) == 0) then
          y_older_checkpoint = y_checkpoint
          y_checkpoint = y
        end if
      end do
    end associate
  contains
    !> The active lanes whose step met a limit (end_at_limit, the one-case
    !> code on the lane): those whose case ends there leave the batch; those
    !> whose step the flow shows inside the model, taken in pieces, go on
    !> (accepted, their new state observed with the others'), the summary
    !> of their pieces taken back into the lane's.
    subroutine meet_limits()
      type(observation_t) :: obs
      do l = 1, b%n
        if (.not. b%active(l) .or. accepted(l)) cycle
        results(l)%n_rhs = results(l)%n_rhs + 4
        results(l)%n_steps = step
        call samples%flush(l, results(l))
        call b%summary%store(l, b%run(l), results(l))
        ! the stages' own limit, which rk4_ball_step tells, is found in the approach
        y_lane = b%y(l, :)
        f_lane = b%f(l, :)
        checkpoint_lane = y_older_checkpoint(l, :)
        if (b%run(l)%ball%nonsmooth()) call b%run(l)%ball%begin_step(y_lane)    ! the step's mode
        call end_at_limit(integrator, b%run(l), plan, cases(l)%t_end, checkpoint_lane, step - 1, y_lane, f_lane, h(l), &
                          every(l), merge(out%status(l), status_no_fit, out%status(l) /= status_completed), &
                          results(l), y_new_lane, f_new_lane, obs)
        if (results(l)%status /= status_completed) then
          b%active(l) = .false.
          cycle
        end if
        passed(l) = .true.
        y_new(l, :) = y_new_lane
        f_new(l, :) = f_new_lane
        call b%summary%load(l, b%run(l))
        b%summary%theta_moved(l) = .false.       ! results(l) holds the largest theta so far
        samples%first(l) = results(l)%n_recorded + 1
      end do
      if (.not. any(passed)) return
      if (b%cups%moving) then
        call lanes_observe(b%balls, y_new, f_new, out, base_end)
      else
        call lanes_observe(b%balls, y_new, f_new, out)
      end if
      accepted = accepted .or. passed
    end subroutine meet_limits
  end subroutine fixed_step_lanes

  !> The active lanes whose rolling stops inside the step from t (steps h,
  !> derivatives f_start at its start in its law) just taken
  !> (lanes_rolling_stops, where the step stayed inside the model): the
  !> step taken again through the rest event with the one-case code on the
  !> lane (step_through_event, in the lane's mode and law for the step);
  !> its end (y_new, f_new) observed with the others' (out; base_end: the
  !> cups' accelerations there); a lane whose step then meets a limit is
  !> not inside (meet_limits). The others' steps taken in another law than
  !> law_exact: f_new in law_exact (exact_lane_ends), out in their law.
  subroutine rest_events(b, integrator, t, h, f_start, y_new, f_new, inside, out, base_end, results)
    type(batch_t), intent(inout) :: b
    class(integrator_t), intent(inout) :: integrator
    real(wp), intent(in) :: t(lanes), h(lanes), base_end(lanes, 3), f_start(lanes, state_size)
    real(wp), dimension(lanes, state_size), intent(inout) :: y_new, f_new
    logical, intent(inout) :: inside(lanes)
    type(lane_outputs_t), intent(inout) :: out
    type(case_result_t), intent(inout) :: results(:)
    real(wp), dimension(state_size) :: y_lane, f_lane, y_new_lane, f_new_lane
    type(observation_t) :: obs
    logical :: stops(lanes), ends(lanes)
    real(wp) :: t_event
    integer :: status, l
    ends = b%active .and. inside .and. out%status == status_completed
    stops = lanes_rolling_stops(b%balls, y_new) .and. ends
    ends = ends .and. .not. stops .and. b%balls%law > 0
    if (.not. any(stops .or. ends)) return
    do l = 1, b%n
      if (.not. stops(l)) cycle
      y_lane = b%y(l, :)
      f_lane = f_start(l, :)
      y_new_lane = y_new(l, :)                 ! where the event was seen
      call b%run(l)%ball%begin_step(y_lane)
      b%run(l)%ball%rolling_law = nint(b%balls%law(l))
      b%run(l)%ball%law_step = b%balls%law_step(l)
      call step_through_event(integrator, b%run(l), event_rest, t(l), y_lane, f_lane, h(l), y_new_lane, f_new_lane, &
                              obs, status, results(l)%n_rhs, t_event)
      b%run(l)%ball%rolling_law = law_exact
      b%run(l)%stopped_at = t_event
      y_new(l, :) = y_new_lane
      f_new(l, :) = f_new_lane
      inside(l) = status == status_completed
    end do
    if (b%cups%moving .and. any(stops)) then
      call lanes_observe(b%balls, y_new, f_new, out, base_end)
    else if (any(stops)) then
      call lanes_observe(b%balls, y_new, f_new, out)
    end if
    call exact_lane_ends(b%balls, b%run, ends, t + h, y_new, f_new, results)
  end subroutine rest_events

  !> Every lane's fixed step number `step` (steps h, from t = (step - 1) h,
  !> the one-case loop's times) and the observation of its end (base_end:
  !> the cups' accelerations there, when they move); with rolling
  !> resistance, in each lane's mode from the step's start.
  subroutine step_lanes(b, integrator, step, h, f_start, y_new, f_new, inside, out, base_end, results)
    type(batch_t), intent(inout) :: b
    class(integrator_t), intent(in) :: integrator
    integer(i8), intent(in) :: step
    real(wp), intent(in) :: h(lanes)
    real(wp), dimension(lanes, state_size), intent(out) :: f_start, y_new, f_new
    logical, intent(out) :: inside(lanes)
    type(lane_outputs_t), intent(inout) :: out
    real(wp), intent(inout) :: base_end(lanes, 3)
    type(case_result_t), intent(inout) :: results(:)
    real(wp) :: base_half(lanes, 3)
    real(wp) :: t(lanes)
    ! (the product's value through max, an operation of its own: t + h is rounded after t, as the one-case
    ! loop's, not fused into (step - 1) h + h whatever the inlining; a finite t is its own max with -huge)
    t = max(real(step - 1, wp) * h, -huge(1.0_wp))
    f_start = b%f
    if (b%balls%resists) then                  ! the modes and laws (f_start: the derivatives in them)
      base_half = 0
      if (b%cups%moving) call b%cups%at(t, base_half)
      call choose_lane_laws(b%balls, b%run, b%active, b%y, b%f, t, h, base_half, f_start, results)
    end if
    if (b%cups%moving) then
      call b%cups%at(t + h/2, base_half)
      call b%cups%at(t + h, base_end)
      call lanes_fixed_step(integrator, b%balls, b%y, f_start, h, y_new, f_new, inside, base_half, base_end)
      call lanes_observe(b%balls, y_new, f_new, out, base_end)
    else
      call lanes_fixed_step(integrator, b%balls, b%y, f_start, h, y_new, f_new, inside)
      call lanes_observe(b%balls, y_new, f_new, out)
    end if
  end subroutine step_lanes

  !> An embedded pair with each case's tolerances (adaptive_loop across
  !> lanes): the attempts of all lanes together, the step control of each
  !> lane its own. An attempt, with the dense-output stages computed for all
  !> lanes, is copied into the lane's pair (one per lane, all of one
  !> type) only when its dense output is needed (a sample or a maximum of
  !> Theta inside the step, a crossed limit).
  subroutine adaptive_lanes(b, pairs, cases, plan, results)
    type(batch_t), intent(inout) :: b
    class(embedded_pair_t), intent(inout) :: pairs(lanes)
    type(case_t), intent(in) :: cases(:)
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(inout) :: results(:)
    type(lane_outputs_t) :: out
    real(wp), dimension(lanes, state_size) :: y_raw, y_new, f_new
    real(wp), dimension(lanes, 3) :: base_end
    real(wp) :: k(lanes, state_size, max_pair_stages)
    real(wp), dimension(lanes) :: t, h, h_max, t_end, rtol, atol, error_norm
    type(nutation_peak_t) :: peaks(lanes)
    type(step_control_t) :: control(lanes)
    logical, dimension(lanes) :: accepted, sample_inside, peak_inside, dense, screened
    integer :: inside_status(lanes)
    real(wp) :: passed(lanes)             ! where the path inside a step is known past a limit
    integer(i8) :: attempt
    integer :: round_off_attempts(lanes)
    integer :: l, attempt_calls, end_stage
    associate (run => b%run, balls => b%balls, summary => b%summary, y => b%y, f => b%f, active => b%active, &
               n => b%n, donor => b%donor)
      attempt_calls = pairs(1)%attempt_calls()      ! the lanes' pairs are of one type
      end_stage = pairs(1)%end_stage()
      t = 0
      base_end = 0
      call start_pair_lanes(b, pairs, cases, control, rtol, atol, h_max, t_end, h, results)
      attempt = 0
      round_off_attempts = 0
      do while (any(active))
        attempt = attempt + 1
        if (stop_asked(attempt)) exit
        call next_steps(b, control, t, t_end, h, round_off_attempts, results)
        if (.not. any(active)) exit
        if (b%cups%moving) then
          call lanes_pair_attempt(pairs(1), balls, y, f, h, rtol, atol, k, y_raw, error_norm, b%cups, t)
        else
          call lanes_pair_attempt(pairs(1), balls, y, f, h, rtol, atol, k, y_raw, error_norm)
        end if
        call judge_attempts(b, control, h, atol, attempt_calls, error_norm, accepted, results)
        if (.not. any(accepted)) cycle
        call project_lanes(y_raw, k(:, :, end_stage), y_new, f_new)
        if (b%cups%moving) then
          call b%cups%at(t + h, base_end)
          call lanes_observe(balls, y_new, f_new, out, base_end)
        else
          call lanes_observe(balls, y_new, f_new, out)
        end if
        ! a step with a sample, a maximum of Theta, a crossed limit or the cup's
        ! clearance changing sign inside needs its dense output (all lanes' stages)
        sample_inside = .false.
        peak_inside = .false.
        screened = .false.
        do l = 1, n
          if (.not. accepted(l)) cycle
          sample_inside(l) = sample_due(run(l), plan, t(l) + h(l))
          peak_inside(l) = nutation_peak_inside(y(l, :), f(l, :), y_new(l, :), f_new(l, :), h(l))
          ! (the peak quantities' screen: ellroll_step_peaks)
          screened(l) = run(l)%ball%reaction_limited() .or. may_peak_inside(run(l)%ball, h(l), y(l, :), &
              f(l, :), y_new(l, :), f_new(l, :), summary%stats%clear_maximum(l, peak_quantities))
        end do
        dense = sample_inside .or. peak_inside .or. (accepted .and. (out%status /= status_completed .or. screened &
                .or. (summary%stats%clear_last .neqv. out%quantity(:, q_fit_clearance) > 0)))
        if (any(dense)) then
          if (b%cups%moving) then
            call lanes_pair_dense_stages(pairs(1), balls, y, h, k, b%cups, t)
          else
            call lanes_pair_dense_stages(pairs(1), balls, y, h, k)
          end if
        end if
        ! the path past a limit inside the step (past the rim at a maximum of
        ! Theta, or slipping): the step's end is not the case's
        call limits_inside_steps(b, pairs, out, t, h, y_raw, k, error_norm, accepted, dense, screened, peak_inside, &
                                 peaks, inside_status, passed, results)
        call summary%add(out, t + h, accepted .and. out%status == status_completed .and. inside_status == status_completed)
        do l = 1, n
          if (.not. accepted(l)) cycle
          if (inside_status(l) /= status_completed) then
            call summary%store(l, run(l), results(l))
            call stop_in_step(pairs(l), run(l), plan, inside_status(l), results(l), passed(l))
            active(l) = .false.
            cycle
          end if
          if (out%status(l) /= status_completed) then
            call summary%store(l, run(l), results(l))
            call stop_in_step(pairs(l), run(l), plan, out%status(l), results(l))
            active(l) = .false.
            cycle
          end if
          if (sample_inside(l)) call record_samples_until(pairs(l), run(l), plan, t(l) + h(l), &
                                                          lane_observation(out, y_new, base_end, l, run(l)%ball%radius), results(l))
          peak_inside(l) = peak_inside(l) .and. peaks(l)%found
          if (peak_inside(l)) call summary%note_nutation(l, peaks(l)%tan_nutation, peaks(l)%lateral, peaks(l)%normal_z)
          call track_pair_step(run(l), y(l, :), f(l, :), y_new(l, :), f_new(l, :), t(l) + h(l), peak_inside(l), &
                               peaks(l), pairs(l)%atol, pairs(l)%rtol)
          if (.not. round_off_step(t(l), h(l), t_end(l))) round_off_attempts(l) = 0
          t(l) = t(l) + h(l)
          results(l)%n_steps = results(l)%n_steps + 1
          if (b%cups%moving) call track_cups(b, out, base_end, t, lane_only(l))
          if (t(l) < t_end(l)) then
            y(l, :) = y_new(l, :)
            f(l, :) = f_new(l, :)
            call control(l)%accept(h(l), error_norm(l), h_max(l))
          else                     ! done: the lane repeats its last attempt, idle
            results(l)%t_final = t_end(l)
            call summary%store(l, run(l), results(l))
            active(l) = .false.
          end if
        end do
      end do
    end associate
  end subroutine adaptive_lanes

  !> Each active lane's next attempt from t (h clipped to its t_end and to
  !> its step control); a lane whose steps have shrunk to round-off ends as
  !> unstable (adaptive_loop) and idles.
  subroutine next_steps(b, control, t, t_end, h, round_off_attempts, results)
    type(batch_t), intent(inout) :: b
    type(step_control_t), intent(in) :: control(lanes)
    real(wp), dimension(lanes), intent(in) :: t, t_end
    real(wp), intent(inout) :: h(lanes)
    integer, intent(inout) :: round_off_attempts(lanes)
    type(case_result_t), intent(inout) :: results(:)
    integer :: l
    do l = 1, lanes
      if (.not. b%active(l)) cycle
      h(l) = next_step(t(l), h(l), t_end(l), control(l)%after_rejection, b%run(l)%ball%excitation)
      if (round_off_step(t(l), h(l), t_end(l))) round_off_attempts(l) = round_off_attempts(l) + 1
      if (cannot_follow(h(l), round_off_attempts(l), results(l)%n_steps + results(l)%n_rejected)) then
        results(l)%status = status_unstable
        results(l)%t_final = t(l)
        call b%summary%store(l, b%run(l), results(l))
        b%active(l) = .false.
        h(l) = max(h(l), tiny(1.0_wp))     ! idle: a round-off step from a valid state, never 0 (0 / 0)
      end if
    end do
  end subroutine next_steps

  !> Each active lane's attempt (steps h) judged by its error norm (the
  !> one-case rule); a rejected one shrinks its step.
  subroutine judge_attempts(b, control, h, atol, attempt_calls, error_norm, accepted, results)
    type(batch_t), intent(in) :: b
    type(step_control_t), intent(inout) :: control(lanes)
    real(wp), intent(inout) :: h(lanes), error_norm(lanes)
    real(wp), intent(in) :: atol(lanes)
    integer, intent(in) :: attempt_calls
    logical, intent(out) :: accepted(lanes)
    type(case_result_t), intent(inout) :: results(:)
    integer :: l
    accepted = .false.
    do l = 1, b%n
      if (.not. b%active(l)) cycle
      results(l)%n_rhs = results(l)%n_rhs + attempt_calls
      error_norm(l) = judged_norm(error_norm(l), h(l), is_zero(atol(l)))
      accepted(l) = error_norm(l) <= 1
      if (.not. accepted(l)) then
        call control(l)%reject(h(l), error_norm(l))
        results(l)%n_rejected = results(l)%n_rejected + 1
      end if
    end do
  end subroutine judge_attempts

  !> The lanes' pairs and step controls with each case's tolerances and
  !> largest step (an idle lane its donor's), and each lane's first step
  !> (initial_step; an idle lane's RHS calls counted nowhere).
  subroutine start_pair_lanes(b, pairs, cases, control, rtol, atol, h_max, t_end, h, results)
    type(batch_t), intent(in) :: b
    class(embedded_pair_t), intent(inout) :: pairs(lanes)
    type(case_t), intent(in) :: cases(:)
    type(step_control_t), intent(inout) :: control(lanes)
    real(wp), dimension(lanes), intent(out) :: rtol, atol, h_max, t_end, h
    type(case_result_t), intent(inout) :: results(:)
    real(wp), dimension(state_size) :: y_lane, f_lane
    integer(i8) :: idle_rhs
    integer :: i, l
    idle_rhs = 0
    do l = 1, lanes
      i = merge(l, b%donor, b%active(l))
      pairs(l)%rtol = cases(i)%param(p_rtol)
      pairs(l)%atol = cases(i)%param(p_atol)
      control(l)%order = pairs(1)%control_order()
      rtol(l) = cases(i)%param(p_rtol)
      atol(l) = cases(i)%param(p_atol)
      h_max(l) = min(cases(i)%param(p_dt), longest_step(b%run(i)%ball%excitation))
      t_end(l) = cases(i)%t_end
      y_lane = b%y(l, :)
      f_lane = b%f(l, :)
      if (b%active(l)) then
        call pairs(l)%initial_step(b%run(l)%ball, 0.0_wp, y_lane, f_lane, h_max(l), h(l), results(l)%n_rhs)
      else
        call pairs(l)%initial_step(b%run(i)%ball, 0.0_wp, y_lane, f_lane, h_max(l), h(l), idle_rhs)
      end if
    end do
  end subroutine start_pair_lanes

  !> The accepted lanes' attempts (from t, steps h) on the one-case code per
  !> lane: a limit the path passes inside though the end is inside (past the
  !> rim at a maximum of Theta, or slipping: inside_status, and passed, where
  !> the path is known past it), the peaks, the clearance's changes of sign.
  !> A lane whose dense output is needed (dense) first takes its attempt into
  !> its pair (load_attempt); the maxima of Theta (peak_inside) into peaks.
  subroutine limits_inside_steps(b, pairs, out, t, h, y_raw, k, error_norm, accepted, dense, screened, peak_inside, &
                                 peaks, inside_status, passed, results)
    type(batch_t), intent(inout) :: b
    class(embedded_pair_t), intent(inout) :: pairs(lanes)
    type(lane_outputs_t), intent(in) :: out
    real(wp), dimension(lanes), intent(in) :: t, h, error_norm
    real(wp), intent(in) :: y_raw(lanes, state_size), k(lanes, state_size, max_pair_stages)
    logical, dimension(lanes), intent(in) :: accepted, dense, screened, peak_inside
    type(nutation_peak_t), intent(inout) :: peaks(lanes)
    integer, intent(out) :: inside_status(lanes)
    real(wp), intent(inout) :: passed(lanes)
    type(case_result_t), intent(inout) :: results(:)
    real(wp), dimension(state_size) :: y_lane, f_lane
    real(wp) :: quantity_lane(size(out%quantity, 2)), above(size(peak_quantities))
    type(step_screen_t) :: screen
    integer :: l
    inside_status = status_completed
    do l = 1, b%n
      if (.not. accepted(l)) cycle
      if (dense(l)) call load_attempt(pairs(l), l, t(l), h(l), b%y, y_raw, k, error_norm(l))
      if (out%status(l) /= status_completed) cycle
      if (peak_inside(l)) then
        call locate_nutation_peak(pairs(l), b%run(l)%ball, peaks(l), results(l)%n_rhs)
        if (beyond_rim(peaks(l))) then
          inside_status(l) = status_rim
          passed(l) = peaks(l)%t - t(l)
          cycle
        end if
      end if
      y_lane = b%y(l, :)
      f_lane = b%f(l, :)
      quantity_lane = out%quantity(l, :)          ! (contiguous rows: no array temporary)
      above = b%summary%stats%clear_maximum(l, peak_quantities)
      call screen_and_peaks(pairs(l), b%run(l), y_lane, f_lane, out%quantity(l, q_friction_needed), &
                            out%quantity(l, q_reaction_normal), screened(l), inside_status(l), passed(l), screen, &
                            results(l)%n_rhs, above, quantity_lane(peak_quantities))
      if (inside_status(l) /= status_completed) cycle
      call add_clearance_crossing(pairs(l), b%run(l)%ball, quantity_lane(q_fit_clearance), 1.0_wp, results(l)%n_rhs, &
                                  lane_stats=b%summary%stats, l=l)
      if (.not. screened(l)) cycle
      call note_screen_end(screen, quantity_lane)
      call add_step_peaks(pairs(l), b%run(l)%ball, screen, results(l)%n_rhs, lane_stats=b%summary%stats, l=l)
    end do
  end subroutine limits_inside_steps

  !> Lane l's last attempt (from t, step h: y -> y_raw, stages k with the
  !> dense-output ones) into its pair, as pair_ball_step leaves it, for its
  !> dense output.
  pure subroutine load_attempt(pair, l, t, h, y, y_raw, k, error_norm)
    class(embedded_pair_t), intent(inout) :: pair
    integer, intent(in) :: l
    real(wp), intent(in) :: t, h, y(lanes, state_size), y_raw(lanes, state_size), k(lanes, state_size, max_pair_stages)
    real(wp), intent(in) :: error_norm
    real(wp) :: y_lane(state_size), y_raw_lane(state_size)
    pair%k(:state_size, :) = k(l, :, :)
    y_lane = y(l, :)                     ! contiguous for hold_attempt's explicit-shape arguments
    y_raw_lane = y_raw(l, :)
    call pair%hold_attempt(t, h, y_lane, y_raw_lane, error_norm, dense_stages_ready=.true.)
  end subroutine load_attempt

  !> Lane l's end-of-step observation, what an output sample stores (base:
  !> the cups' accelerations there).
  pure function lane_observation(out, y, base, l, radius) result(obs)
    type(lane_outputs_t), intent(in) :: out
    real(wp), intent(in) :: y(lanes, state_size), base(lanes, 3), radius
    integer, intent(in) :: l
    type(observation_t) :: obs
    obs%normal = out%normal(l, :)
    obs%omega = y(l, 4:6)
    obs%contact = out%contact(l, :)
    obs%center = obs%contact + radius * obs%normal
    obs%lateral = out%lateral(l)
    obs%reaction = out%reaction(l, :)
    obs%energy = out%quantity(l, q_energy)
    obs%base_acceleration = base(l, :)
    obs%center_acceleration = out%center_acceleration(l, :)
  end function lane_observation

  !> What the accepted lanes' new states (at times t) add to the summary of
  !> a moving cup beyond the statistics (track_cup_motion, the one-case
  !> code on each lane).
  subroutine track_cups(b, out, base, t, accepted)
    type(batch_t), intent(inout) :: b
    type(lane_outputs_t), intent(in) :: out
    real(wp), intent(in) :: base(lanes, 3), t(lanes)
    logical, intent(in) :: accepted(lanes)
    real(wp) :: center_acceleration(2), base_lane(2)   ! contiguous rows for track_cup_motion
    integer :: l
    do l = 1, b%n
      if (.not. accepted(l)) cycle
      center_acceleration = out%center_acceleration(l, 1:2)
      base_lane = base(l, 1:2)
      call track_cup_motion(b%run(l), t(l), center_acceleration, base_lane)
    end do
  end subroutine track_cups

  !> What the accepted lanes' new states y (derivatives f, observed: out, at
  !> times t) add to the summary of a batch with rolling resistance: the
  !> couple's work (track_rolling_resistance, the one-case code on each lane
  !> that has it), then the step-end quantities, the energy with that work
  !> (energy_drift: the residual of the balance E + W = E0).
  subroutine track_resistance(b, out, y, f, t, accepted, results)
    type(batch_t), intent(inout) :: b
    type(lane_outputs_t), intent(in) :: out
    real(wp), intent(in) :: y(lanes, state_size), f(lanes, state_size), t(lanes)
    logical, intent(in) :: accepted(lanes)
    type(case_result_t), intent(inout) :: results(:)
    type(observation_t) :: obs
    logical :: still(lanes)
    real(wp) :: works(lanes)
    integer :: l
    still = lanes_at_rest(b%balls, f)
    works = 0
    do l = 1, b%n
      if (.not. (accepted(l) .and. b%balls%resistance(l) > 0)) cycle
      obs%normal = out%normal(l, :)
      obs%omega = y(l, 4:6)
      obs%center = out%contact(l, :) + b%run(l)%ball%radius * obs%normal
      obs%reaction_normal = out%quantity(l, q_reaction_normal)
      obs%fit_clearance = out%quantity(l, q_fit_clearance)
      call track_rolling_resistance(b%run(l), results(l), t(l), obs, still(l))
      works(l) = results(l)%reals(fig_rolling_resistance_energy)
    end do
    call b%summary%add(out, t, accepted, works)
  end subroutine track_resistance

  !> The mask of lane l alone.
  pure function lane_only(l) result(mask)
    integer, intent(in) :: l
    logical :: mask(lanes)
    integer :: j
    mask = [(j == l, j = 1, lanes)]
  end function lane_only

end module ellroll_batch_run
