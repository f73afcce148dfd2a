!> The works of the friction and of the rolling resistance over the step
!> (or piece of step) that an embedded pair has just taken, in either
!> regime: the 3-point Gauss-Legendre rule on the pair's dense output (exact
!> to degree 5, its error far below the pair's own over the long steps the
!> pair takes, where the trapezoidal rule's h^2 error does not fall with the
!> tolerance).
module ellroll_step_works
  use ellroll_kinds, only: wp, i8
  use ellroll_integrators, only: embedded_pair_t
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, ball_derivative, observe, normalize_normal
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, dissipation, resistance_power
  implicit none
  private

  public :: step_works

contains

  !> work(1): the friction's, work(2): the rolling resistance's (both >= 0,
  !> J) over the pair's last step, of size h from t, sliding (sb) or rolling
  !> (ball, in the mode of the step: begin_step); n_rhs counts the RHS calls.
  subroutine step_works(pair, ball, sb, sliding, t, h, work, n_rhs)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    type(sliding_ball_t), intent(in) :: sb
    logical, intent(in) :: sliding
    real(wp), intent(in) :: t, h
    real(wp), intent(out) :: work(2)
    integer(i8), intent(inout) :: n_rhs
    real(wp), parameter :: offset = 0.3872983346207416885_wp      ! sqrt(15) / 10
    real(wp), parameter :: nodes(3) = [0.5_wp - offset, 0.5_wp, 0.5_wp + offset]
    real(wp), parameter :: weights(3) = [5.0_wp, 8.0_wp, 5.0_wp] / 18
    real(wp) :: s(slide_state_size), y(state_size), f(state_size), power(2), at
    type(observation_t) :: obs
    integer :: i
    work = 0
    do i = 1, 3
      at = t + nodes(i) * h
      if (sliding) then
        call pair%dense(sb, nodes(i), s, n_rhs)
        power = dissipation(sb, at, s)
      else
        call pair%dense(ball, nodes(i), y, n_rhs)
        call normalize_normal(y)
        call ball_derivative(ball, at, y, f)
        call observe(ball, at, y, f, obs)
        power = [0.0_wp, -resistance_power(ball, obs%normal, obs%omega, obs%reaction_normal)]
      end if
      work = work + weights(i) * power
    end do
    n_rhs = n_rhs + 3
    work = h * work
  end subroutine step_works
end module ellroll_step_works
