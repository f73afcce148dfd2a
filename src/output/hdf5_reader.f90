!> Reading ellroll's HDF5 output back (merge, summary, tests): a thin
!> reader that gives back columns, cases and attributes. Every HDF5 call
!> that reads lives here.
module ellroll_hdf5_reader
  use, intrinsic :: iso_c_binding, only: c_loc, c_ptr, c_char, c_null_char, c_size_t, c_associated, c_f_pointer, c_int, c_int64_t
  use hdf5
  use h5lt
  use h5ds
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: itoa
  use ellroll_errors, only: error_t, set_error, err_input, err_output
  use ellroll_records, only: named_value_t, kind_int
  use ellroll_cases, only: field_count, field_names, field_ncomp, field_descriptions
  use ellroll_campaign, only: max_cases
  use ellroll_results, only: case_result_t, summary_record, set_summary_value
  use ellroll_files, only: path_kind, kind_missing, lock_held, holder_line, resume_advice
  use ellroll_system, only: open_regular_file, file_type_words, close_descriptor
  use ellroll_hdf5_common, only: hdf5_reason, note_failed_close, select_slab, new_text_type, hdf5_quiet, &
      forget_system_failure, system_failure, file_identity
  implicit none
  private

  public :: h5_input_t

  interface
    integer(c_size_t) function c_strlen(s) bind(c, name='strlen')
      import :: c_size_t, c_ptr
      type(c_ptr), value :: s
    end function c_strlen
    integer(c_int) function c_h5free_memory(mem) bind(c, name='H5free_memory')
      import :: c_int, c_ptr
      type(c_ptr), value :: mem
    end function c_h5free_memory
  end interface

  !> Width of the text text_column gives (a record's name is at most 32
  !> characters).
  integer, parameter :: text_column_width = 64

  type :: h5_input_t
    integer(hid_t) :: file = -1
    character(len=:), allocatable :: path
    integer(i8) :: n_cases = 0
    !> open failed on a killed run's work file (HDF5 finds it still marked
    !> open for writing)
    logical :: unfinished = .false.
  contains
    procedure :: open => open_input
    procedure :: read_failed
    procedure :: made_here
    procedure :: close => close_input
    procedure :: has
    procedure :: members
    procedure :: dataset_length
    procedure :: text_attribute
    procedure :: int_attribute
    procedure :: real_column
    procedure :: int_column
    procedure :: text_column
    procedure :: real_rows
    procedure :: read_case_result
    procedure :: read_slab
  end type h5_input_t

contains

  !> Open the ellroll file at path to read. A file that cannot be read (a
  !> system call failed: EIO) is err_output, 'cannot read it', whatever
  !> it holds; one HDF5 finds damaged, or that is not ellroll's, err_input.
  !> Where it fails, nothing of HDF5's is left open.
  subroutine open_input(self, path, err)
    class(h5_input_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    call open_checked(self, path, err)
    if (err%failed()) call self%close()
    ! a file HDF5 met a read error in (H5Fis_hdf5's own open and close
    ! included) may stay in its list of open files, with no id to close
    if (err%code == err_output) call note_failed_close()
  end subroutine open_input

  !> Whether the open file is one ellroll made, not a copy of one by another
  !> program: its root attribute file_identity matches where its objects
  !> lie (hdf5_common's file_identity).
  logical function made_here(self)
    class(h5_input_t), intent(in) :: self
    character(len=:), allocatable :: stored, id, identity
    call self%text_attribute('file_identity', stored)
    call self%text_attribute('campaign_id', id)
    call file_identity(self%file, id, identity)
    made_here = len(stored) > 0 .and. stored == identity
  end function made_here

  subroutine open_checked(self, path, err)
    class(h5_input_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    integer :: hdferr, code, fd
    integer(i8) :: bytes
    character :: file_type
    logical :: is_hdf5
    character(len=:), allocatable :: program, reason, holder
    self%path = path
    call h5open_f(hdferr)
    call hdf5_quiet()
    call forget_system_failure()
    if (path_kind(path) == kind_missing) then
      if (path_kind(path // '.partial') == kind_missing) then
        call set_error(err, err_input, path // ': no such file')
      else if (lock_held(lock_of(path), holder)) then
        call holder_line(holder)
        call set_error(err, err_input, path // ': not there yet: a running ellroll writes it (' // holder // &
            ', holding ' // lock_of(path) // ') into ' // path // '.partial; read it when that run ends')
      else
        call resume_advice(path, holder, reason)
        call set_error(err, err_input, path // ': not there: ' // path // ".partial is its unfinished run's " // &
            'work file; ' // reason // ', then read ' // path)
      end if
      return
    end if
    ! (HDF5 would open a FIFO and wait for a writer, past SIGTERM, or read a
    ! device that may never end)
    code = open_regular_file(path, fd, bytes, file_type)
    if (code == -1) then
      call set_error(err, err_input, path // ': ' // trim(file_type_words(file_type)) // ', not a regular file')
      return
    end if
    if (code == 0) code = close_descriptor(fd)
    call h5fis_hdf5_f(path, is_hdf5, hdferr)
    if (hdferr < 0) then
      call hdf5_reason(reason)
      call set_error(err, err_output, path // ': cannot read it: ' // reason)
      return
    else if (.not. is_hdf5) then
      if (read_failed(self, err)) return
      if (len(path) > 8) then
        if (path(len(path) - 7:) == '.journal') then
          if (begins_as_journal(path)) then
            call say_journal(path(:len(path) - 8), err)
            return
          end if
        end if
      end if
      call set_error(err, err_input, path // ': not an HDF5 file')
      return
    end if
    call h5fopen_f(path, H5F_ACC_RDONLY_F, self%file, hdferr)
    if (hdferr < 0) then
      call hdf5_reason(reason)
      if (index(reason, 'temporarily unavailable') > 0 .or. index(reason, 'already open for write') > 0) then
        ! (HDF5's flock: EAGAIN, another process has it open to write; with its
        ! flock off, HDF5_USE_FILE_LOCKING=FALSE, the writer's mark in the file)
        if (lock_held(lock_of(path), holder)) then
          call holder_line(holder)        ! (the output's own lock names the run)
          call set_error(err, err_output, path // ': a running ellroll writes it (' // holder // &
              ', holding ' // lock_of(path) // '); read it when that run ends')
        else if (index(reason, 'temporarily unavailable') > 0) then
          call set_error(err, err_output, path // ': cannot open the HDF5 file: another process has it open to ' // &
              'write (' // reason // '); read it when that process ends')
        else
          ! (no process has it open: its writer stopped before closing it)
          self%unfinished = .true.
          call resume_advice(path(:len(path) - trimmed(path)), holder, reason)
          call set_error(err, err_output, path // ": an unfinished run's work file (its run stopped before it " // &
              "closed the file: killed?); " // reason // ', then read ' // path(:len(path) - trimmed(path)) // &
              '; do not h5clear it')
        end if
      else if (index(reason, 'HDF5: ') /= 1) then      ! the system's reason
        call set_error(err, err_output, path // ': cannot open the HDF5 file: ' // reason)
      else                      ! HDF5's own tables do not hold together (a file cut short)
        call set_error(err, err_input, path // ': damaged: HDF5 cannot open it (' // reason(7:) // ')')
      end if
      return
    end if
    call self%text_attribute('program', program)
    if (program /= 'ellroll') then
      if (.not. read_failed(self, err)) call set_error(err, err_input, path // ': not an ellroll file')
      return
    end if
    self%n_cases = self%dataset_length('summary/status')
    if (read_failed(self, err)) return
    if (self%n_cases > max_cases) then     ! (its tables would be read whole: gigabytes of rows no run wrote)
      call set_error(err, err_input, path // ': not laid out as ellroll writes its files (/summary/status holds ' // &
                     itoa(self%n_cases) // ' rows, more than the ' // itoa(max_cases) // &
                     ' cases of any campaign; changed by another program?)')
      self%n_cases = 0
    end if
  end subroutine open_checked

  !> Whether an HDF5 call failed in a system call (a read error) since
  !> the file was opened: err then says the file cannot be read, and why.
  logical function read_failed(self, err)
    class(h5_input_t), intent(in) :: self
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: words, file
    read_failed = system_failure(words, file)
    if (read_failed) call set_error(err, err_output, self%path // ': cannot read it: ' // words)
  end function read_failed

  subroutine close_input(self)
    class(h5_input_t), intent(inout) :: self
    integer :: hdferr
    if (self%file < 0) return
    call h5fclose_f(self%file, hdferr)
    if (hdferr < 0) call note_failed_close()       ! (a file only read: nothing is lost)
    self%file = -1
  end subroutine close_input

  logical function has(self, name)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    integer :: hdferr
    call h5lexists_f(self%file, name, has, hdferr)
    if (hdferr < 0) has = .false.
  end function has

  !> The names of the members of a group, in their creation order (none
  !> where it is absent).
  subroutine members(self, group, names)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: group
    character(len=64), allocatable, intent(out) :: names(:)
    integer(hid_t) :: gid
    integer :: hdferr, storage, n_links, max_order, k
    integer(size_t) :: length
    allocate (names(0))
    if (.not. self%has(group)) return
    call h5gopen_f(self%file, group, gid, hdferr)
    if (hdferr < 0) return
    call h5gget_info_f(gid, storage, n_links, max_order, hdferr)
    if (hdferr >= 0) then
      deallocate (names)
      allocate (names(n_links))
      names = ''
      do k = 1, n_links
        call h5lget_name_by_idx_f(gid, '.', H5_INDEX_CRT_ORDER_F, H5_ITER_INC_F, int(k - 1, hsize_t), names(k), &
                                  hdferr, length)
        if (hdferr < 0) names(k) = ''
      end do
    end if
    call h5gclose_f(gid, hdferr)
  end subroutine members

  integer(i8) function dataset_length(self, name) result(n)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    integer(hid_t) :: dset, space
    integer(hsize_t) :: dims(3), max_dims(3)
    integer :: hdferr, rank
    n = 0
    call h5dopen_f(self%file, name, dset, hdferr)
    if (hdferr < 0) return
    call h5dget_space_f(dset, space, hdferr)
    call h5sget_simple_extent_ndims_f(space, rank, hdferr)
    call h5sget_simple_extent_dims_f(space, dims(:rank), max_dims(:rank), hdferr)
    n = dims(rank)                     ! the case (slowest, C order) dimension
    call h5sclose_f(space, hdferr)
    call h5dclose_f(dset, hdferr)
  end function dataset_length

  !> An attribute written as a variable-length string, of the root or of
  !> the dataset `object` ('' when absent).
  subroutine text_attribute(self, name, text, object)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(out) :: text
    character(len=*), intent(in), optional :: object
    character(len=:), allocatable :: owner
    integer(hid_t) :: attr, text_type
    type(c_ptr), target :: pointer(1)
    type(c_ptr) :: address
    character(kind=c_char), pointer :: chars(:)
    integer :: hdferr, n, k
    logical :: exists
    text = ''
    owner = '.'
    if (present(object)) owner = object
    if (.not. self%has(owner) .and. owner /= '.') return
    call h5aexists_by_name_f(self%file, owner, name, exists, hdferr)
    if (hdferr < 0 .or. .not. exists) return
    call h5aopen_by_name_f(self%file, owner, name, attr, hdferr)
    text_type = new_text_type()
    address = c_loc(pointer)
    call h5aread_f(attr, text_type, address, hdferr)
    if (hdferr >= 0 .and. c_associated(pointer(1))) then
      n = int(c_strlen(pointer(1)))
      call c_f_pointer(pointer(1), chars, [n])
      text = repeat(' ', n)
      do k = 1, n
        text(k:k) = chars(k)
      end do
      hdferr = c_h5free_memory(pointer(1))     ! the string HDF5 allocated
    end if
    call h5tclose_f(text_type, hdferr)
    call h5aclose_f(attr, hdferr)
  end subroutine text_attribute

  !> A root attribute written as one integer (-1 when absent or unreadable).
  integer function int_attribute(self, name) result(value)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    integer :: found(1), hdferr
    logical :: exists
    value = -1
    call h5aexists_by_name_f(self%file, '.', name, exists, hdferr)
    if (hdferr < 0 .or. .not. exists) return
    call h5ltget_attribute_int_f(self%file, '.', name, found, hdferr)
    if (hdferr >= 0) value = found(1)
  end function int_attribute

  !> A whole 1-D real dataset (e.g. one value per case).
  function real_column(self, name, err) result(values)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    type(error_t), intent(inout) :: err
    real(wp), allocatable, target :: values(:)
    allocate (values(column_rows(self, name, err)))
    values = ieee_value(0.0_wp, ieee_quiet_nan)
    call self%read_slab(name, H5T_NATIVE_DOUBLE, c_loc(values), [0_i8], [size(values, kind=i8)], err)
  end function real_column

  !> A whole dataset of `ncomp` values per case, as (ncomp, case).
  function real_rows(self, name, ncomp, err) result(values)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: ncomp
    type(error_t), intent(inout) :: err
    real(wp), allocatable, target :: values(:, :)
    allocate (values(ncomp, column_rows(self, name, err)))
    values = ieee_value(0.0_wp, ieee_quiet_nan)
    call self%read_slab(name, H5T_NATIVE_DOUBLE, c_loc(values), [0_i8, 0_i8], &
                        [int(ncomp, i8), size(values, 2, kind=i8)], err)
  end function real_rows

  !> A whole 1-D dataset of per-case text (variable-length strings), blank
  !> padded; a string never written (a null pointer) is blank.
  function text_column(self, name, err) result(values)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    type(error_t), intent(inout) :: err
    character(len=text_column_width), allocatable :: values(:)
    type(c_ptr), allocatable, target :: pointers(:)
    character(kind=c_char), pointer :: chars(:)
    integer(hid_t) :: text_type
    integer :: hdferr, k, n
    allocate (values(column_rows(self, name, err)))
    allocate (pointers(size(values)))
    values = ''
    text_type = new_text_type()
    call self%read_slab(name, text_type, c_loc(pointers), [0_i8], [size(values, kind=i8)], err)
    call h5tclose_f(text_type, hdferr)
    if (err%failed()) return
    do k = 1, size(values)
      if (.not. c_associated(pointers(k))) cycle
      n = int(c_strlen(pointers(k)))
      call c_f_pointer(pointers(k), chars, [n])
      values(k) = transfer(chars(:min(n, text_column_width)), values(k)(:min(n, text_column_width)))
      hdferr = c_h5free_memory(pointers(k))     ! the string HDF5 allocated
    end do
  end function text_column

  function int_column(self, name, err) result(values)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    type(error_t), intent(inout) :: err
    integer(i8), allocatable, target :: values(:)
    allocate (values(column_rows(self, name, err)))
    values = 0
    call self%read_slab(name, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(values), [0_i8], &
                        [size(values, kind=i8)], err)
  end function int_column

  !> The rows to read of dataset `name`: its length along the case
  !> dimension. A table of one row per case (under summary/, case/ or
  !> limit_state/) that holds another number of rows than /summary/status
  !> (n_cases) is a file changed by another program: err says so, naming
  !> it, and the rows are n_cases, none read (so that no caller reads or
  !> writes past the rows it expects).
  integer(i8) function column_rows(self, name, err) result(rows)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    type(error_t), intent(inout) :: err
    integer(i8) :: rows_read
    rows = self%dataset_length(name)
    if (rows == self%n_cases) return
    if (index(name, 'summary/') /= 1 .and. index(name, 'case/') /= 1 .and. index(name, 'limit_state/') /= 1) return
    rows_read = rows
    rows = self%n_cases
    if (err%failed()) return
    if (read_failed(self, err)) return        ! (a length a read error left unread is no verdict on the file)
    call set_error(err, err_input, self%path // ': not laid out as ellroll writes its files (/' // name // &
        ' holds ' // itoa(rows_read) // ' rows, /summary/status ' // itoa(self%n_cases) // '; changed by another program?)')
  end function column_rows

  !> Everything stored about the case in slot `slot` (0-based): its status,
  !> summary and the trajectories present in the file.
  subroutine read_case_result(self, slot, n_samples, res, err)
    class(h5_input_t), intent(in) :: self
    integer(i8), intent(in) :: slot, n_samples
    type(case_result_t), intent(out), target :: res
    type(error_t), intent(inout) :: err
    type(named_value_t), allocatable :: rec(:)
    integer(i8), target :: int_buffer(1)
    real(wp), target :: real_buffer(3)
    integer :: k, f
    call self%read_slab('summary/status', h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(int_buffer), &
                        [slot], [1_i8], err)
    res%status = int(int_buffer(1))
    rec = summary_record(res)
    do k = 1, size(rec)
      if (.not. self%has('summary/' // trim(rec(k)%name))) cycle   ! a file of another version may lack it: NaN, 0
      if (rec(k)%kind == kind_int) then
        call self%read_slab('summary/' // trim(rec(k)%name), h5kind_to_type(i8, H5_INTEGER_KIND), &
                            c_loc(int_buffer), [slot], [1_i8], err)
        rec(k)%int = int_buffer(1)
      else
        if (rec(k)%ncomp == 1) then
          call self%read_slab('summary/' // trim(rec(k)%name), H5T_NATIVE_DOUBLE, c_loc(real_buffer), &
                              [slot], [1_i8], err)
        else
          call self%read_slab('summary/' // trim(rec(k)%name), H5T_NATIVE_DOUBLE, c_loc(real_buffer), &
                              [0_i8, slot], [int(rec(k)%ncomp, i8), 1_i8], err)
        end if
        rec(k)%reals = real_buffer
      end if
      call set_summary_value(res, k, rec(k))
    end do
    do f = 1, field_count
      if (.not. self%has('trajectory/' // trim(field_names(f)))) cycle
      allocate (res%fields(f)%values(field_ncomp(f), n_samples))
      if (field_ncomp(f) == 1) then
        call self%read_slab('trajectory/' // trim(field_names(f)), H5T_NATIVE_DOUBLE, &
                            c_loc(res%fields(f)%values), [0_i8, slot], [n_samples, 1_i8], err)
      else
        call self%read_slab('trajectory/' // trim(field_names(f)), H5T_NATIVE_DOUBLE, &
                            c_loc(res%fields(f)%values), [0_i8, 0_i8, slot], [3_i8, n_samples, 1_i8], err)
      end if
    end do
  end subroutine read_case_result

  subroutine read_slab(self, name, mem_type, buffer, offset, counts, err)
    class(h5_input_t), intent(in) :: self
    character(len=*), intent(in) :: name
    integer(hid_t), intent(in) :: mem_type
    type(c_ptr), intent(in) :: buffer
    integer(i8), intent(in) :: offset(:), counts(:)
    type(error_t), intent(inout) :: err
    integer(hid_t) :: dset, file_space, mem_space
    integer :: hdferr
    type(c_ptr) :: target_buffer
    if (err%failed()) return
    call h5dopen_f(self%file, name, dset, hdferr)
    if (hdferr < 0) then
      ! (a read error on the way is the file's, not a dataset missing)
      if (.not. self%read_failed(err)) call set_error(err, err_input, self%path // ': no dataset /' // name)
      return
    end if
    call select_slab(dset, offset, counts, file_space, mem_space, hdferr)
    target_buffer = buffer
    if (hdferr >= 0) call h5dread_f(dset, mem_type, target_buffer, hdferr, mem_space_id=mem_space, &
                                    file_space_id=file_space)
    if (hdferr < 0) then
      if (.not. self%read_failed(err)) call set_error(err, err_input, self%path // ': cannot read /' // name)
    end if
    call h5sclose_f(file_space, hdferr)
    call h5sclose_f(mem_space, hdferr)
    call h5dclose_f(dset, hdferr)
  end subroutine read_slab

  !> The characters of path's suffix '.partial' or '.partial.new' (0: none).
  pure integer function trimmed(path)
    character(len=*), intent(in) :: path
    trimmed = 0
    if (len(path) > 12) then
      if (path(len(path) - 11:) == '.partial.new') trimmed = 12
    end if
    if (trimmed == 0 .and. len(path) > 8) then
      if (path(len(path) - 7:) == '.partial') trimmed = 8
    end if
  end function trimmed

  !> Whether the regular file at path begins as ellroll's journals do.
  logical function begins_as_journal(path)
    character(len=*), intent(in) :: path
    character(len=7) :: head
    integer :: unit, code
    begins_as_journal = .false.
    open (newunit=unit, file=path, access='stream', form='unformatted', action='read', status='old', iostat=code)
    if (code /= 0) return
    read (unit, iostat=code) head
    begins_as_journal = code == 0 .and. head == 'ELLROLL'
    close (unit, iostat=code)          ! (a file only read: nothing is lost)
  end function begins_as_journal

  !> OUT.journal, the cases a run of `output` has finished (in the journal's
  !> own format), read as an output: err says what to read instead.
  subroutine say_journal(output, err)
    character(len=*), intent(in) :: output
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: holder, reason
    if (lock_held(output // '.lock', holder)) then
      call holder_line(holder)
      call set_error(err, err_input, output // ".journal: ellroll's journal of a running ellroll (" // holder // &
          ', holding ' // output // '.lock: the cases it finished), not an output file; read ' // output // &
          ' when that run ends')
    else
      call resume_advice(output, holder, reason)
      call set_error(err, err_input, output // ".journal: ellroll's journal of an unfinished run (the cases it " // &
          'finished, for --resume), not an output file; ' // reason // ', then read ' // output)
    end if
  end subroutine say_journal

  !> The lock file of the output whose file (OUT, OUT.partial or
  !> OUT.partial.new) is at path: OUT.lock.
  pure function lock_of(path) result(lock)
    character(len=*), intent(in) :: path
    character(len=len(path) - trimmed(path) + 5) :: lock
    lock = path(:len(path) - trimmed(path)) // '.lock'
  end function lock_of
end module ellroll_hdf5_reader
