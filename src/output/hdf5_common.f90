!> What ellroll's HDF5 writer, reader and layout share: hyperslabs (selected
!> and written), dimension numbering, text types and text attributes.
module ellroll_hdf5_common
  use, intrinsic :: iso_c_binding, only: c_loc, c_ptr, c_char, c_null_char, c_int, c_int64_t, c_long_long
  use hdf5
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_output
  use ellroll_checksum, only: text_checksum
  use ellroll_files, only: text_of
  implicit none
  private

  public :: hdf5_reason, note_failed_close, hdf5_close_failed, hdf5_quiet, forget_system_failure, system_failure, &
      hdf5_descriptor, file_identity, hdf5_open_ids
  public :: select_slab, dataset_name, dim_index, new_text_type, write_text_attribute, &
      write_text_slab, write_real_slab, write_int_slab

  !> The type conversion buffer of a write of text rows (bytes).
  integer(size_t), parameter :: text_buffer_bytes = 16384

  !> H5T_VARIABLE of the C API: (size_t) -1.
  integer(size_t), parameter :: variable_length = -1

  !> A file HDF5 could not close stays in its list of open files, and its
  !> exit handler trips over it: the program then leaves without it.
  logical :: failed_close = .false.

  interface
    subroutine c_hdf5_error_text(text, size) bind(c, name='ellroll_hdf5_error_text')
      import :: c_char, c_int
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int), value :: size
    end subroutine c_hdf5_error_text
    !> (see hdf5_errors.c)
    subroutine hdf5_quiet() bind(c, name='ellroll_hdf5_quiet')
    end subroutine hdf5_quiet
    subroutine forget_system_failure() bind(c, name='ellroll_hdf5_forget_failure')
    end subroutine forget_system_failure
    integer(c_int) function c_system_failure(words, words_size, file, file_size) &
        bind(c, name='ellroll_hdf5_system_failure')
      import :: c_char, c_int
      character(kind=c_char), intent(out) :: words(*), file(*)
      integer(c_int), value :: words_size, file_size
    end function c_system_failure
    integer(c_long_long) function c_object_address(loc, name) bind(c, name='ellroll_hdf5_object_address')
      import :: c_long_long, c_int64_t, c_char
      integer(c_int64_t), value :: loc
      character(kind=c_char), intent(in) :: name(*)
    end function c_object_address
    !> How many files, groups, datasets and attributes HDF5 holds open in
    !> this process: none once a command is done with its files (-1: unknown).
    integer(c_long_long) function hdf5_open_ids() bind(c, name='ellroll_hdf5_open_ids')
      import :: c_long_long
    end function hdf5_open_ids
    integer(c_int) function c_hdf5_descriptor(file) bind(c, name='ellroll_hdf5_descriptor')
      import :: c_int, c_int64_t
      integer(c_int64_t), value :: file      !< an hid_t (int64_t since HDF5 1.10)
    end function c_hdf5_descriptor
  end interface

contains

  subroutine note_failed_close()
    failed_close = .true.
  end subroutine note_failed_close

  !> Whether HDF5 failed to close a file (hdf5_common's note).
  logical function hdf5_close_failed()
    hdf5_close_failed = failed_close
  end function hdf5_close_failed

  !> Why the last HDF5 call failed: the system's words where HDF5's file
  !> driver recorded them ('Input/output error', 'No space left on
  !> device'), else HDF5's own. HDF5's error stack is cleared.
  subroutine hdf5_reason(reason)
    character(len=:), allocatable, intent(out) :: reason
    character(kind=c_char) :: buffer(256)
    integer :: n
    call c_hdf5_error_text(buffer, size(buffer))
    n = findloc(buffer, c_null_char, dim=1) - 1
    if (n < 0) n = size(buffer)
    reason = repeat(' ', n)
    reason = transfer(buffer(:n), reason)
  end subroutine hdf5_reason

  !> Whether an HDF5 call on this thread failed in a system call (a read
  !> or write error) since forget_system_failure: the system's words and the
  !> file's name ('' where HDF5 did not give it).
  logical function system_failure(words, file)
    character(len=:), allocatable, intent(out) :: words, file
    character(kind=c_char) :: word_buffer(160), file_buffer(1024)
    system_failure = c_system_failure(word_buffer, size(word_buffer), file_buffer, size(file_buffer)) /= 0
    call text_of(word_buffer, words)
    call text_of(file_buffer, file)
  end function system_failure

  !> A descriptor of its own of the file HDF5 has open as `file` (sec2
  !> driver), or -1.
  integer function hdf5_descriptor(file)
    integer(hid_t), intent(in) :: file
    hdf5_descriptor = c_hdf5_descriptor(int(file, c_int64_t))
  end function hdf5_descriptor

  !> The root attribute file_identity of ellroll's file `file` of campaign
  !> `id`: the CRC-32C (8 hex digits) of the campaign id and the file
  !> addresses of /summary/status and /summary/checksum. A copy made by
  !> another program (h5py, xarray, h5repack) lays its objects out anew and
  !> does not match; a copy of the bytes (cp) does. '' where an object is
  !> missing.
  subroutine file_identity(file, id, identity)
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: id
    character(len=:), allocatable, intent(out) :: identity
    integer(c_long_long) :: status_at, checksum_at
    character(len=64) :: text
    status_at = c_object_address(int(file, c_int64_t), 'summary/status' // c_null_char)
    checksum_at = c_object_address(int(file, c_int64_t), 'summary/checksum' // c_null_char)
    identity = ''
    if (status_at < 0 .or. checksum_at < 0) return
    write (text, '(i0, a, i0)') status_at, ' ', checksum_at
    write (text, '(z8.8)') text_checksum(id // ' ' // trim(text))
    identity = trim(text)
  end subroutine file_identity

  !> h5dsattach_scale_f counts dimensions in C order from 1 (unlike the
  !> Fortran-order dataspace calls); `dim` is the h5py index, from 0.
  pure integer function dim_index(dim)
    integer, intent(in) :: dim
    dim_index = dim + 1
  end function dim_index

  !> The hyperslab of a dataset and a memory space of its shape; hdferr < 0
  !> when any step failed.
  subroutine select_slab(dset, offset, counts, file_space, mem_space, hdferr)
    integer(hid_t), intent(in) :: dset
    integer(i8), intent(in) :: offset(:), counts(:)
    integer(hid_t), intent(out) :: file_space, mem_space
    integer, intent(out) :: hdferr
    integer :: code
    mem_space = -1
    call h5dget_space_f(dset, file_space, hdferr)
    if (hdferr < 0) return
    call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, int(offset, hsize_t), &
                               int(counts, hsize_t), hdferr)
    call h5screate_simple_f(size(counts), int(counts, hsize_t), mem_space, code)
    hdferr = min(hdferr, code)
  end subroutine select_slab

  !> UTF-8 variable-length strings: h5py reads them as str, not bytes.
  integer(hid_t) function new_text_type() result(text_type)
    integer :: hdferr
    call h5tcopy_f(H5T_FORTRAN_S1, text_type, hdferr)
    call h5tset_size_f(text_type, variable_length, hdferr)
    call h5tset_strpad_f(text_type, H5T_STR_NULLTERM_F, hdferr)
    call h5tset_cset_f(text_type, H5T_CSET_UTF8_F, hdferr)
  end function new_text_type
  !> A text attribute; hdferr < 0 when any step (closes included) failed.
  subroutine write_text_attribute(loc, name, value, hdferr)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name, value
    integer, intent(out) :: hdferr
    integer(hid_t) :: text_type, space, attr
    ! (on the heap: the input's whole text is one, of any length)
    character(len=:, kind=c_char), allocatable, target :: text
    type(c_ptr), target :: pointers(1)
    integer :: code
    text = value // c_null_char
    pointers(1) = c_loc(text)
    text_type = new_text_type()
    call h5screate_f(H5S_SCALAR_F, space, hdferr)
    if (hdferr >= 0) call h5acreate_f(loc, name, text_type, space, attr, hdferr)
    if (hdferr >= 0) then
      call h5awrite_f(attr, text_type, c_loc(pointers), hdferr)
      call h5aclose_f(attr, code)
      hdferr = min(hdferr, code)
    end if
    call h5sclose_f(space, code)
    hdferr = min(hdferr, code)
    call h5tclose_f(text_type, code)
    hdferr = min(hdferr, code)
  end subroutine write_text_attribute

  !> The name of an open dataset ('/summary/theta_max'), for messages.
  subroutine dataset_name(dset, name)
    integer(hid_t), intent(in) :: dset
    character(len=:), allocatable, intent(out) :: name
    character(len=256) :: buffer
    integer(size_t) :: length
    integer :: hdferr
    call h5iget_name_f(dset, buffer, int(len(buffer), size_t), length, hdferr)
    name = 'a dataset'
    if (hdferr >= 0 .and. length > 0) name = buffer(:min(int(length), len(buffer)))
  end subroutine dataset_name

  !> Per-case text (method, excitation kind, record) as variable-length
  !> strings, as the text attributes: netCDF-C, h5netcdf and h5py all read
  !> them as text (netCDF-C reads fixed-length strings as variable-length
  !> ones, and xarray then fails on the `_Encoding` that h5netcdf needs to
  !> give fixed-length ones as text). The rows go in windows of cases, so
  !> the global heap that holds them grows by whole collections, as the
  !> fixed-length datasets did.
  subroutine write_text_slab(path, dset, values, offset, err)
    character(len=*), intent(in) :: path           !< the file, for messages
    integer(hid_t), intent(in) :: dset
    character(len=*), intent(in) :: values(:)
    integer(i8), intent(in) :: offset
    type(error_t), intent(inout) :: err
    character(len=len(values) + 1, kind=c_char), target :: texts(size(values))
    type(c_ptr), target :: pointers(size(values))
    integer(hid_t) :: text_type, xfer
    integer :: k, hdferr
    do k = 1, size(values)
      texts(k) = trim(values(k)) // c_null_char
      pointers(k) = c_loc(texts(k))
    end do
    text_type = new_text_type()
    ! the strings go through a conversion buffer, which HDF5 allocates and
    ! clears for every write (1 MiB by default: 9 % of a campaign of short
    ! cases); a window's rows need a few KiB
    call h5pcreate_f(H5P_DATASET_XFER_F, xfer, hdferr)
    if (hdferr >= 0) call h5pset_buffer_f(xfer, text_buffer_bytes, hdferr)
    if (hdferr < 0) then
      call set_error(err, err_output, path // ': cannot set a conversion buffer')
    else
      call write_slab(path, dset, text_type, c_loc(pointers), [offset], [size(values, kind=i8)], err, xfer)
    end if
    call h5pclose_f(xfer, hdferr)
    call h5tclose_f(text_type, hdferr)
  end subroutine write_text_slab

  subroutine write_real_slab(path, dset, values, offset, counts, err)
    character(len=*), intent(in) :: path           !< the file, for messages
    integer(hid_t), intent(in) :: dset
    real(wp), intent(in), target :: values(*)
    integer(i8), intent(in) :: offset(:), counts(:)
    type(error_t), intent(inout) :: err
    call write_slab(path, dset, H5T_NATIVE_DOUBLE, c_loc(values), offset, counts, err)
  end subroutine write_real_slab

  subroutine write_int_slab(path, dset, values, offset, counts, err)
    character(len=*), intent(in) :: path           !< the file, for messages
    integer(hid_t), intent(in) :: dset
    integer(i8), intent(in), target :: values(*)
    integer(i8), intent(in) :: offset(:), counts(:)
    type(error_t), intent(inout) :: err
    call write_slab(path, dset, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(values), offset, counts, err)
  end subroutine write_int_slab

  subroutine write_slab(path, dset, mem_type, buffer, offset, counts, err, xfer)
    character(len=*), intent(in) :: path           !< the file, for messages
    integer(hid_t), intent(in) :: dset, mem_type
    type(c_ptr), intent(in) :: buffer
    integer(i8), intent(in) :: offset(:), counts(:)
    type(error_t), intent(inout) :: err
    integer(hid_t), intent(in), optional :: xfer   !< a transfer property list (default: HDF5's)
    integer(hid_t) :: file_space, mem_space
    integer :: hdferr, code
    character(len=:), allocatable :: name, reason
    if (err%failed()) return
    call select_slab(dset, offset, counts, file_space, mem_space, hdferr)
    if (hdferr >= 0) then
      if (present(xfer)) then
        call h5dwrite_f(dset, mem_type, buffer, hdferr, mem_space_id=mem_space, file_space_id=file_space, &
                        xfer_prp=xfer)
      else
        call h5dwrite_f(dset, mem_type, buffer, hdferr, mem_space_id=mem_space, file_space_id=file_space)
      end if
    end if
    if (hdferr < 0) call hdf5_reason(reason)        ! now: the next HDF5 call clears HDF5's record of it
    call h5sclose_f(file_space, code)
    if (code < 0 .and. hdferr >= 0) call hdf5_reason(reason)
    hdferr = min(hdferr, code)
    call h5sclose_f(mem_space, code)
    if (code < 0 .and. hdferr >= 0) call hdf5_reason(reason)
    hdferr = min(hdferr, code)
    if (hdferr < 0) then
      call dataset_name(dset, name)
      call set_error(err, err_output, path // ': cannot write ' // name // ': ' // reason)
    end if
  end subroutine write_slab
end module ellroll_hdf5_common
