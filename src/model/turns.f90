!> Whether a turn found inside a step is the motion's or a stop's residue,
!> and the law of the couple of rolling resistance for a fixed step in
!> which its direction turns faster than the step. The rolling of a ball
!> with rolling resistance and the slip of a sliding ball each end a step
!> where they have turned by a right angle (an event); near a stop their
!> direction relaxes faster than a step can follow, and what is left there
!> is the stop's, while elsewhere the motion itself turned and goes on
!> (docs/model.md, "The stop is an event", "A fixed step where the couple
!> turns faster than the step" and "The aligned law").
module ellroll_turns
  use ellroll_kinds, only: wp
  use ellroll_norms, only: in_mass_units
  use ellroll_rolling_ball, only: rolling_ball_t, state_size, law_exact, law_held, law_implicit, rolling_rate, cross, &
      couple_inertia
  use ellroll_excitation, only: excitation_none, base_acceleration
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, sliding_derivative, slip_velocity
  implicit none
  private

  public :: turn_resolved, direction_unresolved, choose_rolling_law, stiff_rolling

contains

  !> Whether the rolling part of omega at y, where it has turned by a right
  !> angle inside a step h (the rest event's cut; f the derivative at y),
  !> is the motion's, a rolling that turns in 3D and rolls on: the couple
  !> C = delta N / (m R^2 (1 + k)) would take a tenth of h or more to stop
  !> it (|omega_t| >= C h / 10: the step resolves the direction's relaxation
  !> near a stop), and the ball would roll further than the step's error
  !> in the meantime (R |omega_t|^2 / (2 C) > R tolerance; an embedded
  !> pair's atol + rtol, 0 for a fixed step).
  pure logical function turn_resolved(ball, t, y, f, h, tolerance)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, y(state_size), f(state_size), h, tolerance
    real(wp) :: couple, rate, n(3)
    logical :: stiff
    call stiff_rolling(ball, t, y, f, h, couple, stiff)
    n = y(1:3) / norm2(y(1:3))
    rate = norm2(y(4:6) - dot_product(y(4:6), n) * n)
    turn_resolved = 10 * rate >= couple * h .and. rate**2 > 2 * couple * tolerance
  end function turn_resolved

  !> Whether the direction of the slip at sliding state y relaxes towards
  !> -F_req in less than a tenth of a step h (tau = |u| / (kappa |F_req|),
  !> kappa = 1/m + R^2/J): the explicit stages of such a step do not resolve
  !> it, so that a turn of the slip found inside it is the residue of that
  !> stiff mode, not the motion's (whose slip stays along -F_req as it
  !> shrinks).
  pure logical function direction_unresolved(sb, t, y, h) result(unresolved)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, y(slide_state_size), h
    real(wp) :: rate(slide_state_size), big_n, need(3), reach
    call sliding_derivative(sb, t, y, rate, big_n, needed=need)
    ! kappa |F_req|, the force in units of the mass's power of two
    reach = (1 + 1 / sb%ball%inertia_factor) / fraction(sb%ball%mass) * norm2(in_mass_units(need, sb%ball%mass))
    unresolved = 10 * norm2(slip_velocity(sb%ball, y)) < h * reach
  end function direction_unresolved

  !> The law of the couple for a fixed step h from (t, y), f = the
  !> derivative there with the couple against omega_t (after begin_step):
  !> where its direction would turn faster than the step (stiff_rolling:
  !> C h > |omega_t|, C the couple over the rolling inertia), law_implicit
  !> where the implicit Euler step's rolling part, omega_t + h F_t, is
  !> longer than C h and F_t leans the way the ball rolls (the ball rolls
  !> on through the step: the couple against where it goes), else law_held
  !> (it stops inside the step: the couple against where it went; the stop
  !> event locates it). docs/model.md, "Rolling resistance".
  pure subroutine choose_rolling_law(ball, t, y, f, h, release)
    type(rolling_ball_t), intent(inout) :: ball
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    logical, intent(in), optional :: release   !< a step from rest that the couple lets go: law_implicit (released)
    real(wp) :: couple, free(3), ahead(3)
    logical :: stiff
    ball%rolling_law = law_exact
    if (present(release)) then
      if (release) call released(ball, y, f, h)
      if (ball%rolling_law /= law_exact) return
    end if
    call stiff_rolling(ball, t, y, f, h, couple, stiff)
    if (.not. stiff) return
    free = rolling_rate(y, f) + couple * ball%rolling_mode        ! f's couple taken out
    ahead = ball%rolling_at_start + h * free
    ball%law_step = h
    ball%rolling_law = law_held
    if (sqrt(ahead(1) * ahead(1) + ahead(2) * ahead(2) + ahead(3) * ahead(3)) > couple * h .and. &
        ball%rolling_at_start(1) * free(1) + ball%rolling_at_start(2) * free(2) &
        + ball%rolling_at_start(3) * free(3) > 0) ball%rolling_law = law_implicit
  end subroutine choose_rolling_law

  !> A step h from rest that the couple does not hold (f: the derivative):
  !> the couple's direction turns at C / |omega_t|, without bound at the
  !> start, so it acts against omega_t + h F_t (law_implicit along the
  !> drive), whose rate C / |h F_t| < 1 / h gauss4's stages can solve.
  !> Held (f = 0) or rolling: law_exact.
  pure subroutine released(ball, y, f, h)
    type(rolling_ball_t), intent(inout) :: ball
    real(wp), intent(in) :: y(state_size), f(state_size), h
    real(wp) :: start(3), rate
    ball%rolling_law = law_exact
    if (.not. ball%rolling_resistance > 0 .or. sum(ball%rolling_mode**2) > 0) return
    start = rolling_rate(y, f)
    rate = sqrt(start(1) * start(1) + start(2) * start(2) + start(3) * start(3))
    if (.not. rate > 0) return
    ball%rolling_mode = start / rate
    ball%law_step = h
    ball%rolling_law = law_implicit
  end subroutine released

  !> Whether a step h from (t, y), f the derivative there, is one in which
  !> the couple's direction turns faster than the step (stiff): the ball
  !> rolls (begin_step's mode) and C h > |omega_t|, couple = C = delta N /
  !> (m R^2 (1 + k)) (N as resist_rolling takes it, from f's n').
  pure subroutine stiff_rolling(ball, t, y, f, h, couple, stiff)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: t, y(state_size), f(state_size), h
    real(wp), intent(out) :: couple
    logical, intent(out) :: stiff
    real(wp) :: n(3), gravity(3), turn(3), inv_length
    couple = 0
    stiff = .false.
    if (.not. (ball%rolling_resistance > 0 .and. sum(ball%rolling_mode**2) > 0)) return
    inv_length = 1 / sqrt(y(1) * y(1) + y(2) * y(2) + y(3) * y(3))
    n = y(1:3) * inv_length
    gravity = [0.0_wp, 0.0_wp, -ball%g]
    if (ball%excitation%kind /= excitation_none) gravity = gravity - base_acceleration(ball%excitation, t)
    turn = cross(f(1:3), n)
    couple = ball%rolling_resistance * max(ball%mass * (ball%radius * (y(4) * turn(1) + y(5) * turn(2) &
             + y(6) * turn(3)) * inv_length - (gravity(1) * n(1) + gravity(2) * n(2) + gravity(3) * n(3))), 0.0_wp) &
             / couple_inertia(ball)
    stiff = couple * h > sqrt(ball%rolling_at_start(1) * ball%rolling_at_start(1) &
            + ball%rolling_at_start(2) * ball%rolling_at_start(2) + ball%rolling_at_start(3) * ball%rolling_at_start(3))
  end subroutine stiff_rolling
end module ellroll_turns
