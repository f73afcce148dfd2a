!> The quantities of the ball's state at each accepted step end that the
!> summary's figures accumulate (ellroll_figures): their names, named indices
!> and how the figures take them. The one-case path takes them from an
!> observation (ellroll_case_run), the batch's lanes_observe computes them in
!> the same arithmetic, into one column each.
module ellroll_quantities
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: quantity_t, quantities, quantity_count, peak_clearance

  ! The norms are taken with norm_of (ellroll_norms), accurate however small
  ! the motion. The horizontal force is kept in units of 2^exponent(m) N, m
  ! the ball's mass (a power of two: the same digits as in N), so that its
  ! norm and the friction ratio are formed without underflow for any mass.

  !> The peaks of a case that ends at a model limit are taken over the step
  !> ends where both principal radii of curvature of the cup at the contact
  !> exceed R (1 + peak_clearance): the approach to no_fit (r_min -> R) is
  !> singular, its forces grow as 1 / (r_min - R) to a size set by
  !> fit_margin alone.
  real(wp), parameter :: peak_clearance = 0.05_wp

  type :: quantity_t
    character(len=24) :: name
    logical :: change = .false.    !< the figures take its change from its value at t = 0, |q - q(0)|
  end type quantity_t

  type(quantity_t), parameter :: quantities(*) = [ &
      quantity_t('displacement'), &                          ! |C_horizontal|, cup frame, m
      quantity_t('horizontal_force_scaled'), &               ! |F_horizontal| of the cup on the ball / 2^exponent(m)
      quantity_t('reaction_normal'), &                       ! normal force, N
      quantity_t('friction_needed'), &                       ! |F_t| / N
      quantity_t('energy', change=.true.), &                 ! J
      quantity_t('surface_residual'), &                      ! of the contact point
      quantity_t('fit_clearance')]                           ! > 0: both principal radii above R (1 + peak_clearance)
  integer, parameter :: quantity_count = size(quantities)
  integer, parameter, public :: q_displacement = findloc(quantities%name, 'displacement', dim=1), &
      q_horizontal_force_scaled = findloc(quantities%name, 'horizontal_force_scaled', dim=1), &
      q_reaction_normal = findloc(quantities%name, 'reaction_normal', dim=1), &
      q_friction_needed = findloc(quantities%name, 'friction_needed', dim=1), &
      q_energy = findloc(quantities%name, 'energy', dim=1), &
      q_surface_residual = findloc(quantities%name, 'surface_residual', dim=1), &
      q_fit_clearance = findloc(quantities%name, 'fit_clearance', dim=1)
end module ellroll_quantities
