!> Progress of a campaign on stderr: cases done/total, cases per second and
!> the time left, at most a line a second; one refreshing line on a
!> terminal, plain lines in a log.
module ellroll_progress
  use, intrinsic :: iso_fortran_env, only: error_unit
  use, intrinsic :: iso_c_binding, only: c_int
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: itoa, format_real
  implicit none
  private

  public :: progress_t

  interface
    integer(c_int) function c_isatty(fd) bind(c, name='isatty')
      import :: c_int
      integer(c_int), value :: fd
    end function c_isatty
  end interface

  type :: progress_t
    integer(i8) :: total = 0, done = 0, resumed = 0
    integer(i8) :: clock_start = 0, clock_last = 0, clock_rate = 1
    logical :: quiet = .false., terminal = .false., printed = .false.
  contains
    procedure :: start
    procedure :: advance
    procedure :: finish
  end type progress_t

contains

  subroutine start(self, total, already_done, quiet)
    class(progress_t), intent(inout) :: self
    integer(i8), intent(in) :: total, already_done
    logical, intent(in) :: quiet
    self%total = total
    self%done = already_done
    self%resumed = already_done
    self%quiet = quiet
    self%terminal = c_isatty(2_c_int) == 1
    call system_clock(self%clock_start, self%clock_rate)
    self%clock_last = self%clock_start
  end subroutine start

  !> One more case done; print if a second has passed since the last line.
  subroutine advance(self)
    class(progress_t), intent(inout) :: self
    integer(i8) :: now
    self%done = self%done + 1
    if (self%quiet) return
    call system_clock(now)
    if (now - self%clock_last < self%clock_rate .and. self%done < self%total) return
    self%clock_last = now
    call print_line(self, now)
  end subroutine advance

  subroutine finish(self)
    class(progress_t), intent(inout) :: self
    if (self%quiet .or. .not. self%printed) return
    if (self%terminal) write (error_unit, '(a)') ''
  end subroutine finish

  subroutine print_line(self, now)
    type(progress_t), intent(inout) :: self
    integer(i8), intent(in) :: now
    real(wp) :: elapsed, rate, left
    character(len=:), allocatable :: line
    elapsed = real(now - self%clock_start, wp) / real(self%clock_rate, wp)
    rate = real(self%done - self%resumed, wp) / max(elapsed, 1.0e-9_wp)
    line = 'ellroll: ' // itoa(int(self%done)) // '/' // itoa(int(self%total)) // ' cases (' // &
           itoa(int(100 * self%done / max(1_i8, self%total))) // '%), ' // &
           format_real(anint(10 * rate) / 10) // ' cases/s'
    if (rate > 0 .and. self%done < self%total) then
      left = real(self%total - self%done, wp) / rate
      line = line // ', ETA ' // clock_text(left)
    end if
    if (self%terminal) then
      write (error_unit, '(a)', advance='no') achar(13) // line // '   '
      flush (error_unit)
    else
      write (error_unit, '(a)') line
    end if
    self%printed = .true.
  end subroutine print_line

  function clock_text(seconds) result(text)
    real(wp), intent(in) :: seconds
    character(len=:), allocatable :: text
    integer :: s
    character(len=16) :: buf
    s = nint(seconds)
    write (buf, '(i0, ":", i2.2, ":", i2.2)') s / 3600, mod(s / 60, 60), mod(s, 60)
    text = trim(buf)
  end function clock_text
end module ellroll_progress
