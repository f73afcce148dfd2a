!> Geometry against independent truth: the implicit surface equation,
!> the paper's shape operator diagonalised by LAPACK, the bottom radii
!> a^2/c and b^2/c, and quad-precision radii on a nearly spherical cup.
program test_ellipsoid
  use ellroll_kinds, only: wp
  use ellroll_lapack, only: dsyev
  use ellroll_ellipsoid
  use testing
  implicit none
  integer, parameter :: qp = selected_real_kind(30)
  type(ellipsoid_t) :: cup
  real(wp) :: n(3), p(3), back(3), radii(2), reference(2), worst_residual, worst_roundtrip, worst_radii
  integer :: trial

  cup = new_ellipsoid(1.0_wp, 0.4_wp, 0.2_wp)
  call random_seed_fixed()
  worst_residual = 0; worst_roundtrip = 0; worst_radii = 0
  do trial = 1, 2000
    n = random_lower_normal()
    p = contact_from_normal(cup, n)
    worst_residual = max(worst_residual, surface_residual(cup, p))
    back = normal_from_contact(cup, p(1), p(2))
    worst_roundtrip = max(worst_roundtrip, maxval(abs(back - n)))
    radii = principal_radii(cup, n)
    reference = radii_from_shape_operator(cup, p)
    worst_radii = max(worst_radii, maxval(abs(radii - reference) / reference))
  end do
  call check_below(worst_residual, 4 * epsilon(1.0_wp), 'contact_from_normal lies on the surface')
  call check_below(worst_roundtrip, 1.0e-13_wp, 'normal -> contact -> normal round trip')
  call check_below(worst_radii, 1.0e-11_wp, 'principal radii match the LAPACK eigenvalues of the shape operator')

  radii = principal_radii(cup, [0.0_wp, 0.0_wp, 1.0_wp])
  call check_close(radii(1), 0.4_wp**2 / 0.2_wp, 1.0e-14_wp, 'bottom radius in y-z = b^2/c')
  call check_close(radii(2), 1.0_wp / 0.2_wp, 1.0e-14_wp, 'bottom radius in x-z = a^2/c')

  ! Nearly spherical cup: the radii differ by ~1e-8 of their size; their
  ! difference must still be right to many digits (quad-precision reference),
  ! measured against the cup's own asphericity a^2 - c^2.
  cup = new_ellipsoid(1.0_wp + 3.0e-8_wp, 1.0_wp + 1.0e-8_wp, 1.0_wp)
  worst_radii = 0
  do trial = 1, 200
    n = random_lower_normal()
    radii = principal_radii(cup, n)
    reference = quad_radii(cup, n)
    worst_radii = max(worst_radii, abs((radii(2) - radii(1)) - (reference(2) - reference(1))) &
                                   / (cup%a**2 - cup%c**2))
  end do
  call check_below(worst_radii, 1.0e-6_wp, 'nearly spherical cup: error of r2 - r1 / (a^2 - c^2)')
  call finish('test_ellipsoid')

contains

  subroutine random_seed_fixed()
    integer :: size_seed
    call random_seed(size=size_seed)
    call random_seed(put=[(12345 + 7 * trial, trial = 1, size_seed)])
  end subroutine random_seed_fixed

  !> A random unit normal of the lower half, nutation up to ~80 degrees.
  function random_lower_normal() result(n)
    real(wp) :: n(3), u(3)
    call random_number(u)
    n = [2 * u(1) - 1, 2 * u(2) - 1, 0.2_wp + u(3)]
    n = n / norm2(n)
  end function random_lower_normal

  !> The paper's form: dn/dr_A = -(I - q^ q^T) D / Q; principal curvatures are the
  !> tangent eigenvalues of (I - q^q^T) D (I - q^q^T) / Q.
  function radii_from_shape_operator(cup, p) result(r)
    type(ellipsoid_t), intent(in) :: cup
    real(wp), intent(in) :: p(3)
    real(wp) :: r(2), q(3), qhat(3), proj(3, 3), d(3, 3), s(3, 3), eig(3), work(64)
    integer :: info, i
    q = [p(1) / cup%a**2, p(2) / cup%b**2, (p(3) - cup%c) / cup%c**2]
    qhat = q / norm2(q)
    proj = -spread(qhat, 2, 3) * spread(qhat, 1, 3)
    d = 0
    do i = 1, 3
      proj(i, i) = proj(i, i) + 1
    end do
    d(1,1) = 1 / cup%a**2; d(2,2) = 1 / cup%b**2; d(3,3) = 1 / cup%c**2
    s = matmul(proj, matmul(d, proj)) / norm2(q)
    call dsyev('N', 'U', 3, s, 3, eig, work, size(work), info)
    ! eig ascending: the normal direction gives 0, then the two curvatures
    r = [1 / eig(3), 1 / eig(2)]
  end function radii_from_shape_operator

  function quad_radii(cup, n) result(r)
    type(ellipsoid_t), intent(in) :: cup
    real(wp), intent(in) :: n(3)
    real(wp) :: r(2)
    real(qp) :: nq(3), a2(3), an(3), s2, trace, det, k(3, 3), disc
    integer :: i
    nq = real(n, qp)
    nq = nq / sqrt(sum(nq**2))      ! unit to quad precision: r2 - r1 is that sensitive
    a2 = [real(cup%a, qp)**2, real(cup%b, qp)**2, real(cup%c, qp)**2]
    an = a2 * nq
    s2 = sum(nq * an)
    k = -spread(an, 2, 3) * spread(an, 1, 3) / s2
    do i = 1, 3
      k(i, i) = k(i, i) + a2(i)
    end do
    k = k / sqrt(s2)
    trace = k(1,1) + k(2,2) + k(3,3)
    det = a2(1) * a2(2) * a2(3) / s2**2
    disc = sqrt(max(0.0_qp, trace**2 - 4 * det))
    r = real([(trace - disc) / 2, (trace + disc) / 2], wp)
  end function quad_radii
end program test_ellipsoid
