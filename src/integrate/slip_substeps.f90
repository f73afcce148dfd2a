!> A fixed-step method's piece of sliding where the slip is small against
!> what the friction takes from it over the piece (docs/model.md, "Where
!> the slip is small"): there the slip's direction relaxes to the direction
!> the other forces give it at the rate mu N (1/m + R^2/J) / |u|, far above
!> 1/h, and a step's stages, whose slip is the step's error, take the
!> friction in a direction of noise (right after a switch into sliding,
!> the slip jumps to about a third of the friction's reach over the step,
!> and keeps that excess: the slip then stops late by a part of the step).
!> Such a piece is taken in substeps of the same method, each judged by step
!> doubling on the slip (its error to slip_tolerance of the contact's
!> speeds) and extrapolated (order 5 for rk4). So is a piece over which the
!> couple of rolling resistance may turn (omega_t passing near zero: a ball
!> with backspin), whose jump in omega' a plain step would take with an error
!> of the step's size; its works are then the substeps' trapezoids.
module ellroll_slip_substeps
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_ode, only: no_step_solution
  use ellroll_integrators, only: integrator_t
  use ellroll_case_run, only: stopping
  use ellroll_rolling_ball, only: rolling_part, state_size
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, slip_velocity, center_velocity, couple_steady_at, &
      dissipation
  implicit none
  private

  public :: slide_piece

  !> A piece is taken in substeps where its slip at the start, or at the end
  !> of the plain step, is below this many times the friction's reach over
  !> it (mu N (1/m + R^2/J) h): there the slip's direction turns within the
  !> step, which an explicit step does not resolve (a stop found from there
  !> is off by the slip left over its approach rate).
  real(wp), parameter :: stiff_reach = 8
  !> A substep's error in the slip, against |V_C| + R |omega| + the
  !> friction's reach over the piece.
  real(wp), parameter :: slip_tolerance = 2.0e-12_wp
  !> A slip below its value at the piece's start that has not halved over
  !> this many substeps has stalled: where rolling needs nearly mu N (the
  !> slip's approach slow) the substeps' own errors turn its direction near
  !> zero, and it hovers there without reaching zero; it stops there.
  integer, parameter :: stall_substeps = 64
  !> Substeps of one piece at most (the rest is then taken whole); a
  !> substep that leaves the motion's scale (speeds beyond beyond_scale
  !> times the piece's start, with what the start's accelerations add over
  !> the piece: a couple whose direction turns far faster than round-off-sized
  !> substeps) leaves the piece without a solution.
  integer, parameter :: max_substeps = 100000
  real(wp), parameter :: beyond_scale = 1.0e3_wp

contains

  !> The piece of size h from (t, y0) (f0 its derivative) of sliding ball sb,
  !> whose normal force there is big_n: y_end at its end, reached = h
  !> (integrator's stage_limit set by the substep that met a limit, where one
  !> did), or, where the slip stops inside it (the event of sb crosses, or the
  !> slip stalls: stalled), the state at the end of the substep where it did,
  !> reached its time from t (the caller locates the stop by the piece's size).
  !> The piece has no solution (no_step_solution) once the run is asked to
  !> stop (stopping), or where a substep it takes (shrunk to round-off, or
  !> the rest taken whole after max_substeps) leaves the motion's scale.
  !> works: the friction's and the couple's works over the whole piece where
  !> the couple's turn put it in substeps, else -1 (the caller's trapezoid).
  subroutine slide_piece(integrator, sb, t, h, y0, f0, big_n, y_end, reached, stalled, works, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h, y0(slide_state_size), f0(slide_state_size), big_n
    real(wp), intent(out) :: y_end(slide_state_size), reached, works(2)
    logical, intent(out) :: stalled
    integer(i8), intent(inout) :: n_rhs
    real(wp), dimension(slide_state_size) :: y, f, whole, half, halves, f_half
    real(wp) :: reach, tolerance, tau, s, error, slip, slip_before, slip_start, scale, power(2), power_before(2)
    real(wp) :: turn_reach
    integer :: k, accepted
    logical :: small_slip, turning
    stalled = .false.
    reached = h
    works = -1
    reach = sb%ball%mu * max(big_n, 0.0_wp) * (1 + 1 / sb%ball%inertia_factor) / sb%ball%mass * h
    small_slip = norm2(slip_velocity(sb%ball, y0)) < stiff_reach * reach
    turning = couple_turns(sb, y0, f0, big_n, h)
    if (.not. (small_slip .or. turning)) then
      call integrator%step(sb, t, y0, f0, h, y_end, n_rhs)
      if (integrator%stage_limit /= 0) return
      small_slip = norm2(slip_velocity(sb%ball, y_end)) < stiff_reach * reach
      if (.not. small_slip) return
    end if
    slip_start = norm2(slip_velocity(sb%ball, y0))
    slip_before = slip_start
    accepted = 0
    tolerance = slip_tolerance * speed(y0)
    ! (a start at rest where the friction is weak, mu N far below the weight's
    ! pull along the cup: the speeds the piece gains are the accelerations'
    ! reach over it, not the start's speeds)
    scale = beyond_scale * (speed(y0) + h * (norm2(center_rate(y0, f0)) + sb%ball%radius * norm2(f0(4:6))))
    y = y0
    f = f0
    tau = 0
    if (turning) call add_works(t, 0.0_wp)
    s = h / 64
    do k = 1, max_substeps
      if (stopping()) then
        integrator%stage_limit = no_step_solution
        whole = y
        exit
      end if
      s = min(s, h - tau)
      if (k == max_substeps) s = h - tau
      call integrator%step(sb, t + tau, y, f, s, whole, n_rhs)
      if (integrator%stage_limit /= 0) exit
      call integrator%step(sb, t + tau, y, f, s / 2, half, n_rhs)
      if (integrator%stage_limit /= 0) exit
      call sb%rhs(t + tau + s / 2, half, f_half)
      call integrator%step(sb, t + tau + s / 2, half, f_half, s / 2, halves, n_rhs)
      n_rhs = n_rhs + 1
      if (integrator%stage_limit /= 0) exit
      error = norm2(slip_velocity(sb%ball, halves) - slip_velocity(sb%ball, whole)) / 15
      ! a substep over which omega_t turns by more than a right angle holds the
      ! couple's turn, whose jump in omega' step doubling may not see (a turn
      ! near the substep's middle): its slip errs by up to the jump's reach
      if (turning) then
        if (dot_product(rolling_part(y(1:state_size)), rolling_part(halves(1:state_size))) < 0) error = max(error, turn_reach * s)
      end if
      if (error <= tolerance .or. s <= 16 * spacing(t + h) .or. k == max_substeps) then
        if (.not. speed(halves) <= scale) then
          integrator%stage_limit = no_step_solution       ! the substeps leave the motion's scale
          whole = y
          exit
        end if
        tau = tau + s
        y = halves + (halves - whole) / 15
        if (turning) call add_works(t + tau, s)
        if (tau >= h) exit
        call sb%rhs(t + tau, y, f)
        n_rhs = n_rhs + 1
        if (sb%event_crossed(y0, y) /= 0) exit      ! the stop: the caller locates it, from the sign there
        accepted = accepted + 1
        if (small_slip .and. mod(accepted, stall_substeps) == 0) then
          slip = norm2(slip_velocity(sb%ball, y))
          stalled = slip < slip_start .and. slip > slip_before / 2
          if (stalled) exit
          slip_before = slip
        end if
      end if
      if (.not. ieee_is_finite(error)) then
        s = s / 4
      else
        s = s * min(4.0_wp, max(0.2_wp, 0.9_wp * (tolerance / max(error, tiny(1.0_wp)))**0.2_wp))
      end if
    end do
    if (integrator%stage_limit /= 0) then
      y_end = whole                   ! (not valid: the caller ends the case where its partial steps meet the limit)
      reached = h
    else
      y_end = y
      reached = min(tau, h)
    end if
    if (integrator%stage_limit /= 0 .or. tau < h .or. .not. turning) works = -1
  contains
    !> The works' trapezoid over the substep of `size` ending at (at, y) (0: the
    !> piece's start, and turn_reach, the couple's jump 2 delta N / J in omega' in u).
    subroutine add_works(at, size)
      real(wp), intent(in) :: at, size
      power = dissipation(sb, at, y)
      n_rhs = n_rhs + 1
      if (size > 0) then
        works = works + 0.5_wp * size * (power_before + power)
      else
        works = 0
        turn_reach = 2 * sb%ball%rolling_resistance * max(big_n, 0.0_wp) &
                     / (sb%ball%inertia_factor * sb%ball%mass * sb%ball%radius)
      end if
      power_before = power
    end subroutine add_works

    !> The speeds of the centre and of the contact's turning at sliding state x,
    !> with the friction's reach over the piece: the motion's scale.
    real(wp) function speed(x)
      real(wp), intent(in) :: x(slide_state_size)
      speed = norm2(center_velocity(x)) + sb%ball%radius * norm2(x(4:6)) + reach
    end function speed
  end subroutine slide_piece

  !> Whether the couple of rolling resistance may turn over a piece h from
  !> sliding state y (rate f, normal force big_n) faster than a plain step
  !> follows: omega_t passes near zero (couple_steady_at), or it is small
  !> against the couple's reach over the piece, delta N h / J, where its
  !> direction relaxes faster than the step (as a small slip's).
  pure logical function couple_turns(sb, y, f, big_n, h) result(turns)
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: y(slide_state_size), f(slide_state_size), big_n, h
    turns = .false.
    if (.not. sb%ball%rolling_resistance > 0) return
    turns = .not. couple_steady_at(y, f, h) .or. norm2(rolling_part(y(1:state_size))) < stiff_reach * &
            sb%ball%rolling_resistance * max(big_n, 0.0_wp) * h / (sb%ball%inertia_factor * sb%ball%mass * &
            sb%ball%radius**2)
  end function couple_turns

  !> The rate of the centre's velocity at sliding state y whose derivative
  !> is dydt (its z component from V_z = -(n_x V_x + n_y V_y) / n_z, differentiated).
  pure function center_rate(y, dydt) result(rate)
    real(wp), intent(in) :: y(slide_state_size), dydt(slide_state_size)
    real(wp) :: rate(3)
    rate(1:2) = dydt(7:8)
    rate(3) = -((dydt(1) * y(7) + y(1) * dydt(7) + dydt(2) * y(8) + y(2) * dydt(8)) * y(3) &
                - (y(1) * y(7) + y(2) * y(8)) * dydt(3)) / y(3)**2
  end function center_rate


end module ellroll_slip_substeps
