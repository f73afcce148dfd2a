!> The program's standard output (the commands' tables, summaries and
!> help): every line goes through put_line, which sees a failed write
!> (gfortran's runtime drops those on its own units: standard_output.c),
!> and the program asks stdout_error once at the end, so a full disk,
!> /dev/full or an I/O error ends the program with exit 3 and a message.
!> Only the program's main thread writes here.
module ellroll_standard_output
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_size_t
  use ellroll_errors, only: error_t, set_error, err_output
  use ellroll_system, only: system_error_text
  implicit none
  private

  public :: put_line, put_lines, stdout_error

  !> errno of the first failed write (0: none); later lines are not tried
  integer, save :: first_failure = 0

  interface
    integer(c_int) function c_write_stdout(text, bytes) bind(c, name='ellroll_write_stdout')
      import :: c_int, c_char, c_size_t
      character(kind=c_char), intent(in) :: text(*)
      integer(c_size_t), value :: bytes
    end function c_write_stdout
    integer(c_int) function c_close_stdout() bind(c, name='ellroll_close_stdout')
      import :: c_int
    end function c_close_stdout
  end interface

contains

  !> One line of standard output (the newline added).
  subroutine put_line(text)
    character(len=*), intent(in) :: text
    if (first_failure /= 0) return
    first_failure = c_write_stdout(text // new_line('a'), int(len(text) + 1, c_size_t))
  end subroutine put_line

  !> Lines of standard output, each without its trailing blanks.
  subroutine put_lines(lines)
    character(len=*), intent(in) :: lines(:)
    integer :: k
    do k = 1, size(lines)
      call put_line(trim(lines(k)))
    end do
  end subroutine put_lines

  !> Whether every line reached standard output, asked once when the program
  !> ends (a close of a copy of it then reports deferred write errors).
  subroutine stdout_error(err)
    type(error_t), intent(inout) :: err
    if (first_failure == 0) first_failure = c_close_stdout()
    if (first_failure /= 0) call set_error(err, err_output, 'cannot write the standard output: ' // &
        system_error_text(first_failure))
  end subroutine stdout_error
end module ellroll_standard_output
