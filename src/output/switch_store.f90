!> The switches of regime of a campaign's cases (/switches): kept case by
!> case as the cases come, in any order, and given out (ragged) in case
!> order, which the file (ellroll_hdf5_groups' switch_group, when it
!> closes) and the Python API lay out as two ragged columns (time, kind: every case's switches
!> one case after the other) indexed per case by first and count. A case's
!> switches are few (tens), the table of a campaign is small beside its
!> trajectories, and the file holds them in the same order whatever order
!> the threads, a resume or a merge kept them in.
module ellroll_switch_store
  use ellroll_kinds, only: wp, i8
  use ellroll_status, only: status_pending, status_invalid
  use ellroll_results, only: case_result_t, count_undefined
  implicit none
  private

  public :: switch_store_t, switch_flag_meanings

  !> flag_meanings of /switches/kind, in the order of switch_to_sliding, switch_to_rolling
  character(len=*), parameter :: switch_flag_meanings = 'to_sliding to_rolling'

  type :: switch_store_t
    logical :: active = .false.                  !< the campaign may slide: the file holds /switches
    integer(i8), allocatable :: indices(:)       !< global index of each case slot
    integer(i8), allocatable :: first(:), count(:)   !< per slot: where its switches lie in the pool (1-based), how many
    real(wp), allocatable :: times(:)            !< the pool, in the order cases were kept
    integer(i8), allocatable :: kinds(:)
    integer(i8) :: n_pool = 0
  contains
    procedure :: start
    procedure :: keep
    procedure :: ragged
  end type switch_store_t

contains

  subroutine start(self, indices)
    class(switch_store_t), intent(inout) :: self
    integer(i8), intent(in) :: indices(:)
    self%active = .true.
    self%indices = indices
    allocate (self%first(size(indices)), self%count(size(indices)), self%times(64), self%kinds(64))
    self%first = 0
    self%count = count_undefined
    self%n_pool = 0
  end subroutine start

  !> Keep the switches of the case at slot (0-based); a case kept again
  !> replaces its switches.
  subroutine keep(self, slot, res)
    class(switch_store_t), intent(inout) :: self
    integer(i8), intent(in) :: slot
    type(case_result_t), intent(in) :: res
    real(wp), allocatable :: times(:)
    integer(i8), allocatable :: kinds(:)
    integer(i8) :: n
    if (.not. self%active) return
    if (res%status == status_pending .or. res%status == status_invalid) then
      self%count(slot + 1) = count_undefined         ! never run: no count, as /summary's counts
      return
    end if
    n = res%n_switches
    if (self%n_pool + n > size(self%times, kind=i8)) then
      allocate (times(2 * (self%n_pool + n)), kinds(2 * (self%n_pool + n)))
      times(:self%n_pool) = self%times(:self%n_pool)
      kinds(:self%n_pool) = self%kinds(:self%n_pool)
      call move_alloc(times, self%times)
      call move_alloc(kinds, self%kinds)
    end if
    self%first(slot + 1) = self%n_pool + 1
    self%count(slot + 1) = n
    if (n > 0) then
      self%times(self%n_pool + 1:self%n_pool + n) = res%switch_time(:n)
      self%kinds(self%n_pool + 1:self%n_pool + n) = int(res%switch_kind(:n), i8)
    end if
    self%n_pool = self%n_pool + n
  end subroutine keep

  !> The cases' switches in case order: every case's first switch (0-based;
  !> -1 for a case never run), count (-1 never run), and every switch's
  !> time and kind.
  subroutine ragged(self, first, count, times, kinds)
    class(switch_store_t), intent(in) :: self
    integer(i8), allocatable, intent(out) :: first(:), count(:), kinds(:)
    real(wp), allocatable, intent(out) :: times(:)
    integer(i8) :: n, k, at
    allocate (count(size(self%count)))
    count(:) = self%count
    n = sum(max(count, 0_i8))
    allocate (first(size(count)), times(n), kinds(n))
    at = 0
    do k = 1, size(count, kind=i8)
      first(k) = merge(at, count_undefined, count(k) >= 0)
      if (count(k) <= 0) cycle
      times(at + 1:at + count(k)) = self%times(self%first(k):self%first(k) + count(k) - 1)
      kinds(at + 1:at + count(k)) = self%kinds(self%first(k):self%first(k) + count(k) - 1)
      at = at + count(k)
    end do
  end subroutine ragged

end module ellroll_switch_store
