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
!> speeds) and extrapolated (order 5 for rk4).
module ellroll_slip_substeps
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_ode, only: no_step_solution
  use ellroll_integrators, only: integrator_t
  use ellroll_case_run, only: stopping
  use ellroll_sliding_ball, only: sliding_ball_t, slide_state_size, slip_velocity, center_velocity
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
  subroutine slide_piece(integrator, sb, t, h, y0, f0, big_n, y_end, reached, stalled, n_rhs)
    class(integrator_t), intent(inout) :: integrator
    type(sliding_ball_t), intent(in) :: sb
    real(wp), intent(in) :: t, h, y0(slide_state_size), f0(slide_state_size), big_n
    real(wp), intent(out) :: y_end(slide_state_size), reached
    logical, intent(out) :: stalled
    integer(i8), intent(inout) :: n_rhs
    real(wp), dimension(slide_state_size) :: y, f, whole, half, halves, f_half
    real(wp) :: reach, tolerance, tau, s, error, slip, slip_before, slip_start, scale
    integer :: k, accepted
    stalled = .false.
    reached = h
    reach = sb%ball%mu * max(big_n, 0.0_wp) * (1 + 1 / sb%ball%inertia_factor) / sb%ball%mass * h
    if (.not. norm2(slip_velocity(sb%ball, y0)) < stiff_reach * reach) then
      call integrator%step(sb, t, y0, f0, h, y_end, n_rhs)
      if (integrator%stage_limit /= 0) return
      if (.not. norm2(slip_velocity(sb%ball, y_end)) < stiff_reach * reach) return
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
      if (error <= tolerance .or. s <= 16 * spacing(t + h) .or. k == max_substeps) then
        if (.not. speed(halves) <= scale) then
          integrator%stage_limit = no_step_solution       ! the substeps leave the motion's scale
          whole = y
          exit
        end if
        tau = tau + s
        y = halves + (halves - whole) / 15
        if (tau >= h) exit
        call sb%rhs(t + tau, y, f)
        n_rhs = n_rhs + 1
        if (sb%event_crossed(y0, y) /= 0) exit      ! the stop: the caller locates it, from the sign there
        accepted = accepted + 1
        if (mod(accepted, stall_substeps) == 0) then
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
  contains
    !> The speeds of the centre and of the contact's turning at sliding state x,
    !> with the friction's reach over the piece: the motion's scale.
    real(wp) function speed(x)
      real(wp), intent(in) :: x(slide_state_size)
      speed = norm2(center_velocity(x)) + sb%ball%radius * norm2(x(4:6)) + reach
    end function speed
  end subroutine slide_piece

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
