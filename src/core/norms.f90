!> Euclidean norms of 2- and 3-vectors that stay accurate where the squares
!> of the components fall below the normal range (a motion of 1e-160 m, the
!> forces on a ball of weight 1e-300 N). Where the sum of squares is at
!> least 2^-960 it is sqrt of that sum, the expression of every normal-size
!> case (the same contraction into fused multiply-adds); below, the components are scaled by 2^600
!> first and the root by 2^-600 after (both exact), so the root keeps all
!> its digits down to the subnormal components themselves. Elemental and
!> branch-free (merge of values), so that the batch's lane loops vectorize.
module ellroll_norms
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: norm_of, small_sum, norm_up, norm_down

  interface norm_of
    module procedure norm_of_2, norm_of_3
  end interface norm_of

  !> below it a square may have lost digits to underflow (the components
  !> are then below 2^-480: scaled, their squares stay below 2^240)
  real(wp), parameter :: small_sum = scale(1.0_wp, -960)
  real(wp), parameter :: norm_up = scale(1.0_wp, 600), norm_down = scale(1.0_wp, -600)

contains

  elemental real(wp) function norm_of_2(x, y) result(norm)
    real(wp), intent(in) :: x, y
    real(wp) :: sum, factor
    logical :: small
    sum = x**2 + y**2
    small = sum < small_sum
    factor = merge(norm_up, 1.0_wp, small)
    norm = merge(sqrt((factor * x)**2 + (factor * y)**2) * norm_down, sqrt(sum), small)
  end function norm_of_2

  elemental real(wp) function norm_of_3(x, y, z) result(norm)
    real(wp), intent(in) :: x, y, z
    real(wp) :: sum, factor
    logical :: small
    sum = x**2 + y**2 + z**2
    small = sum < small_sum
    factor = merge(norm_up, 1.0_wp, small)
    norm = merge(sqrt((factor * x)**2 + (factor * y)**2 + (factor * z)**2) * norm_down, sqrt(sum), small)
  end function norm_of_3
end module ellroll_norms
