!> Exact comparisons of reals, where exact is what is meant: a value never
!> computed (a default, a sentinel), a division by zero to avoid, a value
!> read back bit for bit. Written as orderings, so that the compiler's
!> check on == and /= between reals (-Wcompare-reals), which finds
!> comparisons that want a tolerance, stays on for every other place.
module ellroll_exact
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: is_zero, equals

contains

  !> x is +0 or -0 (NaN is not).
  elemental logical function is_zero(x)
    real(wp), intent(in) :: x
    is_zero = abs(x) <= 0
  end function is_zero

  !> a and b are the same number (+0 equals -0; NaN equals nothing).
  elemental logical function equals(a, b)
    real(wp), intent(in) :: a, b
    equals = a <= b .and. a >= b
  end function equals
end module ellroll_exact
