!> What an integrator sees of a model: a right-hand side and an optional
!> projection back onto the model's manifold after each step.
module ellroll_ode
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: ode_system_t

  type, abstract :: ode_system_t
  contains
    procedure(rhs_interface), deferred :: rhs
    procedure :: project => no_projection
  end type ode_system_t

  abstract interface
    pure subroutine rhs_interface(self, t, y, dydt)
      import :: ode_system_t, wp
      class(ode_system_t), intent(in) :: self
      real(wp), intent(in) :: t
      real(wp), intent(in) :: y(:)
      real(wp), intent(out) :: dydt(:)
    end subroutine rhs_interface
  end interface

contains

  pure subroutine no_projection(self, y)
    class(ode_system_t), intent(in) :: self
    real(wp), intent(inout) :: y(:)
  end subroutine no_projection
end module ellroll_ode
