!> Laying out a new output file: groups, datasets with their units and long
!> names, dimension scales and the values written once. A layout_t carries
!> what every step shares (the file, its path, the deflate level, the
!> shared scales) and the first error: after it every step does nothing, so
!> a layout reads as a list of calls with one check at the end.
module ellroll_hdf5_layout
  use, intrinsic :: iso_c_binding, only: c_loc
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use hdf5
  use h5ds, only: h5dsset_scale_f, h5dsattach_scale_f
  use h5lt, only: h5ltset_attribute_double_f
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_output
  use ellroll_hdf5_common, only: hdf5_reason, dim_index, new_text_type, write_text_attribute, write_text_slab, write_real_slab, &
      write_int_slab
  implicit none
  private

  public :: layout_t

  type :: layout_t
    integer(hid_t) :: file = -1
    character(len=:), allocatable :: path
    integer :: deflate_level = 0               !< of the chunked datasets: 0 none, 1..9
    integer(hid_t) :: time_scale = -1, xyz_scale = -1, mode_scale = -1
    type(error_t) :: err
  contains
    procedure :: check
    procedure :: new_group
    procedure :: text_attribute
    procedure :: int_attribute
    procedure :: real_attribute
    procedure :: real_dataset
    procedure :: int_dataset
    procedure :: text_dataset
    procedure :: attach
    procedure :: make_scale
    procedure :: write_reals
    procedure :: write_ints
    procedure :: write_texts
    procedure :: close_dataset
    procedure :: close_group
  end type layout_t

contains

  !> Record a failed HDF5 call (code < 0) as the layout's error: "cannot what".
  subroutine check(self, code, what)
    class(layout_t), intent(inout) :: self
    integer, intent(in) :: code
    character(len=*), intent(in) :: what
    character(len=:), allocatable :: reason
    if (code < 0 .and. .not. self%err%failed()) then
      call hdf5_reason(reason)
      call set_error(self%err, err_output, self%path // ': cannot ' // what // ': ' // reason)
    end if
  end subroutine check

  !> A group that keeps its members in the order they are made (HDF5's
  !> link creation order, tracked and indexed): readers list /case and
  !> /summary in the order of the tables they come from.
  integer(hid_t) function new_group(self, name) result(id)
    class(layout_t), intent(inout) :: self
    character(len=*), intent(in) :: name
    integer(hid_t) :: gcpl
    integer :: hdferr
    id = -1
    if (self%err%failed()) return
    call h5pcreate_f(H5P_GROUP_CREATE_F, gcpl, hdferr)
    call self%check(hdferr, 'create a property list')
    if (.not. self%err%failed()) &
      call h5pset_link_creation_order_f(gcpl, ior(H5P_CRT_ORDER_TRACKED_F, H5P_CRT_ORDER_INDEXED_F), hdferr)
    call self%check(hdferr, 'set the link creation order')
    if (.not. self%err%failed()) call h5gcreate_f(self%file, name, id, hdferr, gcpl_id=gcpl)
    call self%check(hdferr, 'create group /' // name)
    call h5pclose_f(gcpl, hdferr)
    call self%check(hdferr, 'close a property list')
  end function new_group

  subroutine text_attribute(self, loc, name, value)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name, value
    integer :: hdferr
    if (self%err%failed()) return
    call write_text_attribute(loc, name, value, hdferr)
    call self%check(hdferr, 'write attribute ' // name)
  end subroutine text_attribute

  !> An attribute of 64-bit integers (8-bit where `small`), the type of the
  !> int datasets (CF asks flag_values and _FillValue to have the type of
  !> their variable).
  subroutine int_attribute(self, loc, name, values, small)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(i8), intent(in), target :: values(:)
    logical, intent(in), optional :: small
    integer(hid_t) :: space, attr, file_type
    integer :: hdferr, code
    if (self%err%failed()) return
    file_type = H5T_STD_I64LE
    if (present(small)) then
      if (small) file_type = H5T_STD_I8LE
    end if
    call h5screate_simple_f(1, [size(values, kind=hsize_t)], space, hdferr)
    if (hdferr >= 0) call h5acreate_f(loc, name, file_type, space, attr, hdferr)
    if (hdferr >= 0) then
      call h5awrite_f(attr, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(values), hdferr)
      call h5aclose_f(attr, code)
      hdferr = min(hdferr, code)
    end if
    call h5sclose_f(space, code)
    call self%check(min(hdferr, code), 'write attribute ' // name)
  end subroutine int_attribute

  subroutine real_attribute(self, loc, name, value)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(wp), intent(in) :: value
    integer :: hdferr
    if (self%err%failed()) return
    call h5ltset_attribute_double_f(loc, '.', name, [value], 1_size_t, hdferr)
    call self%check(hdferr, 'write attribute ' // name)
  end subroutine real_attribute

  !> A dataset of reals, NaN until written, with its units and long name:
  !> chunked (and deflated at the layout's level) when `chunk` is given;
  !> contiguous, allocated now and never filled when `in_place`.
  integer(hid_t) function real_dataset(self, loc, name, dims, units, description, chunk, in_place) result(dset)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name, units, description
    integer(i8), intent(in) :: dims(:)
    integer(i8), intent(in), optional :: chunk(:)
    logical, intent(in), optional :: in_place
    integer(hid_t) :: space, dcpl
    integer :: hdferr
    real(wp), target :: fill
    fill = ieee_value(fill, ieee_quiet_nan)
    dset = -1
    if (self%err%failed()) return
    call h5screate_simple_f(size(dims), int(dims, hsize_t), space, hdferr)
    call self%check(hdferr, 'create a dataspace')
    call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, hdferr)
    call self%check(hdferr, 'create a property list')
    call h5pset_fill_value_f(dcpl, H5T_NATIVE_DOUBLE, c_loc(fill), hdferr)
    call self%check(hdferr, 'set a fill value')
    if (present(chunk)) then
      call h5pset_chunk_f(dcpl, size(chunk), int(chunk, hsize_t), hdferr)
      call self%check(hdferr, 'set a chunk size')
      ! off by default: trajectories shrink by some 20 % and deflating them
      ! in the single writer took as long as integrating them
      if (self%deflate_level > 0) then
        call h5pset_shuffle_f(dcpl, hdferr)
        call self%check(hdferr, 'set the shuffle filter')
        call h5pset_deflate_f(dcpl, self%deflate_level, hdferr)
        call self%check(hdferr, 'set the deflate filter')
      end if
    end if
    if (present(in_place)) then
      if (in_place) then
        call h5pset_alloc_time_f(dcpl, H5D_ALLOC_TIME_EARLY_F, hdferr)
        call self%check(hdferr, 'set an allocation time')
        call h5pset_fill_time_f(dcpl, H5D_FILL_TIME_NEVER_F, hdferr)
        call self%check(hdferr, 'set a fill time')
      end if
    end if
    if (.not. self%err%failed()) call h5dcreate_f(loc, name, H5T_NATIVE_DOUBLE, space, dset, hdferr, dcpl_id=dcpl)
    call self%check(hdferr, 'create dataset ' // name)
    call h5pclose_f(dcpl, hdferr)
    call self%check(hdferr, 'close a property list')
    call h5sclose_f(space, hdferr)
    call self%check(hdferr, 'close a dataspace')
    call describe(self, dset, units, description)
    ! CF's _FillValue, of the variable's type: what was never written (a
    ! sample after a case ended, a figure of a case never run) is missing
    ! to netCDF readers and xarray, as NaN is to h5py and numpy
    if (.not. self%err%failed()) then
      call h5ltset_attribute_double_f(dset, '.', '_FillValue', [fill], 1_size_t, hdferr)
      call self%check(hdferr, 'write attribute _FillValue')
    end if
  end function real_dataset

  !> A dataset of integers (64-bit; 8-bit where `small`: flags), written
  !> from 64-bit values.
  integer(hid_t) function int_dataset(self, loc, name, n, units, description, fill, small) result(dset)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name, units, description
    integer(i8), intent(in) :: n
    integer(i8), intent(in), optional, target :: fill
    logical, intent(in), optional :: small
    integer(hid_t) :: space, dcpl, file_type
    integer :: hdferr
    dset = -1
    if (self%err%failed()) return
    call h5screate_simple_f(1, [int(n, hsize_t)], space, hdferr)
    call self%check(hdferr, 'create a dataspace')
    call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, hdferr)
    call self%check(hdferr, 'create a property list')
    if (present(fill)) then
      call h5pset_fill_value_f(dcpl, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(fill), hdferr)
      call self%check(hdferr, 'set a fill value')
    end if
    file_type = H5T_STD_I64LE
    if (present(small)) then
      if (small) file_type = H5T_STD_I8LE
    end if
    if (.not. self%err%failed()) call h5dcreate_f(loc, name, file_type, space, dset, hdferr, dcpl_id=dcpl)
    call self%check(hdferr, 'create dataset ' // name)
    call h5pclose_f(dcpl, hdferr)
    call self%check(hdferr, 'close a property list')
    call h5sclose_f(space, hdferr)
    call self%check(hdferr, 'close a dataspace')
    call describe(self, dset, units, description)
  end function int_dataset

  integer(hid_t) function text_dataset(self, loc, name, n, description) result(dset)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name, description
    integer(i8), intent(in) :: n
    integer(hid_t) :: space, text_type
    integer :: hdferr
    dset = -1
    if (self%err%failed()) return
    call h5screate_simple_f(1, [int(n, hsize_t)], space, hdferr)
    call self%check(hdferr, 'create a dataspace')
    text_type = new_text_type()
    if (.not. self%err%failed()) call h5dcreate_f(loc, name, text_type, space, dset, hdferr)
    call self%check(hdferr, 'create dataset ' // name)
    call h5tclose_f(text_type, hdferr)
    call self%check(hdferr, 'close a datatype')
    call h5sclose_f(space, hdferr)
    call self%check(hdferr, 'close a dataspace')
    call describe(self, dset, '1', description)
  end function text_dataset

  subroutine describe(self, dset, units, description)
    type(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: dset
    character(len=*), intent(in) :: units, description
    call self%text_attribute(dset, 'units', trim(units))
    call self%text_attribute(dset, 'long_name', trim(description))
  end subroutine describe

  !> Attach scale to the dataset's dimension `dim` as h5py counts them.
  subroutine attach(self, dset, scale, dim)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: dset, scale
    integer, intent(in) :: dim
    integer :: hdferr
    if (self%err%failed()) return
    call h5dsattach_scale_f(dset, scale, dim_index(dim), hdferr)
    call self%check(hdferr, 'attach a dimension scale')
  end subroutine attach

  subroutine make_scale(self, dset, name)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: dset
    character(len=*), intent(in) :: name
    integer :: hdferr
    if (self%err%failed()) return
    call h5dsset_scale_f(dset, hdferr, name)
    call self%check(hdferr, 'make ' // name // ' a dimension scale')
  end subroutine make_scale

  !> Close a dataset the layout made (its data written then, where HDF5
  !> held it back), the failure recorded.
  subroutine close_dataset(self, dset)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: dset
    integer :: hdferr
    if (dset < 0) return
    call h5dclose_f(dset, hdferr)
    call self%check(hdferr, 'close a dataset')
  end subroutine close_dataset

  subroutine close_group(self, group)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: group
    integer :: hdferr
    if (group < 0) return
    call h5gclose_f(group, hdferr)
    call self%check(hdferr, 'close a group')
  end subroutine close_group

  subroutine write_reals(self, dset, values, offset, counts)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: dset
    real(wp), intent(in), target :: values(*)
    integer(i8), intent(in) :: offset(:), counts(:)
    call write_real_slab(self%path, dset, values, offset, counts, self%err)
  end subroutine write_reals

  subroutine write_ints(self, dset, values, offset)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: dset
    integer(i8), intent(in), target :: values(:)
    integer(i8), intent(in) :: offset
    call write_int_slab(self%path, dset, values, [offset], [size(values, kind=i8)], self%err)
  end subroutine write_ints

  subroutine write_texts(self, dset, values, offset)
    class(layout_t), intent(inout) :: self
    integer(hid_t), intent(in) :: dset
    character(len=*), intent(in) :: values(:)
    integer(i8), intent(in) :: offset
    call write_text_slab(self%path, dset, values, offset, self%err)
  end subroutine write_texts
end module ellroll_hdf5_layout
