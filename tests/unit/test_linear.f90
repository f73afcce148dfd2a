!> Linearised small oscillations about the bottom: without spin, the
!> classical 2 pi sqrt(7 (rho - R) / (5 g)) in both principal planes; with
!> spin, the two gyroscopic mode periods against the frequencies found in a
!> simulated small oscillation (peaks of a windowed Fourier transform).
program test_linear
  use ellroll_kinds, only: wp, pi, two_pi
  use ellroll_cases, only: case_t, make_ball, field_contact
  use ellroll_results, only: case_result_t
  use ellroll_linear, only: oscillation_periods
  use fixtures, only: paper_case, run_case
  use testing
  implicit none
  type(case_t) :: cs
  type(case_result_t) :: res
  real(wp) :: periods(2), expected(2), measured(2), sigma

  cs = paper_case(1.0e-3_wp, 1.0_wp)
  periods = oscillation_periods(make_ball(cs), 0.0_wp)
  expected = 2 * pi * sqrt(7 * ([cs%a**2, cs%b**2] / cs%c - cs%radius) / (5 * cs%g))
  call check_close(periods(1), expected(1), 1.0e-8_wp, 'no spin: x-z period from the eigenvalues (s)')
  call check_close(periods(2), expected(2), 1.0e-8_wp, 'no spin: y-z period from the eigenvalues (s)')

  sigma = 40
  periods = oscillation_periods(make_ball(cs), sigma)
  call check(periods(1) > expected(1) .and. periods(2) < expected(2), 'spin splits the modes apart')
  cs = paper_case(0.01_wp, 400.0_wp)
  cs%x0 = 1.0e-4_wp
  cs%y0 = 0.5e-4_wp
  cs%omega0 = [0.0_wp, 0.0_wp, sigma]
  res = run_case(cs, 1)
  measured = [two_pi / peak_frequency(res%fields(field_contact)%values(1, :), 0.01_wp, two_pi / periods(1)), &
              two_pi / peak_frequency(res%fields(field_contact)%values(1, :), 0.01_wp, two_pi / periods(2))]
  call check_close(measured(1), periods(1), 1.0e-4_wp, 'spin 40 rad/s: slow mode period, simulated vs linear (s)')
  call check_close(measured(2), periods(2), 1.0e-4_wp, 'spin 40 rad/s: fast mode period, simulated vs linear (s)')
  call finish('test_linear')

contains

  !> The angular frequency of the largest peak of |DFT(hann * x)| within
  !> 10 % of guess, found by golden-section search on the continuous DFT.
  real(wp) function peak_frequency(x, dt, guess) result(best)
    real(wp), intent(in) :: x(:), dt, guess
    real(wp) :: low, high, a, b, window(size(x)), times(size(x))
    real(wp), parameter :: golden = 0.6180339887498949_wp
    integer :: k, iteration
    times = [((k - 1) * dt, k = 1, size(x))]
    window = 0.5_wp - 0.5_wp * cos(two_pi * times / times(size(x)))
    ! coarse scan, then golden section around the best point
    best = guess
    do k = -200, 200
      if (power(x, window, times, guess * (1 + 0.0005_wp * k)) > power(x, window, times, best)) best = guess * (1 + 0.0005_wp * k)
    end do
    low = best * (1 - 0.0005_wp)
    high = best * (1 + 0.0005_wp)
    do iteration = 1, 80
      a = high - golden * (high - low)
      b = low + golden * (high - low)
      if (power(x, window, times, a) > power(x, window, times, b)) then
        high = b
      else
        low = a
      end if
    end do
    best = (low + high) / 2
  end function peak_frequency

  real(wp) function power(x, window, times, w)
    real(wp), intent(in) :: x(:), window(:), times(:), w
    power = sum(window * x * cos(w * times))**2 + sum(window * x * sin(w * times))**2
  end function power
end program test_linear
