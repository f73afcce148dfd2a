!> The running state of one case and everything its accepted points add to
!> the result: the start and the end of a case, the summary's step-end
!> quantities (their statistics: ellroll_running), the maxima of Theta, the
!> transmissibility's fit, the output samples, and the search for
!> where a step crossed a model limit. Shared by the one-case loops
!> (fixed-step and adaptive) and the batches.
module ellroll_case_run
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite
  use ellroll_kinds, only: wp, i8, two_pi
  use ellroll_exact, only: is_zero, equals
  use ellroll_norms, only: norm_of
  use ellroll_excitation, only: excitation_harmonic, excitation_record, excitation_end
  use ellroll_record_store, only: record_samples
  use ellroll_intensity, only: felt_spectral_acceleration
  use ellroll_status, only: status_completed, status_pending
  use ellroll_cases, only: case_t, output_plan_t, make_ball, field_contact, field_center, field_omega, &
      field_normal, field_nutation, field_reaction, field_energy, field_base_acceleration, &
      field_regime, field_slip_speed
  use ellroll_results, only: case_result_t, allocate_fields, fill_unrecorded, set_figure_values
  use ellroll_quantities, only: quantity_count, q_displacement, q_horizontal_force_scaled, q_reaction_normal, &
      q_friction_needed, q_energy, q_surface_residual, q_fit_clearance
  use ellroll_figures, only: figure_slots, fig_sa_linear_periods
  use ellroll_figures, only: fig_theta_max, fig_nutation_maxima, fig_nutation_period, fig_transmissibility, &
      fig_linear_periods, fig_residual_displacement, fig_rest_time, fig_at_rest, fig_sliding_time, &
      fig_friction_energy, fig_slip_speed_max, fig_rolling_resistance_energy
  use ellroll_running, only: running_t, start_running, add_step_ends, finish_running
  use ellroll_limit_states, only: is_model_limit
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, initial_state, observe, &
      limit_status, ball_derivative, nutation_angle, at_rest, is_still
  use ellroll_events, only: crossing_search_t
  use ellroll_nutation_peaks, only: nutation_peak_t, rest_turn, tan_nutation, rest_left_falling
  use ellroll_nutation_maxima, only: maxima_t
  use ellroll_sliding_ball, only: resistance_power
  use ellroll_linear, only: oscillation_periods
  use ellroll_harmonic_fit, only: harmonic_fit_t
  use ellroll_ellipsoid, only: contact_from_normal
  use ellroll_system, only: stop_signal
  use ellroll_params, only: p_scale, p_excitation_frequency, p_omega_x, p_omega_z, p_x, p_y, p_settle, p_dt
  implicit none
  private

  public :: run_state_t, limit_search_t, start_case, restart_case, finish_case, sample_due, stop_asked, stopping, &
            latest_end, settled, regular_steps, last_fixed_step, fixed_step_time, reach_stop
  public :: track, track_step_end, track_cup_motion, track_rolling_resistance, add_step_resistance, note_nutation, &
            accumulate, record_sample, record_geometry_sample, stored, track_pair_step

  !> An integration looks whether the run was asked to stop (SIGTERM,
  !> SIGINT) every this many steps: at most a few ms apart.
  integer(i8), parameter :: stop_poll_steps = 4096

  !> Model limits are located in time to this many units in the last place
  !> of t: next to the fit limit's square-root singularity the state changes
  !> by the fit margin itself within 1e-12 s.
  real(wp), parameter :: event_time_ulps = 16

  !> The search for where a step crossed a model limit, keeping the last
  !> valid observation and the status of the limit met.
  type, extends(crossing_search_t) :: limit_search_t
    type(observation_t) :: last_valid
    type(observation_t) :: last_trial     !< at the last offset tried
    logical :: found_valid = .false.
    integer :: crossed = status_completed
  contains
    procedure :: begin => begin_limit_search
    procedure :: record => record_trial
  end type limit_search_t

  !> What one integration needs as it goes.
  type :: run_state_t
    type(rolling_ball_t) :: ball
    real(wp) :: start(state_size) = 0     !< the state at t = 0
    type(maxima_t) :: maxima
    !> harmonic forcing: the steady response at the forcing frequency (the transmissibility)
    type(harmonic_fit_t) :: fit
    real(wp) :: spin0 = 0                 !< omega . n at the start
    real(wp) :: tan_theta_max = -1        !< largest tan Theta so far
    !> the statistics of the step-end quantities (the batch's lanes keep the same)
    type(running_t) :: stats
    integer(i8) :: next_sample = 2        !< index of the next output sample
    !> with rolling resistance: whether the ball is at rest at the last step
    !> end (at_rest), since when, and its centre's horizontal distance from
    !> the cup's lowest point there (held: it stays)
    logical :: resting = .false.
    real(wp) :: rest_since = 0, rest_displacement = 0
    !> where the rest event of the step just taken was located inside it
    !> (a fixed step: it ends on the grid past it; < 0: none)
    real(wp) :: stopped_at = -1
    !> with rolling resistance: the time and the couple's power -delta N
    !> |omega_t| of the last state tracked (its work is summed by the
    !> trapezoidal rule over the states tracked: step ends and switches)
    real(wp) :: resistance_time = 0, resistance_power = 0
    !> sliding: the friction's work so far, which the step ends' energy
    !> adds to E with the couple's (energy_drift: the residual of the
    !> balance E + W = E0), and
    !> its value at the last step end clear of the cup's curvature (where a
    !> case that ends at a model limit cuts it, as its peaks)
    real(wp) :: friction_work = 0, friction_work_clear = 0
    !> the largest slip speed and the couple's work at that step end
    real(wp) :: slip_speed_clear = 0, resistance_work_clear = 0
  end type run_state_t

contains

  !> The state at t = 0 and everything it adds to the result; a start
  !> outside the model ends the case at once (res%status).
  subroutine start_case(cs, plan, run, res, y, f)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(out) :: run
    type(case_result_t), intent(out) :: res
    real(wp), intent(out) :: y(state_size), f(state_size)
    type(observation_t) :: obs
    run%ball = make_ball(cs)
    ! where the running figures start (every other one is set at the end)
    res%t_final = 0
    res%wall_time = 0
    res%reals(fig_theta_max) = 0
    ! rolling throughout unless the slide loop says otherwise
    res%reals([fig_sliding_time, fig_friction_energy, fig_slip_speed_max, fig_rolling_resistance_energy]) = 0
    call allocate_fields(res, plan%fields, plan%n_samples)
    y = initial_state(run%ball, cs%param(p_x), cs%param(p_y), cs%param(p_omega_x:p_omega_z))
    run%start = y
    call ball_derivative(run%ball, 0.0_wp, y, f)
    res%n_rhs = 1
    call observe(run%ball, 0.0_wp, y, f, obs)
    call start_running(run%stats, step_quantities(obs), cs%param)
    run%spin0 = dot_product(cs%param(p_omega_x:p_omega_z), obs%normal)
    call start_fit(cs, run)
    call track(run, res, 0.0_wp, obs)
    call record_sample(res, 1_i8, obs)
    res%status = limit_status(run%ball, y, obs)
  end subroutine start_case

  !> The summary's statistics start again from observation obs at t = 0
  !> (a start that slides: its centre's velocity is not rolling's, so
  !> neither are E0 and the forces at t = 0).
  pure subroutine restart_case(cs, run, res, obs)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    type(observation_t), intent(in) :: obs
    type(running_t) :: fresh
    run%stats = fresh
    call start_running(run%stats, step_quantities(obs), cs%param)
    call track(run, res, 0.0_wp, obs, still=.false.)       ! (sliding: not at rest)
  end subroutine restart_case

  !> Harmonic forcing: the fit of the steady response at the forcing
  !> frequency (ellroll_harmonic_fit) over the last whole forcing periods
  !> (at least half the run), beside the free oscillation at the linear
  !> modes' frequencies about the bottom (those of the case's spin).
  subroutine start_fit(cs, run)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(inout) :: run
    real(wp) :: start, periods(2)
    associate (frequency => cs%param(p_excitation_frequency))
      if (cs%excitation%kind /= excitation_harmonic .or. .not. frequency > 0) return
      if (floor(0.5_wp * cs%t_end * frequency) < 1) return
      start = cs%t_end - floor(0.5_wp * cs%t_end * frequency) / frequency
      periods = oscillation_periods(run%ball, run%spin0)
      call run%fit%begin(two_pi * frequency, two_pi / periods, start, cs%t_end - start)
    end associate
  end subroutine start_fit

  !> The figures made from the whole run.
  subroutine finish_case(cs, run, res)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(in) :: run
    type(case_result_t), intent(inout) :: res
    real(wp) :: periods(2)
    integer :: k
    res%counts(fig_nutation_maxima) = run%maxima%count
    res%reals(fig_nutation_period) = run%maxima%mean_interval()
    ! a fixed step's maximum of Theta between its step ends: the parabola's
    ! (maxima of tan Theta are those of Theta)
    if (run%maxima%top > run%tan_theta_max) res%reals(fig_theta_max) = atan(run%maxima%top)
    if (res%status == status_completed .and. run%fit%start < cs%t_end) res%reals(fig_transmissibility) = run%fit%ratio()
    if (res%status == status_completed .and. settled(run, res%t_final)) then
      res%reals(fig_residual_displacement) = run%rest_displacement
      res%reals(fig_rest_time) = run%rest_since
      res%counts(fig_at_rest) = 1
    end if
    call finish_running(run%stats, run%ball%mass, res)
    if (is_model_limit(res%status)) call cut_at_limit(cs, run, res)
    periods = oscillation_periods(run%ball, run%spin0)
    call set_figure_values(res, fig_linear_periods, periods)
    ! (Sa runs over the whole record, seconds for one of 1e7 samples: a case
    ! that ends as the run is asked to stop is dropped with those under way)
    if (cs%excitation%kind == excitation_record .and. res%status /= status_pending) then
      if (stopping()) res%status = status_pending
    end if
    if (cs%excitation%kind == excitation_record .and. res%status /= status_pending) then
      do k = 1, 2          ! (NaN apart: a mode that does not oscillate)
        if (ieee_is_finite(periods(k))) res%reals(figure_slots(fig_sa_linear_periods)) = &
            spectral_at(cs, periods(k), k, res%reals(figure_slots(fig_sa_linear_periods)))
      end do
    end if
    call fill_unrecorded(res)
  end subroutine finish_case

  !> The latest time case cs runs to: t_end, or t_end + settle where the
  !> ball can come to rest for good (rolling resistance, and a cup that
  !> comes to rest: a record, or none); it then ends where it is at rest
  !> past t_end (settled).
  pure real(wp) function latest_end(cs, run)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(in) :: run
    latest_end = cs%t_end
    if (cs%param(p_settle) > 0 .and. run%ball%rolling_resistance > 0 .and. &
        excitation_end(run%ball%excitation) < huge(1.0_wp)) latest_end = cs%t_end + cs%param(p_settle)
  end function latest_end

  !> Whether an adaptive loop at t, its stop t_stop (t_end, then latest_end
  !> while the ball settles), is done: t has reached t_stop and, past t_end,
  !> the ball is at rest for good or latest_end is reached; t_stop moves on
  !> to latest_end where the ball is still to settle.
  pure subroutine reach_stop(cs, run, t, t_stop, done)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: t
    real(wp), intent(inout) :: t_stop
    logical, intent(out) :: done
    done = .false.
    if (t < t_stop) return
    if (t_stop < latest_end(cs, run) .and. .not. settled(run, t)) then
      t_stop = latest_end(cs, run)
    else
      done = .true.
    end if
  end subroutine reach_stop

  !> The fixed steps (of dt) from 0 to t_end, a whole number of them.
  pure integer(i8) function regular_steps(cs)
    type(case_t), intent(in) :: cs
    regular_steps = nint(cs%t_end / cs%param(p_dt), i8)
  end function regular_steps

  !> The last fixed step (of dt) case cs may take: t_end's, or latest_end's
  !> where it settles past t_end.
  pure integer(i8) function last_fixed_step(cs, run) result(n_last)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(in) :: run
    n_last = regular_steps(cs)
    if (latest_end(cs, run) > cs%t_end) n_last = max(nint(latest_end(cs, run) / cs%param(p_dt), i8), n_last)
  end function last_fixed_step

  !> The time a fixed-step case has reached after `steps` steps: t (steps
  !> dt, as the steps computed it), but t_end itself after its last regular
  !> step. t_end is a whole number of steps, where the product can be an
  !> ulp off it (3 x 0.1 = 0.30000000000000004).
  pure real(wp) function fixed_step_time(cs, steps, t)
    type(case_t), intent(in) :: cs
    integer(i8), intent(in) :: steps
    real(wp), intent(in) :: t
    fixed_step_time = t
    if (steps == regular_steps(cs)) fixed_step_time = cs%t_end
  end function fixed_step_time

  !> Whether the ball is at rest for good at the step end t just tracked:
  !> at rest, and the cup at rest for ever from t on (a ball held while the
  !> cup moves may start again).
  pure logical function settled(run, t)
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: t
    settled = run%resting
    if (settled) settled = t >= excitation_end(run%ball%excitation)
  end function settled

  !> Sa of the case's scaled record at `period`, put at component k of `sa`.
  pure function spectral_at(cs, period, k, sa) result(next)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: period, sa(2)
    integer, intent(in) :: k
    real(wp) :: next(2), one(1)
    next = sa
    one = felt_spectral_acceleration(record_samples(cs%excitation%record)%times, record_samples(cs%excitation%record)%values, &
                                     [period])
    next(k) = cs%param(p_scale) * one(1)
  end function spectral_at

  !> Whether the run was asked to stop, looked at once in stop_poll_steps
  !> steps: the case is then dropped (its result is never written).
  logical function stop_asked(step)
    integer(i8), intent(in) :: step
    stop_asked = .false.
    if (mod(step, stop_poll_steps) == 0) stop_asked = stop_signal() /= 0
  end function stop_asked

  !> Whether the run was asked to stop, looked at on every call (a relaxed
  !> atomic load). Every fixed step polls it (fixed_step, slide_piece's
  !> substeps): once a stop is asked, each step fails at once, without
  !> solution, so that the searches and piece loops around a step (a limit
  !> located in partial steps, a step taken again in 2^20 pieces, a switch
  !> located inside a step), bounded in trials but not in what a trial
  !> costs, end within a few hundred cheap trials; the runner drops the case
  !> cut short (run_block). The outer loops' stop_asked ends a case whose
  !> steps are cheap.
  logical function stopping()
    stopping = stop_signal() /= 0
  end function stopping

  !> Whether the next output sample falls at or before t_until (to round-off).
  pure logical function sample_due(run, plan, t_until)
    type(run_state_t), intent(in) :: run
    type(output_plan_t), intent(in) :: plan
    real(wp), intent(in) :: t_until
    sample_due = run%next_sample <= plan%n_samples
    if (sample_due) sample_due = real(run%next_sample - 1, wp) * plan%interval <= t_until * (1 + 1.0e-14_wp)
  end function sample_due

  !> A search over offsets (0, invalid] from t_start.
  pure subroutine begin_limit_search(self, t_start, invalid, crossed)
    class(limit_search_t), intent(inout) :: self
    real(wp), intent(in) :: t_start, invalid
    integer, intent(in) :: crossed
    call self%start(invalid, event_time_ulps * spacing(t_start + invalid))
    self%found_valid = .false.
    self%crossed = crossed
  end subroutine begin_limit_search

  pure subroutine record_trial(self, offset, status, obs)
    class(limit_search_t), intent(inout) :: self
    real(wp), intent(in) :: offset
    integer, intent(in) :: status
    type(observation_t), intent(in) :: obs
    call self%report(offset, status == status_completed)
    self%last_trial = obs
    if (status == status_completed) then
      self%last_valid = obs
      self%found_valid = .true.
    else
      self%crossed = status
    end if
  end subroutine record_trial

  !> What an embedded pair's step from y to y_new (ending at t, its
  !> tolerances atol and rtol) adds to the maxima of Theta: the maximum
  !> located inside it (`located`: peak), or else its turn at a still state
  !> (ellroll_nutation_peaks rest_turn); where the ball was still since the
  !> last maximum, each counted where Theta rose to it from its lowest since
  !> by more than resolved_rise times the step's tolerance on the normal,
  !> atol + rtol times the value.
  pure subroutine track_pair_step(run, y, f, y_new, f_new, t, located, peak, atol, rtol)
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: y(:), f(:), y_new(:), f_new(:)
    real(wp), intent(in) :: t, atol, rtol
    logical, intent(in) :: located
    type(nutation_peak_t), intent(in) :: peak
    !> the error a pair's steps leave, as a multiple of their tolerance,
    !> where the rolling stops (the couple's kink): vern9 at rtol 1e-10 rises
    !> 2.2e-12 into a rest, 1.1 times its tolerance, where rk4 at dt 1e-5
    !> falls; a rise of 6e-11 into a rest, 30 times it, rk4 follows too
    real(wp), parameter :: resolved_rise = 10
    real(wp) :: v_start, v_end
    logical :: still, still_new
    v_start = tan_nutation(y)
    v_end = tan_nutation(y_new)
    still = is_still(run%ball, y)
    still_new = is_still(run%ball, y_new)
    call run%maxima%note_value(v_start, still)
    if (located .and. .not. still) then
      call run%maxima%add_located(peak%t, peak%tan_nutation, rise(peak%tan_nutation))
    else if (located) then
      ! a peak no higher than the rest the step sets off from is that rest's
      ! edge (the ball leaves it falling): the rest's turn
      if (peak%tan_nutation - v_start > rise(peak%tan_nutation)) then
        call run%maxima%add_located(peak%t, peak%tan_nutation, rise(peak%tan_nutation))
      else
        call run%maxima%add_rest_turn(rest_left_falling, t, v_end, rise(v_end))
      end if
    else
      call run%maxima%add_rest_turn(rest_turn(y, f, y_new, f_new, still, still_new), t, v_end, rise(v_end))
    end if
    call run%maxima%note_value(v_end, still_new)
  contains
    pure real(wp) function rise(v)
      real(wp), intent(in) :: v
      rise = resolved_rise * (atol + rtol * v)
    end function rise
  end subroutine track_pair_step

  !> Everything a fixed step's end point adds to the summary; the maxima of
  !> Theta from the step ends (refined by parabolas).
  pure subroutine track(run, res, t, obs, still)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    logical, intent(in), optional :: still      !< whether the ball is at rest there, where known
    ! maxima of tan Theta are the maxima of Theta (tan is increasing)
    call run%maxima%add(t, obs%tan_nutation)
    call track_step_end(run, res, t, obs, still)
  end subroutine track

  !> What any step's end point adds to the summary but the maxima of Theta.
  pure subroutine track_step_end(run, res, t, obs, still)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    logical, intent(in), optional :: still      !< whether the ball is at rest there, where known
    call track_cup_motion(run, t, obs%center_acceleration(1:2), obs%base_acceleration(1:2))
    call track_rolling_resistance(run, res, t, obs, still)
    call accumulate(run, res, t, obs)
  end subroutine track_step_end

  !> What a step's end point adds to the summary of rolling resistance: the
  !> rest (note_rest) and the couple's work (from obs's normal, omega,
  !> centre, normal force and fit clearance; the batches call it per lane,
  !> with whether the ball is at rest there: still, lanes_at_rest's).
  pure subroutine track_rolling_resistance(run, res, t, obs, still)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    logical, intent(in), optional :: still
    real(wp) :: stopped_at
    if (run%ball%rolling_resistance > 0) then
      stopped_at = run%stopped_at         ! (note_rest takes it)
      call note_rest(run, t, obs, still)
      call add_resistance_work(run, res, t, obs, stopped_at)
      if (obs%fit_clearance > 0) run%resistance_work_clear = res%reals(fig_rolling_resistance_energy)
    end if
  end subroutine track_rolling_resistance

  !> A case that ended at a model limit: the works of friction and of the
  !> couple and the largest slip speed up to the step ends the peaks take
  !> (NaN where none was): near the limit N grows without bound, and a
  !> piece's quadrature with it (near the rim a sliding state's V_z).
  pure subroutine cut_at_limit(cs, run, res)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(in) :: run
    type(case_result_t), intent(inout) :: res
    real(wp) :: nan
    nan = ieee_value(nan, ieee_quiet_nan)
    if (cs%slide) then
      res%reals([fig_friction_energy, fig_slip_speed_max]) = nan
      if (run%stats%n_clear(1) > 0) then
        res%reals(fig_friction_energy) = run%friction_work_clear
        res%reals(fig_slip_speed_max) = run%slip_speed_clear
      end if
    end if
    if (run%ball%rolling_resistance > 0) then
      res%reals(fig_rolling_resistance_energy) = nan
      if (run%stats%n_clear(1) > 0) res%reals(fig_rolling_resistance_energy) = run%resistance_work_clear
    end if
  end subroutine cut_at_limit

  !> An embedded pair's step (or piece of step) ending at t adds `work`, the
  !> couple's work over it (step_works' rule on its dense output), in place
  !> of the trapezoid over it: the state obs tracked at t then adds nothing.
  pure subroutine add_step_resistance(run, res, t, work, obs)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t, work
    type(observation_t), intent(in) :: obs
    res%reals(fig_rolling_resistance_energy) = res%reals(fig_rolling_resistance_energy) + work
    run%resistance_time = t
    run%resistance_power = resistance_power(run%ball, obs%normal, obs%omega, obs%reaction_normal)
  end subroutine add_step_resistance

  !> The rolling resistance's work from the last state tracked to this one
  !> (trapezoidal rule; a state tracked again at the same time adds nothing).
  !> Where a fixed step's rolling stopped inside it (at stopped_at, >= 0),
  !> the couple's power falls to zero there and rises from it (the ball held,
  !> or rolling back): a trapezoid on each side of the stop, not one over the
  !> step, which counts the power at the step's start for all of it.
  pure subroutine add_resistance_work(run, res, t, obs, stopped_at)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    real(wp), intent(in) :: stopped_at
    real(wp) :: power
    if (t < run%resistance_time) return
    power = resistance_power(run%ball, obs%normal, obs%omega, obs%reaction_normal)
    if (stopped_at > run%resistance_time .and. stopped_at < t) then
      res%reals(fig_rolling_resistance_energy) = res%reals(fig_rolling_resistance_energy) &
          - 0.5_wp * ((stopped_at - run%resistance_time) * run%resistance_power + (t - stopped_at) * power)
    else
      res%reals(fig_rolling_resistance_energy) = res%reals(fig_rolling_resistance_energy) &
          - 0.5_wp * (t - run%resistance_time) * (run%resistance_power + power)
    end if
    run%resistance_time = t
    run%resistance_power = power
  end subroutine add_resistance_work

  !> What a step's end point adds to the summary of a moving cup beyond the
  !> step-end statistics (the transmissibility's fit), from the horizontal
  !> absolute accelerations of the centre and of the cup (the batches call
  !> it per lane).
  pure subroutine track_cup_motion(run, t, center_acceleration, base)
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, center_acceleration(2), base(2)
    if (run%fit%n_basis > 0) call run%fit%add(t, center_acceleration, base)
  end subroutine track_cup_motion

  !> Whether the ball is at rest at a step end at time t, and where and
  !> since when it rests: the rest event's time where the step located one
  !> inside it (stopped_at), else t (an adaptive step ends at the event).
  pure subroutine note_rest(run, t, obs, still)
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    logical, intent(in), optional :: still      !< whether it is at rest (at_rest), when known
    logical :: resting
    if (present(still)) then
      resting = still
    else
      resting = at_rest(run%ball, t, [obs%normal, obs%omega])
    end if
    if (resting) then
      if (.not. run%resting) then
        run%resting = .true.
        run%rest_since = t
        if (run%stopped_at >= 0) run%rest_since = run%stopped_at
        run%rest_displacement = sqrt(obs%center(1)**2 + obs%center(2)**2)
      end if
    else
      run%resting = .false.
    end if
    run%stopped_at = -1
  end subroutine note_rest

  !> A nutation angle (tan Theta, and the lateral and vertical components of
  !> the unit normal) for the largest Theta; one nutation_angle per new maximum only.
  pure subroutine note_nutation(run, res, tan_nutation, lateral, normal_z)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: tan_nutation, lateral, normal_z
    if (tan_nutation > run%tan_theta_max) then
      run%tan_theta_max = tan_nutation
      res%reals(fig_theta_max) = nutation_angle(lateral, normal_z)
    end if
  end subroutine note_nutation

  !> What an accepted step end adds to the summary: the nutation angle, and
  !> the step-end quantities to their statistics (the energy with the works
  !> of the friction and of the couple of rolling resistance so far, tracked
  !> up to t before: energy_drift is the residual of the balance E + W = E0).
  pure subroutine accumulate(run, res, t, obs)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    real(wp) :: q(1, quantity_count)
    call note_nutation(run, res, obs%tan_nutation, obs%lateral, obs%normal(3))
    q = step_quantities(obs)
    q(1, q_energy) = q(1, q_energy) + run%friction_work
    if (run%ball%rolling_resistance > 0) q(1, q_energy) = q(1, q_energy) + res%reals(fig_rolling_resistance_energy)
    if (obs%fit_clearance > 0) then
      run%friction_work_clear = run%friction_work
      run%slip_speed_clear = res%reals(fig_slip_speed_max)
    end if
    call add_step_ends(run%stats, q, t)
  end subroutine accumulate

  !> The step-end quantities of an observation (the norms by norm_of, as
  !> the batch's lanes_observe computes them); displacement: of the centre
  !> from the vertical through the lowest point.
  pure function step_quantities(obs) result(q)
    type(observation_t), intent(in) :: obs
    real(wp) :: q(1, quantity_count)
    q(1, q_displacement) = norm_of(obs%center(1), obs%center(2))
    q(1, q_horizontal_force_scaled) = obs%horizontal_force_scaled
    q(1, q_reaction_normal) = obs%reaction_normal
    q(1, q_friction_needed) = obs%friction_needed
    q(1, q_energy) = obs%energy
    q(1, q_surface_residual) = obs%surface_residual
    q(1, q_fit_clearance) = obs%fit_clearance
  end function step_quantities

  !> Every stored field's values at one output sample (Theta from the
  !> lateral and vertical parts of the normal, only when it is stored).
  pure subroutine record_sample(res, sample, obs)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    type(observation_t), intent(in) :: obs
    call put(res, sample, field_contact, obs%contact)
    call put(res, sample, field_center, obs%center)
    call put(res, sample, field_omega, obs%omega)
    call put(res, sample, field_normal, obs%normal)
    if (stored(res, field_nutation)) res%fields(field_nutation)%values(1, sample) = nutation_angle(obs%lateral, obs%normal(3))
    call put(res, sample, field_reaction, obs%reaction)
    if (stored(res, field_energy)) res%fields(field_energy)%values(1, sample) = obs%energy
    call put(res, sample, field_base_acceleration, obs%base_acceleration)
    call record_rolling(res, sample)
    res%n_recorded = sample
  end subroutine record_sample

  !> A rolling sample's regime (0) and slip speed (0), where they are stored;
  !> the sliding run writes its own over them.
  pure subroutine record_rolling(res, sample)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    if (stored(res, field_regime)) res%fields(field_regime)%values(1, sample) = 0
    if (stored(res, field_slip_speed)) res%fields(field_slip_speed)%values(1, sample) = 0
  end subroutine record_rolling

  !> An output sample of the state y (normal not projected) that stores only
  !> its geometry (contact point, centre, omega, normal, Theta), each figure
  !> computed only when a stored field needs it. The contact point is
  !> homogeneous of degree 0 in the normal: taken from y as it is.
  pure subroutine record_geometry_sample(res, sample, ball, y)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size)
    real(wp) :: contact(3), normal(3)
    if (stored(res, field_contact) .or. stored(res, field_center)) then
      contact = contact_from_normal(ball%cup, y(1:3))
      call put(res, sample, field_contact, contact)
    end if
    call put(res, sample, field_omega, y(4:6))
    if (stored(res, field_center) .or. stored(res, field_normal) .or. stored(res, field_nutation)) then
      normal = y(1:3) / sqrt(y(1) * y(1) + y(2) * y(2) + y(3) * y(3))
      if (stored(res, field_center)) res%fields(field_center)%values(:, sample) = contact + ball%radius * normal
      call put(res, sample, field_normal, normal)
      if (stored(res, field_nutation)) &
        res%fields(field_nutation)%values(1, sample) = nutation_angle(sqrt(normal(1)**2 + normal(2)**2), normal(3))
    end if
    call record_rolling(res, sample)
    res%n_recorded = sample
  end subroutine record_geometry_sample

  !> Whether the case stores this output field.
  pure logical function stored(res, field)
    type(case_result_t), intent(in) :: res
    integer, intent(in) :: field
    stored = allocated(res%fields(field)%values)
  end function stored

  !> A 3-vector field's values at one output sample, when it is stored.
  pure subroutine put(res, sample, field, values)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    integer, intent(in) :: field
    real(wp), intent(in) :: values(3)
    if (stored(res, field)) res%fields(field)%values(:, sample) = values
  end subroutine put
end module ellroll_case_run
