!> Linear analysis of the rolling ball: the Jacobian of the right-hand side
!> (central differences) and its eigenvalues (LAPACK dgeev).
!>  - small-oscillation periods about the bottom equilibrium spinning with
!>    sigma = omega . n about the vertical (n = e_z, omega = sigma e_z);
!>  - the fastest rate of the linearised motion at a state, which sets the
!>    step a fixed-step method needs.
module ellroll_linear
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, two_pi
  use ellroll_rolling_ball, only: rolling_ball_t, state_size
  implicit none
  private

  public :: jacobian, eigenvalues, oscillation_periods, fastest_rate

contains

  !> d f / d y at y, by central differences (error ~ delta^2).
  function jacobian(ball, y) result(jac)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size)
    real(wp) :: jac(state_size, state_size)
    real(wp) :: plus(state_size), minus(state_size), step(state_size), delta
    integer :: j
    do j = 1, state_size
      delta = epsilon(1.0_wp)**(1.0_wp / 3) * max(abs(y(j)), 1.0_wp)
      step = 0
      step(j) = delta
      call ball%rhs(0.0_wp, y + step, plus)
      call ball%rhs(0.0_wp, y - step, minus)
      jac(:, j) = (plus - minus) / (2 * delta)
    end do
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

  !> The two small-oscillation periods (longer first) about the bottom,
  !> spinning at sigma; NaN for a mode that does not oscillate.
  function oscillation_periods(ball, sigma) result(periods)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: sigma
    real(wp) :: periods(2)
    real(wp) :: re(state_size), im(state_size), frequencies(state_size), scale
    integer :: n_modes, k
    call eigenvalues(jacobian(ball, [0.0_wp, 0.0_wp, 1.0_wp, 0.0_wp, 0.0_wp, sigma]), re, im)
    scale = maxval(abs(im))
    n_modes = 0
    do k = 1, state_size
      if (im(k) > 1.0e-9_wp * scale) then
        n_modes = n_modes + 1
        frequencies(n_modes) = im(k)
      end if
    end do
    periods = ieee_value(0.0_wp, ieee_quiet_nan)
    do k = 1, min(2, n_modes)
      periods(k) = two_pi / frequencies(k)
    end do
    if (n_modes >= 2 .and. periods(2) > periods(1)) periods = periods([2, 1])
  end function oscillation_periods

  !> Largest |eigenvalue| of the Jacobian at y (1/s).
  real(wp) function fastest_rate(ball, y)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size)
    real(wp) :: re(state_size), im(state_size)
    call eigenvalues(jacobian(ball, y), re, im)
    fastest_rate = maxval(hypot(re, im))
  end function fastest_rate
end module ellroll_linear
