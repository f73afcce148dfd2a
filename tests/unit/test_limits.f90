!> Cases that end at a model limit: the right status, a located end time
!> that converges as dt shrinks, NaN fill after the end, and nothing past it.
program test_limits
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp
  use ellroll_exact, only: is_zero
  use ellroll_cases, only: case_t, field_contact, field_nutation
  use ellroll_results, only: case_result_t
  use ellroll_status, only: status_rim, status_no_fit, status_slip, status_name
  use fixtures, only: paper_case, run_case
  use testing
  use ellroll_params, only: p_b, p_c, p_dt, p_fit_margin, p_mu, p_omega_x, p_omega_z, p_radius
  use ellroll_figures, only: fig_friction_needed_max, fig_theta_max
  implicit none
  type(case_t) :: cs
  type(case_result_t) :: coarse, fine
  integer :: last_valid

  ! --- rim: a small ball flung up the short side of the cup
  cs = paper_case(1.0e-3_wp, 5.0_wp)
  cs%param(p_radius) = 0.01_wp
  cs%param(p_omega_x:p_omega_z) = [-40.0_wp, 0.0_wp, 0.0_wp]     ! V_C = R omega x n = (0, 0.4, 0) m/s
  cs%param(p_omega_x:p_omega_z) = cs%param(p_omega_x:p_omega_z) * 10
  coarse = run_case(cs, 10)
  call check(coarse%status == status_rim, 'rim case ends at the rim: got ' // status_name(coarse%status))
  cs%param(p_dt) = 2.5e-4_wp
  fine = run_case(cs, 40)
  call check(fine%status == status_rim, 'rim case ends at the rim with a finer step')
  call check_close(coarse%t_final, fine%t_final, 1.0e-6_wp, 'rim time independent of dt')
  call check(coarse%t_final < cs%t_end, 'rim reached before t_end')
  last_valid = floor(coarse%t_final / 0.01_wp) + 1
  call check(all(coarse%fields(field_contact)%values(3, :last_valid) < cs%param(p_c)), 'no sample above the rim')
  call check(all(ieee_is_nan(coarse%fields(field_nutation)%values(1, last_valid + 1:))), &
             'samples after the end are NaN')
  call check(.not. any(ieee_is_nan(coarse%fields(field_nutation)%values(1, :last_valid))), &
             'samples up to the end are numbers')

  ! --- no fit: a ball just below the bottom radius b^2/c = 0.8 rolling in the
  ! y-z plane, where the cup's radius of curvature shrinks as it climbs. The
  ! case must end where rho(theta) = R (1 + fit_margin): the largest nutation
  ! reached equals that angle, found here from the ellipse alone.
  cs = paper_case(1.0e-3_wp, 5.0_wp)
  cs%param(p_radius) = 0.7_wp
  cs%param(p_omega_x:p_omega_z) = [-1.0_wp, 0.0_wp, 0.0_wp]
  coarse = run_case(cs, 10)
  call check(coarse%status == status_no_fit, 'no-fit case ends with no_fit: got ' // status_name(coarse%status))
  call check_close(coarse%reals(fig_theta_max), no_fit_angle(cs), 1.0e-5_wp, 'no-fit: nutation at the end (rad)')
  cs%param(p_dt) = 2.5e-4_wp
  fine = run_case(cs, 40)
  call check(fine%status == status_no_fit, 'no-fit with a finer step')
  call check_close(fine%reals(fig_theta_max), no_fit_angle(cs), 1.0e-5_wp, &
      'no-fit, finer step: nutation at the end (rad)')

  ! --- slip: the paper's case needs friction 0.076 at the start and 0.090 at
  ! t = 9.5 s; with mu = 0.085 it slips in between
  cs = paper_case(1.0e-3_wp, 30.0_wp)
  cs%param(p_mu) = 0.085_wp
  coarse = run_case(cs, 10)
  call check(coarse%status == status_slip, 'slip case ends with slip: got ' // status_name(coarse%status))
  call check(coarse%t_final > 1 .and. coarse%t_final < 9.5_wp, 'slip happens after the start, before the peak')
  call check(coarse%reals(fig_friction_needed_max) <= cs%param(p_mu), 'friction needed stays within mu up to the end')
  cs%param(p_dt) = 2.5e-4_wp
  fine = run_case(cs, 40)
  call check_close(coarse%t_final, fine%t_final, 1.0e-8_wp, 'slip time independent of dt')

  ! --- a start that already needs more friction than mu ends at t = 0
  cs%param(p_mu) = 0.05_wp
  coarse = run_case(cs, 10)
  call check(coarse%status == status_slip .and. is_zero(coarse%t_final), 'slip at the start ends at t = 0')
  call finish('test_limits')

contains

  !> Nutation angle in the y-z principal plane where the radius of curvature
  !> rho(phi) = (b^2 sin^2 phi + c^2 cos^2 phi)^(3/2) / (b c) of the section
  !> y = b cos phi, z = c (1 - sin phi) equals R (1 + fit_margin).
  real(wp) function no_fit_angle(cs) result(theta)
    type(case_t), intent(in) :: cs
    real(wp) :: low, high, phi, target_radius
    integer :: iteration
    target_radius = cs%param(p_radius) * (1 + cs%param(p_fit_margin))
    low = 0; high = 2 * atan(1.0_wp)     ! rho(0) = c^2/b < R < rho(pi/2) = b^2/c
    do iteration = 1, 200
      phi = (low + high) / 2
      if (section_radius(cs, phi) < target_radius) then
        low = phi
      else
        high = phi
      end if
    end do
    theta = atan(cs%param(p_c) * cos(phi) / (cs%param(p_b) * sin(phi)))
  end function no_fit_angle

  real(wp) function section_radius(cs, phi)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: phi
    section_radius = (cs%param(p_b)**2 * sin(phi)**2 + cs%param(p_c)**2 * cos(phi)**2)**1.5_wp / (cs%param(p_b) * cs%param(p_c))
  end function section_radius
end program test_limits
