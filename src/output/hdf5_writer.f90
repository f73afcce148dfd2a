!> Writing ellroll's HDF5 output: a thin writer that lays out /time, /case,
!> /trajectory and /summary for n cases and takes one case at a time. Every
!> HDF5 call that writes lives here (ellroll_hdf5_reader reads).
!>
!> HDF5 stores arrays in C order, so the Fortran dimensions below are the
!> reverse of what h5py shows: Fortran (3, nt, ncase) is h5py (ncase, nt, 3).
module ellroll_hdf5_writer
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use hdf5
  use h5lt, only: h5ltset_attribute_int_f
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_output
  use ellroll_records, only: named_value_t, kind_real, kind_int, kind_text
  use ellroll_cases, only: case_t, case_record, field_count, field_names, field_ncomp
  use ellroll_switch_store, only: switch_store_t
  use ellroll_results, only: case_result_t, summary_record
  use ellroll_campaign, only: coordinate_t
  use ellroll_system, only: close_descriptor, system_error_text
  use ellroll_strings, only: itoa
  use ellroll_files, only: descriptor_is_at, descriptor_identity, rename_path
  use ellroll_trajectory_store, only: trajectory_store_t, label_bytes, label_search_bytes
  use ellroll_hdf5_common, only: file_identity, hdf5_reason, note_failed_close, write_text_slab, write_real_slab, &
      write_int_slab, hdf5_quiet, hdf5_descriptor
  use ellroll_hdf5_layout, only: layout_t
  use ellroll_hdf5_groups, only: shared_scales, case_group, trajectory_group, trajectory_label, limit_state_group, &
      switch_group
  use ellroll_file_layout, only: table_row, file_row, limit_state_row, file_title, file_references
  use ellroll_case_checksum, only: case_checksum
  implicit none
  private

  public :: h5_output_t, provenance_t, window_list_t, table_row, written_in_place, describe_writer

  type :: provenance_t
    character(len=:), allocatable :: program, version, created, input_file, input_namelist, command_line
    character(len=:), allocatable :: build          !< the build type and options ('Release native')
    character(len=:), allocatable :: campaign_id    !< hash of the canonical input and its files' fingerprints
    character(len=:), allocatable :: input_files    !< the files the input reads, with their fingerprints
    integer(i8) :: n_cases_total = 0                !< cases of the whole campaign
    character(len=:), allocatable :: shard          !< 'I/N'
  end type provenance_t


  !> Cases are kept per window of consecutive cases (their table rows: inputs,
  !> summary, status; and compressed trajectories) and written with one
  !> hyperslab per dataset when the window is complete: case by case, the
  !> HDF5 calls (some 45 small writes and one per field) cost as much as
  !> integrating a short case, in the one writer every thread waits for. A
  !> window holds at most max_window_rows cases and about window_bytes of
  !> trajectories; at most max_windows are kept (a resume replays its journal
  !> in any order), the oldest then goes out as it is.
  !>
  !> Uncompressed trajectories (the default) do not go through HDF5 at all
  !> once the file is laid out: each is a contiguous dataset allocated when
  !> it is created, so a case's samples have a fixed place in the file, and
  !> the thread that integrated the case writes them there itself (pwritev),
  !> beside the other threads. Through HDF5 they held the one writer lock for
  !> 10 % of a one-thread campaign: a cap of 10x on any number of threads.
  integer, parameter :: max_window_rows = 64, max_windows = 16
  integer(i8), parameter :: window_bytes = 4 * 2_i8**20

  type :: sample_block_t
    real(wp), allocatable :: values(:, :)            !< (component x sample, row)
  end type sample_block_t

  type :: row_window_t
    logical :: in_use = .false.
    integer(i8) :: first = 0                         !< the case of its first row
    integer(i8) :: opened = 0                        !< when it was opened (the oldest goes first)
    integer :: expected = 0, filled = 0
    logical, allocatable :: present(:)
    type(named_value_t), allocatable :: rows(:, :)   !< (entry, row)
    type(sample_block_t) :: samples(field_count)     !< the stored fields' trajectories
  end type row_window_t

  !> Windows taken out of the writer, complete (or evicted), to be written:
  !> keeping a case is a copy, writing a window is HDF5 and the disk, so the
  !> threads of a campaign hold one lock for the first and another for the
  !> second, and keep cases while a window is being written.
  type :: window_list_t
    integer :: n = 0
    type(row_window_t), allocatable :: items(:)
  end type window_list_t

  type :: h5_output_t
    integer(hid_t) :: file = -1
    character(len=:), allocatable :: path
    integer(i8) :: n_cases = 0
    integer(i8) :: n_samples = 0
    logical :: fields(field_count) = .false.           !< the stored fields
    logical :: in_windows(field_count) = .false.       !< stored fields written through HDF5 (compressed)
    type(trajectory_store_t) :: in_place               !< the others, written in place
    ! datasets stay open while cases are written: opening and closing some 30
    ! datasets per case cost more than integrating it
    character(len=64), allocatable :: open_names(:)
    integer(hid_t), allocatable :: open_ids(:)
    type(row_window_t), allocatable :: windows(:)    !< max_windows slots, allocated once
    type(window_list_t) :: spare                     !< written windows, their buffers kept for reuse
    integer(i8) :: windows_opened = 0
    integer :: window_rows = 1                       !< cases per window
    character(len=11), allocatable :: row_groups(:)  !< the group of each row entry
    type(switch_store_t) :: switches                 !< the switches of regime, written at close
    !> the file's identity (device, inode) as it was made: the file this
    !> process writes, whatever is moved to its name later
    integer(i8) :: identity(2) = 0
  contains
    procedure :: create
    procedure :: row => case_row
    procedure :: keep_case
    procedure :: put_trajectories
    procedure :: write_windows
    procedure :: recycle
    procedure :: write_case
    procedure :: move_to
    procedure :: close => close_file
  end type h5_output_t

contains

  !> Create the file (where nothing is at path) and every dataset,
  !> filled with NaN / status 'pending' until cases are written.
  subroutine create(self, path, indices, times, fields, template, prov, coords, err, compression)
    class(h5_output_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: indices(:)      !< global index of each case slot
    real(wp), intent(in) :: times(:)
    logical, intent(in) :: fields(field_count)
    type(case_t), intent(in) :: template         !< gives the /case/ layout
    type(provenance_t), intent(in) :: prov
    type(coordinate_t), intent(in) :: coords(:)    !< the varied inputs, in /summary and /trajectory
    type(error_t), intent(inout) :: err
    integer, intent(in), optional :: compression   !< deflate level of the trajectories (0: none, the default)
    type(layout_t) :: lay
    integer(i8) :: address(field_count), label_address
    logical :: in_place_fields(field_count)     !< stored fields written in place, outside HDF5
    type(named_value_t), allocatable :: inputs(:), figures(:), states(:)
    integer :: own, closed

    lay%path = path
    if (present(compression)) lay%deflate_level = compression
    self%path = path
    self%n_cases = size(indices, kind=i8)
    self%n_samples = size(times, kind=i8)
    self%fields = fields
    in_place_fields = written_in_place(fields, lay%deflate_level)
    self%in_windows = fields .and. .not. in_place_fields
    self%window_rows = int(max(1_i8, min(int(max_window_rows, i8), window_bytes / &
        max(1_i8, 8 * self%n_samples * sum(field_ncomp, mask=self%in_windows)))))
    call open_new_file(self, lay, any(in_place_fields), label_address, own)
    call shared_scales(lay, times)
    inputs = case_record(template)
    figures = summary_record(case_result_t())
    call case_group(lay, 'case', indices, inputs, coords(:0))
    call trajectory_group(lay, self%fields, self%in_windows, times, indices, coords, address)
    call case_group(lay, 'summary', indices, figures, coords)
    states = limit_state_row(template, case_result_t())
    if (size(states) > 0) call limit_state_group(lay, indices, template%limit_states, states, coords)
    ! a row (file_row): the inputs, the figures, the status, the checksum, the limit states
    self%row_groups = [character(len=11) :: spread('case', 1, size(inputs)), &
                       spread('summary', 1, size(figures) + 2), spread('limit_state', 1, size(states))]
    call lay%close_dataset(lay%time_scale)
    call lay%close_dataset(lay%xyz_scale)
    call lay%close_dataset(lay%mode_scale)
    call write_provenance(self, lay, prov)
    if (lay%err%failed()) then
      if (.not. err%failed()) err = lay%err
      if (own >= 0) closed = close_descriptor(own)
      return
    end if
    call self%in_place%start(path, own, self%n_cases, self%n_samples, in_place_fields, address, label_address, err)
    ! a campaign that may slide (its regime is stored) stores its switches
    if (template%slide) call self%switches%start(indices)
  end subroutine create

  !> Create the file where nothing is, and with `labelled`
  !> /trajectory_label (its address: label_address). own: a descriptor of
  !> the file HDF5 made, for the trajectories written in place (-1: none).
  subroutine open_new_file(self, lay, labelled, label_address, own)
    type(h5_output_t), intent(inout) :: self
    type(layout_t), intent(inout) :: lay
    logical, intent(in) :: labelled         !< room for the label of trajectories written in place
    integer(i8), intent(out) :: label_address
    integer, intent(out) :: own
    integer :: hdferr, closed
    integer(hid_t) :: fapl
    character(len=:), allocatable :: reason
    label_address = -1
    own = -1
    call h5open_f(hdferr)
    call lay%check(hdferr, 'initialise HDF5')
    if (lay%err%failed()) return
    call hdf5_quiet()   ! errors are reported through err, not printed by HDF5
    ! the 1.10 format indexes each fixed-size chunked dataset with a compact
    ! fixed array instead of a B-tree: memory stays flat as cases are added
    call h5pcreate_f(H5P_FILE_ACCESS_F, fapl, hdferr)
    call lay%check(hdferr, 'create a property list')
    ! the sec2 driver (whatever HDF5_DRIVER says): its handle is the file's descriptor
    call h5pset_fapl_sec2_f(fapl, hdferr)
    call lay%check(hdferr, 'choose the file driver')
    call h5pset_libver_bounds_f(fapl, H5F_LIBVER_V110_F, H5F_LIBVER_V110_F, hdferr)
    call lay%check(hdferr, 'set the file format')
    ! no sieve buffer: a write goes to the file in its own call, so that a
    ! failed write is told by that call (a buffer flushed later reported into
    ! nothing that was checked)
    call h5pset_sieve_buf_size_f(fapl, 0_size_t, hdferr)
    call lay%check(hdferr, 'set the sieve buffer')
    if (lay%err%failed()) return
    ! H5F_ACC_EXCL: O_CREAT | O_EXCL, which fails on any name there, a
    ! symbolic link included (never followed): HDF5 writes only a file it made
    call h5fcreate_f(lay%path, H5F_ACC_EXCL_F, self%file, hdferr, access_prp=fapl)
    if (hdferr < 0) then
      call hdf5_reason(reason)
      call set_error(lay%err, err_output, lay%path // ': cannot create the file: ' // reason)
    end if
    call h5pclose_f(fapl, closed)
    call lay%check(closed, 'close a property list')
    if (lay%err%failed()) return
    ! what ellroll writes beside HDF5 goes to that same file, by its descriptor
    own = hdf5_descriptor(self%file)
    if (own < 0) then
      call set_error(lay%err, err_output, lay%path // ': cannot take the descriptor of the file HDF5 made')
    else if (.not. descriptor_is_at(own, lay%path)) then
      call set_error(lay%err, err_output, lay%path // ': was replaced while it was being created')
    else
      self%identity = descriptor_identity(own)
    end if
    if (lay%err%failed()) return
    lay%file = self%file
    ! the label first, so that it lies near the file's start, where a
    ! resume looks for it
    if (labelled) then
      label_address = trajectory_label(lay, label_bytes)
      if (label_address + label_bytes > label_search_bytes .and. .not. lay%err%failed()) &
        call set_error(lay%err, err_output, lay%path // ': /trajectory_label lies beyond the file''s first ' // &
                       itoa(label_search_bytes) // ' bytes')
    end if
  end subroutine open_new_file

  !> 'ellroll VERSION (BUILD build)' of a file's or journal's writer: what
  !> merge and --resume compare (build '': a file without the attribute
  !> `build`, of unknown type).
  subroutine describe_writer(version, build, text)
    character(len=*), intent(in) :: version, build
    character(len=:), allocatable, intent(out) :: text
    if (len_trim(build) == 0) then
      text = 'ellroll ' // trim(version) // ' (build of unknown type)'
    else
      text = 'ellroll ' // trim(version) // ' (' // trim(build) // ' build)'
    end if
  end subroutine describe_writer

  !> The root's attributes: written after the layout, so that where the
  !> trajectories lie (and so /trajectory_label) depends on the layout
  !> alone, not on the command line or the input's text.
  subroutine write_provenance(self, lay, prov)
    type(h5_output_t), intent(inout) :: self
    type(layout_t), intent(inout) :: lay
    type(provenance_t), intent(in) :: prov
    integer :: hdferr
    character(len=:), allocatable :: identity
    if (lay%err%failed()) return
    ! CF-1.10 global attributes, then ellroll's own provenance
    call lay%text_attribute(self%file, 'Conventions', 'CF-1.10')
    call lay%text_attribute(self%file, 'title', file_title)
    call lay%text_attribute(self%file, 'source', prov%program // ' ' // prov%version)
    call lay%text_attribute(self%file, 'history', prov%created // ' ' // prov%command_line)
    call lay%text_attribute(self%file, 'references', file_references)
    call lay%text_attribute(self%file, 'program', prov%program)
    call lay%text_attribute(self%file, 'version', prov%version)
    if (allocated(prov%build)) call lay%text_attribute(self%file, 'build', prov%build)
    call lay%text_attribute(self%file, 'created', prov%created)
    call lay%text_attribute(self%file, 'input_file', prov%input_file)
    call lay%text_attribute(self%file, 'input_namelist', prov%input_namelist)
    call lay%text_attribute(self%file, 'command_line', prov%command_line)
    call lay%text_attribute(self%file, 'campaign_id', prov%campaign_id)
    if (allocated(prov%input_files)) call lay%text_attribute(self%file, 'input_files', prov%input_files)
    call lay%text_attribute(self%file, 'shard', prov%shard)
    if (lay%err%failed()) return
    call h5ltset_attribute_int_f(self%file, '.', 'n_cases_total', [int(prov%n_cases_total)], 1_size_t, hdferr)
    call lay%check(hdferr, 'write attribute n_cases_total')
    ! what --overwrite checks before it replaces a file as ellroll's
    call file_identity(self%file, prov%campaign_id, identity)
    if (len(identity) == 0) call lay%check(-1, 'find /summary/status and /summary/checksum')
    call lay%text_attribute(self%file, 'file_identity', identity)
  end subroutine write_provenance

  !> Store one case's inputs, trajectories and summary at its slot icase
  !> (0-based). Trajectories read from another file's store (`moved_from`,
  !> a resume's) are freed there as they are written.
  subroutine write_case(self, icase, cs, res, err, moved_from)
    class(h5_output_t), intent(inout) :: self
    integer(i8), intent(in) :: icase
    type(case_t), intent(in) :: cs
    type(case_result_t), intent(in) :: res
    type(error_t), intent(inout) :: err
    type(trajectory_store_t), intent(inout), optional :: moved_from
    type(window_list_t) :: full
    if (present(moved_from)) then
      call self%in_place%move_in(icase, res, moved_from, err)
    else
      call self%put_trajectories(icase, [res], err)
    end if
    call self%keep_case(icase, self%row(cs, res), res, full)
    call self%write_windows(full, err)
    call self%recycle(full)
  end subroutine write_case

  !> A case's row of this file (file_row), its checksum of what the file
  !> stores of it included. Threads may call this at the same time.
  function case_row(self, cs, res) result(row)
    class(h5_output_t), intent(in) :: self
    type(case_t), intent(in) :: cs
    type(case_result_t), intent(in) :: res
    type(named_value_t), allocatable :: row(:)
    row = file_row(cs, res, case_checksum(res, self%fields, self%n_samples))
  end function case_row

  !> Write the uncompressed trajectories of cases in consecutive slots, from
  !> slot `first` on, in their place in the file (the other fields go with
  !> their windows). Threads may call this at the same time, for different
  !> cases, and beside the writer.
  subroutine put_trajectories(self, first, results, err)
    class(h5_output_t), intent(in) :: self
    integer(i8), intent(in) :: first
    type(case_result_t), intent(in) :: results(:)
    type(error_t), intent(inout) :: err
    call self%in_place%put(first, results, err)
  end subroutine put_trajectories

  !> Rename the open file to `path` (atomically replacing a file there).
  subroutine move_to(self, path, err)
    class(h5_output_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    integer :: code
    code = rename_path(self%path, path)
    if (code /= 0) then
      call set_error(err, err_output, path // ': cannot move ' // self%path // ' there: ' // system_error_text(code))
      return
    end if
    self%path = path
    self%in_place%path = path
  end subroutine move_to

  !> The stored fields whose trajectories go in place, outside HDF5: all of
  !> them, unless they are compressed (deflate level > 0).
  pure function written_in_place(fields, deflate_level)
    logical, intent(in) :: fields(field_count)
    integer, intent(in) :: deflate_level
    logical :: written_in_place(field_count)
    written_in_place = fields .and. deflate_level <= 0
  end function written_in_place

  !> Keep a case (its table row and its trajectories) in its window; a window
  !> complete, or the oldest when all are in use, goes to `full`.
  subroutine keep_case(self, icase, row, res, full)
    class(h5_output_t), intent(inout) :: self
    integer(i8), intent(in) :: icase
    type(named_value_t), intent(in) :: row(:)
    type(case_result_t), intent(in) :: res
    type(window_list_t), intent(inout) :: full
    integer(i8) :: first
    integer :: w, r, f
    if (.not. allocated(self%windows)) allocate (self%windows(max_windows))
    first = (icase / self%window_rows) * self%window_rows
    w = findloc(self%windows%in_use .and. self%windows%first == first, .true., dim=1)
    if (w == 0) then
      w = findloc(self%windows%in_use, .false., dim=1)
      if (w == 0) then                    ! all in use: the oldest goes out as it is
        w = minloc(self%windows%opened, dim=1)
        call take_window(self%windows(w), full)
      end if
      if (.not. allocated(self%windows(w)%present) .and. self%spare%n > 0) then
        call move_window(self%spare%items(self%spare%n), self%windows(w))
        self%spare%n = self%spare%n - 1
      end if
      associate (win => self%windows(w))
        win%in_use = .true.
        win%first = first
        self%windows_opened = self%windows_opened + 1
        win%opened = self%windows_opened
        win%expected = int(min(int(self%window_rows, i8), self%n_cases - first))
        win%filled = 0
        if (.not. allocated(win%present)) then
          allocate (win%present(self%window_rows), win%rows(size(row), self%window_rows))
          do f = 1, field_count
            if (self%in_windows(f)) &
              allocate (win%samples(f)%values(field_ncomp(f) * self%n_samples, self%window_rows))
          end do
        end if
        win%present = .false.
      end associate
    end if
    associate (win => self%windows(w))
      r = int(icase - first) + 1
      if (.not. win%present(r)) win%filled = win%filled + 1
      win%present(r) = .true.
      win%rows(:, r) = row
      do f = 1, field_count
        if (.not. self%in_windows(f)) cycle
        if (allocated(res%fields(f)%values)) then
          call copy_flat(res%fields(f)%values, size(res%fields(f)%values), win%samples(f)%values(:, r))
        else                              ! never integrated (invalid): NaN, as the fill value
          win%samples(f)%values(:, r) = ieee_value(0.0_wp, ieee_quiet_nan)
        end if
      end do
      if (win%filled == win%expected) call take_window(win, full)
    end associate
    call self%switches%keep(icase, res)
  end subroutine keep_case

  !> The values of an array of any shape, in array element order (no temporary).
  subroutine copy_flat(from, n, to)
    integer, intent(in) :: n
    real(wp), intent(in) :: from(n)
    real(wp), intent(out) :: to(n)
    to = from
  end subroutine copy_flat

  !> Move window `win` (its buffers, not a copy) to the end of `list`, and free its slot.
  subroutine take_window(win, list)
    type(row_window_t), intent(inout) :: win
    type(window_list_t), intent(inout) :: list
    type(row_window_t), allocatable :: grown(:)
    integer :: k
    if (.not. allocated(list%items)) allocate (list%items(2))
    if (list%n == size(list%items)) then
      allocate (grown(2 * list%n))
      do k = 1, list%n
        call move_window(list%items(k), grown(k))
      end do
      call move_alloc(grown, list%items)
    end if
    list%n = list%n + 1
    call move_window(win, list%items(list%n))
    win%in_use = .false.
  end subroutine take_window

  subroutine move_window(from, to)
    type(row_window_t), intent(inout) :: from, to
    integer :: f
    to%in_use = from%in_use
    to%first = from%first
    to%opened = from%opened
    to%expected = from%expected
    to%filled = from%filled
    call move_alloc(from%present, to%present)
    call move_alloc(from%rows, to%rows)
    do f = 1, field_count
      call move_alloc(from%samples(f)%values, to%samples(f)%values)
    end do
  end subroutine move_window

  !> Write the windows of `full` (then recycle them).
  subroutine write_windows(self, full, err)
    class(h5_output_t), intent(inout) :: self
    type(window_list_t), intent(in) :: full
    type(error_t), intent(inout) :: err
    integer :: k
    call hdf5_quiet()        ! (any thread of a campaign may write the windows)
    do k = 1, full%n
      call write_window(self, full%items(k), err)
    end do
  end subroutine write_windows

  !> Keep the buffers of written windows for the next windows, and empty
  !> `full`. Freed and allocated again, they page-faulted in each time, and
  !> with a heap per thread (freed by the writing thread into the heap of
  !> the keeping one) fragmented the heaps: peak memory grew with the case
  !> count, 50 -> 135 MiB from 10^3 to 10^5 cases on 16 threads.
  subroutine recycle(self, full)
    class(h5_output_t), intent(inout) :: self
    type(window_list_t), intent(inout) :: full
    integer :: k
    do k = 1, full%n
      if (self%spare%n < max_windows) call take_window(full%items(k), self%spare)
    end do
    full%n = 0
  end subroutine recycle

  !> Write a window: each run of consecutive cases as one hyperslab per dataset.
  subroutine write_window(self, win, err)
    type(h5_output_t), intent(inout) :: self
    type(row_window_t), intent(in) :: win
    type(error_t), intent(inout) :: err
    integer :: first_row, last_row, f
    integer(i8) :: offset, n
    integer(hid_t) :: dset
    last_row = 0
    do while (.not. err%failed())
      first_row = findloc(win%present(last_row + 1:win%expected), .true., dim=1)
      if (first_row == 0) exit
      first_row = last_row + first_row
      last_row = first_row
      do while (last_row < win%expected)
        if (.not. win%present(last_row + 1)) exit
        last_row = last_row + 1
      end do
      offset = win%first + first_row - 1
      n = last_row - first_row + 1
      call write_rows(self, win%rows(:, first_row:last_row), offset, err)
      do f = 1, field_count
        if (.not. self%in_windows(f)) cycle
        if (.not. open_dataset(self, 'trajectory/' // trim(field_names(f)), dset, err)) exit
        if (field_ncomp(f) == 1) then
          call write_real_slab(self%path, dset, win%samples(f)%values(:, first_row:last_row), [0_i8, offset], &
                               [self%n_samples, n], err)
        else
          call write_real_slab(self%path, dset, win%samples(f)%values(:, first_row:last_row), [0_i8, 0_i8, offset], &
                               [3_i8, self%n_samples, n], err)
        end if
      end do
    end do
  end subroutine write_window

  !> Rows of consecutive cases from `offset` on, one hyperslab per dataset.
  subroutine write_rows(self, rows, offset, err)
    type(h5_output_t), intent(inout) :: self
    type(named_value_t), intent(in) :: rows(:, :)
    integer(i8), intent(in) :: offset
    type(error_t), intent(inout) :: err
    integer(hid_t) :: dset
    integer(i8) :: n
    integer(i8), allocatable :: ints(:)
    character(len=len(rows%text)), allocatable :: texts(:)
    integer :: k, ncomp
    n = size(rows, 2, kind=i8)
    allocate (ints(n), texts(n))
    do k = 1, size(rows, 1)
      if (.not. open_dataset(self, trim(self%row_groups(k)) // '/' // trim(rows(k, 1)%name), dset, err)) return
      select case (rows(k, 1)%kind)
      case (kind_real)
        ncomp = rows(k, 1)%ncomp
        if (ncomp == 1) then
          call write_real_slab(self%path, dset, reals_of(1), [offset], [n], err)
        else
          call write_real_slab(self%path, dset, reals_of(ncomp), [0_i8, offset], [int(ncomp, i8), n], err)
        end if
      case (kind_int)        ! (the components copied to contiguous arrays: the slab writers take a buffer)
        ints(:) = rows(k, :)%int
        call write_int_slab(self%path, dset, ints, [offset], [n], err)
      case (kind_text)
        texts(:) = rows(k, :)%text
        call write_text_slab(self%path, dset, texts, offset, err)
      end select
    end do
  contains
    !> The first ncomp components of entry k of every row, row after row.
    pure function reals_of(ncomp) result(values)
      integer, intent(in) :: ncomp
      real(wp) :: values(ncomp * size(rows, 2))
      integer :: j
      do j = 1, size(rows, 2)
        values((j - 1) * ncomp + 1:j * ncomp) = rows(k, j)%reals(:ncomp)
      end do
    end function reals_of
  end subroutine write_rows

  subroutine close_file(self, err)
    class(h5_output_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    integer :: hdferr, k
    character(len=:), allocatable :: reason
    if (self%file < 0) return
    call hdf5_quiet()
    call self%in_place%close(err)
    if (allocated(self%windows)) then          ! rows of incomplete windows (an abandoned run)
      do k = 1, size(self%windows)
        if (self%windows(k)%in_use) call write_window(self, self%windows(k), err)
      end do
      deallocate (self%windows)
    end if
    if (.not. err%failed()) call write_switches(self, err)
    if (allocated(self%open_ids)) then
      do k = 1, size(self%open_ids)
        call h5dclose_f(self%open_ids(k), hdferr)
        if (hdferr < 0 .and. .not. err%failed()) then
          call hdf5_reason(reason)
          call set_error(err, err_output, self%path // ': cannot write /' // trim(self%open_names(k)) // ': ' // reason)
        end if
      end do
      deallocate (self%open_names, self%open_ids)
    end if
    call h5fflush_f(self%file, H5F_SCOPE_GLOBAL_F, hdferr)
    if (hdferr < 0 .and. .not. err%failed()) then
      call hdf5_reason(reason)
      call set_error(err, err_output, self%path // ': cannot write the file''s metadata: ' // reason)
    end if
    call h5fclose_f(self%file, hdferr)
    if (hdferr < 0) call note_failed_close()
    if (hdferr < 0 .and. .not. err%failed()) then
      call hdf5_reason(reason)
      call set_error(err, err_output, self%path // ': cannot close the file: ' // reason)
    end if
    self%file = -1
  end subroutine close_file

  !> /switches, from the switches of every case kept.
  subroutine write_switches(self, err)
    type(h5_output_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    type(layout_t) :: lay
    if (.not. self%switches%active) return
    lay%file = self%file
    lay%path = self%path
    call switch_group(lay, self%switches)
    if (lay%err%failed()) err = lay%err
  end subroutine write_switches

  ! ------------------------------------------------------------ low level

  !> The open dataset `name`, opened on first use and kept open until close.
  logical function open_dataset(self, name, dset, err) result(ok)
    type(h5_output_t), intent(inout) :: self
    character(len=*), intent(in) :: name
    integer(hid_t), intent(out) :: dset
    type(error_t), intent(inout) :: err
    integer :: hdferr, closed, k
    integer(hid_t) :: dapl
    character(len=:), allocatable :: reason
    ok = .false.
    if (err%failed()) return
    if (.not. allocated(self%open_names)) allocate (self%open_names(0), self%open_ids(0))
    do k = 1, size(self%open_names)
      if (self%open_names(k) == name) then
        dset = self%open_ids(k)
        ok = .true.
        return
      end if
    end do
    ! no chunk cache: each window writes whole chunks (one case each) once,
    ! so caching them only adds a copy per chunk
    call h5pcreate_f(H5P_DATASET_ACCESS_F, dapl, hdferr)
    if (hdferr >= 0) call h5pset_chunk_cache_f(dapl, 0_size_t, 0_size_t, 1.0, hdferr)
    if (hdferr >= 0) call h5dopen_f(self%file, name, dset, hdferr, dapl_id=dapl)
    call h5pclose_f(dapl, closed)
    hdferr = min(hdferr, closed)
    if (hdferr < 0) then
      call hdf5_reason(reason)
      call set_error(err, err_output, self%path // ': cannot open dataset /' // name // ': ' // reason)
      return
    end if
    self%open_names = [character(len=64) :: self%open_names, name]
    self%open_ids = [self%open_ids, dset]
    ok = .true.
  end function open_dataset

end module ellroll_hdf5_writer
