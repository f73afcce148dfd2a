!> A heavy ball rolling without slip inside the fixed ellipsoidal cup.
!>
!> State y = (n, omega): the inward unit normal at the contact point and the
!> ball's angular velocity (fixed frame). Equations (derived in docs/model.md):
!>   V_C    = R omega x n                               (rolling, no slip)
!>   n'     = (R I - K)^-1 V_C
!>          = [(R - tr K) V_C + K V_C] / det(L),  det(L) = R^2 - R tr K + det K
!>   omega' = J* [ (omega . n) n' + (n x g_vec) / R ],  J* = 1 / (1 + k)
!> with K the cup's radius-of-curvature operator and J = k m R^2 (k = 2/5 for
!> a homogeneous ball). n' is homogeneous of degree one in |n|, so the
!> direction of n does not depend on the drift of |n| and renormalising
!> after a step changes nothing but round-off.
module ellroll_rolling_ball
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp
  use ellroll_ode, only: ode_system_t
  use ellroll_ellipsoid, only: ellipsoid_t, radius_operator_t, radius_operator, &
      contact_from_normal, normal_from_contact, surface_residual
  use ellroll_excitation, only: excitation_t, excitation_none, base_acceleration
  use ellroll_status, only: status_completed, status_rim, status_no_fit, status_slip, &
      status_liftoff, status_nonfinite, status_constraint
  implicit none
  private

  public :: rolling_ball_t, observation_t, state_size
  public :: initial_state, observe, observe_geometry, limit_status, constraint_tolerance, ball_derivative, &
            nutation_angle

  integer, parameter :: state_size = 6
  !> Largest surface residual accepted before a case ends with 'constraint'.
  real(wp), parameter :: constraint_tolerance = 1.0e-10_wp

  type, extends(ode_system_t) :: rolling_ball_t
    type(ellipsoid_t) :: cup
    real(wp) :: radius = 1
    real(wp) :: mass = 1
    real(wp) :: g = 9.81_wp
    real(wp) :: inertia_factor = 0.4_wp   !< J / (m R^2)
    real(wp) :: mu = -1                   !< friction coefficient; <= 0: no slip check
    real(wp) :: fit_margin = 1.0e-6_wp    !< end when r_min / R - 1 falls to this
    type(excitation_t) :: excitation      !< translation of the cup
  contains
    procedure :: rhs => ball_rhs
    procedure :: project => normalize_normal
  end type rolling_ball_t

  !> Everything derived from one state and its time derivative.
  type :: observation_t
    real(wp) :: normal(3) = 0
    real(wp) :: omega(3) = 0
    real(wp) :: contact(3) = 0
    real(wp) :: center(3) = 0
    real(wp) :: lateral = 0              !< sqrt(n_x^2 + n_y^2): Theta = atan2(lateral, n_z)
    real(wp) :: tan_nutation = 0         !< tan Theta (huge past the rim): cheap, and ordered like Theta
    real(wp) :: reaction(3) = 0          !< force of the cup on the ball, N
    real(wp) :: reaction_normal = 0      !< N = F . n
    real(wp) :: friction_needed = 0      !< |F_t| / N
    real(wp) :: energy = 0               !< J |w|^2/2 + m |V_C|^2/2 + m g z_C
    real(wp) :: energy_of_motion = 0     !< energy - m g R (the bottom at rest is 0)
    real(wp) :: surface_residual = 0
    logical :: fits = .true.             !< r_min > R (1 + fit_margin): the ball fits the cup here
    real(wp) :: base_acceleration(3) = 0 !< acceleration of the cup, m/s^2
    real(wp) :: center_acceleration(3) = 0  !< absolute acceleration of the centre, m/s^2
  end type observation_t

contains

  pure function cross(u, v) result(w)
    real(wp), intent(in) :: u(3), v(3)
    real(wp) :: w(3)
    w = [u(2)*v(3) - u(3)*v(2), u(3)*v(1) - u(1)*v(3), u(1)*v(2) - u(2)*v(1)]
  end function cross

  pure subroutine ball_rhs(self, t, y, dydt)
    class(rolling_ball_t), intent(in) :: self
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(:)
    real(wp), intent(out) :: dydt(:)
    call ball_derivative(self, t, y, dydt)
  end subroutine ball_rhs

  !> The right-hand side on explicit-shape arrays: the one implementation,
  !> behind the generic interface (ball_rhs) and the fused steps; the batch's
  !> lanes_derivative is the same arithmetic, expression by expression.
  !> K comes from y as it is (y = |y| n between projections): with
  !> q = y . A y = |y|^2 s^2, tr K and det K need 1/q and 1/s = |y| / sqrt(q),
  !> whose reciprocal and root run side by side, and n' det L is formed
  !> before 1/det L, the last long operation, is known.
  pure subroutine ball_derivative(ball, t, y, dydt)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(state_size)
    real(wp), intent(out) :: dydt(state_size)
    real(wp) :: r, length2, length, inv_length, ay(3), q, inv_q, inv_s, inv_s2, trace, det, v(3), ay_v, kv(3)
    real(wp) :: n_dot_det_l(3), inv_det_l, j_star, spin
    r = ball%radius
    length2 = y(1) * y(1) + y(2) * y(2) + y(3) * y(3)
    length = sqrt(length2)
    inv_length = 1 / length
    ay = ball%cup%axes2 * y(1:3)
    q = y(1) * ay(1) + y(2) * ay(2) + y(3) * ay(3)
    inv_q = 1 / q
    inv_s = sqrt(q) * (length * inv_q)
    inv_s2 = length2 * inv_q
    trace = (sum(ball%cup%axes2) - (ay(1) * ay(1) + ay(2) * ay(2) + ay(3) * ay(3)) * inv_q) * inv_s
    det = ball%cup%det_axes2 * inv_s2 * inv_s2
    ! V_C = R omega x n; n' = ((R - tr K) V_C + K V_C) / det L
    v = (r * inv_length) * [y(5) * y(3) - y(6) * y(2), y(6) * y(1) - y(4) * y(3), y(4) * y(2) - y(5) * y(1)]
    ay_v = (ay(1) * v(1) + ay(2) * v(2) + ay(3) * v(3)) * inv_q
    kv = (ball%cup%axes2 * v - ay * ay_v) * inv_s
    n_dot_det_l = (r - trace) * v + kv
    inv_det_l = 1 / (r * (r - trace) + det)
    ! omega' = J* ((omega . n) n' + (g / R) (-n_y, n_x, 0))
    j_star = 1 / (1 + ball%inertia_factor)
    spin = (y(4) * y(1) + y(5) * y(2) + y(6) * y(3)) * inv_length
    dydt(1:3) = (length * n_dot_det_l) * inv_det_l
    dydt(4:6) = ((spin * j_star) * n_dot_det_l) * inv_det_l &
                + ((ball%g / r) * j_star * inv_length) * [-y(2), y(1), 0.0_wp]
    ! a moving cup: g_vec - a_base in the cup's frame (only when it moves, so
    ! a fixed cup costs nothing)
    if (ball%excitation%kind /= excitation_none) &
      dydt(4:6) = dydt(4:6) - cross(y(1:3) * inv_length, base_acceleration(ball%excitation, t)) &
                  / (ball%radius * (1 + ball%inertia_factor))
  end subroutine ball_derivative

  pure subroutine normalize_normal(self, y)
    class(rolling_ball_t), intent(in) :: self
    real(wp), intent(inout) :: y(:)
    y(1:3) = y(1:3) / sqrt(dot_product(y(1:3), y(1:3)))
  end subroutine normalize_normal

  !> State for a start at contact point (x, y) of the lower half.
  pure function initial_state(ball, x, y, omega) result(state)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: x, y, omega(3)
    real(wp) :: state(state_size)
    state(1:3) = normal_from_contact(ball%cup, x, y)
    state(4:6) = omega
  end function initial_state

  !> The outputs of a state that are pure geometry: normal, omega, contact
  !> point, centre and the nutation measures (what most samples need).
  pure function observe_geometry(ball, y) result(obs)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(:)
    type(observation_t) :: obs
    real(wp) :: n(3)
    n = y(1:3) * (1 / sqrt(dot_product(y(1:3), y(1:3))))
    obs%normal = n
    obs%omega = y(4:6)
    obs%contact = contact_from_normal(ball%cup, n)
    obs%center = obs%contact + ball%radius * n
    obs%lateral = sqrt(n(1)**2 + n(2)**2)
    obs%tan_nutation = huge(1.0_wp)
    if (n(3) > obs%lateral * tiny(1.0_wp)) obs%tan_nutation = obs%lateral / n(3)
  end function observe_geometry

  !> Every derived output of a state y at time t with time derivative dydt.
  pure function observe(ball, t, y, dydt) result(obs)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(:), dydt(:)
    type(observation_t) :: obs
    real(wp) :: n(3), n_dot(3), omega_dot(3), a_center(3), tangential(3)
    real(wp) :: v_center(3), height_above_rest, fit_radius
    type(radius_operator_t) :: k
    obs = observe_geometry(ball, y)
    n = obs%normal
    n_dot = dydt(1:3) * (1 / sqrt(dot_product(y(1:3), y(1:3))))
    omega_dot = dydt(4:6)
    a_center = ball%radius * (cross(omega_dot, n) + cross(obs%omega, n_dot))
    obs%center_acceleration = a_center
    if (ball%excitation%kind /= excitation_none) then
      obs%base_acceleration = base_acceleration(ball%excitation, t)
      obs%center_acceleration = a_center + obs%base_acceleration
    end if
    ! the force in the inertial frame: m (a_C,rel + a_base - g_vec)
    obs%reaction = ball%mass * (obs%center_acceleration + [0.0_wp, 0.0_wp, ball%g])
    obs%reaction_normal = dot_product(obs%reaction, n)
    tangential = obs%reaction - obs%reaction_normal * n
    if (obs%reaction_normal > 0) then
      obs%friction_needed = sqrt(tangential(1)**2 + tangential(2)**2 + tangential(3)**2) / obs%reaction_normal
    else
      obs%friction_needed = huge(1.0_wp)
    end if
    v_center = ball%radius * cross(obs%omega, n)
    ! z_C - R = z_A - R (1 - n_z), with 1 - n_z = (nx^2 + ny^2)/(1 + n_z): no cancellation
    height_above_rest = obs%contact(3) - ball%radius * (n(1)**2 + n(2)**2) / (1 + n(3))
    obs%energy_of_motion = 0.5_wp * ball%inertia_factor * ball%mass * ball%radius**2 &
        * dot_product(obs%omega, obs%omega) + 0.5_wp * ball%mass * dot_product(v_center, v_center) &
        + ball%mass * ball%g * height_above_rest
    obs%energy = obs%energy_of_motion + ball%mass * ball%g * ball%radius
    obs%surface_residual = surface_residual(ball%cup, obs%contact)
    ! R' = R (1 + margin) is below both principal radii r1 <= r2 exactly when
    ! (R' - r1)(R' - r2) = R'^2 - R' tr K + det K > 0 and R' < (r1 + r2) / 2
    k = radius_operator(ball%cup, n)
    fit_radius = ball%radius * (1 + ball%fit_margin)
    obs%fits = fit_radius * (fit_radius - k%trace) + k%det > 0 .and. 2 * fit_radius < k%trace
  end function observe

  !> The nutation angle Theta, between n and the vertical (rad), from the
  !> lateral and vertical parts of the unit normal.
  elemental real(wp) function nutation_angle(lateral, normal_z)
    real(wp), intent(in) :: lateral, normal_z
    nutation_angle = atan2(lateral, normal_z)
  end function nutation_angle

  !> status_completed while the state is inside the model's domain, otherwise
  !> the limit it crossed (first match in the order of physics.md).
  pure integer function limit_status(ball, y, obs) result(status)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(:)
    type(observation_t), intent(in) :: obs
    if (.not. all(ieee_is_finite(y)) .or. .not. ieee_is_finite(obs%energy) &
        .or. .not. all(ieee_is_finite(obs%reaction))) then
      status = status_nonfinite
    else if (obs%normal(3) <= 0) then
      status = status_rim
    else if (.not. obs%fits) then
      status = status_no_fit
    else if (obs%surface_residual > constraint_tolerance) then
      status = status_constraint
    else if (obs%reaction_normal <= 0) then
      status = status_liftoff
    else if (ball%mu > 0 .and. obs%friction_needed > ball%mu) then
      status = status_slip
    else
      status = status_completed
    end if
  end function limit_status
end module ellroll_rolling_ball
