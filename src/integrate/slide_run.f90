!> One case that may slide (`&ball slip = 'slide'`): the ball rolls (the
!> rolling model's steps, fixed_step, on its six-number state) until the
!> friction rolling needs reaches mu N, slides (ellroll_sliding_ball, eight
!> numbers) until the slip stops with rolling's friction within mu N, and so
!> on. Both switches are located inside the step where they happen (a root
!> search on the method's own partial steps from the step's start); a
!> fixed-step method takes the rest of its step from the switch in the new
!> regime, so that its steps stay on the grid of dt; an adaptive method ends
!> its step at the switch. A limit of the model ends the case where the
!> method's partial steps first meet it.
module ellroll_slide_run
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_status, only: status_pending, status_completed, status_slip, status_unstable, status_rim
  use ellroll_ode, only: no_step_solution
  use ellroll_events, only: root_search_t, crossing_search_t, max_event_trials
  use ellroll_cases, only: case_t, output_plan_t, steps_per_sample, field_regime, field_slip_speed
  use ellroll_results, only: case_result_t
  use ellroll_figures, only: fig_sliding_time, fig_slip_episodes, fig_friction_energy, fig_slip_speed_max
  use ellroll_rolling_ball, only: observation_t, state_size, limit_status, normalize_normal, ball_derivative, observe
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, sliding_from_rolling, &
      observe_sliding, slip_velocity, stick, stick_level, slip_stop_time, sliding_derivative, center_velocity, &
      at_sliding_rim
  use ellroll_integrators, only: integrator_t, embedded_pair_t
  use ellroll_case_run, only: run_state_t, track, restart_case, record_sample, stop_asked, sample_due, stored
  use ellroll_fixed_step_run, only: fixed_step
  use ellroll_params, only: p_dt, p_velocity_x, p_velocity_z
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

  !> Model limits are located to this many units in the last place of t.
  real(wp), parameter :: limit_time_ulps = 16

  !> The state of a run that may slide: the regime and its state.
  type :: regime_state_t
    logical :: sliding = .false.
    real(wp) :: y(state_size) = 0, f(state_size) = 0           !< rolling
    real(wp) :: s(slide_state_size) = 0, fs(slide_state_size) = 0   !< sliding
    type(observation_t) :: obs
    real(wp) :: slip_speed = 0
  end type regime_state_t

  !> What the sliding adds to the summary as it goes.
  type :: slide_tally_t
    real(wp) :: sliding_time = 0
    integer(i8) :: episodes = 0
    real(wp) :: friction_energy = 0
    real(wp) :: slip_speed_max = 0
    real(wp) :: episode_slip_max = 0      !< the largest slip speed of the episode under way
  end type slide_tally_t

contains

  !> The case from (y, f) at t = 0 (start_case) to t_end or the limit it
  !> meets. A start whose friction exceeds mu (res%status slip), or with a
  !> velocity of the centre that is not rolling's, starts sliding.
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
    now%y = y
    now%f = f
    call observe(rolling%ball, 0.0_wp, y, f, now%obs)
    velocity = cs%param(p_velocity_x:p_velocity_z)
    if (all(ieee_is_finite(velocity))) then
      now%s = sliding_from_rolling(sb%ball, y)
      now%s(7:8) = velocity(1:2)
      if (norm2(slip_velocity(sb%ball, now%s)) > 0) then
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
      call record_regime_sample(res, 1_i8, now)         ! the start slides from t = 0
    end if
    res%status = status_completed
    select type (integrator)
    class is (embedded_pair_t)
      call adaptive_slide(integrator, cs, plan, run, rolling, sb, now, tally, res)
    class default
      call fixed_slide(integrator, cs, plan, run, rolling, sb, now, tally, res)
    end select
    res%reals(fig_sliding_time) = tally%sliding_time
    res%counts(fig_slip_episodes) = tally%episodes
    res%reals(fig_friction_energy) = tally%friction_energy
    res%reals(fig_slip_speed_max) = tally%slip_speed_max
  end subroutine slide_loop

  !> The first sample and the summary's start again from the sliding start.
  pure subroutine restart_samples(cs, run, res, now)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    type(regime_state_t), intent(in) :: now
    call record_regime_sample(res, 1_i8, now)
    call restart_case(cs, run, res, now%obs)
  end subroutine restart_samples

  !> A step end's track, its energy with the friction's work so far.
  pure subroutine track_balance(run, res, t, obs, tally)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    type(slide_tally_t), intent(in) :: tally
    run%friction_work = tally%friction_energy
    res%reals(fig_slip_speed_max) = tally%slip_speed_max
    call track(run, res, t, obs)
  end subroutine track_balance

  !> Every stored field's values at one output sample, the regime and the
  !> slip speed with them (a sliding observation's friction is mu N).
  pure subroutine record_regime_sample(res, sample, now)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    type(regime_state_t), intent(in) :: now
    call record_sample(res, sample, now%obs)
    if (.not. now%sliding) return
    if (stored(res, field_regime)) res%fields(field_regime)%values(1, sample) = 1
    if (stored(res, field_slip_speed)) res%fields(field_slip_speed)%values(1, sample) = now%slip_speed
  end subroutine record_regime_sample

  !> Fixed steps of dt, each from the state at its start to the grid point
  !> after it, through the switches inside it (advance).
  subroutine fixed_slide(integrator, cs, plan, run, rolling, sb, now, tally, res)
    class(integrator_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    integer(i8) :: k, n_steps, every, sample
    real(wp) :: t, t_stop
    logical :: ended
    n_steps = nint(cs%t_end / cs%param(p_dt), i8)
    every = steps_per_sample(cs, plan)
    t = 0
    do k = 1, n_steps
      if (stop_asked(k)) then
        res%status = status_pending
        return
      end if
      call advance(integrator, run, rolling, sb, t, cs%param(p_dt), .false., now, tally, res, ended, t_stop)
      res%n_steps = k
      if (ended) return
      t = k * cs%param(p_dt)
      call track_balance(run, res, t, now%obs, tally)
      sample = k / every + 1
      if (mod(k, every) == 0 .and. sample <= plan%n_samples) call record_regime_sample(res, sample, now)
    end do
    res%t_final = t
  end subroutine fixed_slide

  !> An embedded pair's steps, each ending at the next output sample or
  !> before, or at a switch of regime inside it.
  subroutine adaptive_slide(pair, cs, plan, run, rolling, sb, now, tally, res)
    class(embedded_pair_t), intent(inout) :: pair
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    type(regime_state_t) :: trial
    real(wp) :: t, h, h_max, t_next, next_sample_time, factor, window_start
    integer :: status, stalled, hovering, crawling
    integer(i8) :: attempts
    logical :: ended
    h_max = min(cs%t_end, cs%param(p_dt))
    if (.not. ieee_is_finite(h_max) .or. h_max <= 0) h_max = cs%t_end
    if (now%sliding) then
      call pair%initial_step(sb, 0.0_wp, now%s, now%fs, h_max, h, res%n_rhs)
    else
      call pair%initial_step(rolling%ball, 0.0_wp, now%y, now%f, h_max, h, res%n_rhs)
    end if
    t = 0
    attempts = 0
    stalled = 0
    hovering = 0
    crawling = 0
    window_start = 0
    do while (t < cs%t_end)
      attempts = attempts + 1
      if (stop_asked(attempts)) then
        res%status = status_pending
        return
      end if
      h = min(h, h_max, cs%t_end - t)
      t_next = t + h
      if (run%next_sample <= plan%n_samples) then
        next_sample_time = real(run%next_sample - 1, wp) * plan%interval
        if (next_sample_time > t .and. next_sample_time < t_next) t_next = next_sample_time
      end if
      if (cs%t_end - t_next <= 4 * spacing(cs%t_end)) t_next = cs%t_end
      h = t_next - t
      call take(pair, rolling, sb, t, h, now, trial, status, res%n_rhs)
      if (status == status_completed .and. .not. pair%error_norm <= 1) then
        res%n_rejected = res%n_rejected + 1
        h = h * max(0.2_wp, 0.9_wp * pair%error_norm**(-1.0_wp / pair%control_order()))
        if (h <= 16 * spacing(t)) then
          res%status = status_unstable
          res%t_final = t
          return
        end if
        cycle
      end if
      factor = 5
      if (pair%error_norm > 0) factor = min(5.0_wp, max(0.2_wp, 0.9_wp * pair%error_norm**(-1.0_wp / pair%control_order())))
      call advance(pair, run, rolling, sb, t, h, .true., now, tally, res, ended, t_next)
      res%n_steps = res%n_steps + 1
      if (ended) return
      ! steps too short to reach t_end in any time (a couple or a friction
      ! that flips at every stage about omega_t = 0 or u = 0): every
      ! max_hover_steps steps the case must have moved on by crawl_fraction
      ! of t_end per step on average
      if (mod(res%n_steps, int(max_hover_steps, i8)) == 0) then
        crawling = merge(1, 0, t_next - window_start < max_hover_steps * crawl_fraction * cs%t_end)
        window_start = t_next
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
        return
      end if
      t = t_next
      call track_balance(run, res, t, now%obs, tally)
      if (sample_due(run, plan, t)) then
        call record_regime_sample(res, run%next_sample, now)
        run%next_sample = run%next_sample + 1
      end if
      h = h * factor
    end do
    res%t_final = t
  end subroutine adaptive_slide

  !> One step of the method from (t, now) of size h in now's regime: the new
  !> state (normal projected), its derivative and outputs, and the status of
  !> the first limit met at a stage or at the end (0: completed).
  subroutine take(integrator, rolling, sb, t, h, now, new, status, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: now
    type(regime_state_t), intent(out) :: new
    integer, intent(out) :: status
    integer(i8), intent(inout) :: n_rhs
    new%sliding = now%sliding
    if (.not. now%sliding) then
      call fixed_step(integrator, rolling, t, now%y, now%f, h, new%y, new%f, new%obs, status, n_rhs)
      new%slip_speed = 0
      return
    end if
    call integrator%step(sb, t, now%s, now%fs, h, new%s, n_rhs)
    call normalize_normal(new%s)
    if (integrator%stage_limit == no_step_solution) then
      status = status_unstable
    else if (integrator%stage_limit /= 0) then
      status = integrator%stage_limit
    else if (at_sliding_rim(new%s)) then
      status = status_rim
    else
      status = status_completed
    end if
    if (status /= status_completed) return      ! (a state past a limit: its outputs may overflow)
    call observe_sliding(sb, t + h, new%s, new%obs, new%slip_speed, new%fs)
    n_rhs = n_rhs + 1
    status = limit_status(rolling%ball, new%s(1:6), new%obs)
  end subroutine take

  !> A step of size h_step from (t, now), through the switches of regime
  !> on the way: a piece that meets a limit ends the case there (ended); a
  !> switch inside it is located, made, and the rest of the step taken in
  !> the new regime (fixed steps), or the step ends there (stop_at_switch).
  !> t_stop: where the step ended.
  subroutine advance(integrator, run, rolling, sb, t, h_step, stop_at_switch, now, tally, res, ended, t_stop)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: t, h_step
    logical, intent(in) :: stop_at_switch
    type(regime_state_t), intent(inout) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    logical, intent(out) :: ended
    real(wp), intent(out) :: t_stop
    type(regime_state_t) :: new
    real(wp) :: t_at, remaining, piece, offset, slip_before
    integer :: status, switches
    logical :: held, taken
    ended = .false.
    t_at = t
    remaining = h_step
    t_stop = t + h_step
    do switches = 0, max_switches_per_step
      if (now%sliding) call sb%begin_step(now%s)
      ! a fixed step that switches on and on at one instant (a slip that stops
      ! where rolling needs just over mu N): its rest goes on sliding, and the
      ! slip left is the size of the step's friction impulse (stopped below)
      held = .not. stop_at_switch .and. switches >= chatter_switches .and. now%sliding
      piece = remaining
      taken = .false.
      if (.not. held) call stop_bracket(integrator, rolling, sb, t_at, remaining, now, res%n_rhs, piece, new, status, &
                                        taken)
      if (.not. taken) call take(integrator, rolling, sb, t_at, piece, now, new, status, res%n_rhs)
      if (status /= status_completed) then
        call end_at_limit(integrator, run, rolling, sb, t_at, piece, now, tally, res)
        ended = .true.
        return
      end if
      if (held .or. .not. switch_crossed(sb, now, new)) then
        call add_sliding_step(integrator, sb, t_at, remaining, now, new, tally, res%n_rhs)
        slip_before = now%slip_speed
        now = new
        if (now%sliding .and. .not. stop_at_switch .and. now%slip_speed >= slip_before) then
          ! a slip that the friction removes within a fixed step, and that
          ! did not fall over this one: the method's stages around u = 0 do
          ! not resolve its stop (the friction's direction turns there), and
          ! it jitters at the size of a step's friction impulse: it stops
          ! here where rolling can go on (the stop then has an error of up
          ! to a step or two)
          if (now%slip_speed <= sb%ball%mu * now%obs%reaction_normal * remaining &
              * (1 / sb%ball%mass + 1 / (sb%ball%inertia_factor * sb%ball%mass))) &
            call stop_sliding(rolling, sb, t_at + remaining, now, res, tally, at_rest_only=.true.)
        end if
        return
      end if
      call switch_inside(integrator, run, rolling, sb, t_at, piece, now, tally, res, offset, ended)
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

  !> Whether now slides with a slip within the pair's tolerance of zero,
  !> measured against the contact's speeds (|V_C| + R |omega|).
  logical function hovering_slip(pair, sb, now) result(hovering)
    class(embedded_pair_t), intent(in) :: pair
    type(sliding_ball_t), intent(in) :: sb
    type(regime_state_t), intent(in) :: now
    real(wp) :: scale
    hovering = .false.
    if (.not. now%sliding) return            ! (a rolling state's s is not set)
    scale = norm2(center_velocity(now%s)) + sb%ball%radius * norm2(now%s(4:6))
    hovering = now%slip_speed <= 10 * (pair%atol + pair%rtol * scale)
  end function hovering_slip

  !> The piece of the step to take from (t_at, now): all that remains, or,
  !> where the slip's time scale (slip_stop_time) puts its stop inside
  !> it, twice that time where the slip has stopped by then (the stop is
  !> searched for inside that): past a stop the method's stages throw the
  !> slip the other way, by the remaining time over the stop's, which
  !> overflows for a stiff slip (a large mu, a small inertia factor). Where
  !> the piece is that trial's (taken), new and status are its step.
  subroutine stop_bracket(integrator, rolling, sb, t_at, remaining, now, n_rhs, piece, new, status, taken)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t_at, remaining
    type(regime_state_t), intent(in) :: now
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(out) :: piece
    type(regime_state_t), intent(inout) :: new
    integer, intent(inout) :: status
    logical, intent(out) :: taken
    real(wp) :: bracket
    piece = remaining
    taken = .false.
    if (.not. now%sliding) return
    bracket = 2 * slip_stop_time(sb%ball, now%s, now%obs%reaction_normal)
    if (.not. bracket < remaining .or. .not. bracket > 0) return    ! (no slip: nothing to bracket)
    call take(integrator, rolling, sb, t_at, bracket, now, new, status, n_rhs)
    taken = status == status_completed .and. switch_crossed(sb, now, new)
    if (taken) piece = bracket
  end subroutine stop_bracket

  !> Whether the regime switches between now and new (one step apart):
  !> rolling needs more friction than mu N at new; or the slip, nonzero at
  !> now, turned by a right angle or more.
  logical function switch_crossed(sb, now, new) result(crossed)
    type(sliding_ball_t), intent(in) :: sb
    type(regime_state_t), intent(in) :: now, new
    if (now%sliding) then
      crossed = sb%event_crossed(now%s, new%s) /= 0
    else
      crossed = new%obs%friction_needed > sb%ball%mu
    end if
  end function switch_crossed

  !> The switch's function at state x of a step from now: positive before
  !> it (rolling: mu - |F_t|/N; sliding: the slip along its direction at the
  !> step's start).
  real(wp) function switch_value(sb, x) result(g)
    type(sliding_ball_t), intent(in) :: sb
    type(regime_state_t), intent(in) :: x
    if (x%sliding) then
      g = sb%event_value(1, x%s)
    else
      g = sb%ball%mu - x%obs%friction_needed
    end if
  end function switch_value

  !> The step h from (t_at, now) crosses a switch: where (offset, by a root
  !> search on partial steps), the state there, and the regime that goes on
  !> from it (t_at and now moved there). A partial step that meets a limit
  !> counts as past the switch; one to the switch itself that meets one
  !> ends the case (ended).
  subroutine switch_inside(integrator, run, rolling, sb, t_at, h, now, tally, res, offset, ended)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(inout) :: t_at
    real(wp), intent(in) :: h
    type(regime_state_t), intent(inout) :: now
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
    call take(integrator, rolling, sb, t_at, h, now, x, status, res%n_rhs)
    call search%start(max(g_start, tiny(1.0_wp)), h, switch_value(sb, x), sb%event_tolerance(1) * h)
    do k = 1, max_event_trials
      if (search%done()) exit
      trial = search%trial()
      call take(integrator, rolling, sb, t_at, trial, now, x, status, res%n_rhs)
      g = -1
      if (status == status_completed) g = switch_value(sb, x)
      call search%report(trial, g)
    end do
    offset = search%high
    call take(integrator, rolling, sb, t_at, search%high, now, x, status, res%n_rhs)
    if (status /= status_completed) then
      call end_at_limit(integrator, run, rolling, sb, t_at, search%high, now, tally, res)
      ended = .true.
      return
    end if
    call add_sliding_step(integrator, sb, t_at, search%high, now, x, tally, res%n_rhs)
    t_at = t_at + search%high
    now = x
    call track_balance(run, res, t_at, now%obs, tally)
    if (now%sliding) then
      call stop_sliding(rolling, sb, t_at, now, res, tally)
    else
      call start_sliding(sb, t_at, now, res, tally)
    end if
  end subroutine switch_inside

  !> The rolling state now (its friction at mu N) goes on sliding: u = 0,
  !> the friction keeps the direction rolling needed, and u grows against it.
  subroutine start_sliding(sb, t, now, res, tally)
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: t
    type(regime_state_t), intent(inout) :: now
    type(case_result_t), intent(inout) :: res
    type(slide_tally_t), intent(inout) :: tally
    real(wp) :: tangential(3), size_t
    tangential = now%obs%reaction - now%obs%reaction_normal * now%obs%normal
    size_t = norm2(tangential)
    sb%slip_mode = 0
    if (size_t > 0) sb%slip_mode = -tangential / size_t
    now%s = sliding_from_rolling(sb%ball, now%y)
    now%sliding = .true.
    call sb%begin_step(now%s)
    call observe_sliding(sb, t, now%s, now%obs, now%slip_speed, now%fs)
    res%n_rhs = res%n_rhs + 1
    tally%episodes = tally%episodes + 1
    tally%episode_slip_max = 0
  end subroutine start_sliding

  !> The slip of sliding state now has fallen to stick_level of its value
  !> at the piece's start, or turned by a right angle. Where it has stopped
  !> (the first, or the slip is below stick_level of the episode's largest:
  !> where rolling's friction is close to mu N the slip spirals into zero,
  !> turning by a right angle ever more often; the rest of the slip is
  !> stopped by an impulse, stick, its work added to the friction's),
  !> the ball rolls on from there where rolling's friction is within mu N,
  !> else slides on in the direction that friction gives. Where the slip has
  !> only turned, the ball slides on against its new direction.
  subroutine stop_sliding(rolling, sb, t, now, res, tally, at_rest_only)
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: t
    type(regime_state_t), intent(inout) :: now
    type(case_result_t), intent(inout) :: res
    type(slide_tally_t), intent(inout) :: tally
    logical, intent(in), optional :: at_rest_only   !< stop it only where rolling goes on (a slip not located)
    type(regime_state_t) :: rolled
    if (present(at_rest_only)) then
      rolled%y = stick(sb%ball, now%s)
      call ball_derivative(rolling%ball, t, rolled%y, rolled%f)
      call observe(rolling%ball, t, rolled%y, rolled%f, rolled%obs)
      res%n_rhs = res%n_rhs + 1
      if (rolled%obs%friction_needed > sb%ball%mu) return
    else if (now%slip_speed > stick_level * max(2 * norm2(sb%slip_at_start), tally%episode_slip_max)) then
      call sb%begin_step(now%s)
      return
    end if
    rolled%sliding = .false.
    rolled%y = stick(sb%ball, now%s)
    call ball_derivative(rolling%ball, t, rolled%y, rolled%f)
    call observe(rolling%ball, t, rolled%y, rolled%f, rolled%obs)
    res%n_rhs = res%n_rhs + 1
    rolled%slip_speed = 0
    tally%friction_energy = tally%friction_energy + (now%obs%energy - rolled%obs%energy)
    now = rolled
    if (rolled%obs%friction_needed > sb%ball%mu) then
      call start_sliding(sb, t, now, res, tally)
      tally%episodes = tally%episodes - 1          ! the same episode, slipping another way
    end if
  end subroutine stop_sliding

  !> The piece of step h from (t, from) to `to` that the integrator has just
  !> taken adds to the sliding figures (add_sliding). An embedded pair's
  !> friction work is the 3-point Gauss-Legendre rule on the piece's dense
  !> output (exact to degree 5, its error far below the pair's own over
  !> the long steps the pair takes; the trapezoidal rule's h^2 error there
  !> does not fall with the tolerance); a fixed step's the trapezoidal rule.
  subroutine add_sliding_step(integrator, sb, t, h, from, to, tally, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: from, to
    type(slide_tally_t), intent(inout) :: tally
    integer(i8), intent(inout) :: n_rhs
    real(wp), parameter :: offset = 0.3872983346207416885_wp      ! sqrt(15) / 10
    real(wp), parameter :: nodes(3) = [0.5_wp - offset, 0.5_wp, 0.5_wp + offset]
    real(wp), parameter :: weights(3) = [5.0_wp, 8.0_wp, 5.0_wp] / 18
    real(wp) :: y(slide_state_size), rate(slide_state_size), big_n, work
    integer :: i
    if (.not. from%sliding) return
    select type (integrator)
    class is (embedded_pair_t)
      work = 0
      do i = 1, 3
        call integrator%dense(sb, nodes(i), y, n_rhs)
        call sliding_derivative(sb, t + nodes(i) * h, y, rate, big_n)
        work = work + weights(i) * max(big_n, 0.0_wp) * norm2(slip_velocity(sb%ball, y))
      end do
      n_rhs = n_rhs + 3
      call add_sliding(sb, h, from, to, tally, h * sb%ball%mu * work)
    class default
      call add_sliding(sb, h, from, to, tally)
    end select
  end subroutine add_sliding_step

  !> A piece of step h from `from` to `to` adds to the sliding figures:
  !> its time, the friction's work mu N |u| (`work` where given, else the
  !> trapezoidal rule over the piece; the pieces end at the switches), the
  !> largest slip speed.
  pure subroutine add_sliding(sb, h, from, to, tally, work)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: h
    type(regime_state_t), intent(in) :: from, to
    type(slide_tally_t), intent(inout) :: tally
    real(wp), intent(in), optional :: work
    if (.not. from%sliding) return
    tally%sliding_time = tally%sliding_time + h
    if (present(work)) then
      tally%friction_energy = tally%friction_energy + work
    else
      tally%friction_energy = tally%friction_energy + 0.5_wp * h * sb%ball%mu &
          * (from%obs%reaction_normal * from%slip_speed + to%obs%reaction_normal * to%slip_speed)
    end if
    tally%slip_speed_max = max(tally%slip_speed_max, to%slip_speed)
    tally%episode_slip_max = max(tally%episode_slip_max, to%slip_speed)
  end subroutine add_sliding

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

  !> The step h from (t, now) met a limit: the case ends where the method's
  !> partial steps from now first meet it (to limit_time_ulps of t), with
  !> its status; the last valid state (an embedded pair's: within its
  !> tolerance, not only short of the limit: next to the rim a partial
  !> step's stages can pass it and come back far off) adds to the summary.
  subroutine end_at_limit(integrator, run, rolling, sb, t, h, now, tally, res)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: now
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
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
      if (valid) then
        last_valid = x
      else if (status /= status_completed) then
        crossed = status
      end if
      call search%report(trial, valid)
    end do
    if (search%valid > 0) then
      call add_sliding(sb, search%valid, now, last_valid, tally)
      call track_balance(run, res, t + search%valid, last_valid%obs, tally)
    end if
    if (crossed == status_completed) crossed = status_unstable
    res%status = crossed
    res%t_final = t + search%valid
  end subroutine end_at_limit
end module ellroll_slide_run
