!> The embedded pairs at the ends of their inputs' ranges, one case and in a
!> SIMD batch: pure relative error control (atol = 0), with components that
!> are exactly zero; a step control that no step can satisfy, which ends
!> 'unstable' instead of shrinking its step forever (ctest holds the program
!> to a timeout); the approach to the fit limit's singularity, whose
!> round-off steps still reach the limit; and a spin of 1e6 rad/s about
!> every axis, whose starting step is far too long (its stages stay finite:
!> the Debug build traps on overflow).
program test_adaptive
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan, ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_exact, only: equals
  use ellroll_status, only: status_completed, status_no_fit, status_unstable
  use ellroll_cases, only: case_t, output_plan_t, field_contact, field_normal, field_omega
  use ellroll_results, only: case_result_t
  use ellroll_simulate, only: simulate_case, simulate_batch, lanes
  use ellroll_step_control, only: round_off_step, cannot_follow
  use ellroll_integrators, only: methods
  use fixtures, only: paper_case, other_pair
  use testing
  use ellroll_params, only: p_atol, p_fit_margin, p_g, p_mass, p_omega_x, p_omega_z, p_radius, p_rtol
  implicit none
  integer :: k

  call round_off_thresholds()
  do k = 1, size(methods)                 ! every embedded pair of the method table
    if (.not. methods(k)%adaptive) cycle
    call zero_components(trim(methods(k)%name))
    call pure_relative_control(trim(methods(k)%name))
    call unsatisfiable_control(trim(methods(k)%name))
    call fit_singularity(trim(methods(k)%name))
    call fast_spin_start(trim(methods(k)%name))
  end do
  call finish('test_adaptive')

contains

  !> A step of up to 16 eps |t| is round-off (from t = 1 s: 16 eps; from 0
  !> only 0 and NaN); a case ends 'unstable' before a step
  !> of 0 or NaN, after 100,000 attempts of round-off steps in a row, or after
  !> 1e12 attempts.
  subroutine round_off_thresholds()
    real(wp) :: nan
    nan = ieee_value(1.0_wp, ieee_quiet_nan)
    call check(round_off_step(1.0_wp, 16 * epsilon(1.0_wp), 0.5_wp) &
               .and. .not. round_off_step(1.0_wp, 17 * epsilon(1.0_wp), 0.5_wp) &
               .and. round_off_step(0.0_wp, 0.0_wp, 0.0_wp) .and. .not. round_off_step(0.0_wp, tiny(1.0_wp), 0.0_wp) &
               .and. round_off_step(1.0_wp, nan, 1.0_wp), 'round-off steps: 16 ulp of t, 0 and NaN')
    ! before t reaches t_end, 16 ulp of t_end: at t = 0 a step of 1e-101 s
    ! is round-off in a case of 1e-8 s
    call check(round_off_step(0.0_wp, 1.0e-101_wp, 1.0e-8_wp) .and. round_off_step(1.0e-20_wp, 16 * 1.0e-8_wp * &
               epsilon(1.0_wp), 1.0e-8_wp) .and. .not. round_off_step(0.0_wp, 17 * 1.0e-8_wp * epsilon(1.0_wp), &
               1.0e-8_wp), 'round-off steps: 16 ulp of t_end before t reaches it')
    call check(.not. cannot_follow(1.0e-3_wp, 100000, 0_i8) .and. cannot_follow(1.0e-3_wp, 100001, 0_i8) &
               .and. cannot_follow(0.0_wp, 0, 0_i8) .and. cannot_follow(nan, 0, 0_i8) &
               .and. .not. cannot_follow(1.0e-3_wp, 0, 999999999999_i8) .and. cannot_follow(1.0e-3_wp, 0, 10_i8**12), &
               'an adaptive case cannot follow after 100,000 round-off attempts, before a step of 0 or NaN, ' // &
               'after 1e12 attempts')
  end subroutine round_off_thresholds

  !> Output every `interval` s of a case of length t_end, every field.
  function plan_every(interval, t_end) result(plan)
    real(wp), intent(in) :: interval, t_end
    type(output_plan_t) :: plan
    plan%interval = interval
    plan%n_samples = nint(t_end / interval) + 1
    plan%fields = .true.
  end function plan_every

  !> Spinning about the vertical at the bottom, the ball stays where it is:
  !> n = (0, 0, 1) and omega = (0, 0, 20) exactly, four components zero
  !> throughout. Under pure relative control their tolerance is zero, and
  !> so is their error: every step is accepted, and every sample is the
  !> start exactly.
  subroutine zero_components(method)
    character(len=*), intent(in) :: method
    type(case_t) :: cs, cases(lanes)
    type(case_result_t) :: res, batch(lanes)
    type(output_plan_t) :: plan
    type(error_t) :: err
    logical :: exact
    integer :: l
    cs = paper_case(0.5_wp, 3.0_wp)
    cs%method = method
    cs%param(p_omega_x:p_omega_z) = [0.0_wp, 0.0_wp, 20.0_wp]
    cs%param(p_rtol) = 1.0e-9_wp
    cs%param(p_atol) = 0
    plan = plan_every(0.1_wp, cs%t_end)
    call simulate_case(cs, plan, res, err)
    cases = cs
    call simulate_batch(cases, plan, batch)
    exact = at_rest(res)
    do l = 1, lanes
      exact = exact .and. at_rest(batch(l))
    end do
    call check(exact, method // ', atol = 0, spin about the vertical at the bottom: completed, no rejected step, '// &
               'every sample the start exactly (one case and a batch)')
  end subroutine zero_components

  logical function at_rest(res)
    type(case_result_t), intent(in) :: res
    integer :: j
    at_rest = res%status == status_completed .and. res%n_rejected == 0
    do j = 1, size(res%fields(field_normal)%values, 2)
      at_rest = at_rest .and. all(equals(res%fields(field_normal)%values(:, j), [0.0_wp, 0.0_wp, 1.0_wp])) &
                .and. all(equals(res%fields(field_omega)%values(:, j), [0.0_wp, 0.0_wp, 20.0_wp]))
    end do
  end function at_rest

  !> The paper's case with atol = 0 (n_x, n_y are zero at the start): the
  !> contact point at 2 s within 100 rtol of the other pair at rtol 1e-13, as
  !> with atol > 0 (test_integrators), one case and in a batch whose lanes
  !> hold rtol 1e-5 to 1e-12.
  subroutine pure_relative_control(method)
    character(len=*), intent(in) :: method
    type(case_t) :: cs, cases(lanes)
    type(case_result_t) :: reference, res, batch(lanes)
    type(output_plan_t) :: plan
    type(error_t) :: err
    real(wp) :: error, worst
    logical :: completed
    integer :: l
    cs = paper_case(2.0_wp, 2.0_wp)
    plan = plan_every(2.0_wp, cs%t_end)
    cs%method = other_pair(method)
    cs%param(p_rtol) = 1.0e-13_wp
    cs%param(p_atol) = 1.0e-15_wp
    call simulate_case(cs, plan, reference, err)
    cs%method = method
    cs%param(p_atol) = 0
    worst = 0
    completed = .true.
    do l = 1, lanes
      cases(l) = cs
      cases(l)%param(p_rtol) = 10.0_wp**(-4 - l)
      call simulate_case(cases(l), plan, res, err)
      error = norm2(res%fields(field_contact)%values(:, 2) - reference%fields(field_contact)%values(:, 2))
      worst = max(worst, error / cases(l)%param(p_rtol))
      completed = completed .and. res%status == status_completed
    end do
    call simulate_batch(cases, plan, batch)
    do l = 1, lanes
      error = norm2(batch(l)%fields(field_contact)%values(:, 2) - reference%fields(field_contact)%values(:, 2))
      worst = max(worst, error / cases(l)%param(p_rtol))
      completed = completed .and. batch(l)%status == status_completed
    end do
    call check(completed, method // ', atol = 0, rtol 1e-5 to 1e-12: every case completes (one case and a batch)')
    call check_below(worst, 100.0_wp, method // ', atol = 0: contact error at 2 s / rtol, largest')
  end subroutine pure_relative_control

  !> rtol = atol = 0 (below the inputs' range): no step with an error can be
  !> accepted, the step shrinks to round-off, and the case ends 'unstable'
  !> at its last accepted step, its later samples NaN; alone and in a batch,
  !> where the other lanes complete.
  subroutine unsatisfiable_control(method)
    character(len=*), intent(in) :: method
    type(case_t) :: cs, cases(lanes)
    type(case_result_t) :: res, batch(lanes)
    type(output_plan_t) :: plan
    type(error_t) :: err
    logical :: ended, others
    integer :: l
    cs = paper_case(30.0_wp, 30.0_wp)
    cs%method = method
    cs%param(p_rtol) = 0
    cs%param(p_atol) = 0
    plan = plan_every(10.0_wp, cs%t_end)
    call simulate_case(cs, plan, res, err)
    cases = paper_case(30.0_wp, 30.0_wp)      ! 700 to 1,100 steps: lane 3 idles beside them
    cases%method = method
    cases%param(p_rtol) = 1.0e-12_wp
    cases(3) = cs
    call simulate_batch(cases, plan, batch)
    ended = res%status == status_unstable .and. res%t_final < cs%t_end .and. &
            all(ieee_is_nan(res%fields(field_contact)%values(:, 3))) .and. &
            batch(3)%status == status_unstable .and. batch(3)%t_final < cs%t_end
    others = .true.
    do l = 1, lanes
      if (l /= 3) others = others .and. batch(l)%status == status_completed
    end do
    print '(a, es10.3, a, i0, a, i0, a)', method // ' rtol = atol = 0: unstable at t = ', res%t_final, ' s after ', &
          res%n_steps, ' steps, ', res%n_rejected, ' rejected'
    call check(ended, method // ', rtol = atol = 0: ends unstable before t_end, later samples NaN (one case and a batch)')
    call check(others, method // ', rtol = atol = 0 in a batch: the other lanes complete')
  end subroutine unsatisfiable_control

  !> The ball of input/hard/reaches_no_fit.nml with fit_margin = 0: the
  !> fit limit is the equations' square-root singularity, and the step
  !> control shrinks the step to round-off of t on the way; the state
  !> still moves within such steps, and they reach the limit. Both pairs
  !> end no_fit at the same time (to 2e-12 s; they part there by 2.5e-13 s).
  subroutine fit_singularity(method)
    character(len=*), intent(in) :: method
    type(case_t) :: cs, cases(lanes)
    type(case_result_t) :: res, other, batch(lanes)
    type(output_plan_t) :: plan
    type(error_t) :: err
    cs = paper_case(1.0_wp, 1.0_wp)
    cs%param(p_radius) = 0.7_wp
    cs%param(p_mass) = 100 / cs%param(p_g)
    cs%param(p_omega_x:p_omega_z) = [-1.0_wp, 0.0_wp, 0.0_wp]
    cs%param(p_fit_margin) = 0
    cs%param(p_rtol) = 1.0e-10_wp
    cs%param(p_atol) = 1.0e-13_wp
    plan = plan_every(1.0e-3_wp, cs%t_end)
    cs%method = other_pair(method)
    call simulate_case(cs, plan, other, err)
    cs%method = method
    call simulate_case(cs, plan, res, err)
    cases = cs
    call simulate_batch(cases, plan, batch)
    call check(res%status == status_no_fit .and. batch(1)%status == status_no_fit, &
               method // ', fit_margin = 0: the approach to the singularity ends no_fit (one case and a batch)')
    call check_below(abs(res%t_final - other%t_final), 2.0e-12_wp, method // ', fit_margin = 0: no_fit time vs ' // &
                     'the other pair (s)')
  end subroutine fit_singularity

  !> omega = 1e6 rad/s about every axis, rtol = atol = 1e-6: Hairer's
  !> starting step turns the ball by about a radian, and the later stages
  !> of that attempt grow past overflow unless held (stage_clamp). The case
  !> meets the fit limit after 1.1 us, at the same time to 10 rtol with both
  !> pairs, alone and in a batch.
  subroutine fast_spin_start(method)
    character(len=*), intent(in) :: method
    type(case_t) :: cs, cases(lanes)
    type(case_result_t) :: res, other, batch(lanes)
    type(output_plan_t) :: plan
    type(error_t) :: err
    cs = paper_case(1.0e-4_wp, 1.0e-4_wp)
    cs%param(p_omega_x:p_omega_z) = 1.0e6_wp
    cs%param(p_rtol) = 1.0e-6_wp
    cs%param(p_atol) = 1.0e-6_wp
    plan = plan_every(1.0e-5_wp, cs%t_end)
    cs%method = other_pair(method)
    call simulate_case(cs, plan, other, err)
    cs%method = method
    call simulate_case(cs, plan, res, err)
    cases = cs
    call simulate_batch(cases, plan, batch)
    call check(res%status == status_no_fit .and. batch(1)%status == status_no_fit, &
               method // ', omega = 1e6 rad/s about every axis: ends no_fit (one case and a batch)')
    call check_below(abs(res%t_final - other%t_final) / other%t_final, 10 * cs%param(p_rtol), &
                     method // ', omega = 1e6 rad/s: no_fit time vs the other pair (rel.)')
    call check_below(abs(res%t_final - batch(1)%t_final) / res%t_final, 10 * cs%param(p_rtol), &
                     method // ', omega = 1e6 rad/s: no_fit time, batch vs one case (rel.)')
  end subroutine fast_spin_start
end program test_adaptive
