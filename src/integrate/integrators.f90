!> One-step integrators behind one interface. A step receives f(t, y) from
!> the caller (it is the previous step's end-point derivative, which the run
!> loop needs anyway for derived outputs), so RK4 costs 3 new RHS calls.
module ellroll_integrators
  use ellroll_kinds, only: wp, i8
  use ellroll_ode, only: ode_system_t
  use ellroll_errors, only: error_t, set_error, err_input
  implicit none
  private

  public :: integrator_t, rk4_t, new_integrator, method_names

  type, abstract :: integrator_t
  contains
    procedure(step_interface), deferred :: step
    procedure(text_interface), deferred, nopass :: name
    procedure(text_interface), deferred, nopass :: kind
    procedure(order_interface), deferred, nopass :: order
  end type integrator_t

  abstract interface
    !> Advance y(t) by h. f0 = f(t, y) on entry; n_rhs counts new RHS calls.
    pure subroutine step_interface(self, sys, t, y, f0, h, y_new, n_rhs)
      import :: integrator_t, ode_system_t, wp, i8
      class(integrator_t), intent(in) :: self
      class(ode_system_t), intent(in) :: sys
      real(wp), intent(in) :: t, h
      real(wp), intent(in) :: y(:), f0(:)
      real(wp), intent(out) :: y_new(:)
      integer(i8), intent(inout) :: n_rhs
    end subroutine step_interface
    pure function text_interface() result(text)
      character(len=:), allocatable :: text
    end function text_interface
    pure integer function order_interface()
    end function order_interface
  end interface

  !> Classical fourth-order Runge-Kutta, fixed step (the source paper's method).
  type, extends(integrator_t) :: rk4_t
  contains
    procedure :: step => rk4_step
    procedure, nopass :: name => rk4_name
    procedure, nopass :: kind => fixed_kind
    procedure, nopass :: order => rk4_order
  end type rk4_t

  character(len=*), parameter :: method_names = 'rk4'

contains

  subroutine new_integrator(name, integrator, err)
    character(len=*), intent(in) :: name
    class(integrator_t), allocatable, intent(out) :: integrator
    type(error_t), intent(inout) :: err
    select case (name)
    case ('rk4')
      allocate (rk4_t :: integrator)
    case default
      call set_error(err, err_input, "unknown integration method '" // name // &
                     "' (known: " // method_names // ")")
    end select
  end subroutine new_integrator

  pure subroutine rk4_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(rk4_t), intent(in) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: y_new(:)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: k2(size(y)), k3(size(y)), k4(size(y))
    call sys%rhs(t + h/2, y + (h/2) * f0, k2)
    call sys%rhs(t + h/2, y + (h/2) * k2, k3)
    call sys%rhs(t + h, y + h * k3, k4)
    y_new = y + (h/6) * (f0 + 2*(k2 + k3) + k4)
    n_rhs = n_rhs + 3
  end subroutine rk4_step

  pure function rk4_name() result(text)
    character(len=:), allocatable :: text
    text = 'rk4'
  end function rk4_name

  pure function fixed_kind() result(text)
    character(len=:), allocatable :: text
    text = 'fixed'
  end function fixed_kind

  pure integer function rk4_order()
    rk4_order = 4
  end function rk4_order
end module ellroll_integrators
