!> What integrating one case produced: the sampled trajectories of the fields
!> the run asked for, and the per-case summary, kept as the summary table
!> (ellroll_figures) lays it out.
module ellroll_results
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: named_value_t, real_value, int_value, vector_value, kind_int
  use ellroll_status, only: status_pending, status_invalid
  use ellroll_cases, only: field_count, field_ncomp
  use ellroll_figures, only: figure_t, figures, figure_count, real_slots, figure_slots, from_counter, fig_t_final, fig_n_steps, &
      fig_n_rejected, fig_n_rhs, fig_wall_time, fig_n_rhs_reference
  implicit none
  private

  public :: field_buffer_t, case_result_t, summary_record, set_summary_value, figure_values, set_figure_values, &
            allocate_fields, fill_unrecorded, add_switch

  !> A count (an integer figure) undefined for the case, as NaN is for a
  !> real one: /summary's _FillValue of its integer figures
  integer(i8), parameter, public :: count_undefined = -1

  !> The kinds of a switch of regime (case_result_t%switch_kind).
  integer, parameter, public :: switch_to_sliding = 1, switch_to_rolling = 2

  integer :: k        ! (of implied loops in constant expressions)

  !> The counts' defaults: 0, counted up as the case runs, but
  !> n_rhs_reference, which only a reference run (error_estimate) sets
  integer(i8), parameter :: count_defaults(figure_count) = &
      merge(count_undefined, 0_i8, [(k == fig_n_rhs_reference, k = 1, figure_count)])

  !> A NaN for default initialisation (0/0 is not a constant expression).
  real(wp), parameter :: nan_value = transfer(9221120237041090560_i8, 1.0_wp)

  type :: field_buffer_t
    real(wp), allocatable :: values(:, :)    !< (ncomp, n_samples); NaN after the case ended
  end type field_buffer_t

  !> A case's result. Every figure is NaN (a count 0, n_rhs_reference -1)
  !> until the integration sets it: a case never run (invalid, or pending)
  !> holds no number that could pass for data.
  type :: case_result_t
    integer :: status = status_pending
    ! the integration's counters (the summary table's rows from_counter),
    ! which every loop updates as it goes
    real(wp) :: t_final = nan_value
    integer(i8) :: n_steps = 0
    integer(i8) :: n_rejected = 0
    integer(i8) :: n_rhs = 0
    real(wp) :: wall_time = nan_value
    !> every other figure at its row k of the summary table: a real one at
    !> reals(k) (a per-mode one's further components at figure_slots(k)), a
    !> count at counts(k)
    real(wp) :: reals(real_slots) = nan_value
    integer(i8) :: counts(figure_count) = count_defaults
    type(field_buffer_t) :: fields(field_count)
    integer(i8) :: n_recorded = 0              !< output samples recorded so far (they come in order)
    !> a case that may slide: its switches of regime in order, their times
    !> and kinds (switch_to_sliding, switch_to_rolling), n_switches of them
    integer :: n_switches = 0
    real(wp), allocatable :: switch_time(:)
    integer, allocatable :: switch_kind(:)
  end type case_result_t

contains

  !> A switch of regime at time t of kind `kind` joins res's list.
  pure subroutine add_switch(res, t, kind)
    type(case_result_t), intent(inout) :: res
    real(wp), intent(in) :: t
    integer, intent(in) :: kind
    real(wp), allocatable :: times(:)
    integer, allocatable :: kinds(:)
    if (.not. allocated(res%switch_time)) allocate (res%switch_time(8), res%switch_kind(8))
    if (res%n_switches == size(res%switch_time)) then
      allocate (times(2 * res%n_switches), kinds(2 * res%n_switches))
      times(:res%n_switches) = res%switch_time
      kinds(:res%n_switches) = res%switch_kind
      call move_alloc(times, res%switch_time)
      call move_alloc(kinds, res%switch_kind)
    end if
    res%n_switches = res%n_switches + 1
    res%switch_time(res%n_switches) = t
    res%switch_kind(res%n_switches) = kind
  end subroutine add_switch

  !> Buffers in res for the wanted fields only (in place: a function result
  !> would copy every buffer once more); fill_unrecorded makes what the case
  !> did not reach NaN, so that no sample is written twice.
  pure subroutine allocate_fields(res, wanted, n_samples)
    type(case_result_t), intent(inout) :: res
    logical, intent(in) :: wanted(field_count)
    integer(i8), intent(in) :: n_samples
    integer :: f
    do f = 1, field_count
      if (allocated(res%fields(f)%values)) deallocate (res%fields(f)%values)
      if (wanted(f)) then
        allocate (res%fields(f)%values(field_ncomp(f), n_samples))
      end if
    end do
    res%n_recorded = 0
  end subroutine allocate_fields

  !> NaN in every output sample after the last one recorded (the case ended
  !> before it).
  pure subroutine fill_unrecorded(res)
    type(case_result_t), intent(inout) :: res
    integer :: f
    do f = 1, field_count
      if (allocated(res%fields(f)%values)) &
        res%fields(f)%values(:, res%n_recorded + 1:) = ieee_value(0.0_wp, ieee_quiet_nan)
    end do
  end subroutine fill_unrecorded

  !> The per-case summary as stored under /summary/ (status is written
  !> apart): every row of the summary table, in its order; a case never
  !> run (pending, invalid) has its counts count_undefined, its reals NaN.
  pure function summary_record(res) result(rec)
    type(case_result_t), intent(in) :: res
    type(named_value_t) :: rec(figure_count)
    type(figure_t) :: f
    integer :: k
    do k = 1, figure_count
      f = figures(k)        ! (a copy: gfortran 12 misreads an associate name of a constant's element)
      if (f%kind == kind_int) then
        if (res%status == status_pending .or. res%status == status_invalid) then
          rec(k) = int_value(trim(f%name), trim(f%unit), trim(f%long_name), count_undefined)
        else
          rec(k) = int_value(trim(f%name), trim(f%unit), trim(f%long_name), figure_count_value(res, k))
        end if
      else if (f%ncomp == 1) then
        rec(k) = real_value(trim(f%name), trim(f%unit), trim(f%long_name), figure_value(res, k))
      else
        rec(k) = vector_value(trim(f%name), trim(f%unit), trim(f%long_name), figure_values(res, k))
      end if
    end do
  end function summary_record

  !> The inverse of summary_record for its entry k (reading a stored summary back).
  pure subroutine set_summary_value(res, k, value)
    type(case_result_t), intent(inout) :: res
    integer, intent(in) :: k
    type(named_value_t), intent(in) :: value
    if (figures(k)%kind == kind_int) then
      call set_figure_count(res, k, value%int)
    else
      call set_figure_values(res, k, value%reals(:figures(k)%ncomp))
    end if
  end subroutine set_summary_value

  !> Real row k's components.
  pure function figure_values(res, k) result(values)
    type(case_result_t), intent(in) :: res
    integer, intent(in) :: k
    real(wp) :: values(figures(k)%ncomp)
    if (figures(k)%source == from_counter) then
      values = figure_value(res, k)
    else
      values = res%reals(figure_slots(k))
    end if
  end function figure_values

  pure subroutine set_figure_values(res, k, values)
    type(case_result_t), intent(inout) :: res
    integer, intent(in) :: k
    real(wp), intent(in) :: values(figures(k)%ncomp)
    if (figures(k)%source /= from_counter) then
      res%reals(figure_slots(k)) = values
    else if (k == fig_t_final) then
      res%t_final = values(1)
    else if (k == fig_wall_time) then
      res%wall_time = values(1)
    end if
  end subroutine set_figure_values

  !> Real row k's (first) component: an integration counter (t_final,
  !> wall_time) or its slot.
  pure real(wp) function figure_value(res, k) result(value)
    type(case_result_t), intent(in) :: res
    integer, intent(in) :: k
    if (k == fig_t_final) then
      value = res%t_final
    else if (k == fig_wall_time) then
      value = res%wall_time
    else
      value = res%reals(k)
    end if
  end function figure_value

  !> Count row k: an integration counter (n_steps, n_rejected, n_rhs) or its slot.
  pure integer(i8) function figure_count_value(res, k) result(value)
    type(case_result_t), intent(in) :: res
    integer, intent(in) :: k
    if (k == fig_n_steps) then
      value = res%n_steps
    else if (k == fig_n_rejected) then
      value = res%n_rejected
    else if (k == fig_n_rhs) then
      value = res%n_rhs
    else
      value = res%counts(k)
    end if
  end function figure_count_value

  pure subroutine set_figure_count(res, k, value)
    type(case_result_t), intent(inout) :: res
    integer, intent(in) :: k
    integer(i8), intent(in) :: value
    if (k == fig_n_steps) then
      res%n_steps = value
    else if (k == fig_n_rejected) then
      res%n_rejected = value
    else if (k == fig_n_rhs) then
      res%n_rhs = value
    else
      res%counts(k) = value
    end if
  end subroutine set_figure_count
end module ellroll_results
