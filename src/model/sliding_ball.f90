!> The ball sliding on the cup with Coulomb friction (docs/model.md,
!> "Sliding with Coulomb friction"): the regime a case with `slip = 'slide'`
!> enters where the friction that rolling needs reaches mu N, and leaves
!> where the slip stops and rolling's friction is within mu N.
!>
!> State y = (n, omega, V_x, V_y): the inward normal at the contact point
!> (|y(1:3)| = L drifts like rolling's), the angular velocity, and the
!> horizontal part of the centre's velocity relative to the cup; its
!> vertical part follows from V_C . n = 0 (n_z > 0 in the lower half).
!> Seven degrees of freedom in eight numbers (the embedded pairs hold
!> eight equations). With g_eff = g_vec - a_base:
!>   u        = V_C - R omega x n                  slip velocity at A
!>   F        = -mu N u / |u|                      Coulomb friction
!>   m V_C'   = N n + F + m g_eff
!>   J omega' = -R n x F + M
!>   N        = -m (V_C . n' + g_eff . n)          (d/dt V_C . n = 0)
!>   n'       = (R I - K)^-1 V_C                   (as rolling's, with V_C)
!> M = -delta N omega_t / |omega_t| the couple of rolling resistance
!> (&ball rolling_resistance = delta), omega_t = omega - (omega . n) n the
!> rolling part of omega relative to the cup (resist_sliding).
module ellroll_sliding_ball
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_ode, only: hybrid_system_t
  use ellroll_excitation, only: excitation_none, base_acceleration
  use ellroll_status, only: status_liftoff, status_nonfinite, status_rim, status_no_fit
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, observe, ball_derivative, cross, &
      horizontal_force_scaled
  use ellroll_quantities, only: peak_clearance
  use ellroll_norms, only: in_mass_units
  use ellroll_slip_state, only: slide_state_size, center_velocity, at_sliding_rim, slip_velocity, &
      sliding_from_rolling, rolling_from_sliding, stick, stick_loss, slip_stop_time, friction_direction, &
      resolved_slip, stop_floor, stick_value, stick_level
  implicit none
  private

  public :: sliding_ball_t, slide_state_size, sliding_from_rolling, rolling_from_sliding, stick, sliding_derivative, &
            observe_sliding, slip_velocity, slip_rate, center_velocity, friction_direction, resistance_power, &
            slip_stop_time, dissipation, at_sliding_rim, choose_slip_law, align_slip, set_reaction, stop_floor, &
            stick_loss, stick_level, couple_steady_at

  !> The event of the sliding regime: the slip stops.
  integer, parameter, public :: event_stick = 1

  !> Where the slip stops inside a step is located to this part of the step.
  real(wp), parameter :: stick_tolerance = 1.0e-12_wp

  type, extends(hybrid_system_t) :: sliding_ball_t
    type(rolling_ball_t) :: ball
    !> the slip direction where the step started (begin_step), or, where the
    !> slip is zero there (the switch from rolling), the direction it grows:
    !> a stage past the stop keeps the friction against it, so that the flow
    !> up to the stop stays smooth inside the step that is cut there
    real(wp) :: slip_mode(3) = 0
    real(wp) :: slip_at_start(3) = 0
    !> the slip counts as stopped below this (m/s) whatever its start's:
    !> stick_level of a slip near the round-off of V_C - R omega x n lies
    !> below that noise, which no step can bring it under (stop_floor)
    real(wp) :: slip_floor = 0
    !> the step's friction lies along the friction rolling needs (its slip
    !> on the slow manifold: choose_slip_law), not against u / |u|
    logical :: aligned = .false.
    !> the error the aligned law may leave in the slip: align_atol +
    !> align_rtol (|V_C| + R |omega|), m/s (0: the law is never aligned)
    real(wp) :: align_atol = 0, align_rtol = 0
    !> where the full law is stiff over the step (tau below a tenth of it,
    !> its explicit stages then unresolved), the aligned law may leave this
    !> many times that error
    real(wp) :: stiff_allowance = 1
  contains
    procedure :: rhs => sliding_rhs
    procedure :: stage_status => sliding_stage_status
    procedure :: nonsmooth => sliding_nonsmooth
    procedure :: begin_step => sliding_begin_step
    procedure :: event_crossed => sliding_event_crossed
    procedure :: event_start_value => sliding_event_start_value
    procedure :: event_value => sliding_event_value
    procedure, nopass :: event_tolerance => sliding_event_tolerance
    procedure :: apply_event => sliding_apply_event
  end type sliding_ball_t

contains

  !> The rate of the slip velocity, du/dt, at sliding state y whose
  !> derivative is dydt (u = V_C - R omega x n / |n| differentiated).
  pure function slip_rate(ball, y, dydt) result(rate)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(slide_state_size), dydt(slide_state_size)
    real(wp) :: rate(3), length, n(3), n_rate(3), v_rate(3)
    length = norm2(y(1:3))
    n = y(1:3) / length
    n_rate = dydt(1:3) / length - n * dot_product(n, dydt(1:3)) / length
    v_rate(1:2) = dydt(7:8)
    v_rate(3) = -((dydt(1) * y(7) + y(1) * dydt(7) + dydt(2) * y(8) + y(2) * dydt(8)) * y(3) &
                  - (y(1) * y(7) + y(2) * y(8)) * dydt(3)) / y(3)**2
    rate = v_rate - ball%radius * (cross(dydt(4:6), n) + cross(y(4:6), n_rate))
  end function slip_rate

  !> The contact's frame at sliding state y: the unit normal n, V_C, n'
  !> (of y(1:3), in dydt13), g_eff and N (the equations above).
  pure subroutine contact_frame(sb, t, y, base, n, v, dydt13, g_eff, big_n)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size)
    real(wp), intent(in), optional :: base(3)
    real(wp), intent(out) :: n(3), v(3), dydt13(3), g_eff(3), big_n
    real(wp) :: rolling(state_size), rate(state_size)
    associate (ball => sb%ball)
      n = y(1:3) / norm2(y(1:3))
      v = center_velocity(y)
      ! n' from rolling's kinematics with omega such that R omega x n = V_C:
      ! omega = n x V_C / R (its part along n does not move n)
      rolling(1:3) = y(1:3)
      rolling(4:6) = cross(n, v) / ball%radius
      call ball_derivative(ball, t, rolling, rate)     ! (only its n' is used)
      dydt13 = rate(1:3)
      g_eff = [0.0_wp, 0.0_wp, -ball%g]
      if (present(base)) then
        g_eff = g_eff - base
      else if (ball%excitation%kind /= excitation_none) then
        g_eff = g_eff - base_acceleration(ball%excitation, t)
      end if
      big_n = -ball%mass * (dot_product(v, dydt13 / norm2(y(1:3))) + dot_product(g_eff, n))
    end associate
  end subroutine contact_frame

  !> The friction rolling would need at sliding state y (needed_friction).
  pure function needed_at(sb, t, y) result(need)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size)
    real(wp) :: need(3), n(3), v(3), dydt13(3), g_eff(3), big_n, n_dot(3)
    call contact_frame(sb, t, y, n=n, v=v, dydt13=dydt13, g_eff=g_eff, big_n=big_n)
    n_dot = dydt13 / norm2(y(1:3))
    need = needed_friction(sb%ball, n, y(4:6), n_dot - n * dot_product(n, n_dot), big_n, g_eff)
  end function needed_at

  !> What both slip laws take from sliding state y: n' (dydt(1:3): rolling's
  !> kinematics with omega such that R omega x n = V_C, omega = n x V_C / R,
  !> whose part along n does not move n), the unit normal n and its rate, V_C,
  !> g_eff = g - the cup's acceleration, N and the slip u.
  pure subroutine sliding_kinematics(sb, t, y, base, dydt, n, n_dot, v, g_eff, big_n, u)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size)
    real(wp), intent(in), optional :: base(3)
    real(wp), intent(inout) :: dydt(slide_state_size)
    real(wp), intent(out) :: n(3), n_dot(3), v(3), g_eff(3), big_n, u(3)
    real(wp) :: length, rolling(state_size), rate(state_size)
    associate (ball => sb%ball)
      length = norm2(y(1:3))
      n = y(1:3) / length
      v = center_velocity(y)
      rolling(1:3) = y(1:3)
      rolling(4:6) = cross(n, v) / ball%radius
      call ball_derivative(ball, t, rolling, rate)     ! (only its n' is used)
      dydt(1:3) = rate(1:3)
      n_dot = rate(1:3) / length
      g_eff = [0.0_wp, 0.0_wp, -ball%g]
      if (present(base)) then
        g_eff = g_eff - base
      else if (ball%excitation%kind /= excitation_none) then
        g_eff = g_eff - base_acceleration(ball%excitation, t)
      end if
      big_n = -ball%mass * (dot_product(v, n_dot) + dot_product(g_eff, n))
      u = v - ball%radius * cross(y(4:6), n)
    end associate
  end subroutine sliding_kinematics

  !> omega' and V_C' (dydt(4:8)) under the friction force at A.
  pure subroutine friction_rates(ball, n, g_eff, big_n, force, dydt)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: n(3), g_eff(3), big_n, force(3)
    real(wp), intent(inout) :: dydt(slide_state_size)
    real(wp) :: v_dot(3)
    v_dot = (big_n * n + force) / ball%mass + g_eff
    dydt(4:6) = -cross(n, force) / (ball%inertia_factor * ball%mass * ball%radius)
    dydt(7:8) = v_dot(1:2)
  end subroutine friction_rates

  !> The sliding right-hand side (the equations above) without the couple
  !> of rolling resistance (sliding_rate adds it), with N and the friction
  !> force where asked. needed: the friction rolling would need at y (F_req).
  pure subroutine sliding_derivative(sb, t, y, dydt, normal_force, friction, base, needed)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size)
    real(wp), intent(out) :: dydt(slide_state_size)
    real(wp), intent(out), optional :: normal_force, friction(3)
    real(wp), intent(in), optional :: base(3)
    real(wp), intent(out), optional :: needed(3)
    real(wp) :: n(3), v(3), g_eff(3), n_dot(3), u(3), force(3), big_n, need(3)
    associate (ball => sb%ball)
      call sliding_kinematics(sb, t, y, base, dydt, n, n_dot, v, g_eff, big_n, u)
      need = 0
      if (sb%aligned .or. present(needed)) then
        need = needed_friction(ball, n, y(4:6), n_dot - n * dot_product(n, n_dot), big_n, g_eff)
        if (present(needed)) needed = need
      end if
      if (sb%aligned .and. norm2(need) > 0) then
        force = ball%mu * max(big_n, 0.0_wp) * (need / norm2(need))
      else
        force = ball%mu * max(big_n, 0.0_wp) * friction_direction(u, sb%slip_mode)
      end if
      call friction_rates(ball, n, g_eff, big_n, force, dydt)
      if (sb%aligned .and. norm2(u) > 0 .and. norm2(need) > 0) then
        force = turning_friction(sb, t, y, dydt, need, norm2(u), big_n)
        call friction_rates(ball, n, g_eff, big_n, force, dydt)
      end if
      if (present(normal_force)) normal_force = big_n
      if (present(friction)) friction = force
    end associate
  end subroutine sliding_derivative

  !> The aligned law's friction at sliding state y with slip |u| = slip
  !> along -F_req (docs/model.md, "Where the slip is small"): with
  !> f = F_req / |F_req| and u = -|u| f, u' = c (F - F_req) asks for
  !> F = F_req - (|u|' f + |u| f') / c: across f the part -(|u| / c) f'
  !> that turns u with F_req, along f the part that gives |u| the rate of
  !> the full law on its slow manifold, |u|' = c (|F_req| cos(lag) - mu N)
  !> with sin(lag) = |u| |f'| / (c |F_req|) (the lag of -u / |u| behind
  !> f). f' is the difference of f over turn_probe along the flow
  !> (dydt: the derivative with the friction along f).
  pure function turning_friction(sb, t, y, dydt, need, slip, big_n) result(force)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size), dydt(slide_state_size), need(3), slip, big_n
    real(wp) :: force(3), along(3), later(3), turn(3), n(3), c, size_need, lag_sine
    real(wp), parameter :: turn_probe = 1.0e-7_wp
    c = (1 + 1 / sb%ball%inertia_factor) / sb%ball%mass
    size_need = norm2(need)
    along = need / size_need
    later = needed_at(sb, t + turn_probe, y + turn_probe * dydt)
    turn = (later / norm2(later) - along) / turn_probe
    ! (across f in the tangent plane: later is tangent where n has turned)
    n = y(1:3) / norm2(y(1:3))
    turn = turn - dot_product(turn, along) * along - dot_product(turn, n) * n
    lag_sine = min(1.0_wp, slip * norm2(turn) / (c * size_need))
    force = (sb%ball%mu * max(big_n, 0.0_wp) + size_need * (1 - sqrt(1 - lag_sine**2))) * along &
            - (slip / c) * turn
  end function turning_friction

  !> The couple of rolling resistance while the ball slides (docs/model.md,
  !> "Rolling resistance while sliding"): M = -delta N omega_t / |omega_t|
  !> on omega (J omega' gains M; the centre's motion and N do not see a
  !> couple). Where the ball does not roll (omega_t = 0, as a ball launched
  !> without spin) the couple opposes the friction's couple -R n x F that
  !> starts it rolling (delta < mu R: a case's input is checked for it),
  !> and holds it where N vanishes. omega_rate holds omega' without the couple.
  pure subroutine resist_sliding(ball, n, omega, big_n, force, omega_rate)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: n(3), omega(3), big_n, force(3)
    real(wp), intent(inout) :: omega_rate(3)
    real(wp) :: omega_t(3), rate, resistance, inertia, drive(3), drive_size
    resistance = ball%rolling_resistance * max(big_n, 0.0_wp)
    inertia = ball%inertia_factor * ball%mass * ball%radius**2
    omega_t = omega - dot_product(omega, n) * n
    rate = norm2(omega_t)
    if (rate > 1.0e-12_wp * (sqrt(ball%g / ball%radius) + norm2(omega))) then
      omega_rate = omega_rate - (resistance / (rate * inertia)) * omega_t
      return
    end if
    drive = -ball%radius * cross(n, force)
    drive_size = norm2(drive)
    if (drive_size <= resistance) then
      omega_rate = omega_rate - drive / inertia          ! held: no rolling starts
    else
      omega_rate = omega_rate - (resistance / (drive_size * inertia)) * drive
    end if
  end subroutine resist_sliding

  !> The power of the couple of rolling resistance at a state whose normal
  !> force is big_n (either regime): -delta N |omega_t|.
  pure real(wp) function resistance_power(ball, n, omega, big_n) result(power)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: n(3), omega(3), big_n
    power = -ball%rolling_resistance * max(big_n, 0.0_wp) * norm2(omega - dot_product(omega, n) * n)
  end function resistance_power

  !> The friction rolling would need at a sliding state (F_req: the F that
  !> makes the slip's rate zero; docs/model.md, "Where the slip is small"):
  !> u' = b + c F for a tangent F, with c = 1/m + R^2/J (F moves V_C by F / m
  !> and the contact point of omega by (R^2/J) (n x F) x n = (R^2/J) F) and
  !> b = N n / m + g_eff - R (omega_M' x n + omega x n'), omega_M' the
  !> couple of rolling resistance over J; F_req = -b_t / c, b_t the tangent
  !> part of b (its normal part keeps u tangent as n turns). n_rate: n'.
  pure function needed_friction(ball, n, omega, n_rate, big_n, g_eff) result(need)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: n(3), omega(3), n_rate(3), big_n, g_eff(3)
    real(wp) :: need(3), b(3), omega_t(3), couple_rate(3), rate, inertia
    couple_rate = 0
    if (ball%rolling_resistance > 0) then
      inertia = ball%inertia_factor * ball%mass * ball%radius**2
      omega_t = omega - dot_product(omega, n) * n
      rate = norm2(omega_t)
      if (rate > 1.0e-12_wp * (sqrt(ball%g / ball%radius) + norm2(omega))) &
        couple_rate = -(ball%rolling_resistance * max(big_n, 0.0_wp) / (rate * inertia)) * omega_t
    end if
    b = big_n * n / ball%mass + g_eff - ball%radius * (cross(couple_rate, n) + cross(omega, n_rate))
    need = -(b - dot_product(b, n) * n) / ((1 + 1 / ball%inertia_factor) / ball%mass)
  end function needed_friction

  !> The angle between two vectors (0 where either is zero).
  pure real(wp) function turn_angle(a, b) result(angle)
    real(wp), intent(in) :: a(3), b(3)
    angle = atan2(norm2(cross(a, b)), dot_product(a, b))
  end function turn_angle

  !> The slip law of a step of size h from (t, y) (docs/model.md, "Where
  !> the slip is small"): aligned (the friction mu N along F_req) where the
  !> slip lies along -F_req and the lag of its direction behind -F_req,
  !> tau Omega with tau = |u| / (c |F_req|) and Omega the rate at which
  !> F_req turns, leaves an error |u| tau Omega in the slip within
  !> align_atol + align_rtol (|V_C| + R |omega|) over the step (|u| at its
  !> larger end, Omega the larger of its rate at t and its mean over the
  !> step at the state of t); else against u / |u|. Where the law changes,
  !> f (the derivative at y) is taken again with the new one.
  subroutine choose_slip_law(sb, t, y, f, h, n_rhs)
    type(sliding_ball_t), intent(inout) :: sb
    real(wp), intent(in) :: t, y(slide_state_size), h
    real(wp), intent(inout) :: f(slide_state_size)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: rate(slide_state_size), scratch(slide_state_size), need(3), later(3), u(3), along(3)
    real(wp) :: allowed, slip, turn, probe, big_n, reach
    logical :: before
    before = sb%aligned
    sb%aligned = .false.
    allowed = sb%align_atol + sb%align_rtol * (norm2(center_velocity(y)) + sb%ball%radius * norm2(y(4:6)))
    ! (with rolling resistance the aligned law only where the couple keeps
    ! its direction over the step: where the ball does not roll it depends
    ! on the friction)
    if (sb%ball%rolling_resistance > 0 .and. allowed > 0 .and. h > 0) then
      if (.not. couple_steady(sb, t, y, h)) allowed = 0
      n_rhs = n_rhs + 1
    end if
    if (allowed > 0 .and. h > 0) then
      call sliding_derivative(sb, t, y, rate, big_n, needed=need)
      n_rhs = n_rhs + 1
      u = resolved_slip(sb%ball, y)          ! (round-off's slip has no direction)
      along = need / max(norm2(need), tiny(1.0_wp))
      ! on the slow manifold: u along -F_req, its part across within the error
      if (big_n > 0 .and. norm2(need) > 0 .and. .not. dot_product(u, along) > 0 .and. &
          norm2(u - dot_product(u, along) * along) <= allowed) then
        sb%aligned = .true.
        call sliding_derivative(sb, t, y, rate)
        slip = max(norm2(u), norm2(u + h * slip_rate(sb%ball, y, rate)))
        probe = min(h, 1.0e-6_wp)
        call sliding_derivative(sb, t + probe, y + probe * rate, scratch, needed=later)
        turn = turn_angle(need, later) / probe
        call sliding_derivative(sb, t + h, y, scratch, needed=later)
        turn = max(turn, turn_angle(need, later) / h)
        n_rhs = n_rhs + 3
        reach = (1 + 1 / sb%ball%inertia_factor) / sb%ball%mass * norm2(need)      ! kappa |F_req|
        if (10 * slip < h * reach) allowed = allowed * sb%stiff_allowance          ! (tau < h / 10)
        sb%aligned = slip**2 * turn <= allowed * reach
        if (sb%aligned) then
          f = rate
          if (sb%ball%rolling_resistance > 0) then         ! (rate is without the couple)
            call sb%rhs(t, y, f)
            n_rhs = n_rhs + 1
          end if
          return
        end if
      end if
    end if
    if (sb%aligned .neqv. before) then
      call sb%rhs(t, y, f)
      n_rhs = n_rhs + 1
    end if
  end subroutine choose_slip_law

  !> Whether the couple of rolling resistance keeps its direction over a
  !> step h from sliding state y: omega_t, on which it acts, clear of 0 by
  !> twice what omega changes in the step at its rate there. Then F_req
  !> (needed_friction) holds the couple along omega_t, as the flow does.
  logical function couple_steady(sb, t, y, h) result(steady)
    class(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size), h
    real(wp) :: rate(slide_state_size)
    call sb%rhs(t, y, rate)
    steady = couple_steady_at(y, rate, h)
  end function couple_steady

  !> couple_steady where the rate at y is known.
  pure logical function couple_steady_at(y, rate, h) result(steady)
    real(wp), intent(in) :: y(slide_state_size), rate(slide_state_size), h
    real(wp) :: n(3), omega_t(3)
    n = y(1:3) / norm2(y(1:3))
    omega_t = y(4:6) - dot_product(y(4:6), n) * n
    steady = norm2(omega_t) > 2 * h * norm2(rate(4:6))
  end function couple_steady_at

  !> An aligned step's end: the slip turned onto -F_req at its size,
  !> u = -|u| F_req / |F_req|, by an impulse P of the cup at A (m dV_C = P,
  !> J d omega = -R n x P, so du = P (1/m + R^2/J)): the part of the
  !> friction across the slip that turns it with F_req, which the aligned
  !> law leaves out, given at the step's end. It keeps |u| and so the energy
  !> (the energy changes by P . (u + u_new) / 2 = (|u_new|^2 - |u|^2) / (2 c)).
  !> A slip along +F_req (past its stop) is left to the stop's event.
  subroutine align_slip(sb, t, y, n_rhs)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t
    real(wp), intent(inout) :: y(slide_state_size)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: rate(slide_state_size), need(3), along(3), u(3), impulse(3), n(3)
    call sliding_derivative(sb, t, y, rate, needed=need)
    n_rhs = n_rhs + 1
    if (.not. norm2(need) > 0) return
    along = need / norm2(need)
    u = slip_velocity(sb%ball, y)
    if (dot_product(u, along) > 0) return
    associate (m => sb%ball%mass, k => sb%ball%inertia_factor)
      impulse = (-norm2(u) * along - u) / (1 / m + 1 / (k * m))
      n = y(1:3) / norm2(y(1:3))
      y(7:8) = y(7:8) + impulse(1:2) / m
      y(4:6) = y(4:6) - cross(n, impulse) / (k * m * sb%ball%radius)
    end associate
  end subroutine align_slip

  !> The rates at which the friction (mu N |u|) and the couple of rolling
  !> resistance (delta N |omega_t|) take energy at sliding state y, W.
  pure function dissipation(sb, t, y) result(power)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size)
    real(wp) :: power(2), rate(slide_state_size), big_n, force(3)
    call sliding_derivative(sb, t, y, rate, big_n, force)
    if (sb%aligned) then
      power(1) = -dot_product(force, slip_velocity(sb%ball, y))    ! (u is not along -F inside an aligned step)
    else
      power(1) = sb%ball%mu * max(big_n, 0.0_wp) * norm2(slip_velocity(sb%ball, y))
    end if
    power(2) = 0
    if (sb%ball%rolling_resistance > 0) power(2) = -resistance_power(sb%ball, y(1:3) / norm2(y(1:3)), y(4:6), big_n)
  end function dissipation

  !> The sliding right-hand side with the couple of rolling resistance
  !> where the ball has it (sliding_derivative's forces, resist_sliding).
  pure subroutine sliding_rate(sb, t, y, dydt, normal_force, friction)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size)
    real(wp), intent(out) :: dydt(slide_state_size), normal_force, friction(3)
    call sliding_derivative(sb, t, y, dydt, normal_force, friction)
    if (sb%ball%rolling_resistance > 0) &
      call resist_sliding(sb%ball, y(1:3) / norm2(y(1:3)), y(4:6), normal_force, friction, dydt(4:6))
  end subroutine sliding_rate

  pure subroutine sliding_rhs(self, t, y, dydt)
    class(sliding_ball_t), intent(in) :: self
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(:)
    real(wp), intent(out) :: dydt(:)
    real(wp) :: big_n, force(3)
    if (self%ball%rolling_resistance > 0) then
      call sliding_rate(self, t, y, dydt, big_n, force)
    else
      call sliding_derivative(self, t, y, dydt)
    end if
  end subroutine sliding_rhs

  !> The reaction of the cup on the ball in obs, and what follows from it:
  !> its horizontal size and the centre's absolute acceleration.
  pure subroutine set_reaction(sb, reaction, obs)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: reaction(3)
    type(observation_t), intent(inout) :: obs
    obs%reaction = reaction
    obs%horizontal_force_scaled = horizontal_force_scaled(reaction, sb%ball%mass)
    obs%center_acceleration = reaction / sb%ball%mass - [0.0_wp, 0.0_wp, sb%ball%g]
  end subroutine set_reaction

  !> Every derived output of sliding state y (observe's, with the sliding
  !> reaction N n + F, the friction ratio mu, the energy with V_C) and the
  !> slip speed |u|.
  pure subroutine observe_sliding(sb, t, y, obs, slip_speed, dydt)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size)
    type(observation_t), intent(out) :: obs
    real(wp), intent(out) :: slip_speed
    real(wp), intent(out) :: dydt(slide_state_size)
    real(wp) :: big_n, force(3), rolling_rate(state_size), v(3), n(3), height
    call sliding_rate(sb, t, y, dydt, big_n, force)
    ! the aligned law's friction is mu N along f plus its error, which does
    ! not scale with N (|u| f' / kappa): the model's friction is mu N, also
    ! as N falls to zero before a lift-off
    if (sb%aligned .and. big_n > 0 .and. norm2(force) > 0) force = (sb%ball%mu * big_n / norm2(force)) * force
    rolling_rate(1:3) = dydt(1:3)
    rolling_rate(4:6) = dydt(4:6)
    call observe(sb%ball, t, y(1:6), rolling_rate, obs)
    n = obs%normal
    call set_reaction(sb, big_n * n + force, obs)
    obs%reaction_normal = big_n
    obs%friction_needed = huge(1.0_wp)
    if (big_n > 0) obs%friction_needed = norm2(in_mass_units(force, sb%ball%mass)) / in_mass_units(big_n, sb%ball%mass)
    v = center_velocity(y)
    height = obs%contact(3) - sb%ball%radius * (n(1)**2 + n(2)**2) / (1 + n(3))
    associate (m => sb%ball%mass, r => sb%ball%radius)
      obs%energy_of_motion = 0.5_wp * sb%ball%inertia_factor * m * r**2 * dot_product(y(4:6), y(4:6)) &
                             + 0.5_wp * m * dot_product(v, v) + m * sb%ball%g * height
      obs%energy = obs%energy_of_motion + m * sb%ball%g * r
    end associate
    ! V_z's error grows as 1 / n_z towards the rim (rim_level): a step end
    ! within peak_clearance of n_z = 0 is not clear of that singular
    ! configuration either (the peaks and works of a case that ends at a
    ! model limit stop at the last clear one)
    if (.not. n(3) > peak_clearance) obs%fit_clearance = min(obs%fit_clearance, -1.0_wp)
    slip_speed = norm2(slip_velocity(sb%ball, y))
  end subroutine observe_sliding

  !> The limits of a sliding stage: the ball fits the cup short of the rim,
  !> the normal force pushes.
  pure integer function sliding_stage_status(self, t, y, dydt) result(status)
    class(sliding_ball_t), intent(in) :: self
    real(wp), intent(in) :: t, y(:), dydt(:)
    real(wp) :: scratch(state_size), rolling(state_size), big_n, stage_rate(slide_state_size)
    logical :: fits
    status = 0
    if (.not. (all(ieee_is_finite(y)) .and. all(ieee_is_finite(dydt)))) then
      status = status_nonfinite
      return
    end if
    if (at_sliding_rim(y)) then
      status = status_rim
      return
    end if
    rolling = y(1:6)
    call ball_derivative(self%ball, t, rolling, scratch, fits)
    if (.not. fits) then
      status = status_no_fit
      if (y(3) <= 0) status = status_rim
      return
    end if
    call sliding_derivative(self, t, y, stage_rate, big_n)
    if (big_n <= 0) status = status_liftoff
  end function sliding_stage_status

  pure logical function sliding_nonsmooth(self) result(nonsmooth)
    class(sliding_ball_t), intent(in) :: self
    nonsmooth = self%ball%mu > 0
  end function sliding_nonsmooth

  !> The slip mode for a step from y: the slip direction there (kept where
  !> the slip is zero: the direction set by the switch into sliding).
  pure subroutine sliding_begin_step(self, y)
    class(sliding_ball_t), intent(inout) :: self
    real(wp), intent(in), contiguous :: y(:)
    real(wp) :: u(3)
    u = resolved_slip(self%ball, y)
    self%slip_at_start = u
    self%slip_floor = stop_floor(self%ball, y)
    if (norm2(u) > 0) self%slip_mode = u / norm2(u)
  end subroutine sliding_begin_step

  !> event_stick where the slip, nonzero at the step's start, has fallen to
  !> stick_level of it or turned by a right angle or more at its end.
  pure integer function sliding_event_crossed(self, y_start, y_end) result(event)
    class(sliding_ball_t), intent(in) :: self
    real(wp), intent(in), contiguous :: y_start(:), y_end(:)
    real(wp) :: start(3)
    event = 0
    start = resolved_slip(self%ball, y_start)
    if (norm2(start) <= 0) return
    if (stick_value(slip_velocity(self%ball, y_end), start, stop_floor(self%ball, y_start)) <= 0) event = event_stick
  end function sliding_event_crossed

  !> event_stick's function at the step's start: |u|^2 there.
  pure real(wp) function sliding_event_start_value(self, event) result(g)
    class(sliding_ball_t), intent(in) :: self
    integer, intent(in) :: event
    g = 1
    if (event == event_stick) g = dot_product(self%slip_at_start, self%slip_at_start)
  end function sliding_event_start_value

  !> event_stick's function at y: stick_value of the slip there.
  pure real(wp) function sliding_event_value(self, event, y) result(g)
    class(sliding_ball_t), intent(in) :: self
    integer, intent(in) :: event
    real(wp), intent(in), contiguous :: y(:)
    g = 1
    if (event == event_stick) g = stick_value(slip_velocity(self%ball, y), self%slip_at_start, self%slip_floor)
  end function sliding_event_value

  pure real(wp) function sliding_event_tolerance(event) result(tolerance)
    integer, intent(in) :: event
    tolerance = 0
    if (event == event_stick) tolerance = stick_tolerance
  end function sliding_event_tolerance

  !> event_stick: the slip at zero (V_C set to R omega x n); whether the
  !> ball rolls on from there is the run's to decide (the friction rolling
  !> needs there).
  pure subroutine sliding_apply_event(self, event, y)
    class(sliding_ball_t), intent(inout) :: self
    integer, intent(in) :: event
    real(wp), intent(inout), contiguous :: y(:)
    if (event == event_stick) y = sliding_from_rolling(self%ball, rolling_from_sliding(y))
  end subroutine sliding_apply_event
end module ellroll_sliding_ball
