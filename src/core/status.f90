!> How a case ended. Stored in /summary/status with CF flag_values/flag_meanings.
module ellroll_status
  implicit none
  private

  public :: status_pending, status_completed, status_rim, status_no_fit, status_slip, &
            status_liftoff, status_nonfinite, status_constraint, status_invalid, status_unstable, status_name, status_count

  integer, parameter :: status_pending = 0     !< not integrated (yet)
  integer, parameter :: status_completed = 1   !< reached t_end
  integer, parameter :: status_rim = 2         !< contact point reached the rim z = c
  integer, parameter :: status_no_fit = 3      !< ball radius reached a principal radius of curvature
  integer, parameter :: status_slip = 4        !< friction needed exceeded mu
  integer, parameter :: status_liftoff = 5     !< normal force reached zero
  integer, parameter :: status_nonfinite = 6   !< state became NaN or infinite
  integer, parameter :: status_constraint = 7  !< contact point left the surface beyond tolerance
  integer, parameter :: status_invalid = 8     !< input invalid (&campaign invalid = 'skip'), not run
  !> the method could not follow the model: a fixed step was beyond the
  !> method's stability at the start (what it met was its own growth), or
  !> its implicit equations had no solution; an adaptive method's step
  !> control shrank the step to round-off of t (or made max_steps attempts)
  integer, parameter :: status_unstable = 9
  integer, parameter :: status_count = 10

  character(len=10), parameter :: names(0:status_count-1) = [character(len=10) :: &
      'pending', 'completed', 'rim', 'no_fit', 'slip', 'liftoff', 'nonfinite', 'constraint', 'invalid', 'unstable']

contains

  pure function padded_name(status) result(name)
    integer, intent(in) :: status
    character(len=10) :: name
    name = 'unknown'
    if (status >= 0 .and. status < status_count) name = names(status)
  end function padded_name

  pure function status_name(status) result(name)
    integer, intent(in) :: status
    character(len=len_trim(padded_name(status))) :: name
    name = padded_name(status)
  end function status_name

end module ellroll_status
