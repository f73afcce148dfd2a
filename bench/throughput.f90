!> RK4 steps per second per core on the paper's case (30 s, dt = 1e-3),
!> measured side by side in one run:
!>   baseline         a straightforward scalar RK4 of the paper's equations (bench/baseline_rk4.f90)
!>   integrate only   ellroll's RK4 on the ball model (its fused step, the
!>                    model's limits checked at every stage): steps, nothing observed
!>   summary only     a full ellroll case without trajectories (every summary figure, every step)
!>   full output      a full ellroll case storing every field at 100 Hz
!>   batch of 8       8 cases (the paper case with spins 20..27 rad/s) advanced
!>                    together across SIMD lanes (simulate_batch), per case-step;
!>                    integrate only, summary only and full output, and one case
!>                    alone in a batch (the kernels compute its lane alone)
!> Each figure is the best of several repetitions, in the process's CPU time
!> (a machine shared with other work slices its time); ratios are to the baseline
!> and, for the output cost, to summary only. Usage: build/bench_throughput [repeats]
program throughput
  use, intrinsic :: iso_fortran_env, only: output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use bench_args, only: repeats_argument
  use ellroll_kinds, only: wp
  use ellroll_errors, only: error_t
  use ellroll_cases, only: case_t, output_plan_t, make_ball
  use ellroll_results, only: case_result_t
  use ellroll_simulate, only: simulate_case, simulate_batch, lanes
  use ellroll_system, only: tune_runtime
  use ellroll_rolling_ball, only: rolling_ball_t, initial_state, state_size, normalize_normal
  use ellroll_ball_lanes, only: ball_lanes_t, set_lane, lanes_derivative
  use ellroll_ball_steppers, only: lanes_rk4_step, rk4_ball_step
  use baseline_rk4, only: baseline_run
  use ellroll_params, only: p_a, p_b, p_c, p_dt, p_g, p_mass, p_omega_x, p_omega_z, p_radius
  implicit none
  real(wp), parameter :: dt = 1.0e-3_wp, t_end = 30.0_wp
  integer, parameter :: n_steps = 30000
  integer :: repeats, k
  real(wp) :: best(8), seconds, check_baseline(6), check_ellroll(6)
  type(case_t) :: cs, batch_cases(lanes)
  type(output_plan_t) :: summary_plan, full_plan
  type(case_result_t) :: res, batch_results(lanes)
  type(error_t) :: err

  call tune_runtime()               ! as the ellroll program does
  repeats = repeats_argument(default=7)
  cs%param(p_a) = 1
  cs%param(p_b) = 0.4_wp
  cs%param(p_c) = 0.2_wp
  cs%param(p_radius) = 0.2_wp
  cs%param(p_g) = 9.81_wp
  cs%param(p_mass) = 2620 / 9.81_wp
  cs%param(p_omega_x:p_omega_z) = [-2.0_wp, 2.0_wp, 20.0_wp]; cs%param(p_dt) = dt; cs%t_end = t_end
  summary_plan%interval = t_end
  summary_plan%n_samples = 2
  summary_plan%fields = .false.
  full_plan%interval = 0.01_wp
  full_plan%n_samples = 3001
  full_plan%fields = .true.

  batch_cases = cs
  do k = 1, lanes
    batch_cases(k)%param(p_omega_z) = 19 + k
  end do

  best = huge(1.0_wp)
  do k = 1, repeats
    seconds = timed_baseline()
    best(1) = min(best(1), seconds)
    seconds = timed_integration()
    best(2) = min(best(2), seconds)
    seconds = timed_case(summary_plan)
    best(3) = min(best(3), seconds)
    seconds = timed_case(full_plan)
    best(4) = min(best(4), seconds)
    seconds = timed_batch(summary_plan, lanes)
    best(5) = min(best(5), seconds / lanes)
    seconds = timed_batch(full_plan, lanes)
    best(6) = min(best(6), seconds / lanes)
    seconds = timed_batch(summary_plan, 1)
    best(7) = min(best(7), seconds)
    seconds = timed_lanes_integration()
    best(8) = min(best(8), seconds / lanes)
  end do

  write (output_unit, '(a)') 'RK4 on the paper case, 30 s, dt = 1e-3 (30,000 steps), best of repeats, one core'
  write (output_unit, '(a28, a14, a14, a12)') 'path', 'steps/s', 'ns/step', 'vs baseline'
  call report('baseline (3x3 solve per RHS)', best(1))
  call report('ellroll, integrate only', best(2))
  call report('ellroll, summary only', best(3))
  call report('ellroll, full output 100 Hz', best(4))
  call report('batch of 8, integrate only', best(8))
  call report('batch of 8, summary only', best(5))
  call report('batch of 8, full output', best(6))
  call report('batch of 1, summary only', best(7))
  write (output_unit, '(a, f6.1, a, f6.1, a)') 'full output over summary only: +', 100 * (best(4) / best(3) - 1), &
      ' % (one case), +', 100 * (best(6) / best(5) - 1), ' % (batch of 8)'
  write (output_unit, '(a, es10.2)') 'baseline and ellroll agree at 30 s (max |omega| difference, rad/s):', &
      maxval(abs(check_baseline(4:6) - check_ellroll(4:6)))

contains

  subroutine report(name, seconds)
    character(len=*), intent(in) :: name
    real(wp), intent(in) :: seconds
    write (output_unit, '(a28, f14.0, f14.1, f11.2, a)') name, n_steps / seconds, 1.0e9_wp * seconds / n_steps, &
        best(1) / seconds, 'x'
  end subroutine report

  real(wp) function timed_baseline() result(seconds)
    real(wp) :: start, finish
    call cpu_time(start)
    check_baseline = baseline_run(dt, n_steps)
    call cpu_time(finish)
    seconds = finish - start
  end function timed_baseline

  real(wp) function timed_integration() result(seconds)
    type(rolling_ball_t) :: ball
    real(wp) :: y(state_size), f(state_size), y_new(state_size)
    real(wp) :: start, finish
    integer :: step, stage_limit
    ball = make_ball(cs)
    call cpu_time(start)
    y = initial_state(ball, 0.0_wp, 0.0_wp, cs%param(p_omega_x:p_omega_z))
    do step = 1, n_steps
      call ball%rhs(0.0_wp, y, f)
      call rk4_ball_step(ball, 0.0_wp, y, f, dt, y_new, stage_limit)
      if (stage_limit /= 0) error stop 'integration left the model'
      call normalize_normal(y_new)
      y = y_new
    end do
    call cpu_time(finish)
    check_ellroll = y
    seconds = finish - start
  end function timed_integration

  real(wp) function timed_case(plan) result(seconds)
    type(output_plan_t), intent(in) :: plan
    real(wp) :: start, finish
    call cpu_time(start)
    call simulate_case(cs, plan, res, err)
    call cpu_time(finish)
    seconds = finish - start
  end function timed_case

  real(wp) function timed_lanes_integration() result(seconds)
    type(ball_lanes_t) :: balls
    logical :: inside(lanes)
    real(wp), dimension(lanes, state_size) :: y, f, y_new, f_new
    real(wp) :: h(lanes)
    real(wp) :: start, finish
    integer :: step, l
    do l = 1, lanes
      call set_lane(balls, l, make_ball(batch_cases(l)))
      y(l, :) = initial_state(make_ball(batch_cases(l)), 0.0_wp, 0.0_wp, batch_cases(l)%param(p_omega_x:p_omega_z))
    end do
    h = dt
    call cpu_time(start)
    call lanes_derivative(balls, y, f)
    do step = 1, n_steps
      call lanes_rk4_step(balls, y, f, h, y_new, f_new, inside)
      if (.not. all(inside)) exit
      y = y_new
      f = f_new
    end do
    call cpu_time(finish)
    if (.not. (all(ieee_is_finite(y)) .and. all(inside))) error stop 'batch integration failed'
    seconds = finish - start
  end function timed_lanes_integration

  real(wp) function timed_batch(plan, n) result(seconds)
    type(output_plan_t), intent(in) :: plan
    integer, intent(in) :: n
    real(wp) :: start, finish
    call cpu_time(start)
    call simulate_batch(batch_cases(:n), plan, batch_results(:n))
    call cpu_time(finish)
    seconds = finish - start
  end function timed_batch
end program throughput
