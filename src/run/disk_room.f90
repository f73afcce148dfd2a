!> Whether the output of a run fits on its file system: its trajectories
!> (uncompressed: their size is known before the run), its tables and,
!> while it runs, the journal beside it (some 2 kB a case together). A run
!> that meets a full disk stops with exit 3, its journal keeping the cases
!> finished; the warning says so before the first case.
module ellroll_disk_room
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: size_text
  use ellroll_files, only: free_bytes
  use ellroll_input, only: run_input_t
  implicit none
  private

  public :: output_bytes, output_room, disk_room_advice

contains

  !> The bytes the output of n_cases cases and its journal take, about.
  pure real(wp) function output_bytes(inp, n_cases) result(bytes)
    type(run_input_t), intent(in) :: inp
    integer(i8), intent(in) :: n_cases
    bytes = real(n_cases, wp) * (inp%plan%case_bytes() + 2048)
  end function output_bytes

  !> The bytes free on the file system of the output's folder (< 0: unknown).
  real(wp) function output_room(inp)
    type(run_input_t), intent(in) :: inp
    integer :: slash
    slash = index(inp%plan%file, '/', back=.true.)
    if (slash > 0) then
      output_room = real(free_bytes(inp%plan%file(:slash)), wp)
    else
      output_room = real(free_bytes('.'), wp)
    end if
  end function output_room

  !> A warning (or '') where the output of n_cases cases (uncompressed)
  !> and its journal would take more than its file system has free.
  subroutine disk_room_advice(inp, n_cases, message)
    type(run_input_t), intent(in) :: inp
    integer(i8), intent(in) :: n_cases
    character(len=:), allocatable, intent(out) :: message
    real(wp) :: needed, free
    character(len=:), allocatable :: needed_text, free_text
    message = ''
    if (inp%plan%compression > 0) return
    free = output_room(inp)
    needed = output_bytes(inp, n_cases)
    if (.not. (free >= 0 .and. needed > free)) return
    call size_text(needed, needed_text)
    call size_text(free, free_text)
    message = 'ellroll: warning: ' // inp%plan%file // ' and its journal take about ' // needed_text // &
        ', more than the ' // free_text // ' free on its file system: the run stops (exit 3) when it is full, ' // &
        'its journal keeping the cases finished (--resume goes on where there is room)'
  end subroutine disk_room_advice
end module ellroll_disk_room
