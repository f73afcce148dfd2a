!> What an integrator sees of a model: a right-hand side, and for a model
!> with limits (limited_system_t) a check of the states a step evaluates
!> the model at (its stages): 0 where the model holds, else the model's
!> code for the limit met.
module ellroll_ode
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: ode_system_t, limited_system_t, stage_limit

  !> The code of a step whose implicit equations had no solution near its
  !> start: the method cannot continue there.
  integer, parameter, public :: no_step_solution = -1

  type, abstract :: ode_system_t
  contains
    procedure(rhs_interface), deferred :: rhs
  end type ode_system_t

  type, abstract, extends(ode_system_t) :: limited_system_t
  contains
    procedure(stage_status_interface), deferred :: stage_status
  end type limited_system_t

  abstract interface
    pure subroutine rhs_interface(self, t, y, dydt)
      import :: ode_system_t, wp
      class(ode_system_t), intent(in) :: self
      real(wp), intent(in) :: t
      real(wp), intent(in) :: y(:)
      real(wp), intent(out) :: dydt(:)
    end subroutine rhs_interface

    pure integer function stage_status_interface(self, t, y, dydt) result(status)
      import :: limited_system_t, wp
      class(limited_system_t), intent(in) :: self
      real(wp), intent(in) :: t, y(:), dydt(:)
    end function stage_status_interface
  end interface

contains

  !> The limit a stage at (t, y) with derivative dydt meets: 0 for none,
  !> and always 0 for a model without limits.
  pure integer function stage_limit(sys, t, y, dydt) result(status)
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, y(:), dydt(:)
    select type (sys)
    class is (limited_system_t)
      status = sys%stage_status(t, y, dydt)
    class default
      status = 0
    end select
  end function stage_limit
end module ellroll_ode
