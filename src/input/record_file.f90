!> Ground-acceleration records for a moving cup: the file formats ellroll
!> reads (a CSV of time and components, ellroll_record_csv; PEER NGA .AT2
!> files, one per axis, ellroll_record_at2), checked value by value, each
!> problem named with the file and line. A record file is a regular file
!> of at most max_record_bytes, read whole into memory (ellroll_record_text);
!> its numbers are read to the nearest double (ellroll_decimal), the value
!> Fortran's read gives.
module ellroll_record_file
  use ellroll_kinds, only: wp, i8
  use ellroll_checksum, only: text_checksum
  use ellroll_record_text, only: text_file_t, read_record_text
  use ellroll_record_csv, only: load_csv
  use ellroll_record_at2, only: is_at2, refuse_other_quantities, load_at2
  use ellroll_record_axes, only: axis_record_t, merge_axes
  implicit none
  private

  public :: load_ground_motion

contains

  !> The ground acceleration of a record on one time grid: a CSV file (time
  !> and two or three components), or one AT2 file per axis (x, y[, z]),
  !> at rest past its end: it falls to zero over one more sample step (of
  !> the CSV, of each AT2 axis) and stays there.
  !> Every sample is checked against max_record_acceleration as read and
  !> times `factor` (the record's, applied by the caller). reason = '' when
  !> it is usable.
  subroutine load_ground_motion(paths, factor, times, values, reason, fingerprints)
    character(len=*), intent(in) :: paths(:)
    real(wp), intent(in) :: factor
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    character(len=:), allocatable, intent(out) :: reason
    !> each file's size and CRC-32C ('1234 bytes, crc32c 0a1b2c3d'): what a
    !> resume and a merge compare to tell a changed file
    character(len=40), intent(out), optional :: fingerprints(size(paths))
    type(axis_record_t) :: axes(3)
    type(text_file_t) :: file
    integer :: k
    do k = 1, size(paths)
      call read_record_text(trim(paths(k)), file, reason)
      if (len(reason) > 0) return
      if (present(fingerprints)) write (fingerprints(k), '(i0, " bytes, crc32c ", z8.8)') len(file%text, kind=i8), &
          text_checksum(file%text)
      call refuse_other_quantities(file, reason)
      if (len(reason) > 0) return
      if (.not. is_at2(file)) then
        if (size(paths) == 1) then
          call load_csv(file, factor, times, values, reason)
        else
          reason = file%path // ': not a PEER .AT2 file (its fourth line gives no NPTS); a CSV record holds ' // &
                   'every axis, so give it alone'
        end if
        return
      end if
      call load_at2(file, factor, axes(k)%step, axes(k)%values, reason)
      if (len(reason) > 0) return
    end do
    do k = size(paths) + 1, 3
      axes(k)%step = axes(1)%step            ! an axis without a file: at rest
      allocate (axes(k)%values(0))
    end do
    call merge_axes(axes, times, values)
  end subroutine load_ground_motion
end module ellroll_record_file
