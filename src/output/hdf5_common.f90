!> What ellroll's HDF5 writer, reader and layout share: hyperslabs (selected
!> and written), dimension numbering, text types and text attributes.
module ellroll_hdf5_common
  use, intrinsic :: iso_c_binding, only: c_loc, c_ptr, c_char, c_null_char
  use hdf5
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_output
  implicit none
  private

  public :: select_slab, dim_index, new_text_type, fixed_text_type, write_text_attribute, write_text_slab, write_real_slab, &
      write_int_slab, text_width

  !> Width of per-case text datasets (bytes, null-terminated).
  integer, parameter :: text_width = 32

  !> H5T_VARIABLE of the C API: (size_t) -1.
  integer(size_t), parameter :: variable_length = -1

contains

  !> h5dsattach_scale_f counts dimensions in C order from 1 (unlike the
  !> Fortran-order dataspace calls); `dim` is the h5py index, from 0.
  pure integer function dim_index(dim)
    integer, intent(in) :: dim
    dim_index = dim + 1
  end function dim_index

  subroutine select_slab(dset, offset, counts, file_space, mem_space)
    integer(hid_t), intent(in) :: dset
    integer(i8), intent(in) :: offset(:), counts(:)
    integer(hid_t), intent(out) :: file_space, mem_space
    integer :: hdferr
    call h5dget_space_f(dset, file_space, hdferr)
    call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, int(offset, hsize_t), &
                               int(counts, hsize_t), hdferr)
    call h5screate_simple_f(size(counts), int(counts, hsize_t), mem_space, hdferr)
  end subroutine select_slab

  !> UTF-8 variable-length strings: h5py reads them as str, not bytes.
  integer(hid_t) function new_text_type() result(text_type)
    integer :: hdferr
    call h5tcopy_f(H5T_FORTRAN_S1, text_type, hdferr)
    call h5tset_size_f(text_type, variable_length, hdferr)
    call h5tset_strpad_f(text_type, H5T_STR_NULLTERM_F, hdferr)
    call h5tset_cset_f(text_type, H5T_CSET_UTF8_F, hdferr)
  end function new_text_type
  subroutine write_text_attribute(loc, name, value, hdferr)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name, value
    integer, intent(out) :: hdferr
    integer(hid_t) :: text_type, space, attr
    character(len=len(value)+1, kind=c_char), target :: text
    type(c_ptr), target :: pointers(1)
    text = value // c_null_char
    pointers(1) = c_loc(text)
    text_type = new_text_type()
    call h5screate_f(H5S_SCALAR_F, space, hdferr)
    call h5acreate_f(loc, name, text_type, space, attr, hdferr)
    if (hdferr >= 0) then
      call h5awrite_f(attr, text_type, c_loc(pointers), hdferr)
      call h5aclose_f(attr, hdferr)
    end if
    call h5sclose_f(space, hdferr)
    call h5tclose_f(text_type, hdferr)
  end subroutine write_text_attribute

  !> Per-case text (method, excitation kind) is fixed-length: variable-length
  !> strings written case by case would fill HDF5's global heap, in memory
  !> and in the file, in proportion to the number of cases.
  integer(hid_t) function fixed_text_type() result(text_type)
    integer :: hdferr
    call h5tcopy_f(H5T_FORTRAN_S1, text_type, hdferr)
    call h5tset_size_f(text_type, int(text_width, size_t), hdferr)
    call h5tset_strpad_f(text_type, H5T_STR_NULLTERM_F, hdferr)
    call h5tset_cset_f(text_type, H5T_CSET_UTF8_F, hdferr)
  end function fixed_text_type

  subroutine write_text_slab(path, dset, values, offset, err)
    character(len=*), intent(in) :: path           !< the file, for messages
    integer(hid_t), intent(in) :: dset
    character(len=*), intent(in) :: values(:)
    integer(i8), intent(in) :: offset
    type(error_t), intent(inout) :: err
    character(len=text_width, kind=c_char), target :: texts(size(values))
    integer(hid_t) :: text_type
    integer :: k, hdferr
    do k = 1, size(values)
      texts(k) = trim(values(k)) // c_null_char
    end do
    text_type = fixed_text_type()
    call write_slab(path, dset, text_type, c_loc(texts), [offset], [size(values, kind=i8)], err)
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

  subroutine write_slab(path, dset, mem_type, buffer, offset, counts, err)
    character(len=*), intent(in) :: path           !< the file, for messages
    integer(hid_t), intent(in) :: dset, mem_type
    type(c_ptr), intent(in) :: buffer
    integer(i8), intent(in) :: offset(:), counts(:)
    type(error_t), intent(inout) :: err
    integer(hid_t) :: file_space, mem_space
    integer :: hdferr
    if (err%failed()) return
    call select_slab(dset, offset, counts, file_space, mem_space)
    call h5dwrite_f(dset, mem_type, buffer, hdferr, mem_space_id=mem_space, file_space_id=file_space)
    if (hdferr < 0) call set_error(err, err_output, path // ': cannot write data (disk full?)')
    call h5sclose_f(file_space, hdferr)
    call h5sclose_f(mem_space, hdferr)
  end subroutine write_slab
end module ellroll_hdf5_common
