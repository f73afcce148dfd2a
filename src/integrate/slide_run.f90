!> One case that may slide (`&ball slip = 'slide'`): the ball rolls until the
!> friction rolling needs reaches mu N, slides (ellroll_sliding_ball, eight
!> numbers) until the slip stops with rolling's friction within mu N, and so
!> on. An adaptive method rolls in the rolling path's own loop (adaptive_loop,
!> which hands the state over where the friction passes mu N); a fixed-step
!> method rolls with the rolling path's steps and events (step_with_events).
!> The other switches are located inside the step where they happen (a root
!> search on the method's own partial steps from the step's start); a
!> fixed-step method takes the rest of its step from the switch in the new
!> regime, so that its steps stay on the grid of dt; an adaptive method ends
!> its step at the switch. A limit of the model ends the case where the
!> method's partial steps first meet it.
module ellroll_slide_run
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: equals
  use ellroll_status, only: status_pending, status_completed, status_slip, status_unstable, status_liftoff, status_rim, &
      status_no_fit
  use ellroll_errors, only: error_t
  use ellroll_events, only: root_search_t, max_event_trials
  use ellroll_cases, only: case_t, output_plan_t, steps_per_sample
  use ellroll_results, only: case_result_t, add_switch, switch_to_sliding
  use ellroll_figures, only: fig_sliding_time, fig_slip_episodes, fig_friction_energy, fig_slip_speed_max
  use ellroll_rolling_ball, only: state_size, observe, observation_t, ball_derivative
  use ellroll_sliding_ball, only: sliding_ball_t, sliding_from_rolling, observe_sliding, slip_velocity, slip_rate, &
      choose_slip_law, stop_floor
  use ellroll_turns, only: direction_unresolved
  use ellroll_integrators, only: integrator_t, embedded_pair_t, new_pair
  use ellroll_flow_to_limit, only: reference_method, reference_rtol, reference_atol, follow_flow_to_limit
  use ellroll_fixed_step_run, only: checkpoint_steps, older_checkpoint_step
  use ellroll_case_run, only: run_state_t, stop_asked, sample_due, reach_stop, settled, regular_steps, last_fixed_step, &
      fixed_step_time
  use ellroll_adaptive_run, only: adaptive_loop
  use ellroll_excitation, only: step_to_sample, longest_step
  use ellroll_slide_regime, only: regime_state_t, slide_tally_t, take, restart_samples, track_balance, &
      record_regime_sample, switch_crossed, switch_value, start_sliding, stop_sliding, add_sliding_step, &
      slip_stopped, observe_stopped, add_sliding_peaks, step_screen_t, graze_inside, stop_bracket, hovering_slip, &
      switch_reaction
  use ellroll_slide_limits, only: end_at_limit, lift_inside, within_tolerance_to_limit
  use ellroll_params, only: p_dt, p_velocity_x, p_velocity_z, p_settle
  implicit none
  private

  public :: slide_loop

  !> A step in which the regime switches more often than this ends the case
  !> with status slip: the motion chatters between the regimes there.
  integer, parameter :: max_switches_per_step = 64
  !> A fixed step's switches at which its rest is taken in the sliding regime
  integer, parameter :: chatter_switches = 8
  !> An embedded pair's steps in a row in which the slip stays at the size of
  !> its error (hovering_slip) before the slip counts as stopped where rolling
  !> can go on, and before the case ends as unstable where it cannot.
  integer, parameter :: hover_steps = 64, max_hover_steps = 100000
  !> Steps shorter on average than this part of t_end over max_hover_steps
  !> steps crawl: the case would take more than 1e7 steps (it ends unstable).
  real(wp), parameter :: crawl_fraction = 1.0e-7_wp
  !> A slip within this multiple of the pair's tolerances where the steps
  !> crawl dies at the pair's error level: it stops there where rolling can go on.
  real(wp), parameter :: crawl_slip = 1.0e3_wp
  !> The error the aligned slip law may leave in the slip (choose_slip_law):
  !> this part of an embedded pair's tolerance. A fixed-step method keeps the
  !> full law (its substeps resolve the small slip: slip_substeps).
  real(wp), parameter :: align_fraction = 1.0e-3_wp
  !> An embedded pair's first step of a sliding piece: this part of its
  !> initial-step guess. At the switch the slip is zero and its direction's
  !> lag time |u| / (kappa |F_req|) with it: the pair's error estimate of one
  !> long first step does not see the error this start makes (on
  !> test_slip_direction's record the friction's work then wandered by 1e-6
  !> of itself with the tolerance; from a 32nd of the guess it agrees to
  !> 1e-11 across pairs and tolerances).
  real(wp), parameter :: first_step_fraction = 1.0_wp / 32


contains

  !> The case from (y, f) at t = 0 (start_case) to t_end (with settle: on
  !> until the ball is at rest for good, as the rolling loops; latest_end;
  !> a sliding step end is never at rest: track_balance)
  !> or the limit it meets. A start whose friction exceeds mu (res%status
  !> slip), or with a velocity of the centre that is not rolling's (its
  !> slip above the round-off stop_floor counts as stopped), starts sliding; a start whose normal force does not push (rolling's,
  !> res%status liftoff, or the sliding start's) ends at t = 0.
  subroutine slide_loop(integrator, cs, plan, run, y, f, res)
    class(integrator_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: y(state_size), f(state_size)
    type(case_result_t), intent(inout) :: res
    type(run_state_t) :: rolling
    type(sliding_ball_t) :: sb
    type(regime_state_t) :: now
    type(slide_tally_t) :: tally
    real(wp) :: velocity(3)
    rolling = run
    rolling%ball%mu = -1             ! the rolling steps know no slip: its switch is this loop's
    sb%ball = run%ball
    select type (integrator)
    class is (embedded_pair_t)
      call align_to(integrator, sb)
    end select
    now%y = y
    now%f = f
    call observe(rolling%ball, 0.0_wp, y, f, now%obs)
    velocity = cs%param(p_velocity_x:p_velocity_z)
    if (all(ieee_is_finite(velocity))) then
      now%s = sliding_from_rolling(sb%ball, y)
      now%s(7:8) = velocity(1:2)
      if (norm2(slip_velocity(sb%ball, now%s)) > stop_floor(sb%ball, now%s)) then
        now%sliding = .true.
        call sb%begin_step(now%s)
        call observe_sliding(sb, 0.0_wp, now%s, now%obs, now%slip_speed, now%fs)
        res%n_rhs = res%n_rhs + 1
        tally%episodes = 1
        tally%slip_speed_max = now%slip_speed
        tally%episode_slip_max = now%slip_speed
        call restart_samples(cs, run, res, now)
      end if
    end if
    if (.not. now%sliding .and. res%status == status_slip) then
      call start_sliding(sb, 0.0_wp, now, res, tally)
      call add_switch(res, 0.0_wp, switch_to_sliding)
      ! its slip is round-off there: the friction stored is mu N along the
      ! switch's direction (-slip_mode), as the steps from it take it
      if (now%obs%reaction_normal > 0) call switch_reaction(sb, now%obs)
      call restart_samples(cs, run, res, now)     ! the start slides from t = 0: the rolling state never acts
    end if
    if (now%sliding) then
      res%status = merge(status_liftoff, status_completed, now%obs%reaction_normal <= 0)
    else if (res%status /= status_liftoff) then
      res%status = status_completed
    end if
    if (res%status == status_completed) then
      select type (integrator)
      class is (embedded_pair_t)
        call adaptive_slide(integrator, cs, plan, run, rolling, sb, now, tally, res)
      class default
        call fixed_slide(integrator, cs, plan, run, rolling, sb, now, tally, res)
      end select
    end if
    res%reals(fig_sliding_time) = tally%sliding_time
    res%counts(fig_slip_episodes) = tally%episodes
    res%reals(fig_friction_energy) = tally%friction_energy
    res%reals(fig_slip_speed_max) = tally%slip_speed_max
  end subroutine slide_loop

  !> The aligned slip law's tolerances for the embedded pair's steps.
  pure subroutine align_to(pair, sb)
    class(embedded_pair_t), intent(in) :: pair
    type(sliding_ball_t), intent(inout) :: sb
    sb%align_atol = align_fraction * pair%atol
    sb%align_rtol = align_fraction * pair%rtol
    sb%stiff_allowance = 1 / align_fraction
  end subroutine align_to

  !> Fixed steps of dt, each from the state at its start to the grid point
  !> after it, through the switches inside it (advance).
  subroutine fixed_slide(integrator, cs, plan, run, rolling, sb, now, tally, res)
    class(integrator_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    integer(i8) :: k, n_steps, n_last, every, sample
    real(wp) :: t, t_stop, friction_before, friction_start
    logical :: ended
    !> the states at the last two checkpoints (every checkpoint_steps steps),
    !> and the switches made before each
    type(regime_state_t) :: checkpoint, older_checkpoint
    integer :: switches_at_checkpoint, switches_at_older
    n_steps = regular_steps(cs)
    n_last = last_fixed_step(cs, run)     ! past t_end (settle): on until the ball is at rest
    every = steps_per_sample(cs, plan)
    t = 0
    friction_before = huge(1.0_wp)        ! (unknown before the first step: no parabola)
    checkpoint = now
    older_checkpoint = now
    switches_at_checkpoint = res%n_switches
    switches_at_older = res%n_switches
    do k = 1, n_last
      if (stop_asked(k)) then
        res%status = status_pending
        return
      end if
      friction_start = merge(huge(1.0_wp), now%obs%friction_needed, now%sliding)
      call advance(integrator, run, rolling, sb, t, cs%param(p_dt), .false., now, tally, res, ended, t_stop, &
                   friction_before=friction_before)
      friction_before = friction_start
      res%n_steps = k
      if (ended) then
        if (res%status == status_no_fit .and. res%n_switches == switches_at_older) &
          call end_on_exact_flow(cs, run, rolling, sb, older_checkpoint_step(k - 1) * cs%param(p_dt), older_checkpoint, &
                                 t, every, tally, res)
        return
      end if
      t = k * cs%param(p_dt)
      if (mod(k, checkpoint_steps) == 0) then
        older_checkpoint = checkpoint
        switches_at_older = switches_at_checkpoint
        checkpoint = now
        switches_at_checkpoint = res%n_switches
      end if
      call track_balance(run, res, t, now, tally)
      sample = k / every + 1
      if (mod(k, every) == 0 .and. sample <= plan%n_samples) call record_regime_sample(res, sample, now)
      if (k >= n_steps .and. n_last > n_steps) then
        if (settled(run, t)) exit
      end if
    end do
    res%t_final = fixed_step_time(cs, res%n_steps, t)
  end subroutine fixed_slide

  !> A fixed-step case that met the fit limit (res%status no_fit at
  !> res%t_final, in the step from t_last) in the regime it had, without a
  !> switch, since its older checkpoint (from, at t_from). Near the limit's
  !> square-root singularity the method's own last steps meet it late (rk4
  !> at dt = 1e-3 s, 3e-5 s on a paper-cup case; the trajectory before them
  !> is accurate to 4e-9 m), so the case ends where the exact flow from the
  !> checkpoint meets it (the reference pair at its tolerances: the rolling
  !> regime's follow_flow_to_limit, as a case with slip = 'end' ends), where
  !> that flow stays in the regime all the way to the fit limit within two
  !> steps after t_last. A sliding time ends there with it, and samples
  !> after it are dropped (every: the steps per sample). A rolling flow's
  !> step ends after t_last, and where it leaves the cup's curvature, add
  !> to the summary's peaks as slip = 'end''s do (the peaks grow without
  !> bound towards the limit); the works, and a sliding flow's summary,
  !> keep what the method's steps added.
  subroutine end_on_exact_flow(cs, run, rolling, sb, t_from, from, t_last, every, tally, res)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t_from, t_last
    type(regime_state_t), intent(in) :: from
    integer(i8), intent(in) :: every
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    class(embedded_pair_t), allocatable :: pair
    type(error_t) :: err
    type(case_t) :: span
    type(output_plan_t) :: no_samples
    type(run_state_t) :: flow_run, flow_rolling
    type(sliding_ball_t) :: flow_sb
    type(regime_state_t) :: at
    type(slide_tally_t) :: flow_tally
    type(case_result_t) :: flow
    real(wp) :: t, h
    logical :: done
    h = cs%param(p_dt)
    span = cs
    span%t_end = min(t_last + 2 * h, max(cs%t_end, t_last + h))
    span%param(p_settle) = 0
    flow_rolling = rolling
    flow%status = status_completed
    flow%reals = res%reals                ! (the figures the steps' tracking reads; the flow's own are thrown away)
    flow%counts = res%counts
    if (from%sliding) then
      call new_pair(reference_method, pair, err)      ! (a row of the method table: it cannot fail)
      pair%rtol = reference_rtol
      pair%atol = reference_atol
      flow_run = run
      flow_sb = sb
      call align_to(pair, flow_sb)
      at = from
      t = t_from
      call sliding_piece(pair, span, no_samples, flow_run, flow_rolling, flow_sb, t, at, flow_tally, flow, done)
    else
      flow_run = run                      ! (the summary's tracking, with the rolling steps' ball)
      flow_run%ball = rolling%ball
      call follow_flow_to_limit(flow_run, no_samples, t_from, from%y, t_last, span%t_end, flow, done)
    end if
    res%n_rhs = res%n_rhs + flow%n_rhs
    if (.not. (done .and. flow%status == status_no_fit)) return
    if (.not. from%sliding) run%stats = flow_run%stats       ! (the peaks; the works are the steps')
    if (from%sliding) tally%sliding_time = tally%sliding_time + (flow%t_final - res%t_final)
    if (flow%t_final < t_last) res%n_recorded = min(res%n_recorded, int(flow%t_final / h, i8) / every + 1)
    res%t_final = flow%t_final
  end subroutine end_on_exact_flow

  !> An embedded pair's case: its rolling pieces are the rolling path's own
  !> (adaptive_loop, which returns where the friction needed passes mu N,
  !> located on its dense output where slip = 'end' ends the case), its
  !> sliding pieces sliding_piece's steps.
  subroutine adaptive_slide(pair, cs, plan, run, rolling, sb, now, tally, res)
    class(embedded_pair_t), intent(inout) :: pair
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    real(wp) :: t
    logical :: slipped, done
    t = 0
    do
      if (.not. now%sliding) then
        ! the stick's work of the stop just made is the friction's (track_balance's)
        run%friction_work = tally%friction_energy
        call adaptive_loop(pair, cs, plan, run, now%y, now%f, res, t, slipped)
        if (.not. slipped) return
        t = res%t_final
        res%status = status_completed
        if (run%ball%nonsmooth()) call run%ball%begin_step(now%y)
        call ball_derivative(run%ball, t, now%y, now%f)
        call observe(run%ball, t, now%y, now%f, now%obs)
        res%n_rhs = res%n_rhs + 1
        call start_sliding(sb, t, now, res, tally)
        call add_switch(res, t, switch_to_sliding)
      end if
      call sliding_piece(pair, cs, plan, run, rolling, sb, t, now, tally, res, done)
      if (done) return
    end do
  end subroutine adaptive_slide

  !> An embedded pair's steps from (t, now), sliding, each ending at the next
  !> output sample or before, until a switch to rolling (t and now moved
  !> there) or the case's end (done).
  subroutine sliding_piece(pair, cs, plan, run, rolling, sb, t, now, tally, res, done)
    class(embedded_pair_t), intent(inout) :: pair
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(inout) :: t
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    logical, intent(out) :: done
    type(regime_state_t) :: trial
    type(step_screen_t) :: screen
    real(wp) :: h, h_max, t_next, next_sample_time, factor, window_start, h_rejected
    real(wp) :: t_stop                    ! t_end, then, settling, latest_end
    integer :: status, stalled, hovering, crawling
    integer(i8) :: steps
    logical :: ended, rejected
    h_max = min(cs%t_end, cs%param(p_dt))
    if (.not. ieee_is_finite(h_max) .or. h_max <= 0) h_max = cs%t_end
    h_max = min(h_max, longest_step(run%ball%excitation))
    call pair%initial_step(sb, t, now%s, now%fs, h_max, h, res%n_rhs)
    h = first_step_fraction * h
    run%maxima%n_samples = 0              ! (Theta's maxima from these step ends alone)
    steps = 0
    stalled = 0
    hovering = 0
    crawling = 0
    window_start = t
    t_stop = cs%t_end
    do
      call reach_stop(cs, run, t, t_stop, done)       ! (past t_end, settle: on until the ball is at rest)
      if (done) exit
      if (stop_asked(res%n_steps + res%n_rejected)) then
        res%status = status_pending
        done = .true.
        return
      end if
      h = step_to_sample(run%ball%excitation, t, min(h, h_max, t_stop - t))
      t_next = t + h
      if (run%next_sample <= plan%n_samples) then
        next_sample_time = real(run%next_sample - 1, wp) * plan%interval
        if (next_sample_time > t .and. next_sample_time < t_next) t_next = next_sample_time
      end if
      if (t_stop - t_next <= 4 * spacing(t_stop)) t_next = t_stop
      h = t_next - t
      call attempt(pair, rolling, sb, t, h, now, trial, status, res, rejected, screen)
      if (rejected) then
        res%n_rejected = res%n_rejected + 1
        h_rejected = h
        h = h * max(0.2_wp, 0.9_wp * pair%error_norm**(-1.0_wp / pair%control_order()))
        if (h <= 16 * spacing(t)) then
          if (status /= status_completed) then      ! a limit no step within tolerance reaches: met there
            call end_at_limit(pair, run, rolling, sb, t, h_rejected, now, tally, res)
            done = .true.
            return
          end if
          res%status = status_unstable
          res%t_final = t
          done = .true.
          return
        end if
        cycle
      end if
      factor = 5
      if (pair%error_norm > 0) factor = min(5.0_wp, max(0.2_wp, 0.9_wp * pair%error_norm**(-1.0_wp / pair%control_order())))
      call advance(pair, run, rolling, sb, t, h, .true., now, tally, res, ended, t_next, trial, status)
      res%n_steps = res%n_steps + 1
      steps = steps + 1
      done = ended
      if (ended) return
      ! the peaks between the step's ends, where no switch cut it (its dense output is the step's)
      if (status == status_completed .and. equals(t_next, t + h)) &
        call add_sliding_peaks(pair, run, sb, t, h, screen, trial, res%n_rhs)
      ! steps too short to reach t_end in any time (a friction that flips at
      ! every stage about u = 0): every max_hover_steps steps the case must
      ! have moved on by crawl_fraction of t_end per step on average
      if (mod(steps, int(max_hover_steps, i8)) == 0) then
        crawling = merge(1, 0, t_next - window_start < max_hover_steps * crawl_fraction * cs%t_end)
        window_start = t_next
        if (crawling > 0 .and. hovering_slip(pair, sb, now, crawl_slip)) then
          ! a slip that dies at the pair's error level, where the full law's direction is stiff:
          ! the steps crawl, and it stops there if rolling can go on
          call stop_sliding(rolling, sb, t_next, now, res, tally, at_rest_only=.true.)
          if (.not. now%sliding) crawling = 0
        end if
      end if
      stalled = merge(stalled + 1, 0, t_next - t <= 16 * spacing(t_next))
      hovering = merge(hovering + 1, 0, hovering_slip(pair, sb, now))
      if (hovering >= hover_steps .and. mod(hovering, hover_steps) == 0) then
        ! the slip is zero to the pair's tolerance: it stops if rolling can go on
        call stop_sliding(rolling, sb, t_next, now, res, tally, at_rest_only=.true.)
        if (.not. now%sliding) hovering = 0
      end if
      if (stalled > max_switches_per_step .or. hovering > max_hover_steps .or. crawling > 0) then
        res%status = status_unstable           ! switches that no longer move on: chattering
        res%t_final = t
        done = .true.
        return
      end if
      t = t_next
      call track_balance(run, res, t, now, tally)
      if (sample_due(run, plan, t)) then
        call record_regime_sample(res, run%next_sample, now)
        run%next_sample = run%next_sample + 1
      end if
      if (.not. now%sliding) return           ! rolling on from t
      h = h * factor
    end do
    res%t_final = t
  end subroutine sliding_piece

  !> An embedded pair's sliding attempt of size h from (t, now), and whether
  !> its error rejects it: take's step, or its stop bracket's where the slip
  !> stops in that (h cut to it). screen: lift_inside's of an accepted step.
  subroutine attempt(pair, rolling, sb, t, h, now, new, status, res, rejected, screen)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: t
    real(wp), intent(inout) :: h
    type(regime_state_t), intent(inout) :: now
    type(regime_state_t), intent(out) :: new
    integer, intent(out) :: status
    type(case_result_t), intent(inout) :: res
    logical, intent(out) :: rejected
    type(step_screen_t), intent(out) :: screen
    real(wp) :: h_cut
    logical :: taken
    call sb%begin_step(now%s)
    call choose_slip_law(sb, t, now%s, now%fs, h, res%n_rhs)
    call stop_bracket(pair, rolling, sb, t, h, now, res%n_rhs, h_cut, new, status, taken)
    if (.not. taken) call take(pair, rolling, sb, t, h, now, new, status, res%n_rhs)
    h = h_cut
    ! a step that passes the rim or lifts off is located only where the
    ! pair's estimate accepts it, as a rolling step is: near the rim V_z's
    ! 1 / n_z takes the error of a partial step towards it past the
    ! tolerance, and the crossing's search (end_at_limit) would stop there
    rejected = (status == status_completed .or. status == status_rim .or. status == status_liftoff) &
               .and. .not. pair%error_norm <= 1
    if (rejected) return
    if (status == status_completed) call lift_inside(pair, rolling, sb, t, h, now, new, status, res%n_rhs, screen)
    if (status == status_rim .or. status == status_liftoff .or. status == status_no_fit) &
      call within_tolerance_to_limit(pair, rolling, sb, t, h, now, new, status, res%n_rhs)
  end subroutine attempt

  !> A step of size h_step from (t, now), through the switches of regime
  !> on the way: a piece that meets a limit ends the case there (ended); a
  !> switch inside it is located, made, and the rest of the step taken in
  !> the new regime (fixed steps), or the step ends there (stop_at_switch).
  !> t_stop: where the step ended. first, first_status: the step h_step
  !> from now already taken (an embedded pair's judged attempt).
  subroutine advance(integrator, run, rolling, sb, t, h_step, stop_at_switch, now, tally, res, ended, t_stop, &
                     first, first_status, friction_before)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: t, h_step
    logical, intent(in) :: stop_at_switch
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    logical, intent(out) :: ended
    real(wp), intent(out) :: t_stop
    type(regime_state_t), intent(in), optional :: first
    integer, intent(in), optional :: first_status
    real(wp), intent(in), optional :: friction_before
    type(regime_state_t) :: new
    real(wp) :: t_at, remaining, piece, offset, slip_before, before_limit
    integer :: status, switches
    logical :: held, taken, switch_first
    ended = .false.
    t_at = t
    remaining = h_step
    t_stop = t + h_step
    do switches = 0, max_switches_per_step
      if (now%sliding) call sb%begin_step(now%s)
      if (now%sliding .and. .not. (switches == 0 .and. present(first))) &
        call choose_slip_law(sb, t_at, now%s, now%fs, remaining, res%n_rhs)
      ! a fixed step that switches on and on at one instant (a slip that stops
      ! where rolling needs just over mu N): its rest goes on sliding, and the
      ! slip left is the size of the step's friction impulse (stopped below)
      held = .not. stop_at_switch .and. switches >= chatter_switches .and. now%sliding
      piece = remaining
      taken = .false.
      if (switches == 0 .and. present(first)) then
        new = first                        ! (its stop bracket taken with it; the integrator holds its step)
        status = first_status
        taken = .true.
      else if (.not. held) then
        call stop_bracket(integrator, rolling, sb, t_at, remaining, now, res%n_rhs, piece, new, status, taken)
      end if
      if (.not. taken) call take(integrator, rolling, sb, t_at, piece, now, new, status, res%n_rhs)
      if (status /= status_completed) then
        ! a limit ends the case, unless the regime switches on the way there
        call end_at_limit(integrator, run, rolling, sb, t_at, piece, now, tally, res, switch_first, before_limit, new)
        if (.not. switch_first) then
          ended = .true.
          return
        end if
        piece = before_limit
      end if
      if (switches == 0 .and. present(friction_before) .and. .not. now%sliding) then
        if (.not. switch_crossed(sb, now, new)) &
          call graze_inside(integrator, rolling, sb, t_at, remaining, friction_before, now, new, res%n_rhs, piece)
      end if
      if (held .or. .not. switch_crossed(sb, now, new)) then
        call add_sliding_step(integrator, run, rolling, sb, t_at, remaining, now, new, tally, res)
        slip_before = now%slip_speed
        now = new
        if (now%stopped_at >= 0) run%stopped_at = now%stopped_at
        if (now%sliding .and. held .and. now%slip_speed >= slip_before) then
          ! the held rest of a step that chattered, whose slip the friction
          ! removes within a step and did not fall over it: it jitters at the
          ! size of a step's friction impulse and stops here where rolling
          ! can go on (the stop then has an error of up to a step or two).
          ! Elsewhere a slip that does not fall is the motion's (rolling
          ! needs close to mu N), which the substeps resolve.
          if (now%slip_speed <= sb%ball%mu * now%obs%reaction_normal * remaining &
              * (1 / sb%ball%mass + 1 / (sb%ball%inertia_factor * sb%ball%mass))) &
            call stop_sliding(rolling, sb, t_at + remaining, now, res, tally, at_rest_only=.true.)
        end if
        return
      end if
      call switch_inside(integrator, run, rolling, sb, t_at, piece, now, new, tally, res, offset, ended)
      if (ended) return
      remaining = remaining - offset
      if (remaining <= 0 .or. stop_at_switch) then
        t_stop = t_at
        return
      end if
    end do
    res%status = status_unstable          ! a step that switches on and on: chattering
    res%t_final = t_at
    ended = .true.
  end subroutine advance

  !> The step h from (t_at, now) to past crosses a switch: where (offset, by
  !> a root search on partial steps), the state there, and the regime that
  !> goes on from it (t_at and now moved there). A partial step that meets a
  !> limit counts as past the switch; one to the switch itself that meets one
  !> ends the case (ended).
  subroutine switch_inside(integrator, run, rolling, sb, t_at, h, now, past, tally, res, offset, ended)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(inout) :: t_at
    real(wp), intent(in) :: h
    type(regime_state_t), intent(inout) :: now
    type(regime_state_t), intent(in) :: past
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    real(wp), intent(out) :: offset
    logical, intent(out) :: ended
    type(root_search_t) :: search
    type(regime_state_t) :: x
    real(wp) :: g_start, g, trial
    integer :: k, status
    ended = .false.
    if (now%sliding) then
      g_start = sb%event_start_value(1)
    else
      g_start = switch_value(sb, now)
    end if
    call search%start(max(g_start, tiny(1.0_wp)), h, switch_value(sb, past), sb%event_tolerance(1) * h)
    do k = 1, max_event_trials
      if (search%done()) exit
      trial = search%trial()
      call take(integrator, rolling, sb, t_at, trial, now, x, status, res%n_rhs)
      g = -1
      if (status == status_completed) g = switch_value(sb, x)
      call search%report(trial, g)
    end do
    call take(integrator, rolling, sb, t_at, search%high, now, x, status, res%n_rhs)
    if (status /= status_completed) then
      call end_at_limit(integrator, run, rolling, sb, t_at, search%high, now, tally, res)
      ended = .true.
      return
    end if
    offset = x%reached                    ! (a fixed step's substeps may find the stop before search%high)
    call add_sliding_step(integrator, run, rolling, sb, t_at, offset, now, x, tally, res, at_stop=now%sliding)
    t_at = t_at + offset
    now = x
    if (now%stopped_at >= 0) run%stopped_at = now%stopped_at
    if (now%sliding) call finish_stop(integrator, run, rolling, sb, h, h - offset, t_at, now, tally, res, offset)
    if (now%sliding) then
      if (slip_stopped(sb, now, tally)) call observe_stopped(sb, t_at, now)
    end if
    call track_balance(run, res, t_at, now, tally)
    if (now%sliding) then
      call stop_sliding(rolling, sb, t_at, now, res, tally)
    else
      call start_sliding(sb, t_at, now, res, tally)
      call add_switch(res, t_at, switch_to_sliding)
    end if
  end subroutine switch_inside

  !> A located stop leaves a slip of up to stick_level of the episode's
  !> (where the event's function |u| - stick_level |u_start| crossed, or
  !> where the slip, below that, turned by a right angle), and so does a
  !> turn that the step h which found it could not resolve (a slip whose
  !> direction relaxes within a tenth of h: direction_unresolved): u reaches zero
  !> |u|^2 / (-u . u') later, to second order in that time, with the
  !> friction against u itself (past a turn the step's friction is against
  !> its start's slip, not u), and the piece to there (within room) is
  !> taken, again from its end while the slip left is above finish_level of
  !> the first (where the slip's direction still turns, its rate changes
  !> over the piece), so that the switch's time is the stop's to far below
  !> stick_level of the slip's time scale.
  subroutine finish_stop(integrator, run, rolling, sb, h, room, t_at, now, tally, res, offset)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run, rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: h, room
    real(wp), intent(inout) :: t_at, offset
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    real(wp), parameter :: finish_level = 1.0e-6_wp
    integer, parameter :: finish_pieces = 8
    type(regime_state_t) :: x
    real(wp) :: approach, piece, left, first_slip
    integer :: status, k
    logical :: turned
    if (.not. slip_stopped(sb, now, tally)) then         ! turned
      res%n_rhs = res%n_rhs + 1
      if (.not. direction_unresolved(sb, t_at, now%s, h)) return
    end if
    first_slip = now%slip_speed
    left = room
    do k = 1, finish_pieces
      if (k > 1 .and. .not. now%slip_speed > finish_level * first_slip) exit
      turned = .not. dot_product(slip_velocity(sb%ball, now%s), sb%slip_mode) > 0
      call sb%begin_step(now%s)
      if (turned) then
        call sb%rhs(t_at, now%s, now%fs)
        res%n_rhs = res%n_rhs + 1
      end if
      approach = -dot_product(slip_velocity(sb%ball, now%s), slip_rate(sb%ball, now%s, now%fs))
      if (.not. approach > 0) exit
      piece = now%slip_speed**2 / approach
      if (.not. piece < left) exit
      call take(integrator, rolling, sb, t_at, piece, now, x, status, res%n_rhs)
      if (status /= status_completed) exit
      piece = x%reached                      ! (a fixed step's substeps may find the stop before it)
      call add_sliding_step(integrator, run, rolling, sb, t_at, piece, now, x, tally, res, at_stop=.true.)
      t_at = t_at + piece
      offset = offset + piece
      left = left - piece
      now = x
    end do
  end subroutine finish_stop
end module ellroll_slide_run
