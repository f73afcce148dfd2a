!> The summary's time_beyond_capacity against independent truth: a
!> constructed displacement history whose time beyond is known exactly, the
!> same history through a batch's lanes (the one accumulation, bitwise the
!> same wherever the case sits), and the linear small oscillation of a ball
!> in a cup of revolution, where the centre's displacement is A |cos(w t)|
!> and the time beyond a capacity c over whole periods is
!> (2 / pi) acos(c / A) of it; there, the one-case and the batch runs agree
!> bitwise.
program test_figures
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp, i8, pi
  use ellroll_errors, only: error_t
  use ellroll_status, only: status_completed
  use ellroll_cases, only: case_t
  use ellroll_results, only: case_result_t
  use ellroll_params, only: params, p_a, p_b, p_c, p_x, p_omega_x, p_omega_z, p_dt, p_capacity, p_radius, p_g, &
      p_inertia_factor
  use ellroll_quantities, only: quantity_count, q_displacement
  use ellroll_figures, only: fig_time_beyond_capacity
  use ellroll_running, only: running_t, running_lanes_t, start_running, add_step_ends, get_lane, put_lane, &
      finish_running
  use ellroll_simulate, only: simulate_case, simulate_batch, lanes
  use fixtures, only: paper_case, plan_for
  use testing
  implicit none

  call constructed_history()
  call lanes_history()
  call small_oscillation()
  call finish('figures')

contains

  !> The displacement 0, 2, 2, 0 at t = 0, 1, 3, 4 against capacity 1:
  !> beyond from t = 0.5 to 3.5, 3 s; against capacity 3, none; unset, NaN.
  subroutine constructed_history()
    call check_below(abs(run_history(1.0_wp) - 3), 0.0_wp, 'constructed: 3 s beyond capacity 1 (exact)')
    call check_below(abs(run_history(3.0_wp)), 0.0_wp, 'constructed: never beyond capacity 3')
    call check(ieee_is_nan(run_history(params(p_capacity)%default)), 'constructed: capacity unset, NaN')
  end subroutine constructed_history

  !> The constructed history's time beyond capacity.
  real(wp) function run_history(capacity)
    real(wp), intent(in) :: capacity
    real(wp), parameter :: d(4) = [0.0_wp, 2.0_wp, 2.0_wp, 0.0_wp], t(4) = [0.0_wp, 1.0_wp, 3.0_wp, 4.0_wp]
    type(running_t) :: stats
    type(case_result_t) :: res
    real(wp) :: q(1, quantity_count), param(size(params))
    integer :: k
    param = 0
    param(p_capacity) = capacity
    q = 0
    call start_running(stats, q, param)
    do k = 2, size(t)
      q(1, q_displacement) = d(k)
      call add_step_ends(stats, q, t(k))
    end do
    call finish_running(stats, 1.0_wp, res)
    run_history = res%reals(fig_time_beyond_capacity)
  end function run_history

  !> A seeded random history of case 1 alone and in lane 3 of a batch whose
  !> other lanes run other histories and whose lane 3 is left out of some
  !> steps (not accepted): the same bits.
  subroutine lanes_history()
    integer, parameter :: n_steps = 500, mine = 3
    type(running_t) :: alone, from_lane
    type(running_lanes_t) :: batch
    type(case_result_t) :: a, b
    real(wp) :: q(1, quantity_count), ql(lanes, quantity_count), param(size(params)), u(lanes), t(lanes)
    logical :: accepted(lanes)
    integer :: k, l, seed(8)
    integer :: n_seed
    call random_seed(size=n_seed)
    seed = 41
    call random_seed(put=seed(:n_seed))
    param = 0
    param(p_capacity) = 0.5_wp
    q = 0
    call start_running(alone, q, param)
    do l = 1, lanes
      call put_lane(batch, l, alone)
    end do
    t = 0
    do k = 1, n_steps
      call random_number(u)
      ql = 0
      ql(:, q_displacement) = u
      accepted = [(mod(k + l, 3) /= 0, l = 1, lanes)]
      t = t + merge(0.01_wp * (1 + u), 0.0_wp, accepted)
      call add_step_ends(batch, ql, t, accepted)
      if (accepted(mine)) then
        q(1, :) = ql(mine, :)
        call add_step_ends(alone, q, t(mine))
      end if
    end do
    call get_lane(batch, mine, from_lane)
    call finish_running(alone, 1.0_wp, a)
    call finish_running(from_lane, 1.0_wp, b)
    call check(transfer(a%reals(fig_time_beyond_capacity), 1_i8) == transfer(b%reals(fig_time_beyond_capacity), 1_i8) &
               .and. a%reals(fig_time_beyond_capacity) > 0, 'random history: one case and lane 3, the same bits')
  end subroutine lanes_history

  !> A ball (R = 0.2 m, J = 0.4 m R^2) in the cup a = b = 1 m, c = 0.2 m
  !> (radius of curvature at the bottom rho = a^2 / c = 5 m), let go at rest
  !> with its contact point at x0 = 5e-4 rho: it rolls in the x-z plane at
  !> w^2 = g / ((1 + 0.4) (rho - R)), its centre's horizontal displacement
  !> A |cos(w t)| (A the start's; the terms left out are (x0 / rho)^2 = 2.5e-7
  !> relative). Over two periods at 4000 RK4 steps each, the time beyond
  !> c = A / 2 is (2 / pi) acos(1 / 2) 2 T = 4 T / 3, and beyond 0.9 A it
  !> is (4 / pi) acos(0.9) T.
  subroutine small_oscillation()
    type(case_t) :: cs, cases(lanes)
    type(case_result_t) :: single, batch(lanes)
    type(error_t) :: err
    real(wp) :: rho, x0, z0, gx, gz, amplitude, period, expected(2)
    integer :: k, l
    rho = 1.0_wp**2 / 0.2_wp
    x0 = 5.0e-4_wp * rho
    cs = paper_case(1.0_wp, 1.0_wp)
    cs%param(p_b) = 1
    cs%param(p_omega_x:p_omega_z) = 0
    cs%param(p_x) = x0
    ! the centre lies R along the inward normal from the contact point
    z0 = cs%param(p_c) * (1 - sqrt(1 - (x0 / cs%param(p_a))**2))
    gx = x0 / cs%param(p_a)**2
    gz = (z0 - cs%param(p_c)) / cs%param(p_c)**2
    amplitude = x0 - cs%param(p_radius) * gx / hypot(gx, gz)
    period = 2 * pi * sqrt((1 + cs%param(p_inertia_factor)) * (rho - cs%param(p_radius)) / cs%param(p_g))
    cs%t_end = 2 * period
    cs%param(p_dt) = cs%t_end / 8000
    expected = [4 * period / 3, 4 / pi * acos(0.9_wp) * period]
    do k = 1, 2
      cs%param(p_capacity) = merge(0.5_wp, 0.9_wp, k == 1) * amplitude
      call simulate_case(cs, plan_for(cs, 8000), single, err)
      call check(.not. err%failed() .and. single%status == status_completed, 'small oscillation: completes')
      call check_close(single%reals(fig_time_beyond_capacity), expected(k), 1.0e-5_wp, &
                       'small oscillation: time beyond ' // merge('0.5', '0.9', k == 1) // ' A over two periods (s)')
      cases = cs
      call simulate_batch(cases, plan_for(cs, 8000), batch)
      call check(all([(transfer(batch(l)%reals(fig_time_beyond_capacity), 1_i8), l = 1, lanes)] == &
                     transfer(single%reals(fig_time_beyond_capacity), 1_i8)), &
                 'small oscillation: the batch and the one-case run, the same bits')
    end do
  end subroutine small_oscillation
end program test_figures
