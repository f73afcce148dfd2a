!> Where a campaign's time goes (`ellroll run --timings`): before, in and
!> after the parallel loop, and for each section of the loop that one thread
!> at a time can be in, the time spent in it and waiting for it, summed over
!> the threads. Those are the loop's locks, and the writes of trajectories
!> and journal records in place: the threads write at once, but the kernel
!> takes a file's lock for each write (Linux file systems), so they take
!> turns there. The loop cannot take less than its busiest section, whatever
!> the number of threads: on one thread, that share of the loop bounds the
!> speed-up of any number of them.
module ellroll_run_timings
  use ellroll_standard_output, only: put_line
  use ellroll_kinds, only: wp, i8
  implicit none
  private

  public :: run_timings_t, wall_clock
  public :: lock_journal, lock_keep, lock_writer, writes_trajectories, writes_journal

  integer, parameter :: lock_journal = 1, lock_keep = 2, lock_writer = 3, writes_trajectories = 4, &
      writes_journal = 5, section_count = 5
  character(len=*), parameter :: section_names(section_count) = [character(len=36) :: &
      'journal places (lock)', 'keeping rows (lock)', 'HDF5 writer (lock)', &
      'trajectory writes (the file''s lock)', 'journal writes (the file''s lock)']

  type :: run_timings_t
    real(wp) :: advice = 0               !< seconds of the step advice, before the run (parallel)
    real(wp) :: started = 0, checked = 0, loop_started = 0, loop_ended = 0, ended = 0   !< checked: cases checked (parallel)
    real(wp) :: held(section_count) = 0, waited(section_count) = 0   !< waited: for the locks only
  contains
    procedure :: tally
    procedure :: add_write
    procedure :: report
  end type run_timings_t

contains

  !> Seconds on a monotonic clock (nanosecond ticks), safe in threads.
  real(wp) function wall_clock()
    integer(i8) :: count, rate
    call system_clock(count, rate)
    wall_clock = real(count, wp) / real(rate, wp)
  end function wall_clock

  !> Count one holding of `lock`, asked for at `asked` and taken at `taken`;
  !> called by the holder before it lets go, so no two threads add to the
  !> same lock's figures at once.
  subroutine tally(self, lock, asked, taken)
    class(run_timings_t), intent(inout) :: self
    integer, intent(in) :: lock
    real(wp), intent(in) :: asked, taken
    self%waited(lock) = self%waited(lock) + (taken - asked)
    self%held(lock) = self%held(lock) + (wall_clock() - taken)
  end subroutine tally

  !> Count a write in place (`kind`) that started at `started`; any thread.
  subroutine add_write(self, kind, started)
    class(run_timings_t), intent(inout) :: self
    integer, intent(in) :: kind
    real(wp), intent(in) :: started
    real(wp) :: seconds
    seconds = wall_clock() - started
    !$omp atomic update
    self%held(kind) = self%held(kind) + seconds
  end subroutine add_write

  !> On standard output (put_line: a failed write is the program's exit 3).
  subroutine report(self)
    class(run_timings_t), intent(in) :: self
    integer :: k
    real(wp) :: loop
    character(len=200) :: line
    loop = self%loop_ended - self%loop_started
    write (line, '(a, 4(f7.4, a))') 'timings:', self%advice + (self%checked - self%started), &
        ' s in parallel before the loop (checks, step advice),', self%loop_started - self%checked, &
        ' s serial before it (file layout),', loop, &
        ' s in the loop,', self%ended - self%loop_ended, ' s after it (closing)'
    call put_line(trim(line))
    write (line, '(2x, a36, a)') 'one thread at a time', '   inside s  waiting s  (summed over the threads)'
    call put_line(trim(line))
    do k = 1, section_count
      write (line, '(2x, a36, 2f11.4)') section_names(k), self%held(k), self%waited(k)
      call put_line(trim(line))
    end do
    if (maxval(self%held) > 0 .and. loop > 0) then
      write (line, '(a, f5.2, a, f6.1, a)') &
          '  busiest:', 100 * maxval(self%held) / loop, ' % of the loop; no number of threads makes the loop over', &
          loop / maxval(self%held), 'x faster than here'
      call put_line(trim(line))
    end if
  end subroutine report
end module ellroll_run_timings
