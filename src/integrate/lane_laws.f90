!> The couple of rolling resistance in a batch's fixed steps: each lane's
!> mode for a step (lanes_rolling_mode), the law of its couple where its
!> direction turns faster than the step (choose_rolling_law), and the
!> derivative at the end of a step taken in another law (exact_end), with
!> the one-case code on the lanes that need it, so that a lane computes
!> bitwise what its case computes alone.
module ellroll_lane_laws
  use ellroll_kinds, only: wp
  use ellroll_rolling_ball, only: state_size, law_exact
  use ellroll_ball_lanes, only: lanes, ball_lanes_t, lanes_rolling_mode, lanes_may_stiffen
  use ellroll_case_run, only: run_state_t
  use ellroll_results, only: case_result_t
  use ellroll_fixed_step_run, only: choose_law, exact_end
  implicit none
  private

  public :: choose_lane_laws, exact_lane_ends

contains

  !> Each lane's mode and law for a step h from (t, y), derivative f there
  !> (base: the cups' accelerations at t); f_start: f, with the rows of the
  !> active lanes whose law is not law_exact evaluated in it (choose_law).
  subroutine choose_lane_laws(balls, run, active, y, f, t, h, base, f_start, results)
    type(ball_lanes_t), intent(inout) :: balls
    type(run_state_t), intent(inout) :: run(:)
    logical, intent(in) :: active(lanes)
    real(wp), dimension(lanes, state_size), intent(in) :: y, f
    real(wp), intent(in) :: t(lanes), h(lanes), base(lanes, 3)
    real(wp), intent(out) :: f_start(lanes, state_size)
    type(case_result_t), intent(inout) :: results(:)
    real(wp) :: y_lane(state_size), f_lane(state_size)
    logical :: stiff(lanes)
    integer :: l
    f_start = f
    call lanes_rolling_mode(balls, y)
    stiff = lanes_may_stiffen(balls, y, f, h, base) .and. active
    if (.not. any(stiff)) return
    do l = 1, size(run)
      if (.not. stiff(l)) cycle
      y_lane = y(l, :)
      f_lane = f(l, :)
      call run(l)%ball%begin_step(y_lane)
      call choose_law(run(l), t(l), y_lane, h(l), f_lane, results(l)%n_rhs)
      balls%law(l) = real(run(l)%ball%rolling_law, wp)
      balls%law_step(l) = run(l)%ball%law_step
      f_start(l, :) = f_lane
      run(l)%ball%rolling_law = law_exact
    end do
  end subroutine choose_lane_laws

  !> The lanes (ends) whose step to (t, y) was taken in another law than
  !> law_exact: their derivative f there in law_exact (exact_end); every
  !> lane's law back to law_exact.
  subroutine exact_lane_ends(balls, run, ends, t, y, f, results)
    type(ball_lanes_t), intent(inout) :: balls
    type(run_state_t), intent(in) :: run(:)
    logical, intent(in) :: ends(lanes)
    real(wp), intent(in) :: t(lanes), y(lanes, state_size)
    real(wp), intent(inout) :: f(lanes, state_size)
    type(case_result_t), intent(inout) :: results(:)
    real(wp) :: y_lane(state_size), f_lane(state_size)
    integer :: l
    do l = 1, size(run)
      if (.not. (ends(l) .and. balls%law(l) > 0)) cycle
      y_lane = y(l, :)
      call exact_end(run(l), t(l), y_lane, f_lane, results(l)%n_rhs)
      f(l, :) = f_lane
    end do
    balls%law = 0
  end subroutine exact_lane_ends
end module ellroll_lane_laws
