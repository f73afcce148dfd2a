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
  use ellroll_exact, only: is_zero
  use ellroll_norms, only: norm_of, tangential_size, horizontal_force_scaled
  use ellroll_ode, only: hybrid_system_t
  use ellroll_ellipsoid, only: ellipsoid_t, contact_point, normal_from_contact, surface_residual
  use ellroll_excitation, only: excitation_t, excitation_none, base_acceleration
  use ellroll_status, only: status_completed, status_rim, status_no_fit, status_slip, &
      status_liftoff, status_nonfinite, status_constraint
  use ellroll_quantities, only: peak_clearance
  implicit none
  private

  public :: rolling_ball_t, observation_t, state_size
  public :: initial_state, observe, horizontal_force_scaled, limit_status, constraint_tolerance, ball_derivative, &
            nutation_angle, stage_status, fit_indicator, normalize_normal, smooth_part, at_rest, cross, &
            rolling_rate, rest_rate, rolling_part, couple_inertia, is_still

  !> How a fixed step directs the couple of rolling resistance
  !> (choose_rolling_law): against the rolling part of omega as it is
  !> (law_exact), against its direction at the step's start (law_held), or
  !> against the rolling part an implicit Euler step of the whole step would
  !> reach, omega_t + h F_t (law_implicit; F_t the rolling part's rate
  !> without the couple).
  integer, parameter, public :: law_exact = 0, law_held = 1, law_implicit = 2

  integer, parameter :: state_size = 6
  !> Largest surface residual accepted before a case ends with 'constraint'.
  real(wp), parameter :: constraint_tolerance = 1.0e-10_wp

  !> The model's events (hybrid_system_t): the rolling stops (rolling
  !> resistance; the ball at rest there).
  integer, parameter, public :: event_rest = 1

  !> Where the rolling stops inside a step is located to this part of the step.
  real(wp), parameter :: rest_tolerance = 1.0e-12_wp

  type, extends(hybrid_system_t) :: rolling_ball_t
    type(ellipsoid_t) :: cup
    real(wp) :: radius = 1
    real(wp) :: mass = 1
    real(wp) :: g = 9.81_wp
    real(wp) :: inertia_factor = 0.4_wp   !< J / (m R^2)
    real(wp) :: mu = -1                   !< friction coefficient; <= 0: no slip check
    real(wp) :: fit_margin = 1.0e-6_wp    !< end when r_min / R - 1 falls to this
    type(excitation_t) :: excitation      !< translation of the cup
    real(wp) :: rolling_resistance = 0    !< delta: a couple delta N against the rolling, m
    !> the direction of the rolling where the step started (begin_step):
    !> a stage past the stop keeps the couple against it, so that the flow up
    !> to the stop stays smooth inside the step that is cut there
    real(wp) :: rolling_mode(3) = 0
    real(wp) :: rolling_at_start(3) = 0   !< the rolling part of omega where the step started
    !> the couple's law for the step (law_exact unless a fixed step chose
    !> another: choose_rolling_law; begin_step sets law_exact) and the
    !> step h law_implicit looks ahead by
    integer :: rolling_law = law_exact
    real(wp) :: law_step = 0
  contains
    procedure :: rhs => ball_rhs
    procedure :: stage_status => ball_stage_status
    procedure :: reaction_limited
    procedure :: nonsmooth => ball_nonsmooth
    procedure :: begin_step => ball_begin_step
    procedure :: event_crossed => ball_event_crossed
    procedure :: event_start_value => ball_event_start_value
    procedure :: event_value => ball_event_value
    procedure, nopass :: event_tolerance => ball_event_tolerance
    procedure :: apply_event => ball_apply_event
  end type rolling_ball_t

  !> Everything derived from one state and its time derivative (observe sets
  !> every component; no default values, so that none is copied in per call).
  type :: observation_t
    real(wp) :: normal(3)
    real(wp) :: omega(3)
    real(wp) :: contact(3)
    real(wp) :: center(3)
    real(wp) :: lateral              !< |(n_x, n_y)| (norm_of): Theta = atan2(lateral, n_z)
    real(wp) :: tan_nutation         !< tan Theta (huge past the rim): cheap, and ordered like Theta
    real(wp) :: reaction(3)          !< force of the cup on the ball, N
    real(wp) :: reaction_normal      !< N = F . n
    real(wp) :: horizontal_force_scaled  !< |(F_x, F_y)| / 2^exponent(m) (ellroll_quantities)
    real(wp) :: friction_needed      !< |F_t| / N
    real(wp) :: energy               !< J |w|^2/2 + m |V_C|^2/2 + m g z_C
    real(wp) :: energy_of_motion     !< energy - m g R (the bottom at rest is 0)
    real(wp) :: surface_residual
    logical :: fits            !< r_min > R (1 + fit_margin): the ball fits the cup here
    real(wp) :: fit_clearance  !< > 0 where r_min > R (1 + peak_clearance) (ellroll_quantities)
    real(wp) :: base_acceleration(3) !< acceleration of the cup, m/s^2
    real(wp) :: center_acceleration(3)  !< absolute acceleration of the centre, m/s^2
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
  !> From y as it is (y = L n between projections, L = |y|), with q = y . A y
  !> = L^2 s^2 and sigma = sqrt(q), every quotient over one denominator:
  !>   E = sigma^3 (R - tr K) = R sigma q - L P,   P = tr(A) q - |A y|^2,
  !>   D = sigma^4 det L = R sigma E + det(A) L^4,
  !>   n' = R sigma (E w + L M) / D,   w = omega x y,  M = q A w - (A y . w) A y,
  !>   omega' = J* ((omega . y) / L^2 n' + (g / R) (-y_y, y_x, 0) / L).
  !> The two roots and the quotients by D and L^2 are the only long operations,
  !> and the longest chain (q, sigma, E, D, 1/D) is a fifth shorter than with
  !> 1/|y|, 1/q and 1/det L each in turn. fits, when asked for: whether y lies
  !> where the equations hold, the rim not reached and the ball fitting the
  !> cup, from the same q, sigma and P (fit_indicator). base, when given: the
  !> cup's acceleration at t (two stages at one time look it up once).
  pure subroutine ball_derivative(ball, t, y, dydt, fits, base, resting)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(state_size)
    real(wp), intent(out) :: dydt(state_size)
    logical, intent(out), optional :: fits
    real(wp), intent(in), optional :: base(3)
    logical, intent(in), optional :: resting   !< at rest, the couple a resting ball's whatever the step's mode
    real(wp) :: r, length2, length, inv_length2, ay(3), q, sigma, r_sigma, pq, e, denominator, w(3), ay_w, m(3), x(3)
    real(wp) :: rate
    r = ball%radius
    length2 = y(1) * y(1) + y(2) * y(2) + y(3) * y(3)
    length = sqrt(length2)
    inv_length2 = 1 / length2
    ay = ball%cup%axes2 * y(1:3)
    q = y(1) * ay(1) + y(2) * ay(2) + y(3) * ay(3)
    sigma = sqrt(q)
    pq = sum(ball%cup%axes2) * q - (ay(1) * ay(1) + ay(2) * ay(2) + ay(3) * ay(3))
    r_sigma = r * sigma
    e = r_sigma * q - length * pq
    denominator = r_sigma * e + ball%cup%det_axes2 * (length2 * length2)
    if (present(fits)) fits = min(y(3), fit_indicator(r * (1 + ball%fit_margin) * sigma, q, length, pq, &
                                                      ball%cup%det_axes2 * (length2 * length2))) > 0
    w = [y(5) * y(3) - y(6) * y(2), y(6) * y(1) - y(4) * y(3), y(4) * y(2) - y(5) * y(1)]
    ay_w = ay(1) * w(1) + ay(2) * w(2) + ay(3) * w(3)
    m = q * (ball%cup%axes2 * w) - ay_w * ay
    x = e * w + length * m
    rate = 0                ! (D near 0: no fit, where an implicit method's iterate may go; no overflow)
    if (abs(denominator) > (r_sigma / sqrt(huge(1.0_wp))) * max(abs(x(1)), abs(x(2)), abs(x(3)))) &
      rate = r_sigma / denominator
    dydt(1:3) = rate * x
    associate (j_star => 1 / (1 + ball%inertia_factor))
      dydt(4:6) = ((j_star * (y(4) * y(1) + y(5) * y(2) + y(6) * y(3)) * inv_length2) * rate) * x &
                  + ((ball%g / r) * j_star * (length * inv_length2)) * [-y(2), y(1), 0.0_wp]
      ! a moving cup: g_vec - a_base in the cup's frame (only when it moves, so
      ! a fixed cup costs nothing)
      if (ball%excitation%kind /= excitation_none) then
        if (present(base)) then
          dydt(4:6) = dydt(4:6) - cross(y(1:3) * (length * inv_length2), base) / (ball%radius * (1 + ball%inertia_factor))
        else
          dydt(4:6) = dydt(4:6) - cross(y(1:3) * (length * inv_length2), base_acceleration(ball%excitation, t)) &
                      / (ball%radius * (1 + ball%inertia_factor))
        end if
      end if
    end associate
    if (ball%rolling_resistance > 0) call resist_rolling(ball, t, y, length, dydt, base, resting)
  end subroutine ball_derivative

  !> The couple of rolling resistance, delta N against the rolling part
  !> omega_t = omega - (omega . n) n of the angular velocity (the spin about
  !> n is free): omega' gains -delta N omega_t / |omega_t| / (m R^2 (1 + k)),
  !> N = m (R omega . (n' x n) + (a_base - g_vec) . n) the normal force.
  !> At rest (omega_t = 0, as come_to_rest leaves it) the couple holds the
  !> ball up to delta N against the couple m R n x (g_vec - a_base) that
  !> would start it rolling: within that, the state stays exactly as it is;
  !> beyond it, the ball starts rolling that way, the couple against it.
  !> The sums and norms are written out in the order the batch's
  !> lanes_resist_rolling takes them (base: the cup's acceleration at t,
  !> when known).
  pure subroutine resist_rolling(ball, t, y, length, dydt, base, resting)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, y(state_size), length
    real(wp), intent(inout) :: dydt(state_size)
    real(wp), intent(in), optional :: base(3)
    logical, intent(in), optional :: resting
    real(wp) :: n(3), omega_t(3), gravity(3), drive(3), turn(3), normal_force, resistance, rate, drive_size, inv_length
    real(wp) :: ahead(3), ahead_size
    logical :: moving, flows
    inv_length = 1 / length
    n = y(1:3) * inv_length
    gravity = [0.0_wp, 0.0_wp, -ball%g]
    if (ball%excitation%kind /= excitation_none) then
      if (present(base)) then
        gravity = gravity - base
      else
        gravity = gravity - base_acceleration(ball%excitation, t)
      end if
    end if
    turn = cross(dydt(1:3), n)
    normal_force = ball%mass * (ball%radius * (y(4) * turn(1) + y(5) * turn(2) + y(6) * turn(3)) * inv_length &
                                - (gravity(1) * n(1) + gravity(2) * n(2) + gravity(3) * n(3)))
    resistance = ball%rolling_resistance * max(normal_force, 0.0_wp)
    omega_t = y(4:6) - (y(4) * n(1) + y(5) * n(2) + y(6) * n(3)) * n
    rate = sqrt(omega_t(1) * omega_t(1) + omega_t(2) * omega_t(2) + omega_t(3) * omega_t(3))
    moving = rate > rest_rate(ball, y)
    ! a stage at the stop of a step that began rolling keeps the flow's law (against the mode), so
    ! that the step's stages and interpolant are smooth up to the stop
    flows = ball%rolling_law /= law_implicit .and. sum(ball%rolling_mode**2) > 0
    if (present(resting)) flows = flows .and. .not. resting
    if (moving .or. flows) then
      if (ball%rolling_law == law_implicit) then
        ! against omega_t + h F_t, F_t from dydt without the couple (yet)
        ahead = omega_t + ball%law_step * rolling_rate(y, dydt)
        ahead_size = sqrt(ahead(1) * ahead(1) + ahead(2) * ahead(2) + ahead(3) * ahead(3))
        if (ahead_size > 0) then
          dydt(4:6) = dydt(4:6) - (resistance / (ahead_size * couple_inertia(ball))) * ahead
        else
          dydt(4:6) = dydt(4:6) - (resistance / couple_inertia(ball)) * ball%rolling_mode
        end if
      else if (ball%rolling_law == law_held .or. .not. moving .or. omega_t(1) * ball%rolling_mode(1) &
               + omega_t(2) * ball%rolling_mode(2) + omega_t(3) * ball%rolling_mode(3) < 0) then
        ! held, or at or past the stop inside the step cut there
        dydt(4:6) = dydt(4:6) - (resistance / couple_inertia(ball)) * ball%rolling_mode
      else
        dydt(4:6) = dydt(4:6) - (resistance / (rate * couple_inertia(ball))) * omega_t
      end if
      return
    end if
    drive = (ball%mass * ball%radius) * cross(n, gravity)
    drive_size = sqrt(drive(1) * drive(1) + drive(2) * drive(2) + drive(3) * drive(3))
    if (drive_size <= resistance) then
      dydt = 0                                   ! held: at rest
    else
      dydt(4:6) = dydt(4:6) - (resistance / (drive_size * couple_inertia(ball))) * drive
    end if
  end subroutine resist_rolling

  !> m R^2 (1 + k): a couple over it is its angular acceleration.
  pure real(wp) function couple_inertia(ball)
    type(rolling_ball_t), intent(in) :: ball
    couple_inertia = ball%mass * ball%radius**2 * (1 + ball%inertia_factor)
  end function couple_inertia

  !> Below this rolling rate the ball is at rest (come_to_rest leaves round-off
  !> only); written out as lanes_rolling_mode takes it.
  pure real(wp) function rest_rate(ball, y)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(state_size)
    rest_rate = 1.0e-12_wp * (sqrt(ball%g / ball%radius) + sqrt(y(4) * y(4) + y(5) * y(5) + y(6) * y(6)))
  end function rest_rate

  !> Whether the ball is at rest on the cup at time t, state y: with
  !> rolling resistance, no rolling (the spin about the normal is free), as
  !> come_to_rest leaves it, and held there by the couple (resist_rolling:
  !> the state constant), not at a turn it rolls back from. Without it the
  !> ball has no rest but the bottom's unstable balance of round-off: false.
  !> (The batch's lanes_at_rest is the same test on each lane, from its
  !> derivative at the step's end.)
  pure logical function at_rest(ball, t, y)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, y(state_size)
    real(wp) :: dydt(state_size)
    at_rest = .false.
    if (.not. is_still(ball, y)) return
    call ball_derivative(ball, t, y, dydt, resting=.true.)
    at_rest = all(is_zero(dydt))
  end function at_rest

  !> Whether the ball rolls no more at state y than a rest leaves
  !> (rest_rate), with rolling resistance: its normal still, at a rest or a
  !> stop (a turn) that come_to_rest placed. Without rolling resistance no
  !> state is (a turn is inside a step, smooth).
  pure logical function is_still(ball, y)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(:)
    real(wp) :: omega_t(3)
    is_still = .false.
    if (.not. ball%rolling_resistance > 0) return
    omega_t = rolling_part(y(:state_size))
    is_still = .not. sqrt(omega_t(1) * omega_t(1) + omega_t(2) * omega_t(2) + omega_t(3) * omega_t(3)) &
                     > rest_rate(ball, y(:state_size))
  end function is_still

  !> The rolling part of the angular velocity at state y (written out as
  !> the batch's lanes_rolling_mode takes it).
  pure function rolling_part(y) result(omega_t)
    real(wp), intent(in) :: y(state_size)
    real(wp) :: omega_t(3), n(3)
    n = y(1:3) / sqrt(y(1) * y(1) + y(2) * y(2) + y(3) * y(3))
    omega_t = y(4:6) - (y(4) * n(1) + y(5) * n(2) + y(6) * n(3)) * n
  end function rolling_part

  !> Whether the model has non-smooth laws (rolling resistance): a mode
  !> per step and events (hybrid_system_t).
  pure logical function ball_nonsmooth(self) result(nonsmooth)
    class(rolling_ball_t), intent(in) :: self
    nonsmooth = self%rolling_resistance > 0
  end function ball_nonsmooth

  !> The model without its non-smooth laws: their forces turn with the
  !> motion and have no derivative where it stops; they take energy, they
  !> set no frequency (ellroll_linear).
  pure function smooth_part(ball) result(smooth)
    type(rolling_ball_t), intent(in) :: ball
    type(rolling_ball_t) :: smooth
    smooth = ball
    smooth%rolling_resistance = 0
  end function smooth_part

  !> The mode of a step from y: with rolling resistance, the direction of
  !> the rolling there (set_rolling_mode), the couple against the rolling
  !> as it is (law_exact).
  pure subroutine ball_begin_step(self, y)
    class(rolling_ball_t), intent(inout) :: self
    real(wp), intent(in), contiguous :: y(:)
    self%rolling_law = law_exact
    if (self%rolling_resistance > 0) call set_rolling_mode(self, y)
  end subroutine ball_begin_step

  !> The rate of the rolling part omega_t = omega - (omega . n) n at y
  !> with derivative f: its projection on the tangent plane less (omega .
  !> n) n' (written out as the batch's lanes take it).
  pure function rolling_rate(y, f) result(rate)
    real(wp), intent(in) :: y(state_size), f(state_size)
    real(wp) :: rate(3), n(3), inv_length, spin, along
    inv_length = 1 / sqrt(y(1) * y(1) + y(2) * y(2) + y(3) * y(3))
    n = y(1:3) * inv_length
    spin = y(4) * n(1) + y(5) * n(2) + y(6) * n(3)
    along = f(4) * n(1) + f(5) * n(2) + f(6) * n(3)
    rate = f(4:6) - along * n - (spin * inv_length) * f(1:3)
  end function rolling_rate

  !> event_rest where the rolling stops inside a step from y_start to y_end
  !> (rolling_stops), else 0.
  pure integer function ball_event_crossed(self, y_start, y_end) result(event)
    class(rolling_ball_t), intent(in) :: self
    real(wp), intent(in), contiguous :: y_start(:), y_end(:)
    event = 0
    if (rolling_stops(self, y_start, y_end)) event = event_rest
  end function ball_event_crossed

  !> event_rest's function at the step's start: the square of the rolling
  !> part of omega there (begin_step), positive where the ball rolls.
  pure real(wp) function ball_event_start_value(self, event) result(g)
    class(rolling_ball_t), intent(in) :: self
    integer, intent(in) :: event
    g = 1
    if (event == event_rest) g = dot_product(self%rolling_at_start, self%rolling_at_start)
  end function ball_event_start_value

  !> event_rest's function at y: the rolling part of omega along its value
  !> at the step's start; it turns non-positive where the rolling stops.
  pure real(wp) function ball_event_value(self, event, y) result(g)
    class(rolling_ball_t), intent(in) :: self
    integer, intent(in) :: event
    real(wp), intent(in), contiguous :: y(:)
    g = 1
    if (event == event_rest) g = rolling_along(y, self%rolling_at_start)
  end function ball_event_value

  pure real(wp) function ball_event_tolerance(event) result(tolerance)
    integer, intent(in) :: event
    tolerance = 0                       ! (there is no other event)
    if (event == event_rest) tolerance = rest_tolerance
  end function ball_event_tolerance

  !> event_rest: the ball at rest (come_to_rest).
  pure subroutine ball_apply_event(self, event, y)
    class(rolling_ball_t), intent(inout) :: self
    integer, intent(in) :: event
    real(wp), intent(inout), contiguous :: y(:)
    if (.not. (event == event_rest .and. self%rolling_resistance > 0)) return
    call come_to_rest(y)
    call set_rolling_mode(self, y)        ! (at rest: no mode)
  end subroutine ball_apply_event

  !> With rolling resistance, whether the rolling stops inside a step from
  !> y_start to y_end: it rolled at the start, and its rolling part turned
  !> by more than a right angle (where the couple turns against the motion,
  !> an event: the step is cut there).
  pure logical function rolling_stops(ball, y_start, y_end)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y_start(state_size), y_end(state_size)
    real(wp) :: start(3)
    rolling_stops = .false.
    if (.not. ball%rolling_resistance > 0) return
    start = rolling_part(y_start)
    if (.not. sqrt(start(1) * start(1) + start(2) * start(2) + start(3) * start(3)) > rest_rate(ball, y_start)) return
    rolling_stops = rolling_along(y_end, start) <= 0
  end function rolling_stops

  !> The rolling part of the angular velocity at y along direction.
  pure real(wp) function rolling_along(y, direction)
    real(wp), intent(in) :: y(state_size), direction(3)
    real(wp) :: omega_t(3)
    omega_t = rolling_part(y)
    rolling_along = omega_t(1) * direction(1) + omega_t(2) * direction(2) + omega_t(3) * direction(3)
  end function rolling_along

  !> The direction of the rolling at y (zero at rest) as the ball's mode for
  !> a step from y.
  pure subroutine set_rolling_mode(ball, y)
    type(rolling_ball_t), intent(inout) :: ball
    real(wp), intent(in) :: y(state_size)
    real(wp) :: omega_t(3), rate
    omega_t = rolling_part(y)
    rate = sqrt(omega_t(1) * omega_t(1) + omega_t(2) * omega_t(2) + omega_t(3) * omega_t(3))
    ball%rolling_at_start = omega_t
    ball%rolling_mode = 0
    if (rate > rest_rate(ball, y)) ball%rolling_mode = omega_t / rate
  end subroutine set_rolling_mode

  !> The rolling part of the angular velocity at y set to zero (the spin
  !> about the normal kept): the ball at rest, where the couple decides.
  pure subroutine come_to_rest(y)
    real(wp), intent(inout) :: y(state_size)
    real(wp) :: n(3)
    n = y(1:3) / norm2(y(1:3))
    y(4:6) = dot_product(y(4:6), n) * n
  end subroutine come_to_rest

  !> The state back on the model's manifold: the normal of unit length.
  pure subroutine normalize_normal(y)
    real(wp), intent(inout) :: y(:)
    y(1:3) = y(1:3) / sqrt(dot_product(y(1:3), y(1:3)))
  end subroutine normalize_normal

  !> Whether the ball of fit radius R' = R (1 + fit_margin) fits the cup at
  !> the normal y / |y|: R' below both principal radii r1 <= r2, i.e.
  !> (R' - r1)(R' - r2) > 0 and 2 R' < r1 + r2. In ball_derivative's terms
  !> (q = y . A y, sigma = sqrt(q), P = tr(A) q - |A y|^2, L = |y|):
  !>   sigma^4 (R'^2 - R' tr K + det K) = R' sigma (R' sigma q - L P) + det(A) L^4,
  !>   tr K > 2 R'  <=>  L P > 2 R' sigma q;
  !> r_fit_sigma = R' sigma, det_length4 = det(A) L^4: fit_indicator is
  !> positive exactly when the ball fits (the smaller of the two left-hand
  !> sides), NaN for NaN; a min, so that a loop over lanes vectorizes.
  elemental real(wp) function fit_indicator(r_fit_sigma, q, length, pq, det_length4)
    real(wp), intent(in) :: r_fit_sigma, q, length, pq, det_length4
    real(wp) :: e_fit
    e_fit = r_fit_sigma * q - length * pq
    fit_indicator = min(r_fit_sigma * e_fit + det_length4, -(e_fit + r_fit_sigma * q))
  end function fit_indicator

  !> The limits at a state that a step evaluates the model at (a stage),
  !> with its derivative: 0 where the model holds there, else the status of
  !> the limit (first match in limit_status's order). fits is
  !> ball_derivative's; the reaction's limits (lift-off, slip) are looked
  !> at only in the scenes that have them: a moving cup, a friction limit.
  !> (On a fixed cup, N >= m g n_z > 0 wherever the ball fits, so lift-off
  !> cannot come first.)
  pure integer function stage_status(ball, t, y, dydt, fits, base) result(status)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, y(state_size), dydt(state_size)
    logical, intent(in) :: fits
    real(wp), intent(in), optional :: base(3)      !< the cup's acceleration at t, when known
    real(wp) :: n(3), force(3), normal_force, tangential(3)
    status = 0
    if (.not. fits) then
      if (.not. (all(ieee_is_finite(y)) .and. all(ieee_is_finite(dydt)))) then
        status = status_nonfinite
      else if (y(3) <= 0) then
        status = status_rim
      else
        status = status_no_fit
      end if
    else if (ball%reaction_limited()) then
      ! where the ball fits, only the reaction can end the case: the force of
      ! the cup as observe computes it, and nothing else of observe's
      n = y(1:3) / sqrt(y(1)**2 + y(2)**2 + y(3)**2)
      force = reaction_force(ball, t, y(4:6), n, dydt(1:3) / sqrt(y(1)**2 + y(2)**2 + y(3)**2), dydt(4:6), base)
      normal_force = force(1) * n(1) + force(2) * n(2) + force(3) * n(3)
      tangential = force - normal_force * n
      if (.not. all(ieee_is_finite(force))) then
        status = status_nonfinite
      else if (normal_force <= 0) then
        status = status_liftoff
      else if (ball%mu > 0) then
        if (tangential_size(tangential) / normal_force > ball%mu) status = status_slip
      end if
    end if
  end function stage_status

  !> The force of the cup on the ball, m (a_C + a_base - g_vec) with
  !> a_C = R (omega' x n + omega x n'), in the inertial frame, in units of
  !> 2^exponent(m) N (its sign and the friction ratio are those in N, and
  !> a light ball's squares do not underflow).
  pure function reaction_force(ball, t, omega, n, n_dot, omega_dot, base) result(force)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, omega(3), n(3), n_dot(3), omega_dot(3)
    real(wp), intent(in), optional :: base(3)
    real(wp) :: force(3)
    force = ball%radius * (cross(omega_dot, n) + cross(omega, n_dot)) + [0.0_wp, 0.0_wp, ball%g]
    if (present(base)) then
      force = force + base
    else if (ball%excitation%kind /= excitation_none) then
      force = force + base_acceleration(ball%excitation, t)
    end if
    force = fraction(ball%mass) * force
  end function reaction_force

  !> Whether the reaction force can end the case: a cup that moves (lift-off)
  !> or a friction limit (slip).
  pure logical function reaction_limited(self)
    class(rolling_ball_t), intent(in) :: self
    reaction_limited = self%excitation%kind /= excitation_none .or. self%mu > 0
  end function reaction_limited

  !> stage_status behind the ODE interface (the generic steps).
  pure integer function ball_stage_status(self, t, y, dydt) result(status)
    class(rolling_ball_t), intent(in) :: self
    real(wp), intent(in) :: t, y(:), dydt(:)
    real(wp) :: scratch(state_size)
    logical :: fits
    call ball_derivative(self, t, y, scratch, fits)
    status = stage_status(self, t, y, dydt, fits)
  end function ball_stage_status

  !> State for a start at contact point (x, y) of the lower half.
  pure function initial_state(ball, x, y, omega) result(state)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: x, y, omega(3)
    real(wp) :: state(state_size)
    state(1:3) = normal_from_contact(ball%cup, x, y)
    state(4:6) = omega
  end function initial_state

  !> Every derived output of a state y at time t with time derivative dydt,
  !> written out flat: one 1/|y| serves every quantity, and the contact
  !> point's 1/s the fit test's tr K and det K. The batch's lanes_observe
  !> is the same arithmetic, expression by expression (tested to 8 eps: the
  !> compiler fuses multiply-adds differently in the vector code).
  pure subroutine observe(ball, t, y, dydt, obs, base)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(:), dydt(:)
    type(observation_t), intent(out) :: obs
    real(wp), intent(in), optional :: base(3)      !< the cup's acceleration at t, when known
    real(wp) :: r, m, inv_length, n(3), inv_s, inv_s2, p(3), n_dot(3), a_center(3)
    real(wp) :: tangential(3), v_center(3), height_above_rest, an(3), trace, det, fit_radius
    real(wp) :: scaled_force(3), scaled_normal
    r = ball%radius
    m = ball%mass
    inv_length = 1 / sqrt(y(1)**2 + y(2)**2 + y(3)**2)
    n = y(1:3) * inv_length
    obs%normal = n
    obs%omega = y(4:6)
    call contact_point(ball%cup, n, p, inv_s)
    obs%contact = p
    obs%center = p + r * n
    obs%lateral = norm_of(n(1), n(2))
    ! tan Theta where it does not overflow, n_z > lateral tiny; the product is
    ! taken only where n_z is within 2 tiny of 0 (lateral <= 1 elsewhere: the
    ! test holds): one in the subnormal range costs a microcode assist
    obs%tan_nutation = huge(1.0_wp)
    if (n(3) > 2 * tiny(1.0_wp) .and. obs%lateral < 2) then
      obs%tan_nutation = obs%lateral / n(3)
    else if (n(3) > obs%lateral * tiny(1.0_wp)) then
      obs%tan_nutation = obs%lateral / n(3)
    end if
    ! the force of the cup, m (a_C + a_base - g_vec), a_C = R (omega' x n + omega x n')
    n_dot = dydt(1:3) * inv_length
    a_center = r * (cross(dydt(4:6), n) + cross(obs%omega, n_dot))
    obs%base_acceleration = 0
    if (present(base)) then
      obs%base_acceleration = base
    else if (ball%excitation%kind /= excitation_none) then
      obs%base_acceleration = base_acceleration(ball%excitation, t)
    end if
    obs%center_acceleration = a_center + obs%base_acceleration
    obs%reaction = m * (obs%center_acceleration + [0.0_wp, 0.0_wp, ball%g])
    obs%reaction_normal = obs%reaction(1) * n(1) + obs%reaction(2) * n(2) + obs%reaction(3) * n(3)
    ! the horizontal force and the friction ratio from the force in units of
    ! 2^exponent(m) N: the same digits, and no underflow for a light ball
    scaled_force = fraction(m) * (obs%center_acceleration + [0.0_wp, 0.0_wp, ball%g])
    obs%horizontal_force_scaled = norm_of(scaled_force(1), scaled_force(2))
    scaled_normal = scaled_force(1) * n(1) + scaled_force(2) * n(2) + scaled_force(3) * n(3)
    tangential = scaled_force - scaled_normal * n
    obs%friction_needed = huge(1.0_wp)
    if (scaled_normal > 0) obs%friction_needed = tangential_size(tangential) / scaled_normal
    ! z_C - R = z_A - R (1 - n_z), with 1 - n_z = (nx^2 + ny^2)/(1 + n_z): no cancellation
    v_center = r * cross(obs%omega, n)
    height_above_rest = p(3) - r * (n(1)**2 + n(2)**2) / (1 + n(3))
    obs%energy_of_motion = 0.5_wp * ball%inertia_factor * m * r**2 &
        * (obs%omega(1) * obs%omega(1) + obs%omega(2) * obs%omega(2) + obs%omega(3) * obs%omega(3)) &
        + 0.5_wp * m * (v_center(1) * v_center(1) + v_center(2) * v_center(2) + v_center(3) * v_center(3)) &
        + m * ball%g * height_above_rest
    obs%energy = obs%energy_of_motion + m * ball%g * r
    obs%surface_residual = surface_residual(ball%cup, p)
    ! R' = R (1 + margin) is below both principal radii r1 <= r2 exactly when
    ! (R' - r1)(R' - r2) = R'^2 - R' tr K + det K > 0 and R' < (r1 + r2) / 2;
    ! K = (A - (An)(An)^T / s^2) / s on the tangent plane
    an = ball%cup%axes2 * n
    inv_s2 = inv_s * inv_s
    trace = (sum(ball%cup%axes2) - (an(1) * an(1) + an(2) * an(2) + an(3) * an(3)) * inv_s2) * inv_s
    det = ball%cup%det_axes2 * inv_s2 * inv_s2
    fit_radius = r * (1 + ball%fit_margin)
    obs%fits = min(fit_radius * (fit_radius - trace) + det, trace - 2 * fit_radius) > 0
    fit_radius = r * (1 + peak_clearance)
    obs%fit_clearance = min(fit_radius * (fit_radius - trace) + det, trace - 2 * fit_radius)
  end subroutine observe

  !> The nutation angle Theta, between n and the vertical (rad), from the
  !> lateral and vertical parts of the unit normal.
  elemental real(wp) function nutation_angle(lateral, normal_z)
    real(wp), intent(in) :: lateral, normal_z
    nutation_angle = atan2(lateral, normal_z)
  end function nutation_angle

  !> status_completed while the state is inside the model's domain, otherwise
  !> the limit it crossed (the first that matches, in the order below).
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
