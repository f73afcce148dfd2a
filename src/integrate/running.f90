!> The running statistics of the step-end quantities (ellroll_quantities)
!> that the summary's figures take (ellroll_figures), for one case
!> (running_t, in the one-case loops) or for a batch's lanes
!> (running_lanes_t): each statistic is written once, here, for both; the
!> figures are made from them at the end of a case (finish_running).
module ellroll_running
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_norms, only: from_mass_units
  use ellroll_quantities, only: quantities, quantity_count, q_fit_clearance, q_friction_needed
  use ellroll_limit_states, only: is_model_limit
  use ellroll_figures, only: figure_t, figures, figure_count, timed, lasting, beyond, from_counter, &
      from_run, from_maximum, from_maximum_time, from_last, from_time_beyond, finish_none, finish_force, &
      finish_per_mass, finish_per_start, fig_peaks_truncated
  use ellroll_ball_lanes, only: lanes
  use ellroll_results, only: case_result_t
  implicit none
  private

  public :: running_t, running_lanes_t, start_running, add_step_ends, add_inside, get_lane, put_lane, finish_running, &
            unset

  !> One case's running statistics, per quantity: its value at t = 0, its
  !> largest value (its change's, for a changing quantity; every quantity is
  !> a magnitude, so they start at 0) and when it was reached, its value at
  !> the last step end; for a time beyond a threshold, the threshold, the
  !> quantity at the last step end (from t = 0 on) and the time so
  !> far; and the last step end's time. The same arrays as a batch's with
  !> one row.
  !> The maxima and their times also over the step ends clear of the cup's
  !> curvature alone (fit_clearance > 0; ellroll_quantities' peak_clearance),
  !> with the counts of step ends clear and not, and whether the last step
  !> end was clear: a case that ends at a model limit takes its peaks from
  !> those (and from the points where the path's clearance changes sign
  !> inside a step: ellroll_step_peaks' add_clearance_crossing).
  type :: running_t
    real(wp), dimension(1, quantity_count) :: start = 0, maximum = 0, maximum_time = 0, last = 0
    real(wp), dimension(1, quantity_count) :: threshold = 0, value_before = 0, time_beyond = 0
    real(wp), dimension(1, quantity_count) :: clear_maximum = 0, clear_maximum_time = 0
    integer(i8) :: n_clear(1) = 0, n_unclear(1) = 0
    logical :: clear_last(1) = .true.
    real(wp) :: last_time(1) = 0
    logical :: counting(1) = .false.    !< some threshold is set: the times beyond are counted
  end type running_t

  !> The same for the lanes of a batch, a row per lane.
  type :: running_lanes_t
    real(wp), dimension(lanes, quantity_count) :: start = 0, maximum = 0, maximum_time = 0, last = 0
    real(wp), dimension(lanes, quantity_count) :: threshold = 0, value_before = 0, time_beyond = 0
    real(wp), dimension(lanes, quantity_count) :: clear_maximum = 0, clear_maximum_time = 0
    integer(i8) :: n_clear(lanes) = 0, n_unclear(lanes) = 0
    logical :: clear_last(lanes) = .true.
    real(wp) :: last_time(lanes) = 0
    logical :: counting(lanes) = .false.
  end type running_lanes_t

  !> The threshold of an input left unset (NaN): no magnitude exceeds it,
  !> and its figure is NaN.
  real(wp), parameter :: unset = huge(1.0_wp)

  integer :: k_        ! (of implied loops in constant expressions)
  !> The quantities whose times beyond are kept (a constant list: the
  !> per-step work is fixed by the table, not looked up per step).
  integer, parameter :: beyond_list(*) = pack([(k_, k_ = 1, quantity_count)], beyond)

  interface add_step_ends
    module procedure add_case_step_end, add_lanes_step_ends
  end interface add_step_ends

  !> A value of a quantity located inside a step (a peak between its ends).
  interface add_inside
    module procedure add_case_inside, add_lane_inside
  end interface add_inside

contains

  !> The quantities of a case at t = 0, from which the changing ones
  !> change and its times beyond count, and the case's inputs (param, the
  !> parameter table's rows) that hold the thresholds (NaN: unset).
  pure subroutine start_running(stats, q, param)
    type(running_t), intent(inout) :: stats
    real(wp), intent(in) :: q(1, quantity_count), param(:)
    type(figure_t) :: f
    integer :: k, i
    stats%start = q
    do k = 1, figure_count
      f = figures(k)        ! (a copy: gfortran 12 misreads an associate name of a constant's element)
      if (f%source /= from_time_beyond) cycle
      i = f%quantity
      stats%threshold(1, i) = param(f%threshold)
      if (ieee_is_nan(stats%threshold(1, i))) stats%threshold(1, i) = unset
      stats%counting(1) = stats%counting(1) .or. stats%threshold(1, i) < unset
      stats%value_before(1, i) = q(1, i)
    end do
  end subroutine start_running

  !> What an accepted step end at time t with quantities q adds to a case's
  !> statistics (add_row).
  pure subroutine add_case_step_end(stats, q, t)
    type(running_t), intent(inout) :: stats
    real(wp), intent(in) :: q(1, quantity_count), t
    call add_row(1, 1, stats%start, stats%maximum, stats%maximum_time, stats%last, stats%threshold, &
                 stats%value_before, stats%time_beyond, stats%last_time, stats%counting, q, t)
    call add_clear(1, 1, stats%start, stats%clear_maximum, stats%clear_maximum_time, stats%n_clear, stats%n_unclear, &
                   stats%clear_last, q, t)
  end subroutine add_case_step_end

  !> What the accepted lanes' step ends (quantities q, a row per lane, at
  !> times t) add to their statistics: one pass over the lanes, each
  !> accepted one's statistics as one case's (add_row; a test per lane, not
  !> per lane and statistic).
  pure subroutine add_lanes_step_ends(stats, q, t, accepted)
    type(running_lanes_t), intent(inout) :: stats
    real(wp), intent(in) :: q(lanes, quantity_count), t(lanes)
    logical, intent(in) :: accepted(lanes)
    integer :: l
    do l = 1, lanes
      if (.not. accepted(l)) cycle
      call add_row(lanes, l, stats%start, stats%maximum, stats%maximum_time, stats%last, stats%threshold, &
                   stats%value_before, stats%time_beyond, stats%last_time, stats%counting, q, t(l))
      call add_clear(lanes, l, stats%start, stats%clear_maximum, stats%clear_maximum_time, stats%n_clear, &
                     stats%n_unclear, stats%clear_last, q, t(l))
    end do
  end subroutine add_lanes_step_ends

  !> The value of quantity i at time t inside a step (clear: of the cup's
  !> curvature there) into the case's maxima (add_peak_row).
  pure subroutine add_case_inside(stats, i, value, t, clear)
    type(running_t), intent(inout) :: stats
    integer, intent(in) :: i
    real(wp), intent(in) :: value, t
    logical, intent(in) :: clear
    call add_peak_row(1, 1, stats%maximum, stats%maximum_time, stats%clear_maximum, stats%clear_maximum_time, &
                      i, value, t, clear)
  end subroutine add_case_inside

  !> The same into lane l's maxima.
  pure subroutine add_lane_inside(stats, l, i, value, t, clear)
    type(running_lanes_t), intent(inout) :: stats
    integer, intent(in) :: l, i
    real(wp), intent(in) :: value, t
    logical, intent(in) :: clear
    call add_peak_row(lanes, l, stats%maximum, stats%maximum_time, stats%clear_maximum, stats%clear_maximum_time, &
                      i, value, t, clear)
  end subroutine add_lane_inside

  !> Row l's maximum of quantity i (not a changing one) and its time, and
  !> where clear those over the points clear of the cup's curvature, take a
  !> value between step ends; the step-end statistics (counts, last values,
  !> times beyond) are the step ends' alone.
  pure subroutine add_peak_row(n, l, maximum, maximum_time, clear_maximum, clear_maximum_time, i, value, t, clear)
    integer, intent(in) :: n, l, i
    real(wp), intent(inout), dimension(n, quantity_count) :: maximum, maximum_time, clear_maximum, clear_maximum_time
    real(wp), intent(in) :: value, t
    logical, intent(in) :: clear
    if (value > maximum(l, i)) then
      maximum(l, i) = value
      if (timed(i)) maximum_time(l, i) = t
    end if
    if (clear .and. value > clear_maximum(l, i)) then
      clear_maximum(l, i) = value
      clear_maximum_time(l, i) = t
    end if
  end subroutine add_peak_row

  !> Row l's maxima (and their times) over the step ends clear of the
  !> cup's curvature (fit_clearance > 0), taken as add_row takes them over
  !> every step end; the step ends clear and not counted, and whether this
  !> one was (clear_last).
  pure subroutine add_clear(n, l, start, clear_maximum, clear_maximum_time, n_clear, n_unclear, clear_last, q, t)
    integer, intent(in) :: n, l
    real(wp), intent(in), dimension(n, quantity_count) :: start, q
    real(wp), intent(inout), dimension(n, quantity_count) :: clear_maximum, clear_maximum_time
    integer(i8), intent(inout) :: n_clear(n), n_unclear(n)
    logical, intent(inout) :: clear_last(n)
    real(wp), intent(in) :: t
    real(wp) :: value
    integer :: i
    clear_last(l) = q(l, q_fit_clearance) > 0
    if (clear_last(l)) then
      do i = 1, quantity_count
        value = q(l, i)
        if (quantities(i)%change) value = abs(value - start(l, i))
        if (value > clear_maximum(l, i)) then
          clear_maximum(l, i) = value
          clear_maximum_time(l, i) = t
        end if
      end do
      n_clear(l) = n_clear(l) + 1
    else
      n_unclear(l) = n_unclear(l) + 1
    end if
  end subroutine add_clear

  !> What row l's accepted step end (quantities q(l, :), at time t) adds to
  !> the statistics of n rows: the quantities unrolled (constant tests), the
  !> statistics no figure takes dropped; the times beyond only where a
  !> threshold is set (an unset one is huge: nothing is added).
  pure subroutine add_row(n, l, start, maximum, maximum_time, last, threshold, value_before, time_beyond, last_time, &
                          counting, q, t)
    integer, intent(in) :: n, l
    real(wp), intent(in), dimension(n, quantity_count) :: start, threshold, q
    real(wp), intent(inout), dimension(n, quantity_count) :: maximum, maximum_time, last, value_before, time_beyond
    real(wp), intent(inout) :: last_time(n)
    logical, intent(in) :: counting(n)
    real(wp), intent(in) :: t
    real(wp) :: value
    integer :: i, j
!GCC$ unroll 16
    do i = 1, quantity_count
      value = q(l, i)
      if (quantities(i)%change) value = abs(value - start(l, i))
      if (timed(i)) then
        if (value > maximum(l, i)) then
          maximum(l, i) = value
          maximum_time(l, i) = t
        end if
      else
        maximum(l, i) = max(maximum(l, i), value)
      end if
      if (lasting(i)) last(l, i) = q(l, i)
    end do
    if (counting(l)) then
      do j = 1, size(beyond_list)
        i = beyond_list(j)
        value = q(l, i)
        time_beyond(l, i) = time_beyond(l, i) + time_above(value_before(l, i), value, threshold(l, i), t - last_time(l))
        value_before(l, i) = value
      end do
    end if
    last_time(l) = t
  end subroutine add_row

  !> The time within a step of length dt that a magnitude going from r0 to
  !> r1, linearly in time, spends above the threshold c: all of it, none,
  !> or the part beyond the crossing, (max(r0, r1) - c) / |r1 - r0| of it
  !> (in (0, 1]: where exactly one end is above c they differ). Branch-free
  !> (merge evaluates both sides), so every operand is kept finite for the
  !> builds that trap: magnitudes held at most huge, an unset threshold
  !> huge (never exceeded).
  pure real(wp) function time_above(r0, r1, c, dt)
    real(wp), intent(in) :: r0, r1, c, dt
    real(wp) :: u0, u1, fraction
    logical :: crossed
    u0 = min(r0, huge(1.0_wp))
    u1 = min(r1, huge(1.0_wp))
    crossed = (u0 > c) .neqv. (u1 > c)
    fraction = merge((max(u0, u1) - c) / merge(abs(u1 - u0), 1.0_wp, crossed), 0.0_wp, crossed)
    fraction = merge(1.0_wp, fraction, u0 > c .and. u1 > c)
    time_above = dt * fraction
  end function time_above

  !> Lane l's statistics as one case's.
  pure subroutine get_lane(lane_stats, l, stats)
    type(running_lanes_t), intent(in) :: lane_stats
    integer, intent(in) :: l
    type(running_t), intent(inout) :: stats
    stats%start(1, :) = lane_stats%start(l, :)
    stats%maximum(1, :) = lane_stats%maximum(l, :)
    stats%maximum_time(1, :) = lane_stats%maximum_time(l, :)
    stats%last(1, :) = lane_stats%last(l, :)
    stats%threshold(1, :) = lane_stats%threshold(l, :)
    stats%value_before(1, :) = lane_stats%value_before(l, :)
    stats%time_beyond(1, :) = lane_stats%time_beyond(l, :)
    stats%clear_maximum(1, :) = lane_stats%clear_maximum(l, :)
    stats%clear_maximum_time(1, :) = lane_stats%clear_maximum_time(l, :)
    stats%n_clear(1) = lane_stats%n_clear(l)
    stats%n_unclear(1) = lane_stats%n_unclear(l)
    stats%clear_last(1) = lane_stats%clear_last(l)
    stats%last_time(1) = lane_stats%last_time(l)
    stats%counting(1) = lane_stats%counting(l)
  end subroutine get_lane

  !> One case's statistics into lane l.
  pure subroutine put_lane(lane_stats, l, stats)
    type(running_lanes_t), intent(inout) :: lane_stats
    integer, intent(in) :: l
    type(running_t), intent(in) :: stats
    lane_stats%start(l, :) = stats%start(1, :)
    lane_stats%maximum(l, :) = stats%maximum(1, :)
    lane_stats%maximum_time(l, :) = stats%maximum_time(1, :)
    lane_stats%last(l, :) = stats%last(1, :)
    lane_stats%threshold(l, :) = stats%threshold(1, :)
    lane_stats%value_before(l, :) = stats%value_before(1, :)
    lane_stats%time_beyond(l, :) = stats%time_beyond(1, :)
    lane_stats%clear_maximum(l, :) = stats%clear_maximum(1, :)
    lane_stats%clear_maximum_time(l, :) = stats%clear_maximum_time(1, :)
    lane_stats%n_clear(l) = stats%n_clear(1)
    lane_stats%n_unclear(l) = stats%n_unclear(1)
    lane_stats%clear_last(l) = stats%clear_last(1)
    lane_stats%last_time(l) = stats%last_time(1)
    lane_stats%counting(l) = stats%counting(1)
  end subroutine put_lane

  !> The figures made from a case's statistics into res, at the end of the
  !> case, whose ball has this mass. The scalings and quotients are taken of
  !> the maxima kept: both are correctly rounded and monotonic, so the
  !> result is the same number as the maximum of the scaled values or quotients.
  !> A case that ended at a model limit (res%status) after step ends not
  !> clear of the cup's curvature takes its maxima over the clear ones
  !> (NaN where none was) and is marked peaks_truncated.
  pure subroutine finish_running(stats, mass, res)
    type(running_t), intent(in) :: stats
    real(wp), intent(in) :: mass
    type(case_result_t), intent(inout) :: res
    type(figure_t) :: f
    real(wp) :: value, start
    real(wp), dimension(quantity_count) :: maximum, maximum_time
    integer :: k
    maximum = stats%maximum(1, :)
    maximum_time = stats%maximum_time(1, :)
    res%counts(fig_peaks_truncated) = 0
    if (is_model_limit(res%status) .and. stats%n_unclear(1) > 0) then
      res%counts(fig_peaks_truncated) = 1
      maximum = stats%clear_maximum(1, :)
      maximum_time = stats%clear_maximum_time(1, :)
      if (stats%n_clear(1) == 0) then
        maximum = ieee_value(value, ieee_quiet_nan)
        maximum_time = maximum
      end if
    end if
    do k = 1, figure_count
      f = figures(k)        ! (a copy: gfortran 12 misreads an associate name of a constant's element)
      select case (f%source)
      case (from_maximum)
        value = maximum(f%quantity)
      case (from_maximum_time)
        value = maximum_time(f%quantity)
      case (from_last)
        value = stats%last(1, f%quantity)
      case (from_time_beyond)
        value = stats%time_beyond(1, f%quantity)
        if (stats%threshold(1, f%quantity) >= unset) value = ieee_value(value, ieee_quiet_nan)
      case (from_counter, from_run)     ! kept by the loops, or made by the run itself
        cycle
      case default
        error stop 'ellroll_running: a summary figure of an unknown source (ellroll_figures)'
      end select
      select case (f%finish)
      case (finish_none)
        ! the friction ratio where N is not positive (a start that lifts off
        ! at once, without gravity) is huge, as the slip check takes it: undefined
        if (f%quantity == q_friction_needed .and. .not. ieee_is_nan(value)) then
          if (value >= huge(value)) value = ieee_value(value, ieee_quiet_nan)
        end if
      case (finish_force)
        value = from_mass_units(value, mass)
      case (finish_per_mass)
        value = value / fraction(mass)
      case (finish_per_start)
        ! undefined (NaN) where the start is 0, as E0 of a ball at rest
        ! without gravity (the test is also false where the quotient would
        ! overflow)
        start = abs(stats%start(1, f%quantity))
        if (ieee_is_nan(value)) then      ! (no clear step end: NaN is not compared, for the builds that trap)
        else if (value / huge(1.0_wp) < start) then
          value = value / start
        else
          value = ieee_value(value, ieee_quiet_nan)
        end if
      case default
        error stop 'ellroll_running: a summary figure of an unknown finish (ellroll_figures)'
      end select
      res%reals(k) = value
    end do
  end subroutine finish_running
end module ellroll_running
