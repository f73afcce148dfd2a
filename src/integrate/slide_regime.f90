!> One regime's step of a case that may slide and what it adds to the
!> summary: the state of either regime (regime_state_t), a step in it (take),
!> the switches' functions, the making of a switch, the works and the end
!> at a model limit; ellroll_slide_run's loops locate the switches.
module ellroll_slide_regime
  use ellroll_kinds, only: wp, i8
  use ellroll_status, only: status_completed, status_unstable, status_rim
  use ellroll_norms, only: in_mass_units
  use ellroll_ode, only: no_step_solution
  use ellroll_events, only: peak_search_t
  use ellroll_cases, only: case_t, field_regime, field_slip_speed
  use ellroll_results, only: case_result_t, add_switch, switch_to_rolling
  use ellroll_figures, only: fig_slip_speed_max
  use ellroll_rolling_ball, only: observation_t, state_size, limit_status, normalize_normal, ball_derivative, observe
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, sliding_from_rolling, observe_sliding, stick, &
      at_sliding_rim, stick_level, align_slip, sliding_derivative, set_reaction, slip_stop_time, stick_loss, center_velocity
  use ellroll_integrators, only: integrator_t, embedded_pair_t
  use ellroll_case_run, only: run_state_t, track, restart_case, record_sample, stored, add_step_resistance
  use ellroll_fixed_step_run, only: step_with_events
  use ellroll_step_works, only: step_works, gauss_nodes, gauss_weights
  use ellroll_slip_substeps, only: slide_piece
  use ellroll_step_peaks, only: step_screen_t, screen_theta, note_screen, peak_count, peak_quantities, peak_values, &
      worth_refining, peak_resolution
  use ellroll_running, only: add_inside
  implicit none
  private

  public :: regime_state_t, slide_tally_t, limit_time_ulps, take, restart_samples, track_balance, &
            record_regime_sample, switch_crossed, switch_value, start_sliding, stop_sliding, add_sliding_step, &
            add_sliding, slip_stopped, observe_stopped, add_sliding_peaks, step_screen_t, graze_inside, stop_bracket, &
            hovering_slip, switch_reaction

  !> Model limits are located to this many units in the last place of t.
  real(wp), parameter :: limit_time_ulps = 16

  !> The state of a run that may slide: the regime and its state.
  type :: regime_state_t
    logical :: sliding = .false.
    real(wp) :: y(state_size) = 0, f(state_size) = 0           !< rolling
    real(wp) :: s(slide_state_size) = 0, fs(slide_state_size) = 0   !< sliding
    type(observation_t) :: obs
    real(wp) :: slip_speed = 0
    logical :: stalled = .false.     !< a fixed step's slip stopped inside the piece that led here (slide_piece)
    !> how far the piece that led here went: its size, or, where a fixed
    !> step's slip stopped or stalled inside it, the time of the substep
    !> that found it (slide_piece)
    real(wp) :: reached = 0
    real(wp) :: stopped_at = -1     !< where a fixed step's rest event (rolling) was made (< 0: none)
    !> the friction's and the couple's works over the piece that led here,
    !> where a fixed step's substeps summed them (slide_piece; < 0: not)
    real(wp) :: works(2) = -1
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

  !> The first sample and the summary's start again from the sliding start.
  pure subroutine restart_samples(cs, run, res, now)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    type(regime_state_t), intent(in) :: now
    call record_regime_sample(res, 1_i8, now)
    call restart_case(cs, run, res, now%obs)
  end subroutine restart_samples

  !> A step end's track at state `at`, its energy with the friction's work
  !> so far (a sliding ball is not at rest: the rolling model's test sees
  !> only its normal and omega).
  pure subroutine track_balance(run, res, t, at, tally)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(regime_state_t), intent(in) :: at
    type(slide_tally_t), intent(in) :: tally
    run%friction_work = tally%friction_energy
    res%reals(fig_slip_speed_max) = tally%slip_speed_max
    if (at%sliding) then
      call track(run, res, t, at%obs, still=.false.)
    else
      call track(run, res, t, at%obs)
    end if
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

  !> One step of the method from (t, now) of size h in now's regime: the new
  !> state (normal projected), its derivative and outputs, and the status of
  !> the first limit met at a stage or at the end (0: completed). Rolling,
  !> the step is the rolling model's, through its events (step_with_events:
  !> the rest of rolling resistance).
  subroutine take(integrator, rolling, sb, t, h, now, new, status, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: now
    type(regime_state_t), intent(out) :: new
    integer, intent(out) :: status
    integer(i8), intent(inout) :: n_rhs
    integer :: event
    new%sliding = now%sliding
    new%reached = h
    if (.not. now%sliding) then
      call step_with_events(integrator, rolling, t, now%y, now%f, h, new%y, new%f, new%obs, status, n_rhs, event, &
                            new%stopped_at)
      new%slip_speed = 0
      return
    end if
    select type (integrator)
    class is (embedded_pair_t)
      call integrator%step(sb, t, now%s, now%fs, h, new%s, n_rhs)
    class default
      call slide_piece(integrator, sb, t, h, now%s, now%fs, now%obs%reaction_normal, new%s, new%reached, new%stalled, &
                       new%works, n_rhs)
    end select
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
    if (sb%aligned) call align_slip(sb, t + new%reached, new%s, n_rhs)
    call observe_sliding(sb, t + new%reached, new%s, new%obs, new%slip_speed, new%fs)
    n_rhs = n_rhs + 1
    status = limit_status(rolling%ball, new%s(1:6), new%obs)
  end subroutine take

  !> The peaks inside an embedded pair's accepted sliding step from t of
  !> size h (its dense output), that ended at new, whose screen (lift_inside's)
  !> shows one that may pass the running maximum (worth_refining): located
  !> to peak_resolution of the step by successive parabolas, into run's
  !> maxima (as a rolling step's: ellroll_step_peaks).
  subroutine add_sliding_peaks(pair, run, sb, t, h, screen, new, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(run_state_t), intent(inout) :: run
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(step_screen_t), intent(inout) :: screen
    type(regime_state_t), intent(in) :: new
    integer(i8), intent(inout) :: n_rhs
    type(peak_search_t) :: search
    type(observation_t) :: obs
    real(wp) :: best, x, fx, top_clearance, q(0:6), values(peak_count)
    real(wp) :: state(slide_state_size), rate(slide_state_size), slip_speed
    integer :: i, j
    call note_screen(screen, 6, new%obs)
    do j = 1, peak_count
      q = screen%q(:, j)
      best = max(run%stats%clear_maximum(1, peak_quantities(j)), q(0), q(6))
      do i = 1, 5
        if (.not. worth_refining(q, i, best)) cycle
        call search%start(screen_theta(i - 1), screen_theta(i), screen_theta(i + 1), q(i - 1), q(i), q(i + 1), &
                          peak_resolution)
        top_clearance = screen%clearance(i)
        do while (.not. search%done())
          x = search%trial()
          call pair%dense(sb, x, state, n_rhs)
          call normalize_normal(state)
          call observe_sliding(sb, t + x * h, state, obs, slip_speed, rate)
          n_rhs = n_rhs + 1
          values = peak_values(obs)
          fx = values(j)
          if (fx >= search%fb) top_clearance = obs%fit_clearance
          call search%report(x, fx)
        end do
        if (search%fb > best) then
          best = search%fb
          call add_inside(run%stats, peak_quantities(j), search%fb, t + search%b * h, top_clearance > 0)
        end if
      end do
    end do
  end subroutine add_sliding_peaks

  !> Whether the regime switches between now and new (one step apart):
  !> rolling needs more friction than mu N at new; or the slip, nonzero at
  !> now, turned by a right angle or more.
  logical function switch_crossed(sb, now, new) result(crossed)
    type(sliding_ball_t), intent(in) :: sb
    type(regime_state_t), intent(in) :: now, new
    if (now%sliding) then
      crossed = new%stalled .or. sb%event_crossed(now%s, new%s) /= 0
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
    if (x%stalled) then
      g = -1                      ! past the stop
    else if (x%sliding) then
      g = sb%event_value(1, x%s)
    else
      g = sb%ball%mu - x%obs%friction_needed
    end if
  end function switch_value

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
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: t
    type(regime_state_t), intent(inout) :: now
    type(case_result_t), intent(inout) :: res
    type(slide_tally_t), intent(inout) :: tally
    logical, intent(in), optional :: at_rest_only   !< stop it only where rolling goes on (a slip not located)
    type(regime_state_t) :: rolled
    if (present(at_rest_only)) then
      rolled%y = stick(sb%ball, now%s)
      call rolling_start(rolling, rolled%y)
      call ball_derivative(rolling%ball, t, rolled%y, rolled%f)
      call observe(rolling%ball, t, rolled%y, rolled%f, rolled%obs)
      res%n_rhs = res%n_rhs + 1
      if (rolled%obs%friction_needed > sb%ball%mu) return
    else if (.not. slip_stopped(sb, now, tally)) then
      call sb%begin_step(now%s)
      return
    end if
    rolled%sliding = .false.
    rolled%y = stick(sb%ball, now%s)
    call rolling_start(rolling, rolled%y)
    call ball_derivative(rolling%ball, t, rolled%y, rolled%f)
    call observe(rolling%ball, t, rolled%y, rolled%f, rolled%obs)
    res%n_rhs = res%n_rhs + 1
    rolled%slip_speed = 0
    tally%friction_energy = tally%friction_energy + stick_loss(sb%ball, now%s)
    now = rolled
    if (rolled%obs%friction_needed > sb%ball%mu) then
      call start_sliding(sb, t, now, res, tally)
      tally%episodes = tally%episodes - 1          ! the same episode, slipping another way
    else
      call add_switch(res, t, switch_to_rolling)
    end if
  end subroutine stop_sliding

  !> The rolling model's mode at rolling state y where the ball starts to
  !> roll (begin_step): with rolling resistance the couple's direction is
  !> the rolling there, not that of the last rolling step before the slip
  !> (rolling_mode: a derivative taken against a mode the rolling has
  !> turned away from would hold the couple against that, and a fixed
  !> step's first stage with it).
  pure subroutine rolling_start(rolling, y)
    type(run_state_t), intent(inout) :: rolling
    real(wp), intent(in) :: y(state_size)
    if (rolling%ball%nonsmooth()) call rolling%ball%begin_step(y)
  end subroutine rolling_start

  !> Whether the slip of sliding state now has stopped (stop_sliding): it
  !> has fallen to stick_level of its value at the piece's start or of the
  !> episode's largest.
  pure logical function slip_stopped(sb, now, tally) result(stopped)
    type(sliding_ball_t), intent(in) :: sb
    type(regime_state_t), intent(in) :: now
    type(slide_tally_t), intent(in) :: tally
    stopped = .not. now%slip_speed > max(stick_level * max(2 * norm2(sb%slip_at_start), tally%episode_slip_max), &
                                         sb%slip_floor)
  end function slip_stopped

  !> The reaction (and the centre's acceleration) of sliding state `at`
  !> whose slip has stopped (slip_stopped): the friction mu N along the one
  !> rolling needs, the limit of the sliding friction as u -> 0 (the slip's
  !> direction relaxes to -F_req: docs/model.md, "The aligned law"), not
  !> against the slip left, whose direction is the step's error there (a
  !> summary maximum taken from it is no value of the motion).
  pure subroutine observe_stopped(sb, t, at)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t
    type(regime_state_t), intent(inout) :: at
    real(wp) :: rate(slide_state_size), big_n, force(3), need(3), size_need
    call sliding_derivative(sb, t, at%s, rate, big_n, force, needed=need)
    size_need = norm2(in_mass_units(need, sb%ball%mass))
    if (.not. size_need > 0) return
    call set_reaction(sb, big_n * at%obs%normal + (in_mass_units(sb%ball%mu * max(big_n, 0.0_wp), sb%ball%mass) &
                                                    / size_need) * need, at%obs)
  end subroutine observe_stopped

  !> The piece of step h from (t, from) to `to` that the integrator has just
  !> taken adds to the sliding figures (add_sliding). An embedded pair's works
  !> of the friction and of the rolling resistance, in either regime, are
  !> step_works' (the latter in place of add_resistance_work's trapezoids:
  !> add_step_resistance). at_stop: the step ends where the slip stops
  !> (step_works' fresh).
  subroutine add_sliding_step(integrator, run, rolling, sb, t, h, from, to, tally, res, at_stop)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: from, to
    type(slide_tally_t), intent(inout) :: tally
    type(case_result_t), intent(inout) :: res
    logical, intent(in), optional :: at_stop
    real(wp) :: work(2)
    select type (integrator)
    class is (embedded_pair_t)
      if (.not. (from%sliding .or. rolling%ball%rolling_resistance > 0)) return
      if (from%sliding) then
        call step_works(integrator, rolling%ball, t, h, work, res%n_rhs, sb, fresh=at_stop)
      else
        call step_works(integrator, rolling%ball, t, h, work, res%n_rhs)
      end if
      call add_sliding(sb, h, from, to, tally, work(1))
      if (rolling%ball%rolling_resistance > 0) call add_step_resistance(run, res, t + h, work(2), to%obs)
    class default
      if (to%works(1) >= 0 .and. abs(to%reached - h) <= 4 * spacing(h)) then     ! (the substeps' works)
        call add_sliding(sb, h, from, to, tally, to%works(1))
        if (rolling%ball%rolling_resistance > 0) call add_step_resistance(run, res, t + h, to%works(2), to%obs)
        return
      end if
      if (present(at_stop)) then
        if (at_stop .and. from%sliding) then
          call stop_piece_work(integrator, rolling, sb, t, h, from, work(1), res%n_rhs)
          if (work(1) >= 0) then
            call add_sliding(sb, h, from, to, tally, work(1))
            return
          end if
        end if
      end if
      call add_sliding(sb, h, from, to, tally)
    end select
  end subroutine add_sliding_step

  !> The friction's work mu N |u| over a fixed step's piece of size h from
  !> `from` that ends where the slip stops: Gauss's 4 nodes, each the
  !> method's partial step from the piece's start. Such a piece may be a
  !> whole slip (a stiff one, shorter than a step), over which the
  !> trapezoid's error does not fall with the step (0.5 % where N changes
  !> by 1.6 % over the slip). -1 where a partial step met a limit.
  subroutine stop_piece_work(integrator, rolling, sb, t, h, from, work, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(in) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h
    type(regime_state_t), intent(in) :: from
    real(wp), intent(out) :: work
    integer(i8), intent(inout) :: n_rhs
    type(run_state_t) :: scratch
    type(regime_state_t) :: x
    integer :: i, status
    scratch = rolling
    work = 0
    do i = 1, size(gauss_nodes)
      call take(integrator, scratch, sb, t, gauss_nodes(i) * h, from, x, status, n_rhs)
      if (status /= status_completed) then
        work = -1
        return
      end if
      work = work + gauss_weights(i) * sb%ball%mu * x%obs%reaction_normal * x%slip_speed
    end do
    work = h * work
  end subroutine stop_piece_work

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

  !> A fixed rolling step h from (t, now) to new whose ends both need less
  !> friction than mu N: where the parabola through the friction needed at
  !> t - h (friction_before), t and t + h peaks inside the step above mu,
  !> the partial step to its vertex is taken, and where that needs more, it
  !> is the step that crosses (new and piece replaced): the friction needed
  !> can pass mu N and fall back between two step ends.
  subroutine graze_inside(integrator, rolling, sb, t, h, friction_before, now, new, n_rhs, piece)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h, friction_before
    type(regime_state_t), intent(in) :: now
    type(regime_state_t), intent(inout) :: new
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(inout) :: piece
    type(regime_state_t) :: x
    real(wp) :: fa, fb, fc, curvature, vertex, peak
    integer :: status
    fa = friction_before
    fb = now%obs%friction_needed
    fc = new%obs%friction_needed
    if (.not. (fa < sb%ball%mu .and. fb < sb%ball%mu .and. fc < sb%ball%mu)) return
    curvature = fa - 2 * fb + fc
    if (.not. curvature < 0) return
    vertex = (fa - fc) / (2 * curvature)
    if (.not. (vertex > 0 .and. vertex < 1)) return
    peak = fb - (fa - fc)**2 / (8 * curvature)
    if (.not. peak > sb%ball%mu) return
    call take(integrator, rolling, sb, t, vertex * h, now, x, status, n_rhs)
    if (status /= status_completed) return
    if (.not. switch_crossed(sb, now, x)) return
    new = x
    piece = vertex * h
  end subroutine graze_inside

  !> The piece of the step to take from (t_at, now): all that remains, or,
  !> where the slip's time scale (slip_stop_time; for a pair, with F_req
  !> where that also lies inside it) puts its stop inside it, twice that
  !> time where the slip has stopped by then (the stop is
  !> searched for inside that): past a stop the method's stages throw the
  !> slip the other way, by the remaining time over the stop's, which
  !> overflows for a stiff slip (a large mu, a small inertia factor). Where
  !> the piece is that trial's (taken), new and status are its step.
  subroutine stop_bracket(integrator, rolling, sb, t_at, remaining, now, n_rhs, piece, new, status, taken)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: rolling
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t_at, remaining
    type(regime_state_t), intent(in) :: now
    integer(i8), intent(inout) :: n_rhs
    real(wp), intent(out) :: piece
    type(regime_state_t), intent(inout) :: new
    integer, intent(inout) :: status
    logical, intent(out) :: taken
    real(wp) :: bracket, within, rate(slide_state_size), need(3)
    piece = remaining
    taken = .false.
    if (.not. now%sliding .or. sb%aligned) return     ! (aligned: the slip passes zero smoothly)
    bracket = 2 * slip_stop_time(sb%ball, now%s, now%obs%reaction_normal)
    if (.not. bracket < remaining .or. .not. bracket > 0) return    ! (no slip: nothing to bracket)
    select type (integrator)
    class is (embedded_pair_t)
      ! where rolling can go on the slip stops within slip_stop_time with
      ! F_req: a pair's step far longer than that leaves the slip at the size
      ! of its error, turning, not at zero, within tolerance (a fixed step's
      ! piece there is taken in substeps: slide_piece)
      call sliding_derivative(sb, t_at, now%s, rate, needed=need)
      n_rhs = n_rhs + 1
      within = slip_stop_time(sb%ball, now%s, now%obs%reaction_normal, need)
      if (within < remaining / 2) bracket = 2 * within
    end select
    call take(integrator, rolling, sb, t_at, bracket, now, new, status, n_rhs)
    taken = status == status_completed .and. switch_crossed(sb, now, new)
    if (taken) piece = bracket
  end subroutine stop_bracket

  !> Whether now slides with a slip within the pair's tolerance of zero,
  !> measured against the contact's speeds (|V_C| + R |omega|).
  logical function hovering_slip(pair, sb, now, times) result(hovering)
    class(embedded_pair_t), intent(in) :: pair
    type(sliding_ball_t), intent(in) :: sb
    type(regime_state_t), intent(in) :: now
    real(wp), intent(in), optional :: times     !< the tolerances' multiple (10)
    real(wp) :: scale, multiple
    hovering = .false.
    if (.not. now%sliding) return            ! (a rolling state's s is not set)
    multiple = 10
    if (present(times)) multiple = times
    scale = norm2(center_velocity(now%s)) + sb%ball%radius * norm2(now%s(4:6))
    hovering = now%slip_speed <= multiple * (pair%atol + pair%rtol * scale)
  end function hovering_slip

  !> The observation of a sliding state at its switch into sliding with
  !> friction mu N against the slip's direction the switch set (where the
  !> state's slip is round-off, the reaction would follow its direction).
  pure subroutine switch_reaction(sb, obs)
    type(sliding_ball_t), intent(in) :: sb
    type(observation_t), intent(inout) :: obs
    call set_reaction(sb, obs%reaction_normal * (obs%normal - sb%ball%mu * sb%slip_mode), obs)
    obs%friction_needed = sb%ball%mu
  end subroutine switch_reaction
end module ellroll_slide_regime
