!> User limit states (&limit_state): a capacity on a /summary figure, and
!> whether a case exceeded it. A case that ended at a model limit (rim,
!> no_fit, slip, liftoff) exceeded every limit state: the isolator's capacity
!> is gone; a completed case exceeded one where its figure is above the
!> capacity, and holds -1 (undefined) where its figure is NaN (undefined for
!> it: residual_displacement while the ball still moves, transmissibility
!> of a record run), its outcome unknown; any other case (never run, a
!> numerical failure) holds 0, its outcome unknown (its status says so).
module ellroll_limit_states
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: kind_real
  use ellroll_status, only: status_completed, status_rim, status_no_fit, status_slip, status_liftoff
  use ellroll_figures, only: figures, figure_count
  implicit none
  private

  public :: limit_state_t, limit_state_figures, is_model_limit, exceeded_flag

  !> /limit_state's flags: CF's flag_values and flag_meanings
  integer(i8), parameter, public :: flag_undefined = -1, flag_not_exceeded = 0, flag_exceeded = 1
  integer(i8), parameter, public :: limit_state_flag_values(*) = [flag_undefined, flag_not_exceeded, flag_exceeded]
  character(len=*), parameter, public :: limit_state_flag_meanings = 'undefined not_exceeded exceeded'

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

  !> 1 where a case of this status and figure value exceeded the capacity:
  !> at a model limit always; completed where value > capacity; -1 where
  !> it completed with a NaN value (a figure undefined for the case: no
  !> outcome, neither exceeded nor not); else 0.
  pure integer(i8) function exceeded_flag(state, status, value) result(flag)
    type(limit_state_t), intent(in) :: state
    integer, intent(in) :: status
    real(wp), intent(in) :: value
    flag = flag_not_exceeded
    if (is_model_limit(status)) then
      flag = flag_exceeded
    else if (status == status_completed) then
      if (ieee_is_nan(value)) then
        flag = flag_undefined
      else if (value > state%capacity) then
        flag = flag_exceeded
      end if
    end if
  end function exceeded_flag
end module ellroll_limit_states
