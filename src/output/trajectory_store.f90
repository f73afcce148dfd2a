!> The uncompressed trajectories of an output file, at fixed places in it:
!> field f of the case in slot s lies at address(f) + s * (bytes per case).
!> The threads that computed the cases write them there with positioned
!> system calls, beside HDF5 (which allocated the space and never touches it
!> again), and a resume reads them back the same way.
!>
!> The file's first label_bytes bytes (HDF5's user block, which the library
!> reserves and leaves alone) hold a label: the case and sample counts and
!> the field addresses. A resume finds a killed run's trajectories from the
!> label alone, without trusting HDF5's metadata, which a kill may have left
!> half written.
module ellroll_trajectory_store
  use, intrinsic :: iso_c_binding, only: c_loc, c_ptr
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_output
  use ellroll_cases, only: field_count, field_names, field_ncomp
  use ellroll_results, only: case_result_t
  use ellroll_checksum, only: checksum
  use ellroll_strings, only: itoa
  use ellroll_system, only: open_for_writing, open_for_reading, write_pieces_at, read_at, close_descriptor, &
      system_error_text
  implicit none
  private

  public :: trajectory_store_t, label_bytes

  integer, parameter :: label_bytes = 512        !< a power of two >= 512, as HDF5 asks of a user block
  integer(i8), parameter :: label_marker = transfer('ellroll:', 0_i8)     !< readable in a dump
  integer(i8), parameter :: label_version = 1
  integer, parameter :: label_words = 4 + field_count + 1     !< marker, version, counts, addresses, checksum

  type :: trajectory_store_t
    character(len=:), allocatable :: path
    integer :: fd = -1
    integer(i8) :: n_cases = 0
    integer(i8) :: n_samples = 0
    logical :: fields(field_count) = .false.       !< the fields stored here
    integer(i8) :: address(field_count) = -1       !< where each begins (-1: not here, or no cases)
  contains
    procedure :: start
    procedure :: open_existing
    procedure :: put
    procedure :: get
    procedure :: close => close_store
  end type trajectory_store_t

contains

  !> Open the file HDF5 laid out for writing, and label it. Nothing to do
  !> when no field is stored in place.
  subroutine start(self, path, n_cases, n_samples, fields, address, err)
    class(trajectory_store_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: n_cases, n_samples
    logical, intent(in) :: fields(field_count)
    integer(i8), intent(in) :: address(field_count)
    type(error_t), intent(inout) :: err
    integer(i8), target :: label(label_bytes / 8)
    integer :: code
    call describe(self, path, n_cases, n_samples, fields)
    self%address = merge(address, -1_i8, fields)
    if (.not. any(fields)) return
    self%fd = open_for_writing(path)
    if (self%fd < 0) then
      call set_error(err, err_output, path // ': cannot open for writing the trajectories: ' // &
                     system_error_text(-self%fd))
      return
    end if
    label = 0
    label(:label_words - 1) = [label_marker, label_version, n_cases, n_samples, self%address]
    label(label_words) = checksum(label(:label_words - 1))
    code = write_pieces_at(self%fd, [c_loc(label)], [int(label_bytes, i8)], 0_i8)
    if (code /= 0) call set_error(err, err_output, path // ': cannot write its label: ' // system_error_text(code))
  end subroutine start

  !> Open an existing file to read its trajectories back; its label must say
  !> it holds `fields` for n_cases cases of n_samples samples. A file missing,
  !> of another layout or never labelled fails with err.
  subroutine open_existing(self, path, n_cases, n_samples, fields, err)
    class(trajectory_store_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: n_cases, n_samples
    logical, intent(in) :: fields(field_count)
    type(error_t), intent(inout) :: err
    integer(i8), target :: label(label_words)
    integer :: code
    call describe(self, path, n_cases, n_samples, fields)
    self%fd = open_for_reading(path)
    if (self%fd < 0) then
      call set_error(err, err_output, path // ': cannot open: ' // system_error_text(-self%fd))
      return
    end if
    code = read_at(self%fd, c_loc(label), 8_i8 * label_words, 0_i8)
    if (code /= 0) then
      call set_error(err, err_output, path // ': no trajectory label')
    else if (label(1) /= label_marker .or. label(label_words) /= checksum(label(:label_words - 1))) then
      call set_error(err, err_output, path // ': no trajectory label, or a damaged one')
    else if (label(2) /= label_version .or. label(3) /= n_cases .or. label(4) /= n_samples .or. &
             any((label(5:4 + field_count) >= 0) .neqv. (fields .and. n_cases > 0))) then
      call set_error(err, err_output, path // ': its trajectories are laid out for another run')
    else
      self%address = label(5:4 + field_count)
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
      if (code /= 0) call set_error(err, err_output, self%path // ': cannot write /trajectory/' // &
          trim(field_names(f)) // ' (disk full?): ' // system_error_text(code))
    end do
  end subroutine put

  !> Read the trajectories of the case in `slot` into res (allocating them).
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
      allocate (res%fields(f)%values(field_ncomp(f), self%n_samples))
      code = read_at(self%fd, c_loc(res%fields(f)%values), 8 * n, self%address(f) + 8 * n * slot)
      if (code == -1) then
        call set_error(err, err_output, self%path // ': ends before /trajectory/' // trim(field_names(f)) // &
                       ' of slot ' // itoa(slot))
      else if (code /= 0) then
        call set_error(err, err_output, self%path // ': cannot read /trajectory/' // trim(field_names(f)) // &
                       ': ' // system_error_text(code))
      end if
    end do
  end subroutine get

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
