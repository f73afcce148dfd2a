!> Linear analysis of the rolling ball: the Jacobian of the right-hand side
!> (central differences) and its eigenvalues (LAPACK dgeev).
!>  - small-oscillation periods about the bottom equilibrium spinning with
!>    sigma = omega . n about the vertical (n = e_z, omega = sigma e_z), in
!>    closed form from the Jacobian's two 2x2 coupling blocks;
!>  - the fastest rate of the linearised motion at a state, which sets the
!>    step a fixed-step method needs, or a cheap bound on it.
module ellroll_linear
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan, ieee_is_finite
  use ellroll_kinds, only: wp, two_pi
  use ellroll_lapack, only: dgeev
  use ellroll_rolling_ball, only: rolling_ball_t, state_size, smooth_part
  use ellroll_ellipsoid, only: bottom_radii
  use ellroll_excitation, only: excitation_none
  use ellroll_exact, only: is_zero
  implicit none
  private

  public :: jacobian, eigenvalues, oscillation_periods, fastest_rate, no_spin_periods, fits_at_bottom

contains

  !> d f / d y at y, by central differences (error ~ delta^2), of the
  !> model's smooth part (smooth_part: without its non-smooth laws). Given
  !> lengths (the size over which f bends along each y_j), steps of
  !> eps^(1/5) max(|y_j|, length_j) and of half that, extrapolated
  !> (Richardson: (4 D(delta / 2) - D(delta)) / 3, error ~ (delta / length)^4,
  !> round-off ~ eps length / delta, both ~ eps^(4/5)); without, one step of
  !> eps^(1/3) max(|y_j|, 1).
  function jacobian(ball, y, lengths) result(jac)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size)
    real(wp), intent(in), optional :: lengths(state_size)
    real(wp) :: jac(state_size, state_size)
    real(wp) :: delta
    type(rolling_ball_t) :: smooth
    integer :: j
    smooth = smooth_part(ball)
    do j = 1, state_size
      if (present(lengths)) then
        delta = epsilon(1.0_wp)**(1.0_wp / 5) * max(abs(y(j)), lengths(j))
        jac(:, j) = (4 * difference(j, delta / 2) - difference(j, delta)) / 3
      else
        delta = epsilon(1.0_wp)**(1.0_wp / 3) * max(abs(y(j)), 1.0_wp)
        jac(:, j) = difference(j, delta)
      end if
    end do
  contains
    function difference(j, delta) result(column)
      integer, intent(in) :: j
      real(wp), intent(in) :: delta
      real(wp) :: column(state_size), plus(state_size), minus(state_size), step(state_size)
      step = 0
      step(j) = delta
      call smooth%rhs(0.0_wp, y + step, plus)
      call smooth%rhs(0.0_wp, y - step, minus)
      column = (plus - minus) / (2 * delta)
    end function difference
  end function jacobian

  subroutine eigenvalues(matrix, real_part, imag_part)
    real(wp), intent(in) :: matrix(:, :)
    real(wp), intent(out) :: real_part(:), imag_part(:)
    real(wp) :: a(size(matrix, 1), size(matrix, 2)), dummy(1, 1), work(8 * size(matrix, 1))
    integer :: info, n
    n = size(matrix, 1)
    a = matrix
    call dgeev('N', 'N', n, a, n, real_part, imag_part, dummy, 1, dummy, 1, work, size(work), info)
    if (info /= 0) then
      real_part = ieee_value(0.0_wp, ieee_quiet_nan)
      imag_part = real_part
    end if
  end subroutine eigenvalues

  !> The small-oscillation periods about the bottom without spin, in the
  !> x-z and y-z planes: 2 pi sqrt((1 + k)(rho - R) / g), rho the cup's
  !> principal radii of curvature there; NaN where the ball cannot sit at the
  !> bottom (fits_at_bottom) or nothing restores it (g = 0).
  pure function no_spin_periods(ball) result(periods)
    type(rolling_ball_t), intent(in) :: ball
    real(wp) :: periods(2)
    periods = ieee_value(0.0_wp, ieee_quiet_nan)
    if (.not. (fits_at_bottom(ball) .and. ball%g > 0)) return
    ! the roots apart: (rho - R) / g overflows for a subnormal g
    periods = 2 * acos(-1.0_wp) * (sqrt((1 + ball%inertia_factor) * (bottom_radii(ball%cup) - ball%radius)) / &
                                   sqrt(ball%g))
  end function no_spin_periods

  !> The ball can rest at the bottom: both principal radii of curvature
  !> there (a^2/c, b^2/c) exceed its radius. Where one does not, the ball
  !> that fits at its start touches the cup at two points before it gets
  !> there, and nothing about the bottom is defined.
  pure logical function fits_at_bottom(ball)
    type(rolling_ball_t), intent(in) :: ball
    fits_at_bottom = all(bottom_radii(ball%cup) > ball%radius)
  end function fits_at_bottom

  !> The two small-oscillation periods (longer first) about the bottom of
  !> the cup at rest, spinning at sigma; NaN for a mode that does not
  !> oscillate (its period infinite: first), and both NaN where the ball cannot sit at the bottom
  !> (fits_at_bottom).
  !> Why 2x2: the cup's mirror x -> -x followed by time reversal maps
  !> (n1, n2, w1, w2) to (-n1, n2, -w1, w2) and keeps the equilibrium, so the
  !> Jacobian J anticommutes with that involution: (n1, w1)' depends on
  !> (n2, w2) alone (block B) and (n2, w2)' on (n1, w1) alone (block C), while
  !> n3 and w3 stay constant to first order. Then J^2 = diag(BC, CB), and the
  !> eigenvalues are the square roots of the eigenvalues mu of the 2x2 BC.
  !> With spin the two mu = -omega^2 part by orders of magnitude: the larger
  !> comes from the quadratic without cancellation, the smaller from the
  !> product omega_1 omega_2 = omega_x omega_y of the no-spin pair (docs/model.md,
  !> "Linear modes"), since det(BC) itself is a difference of products ~ sigma^4.
  function oscillation_periods(ball, sigma) result(periods)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: sigma
    real(wp) :: periods(2)
    integer, parameter :: odd(2) = [1, 4], even(2) = [2, 5]   ! (n1, w1) and (n2, w2)
    real(wp) :: jac(state_size, state_size), squared(2, 2), half_trace, discriminant, frequencies(2)
    real(wp) :: axis_ratios(2)
    complex(wp) :: mu(2)
    type(rolling_ball_t) :: at_rest
    periods = ieee_value(0.0_wp, ieee_quiet_nan)
    if (.not. fits_at_bottom(ball)) return
    if (is_zero(sigma)) then
      ! the no-spin pair in closed form: the quadratic's double root of a
      ! round cup (a = b) would keep half its digits (2e-9)
      periods = no_spin_periods(ball)
      if (.not. ieee_is_nan(periods(1))) periods = [maxval(periods), minval(periods)]
      return
    end if
    ! the isolator's own modes: its cup at rest (a moving cup's vertical
    ! acceleration at t = 0 would stand in for a part of g)
    at_rest = ball
    at_rest%excitation%kind = excitation_none
    ! n_1 and n_2 bend the contact point over c/a and c/b (s = sqrt(c^2 + a^2
    ! n_1^2) about the bottom): a step of eps^(1/3) on a narrow cup leaves
    ! (a/c)^2 eps^(2/3) (9e-8 at a/c = 50)
    axis_ratios = min(1.0_wp, ball%cup%c * ball%cup%inv_axes(1:2))
    jac = jacobian(at_rest, [0.0_wp, 0.0_wp, 1.0_wp, 0.0_wp, 0.0_wp, sigma], &
                   lengths=[axis_ratios(1), axis_ratios(2), 1.0_wp, 1.0_wp, 1.0_wp, 1.0_wp])
    squared = matmul(jac(odd, even), jac(even, odd))
    half_trace = (squared(1, 1) + squared(2, 2)) / 2
    ! (tr/2)^2 - det as ((a - d)/2)^2 + b c: no cancellation where the two
    ! no-spin frequencies nearly agree (a round cup at a small spin)
    discriminant = ((squared(1, 1) - squared(2, 2)) / 2)**2 + squared(1, 2) * squared(2, 1)
    if (stable_gyroscopic(sigma, ball%g, half_trace, discriminant)) then
      ! the fast root by the quadratic, the slow from the product (no round-off
      ! floor below: it is as exact as the fast one)
      frequencies(1) = sqrt(-(half_trace - sqrt(discriminant)))
      frequencies(2) = product(two_pi / no_spin_periods(ball)) / frequencies(1)
      ! (a period that would overflow, from a subnormal g, stays NaN: the
      ! longer, first)
      where (frequencies([2, 1]) > two_pi / huge(1.0_wp)) periods = two_pi / frequencies([2, 1])
      return
    end if
    mu = half_trace + [1, -1] * sqrt(cmplx(discriminant, 0.0_wp, wp))
    ! an eigenvalue sqrt(mu) oscillates at |Im sqrt(mu)|: a real mu < 0 is a
    ! pure oscillation; a complex pair (flutter) grows while it oscillates
    frequencies = abs(aimag(sqrt(mu)))
    if (.not. all(ieee_is_finite(frequencies))) return
    ! nothing restores the ball without g: the slower mode's frequency is
    ! zero (det BC = 0), whatever round-off leaves of it
    if (.not. ball%g > 0) frequencies(minloc(frequencies, dim=1)) = 0
    where (frequencies > 1.0e-9_wp * maxval(frequencies)) periods = two_pi / frequencies
    ! the longer first: a mode that does not oscillate (its period infinite,
    ! NaN) before one that does (as the slow mode before the gyroscopic one
    ! without g). NaN is tested first: an ordered comparison with it traps
    ! where invalid traps.
    if (ieee_is_nan(periods(2))) then
      periods = periods([2, 1])
    else if (.not. ieee_is_nan(periods(1))) then
      if (periods(2) > periods(1)) periods = periods([2, 1])
    end if
  end function oscillation_periods

  !> A spinning pair whose K is positive definite (g > 0, the ball fits at the
  !> bottom): both mu = -omega^2 real and negative. Without spin the quadratic's
  !> roots are the no-spin pair's own, and its two formulas agree.
  pure logical function stable_gyroscopic(sigma, g, half_trace, discriminant)
    real(wp), intent(in) :: sigma, g, half_trace, discriminant
    stable_gyroscopic = .false.
    ! NaN apart first: an ordered comparison with it traps where invalid traps
    if (.not. (ieee_is_finite(half_trace) .and. ieee_is_finite(discriminant))) return
    stable_gyroscopic = abs(sigma) > 0 .and. g > 0 .and. half_trace < 0 .and. discriminant >= 0
  end function stable_gyroscopic

  !> The fastest rate of the motion linearised at y (1/s): the largest
  !> |eigenvalue| of the Jacobian. Where a bound on it (balanced_norm) is
  !> already at most `enough`, that bound instead: a caller asking only
  !> whether the rate passes `enough` is spared the eigenvalue solve.
  real(wp) function fastest_rate(ball, y, enough)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size)
    real(wp), intent(in), optional :: enough
    real(wp) :: jac(state_size, state_size), re(state_size), im(state_size)
    jac = jacobian(ball, y)
    fastest_rate = balanced_norm(jac)
    if (present(enough)) then
      if (fastest_rate <= enough) return
    end if
    call eigenvalues(jac, re, im)
    fastest_rate = maxval(hypot(re, im))
  end function fastest_rate

  !> A bound on every |eigenvalue| of a matrix: a norm of a similar matrix
  !> (Osborne's balancing, a few sweeps: each row's and column's off-diagonal
  !> sums made equal by a diagonal similarity). Unbalanced, a state Jacobian's
  !> entries span orders of magnitude and its plain norm is a loose bound.
  pure real(wp) function balanced_norm(matrix) result(bound)
    real(wp), intent(in) :: matrix(:, :)
    integer, parameter :: sweeps = 4
    real(wp) :: m(size(matrix, 1), size(matrix, 2)), row, column, factor
    integer :: sweep, i
    m = abs(matrix)
    do sweep = 1, sweeps
      do i = 1, size(m, 1)
        column = sum(m(:, i)) - m(i, i)
        row = sum(m(i, :)) - m(i, i)
        if (.not. (column > 0 .and. row > 0)) cycle
        factor = sqrt(row / column)
        m(:, i) = m(:, i) * factor
        m(i, :) = m(i, :) / factor
      end do
    end do
    bound = min(maxval(sum(m, dim=1)), maxval(sum(m, dim=2)))
  end function balanced_norm
end module ellroll_linear
