!> Steps of the integrators on the ball, fused: the same arithmetic as the
!> generic steps (tested against them), but calling the ball's right-hand
!> side directly on fixed-size arrays the compiler keeps in registers: no
!> dynamic dispatch, no array descriptors, sizes known at compile time.
module ellroll_ball_steppers
  use ellroll_kinds, only: wp
  use ellroll_rolling_ball, only: rolling_ball_t, state_size, ball_derivative
  use ellroll_integrators, only: dop853_t, c853, end_stage, max_equations
  implicit none
  private

  public :: rk4_ball_step, dop853_ball_step, dop853_ball_dense

  !> Right-hand-side calls of one DOP853 attempt and of its dense output.
  integer, parameter, public :: dop853_attempt_calls = end_stage - 1, dop853_dense_calls = 3

contains

  !> One classical RK4 step of the ball (generic: rk4_t%step).
  pure subroutine rk4_ball_step(ball, t, y, f0, h, y_new)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(state_size), f0(state_size)
    real(wp), intent(out) :: y_new(state_size)
    real(wp) :: k2(state_size), k3(state_size), k4(state_size), stage(state_size)
    stage = y + (h/2) * f0
    call ball_derivative(ball, t + h/2, stage, k2)
    stage = y + (h/2) * k2
    call ball_derivative(ball, t + h/2, stage, k3)
    stage = y + h * k3
    call ball_derivative(ball, t + h, stage, k4)
    y_new = y + (h/6) * (f0 + 2*(k2 + k3) + k4)
  end subroutine rk4_ball_step

  !> One DOP853 attempt of the ball (generic: dop853_t%step); afterwards
  !> dop%error_norm and dop%k(:, end_stage) = f(t + h, y_new) are set.
  pure subroutine dop853_ball_step(dop, ball, t, y, f0, h, y_new)
    type(dop853_t), intent(inout) :: dop
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(state_size), f0(state_size)
    real(wp), intent(out) :: y_new(state_size)
    real(wp) :: start(max_equations), stage(max_equations)
    integer :: s
    start = 0
    start(:state_size) = y
    dop%k(:state_size, 1) = f0
    do s = 2, end_stage
      call dop%stage_input(s, start, h, stage)
      call ball_derivative(ball, t + c853(s) * h, stage(:state_size), dop%k(:state_size, s))
    end do
    y_new = stage(:state_size)
    call dop%finish_attempt(state_size, t, start, h, stage)
  end subroutine dop853_ball_step

  !> The state at t_old + theta h of the last attempt (generic: dop853_t%dense);
  !> prepared tells whether the dense-output stages were computed now.
  pure subroutine dop853_ball_dense(dop, ball, theta, y, prepared)
    type(dop853_t), intent(inout) :: dop
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(state_size)
    logical, intent(out) :: prepared
    real(wp) :: stage(max_equations)
    integer :: s
    prepared = .not. dop%dense_ready
    if (prepared) then
      do s = end_stage + 1, end_stage + dop853_dense_calls
        call dop%stage_input(s, dop%y_old, dop%h, stage)
        call ball_derivative(ball, dop%t_old + c853(s) * dop%h, stage(:state_size), dop%k(:state_size, s))
      end do
      call dop%build_dense()
    end if
    call dop%dense_value(theta, stage)
    y = stage(:state_size)
  end subroutine dop853_ball_dense
end module ellroll_ball_steppers
