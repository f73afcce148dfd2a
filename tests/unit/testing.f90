!> Minimal assertions for the unit tests: count failures, report, exit non-zero.
module testing
  use ellroll_kinds, only: wp
  implicit none
  private
  public :: check, check_close, check_below, finish

  integer :: failures = 0, checks = 0

contains

  subroutine check(condition, what)
    logical, intent(in) :: condition
    character(len=*), intent(in) :: what
    checks = checks + 1
    if (.not. condition) then
      failures = failures + 1
      print '(a)', 'FAIL: ' // what
    end if
  end subroutine check

  !> |actual - expected| <= rtol |expected|
  subroutine check_close(actual, expected, rtol, what)
    real(wp), intent(in) :: actual, expected, rtol
    character(len=*), intent(in) :: what
    character(len=200) :: line
    write (line, '(a, es24.16, a, es24.16, a, es9.2)') ': got ', actual, ' expected ', expected, &
        ' rel.err ', abs(actual - expected) / max(abs(expected), tiny(1.0_wp))
    call check(abs(actual - expected) <= rtol * abs(expected), what // trim(line))
    if (abs(actual - expected) <= rtol * abs(expected)) print '(a)', 'ok: ' // what // trim(line)
  end subroutine check_close

  !> value <= bound, printing the figure either way
  subroutine check_below(value, bound, what)
    real(wp), intent(in) :: value, bound
    character(len=*), intent(in) :: what
    character(len=120) :: line
    write (line, '(a, es10.3, a, es9.2)') ' = ', value, ' (bound ', bound
    call check(value <= bound, what // trim(line) // ')')
    if (value <= bound) print '(a)', 'ok: ' // what // trim(line) // ')'
  end subroutine check_below

  subroutine finish(name)
    character(len=*), intent(in) :: name
    print '(a, i0, a, i0, a)', name // ': ', checks - failures, ' passed, ', failures, ' failed'
    if (failures > 0) error stop 1
  end subroutine finish
end module testing
