!> Locating where inside a step a model limit is first crossed.
!> Reverse communication: the caller asks for a trial offset, evaluates
!> whether the state there is still valid, and reports back. The search
!> knows nothing of what the limit means.
module ellroll_events
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: crossing_search_t

  type :: crossing_search_t
    real(wp) :: valid = 0      !< largest offset known to be valid
    real(wp) :: invalid = 0    !< smallest offset known to be past the limit
    real(wp) :: tolerance = 0
  contains
    procedure :: start
    procedure :: trial
    procedure :: report
    procedure :: done
  end type crossing_search_t

contains

  pure subroutine start(self, invalid, tolerance)
    class(crossing_search_t), intent(inout) :: self
    real(wp), intent(in) :: invalid, tolerance
    self%valid = 0
    self%invalid = invalid
    self%tolerance = tolerance
  end subroutine start

  pure real(wp) function trial(self)
    class(crossing_search_t), intent(in) :: self
    trial = self%valid + (self%invalid - self%valid) / 2
  end function trial

  pure subroutine report(self, offset, is_valid)
    class(crossing_search_t), intent(inout) :: self
    real(wp), intent(in) :: offset
    logical, intent(in) :: is_valid
    if (is_valid) then
      self%valid = offset
    else
      self%invalid = offset
    end if
  end subroutine report

  pure logical function done(self)
    class(crossing_search_t), intent(in) :: self
    done = self%invalid - self%valid <= self%tolerance
  end function done
end module ellroll_events
