!> What an integrator sees of a model: a right-hand side, an optional
!> projection back onto the model's manifold after each step, and an
!> optional check of the states a step evaluates the model at (its stages):
!> 0 where the model holds, else the model's code for the limit met.
module ellroll_ode
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: ode_system_t

  !> The code of a step whose implicit equations had no solution near its
  !> start: the method cannot continue there.
  integer, parameter, public :: no_step_solution = -1

  type, abstract :: ode_system_t
  contains
    procedure(rhs_interface), deferred :: rhs
    procedure :: project => no_projection
    procedure :: stage_status => holds_everywhere
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

  pure integer function holds_everywhere(self, t, y, dydt) result(status)
    class(ode_system_t), intent(in) :: self
    real(wp), intent(in) :: t, y(:), dydt(:)
    status = 0
  end function holds_everywhere
end module ellroll_ode
