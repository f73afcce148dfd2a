!> Linearised small oscillations about the bottom: without spin, the
!> classical 2 pi sqrt(7 (rho - R) / (5 g)) in both principal planes; with
!> spin, the two gyroscopic mode periods against the frequencies found in a
!> simulated small oscillation (peaks of a windowed Fourier transform).
!> The periods' closed form against the full eigenvalue problem over random
!> cups and spins. Periods about the bottom are NaN where the ball cannot sit
!> there (a principal radius of curvature at the bottom at most R, though the
!> ball fits at its start). The fastest rate's cheap bound: never below the
!> eigenvalues' rate, and within 5x of it about the paper's case.
program test_linear
  use ellroll_kinds, only: wp, pi, two_pi
  use ellroll_exact, only: equals
  use ellroll_cases, only: case_t, make_ball, field_contact
  use ellroll_rolling_ball, only: rolling_ball_t, initial_state, state_size
  use ellroll_results, only: case_result_t
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan, ieee_is_finite
  use ellroll_linear, only: oscillation_periods, fastest_rate, jacobian, eigenvalues, no_spin_periods, fits_at_bottom
  use fixtures, only: paper_case, run_case
  use testing
  use ellroll_params, only: p_a, p_b, p_c, p_g, p_omega_x, p_omega_z, p_radius, p_x, p_y, p_inertia_factor
  implicit none
  type(case_t) :: cs
  type(case_result_t) :: res
  real(wp) :: periods(2), expected(2), measured(2), sigma

  cs = paper_case(1.0e-3_wp, 1.0_wp)
  periods = oscillation_periods(make_ball(cs), 0.0_wp)
  expected = 2 * pi * sqrt(7 * ([cs%param(p_a)**2, &
      cs%param(p_b)**2] / cs%param(p_c) - cs%param(p_radius)) / (5 * cs%param(p_g)))
  call check_close(periods(1), expected(1), 1.0e-8_wp, 'no spin: x-z period from the eigenvalues (s)')
  call check_close(periods(2), expected(2), 1.0e-8_wp, 'no spin: y-z period from the eigenvalues (s)')
  periods = no_spin_periods(make_ball(cs))
  call check_close(periods(1), expected(1), 1.0e-15_wp, 'no spin: x-z period, closed form (s)')
  call check_close(periods(2), expected(2), 1.0e-15_wp, 'no spin: y-z period, closed form (s)')
  call check_where_the_ball_cannot_sit_at_the_bottom()

  sigma = 40
  periods = oscillation_periods(make_ball(cs), sigma)
  call check(periods(1) > expected(1) .and. periods(2) < expected(2), 'spin splits the modes apart')
  cs = paper_case(0.01_wp, 400.0_wp)
  cs%param(p_x) = 1.0e-4_wp
  cs%param(p_y) = 0.5e-4_wp
  cs%param(p_omega_x:p_omega_z) = [0.0_wp, 0.0_wp, sigma]
  res = run_case(cs, 1)
  measured = [two_pi / peak_frequency(res%fields(field_contact)%values(1, :), 0.01_wp, two_pi / periods(1)), &
              two_pi / peak_frequency(res%fields(field_contact)%values(1, :), 0.01_wp, two_pi / periods(2))]
  call check_close(measured(1), periods(1), 1.0e-4_wp, 'spin 40 rad/s: slow mode period, simulated vs linear (s)')
  call check_close(measured(2), periods(2), 1.0e-4_wp, 'spin 40 rad/s: fast mode period, simulated vs linear (s)')
  call check_periods_against_eigenvalues()
  call check_rate_bound()
  call check_fast_spin()
  call finish('test_linear')

contains

  !> a = b = 0.5, c = 2 (bottom radii 0.125 m), R = 0.3 m: the ball fits at
  !> x = 0.45 (radii 0.453 and 5.96 m) but not at the bottom; so too a = 1,
  !> b = 0.2, c = 1e6 (b^2/c = 4e-8 m). Without gravity nothing restores the
  !> ball; with a subnormal g the period is long but finite.
  subroutine check_where_the_ball_cannot_sit_at_the_bottom()
    type(case_t) :: deep
    deep = paper_case(1.0e-3_wp, 1.0_wp)
    deep%param(p_a) = 0.5_wp
    deep%param(p_b) = 0.5_wp
    deep%param(p_c) = 2
    deep%param(p_radius) = 0.3_wp
    deep%param(p_x) = 0.45_wp
    call check(.not. fits_at_bottom(make_ball(deep)), 'a = b = 0.5, c = 2, R = 0.3: does not fit at the bottom')
    call check(all(ieee_is_nan(no_spin_periods(make_ball(deep)))), 'a = b = 0.5, c = 2: no-spin periods NaN')
    call check(all(ieee_is_nan(oscillation_periods(make_ball(deep), 0.0_wp))), &
               'a = b = 0.5, c = 2: periods NaN without spin')
    call check(all(ieee_is_nan(oscillation_periods(make_ball(deep), 20.0_wp))), &
               'a = b = 0.5, c = 2: periods NaN with spin')
    deep%param(p_a) = 1
    deep%param(p_b) = 0.2_wp
    deep%param(p_c) = 1.0e6_wp
    deep%param(p_radius) = 0.2_wp
    deep%param(p_x) = 0
    call check(all(ieee_is_nan(no_spin_periods(make_ball(deep)))), 'a = 1, b = 0.2, c = 1e6: no-spin periods NaN')
    call check(all(ieee_is_nan(oscillation_periods(make_ball(deep), 20.0_wp))), &
               'a = 1, b = 0.2, c = 1e6: periods NaN')
    deep = paper_case(1.0e-3_wp, 1.0_wp)
    deep%param(p_radius) = 0.8_wp * deep%param(p_b)**2 / deep%param(p_c)     ! just fits: periods finite and short
    call check(all(ieee_is_finite(no_spin_periods(make_ball(deep)))), 'R = 0.8 b^2/c: no-spin periods finite')
    deep%param(p_g) = 0
    call check(all(ieee_is_nan(no_spin_periods(make_ball(deep)))), 'g = 0: no-spin periods NaN')
    deep%param(p_g) = tiny(1.0_wp) * epsilon(1.0_wp)
    periods = no_spin_periods(make_ball(deep))
    call check(all(ieee_is_finite(periods) .and. periods > 1.0e150_wp), 'g subnormal: no-spin periods finite')
  end subroutine check_where_the_ball_cannot_sit_at_the_bottom

  !> A cup with random axes (a = 1), a random ball below its least radius of
  !> curvature (c^2 / a), both from draw(1:3).
  function random_cup(draw) result(cup)
    real(wp), intent(in) :: draw(3)
    type(case_t) :: cup
    cup = paper_case(1.0e-3_wp, 1.0_wp)
    cup%param(p_b) = 0.2_wp + 0.8_wp * draw(1)
    cup%param(p_c) = 0.05_wp + 0.15_wp * draw(2)
    cup%param(p_radius) = (0.02_wp + 0.9_wp * draw(3)) * cup%param(p_c)**2 / cup%param(p_a)
  end function random_cup

  subroutine seed_random()
    integer :: n, k
    call random_seed(size=n)
    call random_seed(put=[(12345 + 7 * k, k = 1, n)])
  end subroutine seed_random

  !> oscillation_periods' 2x2 closed form against the periods of the whole
  !> 6x6 Jacobian's eigenvalues (LAPACK), and the symmetry the closed form
  !> rests on: (n1, w1)' does not depend on (n1, w1), nor (n2, w2)' on (n2, w2).
  !> The fast root comes from the same Jacobian both ways; the slow one from
  !> the product omega_x omega_y / omega_f, the 6x6's from the Jacobian. All
  !> against the modes' closed form (exact_frequencies), the Jacobian taken
  !> with oscillation_periods' steps (lengths c/a, c/b along n_1, n_2;
  !> Richardson-extrapolated): 1e-10 in both.
  subroutine check_periods_against_eigenvalues()
    integer, parameter :: odd(2) = [1, 4], even(2) = [2, 5]
    type(case_t) :: cup
    type(rolling_ball_t) :: ball
    real(wp) :: draw(4), sigma, jac(state_size, state_size), re(state_size), im(state_size)
    real(wp) :: closed(2), full(2), exact(2), worst_fast, worst_slow, worst_full_slow, worst_coupling
    integer :: k
    call seed_random()
    worst_fast = 0
    worst_slow = 0
    worst_full_slow = 0
    worst_coupling = 0
    do k = 1, 500
      call random_number(draw)
      cup = random_cup(draw(1:3))
      ball = make_ball(cup)
      sigma = 300 * (2 * draw(4) - 1)
      jac = jacobian(ball, [0.0_wp, 0.0_wp, 1.0_wp, 0.0_wp, 0.0_wp, sigma], lengths=bottom_lengths(cup))
      worst_coupling = max(worst_coupling, maxval(abs([jac(odd, odd), jac(even, even)])) / maxval(abs(jac)))
      call eigenvalues(jac, re, im)
      full = two_pi / pack(im, im > 1.0e-9_wp * maxval(abs(im)))   ! two oscillating modes here
      full = [maxval(full), minval(full)]
      closed = oscillation_periods(ball, sigma)
      exact = two_pi / exact_frequencies(cup, sigma)   ! [fast, slow] periods
      worst_fast = max(worst_fast, abs(closed(2) - full(2)) / full(2))
      worst_slow = max(worst_slow, maxval(abs(closed - exact([2, 1])) / exact([2, 1])))
      worst_full_slow = max(worst_full_slow, maxval(abs(full - exact([2, 1])) / exact([2, 1])))
    end do
    call check_below(worst_coupling, 1.0e-9_wp, 'bottom equilibrium: Jacobian entries the mirror symmetry makes zero')
    call check_below(worst_fast, 1.0e-13_wp, 'fast period: 2x2 closed form against the 6x6 eigenvalues (500 cups)')
    call check_below(worst_slow, 1.0e-10_wp, 'periods: 2x2 closed form against the modes'' closed form (500 cups)')
    call check_below(worst_full_slow, 1.0e-10_wp, 'periods: 6x6 eigenvalues against the modes'' closed form (500 cups)')
  end subroutine check_periods_against_eigenvalues

  !> Over random cups, balls from small to nearly the cup's least radius of
  !> curvature, positions out to near the rim and spins from 0 to about
  !> 1000 rad/s: the bound that fastest_rate returns when it is at most
  !> `enough` is never below the eigenvalues' rate (it is a similar matrix's
  !> norm), and above `enough` the eigenvalues' rate itself comes back.
  subroutine check_rate_bound()
    type(case_t) :: cup
    type(rolling_ball_t) :: ball
    real(wp) :: y(state_size), exact, bound, worst_ratio, draw(6)
    integer :: k, low_count, exact_missed
    call seed_random()
    low_count = 0
    exact_missed = 0
    do k = 1, 2000
      call random_number(draw)
      cup = random_cup(draw(1:3))
      ball = make_ball(cup)
      y = initial_state(ball, 0.7_wp * (2 * draw(4) - 1) * (cup%param(p_a) - cup%param(p_radius)), &
                        0.7_wp * (2 * draw(5) - 1) * (cup%param(p_b) - cup%param(p_radius)), &
                        1000 * draw(6)**3 * [draw(1) - 0.5_wp, draw(2) - 0.5_wp, 1.0_wp])
      exact = fastest_rate(ball, y)
      bound = fastest_rate(ball, y, enough=huge(1.0_wp))
      if (bound < exact * (1 - 1.0e-12_wp)) low_count = low_count + 1
      if (.not. equals(fastest_rate(ball, y, enough=0.5_wp * bound), exact)) exact_missed = exact_missed + 1
    end do
    call check(low_count == 0, 'fastest rate: the bound is never below the eigenvalues'' rate (2000 random states)')
    call check(exact_missed == 0, 'fastest rate: above enough, the eigenvalues'' rate itself (2000 random states)')
    ! tight enough to spare the eigenvalues in a sweep about the paper's case, its purpose
    worst_ratio = 0
    do k = 0, 99
      cup = paper_case(1.0e-3_wp, 1.0_wp)
      cup%param(p_radius) = 0.02_wp + 0.18_wp * mod(k, 10) / 9
      ball = make_ball(cup)
      y = initial_state(ball, 0.0_wp, 0.0_wp, [-2.0_wp, 2.0_wp, 5 + 95 * (k / 10) / 9.0_wp])
      worst_ratio = max(worst_ratio, fastest_rate(ball, y, enough=huge(1.0_wp)) / fastest_rate(ball, y))
    end do
    ! unbalanced, the plain norm is 12.5 times the rate here
    call check_below(worst_ratio, 5.0_wp, 'fastest rate: worst bound / eigenvalues'' rate, paper''s cup swept')
  end subroutine check_rate_bound

  !> Spin sigma about the normal, from 1 to 1e6 rad/s. In n = (n1, n2) the
  !> motion is M n'' + G n' + K n = 0 with M = (1 + k) diag(L1, L2), G = k R sigma
  !> [[0, -1], [1, 0]], K = g I (L = rho - R; docs/model.md, "Linear modes"),
  !> so omega_f^2 + omega_s^2 = omega_x^2 + omega_y^2 + (k R sigma)^2 / ((1 + k)^2 L1 L2)
  !> and omega_f omega_s = omega_x omega_y, the no-spin pair's. Checked: both
  !> periods finite, their product against the no-spin pair's to 1e-12, the
  !> fast one against the closed form and its asymptote 2 pi (1 + k)
  !> sqrt(L1 L2) / (k R sigma); without spin the quadratic's own two roots,
  !> bitwise. Cups: a = b = c = 1 with R = 0.999 (k = 0.4 and 0.1), the paper's.
  subroutine check_fast_spin()
    real(wp), parameter :: spins(9) = [1.0_wp, 10.0_wp, 100.0_wp, 1.0e3_wp, 3.0e3_wp, 1.0e4_wp, 3.0e4_wp, &
                                       1.0e5_wp, 1.0e6_wp]
    type(case_t) :: cup
    real(wp) :: no_spin(2), periods(2), fast, asymptote, lengths(2), k, exact(2)
    real(wp) :: worst_product, worst_fast, worst_asymptote
    integer :: which, j
    logical :: all_finite
    worst_product = 0
    worst_fast = 0
    worst_asymptote = 0
    all_finite = .true.
    do which = 1, 3
      cup = paper_case(1.0e-3_wp, 1.0_wp)
      cup%param(p_inertia_factor) = merge(0.1_wp, 0.4_wp, which == 2)
      if (which <= 2) then
        cup%param(p_a:p_c) = 1
        cup%param(p_radius) = 0.999_wp
      end if
      k = cup%param(p_inertia_factor)
      lengths = [cup%param(p_a)**2, cup%param(p_b)**2] / cup%param(p_c) - cup%param(p_radius)
      no_spin = no_spin_periods(make_ball(cup))
      call check_no_spin_roots(cup)
      do j = 1, size(spins)
        periods = oscillation_periods(make_ball(cup), spins(j))
        all_finite = all_finite .and. all(ieee_is_finite(periods))
        if (.not. all(ieee_is_finite(periods))) cycle
        worst_product = max(worst_product, abs(product(periods) / product(no_spin) - 1))
        fast = two_pi / minval(periods)
        exact = exact_frequencies(cup, spins(j))
        worst_fast = max(worst_fast, abs(fast / exact(1) - 1), abs(two_pi / maxval(periods) / exact(2) - 1))
        asymptote = k * cup%param(p_radius) * spins(j) / ((1 + k) * sqrt(product(lengths)))
        if (spins(j) >= 1.0e5_wp) worst_asymptote = max(worst_asymptote, abs(fast / asymptote - 1))
      end do
    end do
    call check(all_finite, 'spin 1 to 1e6 rad/s: both periods finite (3 cups)')
    call check_below(worst_product, 1.0e-12_wp, 'spin 1 to 1e6 rad/s: period product / the no-spin pair''s - 1')
    ! (the Jacobian's central differences, step ~6e-6 relative, at spin 1e6)
    call check_below(worst_fast, 1.0e-8_wp, 'spin 1 to 1e6 rad/s: both frequencies against the closed form, relative')
    ! the asymptote's own error (omega_x^2 + omega_y^2) / (2 omega_f^2): 5.8e-7 on the paper's cup at 1e5
    call check_below(worst_asymptote, 1.0e-6_wp, 'spin 1e5, 1e6 rad/s: fast frequency against k R sigma / ((1 + k) &
        &sqrt(L1 L2)), relative')
  end subroutine check_fast_spin

  !> The modes' angular frequencies [fast, slow] from M n'' + G n' + K n = 0
  !> (docs/model.md, "Linear modes"): omega^2 solves (1 + k)^2 L1 L2 omega^4 -
  !> ((1 + k) g (L1 + L2) + (k R sigma)^2) omega^2 + g^2 = 0, the larger root
  !> by the quadratic, the smaller from the product of the two.
  function exact_frequencies(cup, sigma) result(frequencies)
    type(case_t), intent(in) :: cup
    real(wp), intent(in) :: sigma
    real(wp) :: frequencies(2), lengths(2), k, a, b, c
    k = cup%param(p_inertia_factor)
    lengths = [cup%param(p_a)**2, cup%param(p_b)**2] / cup%param(p_c) - cup%param(p_radius)
    a = (1 + k)**2 * product(lengths)
    b = (1 + k) * cup%param(p_g) * sum(lengths) + (k * cup%param(p_radius) * sigma)**2
    c = cup%param(p_g)**2
    frequencies(1) = sqrt((b + sqrt((b - 2 * sqrt(a * c)) * (b + 2 * sqrt(a * c)))) / (2 * a))
    frequencies(2) = sqrt(c / a) / frequencies(1)
  end function exact_frequencies

  !> Without spin the two periods (in closed form) are the quadratic's roots
  !> mu = half_trace +- sqrt(discriminant) of the 2x2 product BC of the
  !> Jacobian's blocks (omega = |Im sqrt(mu)|), to the Jacobian's error by
  !> differences, also where they are one (a sphere cup: a double root).
  subroutine check_no_spin_roots(cup)
    type(case_t), intent(in) :: cup
    integer, parameter :: odd(2) = [1, 4], even(2) = [2, 5]
    real(wp) :: jac(state_size, state_size), squared(2, 2), half_trace, discriminant, roots(2), periods(2)
    complex(wp) :: mu(2)
    jac = jacobian(make_ball(cup), [0.0_wp, 0.0_wp, 1.0_wp, 0.0_wp, 0.0_wp, 0.0_wp], lengths=bottom_lengths(cup))
    squared = matmul(jac(odd, even), jac(even, odd))
    half_trace = (squared(1, 1) + squared(2, 2)) / 2
    discriminant = ((squared(1, 1) - squared(2, 2)) / 2)**2 + squared(1, 2) * squared(2, 1)
    mu = half_trace + [1, -1] * sqrt(cmplx(discriminant, 0.0_wp, wp))
    roots = two_pi / abs(aimag(sqrt(mu)))
    periods = oscillation_periods(make_ball(cup), 0.0_wp)
    call check_close(maxval(roots), periods(1), 1.0e-10_wp, 'no spin: longer period, the quadratic''s root (s)')
    call check_close(minval(roots), periods(2), 1.0e-10_wp, 'no spin: shorter period, the quadratic''s root (s)')
  end subroutine check_no_spin_roots

  !> The Jacobian's step lengths oscillation_periods takes at the bottom:
  !> c/a and c/b (at most 1) along n_1 and n_2, 1 along the rest.
  function bottom_lengths(cup) result(lengths)
    type(case_t), intent(in) :: cup
    real(wp) :: lengths(state_size)
    type(rolling_ball_t) :: ball
    ball = make_ball(cup)
    lengths = 1
    lengths(1:2) = min(1.0_wp, ball%cup%c * ball%cup%inv_axes(1:2))
  end function bottom_lengths

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
