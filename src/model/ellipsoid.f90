!> The fixed cup: the lower half of the triaxial ellipsoid
!>     (x/a)^2 + (y/b)^2 + ((z - c)/c)^2 = 1,   z < c,
!> whose lowest point is the origin. Everything is expressed through the
!> inward unit normal n (from the contact point towards the ball centre):
!> the inverse Gauss map p(n) = (0,0,c) - A n / s, A = diag(a^2,b^2,c^2),
!> s = sqrt(n.A n), lands on the surface for every n, so a state built on n
!> cannot leave the surface.
module ellroll_ellipsoid
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: ellipsoid_t, new_ellipsoid
  public :: contact_from_normal, contact_point, normal_from_contact, surface_residual
  public :: principal_radii, bottom_radii

  type :: ellipsoid_t
    real(wp) :: a = 1, b = 1, c = 1
    real(wp) :: axes2(3) = 1          !< (a^2, b^2, c^2): the diagonal of A
    real(wp) :: det_axes2 = 1         !< a^2 b^2 c^2
    real(wp) :: excess2(3) = 0        !< A - c^2 I, computed without cancellation
    real(wp) :: inv_axes(3) = 1       !< (1/a, 1/b, 1/c)
  end type ellipsoid_t

contains

  pure function new_ellipsoid(a, b, c) result(cup)
    real(wp), intent(in) :: a, b, c
    type(ellipsoid_t) :: cup
    cup%a = a; cup%b = b; cup%c = c
    cup%axes2 = [a*a, b*b, c*c]
    cup%det_axes2 = cup%axes2(1) * cup%axes2(2) * cup%axes2(3)
    cup%excess2 = [(a - c)*(a + c), (b - c)*(b + c), 0.0_wp]
    cup%inv_axes = 1 / [a, b, c]
  end function new_ellipsoid

  !> Contact point for a unit normal n with n_z > 0 (the lower half).
  !> The height is written so that it keeps full relative precision near the
  !> bottom: z = c (a^2 nx^2 + b^2 ny^2) / (s (s + c nz)).
  pure function contact_from_normal(cup, n) result(p)
    type(ellipsoid_t), intent(in) :: cup
    real(wp), intent(in) :: n(3)
    real(wp) :: p(3)
    real(wp) :: inv_s
    call contact_point(cup, n, p, inv_s)
  end function contact_from_normal

  !> The contact point p with unit normal n and 1/s, s = sqrt(n . A n) (the
  !> radius operator K = (A - (An)(An)^T / s^2) / s needs it too). p is
  !> homogeneous of degree 0 in n: any positive multiple of n gives it.
  pure subroutine contact_point(cup, n, p, inv_s)
    type(ellipsoid_t), intent(in) :: cup
    real(wp), intent(in) :: n(3)
    real(wp), intent(out) :: p(3), inv_s
    real(wp) :: horizontal, s
    horizontal = cup%axes2(1)*n(1)**2 + cup%axes2(2)*n(2)**2
    s = sqrt(horizontal + cup%axes2(3)*n(3)**2)
    inv_s = 1 / s
    p(1) = -cup%axes2(1) * n(1) * inv_s
    p(2) = -cup%axes2(2) * n(2) * inv_s
    if (n(3) > 0) then
      p(3) = cup%c * horizontal / (s * (s + cup%c * n(3)))
    else
      p(3) = cup%c - cup%axes2(3) * n(3) * inv_s
    end if
  end subroutine contact_point

  !> Inward unit normal at the point of the lower half above (x, y).
  !> Requires (x/a)^2 + (y/b)^2 < 1.
  pure function normal_from_contact(cup, x, y) result(n)
    type(ellipsoid_t), intent(in) :: cup
    real(wp), intent(in) :: x, y
    real(wp) :: n(3)
    real(wp) :: q(3)
    ! q = grad of the implicit surface / 2; (z - c)/c^2 = -sqrt(1 - s)/c exactly.
    q = [x / cup%axes2(1), y / cup%axes2(2), &
         -sqrt(max(0.0_wp, 1 - (x/cup%a)**2 - (y/cup%b)**2)) / cup%c]
    n = -q / norm2(q)
  end function normal_from_contact

  !> |(x/a)^2 + (y/b)^2 + ((z - c)/c)^2 - 1|: how far p is off the surface.
  pure real(wp) function surface_residual(cup, p)
    type(ellipsoid_t), intent(in) :: cup
    real(wp), intent(in) :: p(3)
    surface_residual = abs((p(1) * cup%inv_axes(1))**2 + (p(2) * cup%inv_axes(2))**2 &
                           + ((p(3) - cup%c) * cup%inv_axes(3))**2 - 1)
  end function surface_residual

  !> Principal radii of curvature (smallest first) at the point with unit
  !> normal n. On the tangent plane, s K = c^2 I + dev with (e = the
  !> diagonal of A - c^2 I, w = sum e_i n_i^2)
  !>   dev_ij = delta_ij e_i - n_i n_j (e_i + e_j - w) - n_i n_j (e_i - w)(e_j - w) / s^2,
  !> and r2 - r1 = sqrt(2 |dev|^2 - (tr dev)^2) / s comes from the small
  !> matrix dev: a nearly spherical cup loses no digits to cancellation.
  pure function principal_radii(cup, n) result(r)
    type(ellipsoid_t), intent(in) :: cup
    real(wp), intent(in) :: n(3)
    real(wp) :: r(2)
    real(wp) :: s2, w, u(3), dev, frobenius2, trace_dev, disc, r_max, sum_k
    integer :: i, j
    s2 = dot_product(n, cup%axes2 * n)
    w = dot_product(cup%excess2, n * n)
    u = cup%excess2 - w
    frobenius2 = 0
    trace_dev = 0
    do j = 1, 3
      do i = 1, 3
        dev = -n(i) * n(j) * (cup%excess2(i) + cup%excess2(j) - w + u(i) * u(j) / s2)
        if (i == j) then
          dev = dev + cup%excess2(i)
          trace_dev = trace_dev + dev
        end if
        frobenius2 = frobenius2 + dev * dev
      end do
    end do
    ! the sum of the two eigenvalues of s K as a sum of positive terms,
    ! sum_j n_j^2 a_j^2 (sum_{i /= j} a_i^2) / s^2 (= 2 c^2 + tr dev, which
    ! cancels to nothing in a cup far deeper than wide, c >> a, b)
    sum_k = (n(1)**2 * cup%axes2(1) * (cup%axes2(2) + cup%axes2(3)) &
             + n(2)**2 * cup%axes2(2) * (cup%axes2(1) + cup%axes2(3)) &
             + n(3)**2 * cup%axes2(3) * (cup%axes2(1) + cup%axes2(2))) / s2
    ! their difference squared from dev where dev is small against the sum (a
    ! nearly spherical cup); else from the sum and the product det(A) / s^2
    if (frobenius2 <= sum_k**2) then
      disc = max(0.0_wp, 2 * frobenius2 - trace_dev**2)
    else
      disc = max(0.0_wp, sum_k**2 - 4 * (cup%det_axes2 / s2))
    end if
    r_max = (sum_k + sqrt(min(disc, sum_k**2))) / (2 * sqrt(s2))
    r(2) = r_max
    r(1) = (cup%det_axes2 / (s2 * s2)) / r_max
  end function principal_radii

  !> Principal radii at the bottom in the x-z and y-z planes: a^2/c, b^2/c.
  pure function bottom_radii(cup) result(r)
    type(ellipsoid_t), intent(in) :: cup
    real(wp) :: r(2)
    r = [cup%axes2(1), cup%axes2(2)] / cup%c
  end function bottom_radii
end module ellroll_ellipsoid
