!> Whether a turn found inside a step is the motion's or a stop's residue.
!> The rolling of a ball with rolling resistance and the slip of a sliding
!> ball each end a step where they have turned by a right angle (an event);
!> near a stop their direction relaxes faster than a step can follow, and
!> what is left there is the stop's, while elsewhere the motion itself
!> turned and goes on (docs/model.md, "The stop is an event" and "The
!> aligned law").
module ellroll_turns
  use ellroll_kinds, only: wp
  use ellroll_norms, only: in_mass_units
  use ellroll_rolling_ball, only: rolling_ball_t, state_size, stiff_rolling
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, sliding_derivative, slip_velocity
  implicit none
  private

  public :: turn_resolved, direction_unresolved

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
end module ellroll_turns
