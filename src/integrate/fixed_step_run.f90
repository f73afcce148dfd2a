!> One case with a fixed-step method: each step checked against the model's
!> limits at every state it evaluates the model at (its stages) and at its
!> end, the output samples taken at the steps; the case ends where the flow
!> from the state before a step that meets a limit meets it, or, where the
!> flow meets none, goes on past that step taken in pieces (end_at_limit).
module ellroll_fixed_step_run
  use ellroll_kinds, only: wp, i8
  use ellroll_status, only: status_pending, status_completed, status_unstable
  use ellroll_ode, only: no_step_solution
  use ellroll_excitation, only: excitation_none, base_acceleration
  use ellroll_events, only: event_search_t, max_event_trials
  use ellroll_linear, only: fastest_rate
  use ellroll_cases, only: case_t, output_plan_t, steps_per_sample
  use ellroll_results, only: case_result_t
  use ellroll_rolling_ball, only: observation_t, state_size, observe, limit_status, ball_derivative, normalize_normal, &
      law_exact, law_held, event_rest, at_rest
  use ellroll_turns, only: turn_resolved, choose_rolling_law
  use ellroll_integrators, only: integrator_t, embedded_pair_t, stability_limit
  use ellroll_ball_steppers, only: ball_fixed_step
  use ellroll_gauss4, only: gauss4_t
  use ellroll_case_run, only: run_state_t, track, record_sample, stop_asked, stopping, settled, &
      regular_steps, last_fixed_step, fixed_step_time
  use ellroll_flow_to_limit, only: follow_flow_to_limit
  use ellroll_params, only: p_dt
  implicit none
  private

  public :: fixed_step_loop, end_at_limit, fixed_step, step_through_event, step_with_events, exact_end, choose_law, &
            older_checkpoint_step

  !> Each step of the method's own approach to a limit covers this part of
  !> what remains to the nearest offset known to meet it.
  real(wp), parameter :: approach_fraction = 0.125_wp

  !> The state is kept every checkpoint_steps steps: a step that meets a
  !> limit is followed to it from the older of the last two (end_at_limit).
  integer(i8), parameter, public :: checkpoint_steps = 8



contains

  subroutine fixed_step_loop(integrator, cs, plan, run, y, f, res)
    class(integrator_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    real(wp), intent(inout) :: y(state_size), f(state_size)
    type(case_result_t), intent(inout) :: res
    real(wp) :: y_new(state_size), f_new(state_size), t, t_event
    real(wp) :: y_checkpoint(state_size), y_older_checkpoint(state_size)
    type(observation_t) :: obs
    integer(i8) :: k, n_steps, n_last, every, sample
    integer :: status, event

    n_steps = regular_steps(cs)
    n_last = last_fixed_step(cs, run)     ! past t_end (settle): on until the ball is at rest
    every = steps_per_sample(cs, plan)
    t = 0
    y_checkpoint = y
    y_older_checkpoint = y
    do k = 1, n_last
      if (stop_asked(k)) then
        res%status = status_pending
        return
      end if
      if (run%ball%nonsmooth()) then
        call step_with_events(integrator, run, t, y, f, cs%param(p_dt), y_new, f_new, obs, status, res%n_rhs, event, &
                              t_event)
        if (event /= 0) run%stopped_at = t_event
      else
        call fixed_step(integrator, run, t, y, f, cs%param(p_dt), y_new, f_new, obs, status, res%n_rhs)
      end if
      if (status /= status_completed) then
        call end_at_limit(integrator, run, plan, cs%t_end, y_older_checkpoint, k - 1, y, f, cs%param(p_dt), &
            every, status, res, &
                          y_new, f_new, obs)
        if (res%status /= status_completed) then
          res%n_steps = k
          return
        end if
      end if
      y = y_new
      f = f_new
      t = k * cs%param(p_dt)
      res%n_steps = k
      if (mod(k, checkpoint_steps) == 0) then
        y_older_checkpoint = y_checkpoint
        y_checkpoint = y
      end if
      call track(run, res, t, obs)
      sample = k / every + 1
      if (mod(k, every) == 0 .and. sample <= plan%n_samples) call record_sample(res, sample, obs)
      if (k >= n_steps .and. n_last > n_steps) then
        if (settled(run, t)) exit
      end if
    end do
    res%t_final = fixed_step_time(cs, res%n_steps, t)
  end subroutine fixed_step_loop

  !> One step of size h from (t, y, f) in the mode the model gives y
  !> (begin_step), through an event of the model inside it
  !> (step_through_event): event, its number (0: none), and t_event, where
  !> the model acted (< 0: a limit met first).
  recursive subroutine step_with_events(integrator, run, t, y, f, h, y_new, f_new, obs, status, n_rhs, event, t_event)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    real(wp), intent(out) :: y_new(state_size), f_new(state_size)
    type(observation_t), intent(out) :: obs
    integer, intent(out) :: status, event
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(out) :: t_event
    real(wp) :: f_start(state_size)
    f_start = f
    if (run%ball%nonsmooth()) then
      call run%ball%begin_step(y)
      if (fixed_steps(integrator)) call choose_law(run, t, y, h, f_start, n_rhs, release=implicit_stages(integrator))
    end if
    call fixed_step(integrator, run, t, y, f_start, h, y_new, f_new, obs, status, n_rhs)
    if (status /= status_completed .and. implicit_stages(integrator)) then
      if (at_rest(run%ball, t, y)) then
        call step_from_hold(integrator, run, t, y, h, y_new, f_new, obs, status, n_rhs, event, t_event)
        return
      end if
    end if
    event = 0
    t_event = -1
    if (status == status_completed .and. run%ball%nonsmooth()) event = run%ball%event_crossed(y, y_new)
    if (event /= 0) call step_through_event(integrator, run, event, t, y, f_start, h, y_new, f_new, obs, status, &
                                            n_rhs, t_event)
    ! held past the stop, the couple drives the rolling back ever faster (N
    ! grows with omega^2) and the step can end past a limit: the stop it
    ! holds comes first (docs/model.md, "Rolling resistance")
    if (status /= status_completed .and. run%ball%rolling_law == law_held) then
      event = event_rest
      call step_through_event(integrator, run, event, t, y, f_start, h, y_new, f_new, obs, status, n_rhs, t_event, &
                              passed=.true.)
      if (t_event < 0) event = 0
    end if
    if (run%ball%rolling_law /= law_exact) then
      run%ball%rolling_law = law_exact
      if (event == 0 .and. status == status_completed) call exact_end(run, t + h, y_new, f_new, n_rhs)
    end if
  end subroutine step_with_events

  !> The couple's law for a fixed step h from (t, y) (choose_rolling_law);
  !> f: the derivative at y with the couple against omega_t on entry, in
  !> the law chosen on return.
  subroutine choose_law(run, t, y, h, f, n_rhs, release)
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, y(state_size), h
    real(wp), intent(inout) :: f(state_size)
    integer(i8), intent(inout) :: n_rhs
    logical, intent(in), optional :: release      !< (choose_rolling_law's)
    call choose_rolling_law(run%ball, t, y, f, h, release)
    if (run%ball%rolling_law == law_exact) return
    call ball_derivative(run%ball, t, y, f)
    n_rhs = n_rhs + 1
  end subroutine choose_law

  !> The derivative at the end (t, y) of a step taken in another law of the
  !> couple, in law_exact: the model's there, the next step's start (the
  !> step's outputs there stay its law's).
  subroutine exact_end(run, t, y, f, n_rhs)
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: t, y(state_size)
    real(wp), intent(out) :: f(state_size)
    integer(i8), intent(inout) :: n_rhs
    call ball_derivative(run%ball, t, y, f)
    n_rhs = n_rhs + 1
  end subroutine exact_end

  !> Whether the method takes fixed steps (the couple's law is chosen per
  !> step: choose_rolling_law); an embedded pair controls its steps instead.
  logical function fixed_steps(integrator)
    class(integrator_t), intent(in) :: integrator
    select type (integrator)
    class is (embedded_pair_t)
      fixed_steps = .false.
    class default
      fixed_steps = .true.
    end select
  end function fixed_steps

  !> A step h from (t, y), where the couple holds the ball at rest, of a
  !> method whose stages solve equations (gauss4), that the couple lets go
  !> inside the step (a stage or its end past the hold): no stage polynomial
  !> follows the rest and then the rolling, so the ball stays as it is up to
  !> where the couple first lets go (at_rest, bisected to the rest's event
  !> tolerance from the first of the Gauss nodes and the end that is past
  !> it), and takes the rest of the step from there (step_with_events:
  !> from rest, the release's law). A step held at its nodes and end keeps
  !> the status of the step taken whole.
  recursive subroutine step_from_hold(integrator, run, t, y, h, y_new, f_new, obs, status, n_rhs, event, t_event)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, y(state_size), h
    real(wp), intent(inout) :: y_new(state_size), f_new(state_size)
    type(observation_t), intent(inout) :: obs
    integer, intent(inout) :: status
    integer(i8), intent(inout) :: n_rhs
    integer, intent(out) :: event
    real(wp), intent(out) :: t_event
    real(wp), parameter :: nodes(3) = [0.5_wp - sqrt(3.0_wp) / 6, 0.5_wp + sqrt(3.0_wp) / 6, 1.0_wp]
    real(wp) :: low, high, middle, f_at(state_size)
    integer :: k
    event = 0
    t_event = -1
    call run%ball%begin_step(y)
    high = 0
    do k = 1, size(nodes)
      n_rhs = n_rhs + 1
      if (.not. at_rest(run%ball, t + nodes(k) * h, y)) then
        high = nodes(k) * h
        exit
      end if
    end do
    if (.not. high > 0) return
    low = 0
    do k = 1, max_event_trials
      if (high - low <= run%ball%event_tolerance(event_rest) * h) exit
      middle = low + (high - low) / 2
      n_rhs = n_rhs + 1
      if (at_rest(run%ball, t + middle, y)) then
        low = middle
      else
        high = middle
      end if
    end do
    call ball_derivative(run%ball, t + high, y, f_at)
    n_rhs = n_rhs + 1
    call step_with_events(integrator, run, t + high, y, f_at, h - high, y_new, f_new, obs, status, n_rhs, event, t_event)
  end subroutine step_from_hold

  !> Whether the method's stages solve equations (gauss4): a step from rest
  !> that the couple lets go takes law_implicit (choose_rolling_law's release).
  pure logical function implicit_stages(integrator)
    class(integrator_t), intent(in) :: integrator
    select type (integrator)
    type is (gauss4_t)
      implicit_stages = .true.
    class default
      implicit_stages = .false.
    end select
  end function implicit_stages

  !> A step of size h from (t, y, f) in which an event of the model happens
  !> (event_crossed): it is cut where the event's function changes sign
  !> (event_search_t on the method's own partial steps, a step that meets a
  !> limit counting as past it), the model acts there (apply_event; an
  !> embedded pair's rolling that turned in 3D, turn_resolved, goes on), and the
  !> rest of the step is taken from there in the mode the model gives that
  !> state (begin_step), so that the steps stay on the grid of dt. y_new:
  !> the whole step's end, where the event was seen, on entry; the end of
  !> the step taken through it on return.
  recursive subroutine step_through_event(integrator, run, event, t, y, f, h, y_new, f_new, obs, status, n_rhs, t_event, &
                                          passed)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(in) :: run
    integer, intent(in) :: event
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    real(wp), intent(inout) :: y_new(state_size)
    real(wp), intent(out) :: f_new(state_size)
    type(observation_t), intent(out) :: obs
    integer, intent(out) :: status
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(out) :: t_event       !< where the model acted (< 0: a limit met first)
    logical, intent(in), optional :: passed  !< y_new is past a model limit (the event counts as passed there)
    real(wp) :: y_at(state_size), f_at(state_size), offset, y_rest(state_size), t_later
    type(event_search_t) :: search
    type(run_state_t) :: after
    integer :: k, later
    logical :: stops
    call search%begin(run%ball, event, y_new, h, passed)
    do k = 1, max_event_trials
      if (search%done()) exit
      offset = search%trial()
      call fixed_step(integrator, run, t, y, f, offset, y_at, f_at, obs, status, n_rhs)
      call search%report_state(run%ball, offset, y_at, status == status_completed)
    end do
    t_event = -1
    call fixed_step(integrator, run, t, y, f, search%high, y_at, f_at, obs, status, n_rhs)
    if (status /= status_completed) return
    t_event = t + search%high
    after = run
    select type (integrator)
    class is (embedded_pair_t)
      stops = .not. turn_resolved(run%ball, t + search%high, y_at, f_at, h, integrator%atol + integrator%rtol)
    class default
      ! a fixed step rolls on only where the couple could not hold the ball there
      y_rest = y_at
      call after%ball%apply_event(event, y_rest)
      stops = at_rest(after%ball, t + search%high, y_rest)
      n_rhs = n_rhs + 1
      if (.not. stops) stops = .not. turn_resolved(run%ball, t + search%high, y_at, f_at, h, 0.0_wp)
    end select
    if (stops) call after%ball%apply_event(event, y_at)
    call after%ball%begin_step(y_at)
    call ball_derivative(after%ball, t + search%high, y_at, f_at)
    n_rhs = n_rhs + 1
    if (implicit_stages(integrator)) then
      ! gauss4's stages cannot follow a couple that turns at the event (from
      ! rest it turns without bound): the rest of the step is a step of its
      ! own, in the law of a step from rest (step_with_events: released, or
      ! held), and the model's last act in it is the step's event
      call step_with_events(integrator, after, t + search%high, y_at, f_at, h - search%high, y_new, f_new, obs, &
                            status, n_rhs, later, t_later)
      if (later /= 0 .and. t_later >= 0) t_event = t_later
    else
      call fixed_step(integrator, after, t + search%high, y_at, f_at, h - search%high, y_new, f_new, obs, status, &
                      n_rhs)
    end if
  end subroutine step_through_event

  !> The step at which the older of the two checkpoints lies after n_done
  !> steps: checkpoint_steps to 2 checkpoint_steps - 1 steps back, or the start.
  elemental integer(i8) function older_checkpoint_step(n_done)
    integer(i8), intent(in) :: n_done
    older_checkpoint_step = max(0_i8, (n_done / checkpoint_steps - 1) * checkpoint_steps)
  end function older_checkpoint_step

  !> One step of a fixed-step method from (t, y, f): the new state projected,
  !> f and the derived outputs there, and the limits checked at the stages
  !> and at the new state (the first met wins). RK4 takes the fused step of
  !> the ball (the same arithmetic, tested against the generic one); other
  !> methods their own. Once the run is asked to stop, the step fails at
  !> once (stopping), unmoved.
  subroutine fixed_step(integrator, run, t, y, f, h, y_new, f_new, obs, status, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    real(wp), intent(out) :: y_new(state_size), f_new(state_size)
    type(observation_t), intent(out) :: obs
    integer, intent(out) :: status
    integer(i8), intent(inout) :: n_rhs
    integer :: stage_limit
    real(wp) :: base(3)
    if (stopping()) then
      y_new = y
      f_new = f
      call observe(run%ball, t, y, f, obs)
      status = status_unstable
      return
    end if
    call ball_fixed_step(integrator, run%ball, t, y, f, h, y_new, stage_limit, n_rhs)
    call normalize_normal(y_new)
    base = 0                                  ! the cup's acceleration, looked up once
    if (run%ball%excitation%kind /= excitation_none) base = base_acceleration(run%ball%excitation, t + h)
    call ball_derivative(run%ball, t + h, y_new, f_new, base=base)
    n_rhs = n_rhs + 1
    if (stage_limit == 0) then
      call observe(run%ball, t + h, y_new, f_new, obs, base)
      status = limit_status(run%ball, y_new, obs)
      return
    end if
    ! a step past a limit at a stage, or without solution: its end is no state
    ! of the model (the reaction there can overflow); obs is the start's
    call observe(run%ball, t, y, f, obs)
    status = stage_limit
    if (stage_limit == no_step_solution) status = status_unstable
  end subroutine fixed_step

  !> The step after n_done steps of size h, from the valid state (y, f),
  !> met a limit (status). The case ends where the exact flow from the
  !> method's state at the older checkpoint (y_checkpoint, at step
  !> older_checkpoint_step(n_done)) first meets a model limit, within two
  !> steps from the last state and not after t_end (follow_flow_to_limit),
  !> with that limit's status. Near the fit limit the solution has a
  !> square-root singularity: the method's last steps towards it err far
  !> more than its order says (RK4 at dt = 1e-3 on the paper cup: its own
  !> trajectory meets the limit up to 5e-6 s late, the flow from one step
  !> back 2e-7 s early, from 8 steps back within 1e-9 s of the true
  !> crossing). The end time then has the method's error up to the
  !> checkpoint only. Where the flow leaves the model before the last state,
  !> the samples after its end are dropped; after it, the samples up to its
  !> end are the flow's. Where the flow stays inside, the step is taken
  !> again in pieces (step_in_pieces): the case goes on from its end
  !> (res%status stays completed; y_new, f_new, obs at t + h), or ends where
  !> the method's own trajectory meets the limit. Where h was beyond the
  !> method's stability at the start ('unstable': the linearised motion's
  !> fastest rate times h past stability_limit; the limit was met by the
  !> method's own growth), the method's own trajectory is followed
  !> (approach_on_own_steps).
  subroutine end_at_limit(integrator, run, plan, t_end, y_checkpoint, n_done, y, f, h, every, status, res, &
                          y_new, f_new, obs)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(output_plan_t), intent(in) :: plan
    real(wp), intent(in) :: t_end, y_checkpoint(state_size), y(state_size), f(state_size), h
    integer(i8), intent(in) :: n_done, every
    integer, intent(in) :: status
    type(case_result_t), intent(inout) :: res
    real(wp), intent(out) :: y_new(state_size), f_new(state_size)
    type(observation_t), intent(out) :: obs
    real(wp) :: t, t_checkpoint
    logical :: met
    t = n_done * h
    y_new = y
    f_new = f
    if (beyond_stability(integrator, run, h)) then
      call approach_on_own_steps(integrator, run, t, y, f, h, status, res)
      res%status = status_unstable
      return
    end if
    t_checkpoint = older_checkpoint_step(n_done) * h
    run%next_sample = res%n_recorded + 1        ! the first sample after t, should the flow pass it
    call follow_flow_to_limit(run, plan, t_checkpoint, y_checkpoint, t, min(t + 2 * h, max(t_end, t + h)), res, met)
    if (met) then
      if (res%t_final < t) res%n_recorded = min(res%n_recorded, int(res%t_final / h, i8) / every + 1)
    else
      ! the flow's steps left the ball in the mode of their own last start
      ! (begin_step): the pieces are of the step from y, f the derivative there
      if (run%ball%nonsmooth()) call run%ball%begin_step(y)
      call step_in_pieces(integrator, run, t, y, f, h, res, y_new, f_new, obs)
    end if
  end subroutine end_at_limit

  !> The step h from (t, y, f), which met a limit that the exact flow does
  !> not meet, taken again in pieces of h / 2^j: a piece that meets a limit
  !> is halved, the pieces after it grow back, and the step still ends at
  !> t + h, on the grid of dt. A whole step can meet a limit that the path
  !> does not: at a stage (RK4's last stage, y + h k3, lies on a straight
  !> line off the curved path and leaves the model where the path grazes the
  !> rim closer than about h^2 |n_z''| / 2), where its equations have no
  !> solution (the Gauss method's, next to the fit limit's singularity), or
  !> at its end, by its own error where the path passes close to that
  !> singularity (its derivatives grow as the inverse distance to it). Every
  !> piece's end but the last adds to the summary. All pieces inside:
  !> res%status stays completed, the step's end in y_new, f_new, obs. A piece
  !> of h / 2^max_halvings that still meets a limit: the method's own
  !> trajectory meets it, and the case ends there (approach_on_own_steps
  !> from the piece's start).
  subroutine step_in_pieces(integrator, run, t, y, f, h, res, y_new, f_new, obs)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    type(case_result_t), intent(inout) :: res
    real(wp), intent(out) :: y_new(state_size), f_new(state_size)
    type(observation_t), intent(out) :: obs
    integer, parameter :: max_halvings = 20
    integer(i8), parameter :: whole = 2_i8**max_halvings
    real(wp) :: y_at(state_size), f_at(state_size), t_at, width
    integer(i8) :: done, piece
    integer :: status
    done = 0
    piece = whole
    t_at = t
    y_at = y
    f_at = f
    do while (done < whole)
      width = h * (real(piece, wp) / real(whole, wp))
      call fixed_step(integrator, run, t_at, y_at, f_at, width, y_new, f_new, obs, status, res%n_rhs)
      if (status == status_completed) then
        done = done + piece
        t_at = t + h * (real(done, wp) / real(whole, wp))
        y_at = y_new
        f_at = f_new
        if (done < whole) call track(run, res, t_at, obs)
        if (mod(done, 2 * piece) == 0) piece = 2 * piece
      else if (piece > 1) then
        piece = piece / 2
      else
        call approach_on_own_steps(integrator, run, t_at, y_at, f_at, width, status, res)
        return
      end if
    end do
  end subroutine step_in_pieces

  !> Whether a step h is beyond the method's stability for the case's
  !> linearised motion at the start.
  logical function beyond_stability(integrator, run, h)
    class(integrator_t), intent(in) :: integrator
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: h
    beyond_stability = .false.
    if (stability_limit(integrator) < huge(1.0_wp)) beyond_stability = &
      h * fastest_rate(run%ball, run%start, enough=stability_limit(integrator) / h) > stability_limit(integrator)
  end function beyond_stability

  !> The method's trajectory continued from (t, y, f) on shorter steps, each
  !> approach_fraction of what remains to the nearest offset known to meet
  !> a limit, until that remainder is a few units in the last place of t.
  !> Every step taken adds to the summary; the case ends at the last state
  !> inside the model, with the status of the limit met just after it.
  subroutine approach_on_own_steps(integrator, run, t, y, f, h, status, res)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    integer, intent(in) :: status
    type(case_result_t), intent(inout) :: res
    real(wp) :: y_at(state_size), f_at(state_size), y_trial(state_size), f_trial(state_size)
    real(wp) :: t_at, remaining, step
    type(observation_t) :: obs
    integer :: trial_status
    t_at = t
    y_at = y
    f_at = f
    remaining = h
    res%status = status
    do while (remaining > 16 * spacing(t + h))
      step = remaining * approach_fraction
      call fixed_step(integrator, run, t_at, y_at, f_at, step, y_trial, f_trial, obs, trial_status, res%n_rhs)
      if (trial_status == status_completed) then
        t_at = t_at + step
        y_at = y_trial
        f_at = f_trial
        remaining = remaining - step
        call track(run, res, t_at, obs)
      else
        remaining = step
        ! a limit of the model explains a step without solution next to it
        if (trial_status /= status_unstable .or. res%status == status_unstable) res%status = trial_status
      end if
    end do
    res%t_final = t_at
  end subroutine approach_on_own_steps
end module ellroll_fixed_step_run
