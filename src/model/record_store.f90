!> The samples of the records that shake the cups, held once and shared by
!> every case, ball and SIMD lane that uses them: an excitation_t names its
!> record by its place here. (A record of 1e7 samples is 320 MB, and a
!> batch of 8 cases holds 8 cases, 8 balls and 8 lanes shaken by it.) Records
!> are stored as an input is read and given back when the library's run of
!> it ends (a program's live until it exits); a slot is taken and given back
!> under a lock, as runs of the library may read inputs on several threads
!> at once, and the slots never move, so that a stored record is read
!> without one.
module ellroll_record_store
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: samples_t, record_samples, store_record, release_records, max_stored_records, no_room_for_record

  !> Records held at once, over every input read (a suite's &record groups
  !> and a record of &excitation each take one).
  integer, parameter :: max_stored_records = 16384

  !> Why a record could not be stored, as an input's error says it.
  character(len=*), parameter :: no_room_for_record = 'no memory, or no place left for one more record ' // &
      '(16384 held at once, over every input read)'

  type :: samples_t
    real(wp), allocatable :: times(:)       !< s, strictly increasing
    real(wp), allocatable :: values(:, :)   !< (3, n), m/s^2
  end type samples_t

  type(samples_t), target, protected :: record_samples(max_stored_records)

  interface
    subroutine lock_store() bind(c, name='ellroll_lock_record_store')
    end subroutine lock_store
    subroutine unlock_store() bind(c, name='ellroll_unlock_record_store')
    end subroutine unlock_store
  end interface

contains

  !> Hold a record's samples: index, its place (0: no place left, or no
  !> memory for them).
  subroutine store_record(times, values, index)
    real(wp), intent(in) :: times(:), values(:, :)
    integer, intent(out) :: index
    integer :: k, code
    index = 0
    call lock_store()
    do k = 1, max_stored_records
      if (allocated(record_samples(k)%times)) cycle
      allocate (record_samples(k)%times(size(times)), record_samples(k)%values(3, size(times)), stat=code)
      if (code == 0) then
        record_samples(k)%times = times
        record_samples(k)%values = values
        index = k
      else if (allocated(record_samples(k)%times)) then
        deallocate (record_samples(k)%times)
      end if
      exit
    end do
    call unlock_store()
  end subroutine store_record

  !> Give back the records at these places (0: none; a place named twice
  !> once), which no case reads any more.
  subroutine release_records(indices)
    integer, intent(in) :: indices(:)
    integer :: k
    call lock_store()
    do k = 1, size(indices)
      if (indices(k) < 1 .or. indices(k) > max_stored_records) cycle
      if (any(indices(:k - 1) == indices(k))) cycle
      if (allocated(record_samples(indices(k))%times)) deallocate (record_samples(indices(k))%times)
      if (allocated(record_samples(indices(k))%values)) deallocate (record_samples(indices(k))%values)
    end do
    call unlock_store()
  end subroutine release_records
end module ellroll_record_store
