!> The groups of a new output file, laid out with ellroll_hdf5_layout: the
!> shared dimension scales (/time, /xyz, /mode), /case and /summary (a
!> dataset per entry of a record, one value per case, with the varied
!> inputs as coordinates) and /trajectory (the stored fields).
module ellroll_hdf5_groups
  use, intrinsic :: iso_c_binding, only: c_int64_t
  use hdf5
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: set_error, err_output
  use ellroll_records, only: named_value_t, kind_real, kind_int, kind_text
  use ellroll_status, only: status_count, status_pending
  use ellroll_cases, only: field_count, field_names, field_units, field_ncomp, field_descriptions
  use ellroll_campaign, only: coordinate_t
  use ellroll_params, only: dataset_inputs
  use ellroll_results, only: count_undefined
  use ellroll_limit_states, only: limit_state_t, limit_state_flag_values, limit_state_flag_meanings
  use ellroll_figures, only: figures
  use ellroll_hdf5_layout, only: layout_t
  use ellroll_switch_store, only: switch_store_t, switch_flag_meanings
  use ellroll_file_layout, only: time_entry, xyz_entry, mode_entry, case_entry, status_entry, checksum_entry, &
      status_flag_meanings
  implicit none
  private

  public :: shared_scales, case_group, trajectory_group, trajectory_label, limit_state_group, switch_group

  !> Largest chunk of a trajectory dataset (bytes); one case per chunk at most.
  integer, parameter :: max_chunk_bytes = 2**20
  interface
    !> The file address of a contiguous dataset's data (HADDR_UNDEF, all
    !> bits set, when it has none); not in the 1.10 Fortran API.
    integer(c_int64_t) function h5d_address(dset) bind(c, name='H5Dget_offset')
      import :: c_int64_t
      integer(c_int64_t), value :: dset             !< an hid_t: int64_t since HDF5 1.10
    end function h5d_address
  end interface

contains

  !> /trajectory_label, a scalar fixed-length string of `bytes` bytes,
  !> contiguous and allocated at once, never filled: ellroll_trajectory_store
  !> writes the label of the trajectories written in place there, beside
  !> HDF5. Made first, it lies near the file's start (its address is the
  !> result; -1 when the layout failed).
  integer(i8) function trajectory_label(lay, bytes) result(address)
    type(layout_t), intent(inout) :: lay
    integer, intent(in) :: bytes
    integer(hid_t) :: text_type, space, dcpl, dset
    integer :: hdferr
    address = -1
    if (lay%err%failed()) return
    call h5tcopy_f(H5T_FORTRAN_S1, text_type, hdferr)
    call lay%check(hdferr, 'create a datatype')
    call h5tset_size_f(text_type, int(bytes, size_t), hdferr)
    call lay%check(hdferr, 'set a text size')
    call h5tset_strpad_f(text_type, H5T_STR_NULLPAD_F, hdferr)
    call lay%check(hdferr, 'set a text padding')
    call h5screate_f(H5S_SCALAR_F, space, hdferr)
    call lay%check(hdferr, 'create a dataspace')
    call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, hdferr)
    call lay%check(hdferr, 'create a property list')
    call h5pset_alloc_time_f(dcpl, H5D_ALLOC_TIME_EARLY_F, hdferr)
    call lay%check(hdferr, 'set an allocation time')
    call h5pset_fill_time_f(dcpl, H5D_FILL_TIME_NEVER_F, hdferr)
    call lay%check(hdferr, 'set a fill time')
    if (.not. lay%err%failed()) call h5dcreate_f(lay%file, 'trajectory_label', text_type, space, dset, hdferr, &
                                                  dcpl_id=dcpl)
    call lay%check(hdferr, 'create dataset trajectory_label')
    call h5pclose_f(dcpl, hdferr)
    call h5sclose_f(space, hdferr)
    call h5tclose_f(text_type, hdferr)
    if (lay%err%failed()) return
    call lay%text_attribute(dset, 'units', '1')
    call lay%text_attribute(dset, 'long_name', 'where the trajectories lie in this file (for a resume)')
    address = h5d_address(int(dset, c_int64_t))
    if (address < 0) call set_error(lay%err, err_output, lay%path // ': no file address for /trajectory_label')
    call lay%close_dataset(dset)
  end function trajectory_label

  !> The dimension scales every group shares: /time, /xyz, /mode.
  subroutine shared_scales(lay, times)
    type(layout_t), intent(inout) :: lay
    real(wp), intent(in) :: times(:)
    lay%time_scale = lay%real_dataset(lay%file, trim(time_entry%name), [size(times, kind=i8)], time_entry%units, &
                                      time_entry%description)
    call lay%write_reals(lay%time_scale, times, [0_i8], [size(times, kind=i8)])
    call lay%make_scale(lay%time_scale, trim(time_entry%name))
    lay%xyz_scale = lay%text_dataset(lay%file, trim(xyz_entry%name), 3_i8, xyz_entry%description)
    call lay%write_texts(lay%xyz_scale, ['x', 'y', 'z'], 0_i8)
    call lay%make_scale(lay%xyz_scale, trim(xyz_entry%name))
    lay%mode_scale = lay%int_dataset(lay%file, trim(mode_entry%name), 2_i8, mode_entry%units, mode_entry%description)
    call lay%write_ints(lay%mode_scale, [1_i8, 2_i8], 0_i8)
    call lay%make_scale(lay%mode_scale, trim(mode_entry%name))
  end subroutine shared_scales

  !> A group of one value per case: a dataset per entry of `rec` (/case:
  !> the resolved inputs; /summary: the case's status and figures), with
  !> the varied inputs `coords` as their coordinates.
  subroutine case_group(lay, name, indices, rec, coords)
    type(layout_t), intent(inout) :: lay
    character(len=*), intent(in) :: name
    integer(i8), intent(in) :: indices(:)
    type(named_value_t), intent(in) :: rec(:)
    type(coordinate_t), intent(in) :: coords(:)
    integer(hid_t) :: group, scale, dset
    integer(i8) :: n_cases
    integer(i8), target :: undefined_count
    integer :: k
    undefined_count = count_undefined
    n_cases = size(indices, kind=i8)
    group = lay%new_group(name)
    scale = case_scale(lay, group, indices)
    call coordinate_datasets(lay, group, scale, coords)
    if (name == 'summary') then
      call create_status(lay, group, scale, n_cases, coords)
      call create_checksum(lay, group, scale, n_cases, coords)
    end if
    do k = 1, size(rec)
      if (lay%err%failed()) exit
      select case (rec(k)%kind)
      case (kind_real)
        if (rec(k)%ncomp == 1) then
          dset = lay%real_dataset(group, rec(k)%name, [n_cases], rec(k)%units, rec(k)%description)
          call lay%attach(dset, scale, 0)
        else
          dset = lay%real_dataset(group, rec(k)%name, [int(rec(k)%ncomp, i8), n_cases], rec(k)%units, &
                                  rec(k)%description)
          call lay%attach(dset, scale, 0)
          call lay%attach(dset, merge(lay%xyz_scale, lay%mode_scale, rec(k)%ncomp == 3), 1)
        end if
      case (kind_int)
        if (name == 'summary') then
          ! a count undefined for the case (one never run) is -1, CF's
          ! _FillValue: missing to netCDF readers and xarray
          dset = lay%int_dataset(group, rec(k)%name, n_cases, rec(k)%units, rec(k)%description, &
                                 fill=undefined_count)
          call lay%int_attribute(dset, '_FillValue', [count_undefined])
        else
          dset = lay%int_dataset(group, rec(k)%name, n_cases, rec(k)%units, rec(k)%description)
        end if
        call lay%attach(dset, scale, 0)
      case (kind_text)
        dset = lay%text_dataset(group, rec(k)%name, n_cases, rec(k)%description)
        call lay%attach(dset, scale, 0)
      end select
      ! the names a sweep gives the inputs a /case dataset holds (readers
      ! take them from here)
      if (name == 'case' .and. len_trim(dataset_inputs(rec(k)%name)) > 0) &
        call lay%text_attribute(dset, 'input_names', trim(dataset_inputs(rec(k)%name)))
      call name_coordinates(lay, dset, coords)
      call lay%close_dataset(dset)
    end do
    call lay%close_dataset(scale)
    call lay%close_group(group)
  end subroutine case_group

  !> /limit_state: a flag per case (int8: 1 exceeded, 0 not, -1 undefined) per limit
  !> state, named by it, its figure, capacity and the capacity's units as
  !> attributes; `rec` gives the names and long names (file_layout's
  !> limit_state_row).
  subroutine limit_state_group(lay, indices, states, rec, coords)
    type(layout_t), intent(inout) :: lay
    integer(i8), intent(in) :: indices(:)
    type(limit_state_t), intent(in) :: states(:)
    type(named_value_t), intent(in) :: rec(:)
    type(coordinate_t), intent(in) :: coords(:)
    integer(hid_t) :: group, scale, dset
    integer :: k
    group = lay%new_group('limit_state')
    scale = case_scale(lay, group, indices)
    call coordinate_datasets(lay, group, scale, coords)
    do k = 1, size(states)
      if (lay%err%failed()) exit
      dset = lay%int_dataset(group, trim(rec(k)%name), size(indices, kind=i8), '1', trim(rec(k)%description), &
                             small=.true.)
      call lay%attach(dset, scale, 0)
      call lay%text_attribute(dset, 'figure', trim(figures(states(k)%figure)%name))
      call lay%real_attribute(dset, 'capacity', states(k)%capacity)
      call lay%text_attribute(dset, 'capacity_units', trim(figures(states(k)%figure)%unit))
      call lay%int_attribute(dset, 'flag_values', limit_state_flag_values, small=.true.)
      call lay%text_attribute(dset, 'flag_meanings', limit_state_flag_meanings)
      call name_coordinates(lay, dset, coords)
      call lay%close_dataset(dset)
    end do
    call lay%close_dataset(scale)
    call lay%close_group(group)
  end subroutine limit_state_group

  !> /switches: `time` and `kind` on the `switch` dimension (every case's
  !> switches, case after case), `first` and `count` on the case dimension.
  subroutine switch_group(lay, store)
    type(layout_t), intent(inout) :: lay
    type(switch_store_t), intent(in) :: store
    integer(hid_t) :: group, scale, switch_scale, dset
    integer(i8), allocatable :: first(:), count(:), kinds(:), order(:)
    integer(i8), target :: undefined
    real(wp), allocatable :: times(:)
    integer(i8) :: n, k
    if (.not. store%active) return
    undefined = count_undefined
    call store%ragged(first, count, times, kinds)
    n = size(times, kind=i8)
    order = [(k, k = 0, n - 1)]
    group = lay%new_group('switches')
    scale = lay%int_dataset(group, trim(case_entry%name), size(count, kind=i8), case_entry%units, &
                            case_entry%description)
    call lay%write_ints(scale, store%indices, 0_i8)
    call lay%make_scale(scale, trim(case_entry%name))
    switch_scale = lay%int_dataset(group, 'switch', n, '1', 'index of the switch')
    if (n > 0) call lay%write_ints(switch_scale, order, 0_i8)
    call lay%make_scale(switch_scale, 'switch')
    dset = lay%real_dataset(group, 'switch_time', [n], 's', 'time of the switch of regime')
    if (n > 0) call lay%write_reals(dset, times, [0_i8], [n])
    call lay%attach(dset, switch_scale, 0)
    call lay%close_dataset(dset)
    dset = lay%int_dataset(group, 'switch_kind', n, '1', 'kind of the switch of regime', small=.true.)
    if (n > 0) call lay%write_ints(dset, kinds, 0_i8)
    call lay%int_attribute(dset, 'flag_values', [1_i8, 2_i8], small=.true.)
    call lay%text_attribute(dset, 'flag_meanings', switch_flag_meanings)
    call lay%attach(dset, switch_scale, 0)
    call lay%close_dataset(dset)
    dset = lay%int_dataset(group, 'first', size(count, kind=i8), '1', &
                           'index of the case''s first switch', fill=undefined)
    call lay%int_attribute(dset, '_FillValue', [count_undefined])
    call lay%write_ints(dset, first, 0_i8)
    call lay%attach(dset, scale, 0)
    call lay%close_dataset(dset)
    dset = lay%int_dataset(group, 'count', size(count, kind=i8), '1', 'switches of regime of the case', &
                           fill=undefined)
    call lay%int_attribute(dset, '_FillValue', [count_undefined])
    call lay%write_ints(dset, count, 0_i8)
    call lay%attach(dset, scale, 0)
    call lay%close_dataset(dset)
    call lay%close_dataset(switch_scale)
    call lay%close_dataset(scale)
    call lay%close_group(group)
  end subroutine switch_group

  !> The group's own 'case' scale, holding the global case indices.
  integer(hid_t) function case_scale(lay, group, indices) result(id)
    type(layout_t), intent(inout) :: lay
    integer(hid_t), intent(in) :: group
    integer(i8), intent(in) :: indices(:)
    id = lay%int_dataset(group, trim(case_entry%name), size(indices, kind=i8), case_entry%units, &
                         case_entry%description)
    call lay%write_ints(id, indices, 0_i8)
    call lay%make_scale(id, trim(case_entry%name))
  end function case_scale

  subroutine create_status(lay, group, scale, n_cases, coords)
    type(layout_t), intent(inout) :: lay
    integer(hid_t), intent(in) :: group, scale
    integer(i8), intent(in) :: n_cases
    type(coordinate_t), intent(in) :: coords(:)
    integer(hid_t) :: dset
    integer :: s
    character(len=:), allocatable :: meanings
    integer(i8), target :: pending
    pending = status_pending
    dset = lay%int_dataset(group, trim(status_entry%name), n_cases, status_entry%units, status_entry%description, &
                           fill=pending)
    if (lay%err%failed()) return
    call status_flag_meanings(meanings)
    call lay%int_attribute(dset, 'flag_values', [(int(s, i8), s = 0, status_count - 1)])
    call lay%text_attribute(dset, 'flag_meanings', meanings)
    call lay%attach(dset, scale, 0)
    call name_coordinates(lay, dset, coords)
    call lay%close_dataset(dset)
  end subroutine create_status

  !> /summary/checksum: each case's checksum (file_row), -1 (CF's
  !> _FillValue) for a case not written (status pending).
  subroutine create_checksum(lay, group, scale, n_cases, coords)
    type(layout_t), intent(inout) :: lay
    integer(hid_t), intent(in) :: group, scale
    integer(i8), intent(in) :: n_cases
    type(coordinate_t), intent(in) :: coords(:)
    integer(hid_t) :: dset
    integer(i8), target :: never_run
    never_run = -1
    dset = lay%int_dataset(group, trim(checksum_entry%name), n_cases, checksum_entry%units, &
                           checksum_entry%description, fill=never_run)
    if (lay%err%failed()) return
    call lay%int_attribute(dset, '_FillValue', [never_run])
    call lay%attach(dset, scale, 0)
    call name_coordinates(lay, dset, coords)
    call lay%close_dataset(dset)
  end subroutine create_checksum

  !> The varied inputs as datasets of the group, on its case dimension
  !> (CF auxiliary coordinates: xarray gives them as coordinates of `case`).
  subroutine coordinate_datasets(lay, group, scale, coords)
    type(layout_t), intent(inout) :: lay
    integer(hid_t), intent(in) :: group, scale
    type(coordinate_t), intent(in) :: coords(:)
    integer(hid_t) :: dset
    integer(i8) :: n
    integer :: k
    do k = 1, size(coords)
      if (lay%err%failed()) return
      if (allocated(coords(k)%values)) then
        n = size(coords(k)%values, kind=i8)
        dset = lay%real_dataset(group, trim(coords(k)%name), [n], coords(k)%unit, coords(k)%description)
        call lay%write_reals(dset, coords(k)%values, [0_i8], [n])
      else
        n = size(coords(k)%texts, kind=i8)
        dset = lay%text_dataset(group, trim(coords(k)%name), n, coords(k)%description)
        call lay%write_texts(dset, coords(k)%texts, 0_i8)
      end if
      call lay%attach(dset, scale, 0)
      call lay%close_dataset(dset)
    end do
  end subroutine coordinate_datasets

  !> The CF `coordinates` attribute of a dataset on the case dimension.
  subroutine name_coordinates(lay, dset, coords)
    type(layout_t), intent(inout) :: lay
    integer(hid_t), intent(in) :: dset
    type(coordinate_t), intent(in) :: coords(:)
    character(len=:), allocatable :: names
    integer :: k
    if (size(coords) == 0) return
    names = trim(coords(1)%name)
    do k = 2, size(coords)
      names = names // ' ' // trim(coords(k)%name)
    end do
    call lay%text_attribute(dset, 'coordinates', names)
  end subroutine name_coordinates

  !> /trajectory: the stored fields, on its own `time` scale (the values
  !> of /time: netCDF readers give a group's coordinates from the group
  !> itself, so that xarray's open_dataset(group='trajectory') has time as
  !> a coordinate). Compressed: chunks of one case each,
  !> written through HDF5. Otherwise contiguous, allocated now and never
  !> filled (each case is written once, in place, at `address`; a case not
  !> written yet reads as zeros, its status 'pending').
  subroutine trajectory_group(lay, fields, in_windows, times, indices, coords, address)
    logical, intent(in) :: fields(field_count)       !< the stored fields
    logical, intent(in) :: in_windows(field_count)   !< those written through HDF5 (compressed)
    real(wp), intent(in) :: times(:)                 !< the output times
    type(layout_t), intent(inout) :: lay
    integer(i8), intent(in) :: indices(:)
    type(coordinate_t), intent(in) :: coords(:)
    integer(i8), intent(out) :: address(field_count)
    integer(hid_t) :: group, scale, time, dset
    integer(i8) :: chunk_samples, n_cases, n_samples
    integer(i8), allocatable :: dims(:)
    integer :: f
    address = -1
    n_cases = size(indices, kind=i8)
    n_samples = size(times, kind=i8)
    group = lay%new_group('trajectory')
    scale = case_scale(lay, group, indices)
    time = lay%real_dataset(group, 'time', [n_samples], 's', 'output times')
    call lay%write_reals(time, times, [0_i8], [n_samples])
    call lay%make_scale(time, 'time')
    call coordinate_datasets(lay, group, scale, coords)
    do f = 1, field_count
      if (.not. fields(f) .or. lay%err%failed()) cycle
      chunk_samples = min(n_samples, int(max_chunk_bytes / (8 * field_ncomp(f)), i8))
      if (field_ncomp(f) == 1) then
        dims = [n_samples, n_cases]
      else
        dims = [3_i8, n_samples, n_cases]
      end if
      if (in_windows(f)) then
        dset = lay%real_dataset(group, trim(field_names(f)), dims, trim(field_units(f)), &
                                trim(field_descriptions(f)), chunk=[dims(:size(dims) - 2), chunk_samples, 1_i8])
      else
        dset = lay%real_dataset(group, trim(field_names(f)), dims, trim(field_units(f)), &
                                trim(field_descriptions(f)), in_place=.true.)
        if (dset >= 0) then
          address(f) = h5d_address(int(dset, c_int64_t))
          if (address(f) < 0 .and. n_cases > 0) &   ! an empty shard has no data, no address
            call set_error(lay%err, err_output, lay%path // ': no file address for /trajectory/' // &
                           trim(field_names(f)))
        end if
      end if
      call lay%attach(dset, scale, 0)
      call lay%attach(dset, time, 1)
      if (field_ncomp(f) == 3) call lay%attach(dset, lay%xyz_scale, 2)
      call name_coordinates(lay, dset, coords)
      call lay%close_dataset(dset)
    end do
    call lay%close_dataset(time)
    call lay%close_dataset(scale)
    call lay%close_group(group)
  end subroutine trajectory_group
end module ellroll_hdf5_groups
