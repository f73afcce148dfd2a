!> The baseline of bench/throughput: a straightforward scalar RK4 of the same
!> equations in the paper's form (contact point r_A and omega):
!> each right-hand side solves H r_A' = V_C (3x3, Gaussian elimination with
!> partial pivoting), takes n' = (dn/dr_A) r_A', and projects r_A back onto
!> the surface after each step. No tuning.
module baseline_rk4
  use, intrinsic :: iso_fortran_env, only: wp => real64
  implicit none
  private
  public :: baseline_run

  real(wp), parameter :: a = 1, b = 0.4_wp, c = 0.2_wp, radius = 0.2_wp, g = 9.81_wp

contains

  subroutine normal_and_derivative(r, n, dn_dr)
    real(wp), intent(in) :: r(3)
    real(wp), intent(out) :: n(3), dn_dr(3, 3)
    real(wp) :: q(3), big_q, qhat(3), d(3)
    integer :: i, j
    d = [1 / a**2, 1 / b**2, 1 / c**2]
    q = [r(1) * d(1), r(2) * d(2), (r(3) - c) * d(3)]
    big_q = sqrt(q(1)**2 + q(2)**2 + q(3)**2)
    qhat = q / big_q
    n = -qhat
    do j = 1, 3
      do i = 1, 3
        dn_dr(i, j) = -(merge(1.0_wp, 0.0_wp, i == j) - qhat(i) * qhat(j)) * d(j) / big_q
      end do
    end do
  end subroutine normal_and_derivative

  subroutine rhs(y, dydt)
    real(wp), intent(in) :: y(6)
    real(wp), intent(out) :: dydt(6)
    real(wp) :: n(3), dn_dr(3, 3), h(3, 3), v(3), r_dot(3), n_dot(3), omega(3), spin
    integer :: i
    call normal_and_derivative(y(1:3), n, dn_dr)
    omega = y(4:6)
    v = radius * [omega(2)*n(3) - omega(3)*n(2), omega(3)*n(1) - omega(1)*n(3), omega(1)*n(2) - omega(2)*n(1)]
    h = radius * dn_dr
    do i = 1, 3
      h(i, i) = h(i, i) + 1
    end do
    r_dot = solve3(h, v)
    n_dot = matmul(dn_dr, r_dot)
    spin = dot_product(omega, n)
    dydt(1:3) = r_dot
    dydt(4:6) = 5.0_wp / 7 * (spin * n_dot + (g / radius) * [-n(2), n(1), 0.0_wp])
  end subroutine rhs

  function solve3(matrix, rhs_vector) result(x)
    real(wp), intent(in) :: matrix(3, 3), rhs_vector(3)
    real(wp) :: x(3), m(3, 4), row(4), factor
    integer :: k, i, p
    m(:, 1:3) = matrix
    m(:, 4) = rhs_vector
    do k = 1, 3
      p = k - 1 + maxloc(abs(m(k:3, k)), dim=1)
      if (p /= k) then
        row = m(k, :); m(k, :) = m(p, :); m(p, :) = row
      end if
      do i = k + 1, 3
        factor = m(i, k) / m(k, k)
        m(i, k:4) = m(i, k:4) - factor * m(k, k:4)
      end do
    end do
    do k = 3, 1, -1
      x(k) = (m(k, 4) - dot_product(m(k, k+1:3), x(k+1:3))) / m(k, k)
    end do
  end function solve3

  !> Integrate the paper's case; returns the final state.
  function baseline_run(dt, n_steps) result(y)
    real(wp), intent(in) :: dt
    integer, intent(in) :: n_steps
    real(wp) :: y(6), k1(6), k2(6), k3(6), k4(6), s
    integer :: step
    y = [0.0_wp, 0.0_wp, 0.0_wp, -2.0_wp, 2.0_wp, 20.0_wp]
    do step = 1, n_steps
      call rhs(y, k1)
      call rhs(y + dt / 2 * k1, k2)
      call rhs(y + dt / 2 * k2, k3)
      call rhs(y + dt * k3, k4)
      y = y + dt / 6 * (k1 + 2 * (k2 + k3) + k4)
      ! back onto the surface along its normal: scale (x/a, y/b, (z-c)/c) to unit length
      s = sqrt((y(1) / a)**2 + (y(2) / b)**2 + ((y(3) - c) / c)**2)
      y(1:3) = [y(1) / s, y(2) / s, c + (y(3) - c) / s]
    end do
  end function baseline_run
end module baseline_rk4
