!> The classical Runge-Kutta method: fixed step, order 4 (the source
!> paper's method). The ball's own step is fused (ellroll_ball_steppers).
module ellroll_rk4
  use ellroll_kinds, only: wp, i8
  use ellroll_ode, only: ode_system_t, stage_limit
  use ellroll_integrator, only: integrator_t, max_equations
  implicit none
  private

  public :: rk4_t

  type, extends(integrator_t) :: rk4_t
  contains
    procedure :: step => rk4_step
  end type rk4_t

contains

  subroutine rk4_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(rk4_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: y_new(:)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: k2(max_equations), k3(max_equations), k4(max_equations), stage(max_equations)
    integer :: n
    n = size(y)
    stage(:n) = y + (h/2) * f0
    call sys%rhs(t + h/2, stage(:n), k2(:n))
    self%stage_limit = stage_limit(sys, t + h/2, stage(:n), k2(:n))
    stage(:n) = y + (h/2) * k2(:n)
    call sys%rhs(t + h/2, stage(:n), k3(:n))
    if (self%stage_limit == 0) self%stage_limit = stage_limit(sys, t + h/2, stage(:n), k3(:n))
    stage(:n) = y + h * k3(:n)
    call sys%rhs(t + h, stage(:n), k4(:n))
    if (self%stage_limit == 0) self%stage_limit = stage_limit(sys, t + h, stage(:n), k4(:n))
    y_new = y + (h/6) * (f0 + 2*(k2(:n) + k3(:n)) + k4(:n))
    n_rhs = n_rhs + 3
  end subroutine rk4_step
end module ellroll_rk4
