!> User limit states (&limit_state): a capacity on a /summary figure, and
!> whether a case exceeded it. A case that ended at a model limit (rim,
!> no_fit, slip, liftoff) exceeded every limit state: the isolator's capacity
!> is gone; a completed case exceeded one where its figure is above the
!> capacity; any other case (never run, a numerical failure) holds 0, its
!> outcome unknown (its status says so).
module ellroll_limit_states
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: kind_real
  use ellroll_status, only: status_completed, status_rim, status_no_fit, status_slip, status_liftoff
  use ellroll_figures, only: figures, figure_count
  implicit none
  private

  public :: limit_state_t, limit_state_figures, is_model_limit, exceeded_flag

  type :: limit_state_t
    character(len=32) :: name = ''
    integer :: figure = 0         !< its row of the summary table
    real(wp) :: capacity = 0      !< in the figure's unit
  end type limit_state_t

contains

  !> The figures a limit state may name: the real single-valued rows of the
  !> summary table (a per-mode figure has no one value to compare) but
  !> wall_time (not reproducible).
  pure function limit_state_figures() result(names)
    character(len=len(figures%name)), allocatable :: names(:)
    integer :: k
    names = pack(figures%name, [(figures(k)%kind == kind_real .and. figures(k)%ncomp == 1 .and. &
                                 figures(k)%name /= 'wall_time', k = 1, figure_count)])
  end function limit_state_figures

  pure logical function is_model_limit(status)
    integer, intent(in) :: status
    is_model_limit = any(status == [status_rim, status_no_fit, status_slip, status_liftoff])
  end function is_model_limit

  !> 1 where a case of this status and figure value exceeded the capacity,
  !> else 0: at a model limit always; completed where value > capacity (a
  !> NaN value, a figure undefined for the case, does not exceed).
  pure integer(i8) function exceeded_flag(state, status, value) result(flag)
    type(limit_state_t), intent(in) :: state
    integer, intent(in) :: status
    real(wp), intent(in) :: value
    flag = 0
    if (is_model_limit(status)) then
      flag = 1
    else if (status == status_completed .and. .not. ieee_is_nan(value)) then
      if (value > state%capacity) flag = 1
    end if
  end function exceeded_flag
end module ellroll_limit_states
