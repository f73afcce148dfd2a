!> Whole runs against classical truth: the energy integral (2.15), the
!> surface constraint, small-oscillation periods 2 pi sqrt(7 (rho - R) / (5 g)),
!> constant spin omega . n in a spherical cup, and time reversibility.
program test_physics
  use ellroll_kinds, only: wp, pi
  use ellroll_cases, only: case_t, field_contact, field_omega, field_normal
  use ellroll_results, only: case_result_t
  use ellroll_status, only: status_completed
  use ellroll_ellipsoid, only: new_ellipsoid, surface_residual
  use fixtures, only: paper_case, run_case
  use testing
  use ellroll_params, only: p_a, p_b, p_c, p_omega_x, p_omega_z, p_radius, p_x, p_y, p_dt, p_g
  use ellroll_figures, only: fig_constraint_error_max, fig_energy_drift
  implicit none
  type(case_t) :: cs
  type(case_result_t) :: res, back
  real(wp) :: worst, spin0
  integer :: j

  ! --- the paper's case, 30 s, dt = 1e-3
  cs = paper_case(1.0e-3_wp, 30.0_wp)
  res = run_case(cs, 10)
  call check(res%status == status_completed, 'paper case completes')
  call check_below(res%reals(fig_energy_drift), 1.0e-9_wp, 'paper case: energy drift max |E-E0|/E0 over 30 s')
  call check_below(res%reals(fig_constraint_error_max), 1.0e-13_wp, &
      'paper case: contact point off the surface (all steps)')
  worst = 0
  do j = 1, size(res%fields(field_contact)%values, 2)
    worst = max(worst, surface_residual(new_ellipsoid(cs%param(p_a), cs%param(p_b), cs%param(p_c)), &
        res%fields(field_contact)%values(:, j)))
  end do
  call check_below(worst, 1.0e-13_wp, 'paper case: stored contact points on the surface')

  ! --- small oscillations in both principal planes, no spin
  call check_period('x-z', [1.0e-4_wp, 0.0_wp], 1, cs%param(p_a)**2 / cs%param(p_c))
  call check_period('y-z', [0.0_wp, 1.0e-4_wp], 2, cs%param(p_b)**2 / cs%param(p_c))

  ! --- spherical cup: omega . n stays constant
  cs = paper_case(1.0e-3_wp, 20.0_wp)
  cs%param(p_a) = 1; cs%param(p_b) = 1; cs%param(p_c) = 1; cs%param(p_radius) = 0.3_wp
  cs%param(p_x) = 0.3_wp; cs%param(p_y) = -0.2_wp; cs%param(p_omega_x:p_omega_z) = [1.0_wp, -2.0_wp, 5.0_wp]
  res = run_case(cs, 1)
  call check(res%status == status_completed, 'spherical cup run completes')
  spin0 = dot_product(res%fields(field_omega)%values(:, 1), res%fields(field_normal)%values(:, 1))
  worst = 0
  do j = 1, size(res%fields(field_omega)%values, 2)
    worst = max(worst, abs(dot_product(res%fields(field_omega)%values(:, j), &
                                       res%fields(field_normal)%values(:, j)) - spin0))
  end do
  call check_below(worst, 1.0e-10_wp, 'spherical cup: max |omega.n - omega.n(0)| over 20 s (rad/s)')

  ! --- time reversal: 10 s forward, flip omega, 10 s forward again
  cs = paper_case(2.5e-4_wp, 10.0_wp)
  res = run_case(cs, 40000)
  cs%param(p_x) = res%fields(field_contact)%values(1, 2)
  cs%param(p_y) = res%fields(field_contact)%values(2, 2)
  cs%param(p_omega_x:p_omega_z) = -res%fields(field_omega)%values(:, 2)
  back = run_case(cs, 40000)
  call check_below(maxval(abs(back%fields(field_contact)%values(:, 2))), 1.0e-8_wp, &
                   'time reversal: contact point back at the start (m)')
  call check_below(maxval(abs(back%fields(field_omega)%values(:, 2) + [-2.0_wp, 2.0_wp, 20.0_wp])) / 20, &
                   1.0e-8_wp, 'time reversal: omega back to -omega0 (relative)')
  call finish('test_physics')

contains

  !> Period from the zero crossings of the contact coordinate `axis`.
  subroutine check_period(plane, start, axis, rho)
    character(len=*), intent(in) :: plane
    real(wp), intent(in) :: start(2), rho
    integer, intent(in) :: axis
    type(case_t) :: osc
    type(case_result_t) :: r
    real(wp) :: expected, first, last, u0, u1, crossing
    integer :: j, crossings
    osc = paper_case(1.0e-3_wp, 40.0_wp)
    osc%param(p_x) = start(1); osc%param(p_y) = start(2); osc%param(p_omega_x:p_omega_z) = 0
    r = run_case(osc, 1)
    expected = 2 * pi * sqrt(7 * (rho - osc%param(p_radius)) / (5 * osc%param(p_g)))
    crossings = 0
    first = 0; last = 0
    do j = 1, size(r%fields(field_contact)%values, 2) - 1
      u0 = r%fields(field_contact)%values(axis, j)
      u1 = r%fields(field_contact)%values(axis, j + 1)
      if (u0 * u1 < 0) then
        crossing = ((j - 1) + u0 / (u0 - u1)) * osc%param(p_dt)
        if (crossings == 0) first = crossing
        last = crossing
        crossings = crossings + 1
      end if
    end do
    call check(crossings >= 4, plane // ': enough zero crossings')
    call check_close(2 * (last - first) / (crossings - 1), expected, 1.0e-4_wp, &
                     'small-oscillation period in the ' // plane // ' plane (s)')
  end subroutine check_period
end program test_physics
