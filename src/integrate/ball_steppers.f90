!> Steps of the integrators on the ball, fused: the same arithmetic as the
!> generic steps (tested against them), but calling the ball's right-hand
!> side directly on fixed-size arrays the compiler keeps in registers: no
!> dynamic dispatch of the right-hand side, no array descriptors, sizes
!> known at compile time.
!> The lanes_ steps advance several balls at once, one per SIMD lane
!> (ellroll_ball_lanes), each lane with its own step size.
module ellroll_ball_steppers
  use ellroll_kinds, only: wp, i8
  use ellroll_rolling_ball, only: rolling_ball_t, state_size, ball_derivative, stage_status
  use ellroll_excitation, only: excitation_none, base_acceleration
  use ellroll_integrator, only: integrator_t
  use ellroll_rk4, only: rk4_t
  use ellroll_embedded_pair, only: embedded_pair_t, width, max_pair_stages, stage_clamp
  use ellroll_ball_lanes, only: lanes, ball_lanes_t, lane_outputs_t, lanes_derivative, lanes_observe
  use ellroll_excitation_lanes, only: excitation_lanes_t
  use ellroll_status, only: status_completed
  implicit none
  private

  public :: ball_fixed_step, rk4_ball_step, pair_ball_step, pair_ball_dense, lanes_fixed_step, lanes_rk4_step, &
            lanes_pair_attempt, lanes_pair_dense_stages

contains

  !> One step of a fixed-step method on the ball from (t, y, f): its fused
  !> step where it has one (RK4), else its own; stage_limit as
  !> rk4_ball_step's, n_rhs counts its RHS calls.
  subroutine ball_fixed_step(integrator, ball, t, y, f, h, y_new, stage_limit, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    real(wp), intent(out) :: y_new(state_size)
    integer, intent(out) :: stage_limit
    integer(i8), intent(inout) :: n_rhs
    select type (integrator)
    type is (rk4_t)
      call rk4_ball_step(ball, t, y, f, h, y_new, stage_limit)
      n_rhs = n_rhs + 3
    class default
      call integrator%step(ball, t, y, f, h, y_new, n_rhs)
      stage_limit = integrator%stage_limit
    end select
  end subroutine ball_fixed_step

  !> One step of a fixed-step method that batches (its row of the method
  !> table) across lanes: RK4's lanes_rk4_step.
  pure subroutine lanes_fixed_step(integrator, p, y, f0, h, y_new, f_new, inside, base_half, base_end)
    class(integrator_t), intent(in) :: integrator
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size), f0(lanes, state_size), h(lanes)
    real(wp), intent(out) :: y_new(lanes, state_size), f_new(lanes, state_size)
    logical, intent(out), optional :: inside(lanes)
    real(wp), dimension(lanes, 3), intent(in), optional :: base_half, base_end
    select type (integrator)
    type is (rk4_t)
      call lanes_rk4_step(p, y, f0, h, y_new, f_new, inside, base_half, base_end)
    class default
      error stop 'lanes_fixed_step: a method marked as batching has no step across lanes'
    end select
  end subroutine lanes_fixed_step

  !> One classical RK4 step of the ball (generic: rk4_t%step); stage_limit
  !> is 0 when the model held at every stage, else the status of the first
  !> limit met at one (stage_status).
  pure subroutine rk4_ball_step(ball, t, y, f0, h, y_new, stage_limit)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(state_size), f0(state_size)
    real(wp), intent(out) :: y_new(state_size)
    integer, intent(out) :: stage_limit
    real(wp) :: k2(state_size), k3(state_size), k4(state_size), stage(state_size), base_half(3), base_end(3)
    logical :: fits, reaction_limited
    reaction_limited = ball%reaction_limited()
    base_half = 0
    base_end = 0
    if (ball%excitation%kind /= excitation_none) then      ! the cup's acceleration, once per time
      base_half = base_acceleration(ball%excitation, t + h/2)
      base_end = base_acceleration(ball%excitation, t + h)
    end if
    stage = y + (h/2) * f0
    call ball_derivative(ball, t + h/2, stage, k2, fits, base_half)
    stage_limit = 0
    if (.not. fits .or. reaction_limited) stage_limit = stage_status(ball, t + h/2, stage, k2, fits, base_half)
    stage = y + (h/2) * k2
    call ball_derivative(ball, t + h/2, stage, k3, fits, base_half)
    if (stage_limit == 0 .and. (.not. fits .or. reaction_limited)) &
      stage_limit = stage_status(ball, t + h/2, stage, k3, fits, base_half)
    stage = y + h * k3
    call ball_derivative(ball, t + h, stage, k4, fits, base_end)
    if (stage_limit == 0 .and. (.not. fits .or. reaction_limited)) &
      stage_limit = stage_status(ball, t + h, stage, k4, fits, base_end)
    y_new = y + (h/6) * (f0 + 2*(k2 + k3) + k4)
  end subroutine rk4_ball_step

  !> One attempt of an embedded pair on the ball (generic: pair%step);
  !> afterwards pair%error_norm and pair%k(:, pair%end_stage()) = f(t + h,
  !> y_new) are set; its stage inputs are held within +-stage_clamp.
  pure subroutine pair_ball_step(pair, ball, t, y, f0, h, y_new)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(state_size), f0(state_size)
    real(wp), intent(out) :: y_new(state_size)
    real(wp) :: start(width), stage(width), steps(width)
    integer :: s
    start = 0
    start(:state_size) = y
    steps = h
    pair%k(:state_size, 1) = f0
    do s = 2, pair%end_stage()                ! the last stage input is y_new
      call pair%stage_columns(s, 1, pair%k, start, steps, stage)
      if (.not. all(abs(stage) <= stage_clamp)) stage = min(max(stage, -stage_clamp), stage_clamp)
      call ball_derivative(ball, t + pair%node(s) * h, stage(:state_size), pair%k(:state_size, s))
    end do
    y_new = stage(:state_size)
    call pair%finish_attempt(state_size, t, start, h, stage)
  end subroutine pair_ball_step

  !> The state at t_old + theta h of the last attempt (generic: pair%dense);
  !> prepared tells whether the dense-output stages were computed now.
  pure subroutine pair_ball_dense(pair, ball, theta, y, prepared)
    class(embedded_pair_t), intent(inout) :: pair
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(state_size)
    logical, intent(out) :: prepared
    real(wp) :: stage(width), steps(width)
    integer :: s
    prepared = .not. pair%dense_ready
    if (prepared) then
      if (.not. pair%dense_stages_ready) then
        steps = pair%h
        do s = pair%end_stage() + 1, pair%end_stage() + pair%dense_calls()
          call pair%stage_columns(s, 1, pair%k, pair%y_old, steps, stage)
          call ball_derivative(ball, pair%t_old + pair%node(s) * pair%h, stage(:state_size), pair%k(:state_size, s))
        end do
      end if
      call pair%build_dense()
    end if
    call pair%dense_value(theta, stage)
    y = stage(:state_size)
  end subroutine pair_ball_dense
  !> One classical RK4 step of every lane (rk4_ball_step), the new normal
  !> projected to unit length, and f there; inside, when asked for, tells
  !> the lanes whose every stage lies where the equations hold (a lane
  !> without is looked at with rk4_ball_step). base_half and base_end, given
  !> together where some lane's cup moves: the cups' accelerations at each
  !> lane's t + h/2 and t + h (a moving cup's stages are checked for the
  !> reaction's limits, as rk4_ball_step's).
  pure subroutine lanes_rk4_step(p, y, f0, h, y_new, f_new, inside, base_half, base_end)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size), f0(lanes, state_size), h(lanes)
    real(wp), intent(out) :: y_new(lanes, state_size), f_new(lanes, state_size)
    logical, intent(out), optional :: inside(lanes)
    real(wp), dimension(lanes, 3), intent(in), optional :: base_half, base_end
    logical :: reaction_limited
    real(wp) :: margin(lanes)
    real(wp) :: k2(lanes, state_size), k3(lanes, state_size), k4(lanes, state_size), stage(lanes, state_size)
    real(wp) :: length
    integer :: i, l, n
    reaction_limited = .false.
    ! (a moving cup's reaction is checked with the stage's derivative: lanes_derivative)
    if (present(inside)) reaction_limited = any(p%mu > 0 .and. .not. p%moves > 0)
    margin = 1
    ! the lanes the kernels compute only (1 to width): what lanes_derivative
    ! stores a lane at a time is read back as such (a whole-vector load of
    ! values stored in pieces stalls), and a lone case's idle lanes cost
    ! nothing; the lanes past the width are left undefined in y_new and f_new
    n = p%width
    do i = 1, state_size
      stage(:n, i) = y(:n, i) + (h(:n)/2) * f0(:n, i)
    end do
    call lanes_derivative(p, stage, k2, margin, base_half)
    if (reaction_limited) call lanes_check_reaction(p, stage, k2, margin, base_half)
    do i = 1, state_size
      stage(:n, i) = y(:n, i) + (h(:n)/2) * k2(:n, i)
    end do
    call lanes_derivative(p, stage, k3, margin, base_half)
    if (reaction_limited) call lanes_check_reaction(p, stage, k3, margin, base_half)
    do i = 1, state_size
      stage(:n, i) = y(:n, i) + h(:n) * k3(:n, i)
    end do
    call lanes_derivative(p, stage, k4, margin, base_end)
    if (reaction_limited) call lanes_check_reaction(p, stage, k4, margin, base_end)
    do i = 1, state_size
      y_new(:n, i) = y(:n, i) + (h(:n)/6) * (f0(:n, i) + 2*(k2(:n, i) + k3(:n, i)) + k4(:n, i))
    end do
    do l = 1, n
      length = sqrt(y_new(l, 1) * y_new(l, 1) + y_new(l, 2) * y_new(l, 2) + y_new(l, 3) * y_new(l, 3))
      y_new(l, 1:3) = y_new(l, 1:3) / length
    end do
    call lanes_derivative(p, y_new, f_new, base=base_end)
    if (present(inside)) inside = margin > 0
  end subroutine lanes_rk4_step

  !> A stage's friction limit on a fixed cup in a batch (rk4_ball_step's
  !> stage_status): the stage's whole limit status, as at a step's end;
  !> margin is set to -1 where a limit is met (a lane whose cup moves is
  !> checked by lanes_derivative).
  pure subroutine lanes_check_reaction(p, state, rate, margin, base)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: state(lanes, state_size), rate(lanes, state_size)
    real(wp), intent(inout) :: margin(lanes)
    real(wp), intent(in), optional :: base(lanes, 3)
    type(lane_outputs_t) :: out
    call lanes_observe(p, state, rate, out, base)
    where (.not. p%moves > 0 .and. out%status /= status_completed) margin = -1
  end subroutine lanes_check_reaction

  !> One attempt of the pair of every lane, each lane with its own h
  !> (pair_ball_step across lanes, the same sums in the same order): the
  !> stages k(:, :, 1:end_stage) (the last one f at the new point), the new
  !> point (not projected) and the error norm of the pair's finish_attempt.
  !> exc and t, given together where some lane's cup moves: the lanes'
  !> excitations and the attempts' start times.
  pure subroutine lanes_pair_attempt(pair, p, y, f0, h, rtol, atol, k, y_new, error_norm, exc, t)
    class(embedded_pair_t), intent(in) :: pair
    type(ball_lanes_t), intent(in) :: p
    real(wp), dimension(lanes, state_size), intent(in) :: y, f0
    real(wp), dimension(lanes), intent(in) :: h, rtol, atol
    real(wp), intent(out) :: k(lanes, state_size, max_pair_stages), y_new(lanes, state_size), error_norm(lanes)
    type(excitation_lanes_t), intent(inout), optional :: exc
    real(wp), intent(in), optional :: t(lanes)
    k(:, :, 1) = f0
    call lanes_stages(pair, p, 2, pair%end_stage(), y, h, k, y_new, exc, t)   ! the last stage input is y_new
    call pair%error_norms_across(state_size, k, y, y_new, h, rtol, atol, error_norm)
  end subroutine lanes_pair_attempt

  !> The dense-output stages k(:, :, end_stage + 1:) of every lane's last
  !> attempt from y with step h (pair_ball_dense across lanes).
  pure subroutine lanes_pair_dense_stages(pair, p, y, h, k, exc, t)
    class(embedded_pair_t), intent(in) :: pair
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size), h(lanes)
    real(wp), intent(inout) :: k(lanes, state_size, max_pair_stages)
    type(excitation_lanes_t), intent(inout), optional :: exc
    real(wp), intent(in), optional :: t(lanes)
    real(wp) :: stage(lanes, state_size)
    call lanes_stages(pair, p, pair%end_stage() + 1, pair%end_stage() + pair%dense_calls(), y, h, k, stage, exc, t)
  end subroutine lanes_pair_dense_stages

  !> Stages first to last of the pair of every lane, from y with step h: f
  !> at each stage's input (held within +-stage_clamp) into k; stage: the
  !> last stage's input. The lanes are the pair's columns of `width` values
  !> (ellroll_embedded_pair), one column per component. exc and t: as
  !> lanes_pair_attempt's (each stage's cup acceleration at t + c_s h).
  pure subroutine lanes_stages(pair, p, first, last, y, h, k, stage, exc, t)
    class(embedded_pair_t), intent(in) :: pair
    type(ball_lanes_t), intent(in) :: p
    integer, intent(in) :: first, last
    real(wp), intent(in) :: y(lanes, state_size), h(lanes)
    real(wp), intent(inout) :: k(lanes, state_size, max_pair_stages)
    real(wp), intent(out) :: stage(lanes, state_size)
    type(excitation_lanes_t), intent(inout), optional :: exc
    real(wp), intent(in), optional :: t(lanes)
    real(wp) :: base(lanes, 3)
    integer :: s
    do s = first, last
      call pair%stage_columns(s, state_size, k, y, h, stage)
      stage = min(max(stage, -stage_clamp), stage_clamp)
      if (present(exc) .and. present(t)) then
        call exc%at(t + pair%node(s) * h, base)
        call lanes_derivative(p, stage, k(:, :, s), base=base)
      else
        call lanes_derivative(p, stage, k(:, :, s))
      end if
    end do
  end subroutine lanes_stages
end module ellroll_ball_steppers
