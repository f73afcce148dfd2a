!> Whether the output of a run fits on its file system: its trajectories
!> (uncompressed: their size is known before the run), its tables and,
!> while it runs, the journal beside it (some 2 kB a case together). A run
!> that meets a full disk stops with exit 3, its journal keeping the cases
!> finished; the warning says so before the first case.
module ellroll_disk_room
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: format_real
  use ellroll_files, only: free_bytes
  use ellroll_cases, only: field_ncomp
  use ellroll_input, only: run_input_t
  implicit none
  private

  public :: output_bytes, output_room, disk_room_advice, shard_size

contains

  !> The cases of shard (I, N) of a campaign of n_cases: I, I + N, ...
  elemental integer(i8) function shard_size(n_cases, index, count)
    integer(i8), intent(in) :: n_cases
    integer, intent(in) :: index, count
    shard_size = 0
    if (index < n_cases .and. count > 0) shard_size = (n_cases - 1 - index) / count + 1
  end function shard_size

  !> The bytes the output of n_cases cases and its journal take, about.
  pure real(wp) function output_bytes(inp, n_cases) result(bytes)
    type(run_input_t), intent(in) :: inp
    integer(i8), intent(in) :: n_cases
    bytes = real(n_cases, wp) * (8 * real(inp%plan%n_samples, wp) * sum(field_ncomp, mask=inp%plan%fields) + 2048)
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
    message = ''
    if (inp%plan%compression > 0) return
    free = output_room(inp)
    needed = output_bytes(inp, n_cases)
    if (.not. (free >= 0 .and. needed > free)) return
    message = 'ellroll: warning: ' // inp%plan%file // ' and its journal take about ' // &
        format_real(real(nint(10 * needed / 2.0_wp**30, i8), wp) / 10) // ' GiB, more than the ' // &
        format_real(real(nint(10 * free / 2.0_wp**30, i8), wp) / 10) // ' GiB free on its file system: the run ' // &
        'stops (exit 3) when it is full, its journal keeping the cases finished (--resume goes on where there is room)'
  end subroutine disk_room_advice
end module ellroll_disk_room
