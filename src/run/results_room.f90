!> Whether the results of a run held in memory (the library's runs: no
!> file) fit in the memory the process may hold, checked before any of it
!> is taken: a failed allocation would end the calling process.
module ellroll_results_room
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_strings, only: itoa
  use ellroll_system, only: memory_room
  use ellroll_cases, only: field_ncomp
  use ellroll_input, only: run_input_t
  implicit none
  private

  public :: check_room

contains

  !> The results are held whole, twice while they are laid out (each
  !> case's buffers, then the datasets), with some 2 kB of inputs and
  !> figures a case: refused where that passes the memory the process may
  !> hold (memory_room), before any of it is taken (a failed allocation
  !> would end the calling process).
  subroutine check_room(label, inp, n_cases, err)
    character(len=*), intent(in) :: label          !< the input's name
    type(run_input_t), intent(in) :: inp
    integer(i8), intent(in) :: n_cases
    type(error_t), intent(inout) :: err
    real(wp) :: needed, room
    room = real(memory_room(), wp)
    needed = real(n_cases, wp) * (2 * inp%plan%case_bytes() + 2048)
    if (.not. (room > 0 .and. needed > room)) return
    call set_error(err, err_input, label // ': the results of ' // itoa(n_cases) // ' cases, ' // &
        itoa(inp%plan%n_samples) // ' samples of ' // itoa(sum(field_ncomp, mask=inp%plan%fields)) // &
        ' values each, need about ' // itoa(gib(needed)) // ' GiB of memory, more than this process may hold (' // &
        itoa(gib(room)) // ' GiB' // &
        '): store fewer fields, fewer samples (a longer interval) or fewer cases at a time, or write them to a ' // &
        "file with 'ellroll run', which holds a case's results only until they are written")
  contains
    pure integer(i8) function gib(bytes)
      real(wp), intent(in) :: bytes
      gib = max(1_i8, nint(bytes / 2.0_wp**30, i8))
    end function gib
  end subroutine check_room
end module ellroll_results_room
