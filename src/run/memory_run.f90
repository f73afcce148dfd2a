!> Running a campaign into memory instead of a file: the input from its
!> text, its cases integrated as `ellroll run` integrates them (the same
!> blocks and batches, so the results are bitwise the file's), and the
!> results laid out as the file's datasets (ellroll_file_layout): the root's
!> scales, /case, /trajectory and /summary, each dataset with its units,
!> long name, dimensions and attributes, which the C interface (src/capi)
!> hands out. No file is read but the records the input names; nothing is
!> written or printed; every call keeps its state in its own memory_output_t
!> (calls may run at the same time).
module ellroll_memory_run
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  !$ use omp_lib, only: omp_get_max_threads, omp_set_num_threads
  use ellroll_kinds, only: wp, i8
  use ellroll_threads, only: team_size
  use ellroll_errors, only: error_t, set_error, err_interrupted
  use ellroll_system, only: stop_signal, signal_name
  use ellroll_strings, only: itoa
  use ellroll_status, only: status_invalid, status_count
  use ellroll_records, only: named_value_t, kind_real, kind_int, kind_text
  use ellroll_cases, only: case_t, field_count, field_names, field_units, field_ncomp, field_descriptions
  use ellroll_results, only: case_result_t, field_buffer_t, count_undefined
  use ellroll_figures, only: figure_count
  use ellroll_campaign, only: coordinate_t
  use ellroll_params, only: params, param_count, param_dataset
  use ellroll_input, only: run_input_t, read_input_text
  use ellroll_invalid_cases, only: find_invalid_cases, refuse_invalid_cases
  use ellroll_results_room, only: check_room
  use ellroll_record_store, only: release_records
  use ellroll_shards, only: campaign_id
  use ellroll_switch_store, only: switch_store_t, switch_flag_meanings
  use ellroll_block_run, only: simulate_block, uses_batches, lanes
  use ellroll_case_checksum, only: case_checksum
  use ellroll_file_layout, only: time_entry, xyz_entry, mode_entry, case_entry, status_entry, checksum_entry, file_title, &
      file_references, table_row, status_flag_meanings
  implicit none
  private

  public :: memory_output_t, memory_dataset_t, run_in_memory, text_width, tab, newline, field_end, record_end

  !> characters of a text value (a named_value_t's text)
  type(named_value_t), parameter :: blank_value = named_value_t()
  integer, parameter :: text_width = len(blank_value%text)
  character, parameter :: tab = achar(9), newline = achar(10)
  !> ASCII's unit and record separators, which no name or attribute holds
  character, parameter :: field_end = achar(31), record_end = achar(30)

  !> One dataset as the file holds it, in memory. Shapes and dimensions are
  !> as h5py and numpy show them (C order: the case first), the reverse of
  !> Fortran's; the values are in Fortran's order, which is the same memory.
  type :: memory_dataset_t
    character(len=16) :: group = ''          !< '' (the root), 'case', 'trajectory' or 'summary'
    character(len=32) :: name = ''
    character(len=16) :: units = ''
    character(len=160) :: long_name = ''
    integer :: kind = kind_real
    integer :: ndim = 1
    integer(i8) :: shape(3) = 0
    character(len=8) :: dims(3) = ''
    !> other attributes, a line 'NAME<tab>TYPE<tab>VALUE' each (TYPE: str,
    !> or i4 / i8 for a list of 4- / 8-byte integers)
    character(len=:), allocatable :: attributes
    integer :: field = 0                     !< a trajectory: its field, read from the cases' results
    logical :: taken = .false.               !< its values taken out (ellroll_take): nothing to read
    real(wp), allocatable :: reals(:)
    integer(i8), allocatable :: ints(:)
    character(len=text_width), allocatable :: texts(:)
  end type memory_dataset_t

  type :: memory_output_t
    type(error_t) :: err
    integer :: n = 0                         !< datasets
    type(memory_dataset_t), allocatable :: datasets(:)
    type(case_result_t), allocatable :: results(:)   !< by case index (their trajectories)
    integer(i8) :: n_samples = 0
    character(len=:), allocatable :: attributes      !< the root's, as a dataset's
    !> every dataset's description in one text (write_catalog)
    character(len=:), allocatable :: catalog
  contains
    procedure :: read_reals
  end type memory_output_t

contains

  !> Read the input from its text (label: its name in messages, and the
  !> folder its record files are relative to), run every case on `threads`
  !> threads (0: OMP_NUM_THREADS or all cores) and lay the results out.
  !> A bad input or a failed case leaves out%err set and no datasets.
  subroutine run_in_memory(label, text, threads, out)
    character(len=*), intent(in) :: label, text
    integer, intent(in) :: threads
    type(memory_output_t), intent(inout) :: out
    type(run_input_t) :: inp
    integer :: default_threads
    ! every parallel loop of the run on `threads` threads, as `ellroll run
    ! --threads` sets it (for the calling thread only; put back at the end)
    default_threads = 0
    !$ default_threads = omp_get_max_threads()
    !$ call omp_set_num_threads(team_size(threads, huge(1_i8)))
    ! (no file written: the plan needs no &output file; the records read are
    ! given back after the run, as the library runs many inputs)
    call read_input_text(label, text, '(memory)', inp, out%err)
    if (.not. out%err%failed()) call run_input(label, threads, inp, out)
    call release_records(inp%campaign%record_places())
    !$ call omp_set_num_threads(default_threads)
  end subroutine run_in_memory

  subroutine run_input(label, threads, inp, out)
    character(len=*), intent(in) :: label
    integer, intent(in) :: threads
    type(run_input_t), intent(in) :: inp
    type(memory_output_t), intent(inout) :: out
    logical, allocatable :: invalid(:)
    character(len=:), allocatable :: messages
    integer(i8) :: i, n_cases
    integer :: sig
    call find_invalid_cases(inp, invalid, messages)
    call refuse_invalid_cases(inp, invalid, messages, out%err)
    if (out%err%failed()) return
    n_cases = inp%campaign%n_cases()
    call check_room(label, inp, n_cases, out%err)
    if (out%err%failed()) return
    allocate (out%results(0:n_cases - 1))
    do i = 0, n_cases - 1
      if (invalid(i)) out%results(i)%status = status_invalid
    end do
    call run_cases(inp, invalid, threads, out)
    ! asked to stop (ellroll_stop): cases were cut short or never run
    sig = stop_signal()
    if (sig /= 0 .and. .not. out%err%failed()) &
      call set_error(out%err, err_interrupted + sig, 'interrupted by ' // signal_name(sig))
    if (out%err%failed()) then
      deallocate (out%results)
      return
    end if
    call lay_out(inp, out)
  end subroutine run_input

  !> Every valid case, in the blocks `ellroll run` makes of them (run_campaign).
  subroutine run_cases(inp, invalid, threads, out)
    type(run_input_t), intent(in) :: inp
    logical, intent(in) :: invalid(0:)
    integer, intent(in) :: threads
    type(memory_output_t), intent(inout) :: out
    integer(i8) :: n_cases, block_slots, chunk
    integer :: n_threads, failed
    logical :: use_batches
    n_cases = inp%campaign%n_cases()
    n_threads = team_size(threads, n_cases)
    use_batches = uses_batches(inp%campaign)
    block_slots = lanes
    if (.not. use_batches) block_slots = max(1_i8, min(int(lanes, i8), n_cases / (4_i8 * n_threads)))
    failed = 0
    ! (no more threads than blocks: a single case runs on this thread alone)
    n_threads = int(min(int(n_threads, i8), (n_cases - 1) / block_slots + 1))
    !$omp parallel do schedule(dynamic, 1) num_threads(n_threads) default(shared) private(chunk)
    do chunk = 0, (n_cases - 1) / block_slots
      if (.not. loop_failed()) then
        if (stop_signal() == 0) call run_block(chunk)
      end if
    end do
    !$omp end parallel do
  contains
    subroutine run_block(chunk)
      integer(i8), intent(in) :: chunk
      type(case_t) :: cases(lanes)
      type(case_result_t) :: results(lanes)
      type(field_buffer_t) :: moved(field_count)
      type(error_t) :: case_err
      integer(i8) :: slots(lanes), slot
      integer :: n, n_done, j, f
      n = 0
      do slot = chunk * block_slots, min(n_cases, (chunk + 1) * block_slots) - 1
        if (invalid(slot)) cycle
        n = n + 1
        slots(n) = slot
        cases(n) = inp%campaign%case_at(slot)
      end do
      if (n == 0) return
      call simulate_block(cases(:n), use_batches, inp%plan, results(:n), n_done, case_err)
      ! each result to its case, its trajectories moved rather than copied
      do j = 1, n_done
        do f = 1, field_count
          call move_alloc(results(j)%fields(f)%values, moved(f)%values)
        end do
        out%results(slots(j)) = results(j)
        do f = 1, field_count
          call move_alloc(moved(f)%values, out%results(slots(j))%fields(f)%values)
        end do
      end do
      if (case_err%failed()) then
        !$omp critical (ellroll_memory_first_error)
        if (.not. out%err%failed()) out%err = case_err
        !$omp end critical (ellroll_memory_first_error)
        !$omp atomic write
        failed = 1
      end if
    end subroutine run_block

    logical function loop_failed()
      integer :: flag
      !$omp atomic read
      flag = failed
      loop_failed = flag /= 0
    end function loop_failed
  end subroutine run_cases

  !> The datasets of the file, in the order the file makes them.
  subroutine lay_out(inp, out)
    type(run_input_t), intent(in) :: inp
    type(memory_output_t), intent(inout) :: out
    type(named_value_t), allocatable :: row(:)
    type(coordinate_t), allocatable :: coords(:)
    integer(i8), allocatable :: indices(:)
    integer, allocatable :: where(:)          !< the dataset of each entry of a row
    character(len=:), allocatable :: coordinate_names, meanings, input_names
    character(len=len(params%name)) :: row_datasets(param_count)
    integer(i8) :: i, n_cases, n_samples
    integer :: k, p, f, d, n_case_entries
    n_cases = inp%campaign%n_cases()
    n_samples = inp%plan%n_samples
    out%n_samples = n_samples
    allocate (indices(n_cases))
    do i = 1, n_cases
      indices(i) = i - 1
    end do
    coords = inp%campaign%coordinates(indices)
    ! a row: the case's inputs (/case), its figures and its status
    ! (/summary); the first case's, which fill_columns takes as it is
    ! (every row has the same entries)
    if (n_cases > 0) then
      allocate (row, source=table_row(inp%campaign%case_at(0_i8), out%results(0)))
    else
      allocate (row, source=table_row(inp%campaign%base, case_result_t()))
    end if
    n_case_entries = size(row) - figure_count - 1
    ! the root's 3 scales; /case: its scale and inputs; /trajectory: its
    ! scale, the coordinates and the fields; /summary: its scale, the
    ! coordinates, the status, the checksum and the figures
    allocate (out%datasets(3 + n_case_entries + 1 + 1 + size(coords) + count(inp%plan%fields) + 1 + size(coords) + &
                           (size(row) - n_case_entries) + 1))
    out%n = 0
    coordinate_names = ''
    do k = 1, size(coords)
      coordinate_names = coordinate_names // ' ' // trim(coords(k)%name)
    end do
    coordinate_names = adjustl(coordinate_names)

    call lay_out_root(inp, out, n_cases, n_samples)

    allocate (where(size(row)))

    ! /case: the resolved inputs, each with the names of the inputs it holds
    ! (ellroll_params' dataset_inputs, from a table of every row's dataset
    ! made once: a search of the parameter table per dataset costs more
    ! than the rest of the lay-out)
    row_datasets = [(param_dataset(k), k = 1, param_count)]
    call case_scale(out, 'case', indices)
    do k = 1, n_case_entries
      where(k) = add_entry(out, 'case', row(k), n_cases)
      input_names = ''
      do p = 1, param_count
        if (row_datasets(p) == row(k)%name) input_names = input_names // ' ' // trim(params(p)%name)
      end do
      if (len(input_names) > 0) call add_attribute(out%datasets(where(k)), 'input_names', input_names(2:))
    end do
    ! /trajectory: the stored fields
    call case_scale(out, 'trajectory', indices)
    call coordinate_datasets(out, 'trajectory', coords, n_cases)
    do f = 1, field_count
      if (.not. inp%plan%fields(f)) cycle
      if (field_ncomp(f) == 1) then
        d = add(out, 'trajectory', named_value_t(field_names(f), field_units(f), field_descriptions(f)), kind_real, &
                [character(len=8) :: 'case', 'time'], [n_cases, n_samples])
      else
        d = add(out, 'trajectory', named_value_t(field_names(f), field_units(f), field_descriptions(f)), kind_real, &
                [character(len=8) :: 'case', 'time', 'xyz'], [n_cases, n_samples, 3_i8])
      end if
      out%datasets(d)%field = f
      call name_coordinates(out%datasets(d), coordinate_names)
    end do
    ! /summary: the status, then the figures
    call case_scale(out, 'summary', indices)
    call coordinate_datasets(out, 'summary', coords, n_cases)
    where(size(row)) = add(out, 'summary', status_entry, kind_int, ['case'], [n_cases])
    call status_flag_meanings(meanings)
    call add_attribute(out%datasets(where(size(row))), 'flag_values', &
                       int_list([(int(k, i8), k = 0, status_count - 1)]), 'i8')
    call add_attribute(out%datasets(where(size(row))), 'flag_meanings', meanings)
    call name_coordinates(out%datasets(where(size(row))), coordinate_names)
    call checksum_dataset(inp, out, coordinate_names)
    do k = n_case_entries + 1, size(row) - 1
      where(k) = add_entry(out, 'summary', row(k), n_cases)
      ! as the file has it: an integer figure undefined for a case is -1
      if (row(k)%kind == kind_int) &
        call add_attribute(out%datasets(where(k)), '_FillValue', int_list([count_undefined]), 'i8')
      call name_coordinates(out%datasets(where(k)), coordinate_names)
    end do

    call fill_columns(inp, out, row, where)
    if (inp%campaign%base%slide) call switch_datasets(out, indices)
    call write_catalog(out)
  end subroutine lay_out

  !> /summary/checksum, as the file holds it: each case's checksum of what
  !> the file would store of it (ellroll_case_checksum).
  subroutine checksum_dataset(inp, out, coordinate_names)
    type(run_input_t), intent(in) :: inp
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: coordinate_names
    integer(i8) :: i, n_cases
    integer :: d
    n_cases = inp%campaign%n_cases()
    d = add(out, 'summary', checksum_entry, kind_int, ['case'], [n_cases])
    out%datasets(d)%ints = [(case_checksum(out%results(i), inp%plan%fields, inp%plan%n_samples), i = 0, n_cases - 1)]
    call add_attribute(out%datasets(d), '_FillValue', int_list([-1_i8]), 'i8')
    call name_coordinates(out%datasets(d), coordinate_names)
  end subroutine checksum_dataset

  !> /switches of a campaign that may slide, as the file holds it.
  subroutine switch_datasets(out, indices)
    type(memory_output_t), intent(inout) :: out
    integer(i8), intent(in) :: indices(:)
    type(switch_store_t) :: store
    integer(i8), allocatable :: first(:), count(:), kinds(:)
    real(wp), allocatable :: times(:)
    integer(i8) :: k, n
    integer :: d
    call store%start(indices)
    do k = 0, size(indices, kind=i8) - 1
      call store%keep(k, out%results(k))
    end do
    call store%ragged(first, count, times, kinds)
    n = size(times, kind=i8)
    call case_scale(out, 'switches', indices)
    d = add(out, 'switches', named_value_t('switch', '1', 'index of the switch'), kind_int, &
            ['switch'], [n])
    out%datasets(d)%ints = [(k, k = 0, n - 1)]
    d = add(out, 'switches', named_value_t('switch_time', 's', 'time of the switch of regime'), kind_real, &
            ['switch'], [n])
    out%datasets(d)%reals = times
    d = add(out, 'switches', named_value_t('switch_kind', '1', 'kind of the switch of regime'), kind_int, &
            ['switch'], [n])
    out%datasets(d)%ints = kinds
    call add_attribute(out%datasets(d), 'flag_values', int_list([1_i8, 2_i8]), 'i8')
    call add_attribute(out%datasets(d), 'flag_meanings', switch_flag_meanings)
    d = add(out, 'switches', named_value_t('first', '1', 'index of the case''s first switch'), &
            kind_int, ['case'], [size(indices, kind=i8)])
    out%datasets(d)%ints = first
    call add_attribute(out%datasets(d), '_FillValue', int_list([count_undefined]), 'i8')
    d = add(out, 'switches', named_value_t('count', '1', 'switches of regime of the case'), kind_int, ['case'], &
            [size(indices, kind=i8)])
    out%datasets(d)%ints = count
    call add_attribute(out%datasets(d), '_FillValue', int_list([count_undefined]), 'i8')
  end subroutine switch_datasets

  !> A /case or /summary entry of a row as a dataset of `group`: one value,
  !> one per mode or an xyz vector per case.
  integer function add_entry(out, group, entry, n_cases) result(d)
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: group
    type(named_value_t), intent(in) :: entry
    integer(i8), intent(in) :: n_cases
    select case (entry%ncomp)
    case (1)
      d = add(out, group, entry, entry%kind, ['case'], [n_cases])
    case (2)
      d = add(out, group, entry, entry%kind, [character(len=8) :: 'case', 'mode'], [n_cases, 2_i8])
    case default
      d = add(out, group, entry, entry%kind, [character(len=8) :: 'case', 'xyz'], [n_cases, 3_i8])
    end select
  end function add_entry

  !> A group's case scale (the cases' indices).
  subroutine case_scale(out, group, indices)
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: group
    integer(i8), intent(in) :: indices(:)
    integer :: d
    d = add(out, group, case_entry, kind_int, ['case'], [size(indices, kind=i8)])
    out%datasets(d)%ints = indices
  end subroutine case_scale

  !> A group's datasets of the campaign's coordinates (a swept input's
  !> value, or a suite's record name, per case).
  subroutine coordinate_datasets(out, group, coords, n_cases)
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: group
    type(coordinate_t), intent(in) :: coords(:)
    integer(i8), intent(in) :: n_cases
    integer :: c, d
    do c = 1, size(coords)
      if (allocated(coords(c)%values)) then
        d = add(out, group, named_value_t(coords(c)%name, coords(c)%unit, coords(c)%description), kind_real, &
                ['case'], [n_cases])
        out%datasets(d)%reals = coords(c)%values
      else
        d = add(out, group, named_value_t(coords(c)%name, '1', coords(c)%description), kind_text, ['case'], &
                [n_cases])
        allocate (out%datasets(d)%texts(n_cases))
        out%datasets(d)%texts(:) = coords(c)%texts
      end if
    end do
  end subroutine coordinate_datasets

  !> The CF attribute naming a dataset's auxiliary coordinates, if any.
  subroutine name_coordinates(ds, coordinate_names)
    type(memory_dataset_t), intent(inout) :: ds
    character(len=*), intent(in) :: coordinate_names
    if (len(coordinate_names) > 0) call add_attribute(ds, 'coordinates', coordinate_names)
  end subroutine name_coordinates

  !> The root's shared dimension scales and its attributes (as the file's).
  subroutine lay_out_root(inp, out, n_cases, n_samples)
    type(run_input_t), intent(in) :: inp
    type(memory_output_t), intent(inout) :: out
    integer(i8), intent(in) :: n_cases, n_samples
    integer(i8) :: i
    integer :: d
    d = add(out, '', time_entry, kind_real, ['time'], [n_samples])
    ! (as open_outputs; a loop, not an array constructor, which grows a temporary)
    allocate (out%datasets(d)%reals(n_samples))
    do i = 0, n_samples - 1
      out%datasets(d)%reals(i + 1) = real(i, wp) * inp%plan%interval
    end do
    d = add(out, '', xyz_entry, kind_text, ['xyz'], [3_i8])
    out%datasets(d)%texts = [character(len=text_width) :: 'x', 'y', 'z']
    d = add(out, '', mode_entry, kind_int, ['mode'], [2_i8])
    out%datasets(d)%ints = [1_i8, 2_i8]
    out%attributes = 'Conventions' // tab // 'str' // tab // 'CF-1.10' // newline // &
                     'title' // tab // 'str' // tab // file_title // newline // &
                     'references' // tab // 'str' // tab // file_references // newline // &
                     'campaign_id' // tab // 'str' // tab // campaign_id(inp) // newline // &
                     'n_cases_total' // tab // 'i4' // tab // itoa(n_cases) // newline
    ! the input, as the file keeps it, in a line of its own: it holds newlines
    out%attributes = out%attributes // 'input_namelist' // tab // 'str' // tab // escaped(inp%text) // newline
  end subroutine lay_out_root

  !> Every case's row (its inputs, status and figures) into the columns of
  !> the datasets `where` names, entry by entry.
  subroutine fill_columns(inp, out, row, where)
    type(run_input_t), intent(in) :: inp
    type(memory_output_t), intent(inout) :: out
    type(named_value_t), intent(inout) :: row(:)
    integer, intent(in) :: where(:)
    integer(i8) :: i, n_cases
    integer :: k, ncomp
    n_cases = inp%campaign%n_cases()
    do k = 1, size(row)
      associate (ds => out%datasets(where(k)))
        select case (ds%kind)
        case (kind_real); allocate (ds%reals(row(k)%ncomp * n_cases))
        case (kind_int); allocate (ds%ints(n_cases))
        case (kind_text); allocate (ds%texts(n_cases))
        end select
      end associate
    end do
    do i = 0, n_cases - 1
      ! (row: case 0's already)
      if (i > 0) row(:) = table_row(inp%campaign%case_at(i), out%results(i))      ! (every row has the same entries)
      do k = 1, size(row)
        associate (ds => out%datasets(where(k)))
          select case (ds%kind)
          case (kind_real)
            ncomp = row(k)%ncomp
            ds%reals(i * ncomp + 1:(i + 1) * ncomp) = row(k)%reals(:ncomp)
          case (kind_int)
            ds%ints(i + 1) = row(k)%int
          case (kind_text)
            ds%texts(i + 1) = row(k)%text
          end select
        end associate
      end do
    end do
  end subroutine fill_columns

  pure integer function digit_count(value)
    integer(i8), intent(in) :: value          !< >= 0
    integer(i8) :: rest
    digit_count = 1
    rest = value
    do while (rest >= 10)
      digit_count = digit_count + 1
      rest = rest / 10
    end do
  end function digit_count

  !> Every dataset's description in one text, for a caller that reads
  !> them all: a record each, ended by record_end, of fields ended by
  !> field_end: group, name, units, long name, dimensions (space-separated),
  !> kind (1 real, 2 integer, 3 text), bytes per value, shape
  !> (space-separated), the other attributes.
  subroutine write_catalog(out)
    type(memory_output_t), intent(inout) :: out
    integer :: d, k, itemsize
    integer(i8) :: n
    ! (built in place, without a formatted write: a run of a short case
    ! should not spend as long on this as on integrating)
    allocate (character(len=4096) :: out%catalog)
    n = 0
    do d = 1, out%n
      associate (ds => out%datasets(d))
        itemsize = 8
        if (ds%kind == kind_text) itemsize = text_width
        ! (piece by piece, and substrings rather than trim(): a concatenation
        ! or a trim would allocate a temporary each)
        call append(ds%group(:len_trim(ds%group)), field_end)
        call append(ds%name(:len_trim(ds%name)), field_end)
        call append(ds%units(:len_trim(ds%units)), field_end)
        call append(ds%long_name(:len_trim(ds%long_name)), field_end)
        call append(ds%dims(1)(:len_trim(ds%dims(1))))
        do k = 2, ds%ndim
          call append(' ', ds%dims(k)(:len_trim(ds%dims(k))))
        end do
        call append(field_end, decimal_digits(int(ds%kind, i8)))
        call append(field_end, decimal_digits(int(itemsize, i8)))
        call append(field_end, decimal_digits(ds%shape(1)))
        do k = 2, ds%ndim
          call append(' ', decimal_digits(ds%shape(k)))
        end do
        call append(field_end)
        if (allocated(ds%attributes)) call append(ds%attributes)
        call append(field_end, record_end)
      end associate
    end do
    out%catalog = out%catalog(:n)
  contains
    !> piece, then second (if given), at the end of the catalog
    subroutine append(piece, second)
      character(len=*), intent(in) :: piece
      character(len=*), intent(in), optional :: second
      call append_one(piece)
      if (present(second)) call append_one(second)
    end subroutine append

    subroutine append_one(piece)
      character(len=*), intent(in) :: piece
      character(len=:), allocatable :: grown
      if (n + len(piece) > len(out%catalog)) then
        allocate (character(len=2 * (n + len(piece))) :: grown)
        grown(:n) = out%catalog(:n)
        call move_alloc(grown, out%catalog)
      end if
      out%catalog(n + 1:n + len(piece)) = piece
      n = n + len(piece)
    end subroutine append_one
  end subroutine write_catalog

  !> A count's decimal digits.
  pure function decimal_digits(value) result(text)
    integer(i8), intent(in) :: value
    character(len=digit_count(value)) :: text
    integer(i8) :: rest
    integer :: k
    rest = value
    do k = len(text), 1, -1
      text(k:k) = achar(iachar('0') + int(mod(rest, 10_i8)))
      rest = rest / 10
    end do
  end function decimal_digits

  !> A new dataset of group `group`, described by `entry`, at the end of the list.
  integer function add(out, group, entry, kind, dims, shape) result(d)
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: group
    type(named_value_t), intent(in) :: entry
    integer, intent(in) :: kind
    character(len=*), intent(in) :: dims(:)
    integer(i8), intent(in) :: shape(:)
    type(memory_dataset_t), allocatable :: grown(:)
    integer :: k
    if (out%n == size(out%datasets)) then
      allocate (grown(2 * out%n))
      do k = 1, out%n
        call move_dataset(out%datasets(k), grown(k))
      end do
      call move_alloc(grown, out%datasets)
    end if
    out%n = out%n + 1
    d = out%n
    associate (ds => out%datasets(d))
      ds%group = group
      ds%name = entry%name
      ds%units = entry%units
      ds%long_name = entry%description
      ds%kind = kind
      ds%ndim = size(dims)
      ds%dims(:size(dims)) = dims
      ds%shape(:size(shape)) = shape
    end associate
  end function add

  subroutine move_dataset(from, to)
    type(memory_dataset_t), intent(inout) :: from, to
    to%group = from%group
    to%name = from%name
    to%units = from%units
    to%long_name = from%long_name
    to%kind = from%kind
    to%ndim = from%ndim
    to%shape = from%shape
    to%dims = from%dims
    if (allocated(from%attributes)) call move_alloc(from%attributes, to%attributes)
    to%field = from%field
    to%taken = from%taken
    call move_alloc(from%reals, to%reals)
    call move_alloc(from%ints, to%ints)
    call move_alloc(from%texts, to%texts)
  end subroutine move_dataset

  subroutine add_attribute(ds, name, value, type)
    type(memory_dataset_t), intent(inout) :: ds
    character(len=*), intent(in) :: name, value
    character(len=*), intent(in), optional :: type
    character(len=3) :: value_type
    value_type = 'str'
    if (present(type)) value_type = type
    if (.not. allocated(ds%attributes)) ds%attributes = ''
    ds%attributes = ds%attributes // name // tab // trim(value_type) // tab // value // newline
  end subroutine add_attribute

  pure function int_list(values) result(text)
    integer(i8), intent(in) :: values(:)
    character(len=21 * size(values)) :: text
    integer :: k
    text = ''
    do k = 1, size(values)
      text = trim(text) // ' ' // itoa(values(k))
    end do
    text = adjustl(text)
  end function int_list

  pure integer function count_special(text)
    character(len=*), intent(in) :: text
    integer :: k
    count_special = 0
    do k = 1, len(text)
      if (text(k:k) == '\' .or. text(k:k) == newline) count_special = count_special + 1
    end do
  end function count_special

  !> A text on one line: backslash and newline written as \\ and \n.
  pure function escaped(text) result(line)
    character(len=*), intent(in) :: text
    character(len=len(text) + count_special(text)) :: line
    integer :: k, pos
    pos = 0
    do k = 1, len(text)
      select case (text(k:k))
      case ('\')
        line(pos + 1:pos + 2) = '\\'
        pos = pos + 2
      case (newline)
        line(pos + 1:pos + 2) = '\n'
        pos = pos + 2
      case default
        line(pos + 1:pos + 1) = text(k:k)
        pos = pos + 1
      end select
    end do
  end function escaped

  !> The values of real dataset d, in Fortran's order, into `values`
  !> (a trajectory: each case's samples, NaN for a case never integrated).
  subroutine read_reals(self, d, values)
    class(memory_output_t), intent(in) :: self
    integer, intent(in) :: d
    real(wp), intent(out) :: values(:)
    integer(i8) :: i, per_case
    integer :: f
    associate (ds => self%datasets(d))
      if (ds%field == 0) then
        values = ds%reals
        return
      end if
      f = ds%field
      per_case = field_ncomp(f) * self%n_samples
      do i = 0, size(self%results, kind=i8) - 1
        if (allocated(self%results(i)%fields(f)%values)) then
          call copy_flat(self%results(i)%fields(f)%values, per_case, values(i * per_case + 1:(i + 1) * per_case))
        else
          values(i * per_case + 1:(i + 1) * per_case) = ieee_value(0.0_wp, ieee_quiet_nan)
        end if
      end do
    end associate
  end subroutine read_reals

  !> The values of an array of any shape, in array element order.
  subroutine copy_flat(from, n, to)
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: from(n)
    real(wp), intent(out) :: to(n)
    to = from
  end subroutine copy_flat
end module ellroll_memory_run
