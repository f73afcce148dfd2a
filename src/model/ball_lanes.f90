!> Several balls advanced together, one per SIMD lane: the
!> state is stored structure-of-arrays, y(lane, component), and every kernel
!> is a loop over lanes of straight-line scalar code that the compiler
!> vectorizes across cases. The arithmetic is that of the one-case path
!> (ball_derivative, observe, limit_status), written out
!> expression by expression in the same order; the batch is tested against
!> it. Lanes never interact, so a case's result does not depend on which
!> lane or which batch it runs in. A lane's cup may move (ellroll_excitation):
!> the kernels then take each lane's acceleration of the cup at its time
!> (base, from ellroll_excitation_lanes), and a lane whose cup does not move
!> computes bitwise what it computes in a batch of fixed cups.
module ellroll_ball_lanes
  use ellroll_kinds, only: wp
  use ellroll_norms, only: small_sum, norm_up, norm_down
  use ellroll_rolling_ball, only: rolling_ball_t, state_size, constraint_tolerance
  use ellroll_excitation, only: excitation_none
  use ellroll_quantities, only: quantity_count, q_displacement, q_horizontal_force_scaled, q_reaction_normal, &
      q_friction_needed, q_energy, q_surface_residual, q_fit_clearance, peak_clearance
  use ellroll_status, only: status_completed, status_rim, status_no_fit, status_slip, &
      status_liftoff, status_nonfinite, status_constraint
  implicit none
  private

  public :: lanes, ball_lanes_t, lane_outputs_t, runs_in_lanes, set_lane, lanes_derivative, lanes_observe
  public :: lanes_rolling_mode, lanes_rolling_stops, lanes_at_rest, lanes_may_stiffen, keep_accepted

  !> Cases per batch: two AVX2 or one AVX-512 register of doubles.
  integer, parameter :: lanes = 8

  !> One ball and cup per lane, with the constants the kernels use.
  type :: ball_lanes_t
    real(wp), dimension(lanes) :: c = 1, inv_a = 1, inv_b = 1, inv_c = 1
    real(wp), dimension(lanes) :: a2 = 1, b2 = 1, c2 = 1   !< squared semi-axes
    real(wp), dimension(lanes) :: axes2_sum = 3, det_axes2 = 1
    real(wp), dimension(lanes) :: radius = 1, mass = 1, g = 1, inertia_factor = 0.4_wp
    !> m / 2^exponent(m): the forces the friction ratio and the horizontal
    !> force are formed from, in units of 2^exponent(m) N (ellroll_quantities)
    real(wp), dimension(lanes) :: mass_fraction = 1
    real(wp), dimension(lanes) :: g_over_r = 1, inv_one_plus_k = 1, fit_radius = 1, mu = -1
    real(wp), dimension(lanes) :: base_divisor = 1      !< R (1 + k): the moving cup's couple over it
    !> the kernels compute lanes 1 to width only (a lone case: 1; the lanes
    !> past it hold 0 derivatives and their outputs as they were): a lane's
    !> arithmetic is the same at every width (tested: a case alone in a
    !> batch equals it among others bitwise)
    integer :: width = lanes
    !> 1 where the lane's cup moves, else 0 (a mask of the data's width: a
    !> logical's, narrower, keeps a merge from vectorizing)
    real(wp) :: moves(lanes) = 0
    !> rolling resistance (delta, m; 0: none) and, for a step, each lane's
    !> mode (ball_begin_step's, from lanes_rolling_mode): the direction of
    !> the rolling at its start (0 at rest), the rolling part of omega there,
    !> and 1 where it rolls, else 0
    real(wp) :: resistance(lanes) = 0
    !> rolling resistance's constants: sqrt(g / R) (rest_rate's), m R and
    !> m R^2 (1 + k) (couple_inertia's), as the one-case code computes them
    real(wp), dimension(lanes) :: rest_scale = 1, mass_radius = 1, couple_inertia = 1
    real(wp) :: rolling_mode(lanes, 3) = 0, rolling_at_start(lanes, 3) = 0, rolls(lanes) = 0
    !> each lane's law of the couple for the step (rolling_law's law_exact,
    !> law_held, law_implicit as 0, 1, 2) and the step law_implicit looks
    !> ahead by (choose_rolling_law on the lane: ellroll_lane_laws)
    real(wp) :: law(lanes) = 0, law_step(lanes) = 0
    logical :: resists = .false.          !< some lane has rolling resistance
  end type ball_lanes_t

  !> What the summary, the limits and the stored samples need of a state, per lane.
  type :: lane_outputs_t
    real(wp), dimension(lanes, 3) :: normal = 0, contact = 0, reaction = 0
    !> the absolute acceleration of the centre (a_C + a_base, m/s^2)
    real(wp), dimension(lanes, 3) :: center_acceleration = 0
    real(wp), dimension(lanes) :: tan_nutation = 0, lateral = 0
    !> the step-end quantities (ellroll_quantities: the displacement, the
    !> horizontal force in units of 2^exponent(m) N, the normal force, the
    !> friction needed, the energy, the surface residual), a column each
    real(wp) :: quantity(lanes, quantity_count) = 0
    integer, dimension(lanes) :: status = status_completed
  end type lane_outputs_t

contains

  !> Whether a ball's scene runs in lanes with a method with fixed steps
  !> (fixed_steps) or an embedded pair: the kernels here hold fixed and
  !> moving cups, and rolling resistance on fixed steps (each lane its
  !> mode per step, lanes_rolling_mode, and its rest events, located on the
  !> one-case code: an adaptive step ends at the event, which an attempt
  !> of all lanes does not).
  pure logical function runs_in_lanes(ball, fixed_steps)
    type(rolling_ball_t), intent(in) :: ball
    logical, intent(in) :: fixed_steps
    runs_in_lanes = .not. ball%nonsmooth() .or. fixed_steps
  end function runs_in_lanes

  !> Put a ball into lane l (its cup's motion: ellroll_excitation_lanes).
  pure subroutine set_lane(p, l, ball)
    type(ball_lanes_t), intent(inout) :: p
    integer, intent(in) :: l
    type(rolling_ball_t), intent(in) :: ball
    p%c(l) = ball%cup%c
    p%inv_a(l) = ball%cup%inv_axes(1)
    p%inv_b(l) = ball%cup%inv_axes(2)
    p%inv_c(l) = ball%cup%inv_axes(3)
    p%a2(l) = ball%cup%axes2(1)
    p%b2(l) = ball%cup%axes2(2)
    p%c2(l) = ball%cup%axes2(3)
    p%axes2_sum(l) = sum(ball%cup%axes2)
    p%det_axes2(l) = ball%cup%det_axes2
    p%radius(l) = ball%radius
    p%mass(l) = ball%mass
    p%mass_fraction(l) = fraction(ball%mass)
    p%g(l) = ball%g
    p%inertia_factor(l) = ball%inertia_factor
    p%g_over_r(l) = ball%g / ball%radius
    p%inv_one_plus_k(l) = 1 / (1 + ball%inertia_factor)
    p%fit_radius(l) = ball%radius * (1 + ball%fit_margin)
    p%mu(l) = ball%mu
    p%base_divisor(l) = ball%radius * (1 + ball%inertia_factor)
    p%moves(l) = merge(1.0_wp, 0.0_wp, ball%excitation%kind /= excitation_none)
    p%resistance(l) = max(ball%rolling_resistance, 0.0_wp)
    p%rest_scale(l) = sqrt(ball%g / ball%radius)
    p%mass_radius(l) = ball%mass * ball%radius
    p%couple_inertia(l) = ball%mass * ball%radius**2 * (1 + ball%inertia_factor)
    p%rolling_mode(l, :) = 0
    p%rolling_at_start(l, :) = 0
    p%rolls(l) = 0
    p%law(l) = 0
    p%resists = any(p%resistance > 0)
  end subroutine set_lane

  !> |n| of lane l's state (its first three components), 1/|n| and n/|n|.
  pure subroutine unit_normal(y, l, length, inv_length, n1, n2, n3)
    real(wp), intent(in) :: y(lanes, state_size)
    integer, intent(in) :: l
    real(wp), intent(out) :: length, inv_length, n1, n2, n3
    length = sqrt(y(l, 1)**2 + y(l, 2)**2 + y(l, 3)**2)
    inv_length = 1 / length
    n1 = y(l, 1) * inv_length
    n2 = y(l, 2) * inv_length
    n3 = y(l, 3) * inv_length
  end subroutine unit_normal

  !> dy/dt of every lane (ball_derivative); margin, when
  !> given, is lowered to the lane's n_z and fit_indicator where smaller:
  !> it stays positive while every y it saw lies where the equations hold
  !> (ball_derivative's fits). base: the cup's acceleration of every lane
  !> at its time, given when some lane's cup moves (a lane whose cup does
  !> not move ignores it); with margin, a moving cup's lane also has its
  !> margin set to -1 where the reaction meets a limit (stage_status's
  !> lift-off, slip or a non-finite force, from the step's own n and rates:
  !> a stage's whole check).
  pure subroutine lanes_derivative(p, y, dydt, margin, base)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size)
    real(wp), intent(out) :: dydt(lanes, state_size)
    real(wp), intent(inout), optional :: margin(lanes)
    real(wp), intent(in), optional :: base(lanes, 3)
    real(wp) :: unit_scale(lanes), unused(lanes), u1, u2, u3, c1, c2, c3, fixed_cups(lanes, 3)
    integer :: l
    ! margin lowered lane by lane in the loop that computes it: a whole-vector
    ! min after it read what the loop had just stored in pieces, a stalled
    ! load (a fifth of a lone case's derivative)
    if (present(margin)) then
      call derivative_rows(p, y, dydt, margin, unit_scale)
    else
      unused = 1
      call derivative_rows(p, y, dydt, unused, unit_scale)
    end if
    if (.not. present(base)) then
      if (p%resists) then
        fixed_cups = 0
        call lanes_resist_rolling(p, y, dydt, fixed_cups)
      end if
      return
    end if
    ! a moving cup: g_vec - a_base in the cup's frame, omega' less
    ! (n x a_base) / (R (1 + k)), n = y / |y| (ball_derivative's order)
    do l = 1, p%width
      u1 = y(l, 1) * unit_scale(l)
      u2 = y(l, 2) * unit_scale(l)
      u3 = y(l, 3) * unit_scale(l)
      ! (both values computed, then one picked: a merge of values vectorizes)
      c1 = dydt(l, 4) - (u2 * base(l, 3) - u3 * base(l, 2)) / p%base_divisor(l)
      c2 = dydt(l, 5) - (u3 * base(l, 1) - u1 * base(l, 3)) / p%base_divisor(l)
      c3 = dydt(l, 6) - (u1 * base(l, 2) - u2 * base(l, 1)) / p%base_divisor(l)
      dydt(l, 4) = merge(c1, dydt(l, 4), p%moves(l) > 0)
      dydt(l, 5) = merge(c2, dydt(l, 5), p%moves(l) > 0)
      dydt(l, 6) = merge(c3, dydt(l, 6), p%moves(l) > 0)
    end do
    if (p%resists) call lanes_resist_rolling(p, y, dydt, base)
    if (present(margin)) call lanes_stage_reaction(p, y, dydt, unit_scale, base, margin)
  end subroutine lanes_derivative

  !> lanes_derivative's dy/dt of lanes 1 to width, margin lowered in each
  !> (unit_scale: |y| / |y|^2 of each lane, for a moving cup's terms).
  pure subroutine derivative_rows(p, y, dydt, margin, unit_scale)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size)
    real(wp), intent(out) :: dydt(lanes, state_size)
    real(wp), intent(inout) :: margin(lanes)
    real(wp), intent(out) :: unit_scale(lanes)
    real(wp) :: r, length2, length, inv_length2, ay1, ay2, ay3, q, sigma, r_sigma, pq, e, denominator, w1, w2, w3
    real(wp) :: ay_w, x1, x2, x3, rate, spin_rate, gravity, r_fit_sigma, e_fit
    integer :: l
    do l = 1, p%width
      r = p%radius(l)
      length2 = y(l, 1) * y(l, 1) + y(l, 2) * y(l, 2) + y(l, 3) * y(l, 3)
      length = sqrt(length2)
      inv_length2 = 1 / length2
      ! ball_derivative's q, sigma, P, E, D, w, M (see there)
      ay1 = p%a2(l) * y(l, 1)
      ay2 = p%b2(l) * y(l, 2)
      ay3 = p%c2(l) * y(l, 3)
      q = y(l, 1) * ay1 + y(l, 2) * ay2 + y(l, 3) * ay3
      sigma = sqrt(q)
      pq = p%axes2_sum(l) * q - (ay1 * ay1 + ay2 * ay2 + ay3 * ay3)
      r_sigma = r * sigma
      e = r_sigma * q - length * pq
      denominator = r_sigma * e + p%det_axes2(l) * (length2 * length2)
      ! lowers margin in every lane (a caller without one passes one it
      ! drops): a test of present() inside the loop stops it from vectorizing
      ! fit_indicator written out: a call to another module's function, even
      ! an elemental one, stops the loop from vectorizing
      r_fit_sigma = p%fit_radius(l) * sigma
      e_fit = r_fit_sigma * q - length * pq
      margin(l) = min(margin(l), min(y(l, 3), min(r_fit_sigma * e_fit + p%det_axes2(l) * (length2 * length2), &
                                                  -(e_fit + r_fit_sigma * q))))
      w1 = y(l, 5) * y(l, 3) - y(l, 6) * y(l, 2)
      w2 = y(l, 6) * y(l, 1) - y(l, 4) * y(l, 3)
      w3 = y(l, 4) * y(l, 2) - y(l, 5) * y(l, 1)
      ay_w = ay1 * w1 + ay2 * w2 + ay3 * w3
      x1 = e * w1 + length * (q * (p%a2(l) * w1) - ay_w * ay1)
      x2 = e * w2 + length * (q * (p%b2(l) * w2) - ay_w * ay2)
      x3 = e * w3 + length * (q * (p%c2(l) * w3) - ay_w * ay3)
      rate = r_sigma / denominator
      dydt(l, 1) = rate * x1
      dydt(l, 2) = rate * x2
      dydt(l, 3) = rate * x3
      spin_rate = (p%inv_one_plus_k(l) * (y(l, 4) * y(l, 1) + y(l, 5) * y(l, 2) + y(l, 6) * y(l, 3)) * inv_length2) &
                  * rate
      unit_scale(l) = length * inv_length2
      gravity = p%g_over_r(l) * p%inv_one_plus_k(l) * unit_scale(l)
      dydt(l, 4) = spin_rate * x1 + gravity * (-y(l, 2))
      dydt(l, 5) = spin_rate * x2 + gravity * y(l, 1)
      dydt(l, 6) = spin_rate * x3 + gravity * 0.0_wp
    end do
    ! (a lone case's idle lanes, of a size known here, are set by a few
    ! stores; a section of run-time size is a library call per column)
    if (p%width == 1) then
      dydt(2:, :) = 0
      unit_scale(2:) = 1
    else if (p%width < lanes) then
      dydt(p%width + 1:, :) = 0
      unit_scale(p%width + 1:) = 1
    end if
  end subroutine derivative_rows

  !> The couple of rolling resistance on every lane that has it
  !> (resist_rolling, expression by expression, in the lane's mode for the
  !> step: rolling_mode, rolls); base: the cups' accelerations (0 where a
  !> cup does not move). Every branch computed with safe divisors, then one
  !> picked by merge, so that the loop vectorizes.
  pure subroutine lanes_resist_rolling(p, y, dydt, base)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size), base(lanes, 3)
    real(wp), intent(inout) :: dydt(lanes, state_size)
    real(wp) :: inv_length, n1, n2, n3, g1, g2, g3, t1, t2, t3, normal_force, resistance, spin, o1, o2, o3, rate, rest
    real(wp) :: d1, d2, d3, drive_size, inertia, divisor, quotient, e1, e2, e3, m, r
    real(wp) :: along, a1, a2, a3, ahead_size
    logical :: moving, rolling, past, held, resists, ahead, by_mode
    integer :: l, i
    do l = 1, p%width
      r = p%radius(l)
      m = p%mass(l)
      inv_length = 1 / sqrt(y(l, 1) * y(l, 1) + y(l, 2) * y(l, 2) + y(l, 3) * y(l, 3))
      n1 = y(l, 1) * inv_length
      n2 = y(l, 2) * inv_length
      n3 = y(l, 3) * inv_length
      g1 = merge(0.0_wp - base(l, 1), 0.0_wp, p%moves(l) > 0)
      g2 = merge(0.0_wp - base(l, 2), 0.0_wp, p%moves(l) > 0)
      g3 = merge(-p%g(l) - base(l, 3), -p%g(l), p%moves(l) > 0)
      t1 = dydt(l, 2) * n3 - dydt(l, 3) * n2
      t2 = dydt(l, 3) * n1 - dydt(l, 1) * n3
      t3 = dydt(l, 1) * n2 - dydt(l, 2) * n1
      normal_force = m * (r * (y(l, 4) * t1 + y(l, 5) * t2 + y(l, 6) * t3) * inv_length - (g1 * n1 + g2 * n2 + g3 * n3))
      resistance = p%resistance(l) * max(normal_force, 0.0_wp)
      spin = y(l, 4) * n1 + y(l, 5) * n2 + y(l, 6) * n3
      o1 = y(l, 4) - spin * n1
      o2 = y(l, 5) - spin * n2
      o3 = y(l, 6) - spin * n3
      rate = sqrt(o1 * o1 + o2 * o2 + o3 * o3)
      rest = 1.0e-12_wp * (p%rest_scale(l) + sqrt(y(l, 4) * y(l, 4) + y(l, 5) * y(l, 5) + y(l, 6) * y(l, 6)))
      moving = rate > rest
      rolling = moving .or. (p%rolls(l) > 0 .and. p%law(l) < 1.5_wp)     ! (at the stop: the flow's law)
      past = o1 * p%rolling_mode(l, 1) + o2 * p%rolling_mode(l, 2) + o3 * p%rolling_mode(l, 3) < 0 .or. .not. moving
      ! the step's law: law_implicit against omega_t + h F_t (rolling_rate's
      ! F_t, from dydt without the couple), law_held against the mode
      along = dydt(l, 4) * n1 + dydt(l, 5) * n2 + dydt(l, 6) * n3
      a1 = o1 + p%law_step(l) * (dydt(l, 4) - along * n1 - (spin * inv_length) * dydt(l, 1))
      a2 = o2 + p%law_step(l) * (dydt(l, 5) - along * n2 - (spin * inv_length) * dydt(l, 2))
      a3 = o3 + p%law_step(l) * (dydt(l, 6) - along * n3 - (spin * inv_length) * dydt(l, 3))
      ahead_size = sqrt(a1 * a1 + a2 * a2 + a3 * a3)
      ahead = p%law(l) > 1.5_wp .and. ahead_size > 0
      by_mode = merge(.not. ahead_size > 0, p%law(l) > 0.5_wp .or. past, p%law(l) > 1.5_wp)
      ! at rest: the couple m R n x (g_vec - a_base) that would start it rolling
      d1 = p%mass_radius(l) * (n2 * g3 - n3 * g2)
      d2 = p%mass_radius(l) * (n3 * g1 - n1 * g3)
      d3 = p%mass_radius(l) * (n1 * g2 - n2 * g1)
      drive_size = sqrt(d1 * d1 + d2 * d2 + d3 * d3)
      held = .not. rolling .and. drive_size <= resistance
      inertia = p%couple_inertia(l)
      divisor = merge(merge(inertia, merge(ahead_size * inertia, rate * inertia, ahead), by_mode), &
                      drive_size * inertia, rolling)
      quotient = resistance / merge(divisor, 1.0_wp, .not. held)
      e1 = merge(merge(p%rolling_mode(l, 1), merge(a1, o1, ahead), by_mode), d1, rolling)
      e2 = merge(merge(p%rolling_mode(l, 2), merge(a2, o2, ahead), by_mode), d2, rolling)
      e3 = merge(merge(p%rolling_mode(l, 3), merge(a3, o3, ahead), by_mode), d3, rolling)
      resists = p%resistance(l) > 0
      dydt(l, 4) = merge(dydt(l, 4) - quotient * e1, dydt(l, 4), resists)
      dydt(l, 5) = merge(dydt(l, 5) - quotient * e2, dydt(l, 5), resists)
      dydt(l, 6) = merge(dydt(l, 6) - quotient * e3, dydt(l, 6), resists)
      do i = 1, state_size
        dydt(l, i) = merge(0.0_wp, dydt(l, i), resists .and. held)
      end do
    end do
  end subroutine lanes_resist_rolling

  !> The rolling part of omega = (w1, w2, w3) relative to the cup at the
  !> normal (y1, y2, y3) / |y|: omega - (omega . n) n (one lane's numbers,
  !> inlined into the lane loops).
  pure elemental subroutine rolling_part(y1, y2, y3, w1, w2, w3, o1, o2, o3)
    real(wp), intent(in) :: y1, y2, y3, w1, w2, w3
    real(wp), intent(out) :: o1, o2, o3
    real(wp) :: length, n1, n2, n3, spin
    length = sqrt(y1 * y1 + y2 * y2 + y3 * y3)
    n1 = y1 / length
    n2 = y2 / length
    n3 = y3 / length
    spin = w1 * n1 + w2 * n2 + w3 * n3
    o1 = w1 - spin * n1
    o2 = w2 - spin * n2
    o3 = w3 - spin * n3
  end subroutine rolling_part

  !> Every lane's mode for a step from y (ball_begin_step,
  !> set_rolling_mode's arithmetic): the rolling part of omega, its
  !> direction where the ball rolls (0 at rest) and whether it rolls.
  pure subroutine lanes_rolling_mode(p, y)
    type(ball_lanes_t), intent(inout) :: p
    real(wp), intent(in) :: y(lanes, state_size)
    real(wp) :: o1, o2, o3, rate, rest
    logical :: rolling
    integer :: l
    do l = 1, p%width
      call rolling_part(y(l, 1), y(l, 2), y(l, 3), y(l, 4), y(l, 5), y(l, 6), o1, o2, o3)
      rate = sqrt(o1 * o1 + o2 * o2 + o3 * o3)
      rest = 1.0e-12_wp * (p%rest_scale(l) + sqrt(y(l, 4) * y(l, 4) + y(l, 5) * y(l, 5) + y(l, 6) * y(l, 6)))
      rolling = rate > rest
      p%rolling_at_start(l, :) = [o1, o2, o3]
      p%rolls(l) = merge(1.0_wp, 0.0_wp, rolling)
      p%law(l) = 0
      rate = merge(rate, 1.0_wp, rolling)
      p%rolling_mode(l, 1) = merge(o1 / rate, 0.0_wp, rolling)
      p%rolling_mode(l, 2) = merge(o2 / rate, 0.0_wp, rolling)
      p%rolling_mode(l, 3) = merge(o3 / rate, 0.0_wp, rolling)
    end do
  end subroutine lanes_rolling_mode

  !> The lanes whose step h from y (derivative f there, the cups'
  !> accelerations base) may be one in which the couple's direction turns
  !> faster than the step (stiff_rolling, after lanes_rolling_mode): they
  !> roll and 2 C h > |omega_t|, a margin over the round-off of a vector
  !> code; the one-case code decides on them (ellroll_lane_laws).
  pure function lanes_may_stiffen(p, y, f, h, base) result(stiff)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size), f(lanes, state_size), h(lanes), base(lanes, 3)
    logical :: stiff(lanes)
    real(wp) :: inv_length, n1, n2, n3, g1, g2, g3, t1, t2, t3, normal_force, couple, rate
    integer :: l
    stiff = .false.
    do l = 1, p%width
      inv_length = 1 / sqrt(y(l, 1) * y(l, 1) + y(l, 2) * y(l, 2) + y(l, 3) * y(l, 3))
      n1 = y(l, 1) * inv_length
      n2 = y(l, 2) * inv_length
      n3 = y(l, 3) * inv_length
      g1 = merge(0.0_wp - base(l, 1), 0.0_wp, p%moves(l) > 0)
      g2 = merge(0.0_wp - base(l, 2), 0.0_wp, p%moves(l) > 0)
      g3 = merge(-p%g(l) - base(l, 3), -p%g(l), p%moves(l) > 0)
      t1 = f(l, 2) * n3 - f(l, 3) * n2
      t2 = f(l, 3) * n1 - f(l, 1) * n3
      t3 = f(l, 1) * n2 - f(l, 2) * n1
      normal_force = p%mass(l) * (p%radius(l) * (y(l, 4) * t1 + y(l, 5) * t2 + y(l, 6) * t3) * inv_length &
                                  - (g1 * n1 + g2 * n2 + g3 * n3))
      couple = p%resistance(l) * max(normal_force, 0.0_wp) / p%couple_inertia(l)
      rate = sqrt(p%rolling_at_start(l, 1)**2 + p%rolling_at_start(l, 2)**2 + p%rolling_at_start(l, 3)**2)
      stiff(l) = p%resistance(l) > 0 .and. p%rolls(l) > 0 .and. 2 * couple * h(l) > rate
    end do
  end function lanes_may_stiffen

  !> The accepted lanes' new states and derivatives taken as theirs.
  pure subroutine keep_accepted(y, f, y_new, f_new, accepted)
    real(wp), dimension(lanes, state_size), intent(inout) :: y, f
    real(wp), dimension(lanes, state_size), intent(in) :: y_new, f_new
    logical, intent(in) :: accepted(lanes)
    integer :: i
    if (all(accepted)) then             ! the rule: whole vectors, no test per lane
      y = y_new
      f = f_new
    else
      do i = 1, state_size
        where (accepted)
          y(:, i) = y_new(:, i)
          f(:, i) = f_new(:, i)
        end where
      end do
    end if
  end subroutine keep_accepted

  !> Whether each lane's ball is at rest with derivative f at its state
  !> (at_rest: rolling resistance, no rolling, and held): f = 0. (f = 0
  !> holds where the couple holds the ball, and otherwise only where n' = 0
  !> and so omega is along n: no rolling either way.)
  pure function lanes_at_rest(p, f) result(still)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: f(lanes, state_size)
    logical :: still(lanes)
    integer :: l
    still = .false.
    do l = 1, p%width
      still(l) = p%resistance(l) > 0 .and. &
                 abs(f(l, 1)) + abs(f(l, 2)) + abs(f(l, 3)) + abs(f(l, 4)) + abs(f(l, 5)) + abs(f(l, 6)) <= 0
    end do
  end function lanes_at_rest

  !> Where the rolling stops inside each lane's step to y_end (rolling_stops
  !> after lanes_rolling_mode at the step's start): a lane with rolling
  !> resistance that rolled at the start, its rolling part turned by a
  !> right angle or more.
  pure function lanes_rolling_stops(p, y_end) result(stops)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y_end(lanes, state_size)
    logical :: stops(lanes)
    real(wp) :: o1, o2, o3
    integer :: l
    stops = .false.
    do l = 1, p%width
      call rolling_part(y_end(l, 1), y_end(l, 2), y_end(l, 3), y_end(l, 4), y_end(l, 5), y_end(l, 6), o1, o2, o3)
      stops(l) = p%resistance(l) > 0 .and. p%rolls(l) > 0 .and. &
                 o1 * p%rolling_at_start(l, 1) + o2 * p%rolling_at_start(l, 2) + o3 * p%rolling_at_start(l, 3) <= 0
    end do
  end function lanes_rolling_stops

  !> The reaction's limits at a stage of every lane whose cup moves
  !> (stage_status where the ball fits: a non-finite force, lift-off, slip),
  !> the force as reaction_force computes it; inv_length: 1/|y| of each
  !> lane (lanes_derivative's). margin is set to -1 where one is met (a
  !> lane whose cup does not move is left as it is).
  pure subroutine lanes_stage_reaction(p, y, f, inv_length, base, margin)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size), f(lanes, state_size), inv_length(lanes), base(lanes, 3)
    real(wp), intent(inout) :: margin(lanes)
    real(wp) :: n1, n2, n3, nd1, nd2, nd3, f1, f2, f3, normal_force, t1, t2, t3, quotient, r, m, up
    logical :: limit, small
    integer :: l
    do l = 1, p%width
      r = p%radius(l)
      m = p%mass_fraction(l)
      ! (times 1/|y|: the quotients differ from stage_status's in the last
      ! bit, which moves a limit's decision only within round-off of it)
      n1 = y(l, 1) * inv_length(l)
      n2 = y(l, 2) * inv_length(l)
      n3 = y(l, 3) * inv_length(l)
      nd1 = f(l, 1) * inv_length(l)
      nd2 = f(l, 2) * inv_length(l)
      nd3 = f(l, 3) * inv_length(l)
      f1 = m * ((r * ((f(l, 5) * n3 - f(l, 6) * n2) + (y(l, 5) * nd3 - y(l, 6) * nd2)) + 0.0_wp) + base(l, 1))
      f2 = m * ((r * ((f(l, 6) * n1 - f(l, 4) * n3) + (y(l, 6) * nd1 - y(l, 4) * nd3)) + 0.0_wp) + base(l, 2))
      f3 = m * ((r * ((f(l, 4) * n2 - f(l, 5) * n1) + (y(l, 4) * nd2 - y(l, 5) * nd1)) + p%g(l)) + base(l, 3))
      normal_force = f1 * n1 + f2 * n2 + f3 * n3
      t1 = f1 - normal_force * n1
      t2 = f2 - normal_force * n2
      t3 = f3 - normal_force * n3
      small = t1**2 + t2**2 + t3**2 < small_sum      ! (norm_of's, written out: lanes_observe)
      up = merge(norm_up, 1.0_wp, small)
      quotient = merge(sqrt((up * t1)**2 + (up * t2)**2 + (up * t3)**2) * norm_down, sqrt(t1**2 + t2**2 + t3**2), small) &
                 / merge(normal_force, 1.0_wp, normal_force > 0)
      ! (a sum of magnitudes is NaN or Inf when one of them is)
      limit = .not. (abs(f1) + abs(f2) + abs(f3) <= huge(1.0_wp) .and. normal_force > 0 &
                     .and. .not. (p%mu(l) > 0 .and. quotient > p%mu(l)))
      margin(l) = merge(-1.0_wp, margin(l), p%moves(l) > 0 .and. limit)
    end do
  end subroutine lanes_stage_reaction

  !> The summary's quantities and the limit status of every lane's state y
  !> with derivative f (observe and limit_status); base, when given: the
  !> cup's acceleration of every lane (0 where the cup does not move).
  !> Branch-free (merge with safe divisors instead of if), so that the
  !> loop vectorizes.
  pure subroutine lanes_observe(p, y, f, out, base)
    type(ball_lanes_t), intent(in) :: p
    real(wp), intent(in) :: y(lanes, state_size), f(lanes, state_size)
    type(lane_outputs_t), intent(inout) :: out
    real(wp), intent(in), optional :: base(lanes, 3)
    real(wp) :: b(lanes, 3)
    real(wp) :: length, inv_length, n1, n2, n3, w1, w2, w3, horizontal, s, inv_s, p1, p2, p3, lateral
    real(wp) :: nd1, nd2, nd3, ac1, ac2, ac3, f1, f2, f3, normal_force, t1, t2, t3
    real(wp) :: v1, v2, v3, height, energy, residual, an1, an2, an3, inv_s2, trace, det, r, m, fr
    real(wp) :: p3_lower, p3_upper, quotient, divisor, friction_needed, fs1, fs2, fs3, d1, d2, up
    logical :: upright, pressed, finite, fits, slipping
    integer :: l, status
    ! (a fixed cup's 0 adds nothing: the reaction is bitwise that without it)
    b = 0
    if (present(base)) b = base
    do l = 1, p%width
      r = p%radius(l)
      m = p%mass(l)
      call unit_normal(y, l, length, inv_length, n1, n2, n3)
      w1 = y(l, 4)
      w2 = y(l, 5)
      w3 = y(l, 6)
      ! contact point (contact_from_normal), centre, nutation
      horizontal = p%a2(l) * n1**2 + p%b2(l) * n2**2
      s = sqrt(horizontal + p%c2(l) * n3**2)
      inv_s = 1 / s
      p1 = -p%a2(l) * n1 * inv_s
      p2 = -p%b2(l) * n2 * inv_s
      ! both branches computed (divisors made safe), then one picked: a merge of values
      ! vectorizes; a merge of expressions that may trap (divisions) compiles to branches
      ! (arithmetic inside merge's arguments may trap under IEEE rules: a branch stays)
      divisor = s * (s + p%c(l) * n3)
      p3_lower = p%c(l) * horizontal / merge(divisor, 1.0_wp, n3 > 0)
      p3_upper = p%c(l) - p%c2(l) * n3 * inv_s
      p3 = merge(p3_lower, p3_upper, n3 > 0)
      ! norms as norm_of (ellroll_norms) takes them, written out so that the loop vectorizes
      up = merge(norm_up, 1.0_wp, n1**2 + n2**2 < small_sum)
      lateral = merge(sqrt((up * n1)**2 + (up * n2)**2) * norm_down, sqrt(n1**2 + n2**2), up > 1)
      ! upright: n3 > lateral tiny, with the product taken only where n3 is within 2 tiny of 0
      ! (lateral <= 1 elsewhere: the test holds); a subnormal product costs a microcode assist
      upright = n3 > merge(0.0_wp, lateral, n3 > 2 * tiny(1.0_wp) .and. lateral < 2) * tiny(1.0_wp)
      quotient = lateral / merge(n3, 1.0_wp, upright)
      out%tan_nutation(l) = merge(quotient, huge(1.0_wp), upright)
      out%lateral(l) = lateral
      out%normal(l, :) = [n1, n2, n3]
      out%contact(l, :) = [p1, p2, p3]
      d1 = p1 + r * n1
      d2 = p2 + r * n2
      up = merge(norm_up, 1.0_wp, d1**2 + d2**2 < small_sum)
      out%quantity(l, q_displacement) = merge(sqrt((up * d1)**2 + (up * d2)**2) * norm_down, sqrt(d1**2 + d2**2), up > 1)
      ! reaction m (a_C + g e_z), a_C = R (omega' x n + omega x n')
      nd1 = f(l, 1) * inv_length
      nd2 = f(l, 2) * inv_length
      nd3 = f(l, 3) * inv_length
      ac1 = r * ((f(l, 5) * n3 - f(l, 6) * n2) + (w2 * nd3 - w3 * nd2))
      ac2 = r * ((f(l, 6) * n1 - f(l, 4) * n3) + (w3 * nd1 - w1 * nd3))
      ac3 = r * ((f(l, 4) * n2 - f(l, 5) * n1) + (w1 * nd2 - w2 * nd1))
      ac1 = ac1 + b(l, 1)
      ac2 = ac2 + b(l, 2)
      ac3 = ac3 + b(l, 3)
      out%center_acceleration(l, :) = [ac1, ac2, ac3]
      f1 = m * (ac1 + 0.0_wp)
      f2 = m * (ac2 + 0.0_wp)
      f3 = m * (ac3 + p%g(l))
      out%reaction(l, :) = [f1, f2, f3]
      out%quantity(l, q_reaction_normal) = f1 * n1 + f2 * n2 + f3 * n3
      ! |F_h| and the friction ratio in units of 2^exponent(m) N (observe's): no underflow
      fs1 = p%mass_fraction(l) * (ac1 + 0.0_wp)
      fs2 = p%mass_fraction(l) * (ac2 + 0.0_wp)
      fs3 = p%mass_fraction(l) * (ac3 + p%g(l))
      up = merge(norm_up, 1.0_wp, fs1**2 + fs2**2 < small_sum)
      out%quantity(l, q_horizontal_force_scaled) = merge(sqrt((up * fs1)**2 + (up * fs2)**2) * norm_down, &
                                                         sqrt(fs1**2 + fs2**2), up > 1)
      normal_force = fs1 * n1 + fs2 * n2 + fs3 * n3
      t1 = fs1 - normal_force * n1
      t2 = fs2 - normal_force * n2
      t3 = fs3 - normal_force * n3
      pressed = normal_force > 0
      up = merge(norm_up, 1.0_wp, t1**2 + t2**2 + t3**2 < small_sum)
      divisor = merge(sqrt((up * t1)**2 + (up * t2)**2 + (up * t3)**2) * norm_down, sqrt(t1**2 + t2**2 + t3**2), up > 1)
      quotient = divisor / merge(normal_force, 1.0_wp, pressed)
      friction_needed = merge(quotient, huge(1.0_wp), pressed)
      out%quantity(l, q_friction_needed) = friction_needed
      ! energy, with z_C - R written without cancellation
      v1 = r * (w2 * n3 - w3 * n2)
      v2 = r * (w3 * n1 - w1 * n3)
      v3 = r * (w1 * n2 - w2 * n1)
      height = p3 - r * (n1**2 + n2**2) / (1 + n3)
      energy = 0.5_wp * p%inertia_factor(l) * m * r**2 * (w1 * w1 + w2 * w2 + w3 * w3) &
               + 0.5_wp * m * (v1 * v1 + v2 * v2 + v3 * v3) + m * p%g(l) * height
      energy = energy + m * p%g(l) * r
      out%quantity(l, q_energy) = energy
      residual = abs((p1 * p%inv_a(l))**2 + (p2 * p%inv_b(l))**2 + ((p3 - p%c(l)) * p%inv_c(l))**2 - 1)
      out%quantity(l, q_surface_residual) = residual
      ! does the ball fit (R (1 + margin) below both principal radii)? K from
      ! the contact's s = sqrt(n . A n): no root or division of its own
      an1 = p%a2(l) * n1
      an2 = p%b2(l) * n2
      an3 = p%c2(l) * n3
      inv_s2 = inv_s * inv_s
      trace = (p%axes2_sum(l) - (an1 * an1 + an2 * an2 + an3 * an3) * inv_s2) * inv_s
      det = p%det_axes2(l) * inv_s2 * inv_s2
      fr = p%fit_radius(l)
      ! (both > 0) as min(...) > 0; trace - 2 fr has the sign of the exact difference
      fits = min(fr * (fr - trace) + det, trace - 2 * fr) > 0
      out%quantity(l, q_fit_clearance) = min(r * (1 + peak_clearance) * (r * (1 + peak_clearance) - trace) + det, &
                                             trace - 2 * (r * (1 + peak_clearance)))
      ! the limits of limit_status, the first match winning: applied last to first. A sum of
      ! magnitudes is NaN or Inf when one of them is (a valid state's are far from overflow).
      finite = abs(y(l, 1)) + abs(y(l, 2)) + abs(y(l, 3)) + abs(w1) + abs(w2) + abs(w3) &
               + abs(energy) + abs(f1) + abs(f2) + abs(f3) <= huge(1.0_wp)
      slipping = merge(friction_needed > p%mu(l), .false., p%mu(l) > 0)
      status = merge(status_slip, status_completed, slipping)
      status = merge(status_liftoff, status, .not. pressed)
      status = merge(status_constraint, status, residual > constraint_tolerance)
      status = merge(status_no_fit, status, .not. fits)
      status = merge(status_rim, status, n3 <= 0)
      out%status(l) = merge(status_nonfinite, status, .not. finite)
    end do
  end subroutine lanes_observe
end module ellroll_ball_lanes
