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

  public :: norm_of, small_sum, norm_up, norm_down, tangential_size, horizontal_force_scaled, in_mass_units, &
      from_mass_units

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

  !> |t| as norm_of takes it (scaled where the squares fall below
  !> small_sum), the normal-size root written as one expression on the
  !> vector's components, as the compiler contracts it into fused
  !> multiply-adds in the one-case path.
  pure real(wp) function tangential_size(t)
    real(wp), intent(in) :: t(3)
    real(wp) :: factor
    tangential_size = sqrt(t(1)**2 + t(2)**2 + t(3)**2)
    if (t(1)**2 + t(2)**2 + t(3)**2 < small_sum) then
      factor = norm_up
      tangential_size = sqrt((factor * t(1))**2 + (factor * t(2))**2 + (factor * t(3))**2) * norm_down
    end if
  end function tangential_size

  !> A force (or any size proportional to the mass m) in units of
  !> 2^exponent(m), the mass's power of two: exact, so that norms and
  !> ratios of forces have the same digits at every ordinary mass, and
  !> neither underflow for a light ball nor overflow for a heavy one.
  elemental real(wp) function in_mass_units(force, mass)
    real(wp), intent(in) :: force, mass
    in_mass_units = scale(force, -exponent(mass))
  end function in_mass_units

  !> A size in units of 2^exponent(m) (in_mass_units) back in its own.
  elemental real(wp) function from_mass_units(value, mass)
    real(wp), intent(in) :: value, mass
    from_mass_units = scale(value, exponent(mass))
  end function from_mass_units

  !> |(F_x, F_y)| / 2^exponent(m) of a force F on a ball of mass m
  !> (observation_t), without the squares of a light ball's forces
  !> underflowing.
  pure real(wp) function horizontal_force_scaled(force, mass)
    real(wp), intent(in) :: force(3), mass
    horizontal_force_scaled = norm_of(in_mass_units(force(1), mass), in_mass_units(force(2), mass))
  end function horizontal_force_scaled
end module ellroll_norms
