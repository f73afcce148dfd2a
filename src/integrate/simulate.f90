!> Integrate one case from t = 0 to t_end (or to the model limit it meets),
!> sampling the requested fields every output interval.
module ellroll_simulate
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_status, only: status_completed
  use ellroll_cases, only: case_t, output_plan_t, make_ball, &
      field_contact, field_center, field_omega, field_normal, field_nutation, &
      field_reaction, field_energy
  use ellroll_results, only: case_result_t, new_case_result
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, &
      initial_state, observe, limit_status
  use ellroll_integrators, only: integrator_t, new_integrator
  use ellroll_events, only: crossing_search_t
  implicit none
  private

  public :: simulate_case, event_time_tolerance, maxima_t

  !> Local maxima of a sampled signal, each refined by the parabola through
  !> the three samples around it.
  type :: maxima_t
    real(wp) :: t(3) = 0, v(3) = 0       !< the last three samples
    integer :: n_samples = 0
    integer(i8) :: count = 0
    real(wp) :: first = 0, last = 0      !< times of the first and last maximum
  contains
    procedure :: add => add_sample
    procedure :: mean_interval
  end type maxima_t

  !> Model limits are located in time to this (s).
  real(wp), parameter :: event_time_tolerance = 1.0e-12_wp

contains

  subroutine simulate_case(cs, plan, res, err)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: res
    type(error_t), intent(inout) :: err
    type(rolling_ball_t) :: ball
    class(integrator_t), allocatable :: integrator
    real(wp) :: y(state_size), f(state_size), y_new(state_size), f_new(state_size)
    real(wp) :: t, energy0
    type(observation_t) :: obs
    type(maxima_t) :: maxima
    integer(i8) :: k, n_steps, clock_start, clock_end, clock_rate
    integer :: status

    call system_clock(clock_start, clock_rate)
    call new_integrator(trim(cs%method), integrator, err)
    if (err%failed()) return
    ball = make_ball(cs)
    res = new_case_result(plan%fields, plan%n_samples)

    y = initial_state(ball, cs%x0, cs%y0, cs%omega0)
    call ball%rhs(0.0_wp, y, f)
    res%n_rhs = 1
    obs = observe(ball, y, f)
    energy0 = obs%energy
    call maxima%add(0.0_wp, obs%nutation)
    call accumulate(res, obs, energy0)
    call record_sample(res, 1_i8, obs)
    t = 0
    res%status = limit_status(ball, y, obs)   ! a start outside the model ends at once
    n_steps = nint(cs%t_end / cs%dt, i8)
    if (res%status /= status_completed) n_steps = 0

    do k = 1, n_steps
      call integrator%step(ball, t, y, f, cs%dt, y_new, res%n_rhs)
      call ball%project(y_new)
      call ball%rhs(t + cs%dt, y_new, f_new)
      res%n_rhs = res%n_rhs + 1
      obs = observe(ball, y_new, f_new)
      status = limit_status(ball, y_new, obs)
      if (status /= status_completed) then
        call end_at_limit(status)
        exit
      end if
      y = y_new
      f = f_new
      t = k * cs%dt
      res%n_steps = k
      call maxima%add(t, obs%nutation)
      call accumulate(res, obs, energy0)
      if (mod(k, plan%steps_per_sample) == 0) call record_sample(res, k / plan%steps_per_sample + 1, obs)
    end do
    if (res%status == status_completed) res%t_final = t
    res%nutation_maxima = maxima%count
    res%nutation_period = maxima%mean_interval()

    call system_clock(clock_end)
    res%wall_time = real(clock_end - clock_start, wp) / real(clock_rate, wp)

  contains

    !> The step from t ended outside the model: bisect on partial steps from
    !> the last valid state for the first offset where the limit is crossed,
    !> and end the case at the last valid state found.
    subroutine end_at_limit(step_status)
      integer, intent(in) :: step_status
      type(crossing_search_t) :: search
      real(wp) :: offset, y_try(state_size), f_try(state_size)
      type(observation_t) :: obs_try, obs_valid
      integer :: trial_status
      logical :: found_valid
      res%status = step_status
      found_valid = .false.
      call search%start(cs%dt, event_time_tolerance)
      do while (.not. search%done())
        offset = search%trial()
        call integrator%step(ball, t, y, f, offset, y_try, res%n_rhs)
        call ball%project(y_try)
        call ball%rhs(t + offset, y_try, f_try)
        res%n_rhs = res%n_rhs + 1
        obs_try = observe(ball, y_try, f_try)
        trial_status = limit_status(ball, y_try, obs_try)
        call search%report(offset, trial_status == status_completed)
        if (trial_status == status_completed) then
          obs_valid = obs_try
          found_valid = .true.
        else
          res%status = trial_status
        end if
      end do
      res%t_final = t + search%valid
      res%n_steps = k
      if (found_valid) call accumulate(res, obs_valid, energy0)
    end subroutine end_at_limit
  end subroutine simulate_case

  pure subroutine add_sample(self, t, v)
    class(maxima_t), intent(inout) :: self
    real(wp), intent(in) :: t, v
    real(wp) :: curvature, t_peak, h
    self%t = [self%t(2:3), t]
    self%v = [self%v(2:3), v]
    self%n_samples = self%n_samples + 1
    if (self%n_samples < 3) return
    if (.not. (self%v(2) > self%v(1) .and. self%v(2) >= self%v(3))) return
    h = self%t(2) - self%t(1)
    curvature = self%v(1) - 2 * self%v(2) + self%v(3)
    t_peak = self%t(2)
    if (curvature < 0) t_peak = self%t(2) + h * (self%v(1) - self%v(3)) / (2 * curvature)
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

  pure subroutine accumulate(res, obs, energy0)
    type(case_result_t), intent(inout) :: res
    type(observation_t), intent(in) :: obs
    real(wp), intent(in) :: energy0
    res%theta_max = max(res%theta_max, obs%nutation)
    res%reaction_normal_max = max(res%reaction_normal_max, obs%reaction_normal)
    res%friction_needed_max = max(res%friction_needed_max, obs%friction_needed)
    res%energy_drift = max(res%energy_drift, abs(obs%energy - energy0) / abs(energy0))
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
    call put(res, field_nutation, [obs%nutation])
    call put(res, field_reaction, obs%reaction)
    call put(res, field_energy, [obs%energy])
  contains
    pure subroutine put(res, field, values)
      type(case_result_t), intent(inout) :: res
      integer, intent(in) :: field
      real(wp), intent(in) :: values(:)
      if (allocated(res%fields(field)%values)) res%fields(field)%values(:, sample) = values
    end subroutine put
  end subroutine record_sample
end module ellroll_simulate
