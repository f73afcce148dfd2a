!> The uncompressed trajectories of an output file, at fixed places in it:
!> field f of the case in slot s lies at address(f) + s * (bytes per case).
!> The threads that computed the cases write them there with positioned
!> system calls, beside HDF5 (which allocated the space and never touches it
!> again), and a resume reads them back the same way.
!>
!> A label of label_bytes bytes, the data of a small dataset near the
!> file's start (/trajectory_label, contiguous, allocated before the file's
!> other data and never written by HDF5), holds the case and sample counts
!> and the field addresses, as text (netCDF readers read it as a string). A
!> resume finds a killed run's trajectories from the label alone, without
!> trusting HDF5's metadata, which a kill may have left half written: it
!> looks for the label's marker in the file's first label_search_bytes and
!> takes the first copy whose checksum holds. (An HDF5 user block at the
!> file's start would hold it at a fixed place, but xarray then takes the
!> file for no netCDF/HDF5 file at all.)
module ellroll_trajectory_store
  use, intrinsic :: iso_c_binding, only: c_loc, c_ptr
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_output
  use ellroll_cases, only: field_count, field_names, field_ncomp
  use ellroll_results, only: case_result_t
  use ellroll_checksum, only: checksum
  use ellroll_system, only: open_for_writing, open_for_reading, write_pieces_at, read_at, release_range, &
      close_descriptor, system_error_text
  implicit none
  private

  public :: trajectory_store_t, label_bytes, label_search_bytes, label_marker

  integer(i8), parameter :: piece_words = 2_i8**17      !< a piece of move_in: 1 MiB
  integer, parameter :: label_bytes = 512               !< the label's text, NUL padded
  integer, parameter :: label_search_bytes = 65536      !< where a resume looks for it
  character(len=*), parameter :: label_marker = 'ellroll trajectories:'
  integer(i8), parameter :: label_version = 3           !< 1: binary, in the user block; 2: 8 fields
  integer, parameter :: label_words = 3 + field_count + 1     !< version, counts, addresses, checksum

  type :: trajectory_store_t
    character(len=:), allocatable :: path
    integer :: fd = -1
    integer(i8) :: n_cases = 0
    integer(i8) :: n_samples = 0
    logical :: fields(field_count) = .false.       !< the fields stored here
    integer(i8) :: address(field_count) = -1       !< where each begins (-1: not here, or no cases)
    integer(i8) :: freed_to(field_count) = -1      !< where the storage freed by move_in ends
    integer(i8) :: label_address = -1              !< where the label lies
  contains
    procedure :: start
    procedure :: open_existing
    procedure :: put
    procedure :: get
    procedure :: move_in
    procedure :: n_pieces
    procedure :: piece
    procedure :: take_piece
    procedure :: release_to
    procedure :: release_all_but_trajectories
    procedure :: close => close_store
  end type trajectory_store_t

contains

  !> Take the file HDF5 laid out, open as `fd` (a descriptor of its own,
  !> which the store closes), and write its label at label_address. Nothing
  !> to do (fd closed) when no field is stored in place.
  subroutine start(self, path, fd, n_cases, n_samples, fields, address, label_address, err)
    class(trajectory_store_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer, intent(in) :: fd
    integer(i8), intent(in) :: n_cases, n_samples
    logical, intent(in) :: fields(field_count)
    integer(i8), intent(in) :: address(field_count)
    integer(i8), intent(in) :: label_address
    type(error_t), intent(inout) :: err
    character(len=label_bytes), target :: label
    integer(i8) :: words(label_words)
    integer :: code, k
    call describe(self, path, n_cases, n_samples, fields)
    self%address = merge(address, -1_i8, fields)
    if (.not. any(fields)) then
      if (fd >= 0) code = close_descriptor(fd)
      return
    end if
    self%label_address = label_address
    self%fd = fd
    words(:label_words - 1) = [label_version, n_cases, n_samples, self%address]
    words(label_words) = checksum(words(:label_words - 1))
    write (label, '(a, *(1x, i0))') label_marker, words
    do k = len_trim(label) + 1, label_bytes      ! NUL padded, as its HDF5 type says
      label(k:k) = achar(0)
    end do
    code = write_pieces_at(self%fd, [c_loc(label)], [int(label_bytes, i8)], label_address)
    if (code /= 0) call set_error(err, err_output, path // ': cannot write its label: ' // system_error_text(code))
  end subroutine start

  !> Open an existing file to read its trajectories back, and with
  !> `writable` to write them and free their storage too; its label must say
  !> it holds `fields` for n_cases cases of n_samples samples. A file missing,
  !> of another layout or never labelled fails with err.
  subroutine open_existing(self, path, n_cases, n_samples, fields, writable, err)
    class(trajectory_store_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: n_cases, n_samples
    logical, intent(in) :: fields(field_count)
    logical, intent(in) :: writable
    type(error_t), intent(inout) :: err
    character(len=:), allocatable, target :: head
    integer(i8) :: words(label_words), size_bytes
    integer :: code, at, from, last, ios
    logical :: found
    call describe(self, path, n_cases, n_samples, fields)
    if (writable) then
      self%fd = open_for_writing(path)
    else
      self%fd = open_for_reading(path)
    end if
    if (self%fd < 0) then
      call set_error(err, err_output, path // ': cannot open: ' // system_error_text(-self%fd))
      return
    end if
    inquire (file=path, size=size_bytes)
    allocate (character(len=int(max(0_i8, min(size_bytes, int(label_search_bytes, i8))))) :: head)
    code = -1
    if (len(head) > 0) code = read_at(self%fd, c_loc(head), int(len(head), i8), 0_i8)
    if (code /= 0) then
      call set_error(err, err_output, path // ': no trajectory label')
      return
    end if
    ! the first marker followed by words whose checksum holds
    found = .false.
    from = 1
    do
      at = index(head(from:), label_marker)
      if (at == 0) exit
      at = from + at - 1 + len(label_marker)
      from = at
      last = min(len(head), at + label_bytes - len(label_marker) - 1)
      if (index(head(at:last), achar(0)) > 0) last = at + index(head(at:last), achar(0)) - 2  ! the text ends at its NUL
      read (head(at:last), *, iostat=ios) words
      if (ios /= 0) cycle
      if (words(label_words) /= checksum(words(:label_words - 1))) cycle
      found = .true.
      self%label_address = at - 1 - len(label_marker)
      exit
    end do
    if (.not. found) then
      call set_error(err, err_output, path // ': no trajectory label, or a damaged one')
    else if (words(1) /= label_version .or. words(2) /= n_cases .or. words(3) /= n_samples .or. &
             any((words(4:3 + field_count) >= 0) .neqv. (fields .and. n_cases > 0))) then
      call set_error(err, err_output, path // ': its trajectories are laid out for another run')
    else
      self%address = words(4:3 + field_count)
      self%freed_to = self%address
    end if
  end subroutine open_existing

  subroutine describe(self, path, n_cases, n_samples, fields)
    type(trajectory_store_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: n_cases, n_samples
    logical, intent(in) :: fields(field_count)
    self%path = path
    self%n_cases = n_cases
    self%n_samples = n_samples
    self%fields = fields
  end subroutine describe

  !> Write the trajectories of cases in consecutive slots, from slot `first`
  !> on: one system call per field. Threads may call this at the same time
  !> for different cases. A case never integrated (invalid) gets NaN.
  subroutine put(self, first, results, err)
    class(trajectory_store_t), intent(in) :: self
    integer(i8), intent(in) :: first
    type(case_result_t), intent(in), target :: results(:)
    type(error_t), intent(inout) :: err
    real(wp), allocatable, target :: never_integrated(:)
    type(c_ptr) :: pieces(size(results))
    integer(i8) :: n
    integer :: f, j, code
    do f = 1, field_count
      if (.not. self%fields(f) .or. err%failed()) cycle
      n = field_ncomp(f) * self%n_samples
      do j = 1, size(results)
        if (allocated(results(j)%fields(f)%values)) then
          pieces(j) = c_loc(results(j)%fields(f)%values)
        else
          if (.not. allocated(never_integrated)) &
            never_integrated = spread(ieee_value(0.0_wp, ieee_quiet_nan), 1, int(maxval(field_ncomp) * self%n_samples))
          pieces(j) = c_loc(never_integrated)
        end if
      end do
      code = write_pieces_at(self%fd, pieces, spread(8 * n, 1, size(results)), self%address(f) + 8 * n * first)
      call check_write(self, f, code, err)
    end do
  end subroutine put

  !> Read the trajectories of the case in `slot` into res (allocating them).
  !> What lies beyond the file's end was never written and reads as zeros,
  !> as in a file of full size.
  subroutine get(self, slot, res, err)
    class(trajectory_store_t), intent(in) :: self
    integer(i8), intent(in) :: slot
    type(case_result_t), intent(inout), target :: res
    type(error_t), intent(inout) :: err
    integer(i8) :: n
    integer :: f, code
    do f = 1, field_count
      if (.not. self%fields(f) .or. err%failed()) cycle
      n = field_ncomp(f) * self%n_samples
      if (allocated(res%fields(f)%values)) deallocate (res%fields(f)%values)
      allocate (res%fields(f)%values(field_ncomp(f), self%n_samples), source=0.0_wp)
      code = read_at(self%fd, c_loc(res%fields(f)%values), 8 * n, self%address(f) + 8 * n * slot)
      if (code > 0) call set_error(err, err_output, self%path // ': cannot read /trajectory/' // &
                                   trim(field_names(f)) // ': ' // system_error_text(code))
    end do
  end subroutine get

  !> Write the trajectories of the case in `slot`, read from `source`
  !> (open writable), and free their storage there as they go: a move that
  !> needs room for one piece (piece_words), not for the case.
  !> Whatever lies in `source` before them (cases not needed) is freed too.
  !> Where the file system cannot free parts of a file, nothing is freed
  !> and nothing fails. A move cut short leaves the case's first pieces
  !> here and the others in `source` (take_piece puts it together).
  subroutine move_in(self, slot, res, source, err)
    class(trajectory_store_t), intent(in) :: self
    integer(i8), intent(in) :: slot
    type(case_result_t), intent(in), target :: res
    type(trajectory_store_t), intent(inout) :: source
    type(error_t), intent(inout) :: err
    real(wp), pointer :: values(:)
    integer(i8) :: k, first, count, at
    integer :: f, code
    do k = 1, self%n_pieces()
      call self%piece(k, f, first, count)
      values(1:size(res%fields(f)%values, kind=i8)) => res%fields(f)%values
      at = 8 * (size(values, kind=i8) * slot + first)     ! from the field's start
      code = write_pieces_at(self%fd, [c_loc(values(first + 1))], [8 * count], self%address(f) + at)
      call check_write(self, f, code, err)
      if (err%failed()) return
      call source%release_to(f, source%address(f) + at + 8 * count)
    end do
  end subroutine move_in

  !> The number of pieces of a case's trajectories that move_in moves one
  !> after the other.
  pure integer(i8) function n_pieces(self)
    class(trajectory_store_t), intent(in) :: self
    n_pieces = sum(pieces_of_field(self), mask=self%fields)
  end function n_pieces

  pure function pieces_of_field(self) result(n)
    type(trajectory_store_t), intent(in) :: self
    integer(i8) :: n(field_count)
    n = (field_ncomp * self%n_samples + piece_words - 1) / piece_words
  end function pieces_of_field

  !> Piece k (from 1) of a case: the values first + 1 .. first + count of
  !> field f (in their order in memory).
  pure subroutine piece(self, k, f, first, count)
    class(trajectory_store_t), intent(in) :: self
    integer(i8), intent(in) :: k
    integer, intent(out) :: f
    integer(i8), intent(out) :: first, count
    integer(i8) :: n(field_count), before
    n = pieces_of_field(self)
    before = 0
    do f = 1, field_count
      if (.not. self%fields(f)) cycle
      if (k <= before + n(f)) exit
      before = before + n(f)
    end do
    first = (k - before - 1) * piece_words
    count = min(piece_words, field_ncomp(f) * self%n_samples - first)
  end subroutine piece

  !> Piece k of a case from another read of it: to put a case together
  !> after a move cut short, from the pieces moved and those left.
  subroutine take_piece(self, res, moved, k)
    class(trajectory_store_t), intent(in) :: self
    type(case_result_t), intent(inout), target :: res
    type(case_result_t), intent(in), target :: moved
    integer(i8), intent(in) :: k
    real(wp), pointer :: into(:), from(:)
    integer(i8) :: first, count
    integer :: f
    call self%piece(k, f, first, count)
    into(1:size(res%fields(f)%values, kind=i8)) => res%fields(f)%values
    from(1:size(moved%fields(f)%values, kind=i8)) => moved%fields(f)%values
    into(first + 1:first + count) = from(first + 1:first + count)
  end subroutine take_piece

  subroutine check_write(self, f, code, err)
    type(trajectory_store_t), intent(in) :: self
    integer, intent(in) :: f, code        !< the field, and write_pieces_at's answer
    type(error_t), intent(inout) :: err
    if (code /= 0) call set_error(err, err_output, self%path // ': cannot write /trajectory/' // &
                                  trim(field_names(f)) // ' (disk full?): ' // system_error_text(code))
  end subroutine check_write

  !> Free the storage of field f's trajectories up to byte `to`, where
  !> release_range can: the blocks up to the last whole one before it.
  subroutine release_to(self, f, to)
    class(trajectory_store_t), intent(inout) :: self
    integer, intent(in) :: f
    integer(i8), intent(in) :: to
    if (self%freed_to(f) < 0) return          ! not here, or the file system cannot
    self%freed_to(f) = release_range(self%fd, self%freed_to(f), to)
  end subroutine release_to

  !> Free the storage of everything in the file but its label and its
  !> trajectories (HDF5's metadata and tables, which a resume rebuilds):
  !> the file is no HDF5 file after, only a store of trajectories.
  subroutine release_all_but_trajectories(self)
    class(trajectory_store_t), intent(inout) :: self
    integer(i8) :: kept(2, 0:field_count)     !< (start, end) of the label and of each field's trajectories
    integer(i8) :: gap_start, ignored
    integer :: f, next
    kept(:, 0) = [self%label_address, self%label_address + label_bytes]
    do f = 1, field_count
      kept(:, f) = [self%address(f), self%address(f) + 8 * field_ncomp(f) * self%n_samples * self%n_cases]
    end do
    gap_start = 0
    do
      ! the gap ends where the next range kept begins, or at the file's end
      next = -1
      do f = 0, field_count
        if (kept(1, f) < gap_start) cycle
        if (next < 0) then
          next = f
        else if (kept(1, f) < kept(1, next)) then
          next = f
        end if
      end do
      if (next < 0) then
        ignored = release_range(self%fd, gap_start, huge(0_i8))
        exit
      end if
      ignored = release_range(self%fd, gap_start, kept(1, next))
      gap_start = kept(2, next)
    end do
  end subroutine release_all_but_trajectories

  !> Close the file's descriptor; err reports a write the system could not
  !> finish (a delayed error), unless err holds an error already.
  subroutine close_store(self, err)
    class(trajectory_store_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    integer :: code
    if (self%fd < 0) return
    code = close_descriptor(self%fd)
    self%fd = -1
    if (code /= 0 .and. .not. err%failed()) &
      call set_error(err, err_output, self%path // ': cannot write the trajectories (disk full?): ' // &
                     system_error_text(code))
  end subroutine close_store
end module ellroll_trajectory_store
