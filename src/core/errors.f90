!> Errors travel as a small value (category + message) up to the program,
!> which alone turns them into messages and exit codes.
module ellroll_errors
  implicit none
  private

  public :: error_t, set_error
  public :: err_none, err_input, err_output, err_internal, err_interrupted, exit_code

  integer, parameter :: err_none = 0
  integer, parameter :: err_input = 2      !< bad input: exit 2
  integer, parameter :: err_output = 3     !< cannot write output: exit 3
  integer, parameter :: err_internal = 1   !< a bug or an unexpected failure: exit 1
  !> stopped by signal s (SIGTERM, SIGINT), the finished cases kept: exit 128 + s,
  !> as a shell reports a process ended by that signal
  integer, parameter :: err_interrupted = 128

  type :: error_t
    integer :: code = err_none
    character(len=:), allocatable :: message
  contains
    procedure :: failed
  end type error_t

contains

  logical pure function failed(self)
    class(error_t), intent(in) :: self
    failed = self%code /= err_none
  end function failed

  !> The error `code` with its message, a control character of it (from a
  !> file or a name it quotes: an escape sequence would reach the terminal)
  !> shown as '?'; the line breaks and tabs of the program's own messages kept.
  pure subroutine set_error(err, code, message)
    type(error_t), intent(inout) :: err
    integer, intent(in) :: code
    character(len=*), intent(in) :: message
    integer :: k, c
    err%code = code
    err%message = message
    do k = 1, len(message)
      c = iachar(message(k:k))
      if ((c < 32 .and. c /= 9 .and. c /= 10) .or. c == 127) err%message(k:k) = '?'
    end do
  end subroutine set_error

  integer pure function exit_code(err)
    type(error_t), intent(in) :: err
    exit_code = err%code
  end function exit_code
end module ellroll_errors
