!> Progress of a campaign on stderr: cases done/total, cases per second and
!> the time left. On a terminal one refreshing line, at most once a second;
!> in a log (a batch job's stderr) a full line, flushed, every 10 s and at
!> each tenth of the cases, the last one with the totals: cases per second
!> and the time taken, never a time left.
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
    integer :: last_length = 0           !< of the line on the terminal, which the next overwrites
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

  !> One more case done; print when a line is due (see above).
  subroutine advance(self)
    class(progress_t), intent(inout) :: self
    integer(i8), parameter :: log_every_seconds = 10
    integer(i8) :: now
    logical :: due
    self%done = self%done + 1
    if (self%quiet) return
    call system_clock(now)
    if (self%terminal) then
      due = now - self%clock_last >= self%clock_rate
    else
      due = now - self%clock_last >= log_every_seconds * self%clock_rate .or. &
            10 * self%done / max(1_i8, self%total) > 10 * (self%done - 1) / max(1_i8, self%total)   ! a tenth passed
    end if
    if (.not. (due .or. self%done == self%total)) return
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
    line = 'ellroll: ' // itoa(self%done) // '/' // itoa(self%total) // ' cases (' // &
           itoa(100 * self%done / max(1_i8, self%total)) // '%), ' // &
           format_real(anint(10 * rate) / 10) // ' cases/s'
    if (self%done >= self%total) then
      line = line // ', done in ' // clock_text(elapsed)
    else if (rate > 0) then
      left = real(self%total - self%done, wp) / rate
      line = line // ', ETA ' // clock_text(left)
    end if
    if (self%terminal) then
      ! blanks over what is left of a longer line before it (an ETA)
      write (error_unit, '(a)', advance='no') achar(13) // line // repeat(' ', max(0, self%last_length - len(line)))
      self%last_length = len(line)
      flush (error_unit)
    else
      write (error_unit, '(a)') line
      flush (error_unit)         ! a file's buffer would hold it until the run ends
    end if
    self%printed = .true.
  end subroutine print_line

  pure function clock_digits(seconds) result(text)
    real(wp), intent(in) :: seconds
    character(len=24) :: text
    integer(i8) :: s
    s = nint(min(max(seconds, 0.0_wp), 1.0e15_wp), i8)
    write (text, '(i0, ":", i2.2, ":", i2.2)') s / 3600, mod(s / 60, 60_i8), mod(s, 60_i8)
  end function clock_digits

  !> h:mm:ss
  pure function clock_text(seconds) result(text)
    real(wp), intent(in) :: seconds
    character(len=len_trim(clock_digits(seconds))) :: text
    text = clock_digits(seconds)
  end function clock_text

end module ellroll_progress
