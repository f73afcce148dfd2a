!> The sliding state's kinematics (docs/model.md, "Sliding with Coulomb
!> friction"): the centre's velocity and the slip at A of a state y = (n,
!> omega, V_x, V_y), the changes of state between the regimes (a rolling
!> state slid, a slip stopped by the impulse at A: stick), the friction's
!> direction, and the slip's round-off, below which it counts as zero.
module ellroll_slip_state
  use ellroll_kinds, only: wp
  use ellroll_rolling_ball, only: rolling_ball_t, state_size, cross
  implicit none
  private

  public :: slide_state_size, center_velocity, at_sliding_rim, slip_velocity, sliding_from_rolling, &
            rolling_from_sliding, stick, stick_loss, slip_stop_time, friction_direction, resolved_slip, stop_floor, &
            stick_value, stick_level

  integer, parameter :: slide_state_size = 8

  !> The slip counts as stopped where it has fallen to this part of its
  !> value at the start of the piece of step (a stopping impulse takes the
  !> rest: stick). Near the stop the slip's direction turns ever faster
  !> (at a rate proportional to 1 / |u|), so the stop is located on |u|,
  !> which falls at a rate bounded away from zero, not on the direction.
  real(wp), parameter :: stick_level = 1.0e-6_wp

  !> The sliding state reaches the rim where n_z / |n| falls to this level:
  !> V_z = -(n_x V_x + n_y V_y) / n_z is a quotient of two vanishing numbers
  !> there, whose error (that of n_x V_x + n_y V_y over n_z) overflows the
  !> energy and N at n_z -> 0; the rim is still located to about rim_level
  !> times the cup's size over the speed.
  real(wp), parameter :: rim_level = 1.0e-6_wp

contains

  !> The centre's velocity (cup frame) of sliding state y: its horizontal
  !> part from y, its vertical part from V_C . n = 0.
  pure function center_velocity(y) result(v)
    real(wp), intent(in) :: y(slide_state_size)
    real(wp) :: v(3)
    v = [y(7), y(8), -(y(1) * y(7) + y(2) * y(8)) / y(3)]
  end function center_velocity

  !> Whether sliding state y is at the rim (rim_level).
  pure logical function at_sliding_rim(y) result(at_rim)
    real(wp), intent(in) :: y(:)
    at_rim = .not. y(3) > rim_level * norm2(y(1:3))
  end function at_sliding_rim

  !> The slip velocity u = V_C - R omega x n at sliding state y.
  pure function slip_velocity(ball, y) result(u)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(slide_state_size)
    real(wp) :: u(3)
    u = center_velocity(y) - ball%radius * cross(y(4:6), y(1:3)) / norm2(y(1:3))
  end function slip_velocity

  !> The sliding state at rolling state y (u = 0 there).
  pure function sliding_from_rolling(ball, y) result(s)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size)
    real(wp) :: s(slide_state_size), v(3)
    v = ball%radius * cross(y(4:6), y(1:3)) / norm2(y(1:3))
    s(1:6) = y
    s(7:8) = v(1:2)
  end function sliding_from_rolling

  !> The rolling state at sliding state s where the slip has stopped: the
  !> normal and omega kept (V_C is then R omega x n).
  pure function rolling_from_sliding(s) result(y)
    real(wp), intent(in) :: s(slide_state_size)
    real(wp) :: y(state_size)
    y = s(1:6)
  end function rolling_from_sliding

  !> The rolling state where the slip u of sliding state s is stopped by an
  !> impulse P of the cup at A (the stop located to round-off leaves a
  !> slip of that size): m dV_C = P, J d omega = -R n x P and dV_C -
  !> R d omega x n = -u give P = -u / (1/m + R^2/J); the angular momentum
  !> about A is kept, and the energy falls by |u|^2 / (2 (1/m + R^2/J)),
  !> the friction's work in that impulse.
  pure function stick(ball, s) result(y)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: s(slide_state_size)
    real(wp) :: y(state_size), impulse(3), n(3)
    n = s(1:3) / norm2(s(1:3))
    impulse = -slip_velocity(ball, s) / (1 / ball%mass + 1 / (ball%inertia_factor * ball%mass))
    y(1:3) = s(1:3)
    y(4:6) = s(4:6) - cross(n, impulse) / (ball%inertia_factor * ball%mass * ball%radius)
  end function stick

  !> The energy the stick of sliding state s takes: |u|^2 / (2 (1/m +
  !> R^2/J)), u the slip (tangent), in closed form: the difference of the
  !> energies before and after is round-off where u is small.
  pure real(wp) function stick_loss(ball, s)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: s(slide_state_size)
    real(wp) :: u(3)
    u = slip_velocity(ball, s)
    stick_loss = dot_product(u, u) / (2 * (1 / ball%mass + 1 / (ball%inertia_factor * ball%mass)))
  end function stick_loss

  !> The slip's time scale at sliding state y with normal force N: the
  !> friction alone takes |u| at the rate mu N (1/m + R^2/J) (the part of
  !> du/dt that the friction makes; docs/model.md), so the slip stops in
  !> about |u| / (mu N (1/m + R^2/J)) where that rate outweighs the
  !> others (a large mu, a small inertia factor: a stiff slip). With the
  !> friction rolling needs there (needed, F_req), the time within which
  !> the slip stops where that rate holds: with u' = (1/m + R^2/J) (F - F_req)
  !> and F = -mu N u/|u|, |u| falls at (mu N - |F_req|) (1/m + R^2/J) at
  !> least. Infinite where the normal force does not push, or rolling
  !> needs mu N or more.
  pure real(wp) function slip_stop_time(ball, y, normal_force, needed) result(time)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(slide_state_size), normal_force
    real(wp), intent(in), optional :: needed(3)
    real(wp) :: rate, size_u
    time = huge(1.0_wp)
    rate = ball%mu * normal_force
    if (present(needed)) rate = rate - norm2(needed)
    rate = rate * (1 + 1 / ball%inertia_factor) / ball%mass
    size_u = norm2(slip_velocity(ball, y))
    if (rate > 0 .and. size_u / huge(1.0_wp) < rate) time = size_u / rate
  end function slip_stop_time

  !> The direction of the friction at slip u for a step whose slip mode is
  !> `mode`: against u while u is along the mode (or no mode is set), else
  !> against the mode (past the stop, inside the step cut there).
  pure function friction_direction(u, mode) result(e)
    real(wp), intent(in) :: u(3), mode(3)
    real(wp) :: e(3), size_u
    size_u = norm2(u)
    if (size_u > 0 .and. (dot_product(u, mode) > 0 .or. .not. dot_product(mode, mode) > 0)) then
      e = -u / size_u
    else
      e = -mode
    end if
  end function friction_direction

  !> The slip at sliding state y, zero where it is within the round-off of
  !> V_C - R omega x n (16 eps of its terms' size): its direction is then
  !> noise (at a switch from rolling the terms cancel to about 1e-17 m/s),
  !> which would replace the direction the switch set and cut the next
  !> step at once.
  pure function resolved_slip(ball, y) result(u)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(:)
    real(wp) :: u(3)
    u = slip_velocity(ball, y)
    if (norm2(u) <= slip_noise(ball, y)) u = 0
  end function resolved_slip

  !> The round-off of the slip V_C - R omega x n at sliding state y: 16 eps
  !> of its terms' size.
  pure real(wp) function slip_noise(ball, y)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(:)
    slip_noise = 16 * epsilon(1.0_wp) * (norm2(center_velocity(y)) + ball%radius * norm2(y(4:6)))
  end function slip_noise

  !> The slip below which a piece from sliding state y counts it as stopped
  !> whatever its start's: a few times its noise (slip_noise), where the
  !> slip of a stage past the stop jitters.
  pure real(wp) function stop_floor(ball, y)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(:)
    stop_floor = 4 * slip_noise(ball, y)
  end function stop_floor

  !> The lesser of |u| - max(stick_level |u_start|, floor) (it falls through
  !> zero just before the stop, at a rate bounded away from zero) and the
  !> slip along u_start (it falls through zero where the slip has turned by
  !> a right angle), times |u_start|: continuous, positive at a start above
  !> the floor.
  pure real(wp) function stick_value(u, start, floor) result(g)
    real(wp), intent(in) :: u(3), start(3), floor
    real(wp) :: size_start
    size_start = norm2(start)
    g = min(size_start * (norm2(u) - max(stick_level * size_start, floor)), dot_product(u, start))
  end function stick_value
end module ellroll_slip_state
