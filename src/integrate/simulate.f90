!> Integrate one case from t = 0 to t_end (or to the model limit it meets),
!> sampling the requested fields every output interval: fixed-step methods
!> sample their own steps; the adaptive method samples its dense output.
!> With error_estimate, the case is run again with the adaptive method at a
!> tight tolerance and the differences are its error figures.
module ellroll_simulate
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite
  use ellroll_kinds, only: wp, i8, two_pi
  use ellroll_excitation, only: excitation_harmonic, excitation_none
  use ellroll_errors, only: error_t
  use ellroll_status, only: status_completed
  use ellroll_cases, only: case_t, output_plan_t, make_ball, field_count, &
      field_contact, field_center, field_omega, field_normal, field_nutation, &
      field_reaction, field_energy, field_base_acceleration
  use ellroll_results, only: case_result_t, new_case_result
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, &
      initial_state, observe, observe_geometry, limit_status, ball_derivative, nutation_angle
  use ellroll_integrators, only: integrator_t, dop853_t, rk4_t, new_integrator, end_stage
  use ellroll_ball_steppers, only: rk4_ball_step, dop853_ball_step, dop853_ball_dense, &
      dop853_attempt_calls, dop853_dense_calls
  use ellroll_events, only: crossing_search_t
  use ellroll_linear, only: oscillation_periods
  use ellroll_ball_lanes, only: lanes, ball_lanes_t, lane_outputs_t, set_lane, lanes_rk4_step, lanes_observe
  implicit none
  private

  public :: simulate_case, simulate_batch, batchable, lanes, event_time_tolerance, reference_rtol, reference_atol

  !> Model limits are located in time to this (s).
  real(wp), parameter :: event_time_tolerance = 1.0e-12_wp
  !> Tolerances of the reference run behind error_estimate = 'reference'.
  real(wp), parameter :: reference_rtol = 1.0e-12_wp, reference_atol = 1.0e-14_wp

  !> Local maxima of a sampled signal, each refined by the parabola through
  !> the three samples around it (uneven spacing allowed).
  type :: maxima_t
    real(wp) :: t(3) = 0, v(3) = 0       !< the last three samples
    integer :: n_samples = 0
    integer(i8) :: count = 0
    real(wp) :: first = 0, last = 0      !< times of the first and last maximum
  contains
    procedure :: add => add_sample
    procedure :: mean_interval
  end type maxima_t

  !> Fourier components at the forcing frequency of the horizontal absolute
  !> acceleration of the ball and of the cup, over the last whole forcing
  !> periods (at least half the run): their ratio is the transmissibility.
  !> The model has no damping, so free oscillations never decay; projecting
  !> on the forcing frequency over whole periods separates them out.
  type :: spectrum_t
    real(wp) :: omega = 0                 !< 2 pi f
    real(wp) :: start = huge(1.0_wp)      !< window start, s
    complex(wp) :: ball(2) = 0, base(2) = 0
    real(wp) :: t_prev = 0, ball_prev(2) = 0, base_prev(2) = 0
    logical :: has_prev = .false.
  contains
    procedure :: add => add_spectrum
    procedure :: ratio => spectrum_ratio
  end type spectrum_t

  !> The search for where a step crossed a model limit, keeping the last
  !> valid observation and the status of the limit met.
  type, extends(crossing_search_t) :: limit_search_t
    type(observation_t) :: last_valid
    logical :: found_valid = .false.
    integer :: crossed = status_completed
  contains
    procedure :: begin => begin_limit_search
    procedure :: record => record_trial
  end type limit_search_t

  !> What one integration needs as it goes.
  type :: run_state_t
    type(rolling_ball_t) :: ball
    real(wp) :: energy0 = 0
    type(maxima_t) :: maxima
    type(spectrum_t) :: spectrum
    real(wp) :: spin0 = 0                 !< omega . n at the start
    real(wp) :: tan_theta_max = -1        !< largest tan Theta so far
    integer(i8) :: next_sample = 2        !< index of the next output sample
  end type run_state_t

contains

  subroutine simulate_case(cs, plan, res, err)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: res
    type(error_t), intent(inout) :: err
    type(output_plan_t) :: own_plan
    type(case_t) :: reference_case
    type(case_result_t) :: reference
    integer :: f
    if (.not. cs%error_estimate) then
      call integrate(cs, plan, res, err)
      return
    end if
    ! the error figures need these fields from both runs, stored or not
    own_plan = plan
    own_plan%fields([field_contact, field_nutation, field_energy]) = .true.
    call integrate(cs, own_plan, res, err)
    reference_case = cs
    reference_case%method = 'dop853'
    reference_case%rtol = reference_rtol
    reference_case%atol = reference_atol
    reference_case%dt = cs%t_end
    call integrate(reference_case, own_plan, reference, err)
    res%error_contact = max_difference(res%fields(field_contact)%values, reference%fields(field_contact)%values)
    res%error_theta = max_difference(res%fields(field_nutation)%values, reference%fields(field_nutation)%values)
    res%error_energy = max_difference(res%fields(field_energy)%values, reference%fields(field_energy)%values) &
                       / abs(reference%fields(field_energy)%values(1, 1))
    res%n_rhs_reference = reference%n_rhs
    do f = 1, field_count
      if (.not. plan%fields(f) .and. allocated(res%fields(f)%values)) deallocate (res%fields(f)%values)
    end do
  contains
    !> Largest distance between two sampled fields where both are defined.
    real(wp) function max_difference(a, b)
      real(wp), intent(in) :: a(:, :), b(:, :)
      integer :: j
      max_difference = 0
      do j = 1, size(a, 2)
        if (all(ieee_is_finite(a(:, j))) .and. all(ieee_is_finite(b(:, j)))) &
          max_difference = max(max_difference, norm2(a(:, j) - b(:, j)))
      end do
    end function max_difference
  end subroutine simulate_case

  subroutine integrate(cs, plan, res, err)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: res
    type(error_t), intent(inout) :: err
    class(integrator_t), allocatable :: integrator
    type(run_state_t) :: run
    real(wp) :: y(state_size), f(state_size)
    integer(i8) :: clock_start, clock_end, clock_rate

    call system_clock(clock_start, clock_rate)
    call new_integrator(trim(cs%method), integrator, err)
    if (err%failed()) return
    call start_case(cs, plan, run, res, y, f)
    if (res%status == status_completed) then
      select type (integrator)
      type is (dop853_t)
        integrator%rtol = cs%rtol
        integrator%atol = cs%atol
        call adaptive_loop(integrator, cs, plan, run, y, f, res)
      class default
        call fixed_step_loop(integrator, cs, plan, run, y, f, res)
      end select
    end if
    call finish_case(cs, run, res)
    call system_clock(clock_end)
    res%wall_time = real(clock_end - clock_start, wp) / real(clock_rate, wp)
  end subroutine integrate

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
    res = new_case_result(plan%fields, plan%n_samples)
    y = initial_state(run%ball, cs%x0, cs%y0, cs%omega0)
    call ball_derivative(run%ball, 0.0_wp, y, f)
    res%n_rhs = 1
    obs = observe(run%ball, 0.0_wp, y, f)
    run%energy0 = obs%energy
    run%spin0 = dot_product(cs%omega0, obs%normal)
    if (cs%excitation%kind == excitation_harmonic .and. cs%excitation%frequency > 0) then
      run%spectrum%omega = two_pi * cs%excitation%frequency
      if (floor(0.5_wp * cs%t_end * cs%excitation%frequency) >= 1) run%spectrum%start = &
          cs%t_end - floor(0.5_wp * cs%t_end * cs%excitation%frequency) / cs%excitation%frequency
    end if
    call track(run, res, 0.0_wp, obs)
    call record_sample(res, 1_i8, obs)
    res%status = limit_status(run%ball, y, obs)
  end subroutine start_case

  !> The figures made from the whole run.
  subroutine finish_case(cs, run, res)
    type(case_t), intent(in) :: cs
    type(run_state_t), intent(in) :: run
    type(case_result_t), intent(inout) :: res
    res%nutation_maxima = run%maxima%count
    res%nutation_period = run%maxima%mean_interval()
    if (res%status == status_completed .and. run%spectrum%has_prev .and. run%spectrum%start < cs%t_end) &
      res%transmissibility = run%spectrum%ratio()
    res%linear_periods = oscillation_periods(run%ball, run%spin0)
  end subroutine finish_case

  subroutine fixed_step_loop(integrator, cs, plan, run, y, f, res)
    class(integrator_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    real(wp), intent(inout) :: y(:), f(:)
    type(case_result_t), intent(inout) :: res
    real(wp) :: y_new(state_size), f_new(state_size), t
    type(observation_t) :: obs
    integer(i8) :: k, n_steps
    integer :: status

    n_steps = nint(cs%t_end / cs%dt, i8)
    t = 0
    do k = 1, n_steps
      call fixed_step(integrator, run, t, y, f, cs%dt, y_new, f_new, obs, status, res%n_rhs)
      if (status /= status_completed) then
        call end_at_limit(integrator, run, t, y, f, cs%dt, status, res)
        res%n_steps = k
        return
      end if
      y = y_new
      f = f_new
      t = k * cs%dt
      res%n_steps = k
      call track(run, res, t, obs)
      if (mod(k, plan%steps_per_sample) == 0) call record_sample(res, k / plan%steps_per_sample + 1, obs)
    end do
    res%t_final = t
  end subroutine fixed_step_loop

  !> One step of a fixed-step method from (t, y, f): the new state projected,
  !> f and the derived outputs there, and the limits checked. RK4 takes the
  !> fused step of the ball (the same arithmetic, tested against the generic
  !> one); other methods their own.
  subroutine fixed_step(integrator, run, t, y, f, h, y_new, f_new, obs, status, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    real(wp), intent(out) :: y_new(state_size), f_new(state_size)
    type(observation_t), intent(out) :: obs
    integer, intent(out) :: status
    integer(i8), intent(inout) :: n_rhs
    select type (integrator)
    type is (rk4_t)
      call rk4_ball_step(run%ball, t, y, f, h, y_new)
      n_rhs = n_rhs + 3
    class default
      call integrator%step(run%ball, t, y, f, h, y_new, n_rhs)
    end select
    call run%ball%project(y_new)
    call ball_derivative(run%ball, t + h, y_new, f_new)
    n_rhs = n_rhs + 1
    obs = observe(run%ball, t + h, y_new, f_new)
    status = limit_status(run%ball, y_new, obs)
  end subroutine fixed_step

  !> A step of size h from the valid state (t, y, f) crossed a limit
  !> (status): bisect on partial steps for where, and end the case there.
  subroutine end_at_limit(integrator, run, t, y, f, h, status, res)
    class(integrator_t), intent(inout) :: integrator
    type(run_state_t), intent(inout) :: run
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    integer, intent(in) :: status
    type(case_result_t), intent(inout) :: res
    type(limit_search_t) :: search
    real(wp) :: y_trial(state_size), f_trial(state_size), offset
    type(observation_t) :: obs
    integer :: trial_status
    call search%begin(h, status)
    do while (.not. search%done())
      offset = search%trial()
      call fixed_step(integrator, run, t, y, f, offset, y_trial, f_trial, obs, trial_status, res%n_rhs)
      call search%record(offset, trial_status, obs)
    end do
    res%status = search%crossed
    res%t_final = t + search%valid
    if (search%found_valid) call accumulate(run, res, search%last_valid)
  end subroutine end_at_limit

  !> Whether a case runs in a batch (simulate_batch): RK4 on a fixed cup,
  !> without the reference run; a property of the case alone, so that every
  !> run and every shard takes the same path for it.
  pure logical function batchable(cs)
    type(case_t), intent(in) :: cs
    batchable = cs%method == 'rk4' .and. cs%excitation%kind == excitation_none .and. .not. cs%error_estimate
  end function batchable

  !> Up to `lanes` batchable cases advanced together, one per SIMD lane
  !> (ellroll_ball_lanes): steps, f, the summary's quantities, the stored
  !> outputs and the limits for all lanes at once; maxima of Theta and the
  !> search for a crossed limit per lane with the one-case code. Each result equals
  !> simulate_case's to round-off (tested), whatever the other lanes hold;
  !> wall_time is the batch's time shared equally among its cases.
  subroutine simulate_batch(cases, plan, results)
    type(case_t), intent(in) :: cases(:)
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: results(:)
    type(run_state_t) :: run(lanes)
    type(ball_lanes_t) :: balls
    type(lane_outputs_t) :: out
    type(rk4_t) :: rk4
    type(observation_t) :: obs
    real(wp), dimension(lanes, state_size) :: y, f, y_new, f_new
    real(wp), dimension(lanes) :: h, energy0, tan_max, lateral_at_max, normal_z_at_max
    real(wp), dimension(lanes) :: displacement_max, horizontal_force_max, reaction_normal_max, &
                                  friction_needed_max, energy_drift, constraint_error_max
    integer(i8) :: n_steps(lanes), step, clock_start, clock_end, clock_rate
    logical :: active(lanes), accepted(lanes), theta_moved(lanes), sampled
    real(wp) :: t
    integer :: n, l, i

    n = size(cases)
    if (n == 0) return
    call system_clock(clock_start, clock_rate)
    do l = 1, lanes
      i = min(l, n)                  ! lanes past n repeat the first case, idle
      if (l <= n) then
        call start_case(cases(l), plan, run(l), results(l), y(l, :), f(l, :))
      else
        y(l, :) = y(1, :)
        f(l, :) = f(1, :)
      end if
      call set_lane(balls, l, run(i)%ball)
      h(l) = cases(i)%dt
      n_steps(l) = nint(cases(i)%t_end / cases(i)%dt, i8)
      energy0(l) = run(i)%energy0
      tan_max(l) = run(i)%tan_theta_max
      displacement_max(l) = results(i)%displacement_max
      horizontal_force_max(l) = results(i)%horizontal_force_max
      reaction_normal_max(l) = results(i)%reaction_normal_max
      friction_needed_max(l) = results(i)%friction_needed_max
      energy_drift(l) = results(i)%energy_drift
      constraint_error_max(l) = results(i)%constraint_error_max
      active(l) = l <= n .and. results(i)%status == status_completed .and. n_steps(l) > 0
    end do
    lateral_at_max = 0
    normal_z_at_max = 1
    theta_moved = .false.
    sampled = any(plan%fields)

    step = 0
    do while (any(active))
      step = step + 1
      call lanes_rk4_step(balls, y, f, h, y_new, f_new)
      call lanes_observe(balls, y_new, f_new, out)
      accepted = active .and. out%status == status_completed
      do l = 1, lanes                ! accumulate as in accumulate()
        if (.not. accepted(l)) cycle
        if (out%tan_nutation(l) > tan_max(l)) then
          tan_max(l) = out%tan_nutation(l)
          lateral_at_max(l) = out%lateral(l)
          normal_z_at_max(l) = out%normal(l, 3)
          theta_moved(l) = .true.
        end if
        displacement_max(l) = max(displacement_max(l), out%displacement(l))
        horizontal_force_max(l) = max(horizontal_force_max(l), out%horizontal_force(l))
        reaction_normal_max(l) = max(reaction_normal_max(l), out%reaction_normal(l))
        friction_needed_max(l) = max(friction_needed_max(l), out%friction_needed(l))
        energy_drift(l) = max(energy_drift(l), abs(out%energy(l) - energy0(l)) / abs(energy0(l)))
        constraint_error_max(l) = max(constraint_error_max(l), out%surface_residual(l))
      end do
      do l = 1, n
        if (.not. active(l)) cycle
        results(l)%n_rhs = results(l)%n_rhs + 4
        results(l)%n_steps = step
        if (.not. accepted(l)) then
          call store_summary(l)
          call end_at_limit(rk4, run(l), real(step - 1, wp) * h(l), y(l, :), f(l, :), h(l), out%status(l), &
                            results(l))
          active(l) = .false.
          cycle
        end if
        t = step * h(l)
        call run(l)%maxima%add(t, out%tan_nutation(l))
        if (sampled .and. mod(step, plan%steps_per_sample) == 0) then
          ! the sample from the lane's own outputs (base acceleration: 0)
          obs%normal = out%normal(l, :)
          obs%omega = y_new(l, 4:6)
          obs%contact = out%contact(l, :)
          obs%center = obs%contact + run(l)%ball%radius * obs%normal
          obs%lateral = out%lateral(l)
          obs%reaction = out%reaction(l, :)
          obs%energy = out%energy(l)
          call record_sample(results(l), step / plan%steps_per_sample + 1, obs)
        end if
        if (step == n_steps(l)) then
          results(l)%t_final = t
          call store_summary(l)
          active(l) = .false.
        end if
      end do
      do i = 1, state_size
        where (accepted)
          y(:, i) = y_new(:, i)
          f(:, i) = f_new(:, i)
        end where
      end do
    end do

    call system_clock(clock_end)
    do l = 1, n
      call finish_case(cases(l), run(l), results(l))
      results(l)%wall_time = real(clock_end - clock_start, wp) / real(clock_rate, wp) / n
    end do

  contains

    !> The lane's running summary into its result (and run state).
    subroutine store_summary(l)
      integer, intent(in) :: l
      run(l)%tan_theta_max = tan_max(l)
      if (theta_moved(l)) results(l)%theta_max = atan2(lateral_at_max(l), normal_z_at_max(l))
      results(l)%displacement_max = displacement_max(l)
      results(l)%horizontal_force_max = horizontal_force_max(l)
      results(l)%reaction_normal_max = reaction_normal_max(l)
      results(l)%friction_needed_max = friction_needed_max(l)
      results(l)%energy_drift = energy_drift(l)
      results(l)%constraint_error_max = constraint_error_max(l)
    end subroutine store_summary
  end subroutine simulate_batch

  !> Step-size control of Hairer's DOP853: accept when the error norm <= 1,
  !> next step h (0.9 err^(-1/8)) within [h/3, 6 h], never above dt (the
  !> largest step allowed). Output samples and limit crossings come from the
  !> 7th-order dense output; a sample computes only what the stored fields
  !> need. The steps are the fused ones of the ball (ellroll_ball_steppers).
  subroutine adaptive_loop(integrator, cs, plan, run, y, f, res)
    type(dop853_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    real(wp), intent(inout) :: y(:), f(:)
    type(case_result_t), intent(inout) :: res
    real(wp), parameter :: safety = 0.9_wp, min_factor = 0.333_wp, max_factor = 6
    real(wp) :: y_new(state_size), f_new(state_size), t, h, h_max, factor, length, t_sample, offset
    type(observation_t) :: obs
    type(limit_search_t) :: search
    integer :: status
    logical :: rejected, samples_complete

    samples_complete = any(plan%fields([field_energy, field_reaction, field_base_acceleration]))

    t = 0
    h_max = cs%dt
    call integrator%initial_step(run%ball, t, y, f, h_max, h, res%n_rhs)
    rejected = .false.
    do while (t < cs%t_end)
      if (t + h >= cs%t_end - 1.0e-12_wp * cs%t_end) h = cs%t_end - t
      call dop853_ball_step(integrator, run%ball, t, y, f, h, y_new)
      res%n_rhs = res%n_rhs + dop853_attempt_calls
      if (.not. ieee_is_finite(integrator%error_norm)) integrator%error_norm = huge(1.0_wp)
      if (integrator%error_norm > 1) then
        h = h * max(min_factor, safety / eighth_root(integrator%error_norm))
        rejected = .true.
        cycle
      end if
      length = sqrt(dot_product(y_new(1:3), y_new(1:3)))
      y_new(1:3) = y_new(1:3) / length
      f_new = integrator%k(:state_size, end_stage)
      f_new(1:3) = f_new(1:3) / length          ! n' is homogeneous of degree one in |n|
      obs = observe(run%ball, t + h, y_new, f_new)
      status = limit_status(run%ball, y_new, obs)
      if (status /= status_completed) then
        ! bisect on the dense output; end at the last valid point
        call search%begin(h, status)
        do while (.not. search%done())
          offset = search%trial()
          call dense_state(offset / h, obs, complete=.true., with_rate=.true.)
          call search%record(offset, limit_status(run%ball, [obs%normal, obs%omega], obs), obs)
        end do
        call record_samples_until(t + search%valid)        ! output samples before the end
        res%status = search%crossed
        res%t_final = t + search%valid
        res%n_steps = res%n_steps + 1
        if (search%found_valid) call accumulate(run, res, search%last_valid)
        return
      end if
      call record_samples_until(t + h)
      t = t + h
      y = y_new
      f = f_new
      res%n_steps = res%n_steps + 1
      call track(run, res, t, obs)
      if (integrator%error_norm == 0) then
        factor = max_factor
      else
        factor = min(max_factor, safety / eighth_root(integrator%error_norm))
      end if
      if (rejected) factor = min(1.0_wp, factor)
      rejected = .false.
      h = min(h * factor, h_max)
    end do
    res%t_final = cs%t_end

  contains

    !> x^(1/8) by three square roots (a fraction of the cost of x**0.125).
    pure real(wp) function eighth_root(x)
      real(wp), intent(in) :: x
      eighth_root = sqrt(sqrt(sqrt(x)))
    end function eighth_root

    !> Derived outputs at t + theta h from the dense output: the geometry
    !> only, or when complete all of them, with f there (one more RHS call)
    !> when with_rate (the limits and the stored reaction need it).
    subroutine dense_state(theta, obs_at, complete, with_rate)
      real(wp), intent(in) :: theta
      type(observation_t), intent(out) :: obs_at
      logical, intent(in) :: complete, with_rate
      real(wp) :: y_at(state_size), f_at(state_size)
      logical :: prepared
      call dop853_ball_dense(integrator, run%ball, theta, y_at, prepared)
      if (prepared) res%n_rhs = res%n_rhs + dop853_dense_calls
      call run%ball%project(y_at)
      if (.not. complete) then
        obs_at = observe_geometry(run%ball, y_at)
        return
      end if
      f_at = 0
      if (with_rate) then
        call ball_derivative(run%ball, t + theta * h, y_at, f_at)
        res%n_rhs = res%n_rhs + 1
      end if
      obs_at = observe(run%ball, t + theta * h, y_at, f_at)
    end subroutine dense_state

    !> Record every output sample in (t, t_until] of the current step.
    subroutine record_samples_until(t_until)
      real(wp), intent(in) :: t_until
      type(observation_t) :: obs_at
      do while (run%next_sample <= plan%n_samples)
        t_sample = real(run%next_sample - 1, wp) * plan%interval
        if (t_sample > t_until * (1 + 1.0e-14_wp)) exit
        if (abs(t_sample - (t + h)) <= 1.0e-14_wp * max(1.0_wp, t_sample)) then
          call record_sample(res, run%next_sample, obs)         ! the step's own end point
        else
          call dense_state((t_sample - t) / h, obs_at, samples_complete, plan%fields(field_reaction))
          call record_sample(res, run%next_sample, obs_at)
        end if
        run%next_sample = run%next_sample + 1
      end do
    end subroutine record_samples_until
  end subroutine adaptive_loop

  pure subroutine begin_limit_search(self, invalid, crossed)
    class(limit_search_t), intent(inout) :: self
    real(wp), intent(in) :: invalid
    integer, intent(in) :: crossed
    call self%start(invalid, event_time_tolerance)
    self%found_valid = .false.
    self%crossed = crossed
  end subroutine begin_limit_search

  pure subroutine record_trial(self, offset, status, obs)
    class(limit_search_t), intent(inout) :: self
    real(wp), intent(in) :: offset
    integer, intent(in) :: status
    type(observation_t), intent(in) :: obs
    call self%report(offset, status == status_completed)
    if (status == status_completed) then
      self%last_valid = obs
      self%found_valid = .true.
    else
      self%crossed = status
    end if
  end subroutine record_trial

  pure subroutine add_sample(self, t, v)
    class(maxima_t), intent(inout) :: self
    real(wp), intent(in) :: t, v
    real(wp) :: d1, d3, numerator, denominator, t_peak
    self%t = [self%t(2:3), t]
    self%v = [self%v(2:3), v]
    self%n_samples = self%n_samples + 1
    if (self%n_samples < 3) return
    if (.not. (self%v(2) > self%v(1) .and. self%v(2) >= self%v(3))) return
    ! vertex of the parabola through the three samples
    d1 = self%t(2) - self%t(1)
    d3 = self%t(2) - self%t(3)
    numerator = d1**2 * (self%v(2) - self%v(3)) - d3**2 * (self%v(2) - self%v(1))
    denominator = d1 * (self%v(2) - self%v(3)) - d3 * (self%v(2) - self%v(1))
    t_peak = self%t(2)
    if (denominator /= 0) t_peak = self%t(2) - 0.5_wp * numerator / denominator
    if (self%count == 0) self%first = t_peak
    self%last = t_peak
    self%count = self%count + 1
  end subroutine add_sample

  pure real(wp) function mean_interval(self)
    class(maxima_t), intent(in) :: self
    if (self%count < 3) then
      mean_interval = ieee_value(0.0_wp, ieee_quiet_nan)
    else
      mean_interval = (self%last - self%first) / real(self%count - 1, wp)
    end if
  end function mean_interval

  !> Everything a step's end point adds to the summary.
  pure subroutine track(run, res, t, obs)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    ! maxima of tan Theta are the maxima of Theta (tan is increasing)
    call run%maxima%add(t, obs%tan_nutation)
    if (run%spectrum%omega > 0) call run%spectrum%add(t, obs%center_acceleration(1:2), obs%base_acceleration(1:2))
    call accumulate(run, res, obs)
  end subroutine track

  pure subroutine add_spectrum(self, t, ball, base)
    class(spectrum_t), intent(inout) :: self
    real(wp), intent(in) :: t, ball(2), base(2)
    complex(wp) :: phase_prev, phase_now
    if (t < self%start) return
    if (self%has_prev) then       ! trapezoid rule on (t_prev, t]
      phase_prev = exp(cmplx(0.0_wp, -self%omega * self%t_prev, wp))
      phase_now = exp(cmplx(0.0_wp, -self%omega * t, wp))
      self%ball = self%ball + (t - self%t_prev) / 2 * (self%ball_prev * phase_prev + ball * phase_now)
      self%base = self%base + (t - self%t_prev) / 2 * (self%base_prev * phase_prev + base * phase_now)
    end if
    self%t_prev = t
    self%ball_prev = ball
    self%base_prev = base
    self%has_prev = .true.
  end subroutine add_spectrum

  !> NaN when the cup does not move horizontally (undefined, not infinite).
  pure real(wp) function spectrum_ratio(self)
    class(spectrum_t), intent(in) :: self
    if (sum(abs(self%base)**2) > 0) then
      spectrum_ratio = sqrt(sum(abs(self%ball)**2) / sum(abs(self%base)**2))
    else
      spectrum_ratio = ieee_value(0.0_wp, ieee_quiet_nan)
    end if
  end function spectrum_ratio

  pure subroutine accumulate(run, res, obs)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    type(observation_t), intent(in) :: obs
    if (obs%tan_nutation > run%tan_theta_max) then     ! one atan2 per new maximum only
      run%tan_theta_max = obs%tan_nutation
      res%theta_max = nutation_angle(obs)
    end if
    ! the norms written out, as the batch path (ellroll_ball_lanes) computes them
    res%displacement_max = max(res%displacement_max, &
        sqrt(obs%center(1)**2 + obs%center(2)**2 + (obs%center(3) - run%ball%radius)**2))
    res%horizontal_force_max = max(res%horizontal_force_max, sqrt(obs%reaction(1)**2 + obs%reaction(2)**2))
    res%reaction_normal_max = max(res%reaction_normal_max, obs%reaction_normal)
    res%friction_needed_max = max(res%friction_needed_max, obs%friction_needed)
    res%energy_drift = max(res%energy_drift, abs(obs%energy - run%energy0) / abs(run%energy0))
    res%constraint_error_max = max(res%constraint_error_max, obs%surface_residual)
  end subroutine accumulate

  pure subroutine record_sample(res, sample, obs)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    type(observation_t), intent(in) :: obs
    call put(res, field_contact, obs%contact)
    call put(res, field_center, obs%center)
    call put(res, field_omega, obs%omega)
    call put(res, field_normal, obs%normal)
    if (allocated(res%fields(field_nutation)%values)) call put(res, field_nutation, [nutation_angle(obs)])
    call put(res, field_reaction, obs%reaction)
    call put(res, field_energy, [obs%energy])
    call put(res, field_base_acceleration, obs%base_acceleration)
  contains
    pure subroutine put(res, field, values)
      type(case_result_t), intent(inout) :: res
      integer, intent(in) :: field
      real(wp), intent(in) :: values(:)
      if (allocated(res%fields(field)%values)) res%fields(field)%values(:, sample) = values
    end subroutine put
  end subroutine record_sample
end module ellroll_simulate
