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
  !$ use omp_lib, only: omp_get_max_threads, omp_set_num_threads
  use ellroll_kinds, only: wp, i8
  use ellroll_threads, only: team_size
  use ellroll_errors, only: error_t, set_error, err_interrupted
  use ellroll_system, only: stop_signal, signal_name
  use ellroll_strings, only: itoa, format_real
  use ellroll_status, only: status_invalid, status_count
  use ellroll_records, only: named_value_t, kind_real, kind_int, kind_text
  use ellroll_cases, only: case_t, field_count, field_names, field_units, field_ncomp, field_descriptions
  use ellroll_results, only: case_result_t, field_buffer_t, count_undefined
  use ellroll_figures, only: figure_count, figures
  use ellroll_limit_states, only: limit_state_flag_values, limit_state_flag_meanings
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
      file_references, table_row, limit_state_row, status_flag_meanings
  use ellroll_memory_datasets, only: memory_output_t, memory_dataset_t, text_width, tab, newline, add, add_entry, &
      add_attribute, case_scale, name_coordinates, int_list, escaped, write_catalog
  implicit none
  private

  public :: memory_output_t, memory_dataset_t, run_in_memory, text_width

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
    if (allocated(inp%campaign%base%limit_states)) then
      if (size(inp%campaign%base%limit_states) > 0) call limit_state_datasets(inp, out, indices, coords, coordinate_names)
    end if
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

  !> /limit_state of a campaign with limit states, as the file holds it
  !> (hdf5_groups' limit_state_group): a flag per case per limit state
  !> (1 exceeded, 0 not, -1 undefined), its figure, capacity and the
  !> capacity's units as attributes.
  subroutine limit_state_datasets(inp, out, indices, coords, coordinate_names)
    type(run_input_t), intent(in) :: inp
    type(memory_output_t), intent(inout) :: out
    integer(i8), intent(in) :: indices(:)
    type(coordinate_t), intent(in) :: coords(:)
    character(len=*), intent(in) :: coordinate_names
    type(named_value_t), allocatable :: row(:)
    integer(i8) :: i, n_cases
    integer :: k, d, first
    n_cases = size(indices, kind=i8)
    call case_scale(out, 'limit_state', indices)
    call coordinate_datasets(out, 'limit_state', coords, n_cases)
    allocate (row, source=limit_state_row(inp%campaign%base, case_result_t()))      ! (the names and long names)
    first = out%n + 1
    do k = 1, size(row)
      d = add(out, 'limit_state', row(k), kind_int, ['case'], [n_cases])
      allocate (out%datasets(d)%ints(n_cases))
      associate (state => inp%campaign%base%limit_states(k), ds => out%datasets(d))
        call add_attribute(ds, 'figure', trim(figures(state%figure)%name))
        call add_attribute(ds, 'capacity', format_real(state%capacity), 'f8')
        call add_attribute(ds, 'capacity_units', trim(figures(state%figure)%unit))
        call add_attribute(ds, 'flag_values', int_list(limit_state_flag_values), 'i1')
        call add_attribute(ds, 'flag_meanings', limit_state_flag_meanings)
        call name_coordinates(ds, coordinate_names)
      end associate
    end do
    do i = 0, n_cases - 1
      row(:) = limit_state_row(inp%campaign%case_at(i), out%results(i))      ! (every case has the same states)
      do k = 1, size(row)
        out%datasets(first + k - 1)%ints(i + 1) = row(k)%int
      end do
    end do
  end subroutine limit_state_datasets

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
    call add_attribute(out%datasets(d), 'flag_values', int_list([1_i8, 2_i8]), 'i1')
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

end module ellroll_memory_run
