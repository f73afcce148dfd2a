!> Reading and validating the input namelist file into a campaign (a base
!> case, sweeps and samples) and an output plan. Every message a user sees
!> about input is written here, in ellroll_case_input, ellroll_input_reader or
!> ellroll_campaign_input; each names the file, line, group, variable and
!> value.
module ellroll_input
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_set_halting_mode, ieee_usual
  use, intrinsic :: ieee_exceptions, only: ieee_status_type, ieee_get_status, ieee_set_status
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_namelist_scan, only: nml_file_t, nml_group_t, nml_assignment_t, scan_namelist_file, &
      scan_namelist_text
  use ellroll_strings, only: itoa, join, format_real, excerpt
  use ellroll_cases, only: case_t, output_plan_t, get_param, problem_setting
  use ellroll_campaign, only: campaign_t, sweep_t, sample_t
  use ellroll_input_reader, only: reader_t, namelist_values_t, check_names, max_values, max_fields, not_given, &
      has_unquoted
  use ellroll_campaign_input, only: add_sweep, add_sample
  use ellroll_suite_input, only: record_spec_t, add_record_group
  use ellroll_limit_state_input, only: add_limit_state
  use ellroll_limit_states, only: limit_state_t
  use ellroll_case_input, only: build_input
  use ellroll_params, only: params, param_count, param_default, param_component, param_width
  use ellroll_suggest, only: did_you_mean
  use ellroll_intensity, only: max_sa_periods
  implicit none
  private

  public :: run_input_t, read_input, read_input_text, describe_invalid

  type :: run_input_t
    type(campaign_t) :: campaign
    type(output_plan_t) :: plan
    character(len=:), allocatable :: path
    character(len=:), allocatable :: text       !< the input file, verbatim
    character(len=:), allocatable :: canonical  !< groups and assignments without comments or layout
    !> every file the input reads (records), a line 'NAME: SIZE bytes, crc32c
    !> HEX' each: with `canonical`, what makes a campaign the same
    character(len=:), allocatable :: input_files
  end type run_input_t

  character(len=*), parameter :: known_groups(12) = [character(len=12) :: &
      'geometry', 'ball', 'environment', 'initial', 'integration', 'output', 'excitation', 'campaign', &
      'sweep', 'sample', 'record', 'limit_state']
  !> the groups a file may give more than once
  character(len=*), parameter :: repeated_groups(4) = [character(len=11) :: 'sweep', 'sample', 'record', &
      'limit_state']
contains

  subroutine read_input(path, output_override, inp, err)
    character(len=*), intent(in) :: path
    character(len=*), intent(in) :: output_override   !< '' when not given
    type(run_input_t), intent(out) :: inp
    type(error_t), intent(inout) :: err
    type(reader_t) :: rd
    call scan_namelist_file(path, rd%file, rd%err)
    call interpret(rd, path, output_override, inp, err)
  end subroutine read_input

  !> The same from the text of an input file (as stored in an output file).
  subroutine read_input_text(label, text, output_override, inp, err)
    character(len=*), intent(in) :: label, text, output_override
    type(run_input_t), intent(out) :: inp
    type(error_t), intent(inout) :: err
    type(reader_t) :: rd
    rd%file%path = label
    rd%file%text = text
    call scan_namelist_text(rd%file, rd%err)
    call interpret(rd, label, output_override, inp, err)
  end subroutine read_input_text

  subroutine interpret(rd, path, output_override, inp, err)
    type(reader_t), intent(inout) :: rd
    character(len=*), intent(in) :: path, output_override
    type(run_input_t), intent(inout) :: inp
    type(error_t), intent(inout) :: err
    integer :: k, first
    character(len=:), allocatable :: hint
    if (.not. rd%err%failed()) then
      do k = 1, size(rd%file%groups)
        associate (grp => rd%file%groups(k))
          if (.not. any(known_groups == grp%name)) then
            call did_you_mean(grp%name, known_groups, '&', hint)
            call rd%fail_at(grp%line, 'unknown group &' // grp%name // hint // ' (known groups: ' // &
                            join(known_groups) // ')')
          else if (all(grp%name /= repeated_groups)) then
            first = rd%file%group_index(grp%name)
            if (first /= k) call rd%fail_at(grp%line, '&' // grp%name // ' appears twice (first at line ' // &
                                            itoa(rd%file%groups(first)%line) // '); give each group once')
          end if
        end associate
        if (rd%err%failed()) exit
      end do
    end if
    if (.not. rd%err%failed()) call read_groups(rd, output_override, inp)
    if (rd%err%failed()) then
      err = rd%err
      return
    end if
    inp%path = path
    inp%text = rd%file%text
    call canonical_text(rd%file, inp%canonical)
  end subroutine interpret

  !> Every assignment of every group, each read alone (read_assignment)
  !> into the namelist values v, which build_input then checks and turns
  !> into the campaign and the output plan.
  subroutine read_groups(rd, output_override, inp)
    type(reader_t), intent(inout) :: rd
    character(len=*), intent(in) :: output_override
    type(run_input_t), intent(inout) :: inp
    integer :: gi, k, ios
    character(len=512) :: msg
    character(len=1024) :: excitation_files(3)
    type(sweep_t), allocatable :: sweeps(:)
    type(sample_t), allocatable :: draws(:)
    type(namelist_values_t) :: v
    type(record_spec_t), allocatable :: suite(:)
    integer :: n_records
    type(limit_state_t), allocatable :: states(:)
    integer, allocatable :: state_lines(:)
    character(len=:), allocatable :: reason
    logical :: unquoted

    v%param = [(param_default(k), k = 1, param_count)]     ! NaN: required
    v%method = 'rk4'; v%t_end = nan(); v%error_estimate = 'none'; v%slip = 'end'
    v%file = ''; v%interval = nan(); v%fields = ''; v%compression = 0
    v%combine = 'grid'; v%invalid = 'stop'; v%samples = 0; v%seed = 0
    v%kind = 'none'; v%record_file = ''; v%factor = 1; v%sa_periods = not_given()
    allocate (sweeps(0), draws(0), suite(0), states(0), state_lines(0))
    n_records = 0

    do gi = 1, size(rd%file%groups)
      associate (grp => rd%file%groups(gi))
        if (.not. names_known(rd, gi)) return
        v%name = ''; v%start = nan(); v%stop = nan(); v%count = 0; v%spacing = 'linear'
        ! (max_values of them: only the groups that read them set them)
        if (grp%name == 'sweep' .or. grp%name == 'sample') v%values = not_given()
        v%low = nan(); v%high = nan(); v%figure = ''; v%limit_capacity = nan()
        if (grp%name == 'record') then       ! (its record_file is not &excitation's)
          excitation_files = v%record_file
          v%record_file = ''
          v%factor = 1
        end if
        do k = 1, size(grp%items)
          associate (item => grp%items(k))
            ! (a text goes in quotes; a longer one would be cut to the variable's length without a word)
            unquoted = text_length(v, item%base) > 0 .and. has_unquoted(item%value)
            if (.not. unquoted .and. text_length(v, item%base) > 0 .and. &
                longest_text(item%source) > text_length(v, item%base)) then
              call rd%fail_at(item%line, '&' // grp%name // ': ' // item%name // ' = ' // excerpt(item%value) // &
                  ': a text of ' // itoa(longest_text(item%source)) // ' characters (blanks included); at most ' // &
                  itoa(text_length(v, item%base)) // ' fit')
              return
            end if
            call read_assignment(grp, k, v, ios, msg)
            if (ios == 0 .and. lone_sign(grp%name, item)) ios = 1      ! (gfortran reads a sign alone as 0)
            if (ios == 0 .and. unquoted) ios = 1
            if (ios /= 0) then
              call bad_value_reason(grp%name, item, reason)
              call rd%fail_at(item%line, '&' // grp%name // ': ' // item%name // ' = ' // excerpt(item%value) // reason)
              return
            end if
          end associate
        end do
        if (grp%name == 'sweep') call add_sweep(rd, v, gi, sweeps, draws)
        if (grp%name == 'sample') call add_sample(rd, v, gi, sweeps, draws)
        if (grp%name == 'record') then
          call add_record_group(rd, v, gi, suite, n_records)
          v%record_file = excitation_files
        end if
        if (grp%name == 'limit_state') call add_limit_state(rd, v, gi, states, state_lines)
        if (rd%err%failed()) return
      end associate
    end do
    suite = suite(:n_records)
    call build_input(rd, v, output_override, sweeps, draws, suite, inp%campaign, inp%plan, inp%input_files)
    if (.not. rd%err%failed()) inp%campaign%base%limit_states = states
  end subroutine read_groups

  !> Read assignment k of a group alone: into the parameter table's values,
  !> or into the variables of its namelist (read_namelist).
  subroutine read_assignment(grp, k, v, ios, msg)
    type(nml_group_t), intent(in) :: grp
    integer, intent(in) :: k
    type(namelist_values_t), intent(inout) :: v
    integer, intent(out) :: ios
    character(len=*), intent(inout) :: msg
    type(ieee_status_type) :: fp_state
    character(len=:), allocatable :: one_assignment
    integer :: row
    call assignment_record(grp, k, one_assignment)
    row = variable_row(grp%name, grp%items(k)%base)
    call ieee_get_status(fp_state)
    ! text such as 1e309 reads as Inf, which the checks name; its
    ! conversion must not stop a build that traps on overflow
    call ieee_set_halting_mode(ieee_usual, .false.)
    if (row > 0) then
      call read_table_value(grp%items(k), row, v%param, ios, msg)
    else
      call read_namelist(grp%name, one_assignment, v, ios, msg)
    end if
    call ieee_set_status(fp_state)
  end subroutine read_assignment

  !> One assignment of a group's own variables (outside the parameter
  !> table), read with the group's namelist: its variables start from v's
  !> values and go back into v.
  subroutine read_namelist(group, text, v, ios, msg)
    character(len=*), intent(in) :: group, text
    type(namelist_values_t), intent(inout) :: v
    integer, intent(out) :: ios
    character(len=*), intent(inout) :: msg
    ios = 0
    select case (group)
    case ('integration'); call read_integration()
    case ('ball'); call read_ball()
    case ('output'); call read_output()
    case ('excitation'); call read_excitation()
    case ('campaign'); call read_campaign()
    case ('sweep', 'sample'); call read_sweep_or_sample()
    case ('record'); call read_record_group()
    case ('limit_state'); call read_limit_state()
    end select
  contains
    subroutine read_integration()
      character(len=len(v%method)) :: method, error_estimate
      real(wp) :: t_end
      namelist /integration/ method, t_end, error_estimate
      method = v%method; t_end = v%t_end; error_estimate = v%error_estimate
      read (text, nml=integration, iostat=ios, iomsg=msg)
      v%method = method; v%t_end = t_end; v%error_estimate = error_estimate
    end subroutine read_integration

    subroutine read_ball()
      character(len=len(v%slip)) :: slip
      namelist /ball/ slip
      slip = v%slip
      read (text, nml=ball, iostat=ios, iomsg=msg)
      v%slip = slip
    end subroutine read_ball

    subroutine read_output()
      character(len=len(v%file)) :: file
      real(wp) :: interval
      character(len=len(v%fields)) :: fields(size(v%fields))
      integer :: compression
      namelist /output/ file, interval, fields, compression
      file = v%file; interval = v%interval; fields = v%fields; compression = v%compression
      read (text, nml=output, iostat=ios, iomsg=msg)
      v%file = file; v%interval = interval; v%fields = fields; v%compression = compression
    end subroutine read_output

    subroutine read_excitation()
      character(len=len(v%kind)) :: kind
      character(len=len(v%record_file)) :: record_file(size(v%record_file))
      real(wp) :: sa_periods(size(v%sa_periods))
      namelist /excitation/ kind, record_file, sa_periods
      kind = v%kind; record_file = v%record_file; sa_periods = v%sa_periods
      read (text, nml=excitation, iostat=ios, iomsg=msg)
      v%kind = kind; v%record_file = record_file; v%sa_periods = sa_periods
    end subroutine read_excitation

    subroutine read_campaign()
      character(len=len(v%combine)) :: combine, invalid
      integer(i8) :: samples, seed
      namelist /campaign/ combine, samples, seed, invalid
      combine = v%combine; samples = v%samples; seed = v%seed; invalid = v%invalid
      read (text, nml=campaign, iostat=ios, iomsg=msg)
      v%combine = combine; v%samples = samples; v%seed = seed; v%invalid = invalid
    end subroutine read_campaign

    subroutine read_sweep_or_sample()
      character(len=len(v%name)) :: name
      character(len=len(v%spacing)) :: spacing
      real(wp) :: values(size(v%values)), start, stop, low, high
      integer :: count
      namelist /sweep/ name, values, start, stop, count, spacing
      namelist /sample/ name, low, high, spacing
      name = v%name; values = v%values; start = v%start; stop = v%stop; count = v%count
      spacing = v%spacing; low = v%low; high = v%high
      if (group == 'sweep') then
        read (text, nml=sweep, iostat=ios, iomsg=msg)
      else
        read (text, nml=sample, iostat=ios, iomsg=msg)
      end if
      v%name = name; v%values = values; v%start = start; v%stop = stop; v%count = count
      v%spacing = spacing; v%low = low; v%high = high
    end subroutine read_sweep_or_sample

    subroutine read_record_group()
      character(len=len(v%name)) :: name
      character(len=len(v%record_file)) :: record_file(size(v%record_file))
      real(wp) :: factor
      namelist /record/ name, record_file, factor
      name = v%name; record_file = v%record_file; factor = v%factor
      read (text, nml=record, iostat=ios, iomsg=msg)
      v%name = name; v%record_file = record_file; v%factor = factor
    end subroutine read_record_group

    subroutine read_limit_state()
      character(len=len(v%name)) :: name
      character(len=len(v%figure)) :: figure
      real(wp) :: capacity
      namelist /limit_state/ name, figure, capacity
      name = v%name; figure = v%figure; capacity = v%limit_capacity
      read (text, nml=limit_state, iostat=ios, iomsg=msg)
      v%name = name; v%figure = figure; v%limit_capacity = capacity
    end subroutine read_limit_state
  end subroutine read_namelist

  !> Why a value that Fortran's namelist read refused is wrong, for the
  !> message after 'NAME = VALUE': a word that is not a number where the
  !> variable holds numbers, a fraction where it holds whole numbers, more
  !> values than it holds; else what the variable takes.
  subroutine bad_value_reason(group, item, reason)
    character(len=*), intent(in) :: group
    type(nml_assignment_t), intent(in) :: item
    character(len=:), allocatable, intent(out) :: reason
    type(ieee_status_type) :: fp_state
    call ieee_get_status(fp_state)
    ! its reads convert the user's text too: 1d400 reads as Inf, and must
    ! not stop a build that traps on overflow (as in read_assignment)
    call ieee_set_halting_mode(ieee_usual, .false.)
    call value_reason(group, item, reason)
    call ieee_set_status(fp_state)
  end subroutine bad_value_reason

  subroutine value_reason(group, item, reason)
    character(len=*), intent(in) :: group
    type(nml_assignment_t), intent(in) :: item
    character(len=:), allocatable, intent(out) :: reason
    character(len=:), allocatable :: token, expected
    integer :: row, capacity, count, start, pos, ios, star
    character :: kind, quote
    real(wp) :: x
    integer(i8) :: whole
    row = variable_row(group, item%base)
    if (row > 0) then
      kind = 'r'
      capacity = param_width(row)
    else
      call own_variable_shape(item%base, kind, capacity)
    end if
    if (item%name /= item%base) capacity = huge(1)       ! an element: the count is not checked here
    select case (kind)
    case ('r'); expected = 'a number'
    case ('i'); expected = 'a whole number'
    case default; expected = "a text in quotes, e.g. " // item%base // " = 'value'"
    end select
    if (kind == 'r' .and. capacity > 1 .and. capacity < huge(1)) expected = 'up to ' // itoa(capacity) // ' numbers'
    reason = ' is not a valid value for ' // item%base // ' (it takes ' // expected // ')'
    count = 0
    start = 1
    quote = ' '
    do pos = 1, len(item%value) + 1
      if (pos <= len(item%value)) then
        if (quote /= ' ') then
          if (item%value(pos:pos) == quote) quote = ' '
          cycle
        end if
        if (item%value(pos:pos) == "'" .or. item%value(pos:pos) == '"') quote = item%value(pos:pos)
        if (item%value(pos:pos) /= ',' .and. item%value(pos:pos) /= ' ') cycle
      end if
      token = item%value(start:pos - 1)
      start = pos + 1
      if (len(token) == 0) cycle
      count = count + 1
      star = index(token, '*')
      if (star > 1 .and. quote == ' ') then              ! r*value: r copies
        read (token(:star - 1), *, iostat=ios) whole
        if (ios == 0) count = count + int(min(max(whole, 1_i8), 1000000000_i8)) - 1
        token = token(star + 1:)
        if (len(token) == 0) cycle
      end if
      if (kind == 't') cycle
      read (token, *, iostat=ios) x
      if (ios /= 0 .or. scan(token, '''"/') > 0 .or. token == '-' .or. token == '+') then
        reason = ' is not a number'
        if (len(token) < len(item%value)) reason = ': ' // token // ' is not a number'
        return
      end if
      if (kind == 'i') then
        read (token, *, iostat=ios) whole
        if (scan(token, '0123456789') > 0 .and. verify(token, '+-0123456789') == 0) then   ! a whole number
          if (ios /= 0 .or. whole > largest_whole(item%base) .or. whole < -largest_whole(item%base)) then
            reason = 'out of range (' // item%base // ' holds whole numbers up to ' // &
                     itoa(largest_whole(item%base)) // ' in magnitude)'
            if (len(token) < len(item%value)) reason = token // ' is ' // reason
            reason = ': ' // reason
            return
          end if
        end if
        if (ios /= 0 .or. scan(token, '.eEdD') > 0) then
          reason = ' is not a whole number'
          if (len(token) < len(item%value)) reason = ': ' // token // ' is not a whole number'
          return
        end if
      end if
    end do
    if (count > capacity .and. capacity == 1) then
      reason = ': ' // itoa(count) // ' values given; ' // item%base // ' holds one'
    else if (count > capacity) then
      reason = ': ' // itoa(count) // ' values given; ' // item%base // ' holds ' // itoa(capacity)
    end if
  end subroutine value_reason

  !> Whether a value of a numeric assignment is a sign alone (also after a
  !> repeat count, r*-): gfortran's read takes it for 0.
  logical function lone_sign(group, item)
    character(len=*), intent(in) :: group
    type(nml_assignment_t), intent(in) :: item
    character :: kind
    integer :: capacity, start, pos, star
    lone_sign = .false.
    if (variable_row(group, item%base) == 0) then
      call own_variable_shape(item%base, kind, capacity)
      if (kind == 't') return
    end if
    start = 1
    do pos = 1, len(item%value) + 1
      if (pos <= len(item%value)) then
        if (item%value(pos:pos) /= ',' .and. item%value(pos:pos) /= ' ' .and. item%value(pos:pos) /= achar(10)) cycle
      end if
      if (pos > start) then
        star = index(item%value(start:pos - 1), '*')
        if (item%value(start + star:pos - 1) == '-' .or. item%value(start + star:pos - 1) == '+') lone_sign = .true.
      end if
      start = pos + 1
    end do
  end function lone_sign

  !> The kind ('r' real, 'i' integer, 't' text) and number of values of a
  !> group's own variable (read_namelist's).
  pure subroutine own_variable_shape(base, kind, capacity)
    character(len=*), intent(in) :: base
    character, intent(out) :: kind
    integer, intent(out) :: capacity
    capacity = 1
    select case (base)
    case ('t_end', 'interval', 'start', 'stop', 'low', 'high', 'factor', 'capacity'); kind = 'r'
    case ('values'); kind = 'r'; capacity = max_values
    case ('compression', 'count', 'samples', 'seed'); kind = 'i'
    case ('fields'); kind = 't'; capacity = max_fields
    case ('record_file'); kind = 't'; capacity = 3
    case ('sa_periods'); kind = 'r'; capacity = max_sa_periods
    case default; kind = 't'
    end select
  end subroutine own_variable_shape

  !> The largest magnitude the integer variable `base` of the namelists holds.
  pure integer(i8) function largest_whole(base)
    character(len=*), intent(in) :: base
    select case (base)
    case ('samples', 'seed'); largest_whole = huge(1_i8)
    case default; largest_whole = huge(1)
    end select
  end function largest_whole

  !> The length of the character variable `base` of the namelists (0: not one).
  pure integer function text_length(v, base)
    type(namelist_values_t), intent(in) :: v
    character(len=*), intent(in) :: base
    select case (base)
    case ('method', 'error_estimate'); text_length = len(v%method)
    case ('slip'); text_length = len(v%slip)
    case ('file'); text_length = len(v%file)
    case ('fields'); text_length = len(v%fields)
    case ('kind'); text_length = len(v%kind)
    case ('record_file'); text_length = len(v%record_file)
    case ('combine', 'invalid', 'spacing'); text_length = len(v%combine)
    case ('name'); text_length = len(v%name)
    case ('figure'); text_length = len(v%figure)
    case default; text_length = 0
    end select
  end function text_length

  !> The first row of the parameter table that namelist variable `base` of
  !> `group` sets, or 0.
  pure integer function variable_row(group, base) result(row)
    character(len=*), intent(in) :: group, base
    do row = 1, param_count
      if (params(row)%group == group .and. params(row)%variable == base) return
    end do
    row = 0
  end function variable_row

  !> An assignment to a variable of the parameter table, read as Fortran
  !> reads a namelist: a scalar, a whole vector, or elements of one.
  subroutine read_table_value(item, row, table_values, ios, msg)
    type(nml_assignment_t), intent(in) :: item
    integer, intent(in) :: row                       !< the variable's first row
    real(wp), intent(inout) :: table_values(:)
    integer, intent(out) :: ios
    character(len=*), intent(inout) :: msg
    real(wp) :: scalar, vector(3)
    namelist /table_scalar/ scalar
    namelist /table_vector/ vector
    character(len=:), allocatable :: record, subscript_and_value
    integer :: pos
    ! the source is 'base[(subscript)] = value': read it under our own name
    subscript_and_value = item%source(len(item%base) + 1:)
    do pos = 1, len(subscript_and_value)
      if (subscript_and_value(pos:pos) == achar(10)) subscript_and_value(pos:pos) = ' '
    end do
    if (param_width(row) == 1) then
      record = '&table_scalar scalar' // subscript_and_value // ' /'
      scalar = table_values(row)
      read (record, nml=table_scalar, iostat=ios, iomsg=msg)
      if (ios == 0) table_values(row) = scalar
      call rename_in_message(msg, 'scalar', item%base)
    else
      record = '&table_vector vector' // subscript_and_value // ' /'
      vector = table_values(row:row + 2)
      read (record, nml=table_vector, iostat=ios, iomsg=msg)
      if (ios == 0) table_values(row:row + 2) = vector
      call rename_in_message(msg, 'vector', item%base)
    end if
  end subroutine read_table_value

  !> gfortran's message about our stand-in variable, naming the user's.
  subroutine rename_in_message(msg, stand_in, base)
    character(len=*), intent(inout) :: msg
    character(len=*), intent(in) :: stand_in, base
    integer :: pos
    pos = index(msg, ' ' // stand_in, back=.true.)
    if (pos > 0) msg = msg(:pos) // base // msg(pos + 1 + len(stand_in):)
  end subroutine rename_in_message

  !> Unknown and repeated variables of group gi: it knows its rows of the
  !> parameter table and its own variables.
  logical function names_known(rd, gi) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=len(params%variable)), allocatable :: table_names(:), own_names(:)
    integer :: p
    associate (group => rd%file%groups(gi)%name)
      allocate (table_names, source=pack(params%variable, params%group == group .and. &
                                           [(param_component(p) <= 1, p = 1, param_count)]))
      allocate (own_names, source=own_variables(group))
      ok = check_names(rd, gi, [character(len=len(params%variable)) :: table_names, own_names])
    end associate
  end function names_known

  !> A group's variables outside the parameter table (read_namelist's).
  pure function own_variables(group) result(names)
    character(len=*), intent(in) :: group
    character(len=len(params%variable)), allocatable :: names(:)
    select case (group)
    case ('integration'); names = [character(len=len(names)) :: 'method', 't_end', 'error_estimate']
    case ('ball'); names = [character(len=len(names)) :: 'slip']
    case ('output'); names = [character(len=len(names)) :: 'file', 'interval', 'fields', 'compression']
    case ('excitation'); names = [character(len=len(names)) :: 'kind', 'record_file', 'sa_periods']
    case ('campaign'); names = [character(len=len(names)) :: 'combine', 'samples', 'seed', 'invalid']
    case ('sweep'); names = [character(len=len(names)) :: 'name', 'values', 'start', 'stop', 'count', 'spacing']
    case ('sample'); names = [character(len=len(names)) :: 'name', 'low', 'high', 'spacing']
    case ('record'); names = [character(len=len(names)) :: 'name', 'record_file', 'factor']
    case ('limit_state'); names = [character(len=len(names)) :: 'name', 'figure', 'capacity']
    case default; allocate (names(0))
    end select
  end function own_variables



  !> The message for an invalid case of a campaign: its index, the values
  !> that were varied, and what is wrong.
  subroutine describe_invalid(inp, cs, param, reason, text)
    type(run_input_t), intent(in) :: inp
    type(case_t), intent(in) :: cs
    integer, intent(in) :: param
    character(len=*), intent(in) :: reason
    character(len=:), allocatable, intent(out) :: text
    character(len=:), allocatable :: varied, subject
    integer :: k
    varied = ''
    do k = 1, size(inp%campaign%sweeps) + size(inp%campaign%samples)
      if (k > 1) varied = varied // ', '
      varied = varied // setting(varied_param(k))
    end do
    text = inp%path // ': case ' // itoa(cs%index)
    if (len(varied) > 0) text = text // ' (' // varied // ')'
    call problem_setting(cs, inp%plan%interval, param, subject)
    text = text // ': ' // subject // ': ' // reason
  contains
    integer function varied_param(k)
      integer, intent(in) :: k
      if (k <= size(inp%campaign%sweeps)) then
        varied_param = inp%campaign%sweeps(k)%param
      else
        varied_param = inp%campaign%samples(k - size(inp%campaign%sweeps))%param
      end if
    end function varied_param
    !> 'name = value' of row p in this case.
    pure function setting(p) result(s)
      integer, intent(in) :: p
      character(len=len_trim(params(p)%name) + 3 + len(format_real(get_param(cs, p)))) :: s
      s = trim(params(p)%name) // ' = ' // format_real(get_param(cs, p))
    end function setting
  end subroutine describe_invalid


  !> The longest quoted text in an assignment's source, as read (a doubled
  !> quote is one character), or the longest unquoted item after the '='.
  pure integer function longest_text(source) result(longest)
    character(len=*), intent(in) :: source
    integer :: pos, length
    character :: quote
    logical :: quoted
    longest = 0
    length = 0
    quoted = .false.
    quote = ' '
    pos = index(source, '=') + 1
    do while (pos <= len(source))
      if (quoted) then
        if (source(pos:pos) == quote) then
          if (source(pos:min(pos + 1, len(source))) == quote // quote) then
            pos = pos + 1                 ! a doubled quote: one character of the text
            length = length + 1
          else
            quoted = .false.
          end if
        else
          length = length + 1
        end if
      else if (source(pos:pos) == "'" .or. source(pos:pos) == '"') then
        quoted = .true.
        quote = source(pos:pos)
        length = 0
      else if (any(source(pos:pos) == [' ', ',', achar(9), achar(10)])) then
        length = 0
      else
        length = length + 1
      end if
      longest = max(longest, length)
      pos = pos + 1
    end do
  end function longest_text

  !> A one-assignment namelist in one record: '&group name = value /'.
  !> The assignment's lines are joined by blanks (the scanner blanked its
  !> comments, and no value spans a line break).
  pure subroutine assignment_record(grp, k, record)
    type(nml_group_t), intent(in) :: grp
    integer, intent(in) :: k
    character(len=:), allocatable, intent(out) :: record
    integer :: pos
    record = '&' // grp%name // ' ' // grp%items(k)%source // ' /'
    do pos = 1, len(record)
      if (record(pos:pos) == achar(10)) record(pos:pos) = ' '
    end do
  end subroutine assignment_record

  !> Groups and assignments in file order, without comments or layout: what
  !> decides whether two inputs describe the same campaign.
  !> (Its length counted first, then filled: a text grown a group at a time
  !> takes time growing as the square of the groups' count.)
  pure subroutine canonical_text(file, text)
    type(nml_file_t), intent(in) :: file
    character(len=:), allocatable, intent(out) :: text
    integer :: gi, k, n
    n = 0
    do gi = 1, size(file%groups)
      n = n + 1 + len(file%groups(gi)%name) + 3
      do k = 1, size(file%groups(gi)%items)
        n = n + 2 + len(file%groups(gi)%items(k)%name) + len(file%groups(gi)%items(k)%value)
      end do
    end do
    allocate (character(len=n) :: text)
    n = 0
    do gi = 1, size(file%groups)
      call put('&' // file%groups(gi)%name, text, n)
      do k = 1, size(file%groups(gi)%items)
        call put(' ' // file%groups(gi)%items(k)%name // '=' // file%groups(gi)%items(k)%value, text, n)
      end do
      call put(' /' // achar(10), text, n)
    end do
  contains
    pure subroutine put(piece, text, n)
      character(len=*), intent(in) :: piece
      character(len=*), intent(inout) :: text
      integer, intent(inout) :: n
      text(n + 1:n + len(piece)) = piece
      n = n + len(piece)
    end subroutine put
  end subroutine canonical_text

  real(wp) function nan()
    nan = ieee_value(0.0_wp, ieee_quiet_nan)
  end function nan
end module ellroll_input
