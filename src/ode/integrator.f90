!> What every one-step integrator is (after rklib): a step of a system from
!> (t, y), given f(t, y) by the caller (the previous step's end-point
!> derivative, which the run loop needs anyway for derived outputs). The
!> methods are one module each (ellroll_rk4, ellroll_gauss4, and the
!> embedded pairs on ellroll_embedded_pair); ellroll_integrators is their
!> table.
module ellroll_integrator
  use ellroll_kinds, only: wp, i8
  use ellroll_ode, only: ode_system_t
  implicit none
  private

  public :: integrator_t

  !> Largest system the integrators take: their work arrays are fixed-size
  !> (on the stack), so a step allocates nothing.
  integer, parameter, public :: max_equations = 8

  type, abstract :: integrator_t
    !> fixed-step methods: 0 when the system's model held at every stage of
    !> the last step (ode_system_t%stage_status), else the code of the first
    !> stage where it did not
    integer :: stage_limit = 0
    !> its row of the method table (ellroll_integrators%new_integrator sets
    !> it; 0 for an integrator made otherwise)
    integer :: method = 0
  contains
    procedure(step_interface), deferred :: step
  end type integrator_t

  abstract interface
    !> Advance y(t) by h. f0 = f(t, y) on entry; n_rhs counts new RHS calls.
    subroutine step_interface(self, sys, t, y, f0, h, y_new, n_rhs)
      import :: integrator_t, ode_system_t, wp, i8
      class(integrator_t), intent(inout) :: self
      class(ode_system_t), intent(in) :: sys
      real(wp), intent(in) :: t, h
      real(wp), intent(in) :: y(:), f0(:)
      real(wp), intent(out) :: y_new(:)
      integer(i8), intent(inout) :: n_rhs
    end subroutine step_interface
  end interface
end module ellroll_integrator
