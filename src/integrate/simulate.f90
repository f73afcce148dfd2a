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
  use ellroll_results, only: case_result_t, allocate_fields, fill_unrecorded
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, &
      initial_state, observe, limit_status, ball_derivative, nutation_angle
  use ellroll_integrators, only: integrator_t, dop853_t, rk4_t, new_integrator, max_equations
  use ellroll_dop853_tableau, only: end_stage
  use ellroll_ball_steppers, only: rk4_ball_step, dop853_ball_step, dop853_ball_dense, &
      dop853_attempt_calls, dop853_dense_calls, lanes_rk4_step, lanes_dop853_attempt
  use ellroll_events, only: crossing_search_t
  use ellroll_ellipsoid, only: contact_from_normal
  use ellroll_linear, only: oscillation_periods
  use ellroll_ball_lanes, only: lanes, ball_lanes_t, lane_outputs_t, set_lane, lanes_observe
  implicit none
  private

  public :: simulate_case, simulate_batch, batchable, lanes, event_time_tolerance, reference_rtol, reference_atol

  !> Model limits are located in time to this (s).
  real(wp), parameter :: event_time_tolerance = 1.0e-12_wp
  !> Tolerances of the reference run behind error_estimate = 'reference'.
  real(wp), parameter :: reference_rtol = 1.0e-12_wp, reference_atol = 1.0e-14_wp
  !> Output samples held per batch lane between flushes into the results
  !> (lane_sample_block_t).
  integer, parameter :: block_samples = 128
  !> Step-size control of DOP853 (Hairer's constants).
  real(wp), parameter :: adaptive_safety = 0.9_wp, adaptive_min_factor = 0.333_wp, adaptive_max_factor = 6

  !> Local maxima of a sampled signal, each refined by the parabola through
  !> the three samples around it (uneven spacing allowed).
  type :: maxima_t
    real(wp) :: t(3) = 0, v(3) = 0       !< the last three samples
    integer :: n_samples = 0
    integer(i8) :: count = 0
    real(wp) :: first = 0, last = 0      !< times of the first and last maximum
  contains
    procedure :: add => add_sample
    procedure :: add_peak
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

  !> A maximum of the nutation angle located inside a step.
  type :: nutation_peak_t
    real(wp) :: t = 0, tan_nutation = 0
    real(wp) :: lateral = 0, normal_z = 1     !< of the unit normal there
  end type nutation_peak_t

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
    !> maxima kept before the root or the division by |E0|, taken once in
    !> finish_case: both are correctly rounded and monotonic, so the result
    !> is the same number (the batch's lanes keep the same)
    real(wp) :: displacement_sq_max = 0, horizontal_force_sq_max = 0, energy_deviation_max = 0
    integer(i8) :: next_sample = 2        !< index of the next output sample
  end type run_state_t

  !> The running summary of every lane of a batch (accumulate across lanes),
  !> the squared maxima as run_state_t keeps them.
  type :: lane_summary_t
    real(wp), dimension(lanes) :: energy0 = 1, tan_max = -1, lateral_at_max = 0, normal_z_at_max = 1
    real(wp), dimension(lanes) :: displacement_sq_max = 0, horizontal_force_sq_max = 0, reaction_normal_max = 0, &
                                  friction_needed_max = 0, energy_deviation_max = 0, constraint_error_max = 0
    logical :: theta_moved(lanes) = .false.
  contains
    procedure :: load => load_summary
    procedure :: add => add_to_summary
    procedure :: note_nutation => note_lane_nutation
    procedure :: store => store_summary
  end type lane_summary_t

  !> Output samples of a batch's RK4 lanes, held a block at a time: a
  !> sample step stores each value for every lane at once, and each case's
  !> result takes its samples of the block in one pass (flush). Stored lane
  !> by lane into the eight results, a sample cost about 90 ns per case,
  !> 14 % of a batch storing every field at 100 Hz (bench/throughput); now
  !> 6-9 %, mostly the results' memory filling. Long blocks give each of the
  !> 40 streams a flush writes runs that the prefetcher follows (32 samples:
  !> 6-10 %; 128: 6.5-8 %); the block is 139 kB.
  type :: lane_sample_block_t
    integer :: count = 0                  !< samples held
    integer(i8) :: first = 2              !< output sample index of the first one held
    logical :: fields(field_count) = .false.
    real(wp), dimension(lanes, 3, block_samples) :: contact, center, omega, normal, reaction
    real(wp), dimension(lanes, block_samples) :: lateral, energy
  contains
    procedure :: add => add_lane_samples
    procedure :: flush => flush_lane_samples
    procedure :: next_block => next_sample_block
  end type lane_sample_block_t

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
    call allocate_fields(res, plan%fields, plan%n_samples)
    y = initial_state(run%ball, cs%x0, cs%y0, cs%omega0)
    call ball_derivative(run%ball, 0.0_wp, y, f)
    res%n_rhs = 1
    call observe(run%ball, 0.0_wp, y, f, obs)
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
    res%displacement_max = sqrt(run%displacement_sq_max)
    res%horizontal_force_max = sqrt(run%horizontal_force_sq_max)
    res%energy_drift = run%energy_deviation_max / abs(run%energy0)
    res%linear_periods = oscillation_periods(run%ball, run%spin0)
    call fill_unrecorded(res)
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
    call observe(run%ball, t + h, y_new, f_new, obs)
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

  !> Whether a case runs in a batch (simulate_batch): RK4 or DOP853 on a
  !> fixed cup, without the reference run; a property of the case alone, so
  !> that every run and every shard takes the same path for it.
  pure logical function batchable(cs)
    type(case_t), intent(in) :: cs
    batchable = (cs%method == 'rk4' .or. cs%method == 'dop853') .and. cs%excitation%kind == excitation_none &
                .and. .not. cs%error_estimate
  end function batchable

  !> Up to `lanes` batchable cases of one method advanced together, one per
  !> SIMD lane (ellroll_ball_lanes): steps, f, the summary's quantities, the
  !> stored outputs and the limits for all lanes at once, each lane with its
  !> own step; maxima of Theta, dense output and the search for a crossed
  !> limit per lane with the one-case code. Each result equals
  !> simulate_case's to round-off (tested), whatever the other lanes hold;
  !> wall_time is the batch's time shared equally among its cases.
  subroutine simulate_batch(cases, plan, results)
    type(case_t), intent(in) :: cases(:)
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: results(:)
    type(run_state_t) :: run(lanes)
    type(ball_lanes_t) :: balls
    type(lane_summary_t) :: summary
    real(wp), dimension(lanes, state_size) :: y, f
    integer(i8) :: clock_start, clock_end, clock_rate
    logical :: active(lanes)
    integer :: n, l, donor

    n = size(cases)
    if (n == 0) return
    call system_clock(clock_start, clock_rate)
    do l = 1, n
      call start_case(cases(l), plan, run(l), results(l), y(l, :), f(l, :))
      call set_lane(balls, l, run(l)%ball)
      call summary%load(l, run(l), results(l))
      active(l) = results(l)%status == status_completed .and. cases(l)%t_end > 0
    end do
    active(n + 1:) = .false.
    ! idle lanes compute a valid case's steps alongside, never a state outside the model
    donor = findloc(active, .true., dim=1)
    if (donor > 0) then
      do l = 1, lanes
        if (active(l)) cycle
        call set_lane(balls, l, run(donor)%ball)
        y(l, :) = y(donor, :)
        f(l, :) = f(donor, :)
      end do
      if (cases(1)%method == 'dop853') then
        call adaptive_lanes()
      else
        call fixed_step_lanes()
      end if
    end if

    call system_clock(clock_end)
    do l = 1, n
      call finish_case(cases(l), run(l), results(l))
      results(l)%wall_time = real(clock_end - clock_start, wp) / real(clock_rate, wp) / n
    end do

  contains

    !> RK4 with each case's dt (fixed_step_loop across lanes).
    subroutine fixed_step_lanes()
      type(rk4_t) :: rk4
      type(lane_outputs_t) :: out
      type(lane_sample_block_t) :: samples
      real(wp), dimension(lanes, state_size) :: y_new, f_new
      real(wp) :: h(lanes), t
      integer(i8) :: n_steps(lanes), step
      logical :: accepted(lanes), sampled, sample_step
      integer :: i
      do l = 1, lanes
        i = merge(l, donor, active(l))
        h(l) = cases(i)%dt
        n_steps(l) = nint(cases(i)%t_end / cases(i)%dt, i8)
        if (l <= n) active(l) = active(l) .and. n_steps(l) > 0
      end do
      samples%fields = plan%fields
      sampled = any(plan%fields)
      step = 0
      do while (any(active))
        step = step + 1
        call lanes_rk4_step(balls, y, f, h, y_new, f_new)
        call lanes_observe(balls, y_new, f_new, out)
        sample_step = sampled .and. mod(step, plan%steps_per_sample) == 0
        if (sample_step) call samples%add(out, y_new, balls%radius)
        accepted = active .and. out%status == status_completed
        call summary%add(out, accepted)
        do l = 1, n
          if (.not. active(l)) cycle
          results(l)%n_rhs = results(l)%n_rhs + 4
          results(l)%n_steps = step
          if (.not. accepted(l)) then      ! this step's sample is past the limit: not the case's
            call samples%flush(l, samples%count - merge(1, 0, sample_step), results(l))
            call summary%store(l, run(l), results(l))
            call end_at_limit(rk4, run(l), real(step - 1, wp) * h(l), y(l, :), f(l, :), h(l), out%status(l), &
                              results(l))
            active(l) = .false.
            cycle
          end if
          t = step * h(l)
          call run(l)%maxima%add(t, out%tan_nutation(l))
          if (step == n_steps(l)) then
            call samples%flush(l, samples%count, results(l))
            results(l)%t_final = t
            call summary%store(l, run(l), results(l))
            active(l) = .false.
          end if
        end do
        if (samples%count == block_samples) then
          do l = 1, n
            if (active(l)) call samples%flush(l, samples%count, results(l))
          end do
          call samples%next_block()
        end if
        if (all(accepted)) then             ! the rule: whole vectors, no test per lane
          y = y_new
          f = f_new
        else
          do i = 1, state_size
            where (accepted)
              y(:, i) = y_new(:, i)
              f(:, i) = f_new(:, i)
            end where
          end do
        end if
      end do
    end subroutine fixed_step_lanes

    !> DOP853 with each case's tolerances (adaptive_loop across lanes): the
    !> attempts of all lanes together, the step control of each lane its
    !> own. An attempt is copied into the lane's dop853_t only when its dense
    !> output is needed (a sample inside the step, a crossed limit).
    subroutine adaptive_lanes()
      type(dop853_t) :: dop(lanes)
      type(lane_outputs_t) :: out
      real(wp), dimension(lanes, state_size) :: y_raw, y_new, f_new
      real(wp) :: k(lanes, state_size, end_stage)
      real(wp), dimension(lanes) :: t, h, h_max, t_end, rtol, atol, error_norm
      type(nutation_peak_t) :: peak
      logical :: accepted(lanes), rejected(lanes), loaded
      integer(i8) :: idle_rhs               ! RHS calls of idle lanes, counted nowhere
      integer :: i
      idle_rhs = 0
      t = 0
      rejected = .false.
      do l = 1, lanes
        i = merge(l, donor, active(l))
        dop(l)%rtol = cases(i)%rtol
        dop(l)%atol = cases(i)%atol
        rtol(l) = cases(i)%rtol
        atol(l) = cases(i)%atol
        h_max(l) = cases(i)%dt
        t_end(l) = cases(i)%t_end
        if (active(l)) then
          call dop(l)%initial_step(run(l)%ball, t(l), y(l, :), f(l, :), h_max(l), h(l), results(l)%n_rhs)
        else
          call dop(l)%initial_step(run(i)%ball, t(l), y(l, :), f(l, :), h_max(l), h(l), idle_rhs)
        end if
      end do
      do while (any(active))
        do l = 1, lanes
          if (active(l)) h(l) = last_step_clipped(t(l), h(l), t_end(l))
        end do
        call lanes_dop853_attempt(balls, y, f, h, rtol, atol, k, y_raw, error_norm)
        accepted = .false.
        do l = 1, n
          if (.not. active(l)) cycle
          results(l)%n_rhs = results(l)%n_rhs + dop853_attempt_calls
          if (.not. ieee_is_finite(error_norm(l))) error_norm(l) = huge(1.0_wp)
          accepted(l) = error_norm(l) <= 1
          if (.not. accepted(l)) then
            h(l) = h(l) * rejected_step_factor(error_norm(l))
            rejected(l) = .true.
          end if
        end do
        if (.not. any(accepted)) cycle
        do l = 1, lanes
          y_new(l, :) = y_raw(l, :)
          call project_with_rate(y_new(l, :), k(l, :, end_stage), f_new(l, :))
        end do
        call lanes_observe(balls, y_new, f_new, out)
        call summary%add(out, accepted .and. out%status == status_completed)
        do l = 1, n
          if (.not. accepted(l)) cycle
          if (out%status(l) /= status_completed) then
            call summary%store(l, run(l), results(l))
            call load_attempt(dop(l), l, t(l), h(l), y, y_raw, k, error_norm(l))
            call stop_in_step(dop(l), run(l), plan, out%status(l), results(l))
            active(l) = .false.
            cycle
          end if
          loaded = .false.
          if (sample_due(run(l), plan, t(l) + h(l))) then
            call load_attempt(dop(l), l, t(l), h(l), y, y_raw, k, error_norm(l))
            loaded = .true.
            call record_samples_until(dop(l), run(l), plan, t(l) + h(l), &
                                      lane_observation(out, y_new, l, run(l)%ball%radius), results(l))
          end if
          if (nutation_peak_inside(y(l, :), f(l, :), y_new(l, :), f_new(l, :))) then
            if (.not. loaded) call load_attempt(dop(l), l, t(l), h(l), y, y_raw, k, error_norm(l))
            call locate_nutation_peak(dop(l), run(l)%ball, peak, results(l)%n_rhs)
            call run(l)%maxima%add_peak(peak%t)
            call summary%note_nutation(l, peak%tan_nutation, peak%lateral, peak%normal_z)
          end if
          t(l) = t(l) + h(l)
          results(l)%n_steps = results(l)%n_steps + 1
          if (t(l) < t_end(l)) then
            y(l, :) = y_new(l, :)
            f(l, :) = f_new(l, :)
            h(l) = min(h(l) * accepted_step_factor(error_norm(l), rejected(l)), h_max(l))
            rejected(l) = .false.
          else                     ! done: the lane repeats its last attempt, idle
            results(l)%t_final = t_end(l)
            call summary%store(l, run(l), results(l))
            active(l) = .false.
          end if
        end do
      end do
    end subroutine adaptive_lanes
  end subroutine simulate_batch

  !> Whether the next output sample falls at or before t_until (to round-off).
  pure logical function sample_due(run, plan, t_until)
    type(run_state_t), intent(in) :: run
    type(output_plan_t), intent(in) :: plan
    real(wp), intent(in) :: t_until
    sample_due = run%next_sample <= plan%n_samples
    if (sample_due) sample_due = real(run%next_sample - 1, wp) * plan%interval <= t_until * (1 + 1.0e-14_wp)
  end function sample_due

  !> Lane l's last attempt (from t, step h: y -> y_raw, stages k) into a
  !> dop853_t, as dop853_ball_step leaves it, for its dense output.
  pure subroutine load_attempt(dop, l, t, h, y, y_raw, k, error_norm)
    type(dop853_t), intent(inout) :: dop
    integer, intent(in) :: l
    real(wp), intent(in) :: t, h, y(lanes, state_size), y_raw(lanes, state_size), k(lanes, state_size, end_stage)
    real(wp), intent(in) :: error_norm
    dop%k(:state_size, :end_stage) = k(l, :, :)
    dop%y_old(:state_size) = y(l, :)
    dop%y_new(:state_size) = y_raw(l, :)
    dop%t_old = t
    dop%h = h
    dop%error_norm = error_norm
    dop%dense_ready = .false.
  end subroutine load_attempt

  !> Lane l's end-of-step observation, what an output sample stores (no base
  !> acceleration: batches have fixed cups).
  pure function lane_observation(out, y, l, radius) result(obs)
    type(lane_outputs_t), intent(in) :: out
    real(wp), intent(in) :: y(lanes, state_size), radius
    integer, intent(in) :: l
    type(observation_t) :: obs
    obs%normal = out%normal(l, :)
    obs%omega = y(l, 4:6)
    obs%contact = out%contact(l, :)
    obs%center = obs%contact + radius * obs%normal
    obs%lateral = out%lateral(l)
    obs%reaction = out%reaction(l, :)
    obs%energy = out%energy(l)
    obs%base_acceleration = 0
  end function lane_observation

  !> A case's running summary (accumulate), lane by lane.
  pure subroutine load_summary(self, l, run, res)
    class(lane_summary_t), intent(inout) :: self
    integer, intent(in) :: l
    type(run_state_t), intent(in) :: run
    type(case_result_t), intent(in) :: res
    self%energy0(l) = run%energy0
    self%tan_max(l) = run%tan_theta_max
    self%displacement_sq_max(l) = run%displacement_sq_max
    self%horizontal_force_sq_max(l) = run%horizontal_force_sq_max
    self%reaction_normal_max(l) = res%reaction_normal_max
    self%friction_needed_max(l) = res%friction_needed_max
    self%energy_deviation_max(l) = run%energy_deviation_max
    self%constraint_error_max(l) = res%constraint_error_max
  end subroutine load_summary

  !> What the accepted lanes' new states add to the summary (accumulate);
  !> branch-free (merge), so that the loop vectorizes.
  pure subroutine add_to_summary(self, out, accepted)
    class(lane_summary_t), intent(inout) :: self
    type(lane_outputs_t), intent(in) :: out
    logical, intent(in) :: accepted(lanes)
    logical :: higher
    integer :: l
    do l = 1, lanes
      higher = accepted(l) .and. out%tan_nutation(l) > self%tan_max(l)
      self%tan_max(l) = merge(out%tan_nutation(l), self%tan_max(l), higher)
      self%lateral_at_max(l) = merge(out%lateral(l), self%lateral_at_max(l), higher)
      self%normal_z_at_max(l) = merge(out%normal(l, 3), self%normal_z_at_max(l), higher)
      self%theta_moved(l) = self%theta_moved(l) .or. higher
      self%displacement_sq_max(l) = merge(max(self%displacement_sq_max(l), out%displacement_sq(l)), &
                                          self%displacement_sq_max(l), accepted(l))
      self%horizontal_force_sq_max(l) = merge(max(self%horizontal_force_sq_max(l), out%horizontal_force_sq(l)), &
                                              self%horizontal_force_sq_max(l), accepted(l))
      self%reaction_normal_max(l) = merge(max(self%reaction_normal_max(l), out%reaction_normal(l)), &
                                          self%reaction_normal_max(l), accepted(l))
      self%friction_needed_max(l) = merge(max(self%friction_needed_max(l), out%friction_needed(l)), &
                                          self%friction_needed_max(l), accepted(l))
      self%energy_deviation_max(l) = merge(max(self%energy_deviation_max(l), abs(out%energy(l) - self%energy0(l))), &
                                           self%energy_deviation_max(l), accepted(l))
      self%constraint_error_max(l) = merge(max(self%constraint_error_max(l), out%surface_residual(l)), &
                                           self%constraint_error_max(l), accepted(l))
    end do
  end subroutine add_to_summary

  !> A nutation angle of lane l's case (tan Theta, and the lateral and
  !> vertical components of the unit normal) for the largest Theta.
  pure subroutine note_lane_nutation(self, l, tan_nutation, lateral, normal_z)
    class(lane_summary_t), intent(inout) :: self
    integer, intent(in) :: l
    real(wp), intent(in) :: tan_nutation, lateral, normal_z
    if (tan_nutation > self%tan_max(l)) then
      self%tan_max(l) = tan_nutation
      self%lateral_at_max(l) = lateral
      self%normal_z_at_max(l) = normal_z
      self%theta_moved(l) = .true.
    end if
  end subroutine note_lane_nutation

  !> Lane l's running summary into its result (and run state).
  pure subroutine store_summary(self, l, run, res)
    class(lane_summary_t), intent(in) :: self
    integer, intent(in) :: l
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    run%tan_theta_max = self%tan_max(l)
    if (self%theta_moved(l)) res%theta_max = nutation_angle(self%lateral_at_max(l), self%normal_z_at_max(l))
    run%displacement_sq_max = self%displacement_sq_max(l)
    run%horizontal_force_sq_max = self%horizontal_force_sq_max(l)
    res%reaction_normal_max = self%reaction_normal_max(l)
    res%friction_needed_max = self%friction_needed_max(l)
    run%energy_deviation_max = self%energy_deviation_max(l)
    res%constraint_error_max = self%constraint_error_max(l)
  end subroutine store_summary

  !> Step-size control of Hairer's DOP853: accept when the error norm <= 1,
  !> next step h (0.9 err^(-1/8)) within [h/3, 6 h], never above dt (the
  !> largest step allowed). Output samples, limit crossings and the maxima
  !> of Theta come from the 7th-order dense output, so that they do not
  !> depend on where the steps fall; a sample computes only what the stored
  !> fields need. The steps are the fused ones of the ball (ellroll_ball_steppers).
  subroutine adaptive_loop(integrator, cs, plan, run, y, f, res)
    type(dop853_t), intent(inout) :: integrator
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(run_state_t), intent(inout) :: run
    real(wp), intent(inout) :: y(:), f(:)
    type(case_result_t), intent(inout) :: res
    real(wp) :: y_new(state_size), f_new(state_size), t, h, h_max
    type(observation_t) :: obs
    type(nutation_peak_t) :: peak
    integer :: status
    logical :: rejected

    t = 0
    h_max = cs%dt
    call integrator%initial_step(run%ball, t, y, f, h_max, h, res%n_rhs)
    rejected = .false.
    do while (t < cs%t_end)
      h = last_step_clipped(t, h, cs%t_end)
      call dop853_ball_step(integrator, run%ball, t, y, f, h, y_new)
      res%n_rhs = res%n_rhs + dop853_attempt_calls
      if (.not. ieee_is_finite(integrator%error_norm)) integrator%error_norm = huge(1.0_wp)
      if (integrator%error_norm > 1) then
        h = h * rejected_step_factor(integrator%error_norm)
        rejected = .true.
        cycle
      end if
      call project_with_rate(y_new, integrator%k(:state_size, end_stage), f_new)
      call observe(run%ball, t + h, y_new, f_new, obs)
      status = limit_status(run%ball, y_new, obs)
      if (status /= status_completed) then
        call stop_in_step(integrator, run, plan, status, res)
        return
      end if
      call record_samples_until(integrator, run, plan, t + h, obs, res)
      if (nutation_peak_inside(y, f, y_new, f_new)) then
        call locate_nutation_peak(integrator, run%ball, peak, res%n_rhs)
        call run%maxima%add_peak(peak%t)
        call note_nutation(run, res, peak%tan_nutation, peak%lateral, peak%normal_z)
      end if
      t = t + h
      y = y_new
      f = f_new
      res%n_steps = res%n_steps + 1
      call track_step_end(run, res, t, obs)
      h = min(h * accepted_step_factor(integrator%error_norm, rejected), h_max)
      rejected = .false.
    end do
    res%t_final = cs%t_end
  end subroutine adaptive_loop

  !> The step from t, shortened to end exactly at t_end when it would end
  !> at or within round-off of it.
  pure real(wp) function last_step_clipped(t, h, t_end) result(step)
    real(wp), intent(in) :: t, h, t_end
    step = h
    if (t + h >= t_end - 1.0e-12_wp * t_end) step = t_end - t
  end function last_step_clipped

  !> The new step after a rejected attempt with this error norm (> 1).
  pure real(wp) function rejected_step_factor(error_norm) result(factor)
    real(wp), intent(in) :: error_norm
    factor = max(adaptive_min_factor, adaptive_safety / eighth_root(error_norm))
  end function rejected_step_factor

  !> The next step after an accepted one; no growth right after a rejection.
  pure real(wp) function accepted_step_factor(error_norm, after_rejection) result(factor)
    real(wp), intent(in) :: error_norm
    logical, intent(in) :: after_rejection
    if (error_norm == 0) then
      factor = adaptive_max_factor
    else
      factor = min(adaptive_max_factor, adaptive_safety / eighth_root(error_norm))
    end if
    if (after_rejection) factor = min(1.0_wp, factor)
  end function accepted_step_factor

  !> x^(1/8) by three square roots (a fraction of the cost of x**0.125).
  pure real(wp) function eighth_root(x)
    real(wp), intent(in) :: x
    eighth_root = sqrt(sqrt(sqrt(x)))
  end function eighth_root

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

  !> Whether Theta has a maximum in the step from (y, f) to (y_new, f_new):
  !> d tan(Theta)/dt, of the sign of (n_x n_x' + n_y n_y') n_z - (n_x^2 +
  !> n_y^2) n_z', goes from >= 0 to < 0 (half-open, so that a maximum at a
  !> step's end is found once).
  pure logical function nutation_peak_inside(y, f, y_new, f_new)
    real(wp), intent(in) :: y(state_size), f(state_size), y_new(state_size), f_new(state_size)
    nutation_peak_inside = nutation_trend(y, f) >= 0 .and. nutation_trend(y_new, f_new) < 0
  end function nutation_peak_inside

  !> Of the sign of d tan(Theta)/dt at the state y with rate y' (any scale
  !> of either: the part of y' along y cancels, so |n| need not be 1).
  pure real(wp) function nutation_trend(y, rate)
    real(wp), intent(in) :: y(state_size), rate(state_size)
    nutation_trend = (y(1) * rate(1) + y(2) * rate(2)) * y(3) - (y(1)**2 + y(2)**2) * rate(3)
  end function nutation_trend

  !> The maximum of Theta inside the last attempt (in dop): the root of
  !> d tan(Theta)/dt on its dense output and the interpolant's derivative (a
  !> simple root: its time is well conditioned), by regula falsi with the
  !> Illinois modification (superlinear, the bracket kept) to a bracket of
  !> 4 units of round-off in theta: about 10 evaluations where bisection
  !> takes 52.
  subroutine locate_nutation_peak(dop, ball, peak, n_rhs)
    type(dop853_t), intent(inout) :: dop
    type(rolling_ball_t), intent(in) :: ball
    type(nutation_peak_t), intent(out) :: peak
    integer(i8), intent(inout) :: n_rhs
    integer, parameter :: max_iterations = 100
    real(wp), parameter :: resolution = 4 * epsilon(1.0_wp)
    real(wp) :: low, high, middle, trend_low, trend_high, trend, y(state_size), lateral
    integer :: i, kept_side
    logical :: prepared
    call dop853_ball_dense(dop, ball, 0.0_wp, y, prepared)        ! prepares the interpolant
    if (prepared) n_rhs = n_rhs + dop853_dense_calls
    low = 0
    high = 1
    trend_low = trend_at(low)
    trend_high = trend_at(high)
    ! a root at an end, where round-off decided the step's test: that end
    if (trend_low < 0) then
      high = low
    else if (trend_high >= 0) then
      low = high
    end if
    kept_side = 0
    do i = 1, max_iterations
      if (high - low <= resolution) exit
      middle = (low * trend_high - high * trend_low) / (trend_high - trend_low)
      ! round-off may put the secant's root on an end: halve instead
      if (.not. (middle > low .and. middle < high)) middle = 0.5_wp * (low + high)
      trend = trend_at(middle)
      if (trend >= 0) then
        low = middle
        trend_low = trend
        if (kept_side == 1) trend_high = 0.5_wp * trend_high      ! Illinois: the other end stayed twice
        kept_side = 1
      else
        high = middle
        trend_high = trend
        if (kept_side == -1) trend_low = 0.5_wp * trend_low
        kept_side = -1
      end if
    end do
    middle = 0.5_wp * (low + high)
    call dop853_ball_dense(dop, ball, middle, y, prepared)
    y(1:3) = y(1:3) / sqrt(y(1)**2 + y(2)**2 + y(3)**2)
    lateral = sqrt(y(1)**2 + y(2)**2)
    peak%t = dop%t_old + middle * dop%h
    peak%tan_nutation = lateral / y(3)
    peak%lateral = lateral
    peak%normal_z = y(3)
  contains
    real(wp) function trend_at(theta)
      real(wp), intent(in) :: theta
      real(wp) :: state(state_size), rate(max_equations)
      call dop853_ball_dense(dop, ball, theta, state, prepared)
      call dop%dense_rate(theta, rate)
      trend_at = nutation_trend(state, rate(:state_size))
    end function trend_at
  end subroutine locate_nutation_peak

  !> The last attempt (in dop) crossed a limit (status): bisect on its dense
  !> output, record the output samples before the crossing, and end the
  !> case at the last valid point.
  subroutine stop_in_step(dop, run, plan, status, res)
    type(dop853_t), intent(inout) :: dop
    type(run_state_t), intent(inout) :: run
    type(output_plan_t), intent(in) :: plan
    integer, intent(in) :: status
    type(case_result_t), intent(inout) :: res
    type(limit_search_t) :: search
    type(observation_t) :: obs
    real(wp) :: offset
    call search%begin(dop%h, status)
    do while (.not. search%done())
      offset = search%trial()
      call dense_state(dop, run, offset / dop%h, .true., obs, res%n_rhs)
      call search%record(offset, limit_status(run%ball, [obs%normal, obs%omega], obs), obs)
    end do
    call record_samples_until(dop, run, plan, dop%t_old + search%valid, obs, res)
    res%status = search%crossed
    res%t_final = dop%t_old + search%valid
    res%n_steps = res%n_steps + 1
    if (search%found_valid) call accumulate(run, res, search%last_valid)
  end subroutine stop_in_step

  !> Record every output sample in (t_old, t_until] of the last attempt (in
  !> dop), from its dense output; a sample at the step's end is obs_end. A
  !> sample computes only what the stored fields need: the geometry of the
  !> state, or every derived output (with f there when the reaction is stored).
  subroutine record_samples_until(dop, run, plan, t_until, obs_end, res)
    type(dop853_t), intent(inout) :: dop
    type(run_state_t), intent(inout) :: run
    type(output_plan_t), intent(in) :: plan
    real(wp), intent(in) :: t_until
    type(observation_t), intent(in) :: obs_end
    type(case_result_t), intent(inout) :: res
    type(observation_t) :: obs
    real(wp) :: t_sample, theta, y(state_size), contact(3), lateral
    logical :: complete
    complete = any(plan%fields([field_energy, field_reaction, field_base_acceleration]))
    do while (sample_due(run, plan, t_until))
      t_sample = real(run%next_sample - 1, wp) * plan%interval
      theta = (t_sample - dop%t_old) / dop%h
      if (abs(t_sample - (dop%t_old + dop%h)) <= 1.0e-14_wp * max(1.0_wp, t_sample)) then
        call record_sample(res, run%next_sample, obs_end)          ! the step's own end point
      else if (complete) then
        call dense_state(dop, run, theta, plan%fields(field_reaction), obs, res%n_rhs)
        call record_sample(res, run%next_sample, obs)
      else
        call dense_point(dop, run, theta, y, res%n_rhs)
        contact = contact_from_normal(run%ball%cup, y(1:3))
        lateral = sqrt(y(1)**2 + y(2)**2)
        call store_sample(res, run%next_sample, contact, contact + run%ball%radius * y(1:3), y(4:6), y(1:3), &
                          lateral, [0.0_wp, 0.0_wp, 0.0_wp], 0.0_wp, [0.0_wp, 0.0_wp, 0.0_wp])
      end if
      run%next_sample = run%next_sample + 1
    end do
  end subroutine record_samples_until

  !> The state at t_old + theta h of the last attempt, from its dense
  !> output, the normal projected to unit length.
  subroutine dense_point(dop, run, theta, y, n_rhs)
    type(dop853_t), intent(inout) :: dop
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(state_size)
    integer(i8), intent(inout) :: n_rhs
    logical :: prepared
    call dop853_ball_dense(dop, run%ball, theta, y, prepared)
    if (prepared) n_rhs = n_rhs + dop853_dense_calls
    call run%ball%project(y)
  end subroutine dense_point

  !> Every derived output at t_old + theta h of the last attempt, from its
  !> dense output, with f there (one more RHS call) when with_rate (the
  !> limits and the stored reaction need it).
  subroutine dense_state(dop, run, theta, with_rate, obs, n_rhs)
    type(dop853_t), intent(inout) :: dop
    type(run_state_t), intent(in) :: run
    real(wp), intent(in) :: theta
    logical, intent(in) :: with_rate
    type(observation_t), intent(out) :: obs
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: y(state_size), f(state_size), t
    call dense_point(dop, run, theta, y, n_rhs)
    t = dop%t_old + theta * dop%h
    f = 0
    if (with_rate) then
      call ball_derivative(run%ball, t, y, f)
      n_rhs = n_rhs + 1
    end if
    call observe(run%ball, t, y, f, obs)
  end subroutine dense_state

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
    call self%add_peak(t_peak)
  end subroutine add_sample

  !> A maximum located exactly (by the adaptive method's dense output).
  pure subroutine add_peak(self, t_peak)
    class(maxima_t), intent(inout) :: self
    real(wp), intent(in) :: t_peak
    if (self%count == 0) self%first = t_peak
    self%last = t_peak
    self%count = self%count + 1
  end subroutine add_peak

  pure real(wp) function mean_interval(self)
    class(maxima_t), intent(in) :: self
    if (self%count < 3) then
      mean_interval = ieee_value(0.0_wp, ieee_quiet_nan)
    else
      mean_interval = (self%last - self%first) / real(self%count - 1, wp)
    end if
  end function mean_interval

  !> Everything a fixed step's end point adds to the summary; the maxima of
  !> Theta from the step ends (refined by parabolas).
  pure subroutine track(run, res, t, obs)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    ! maxima of tan Theta are the maxima of Theta (tan is increasing)
    call run%maxima%add(t, obs%tan_nutation)
    call track_step_end(run, res, t, obs)
  end subroutine track

  !> What any step's end point adds to the summary but the maxima of Theta.
  pure subroutine track_step_end(run, res, t, obs)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    type(observation_t), intent(in) :: obs
    if (run%spectrum%omega > 0) call run%spectrum%add(t, obs%center_acceleration(1:2), obs%base_acceleration(1:2))
    call accumulate(run, res, obs)
  end subroutine track_step_end

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

  !> A nutation angle (tan Theta, and the lateral and vertical components of
  !> the unit normal) for the largest Theta; one nutation_angle per new maximum only.
  pure subroutine note_nutation(run, res, tan_nutation, lateral, normal_z)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: tan_nutation, lateral, normal_z
    if (tan_nutation > run%tan_theta_max) then
      run%tan_theta_max = tan_nutation
      res%theta_max = nutation_angle(lateral, normal_z)
    end if
  end subroutine note_nutation

  pure subroutine accumulate(run, res, obs)
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    type(observation_t), intent(in) :: obs
    call note_nutation(run, res, obs%tan_nutation, obs%lateral, obs%normal(3))
    ! the norms written out, as the batch path (ellroll_ball_lanes) computes them
    run%displacement_sq_max = max(run%displacement_sq_max, &
        obs%center(1)**2 + obs%center(2)**2 + (obs%center(3) - run%ball%radius)**2)
    run%horizontal_force_sq_max = max(run%horizontal_force_sq_max, obs%reaction(1)**2 + obs%reaction(2)**2)
    res%reaction_normal_max = max(res%reaction_normal_max, obs%reaction_normal)
    res%friction_needed_max = max(res%friction_needed_max, obs%friction_needed)
    run%energy_deviation_max = max(run%energy_deviation_max, abs(obs%energy - run%energy0))
    res%constraint_error_max = max(res%constraint_error_max, obs%surface_residual)
  end subroutine accumulate

  pure subroutine record_sample(res, sample, obs)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    type(observation_t), intent(in) :: obs
    call store_sample(res, sample, obs%contact, obs%center, obs%omega, obs%normal, obs%lateral, obs%reaction, &
                      obs%energy, obs%base_acceleration)
  end subroutine record_sample

  !> Every lane's values at one output sample into the next slot of the block.
  pure subroutine add_lane_samples(self, out, y, radius)
    class(lane_sample_block_t), intent(inout) :: self
    type(lane_outputs_t), intent(in) :: out
    real(wp), intent(in) :: y(lanes, state_size), radius(lanes)
    integer :: i, j
    self%count = self%count + 1
    j = self%count
    if (self%fields(field_contact)) self%contact(:, :, j) = out%contact
    do i = 1, 3
      if (self%fields(field_center)) self%center(:, i, j) = out%contact(:, i) + radius * out%normal(:, i)
    end do
    if (self%fields(field_omega)) self%omega(:, :, j) = y(:, 4:6)
    if (self%fields(field_normal) .or. self%fields(field_nutation)) self%normal(:, :, j) = out%normal
    if (self%fields(field_nutation)) self%lateral(:, j) = out%lateral
    if (self%fields(field_reaction)) self%reaction(:, :, j) = out%reaction
    if (self%fields(field_energy)) self%energy(:, j) = out%energy
  end subroutine add_lane_samples

  !> Lane l's first n samples of the block into its result (Theta from the
  !> lateral and vertical parts of the normal, as store_sample; a batch's
  !> cup does not move).
  pure subroutine flush_lane_samples(self, l, n, res)
    class(lane_sample_block_t), intent(in) :: self
    integer, intent(in) :: l, n
    type(case_result_t), intent(inout) :: res
    integer(i8) :: last
    if (n <= 0) return
    last = self%first + n - 1
    call put(res, field_contact, self%contact)
    call put(res, field_center, self%center)
    call put(res, field_omega, self%omega)
    call put(res, field_normal, self%normal)
    call put(res, field_reaction, self%reaction)
    if (allocated(res%fields(field_nutation)%values)) call put_nutation(res%fields(field_nutation)%values(1, self%first:last))
    if (allocated(res%fields(field_energy)%values)) res%fields(field_energy)%values(1, self%first:last) = self%energy(l, :n)
    if (allocated(res%fields(field_base_acceleration)%values)) &
      res%fields(field_base_acceleration)%values(:, self%first:last) = 0
    res%n_recorded = last
  contains
    pure subroutine put(res, field, values)
      type(case_result_t), intent(inout) :: res
      integer, intent(in) :: field
      real(wp), intent(in) :: values(lanes, 3, block_samples)
      if (allocated(res%fields(field)%values)) call copy_lane(values, res%fields(field)%values(:, self%first:last))
    end subroutine put
    !> Theta of lane l's samples: a loop the compiler vectorizes, with the
    !> vector atan2 of the C library's libmvec where there is one (within a
    !> few units of round-off of the scalar atan2, which took 3 % of a batch
    !> storing every field).
    pure subroutine put_nutation(stored)
      real(wp), intent(inout) :: stored(n)
      real(wp) :: lateral(n), normal_z(n)
      integer :: j
      do j = 1, n
        lateral(j) = self%lateral(l, j)
        normal_z(j) = self%normal(l, 3, j)
      end do
      do j = 1, n
        stored(j) = nutation_angle(lateral(j), normal_z(j))
      end do
    end subroutine put_nutation
    !> Lane l's vectors, explicit loops on explicit shapes: the array
    !> assignment on the strided section was a slow generic loop.
    pure subroutine copy_lane(values, stored)
      real(wp), intent(in) :: values(lanes, 3, block_samples)
      real(wp), intent(inout) :: stored(3, n)
      integer :: j
      do j = 1, n
        stored(1, j) = values(l, 1, j)
        stored(2, j) = values(l, 2, j)
        stored(3, j) = values(l, 3, j)
      end do
    end subroutine copy_lane
  end subroutine flush_lane_samples

  !> Start the next block, after the one held was flushed.
  pure subroutine next_sample_block(self)
    class(lane_sample_block_t), intent(inout) :: self
    self%first = self%first + self%count
    self%count = 0
  end subroutine next_sample_block

  !> Every stored field's values at one output sample (Theta from the
  !> lateral and vertical parts of the normal, only when it is stored).
  pure subroutine store_sample(res, sample, contact, center, omega, normal, lateral, reaction, energy, &
                               base_acceleration)
    type(case_result_t), intent(inout) :: res
    integer(i8), intent(in) :: sample
    real(wp), intent(in) :: contact(3), center(3), omega(3), normal(3), lateral, reaction(3), energy, &
                            base_acceleration(3)
    call put(res, field_contact, contact)
    call put(res, field_center, center)
    call put(res, field_omega, omega)
    call put(res, field_normal, normal)
    if (allocated(res%fields(field_nutation)%values)) &
      res%fields(field_nutation)%values(1, sample) = nutation_angle(lateral, normal(3))
    call put(res, field_reaction, reaction)
    if (allocated(res%fields(field_energy)%values)) res%fields(field_energy)%values(1, sample) = energy
    call put(res, field_base_acceleration, base_acceleration)
    res%n_recorded = sample
  contains
    pure subroutine put(res, field, values)
      type(case_result_t), intent(inout) :: res
      integer, intent(in) :: field
      real(wp), intent(in) :: values(3)
      if (allocated(res%fields(field)%values)) res%fields(field)%values(:, sample) = values
    end subroutine put
  end subroutine store_sample
end module ellroll_simulate
