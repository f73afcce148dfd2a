!> `ellroll summary OUT.h5`: the summary of an output file, read from the
!> file itself: a table (cases per status, the slowest case, totals; also
!> printed at the end of a run), or one row per case as CSV or JSON.
module ellroll_cmd_summary
  use ellroll_standard_output, only: put_line
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa, format_real, real_text, json_text
  use ellroll_status, only: status_count, status_name, status_pending, status_invalid, status_completed
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_records, only: named_value_t, kind_int
  use ellroll_results, only: case_result_t, summary_record, count_undefined
  use ellroll_cli, only: cli_t
  use ellroll_errors, only: set_error, err_input
  use ellroll_files, only: path_kind, kind_missing, file_size
  use ellroll_system, only: open_regular_file, file_type_words, close_descriptor, system_error_text, read_watchdog
  use ellroll_lapack, only: dlasrt
  use ellroll_cmd_suite, only: print_suite
  implicit none
  private

  public :: summary_command, print_summary

  !> A column of `ellroll summary --format csv|json`: one of its kinds of
  !> values is allocated, one value per case.
  type :: column_t
    character(len=40) :: name = ''
    character(len=:), allocatable :: units
    real(wp), allocatable :: reals(:)
    integer(i8), allocatable :: ints(:)
    character(len=64), allocatable :: texts(:)
  end type column_t

contains

  subroutine summary_command(cli, err)
    type(cli_t), intent(in) :: cli
    type(error_t), intent(inout) :: err
    integer :: seconds
    call check_readable(trim(cli%paths(1)), err)
    if (err%failed()) return
    ! (a file read at 50 MB/s, and 10 s more: its tables take 50 ms)
    seconds = 10 + int(min(max(file_size(trim(cli%paths(1))), 0_i8) / 50000000_i8, 100000_i8))
    call read_watchdog('ellroll: error: ' // trim(cli%paths(1)) // ': a damaged HDF5 file: HDF5 does not ' // &
                       'finish reading it (stopped after ' // itoa(seconds) // ' s)', seconds)
    if (cli%suite) then
      call print_suite(trim(cli%paths(1)), trim(cli%summary_format), err)
    else
      call print_summary(trim(cli%paths(1)), trim(cli%summary_format), err)
    end if
    call read_watchdog('', 0)
  end subroutine summary_command

  !> A folder, a FIFO or a device (not opened: a FIFO would wait for a
  !> writer), or a file this user may not read, is bad input: said so
  !> before HDF5 tries it.
  subroutine check_readable(path, err)
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    integer :: code, fd
    integer(i8) :: bytes
    character :: file_type
    code = open_regular_file(path, fd, bytes, file_type)
    if (code == 0) then
      code = close_descriptor(fd)
    else if (code == -1 .and. file_type == 'd') then
      call set_error(err, err_input, path // ': a folder, not an output file (give the .h5 file in it)')
    else if (code == -1) then
      call set_error(err, err_input, path // ': ' // trim(file_type_words(file_type)) // ', not a regular file')
    else if (path_kind(path) /= kind_missing) then          ! (none: print_summary says 'no such file')
      call set_error(err, err_input, path // ': cannot read it (' // system_error_text(code) // &
                     '); check its permissions')
    end if
  end subroutine check_readable

  !> The summary of a file: the table (format 'table'), or one row per case
  !> ('csv', or strict 'json' with NaN as null and units in a header): the
  !> case index, the varied inputs, the status by name and every figure of
  !> /summary.
  subroutine print_summary(path, format, err)
    character(len=*), intent(in) :: path, format
    type(error_t), intent(inout) :: err
    type(h5_input_t) :: file
    type(column_t), allocatable :: columns(:)
    integer(i8), allocatable :: status(:), steps(:), index(:)
    real(wp), allocatable :: wall(:), theta_max(:)
    allocate (columns(0))
    call file%open(path, err)
    if (err%failed()) return
    if (format == 'table') then
      status = file%int_column('summary/status', err)
      steps = file%int_column('summary/n_steps', err)
      index = file%int_column('summary/case', err)
      wall = file%real_column('summary/wall_time', err)
      theta_max = file%real_column('summary/theta_max', err)
    end if
    ! (apart: status is read for a table only, and .or. may evaluate both sides)
    if (format /= 'table') then
      columns = summary_columns(file, err)
    else if (size(status) > 1) then
      columns = summary_columns(file, err)
    end if
    call file%close()
    call read_watchdog('', 0)         ! (read: the time its rows take to print, to a pipe read late, is not HDF5's)
    if (err%failed()) return
    select case (format)
    case ('csv')
      call print_csv(columns)
    case ('json')
      call print_json(path, columns)
    case default
      call print_table(path, status, steps, index, wall, theta_max)
      if (size(status) > 1) call print_spread(columns, status == status_completed)
    end select
  end subroutine print_summary

  !> The columns of a row: case, the coordinates of /summary (the varied
  !> inputs, as named by its `coordinates` attribute), status, then every
  !> dataset of /summary in the order of the file's layout (a value per mode:
  !> one column per mode, NAME_1, NAME_2) that the file holds.
  function summary_columns(file, err) result(columns)
    type(h5_input_t), intent(in) :: file
    type(error_t), intent(inout) :: err
    type(column_t), allocatable :: columns(:)
    type(named_value_t), allocatable :: figures(:)
    character(len=:), allocatable :: coordinates, units
    integer(i8), allocatable :: status(:)
    character(len=12), allocatable :: status_names(:)
    real(wp), allocatable :: rows(:, :)
    integer :: k, m, first, last
    allocate (columns(0))
    call file%text_attribute('units', units, 'summary/case')
    call append(columns, 'case', units, ints=file%int_column('summary/case', err))
    call file%text_attribute('coordinates', coordinates, 'summary/status')
    first = 1
    do while (first <= len(coordinates))
      last = index(coordinates(first:) // ' ', ' ') + first - 2
      associate (name => coordinates(first:last))
        if (name == 'record') then
          call append(columns, name, '1', texts=file%text_column('summary/' // name, err))
        else
          call file%text_attribute('units', units, 'summary/' // name)
          call append(columns, name, units, reals=file%real_column('summary/' // name, err))
        end if
      end associate
      first = last + 2
    end do
    allocate (status, source=file%int_column('summary/status', err))
    allocate (status_names(size(status)))
    do k = 1, size(status)
      status_names(k) = status_name(int(status(k)))
    end do
    call append(columns, 'status', '1', texts=status_names)
    figures = summary_record(case_result_t())
    do k = 1, size(figures)
      associate (f => figures(k), name => 'summary/' // trim(figures(k)%name))
        if (.not. file%has(name)) cycle            ! a file written by another version may lack it
        if (f%kind == kind_int) then
          call append(columns, f%name, trim(f%units), ints=file%int_column(name, err))
        else if (f%ncomp == 1) then
          call append(columns, f%name, trim(f%units), reals=file%real_column(name, err))
        else
          allocate (rows, source=file%real_rows(name, f%ncomp, err))
          do m = 1, f%ncomp
            call append(columns, trim(f%name) // '_' // itoa(m), trim(f%units), reals=rows(m, :))
          end do
          deallocate (rows)
        end if
      end associate
    end do
  end function summary_columns

  subroutine append(columns, name, units, reals, ints, texts)
    type(column_t), allocatable, intent(inout) :: columns(:)
    character(len=*), intent(in) :: name, units
    real(wp), intent(in), optional :: reals(:)
    integer(i8), intent(in), optional :: ints(:)
    character(len=*), intent(in), optional :: texts(:)
    type(column_t), allocatable :: longer(:)
    integer :: n
    n = size(columns)
    allocate (longer(n + 1))
    longer(:n) = columns
    longer(n + 1)%name = name
    longer(n + 1)%units = units
    if (present(reals)) allocate (longer(n + 1)%reals, source=reals)
    if (present(ints)) allocate (longer(n + 1)%ints, source=ints)
    if (present(texts)) then
      allocate (longer(n + 1)%texts(size(texts)))
      longer(n + 1)%texts = texts
    end if
    call move_alloc(longer, columns)
  end subroutine append

  !> One row per case, a header of the column names with their units,
  !> `name [units]` (the bare name for units '1': dimensionless, counts,
  !> text).
  subroutine print_csv(columns)
    type(column_t), intent(in) :: columns(:)
    character(len=:), allocatable :: line
    integer :: i, k
    line = ''
    do k = 1, size(columns)
      if (k > 1) line = line // ','
      line = line // trim(columns(k)%name)
      if (len_trim(columns(k)%units) > 0 .and. columns(k)%units /= '1') &
        line = line // ' [' // trim(columns(k)%units) // ']'
    end do
    call put_line(line)
    do i = 1, size(columns(1)%ints)
      line = ''
      do k = 1, size(columns)
        if (k > 1) line = line // ','
        call append_cell(line, columns(k), i, json=.false.)
      end do
      call put_line(line)
    end do
  end subroutine print_csv

  !> The same as strict JSON, NaN as null:
  !> {"file": ..., "units": {column: units, ...}, "cases": [{...}, ...]}.
  subroutine print_json(path, columns)
    character(len=*), intent(in) :: path
    type(column_t), intent(in) :: columns(:)
    character(len=:), allocatable :: line
    integer :: i, k
    line = '{"file": "' // json_text(path) // '", "units": {'
    do k = 1, size(columns)
      if (k > 1) line = line // ', '
      line = line // '"' // trim(columns(k)%name) // '": "' // json_text(columns(k)%units) // '"'
    end do
    call put_line(line // '}, "cases": [')
    do i = 1, size(columns(1)%ints)
      line = ' {'
      do k = 1, size(columns)
        if (k > 1) line = line // ', '
        line = line // '"' // trim(columns(k)%name) // '": '
        call append_cell(line, columns(k), i, json=.true.)
      end do
      line = line // '}'
      if (i < size(columns(1)%ints)) line = line // ','
      call put_line(line)
    end do
    call put_line(']}')
  end subroutine print_json

  !> A column's value for case i after line: a number (JSON: null when not
  !> finite), or text (JSON: a string; CSV: quoted when it holds a comma or a
  !> quote).
  subroutine append_cell(line, column, i, json)
    character(len=:), allocatable, intent(inout) :: line
    type(column_t), intent(in) :: column
    integer, intent(in) :: i
    logical, intent(in) :: json
    character(len=40) :: number
    integer :: n
    if (allocated(column%ints)) then
      ! a count undefined for the case (one never run) is missing, as a NaN real is
      if (column%ints(i) == count_undefined .and. column%name /= 'case') then
        line = line // trim(merge('null', 'NaN ', json))
      else
        line = line // itoa(column%ints(i))
      end if
    else if (allocated(column%reals)) then
      if (json .and. .not. ieee_is_finite(column%reals(i))) then
        line = line // 'null'
      else
        call real_text(column%reals(i), number, n)
        line = line // number(:n)
      end if
    else if (json) then
      line = line // '"' // json_text(trim(column%texts(i))) // '"'
    else if (scan(column%texts(i), ',"') > 0) then
      line = line // '"' // marked(trim(column%texts(i)), '"', '"') // '"'
    else
      line = line // trim(column%texts(i))
    end if
  end subroutine append_cell

  pure integer function count_marks(raw, special, mark)
    character(len=*), intent(in) :: raw, special, mark
    integer :: k
    count_marks = 0
    do k = 1, len(raw)
      if (index(special, raw(k:k)) > 0) count_marks = count_marks + len(mark)
    end do
  end function count_marks

  !> raw with `mark` before each of its characters found in `special` (a CSV
  !> field in quotes doubles each quote).
  pure function marked(raw, special, mark) result(text)
    character(len=*), intent(in) :: raw, special, mark
    character(len=len(raw) + count_marks(raw, special, mark)) :: text
    integer :: k, at
    at = 0
    do k = 1, len(raw)
      if (index(special, raw(k:k)) > 0) then
        text(at + 1:at + len(mark)) = mark
        at = at + len(mark)
      end if
      text(at + 1:at + 1) = raw(k:k)
      at = at + 1
    end do
  end function marked

  !> A campaign's figures over its completed cases: the smallest, the median
  !> (of an even count, the mean of the middle two) and the largest, to six
  !> significant digits; figures that are NaN in every completed case left out.
  subroutine print_spread(columns, completed)
    type(column_t), intent(in) :: columns(:)
    logical, intent(in) :: completed(:)
    real(wp), allocatable :: values(:)
    character(len=:), allocatable :: name
    character(len=40) :: label
    integer :: k, first, n, info
    ! the figures follow the status column (a loop: findloc over the
    ! components' strided names would copy them into a temporary)
    first = 0
    do k = 1, size(columns)
      if (columns(k)%name == 'status') first = k + 1
    end do
    if (first == 0 .or. count(completed) == 0) return
    call put_line('  over the ' // itoa(count(completed)) // ' completed ' // &
        trim(merge('case ', 'cases', count(completed) == 1)) // ':')
    call put_line('    figure                                  min            median         max')
    do k = first, size(columns)
      if (.not. allocated(columns(k)%reals) .or. columns(k)%name == 'wall_time') cycle
      values = pack(columns(k)%reals, completed .and. .not. ieee_is_nan(columns(k)%reals))
      n = size(values)
      if (n == 0) cycle
      call dlasrt('I', n, values, info)            ! (values holds no NaN: packed out above)
      name = trim(columns(k)%name)
      if (columns(k)%units /= '1') name = name // ' [' // columns(k)%units // ']'
      label = name
      call put_line('    ' // label // cell(values(1)) // &
          cell((values((n + 1) / 2) + values(n / 2 + 1)) / 2) // trim(cell(values(n))))
    end do
  contains
    !> x to six significant digits, in a column 15 wide.
    function cell(x) result(text)
      real(wp), intent(in) :: x
      character(len=15) :: text
      character(len=24) :: rounded
      real(wp) :: y
      y = x
      if (ieee_is_finite(x)) then
        write (rounded, '(es24.5e3)') x
        read (rounded, *) y
      end if
      text = format_real(y)
    end function cell
  end subroutine print_spread

  subroutine print_table(path, status, steps, index, wall, theta_max)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: status(:), steps(:), index(:)
    real(wp), intent(in) :: wall(:), theta_max(:)
    integer :: s, slowest
    character(len=12) :: label
    character(len=10) :: counted
    logical :: ran(size(status))
    call put_line(path // ': ' // itoa(size(status)) // ' cases')
    do s = 0, status_count - 1
      if (count(status == s) == 0) cycle
      label = status_name(s)
      write (counted, '(i10)') count(status == s)
      call put_line('  ' // label // counted)
    end do
    ! a status this program does not know (a file from a later version, or
    ! altered) is counted as `unknown`, as status_name names it: the counts
    ! add up to the cases
    if (any(status < 0 .or. status >= status_count)) then
      label = status_name(-1)
      write (counted, '(i10)') count(status < 0 .or. status >= status_count)
      call put_line('  ' // label // counted)
    end if
    ran = status /= status_pending .and. status /= status_invalid
    if (.not. any(ran)) return
    slowest = maxloc(wall, dim=1, mask=ran)
    call put_line('  steps, all cases: ' // itoa(sum(steps, mask=ran)) // '; integration time ' // &
        format_real(real(nint(1000 * sum(wall, mask=ran)), wp) / 1000) // ' s (sum over cases)')
    call put_line('  slowest case: ' // itoa(index(slowest)) // ' (' // &
        format_real(real(nint(1.0e4_wp * wall(slowest)), wp) / 1.0e4_wp) // ' s, ' // &
        status_name(int(status(slowest))) // ')')
    if (size(status) == 1) call put_line('  theta_max: ' // format_real(theta_max(1)) // ' rad')
  end subroutine print_table
end module ellroll_cmd_summary
