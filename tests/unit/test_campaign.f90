!> Campaign expansion: grid and zip order, and the counter-based random
!> numbers (uniform moments, independence of streams, and golden values
!> computed by an independent Python port of the hash, which pin the draws
!> on every machine).
program test_campaign
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: equals
  use ellroll_cases, only: case_t
  use ellroll_params, only: param_index, p_a, p_omega_x, p_omega_z, p_radius
  use ellroll_campaign
  use fixtures, only: paper_case
  use testing
  implicit none
  type(campaign_t) :: camp
  type(case_t) :: cs
  real(wp) :: u, total, total2, product_sum, v
  integer(i8) :: i
  integer, parameter :: n = 200000

  camp%base = paper_case(1.0e-3_wp, 1.0_wp)
  allocate (camp%samples(0), camp%sweeps(2))
  camp%sweeps(1) = sweep_t(param=param_index('omega_z'), values=[5.0_wp, 10.0_wp, 20.0_wp])
  camp%sweeps(2) = sweep_t(param=param_index('radius'), values=[0.05_wp, 0.1_wp])
  call check(camp%n_cases() == 6, 'grid of 3 x 2 has 6 cases')
  cs = camp%case_at(3_i8)         ! second omega_z, second radius: the last sweep varies fastest
  call check(equals(cs%param(p_omega_z), 10.0_wp) .and. equals(cs%param(p_radius), 0.1_wp) .and. cs%index == 3, &
      'grid order')
  call check(equals(cs%param(p_omega_x), -2.0_wp) .and. equals(cs%param(p_a), 1.0_wp), &
      'unswept inputs keep the base values')
  camp%combine = combine_zip
  camp%sweeps(2)%values = [0.05_wp, 0.1_wp, 0.15_wp]
  cs = camp%case_at(2_i8)
  call check(camp%n_cases() == 3 .and. equals(cs%param(p_omega_z), 20.0_wp) .and. equals(cs%param(p_radius), 0.15_wp), &
             'zip pairs values')

  total = 0; total2 = 0; product_sum = 0
  do i = 0, n - 1
    u = uniform_hash(42_i8, i, 1)
    v = uniform_hash(42_i8, i, 2)
    call check_range(u)
    total = total + u
    total2 = total2 + u * u
    product_sum = product_sum + (u - 0.5_wp) * (v - 0.5_wp)
  end do
  ! mean 1/2 +- 1/sqrt(12 n), variance 1/12, streams uncorrelated (5 sigma)
  call check_below(abs(total / n - 0.5_wp), 5 / sqrt(12.0_wp * n), 'uniform draws: |mean - 1/2|')
  call check_below(abs(total2 / n - (total / n)**2 - 1 / 12.0_wp), 5 * 0.0745_wp / sqrt(real(n, wp)), &
                   'uniform draws: |variance - 1/12|')
  call check_below(abs(product_sum / n), 5 / (12 * sqrt(real(n, wp))), 'streams 1 and 2: |covariance|')
  call check(.not. equals(uniform_hash(42_i8, 7_i8, 1), uniform_hash(43_i8, 7_i8, 1)), 'seed changes the draws')
  call check(equals(uniform_hash(1_i8, 0_i8, 1), golden(1)) .and. &
             equals(uniform_hash(2026_i8, 123456789012_i8, 3), golden(2)), &
             'golden values (the same on every machine)')
  print '(a, 2es26.18)', 'draws: ', uniform_hash(1_i8, 0_i8, 1), uniform_hash(2026_i8, 123456789012_i8, 3)
  call finish('test_campaign')

contains

  subroutine check_range(x)
    real(wp), intent(in) :: x
    if (.not. (x >= 0 .and. x < 1)) call check(.false., 'draw outside [0, 1)')
  end subroutine check_range

  real(wp) function golden(k)
    integer, intent(in) :: k
    real(wp), parameter :: values(2) = [0.09908184105342588_wp, 0.12414606750744472_wp]
    golden = values(k)
  end function golden
end program test_campaign
