!> Observed order of convergence of RK4: on the harmonic oscillator (exact
!> solution) and on the paper's case (against a much finer run).
module oscillator
  use ellroll_kinds, only: wp
  use ellroll_ode, only: ode_system_t
  implicit none
  private
  public :: oscillator_t

  !> y'' = -y as a first-order system: exact solution cos t.
  type, extends(ode_system_t) :: oscillator_t
  contains
    procedure :: rhs => oscillator_rhs
  end type oscillator_t

contains

  pure subroutine oscillator_rhs(self, t, y, dydt)
    class(oscillator_t), intent(in) :: self
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(:)
    real(wp), intent(out) :: dydt(:)
    dydt = [y(2), -y(1)]
  end subroutine oscillator_rhs
end module oscillator

program test_integrators
  use ellroll_kinds, only: wp, i8
  use oscillator, only: oscillator_t
  use ellroll_integrators, only: integrator_t, new_integrator
  use ellroll_errors, only: error_t
  use ellroll_cases, only: case_t, field_contact, field_omega
  use ellroll_results, only: case_result_t
  use fixtures, only: paper_case, run_case
  use testing
  implicit none

  class(integrator_t), allocatable :: rk4
  type(error_t) :: err
  real(wp) :: errors(4), dts(4), reference(6)
  type(case_result_t) :: res
  integer :: k

  call new_integrator('rk4', rk4, err)
  call check(.not. err%failed(), 'rk4 exists')
  call check(rk4%order() == 4 .and. rk4%name() == 'rk4' .and. rk4%kind() == 'fixed', 'rk4 describes itself')

  dts = [0.1_wp, 0.05_wp, 0.025_wp, 0.0125_wp]
  do k = 1, 4
    errors(k) = oscillator_error(dts(k))
  end do
  do k = 1, 3
    call check_close(log(errors(k) / errors(k+1)) / log(2.0_wp), 4.0_wp, 0.05_wp, &
                     'RK4 order on the harmonic oscillator')
  end do

  ! Paper case to t = 2 s: contact point and omega at the end against dt = 1e-4.
  res = run_case(paper_case(1.0e-4_wp, 2.0_wp), 20000)
  reference = [res%fields(field_contact)%values(:, 2), res%fields(field_omega)%values(:, 2)]
  dts = [0.01_wp, 0.005_wp, 0.0025_wp, 0.00125_wp]
  do k = 1, 4
    res = run_case(paper_case(dts(k), 2.0_wp), nint(2 / dts(k)))
    errors(k) = maxval(abs([res%fields(field_contact)%values(:, 2) * 20, &
                            res%fields(field_omega)%values(:, 2) / 20] - &
                           [reference(1:3) * 20, reference(4:6) / 20]))
  end do
  do k = 1, 3
    call check_close(log(errors(k) / errors(k+1)) / log(2.0_wp), 4.0_wp, 0.05_wp, &
                     'RK4 order on the paper case')
  end do
  call finish('test_integrators')

contains

  real(wp) function oscillator_error(dt)
    real(wp), intent(in) :: dt
    type(oscillator_t) :: osc
    real(wp) :: y(2), f(2), y_new(2), t
    integer(i8) :: n_rhs
    integer :: step
    y = [1.0_wp, 0.0_wp]
    t = 0
    n_rhs = 0
    do step = 1, nint(10 / dt)
      call osc%rhs(t, y, f)
      call rk4%step(osc, t, y, f, dt, y_new, n_rhs)
      y = y_new
      t = step * dt
    end do
    oscillator_error = norm2(y - [cos(t), -sin(t)])
  end function oscillator_error
end program test_integrators
