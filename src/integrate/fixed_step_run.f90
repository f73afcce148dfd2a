!> One case with a fixed-step method: each step's end point observed and
!> checked against the model's limits, the output samples taken at the
!> steps; a step that crosses a limit is bisected for where.
module ellroll_fixed_step_run
  use ellroll_kinds, only: wp, i8
  use ellroll_status, only: status_completed
  use ellroll_cases, only: case_t, output_plan_t
  use ellroll_results, only: case_result_t
  use ellroll_rolling_ball, only: observation_t, state_size, observe, limit_status, ball_derivative
  use ellroll_integrators, only: integrator_t, rk4_t
  use ellroll_ball_steppers, only: rk4_ball_step
  use ellroll_case_run, only: run_state_t, limit_search_t, track, accumulate, record_sample
  implicit none
  private

  public :: fixed_step_loop, end_at_limit

contains

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
end module ellroll_fixed_step_run
