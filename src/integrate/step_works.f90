!> The works of the friction and of the rolling resistance over the step
!> (or piece of step) that an embedded pair has just taken, in either
!> regime and in either model (slip = 'slide' or 'end'): the 4-point
!> Gauss-Legendre rule on the pair's dense output. Over the long steps the
!> pairs take the trapezoidal rule's h^2 error does not fall with the
!> tolerance; this rule, exact to degree 7, has an h^8 error, of dop853's
!> order: on a rolling case whose couple takes 1.29 J in 20 s its error is
!> below dop853's own (1.9e-11 of the work at rtol 1e-10, where the 3-point
!> rule, h^6, leaves 3.4e-10 and splitting each step in two changes nothing).
module ellroll_step_works
  use ellroll_kinds, only: wp, i8
  use ellroll_integrators, only: embedded_pair_t
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, ball_derivative, observe, normalize_normal
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, dissipation, resistance_power
  implicit none
  private

  public :: step_works, gauss_nodes, gauss_weights

  ! the roots of P_4 on [-1, 1], +-sqrt(3/7 -+ 2/7 sqrt(6/5)), and their
  ! weights (18 +- sqrt(30)) / 36, mapped onto [0, 1]
  real(wp), parameter :: inner = 0.33998104358485626480_wp, outer = 0.86113631159405257522_wp
  real(wp), parameter :: gauss_nodes(4) = 0.5_wp + 0.5_wp * [-outer, -inner, inner, outer]
  real(wp), parameter :: gauss_weights(4) = [0.34785484513745385737_wp, 0.65214515486254614263_wp, &
                                             0.65214515486254614263_wp, 0.34785484513745385737_wp] / 2

contains

  !> work(1): the friction's, work(2): the rolling resistance's (both >= 0,
  !> J) over the pair's last step, of size h from t: sliding where sb is
  !> given (its state), else rolling (ball, in the mode of the step:
  !> begin_step; the friction's work 0); n_rhs counts the RHS calls. h may
  !> be the first part of the last step only.
  !> fresh: the sliding state at each node from a step of the pair from
  !> the last step's start, not from its dense output. A step that ends
  !> where the slip stops has stages there, at u near 0, where the friction's
  !> direction -u / |u| is round-off: the step's end does not take them
  !> (their weights are 0), its interpolant does (on a flat plate's stop,
  !> vern9 at rtol 1e-12: 0.66 % too much work over that step).
  subroutine step_works(pair, ball, t, h, work, n_rhs, sb, fresh)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, h
    real(wp), intent(out) :: work(2)
    integer(i8), intent(inout) :: n_rhs
    type(sliding_ball_t), intent(in), optional :: sb
    logical, intent(in), optional :: fresh
    real(wp) :: s(slide_state_size), y(state_size), f(state_size), power(2), at, theta(4)
    type(observation_t) :: obs
    class(embedded_pair_t), allocatable :: stepper
    integer :: i
    work = 0
    theta = (h / pair%h) * gauss_nodes
    if (present(fresh) .and. present(sb)) then
      if (fresh) allocate (stepper, source=pair)      ! (the pair keeps its last step)
    end if
    do i = 1, size(gauss_nodes)
      at = t + gauss_nodes(i) * h
      if (allocated(stepper)) then
        call stepper%step(sb, pair%t_old, pair%y_old(:slide_state_size), pair%k(:slide_state_size, 1), &
                          theta(i) * pair%h, s, n_rhs)
        power = dissipation(sb, at, s)
      else if (present(sb)) then
        call pair%dense(sb, theta(i), s, n_rhs)
        power = dissipation(sb, at, s)
      else
        call pair%dense(ball, theta(i), y, n_rhs)
        call normalize_normal(y)
        call ball_derivative(ball, at, y, f)
        call observe(ball, at, y, f, obs)
        power = [0.0_wp, -resistance_power(ball, obs%normal, obs%omega, obs%reaction_normal)]
      end if
      work = work + gauss_weights(i) * power
    end do
    n_rhs = n_rhs + size(gauss_nodes)
    work = h * work
  end subroutine step_works
end module ellroll_step_works
