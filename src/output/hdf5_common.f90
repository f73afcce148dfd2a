!> What ellroll's HDF5 writer and reader share: hyperslab selection,
!> dimension numbering and the text type.
module ellroll_hdf5_common
  use hdf5
  use ellroll_kinds, only: i8
  implicit none
  private

  public :: select_slab, dim_index, new_text_type

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
end module ellroll_hdf5_common
