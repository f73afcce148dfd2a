!> Reading and validating the input namelist file into a campaign (a base
!> case, sweeps and samples) and an output plan. Every message a user sees
!> about input is written here, in ellroll_input_reader or in
!> ellroll_campaign_input; each names the file, line, group, variable and
!> value.
module ellroll_input
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite, ieee_is_nan, &
      ieee_set_halting_mode, ieee_usual
  use, intrinsic :: ieee_exceptions, only: ieee_status_type, ieee_get_status, ieee_set_status
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_namelist_scan, only: nml_file_t, nml_group_t, nml_assignment_t, scan_namelist_file, &
      scan_namelist_text
  use ellroll_strings, only: lower, itoa, join, format_real
  use ellroll_cases, only: case_t, output_plan_t, check_case, finalize_case, field_names, field_ncomp, &
      get_param, set_param, adaptive_method, range_text, max_steps, field_base_acceleration, is_multiple
  use ellroll_campaign, only: campaign_t, sweep_t, sample_t
  use ellroll_excitation, only: excitation_none, excitation_harmonic, excitation_record, set_record
  use ellroll_integrators, only: method_names
  use ellroll_record_file, only: load_ground_motion
  use ellroll_input_reader, only: reader_t, namelist_values_t, check_names, max_values, max_fields
  use ellroll_campaign_input, only: add_sweep, add_sample, build_campaign
  use ellroll_suite_input, only: record_spec_t, add_record_group, load_suite, record_files, note_files
  use ellroll_params, only: params, param_count, param_default, param_component, param_width, p_radius, &
      p_weight, p_mass, p_dt, p_scale
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

  character(len=*), parameter :: known_groups(11) = [character(len=12) :: &
      'geometry', 'ball', 'environment', 'initial', 'integration', 'output', 'excitation', 'campaign', &
      'sweep', 'sample', 'record']
  !> Largest memory one case's output buffers may take.
  real(wp), parameter :: max_case_buffer_bytes = 2.0_wp**31



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
    if (.not. rd%err%failed()) then
      do k = 1, size(rd%file%groups)
        associate (grp => rd%file%groups(k))
          if (.not. any(known_groups == grp%name)) then
            call rd%fail_at(grp%line, 'unknown group &' // grp%name // ' (known groups: ' // &
                            join(known_groups) // ')')
          else if (all(grp%name /= [character(len=6) :: 'sweep', 'sample', 'record'])) then
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

  !> The namelist variables outside the parameter table are declared in
  !> this one scope, so that one loop reads every assignment of every group;
  !> each assignment is read alone.
  subroutine read_groups(rd, output_override, inp)
    type(reader_t), intent(inout) :: rd
    character(len=*), intent(in) :: output_override
    type(run_input_t), intent(inout) :: inp
    real(wp) :: table_values(param_count)
    ! &integration, &output
    character(len=32) :: method, error_estimate
    real(wp) :: t_end, interval
    character(len=1024) :: file
    character(len=32) :: fields(max_fields)
    integer :: compression
    ! &excitation
    character(len=16) :: kind
    character(len=1024) :: record_file(3), excitation_files(3)
    real(wp) :: factor
    ! &campaign, &sweep, &sample
    character(len=16) :: combine, invalid, spacing
    integer(i8) :: samples, seed
    character(len=32) :: name
    real(wp) :: values(max_values), start, stop, low, high
    integer :: count
    namelist /integration/ method, t_end, error_estimate
    namelist /output/ file, interval, fields, compression
    namelist /excitation/ kind, record_file
    namelist /campaign/ combine, samples, seed, invalid
    namelist /sweep/ name, values, start, stop, count, spacing
    namelist /sample/ name, low, high, spacing
    namelist /record/ name, record_file, factor
    integer :: gi, k, ios
    character(len=512) :: msg
    type(sweep_t), allocatable :: sweeps(:)
    type(sample_t), allocatable :: draws(:)
    type(namelist_values_t) :: v
    type(record_spec_t), allocatable :: suite(:)

    table_values = [(param_default(k), k = 1, param_count)]     ! NaN: required
    method = 'rk4'; t_end = nan(); error_estimate = 'none'
    file = ''; interval = nan(); fields = ''; compression = 0
    combine = 'grid'; invalid = 'stop'; samples = 0; seed = 0
    kind = 'none'; record_file = ''; factor = 1
    allocate (sweeps(0), draws(0), suite(0))

    do gi = 1, size(rd%file%groups)
      associate (grp => rd%file%groups(gi))
        if (.not. names_known(rd, gi)) return
        name = ''; values = nan(); start = nan(); stop = nan(); count = 0; spacing = 'linear'
        low = nan(); high = nan()
        if (grp%name == 'record') then       ! (its record_file is not &excitation's)
          excitation_files = record_file
          record_file = ''
          factor = 1
        end if
        do k = 1, size(grp%items)
          associate (item => grp%items(k))
            ! a longer text would be cut to the variable's length without a word
            if (text_length(item%base) > 0 .and. longest_text(item%source) > text_length(item%base)) then
              call rd%fail_at(item%line, '&' // grp%name // ': ' // item%name // ' = ' // item%value // &
                  ': a text of ' // itoa(longest_text(item%source)) // ' characters (blanks included); at most ' // &
                  itoa(text_length(item%base)) // ' fit')
              return
            end if
          end associate
          call read_assignment(grp, k, ios, msg)
          if (ios /= 0) then
            associate (item => grp%items(k))
              call rd%fail_at(item%line, '&' // grp%name // ': ' // item%name // ' = ' // item%value // &
                  ': not a valid value for this variable (wrong type, or more items than it holds; ' // &
                  'gfortran says: ' // trim(msg) // ')')
            end associate
            return
          end if
        end do
        if (grp%name == 'sweep') call add_sweep(rd, current(), gi, sweeps, draws)
        if (grp%name == 'sample') call add_sample(rd, current(), gi, sweeps, draws)
        if (grp%name == 'record') then
          call add_record_group(rd, current(), gi, suite)
          record_file = excitation_files
        end if
        if (rd%err%failed()) return
      end associate
    end do

    v = current()
    call build_base(rd, v, inp%campaign%base)
    if (rd%err%failed()) return
    inp%input_files = ''
    call build_excitation(rd, v, size(suite) > 0, inp%campaign%base, inp%input_files)
    if (rd%err%failed()) return
    call load_suite(rd, suite, inp%campaign%base, inp%campaign%records, inp%input_files)
    if (rd%err%failed()) return
    call build_plan(rd, v, output_override, inp%campaign%base, inp%plan)
    if (rd%err%failed()) return
    call check_base(rd, inp%campaign%base, inp%plan)
    if (rd%err%failed()) return
    call build_campaign(rd, v, sweeps, draws, inp%campaign)

  contains
    !> Read assignment k of a group alone: into the parameter table's values,
    !> or into the variables of its namelist.
    subroutine read_assignment(grp, k, ios, msg)
      type(nml_group_t), intent(in) :: grp
      integer, intent(in) :: k
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
        call read_table_value(grp%items(k), row, table_values, ios, msg)
      else
        select case (grp%name)
        case ('integration'); read (one_assignment, nml=integration, iostat=ios, iomsg=msg)
        case ('output'); read (one_assignment, nml=output, iostat=ios, iomsg=msg)
        case ('excitation'); read (one_assignment, nml=excitation, iostat=ios, iomsg=msg)
        case ('campaign'); read (one_assignment, nml=campaign, iostat=ios, iomsg=msg)
        case ('sweep'); read (one_assignment, nml=sweep, iostat=ios, iomsg=msg)
        case ('sample'); read (one_assignment, nml=sample, iostat=ios, iomsg=msg)
        case ('record'); read (one_assignment, nml=record, iostat=ios, iomsg=msg)
        end select
      end if
      call ieee_set_status(fp_state)
    end subroutine read_assignment

    !> The length of the character variable `base` (0: not one).
    integer function text_length(base)
      character(len=*), intent(in) :: base
      select case (base)
      case ('method'); text_length = len(method)
      case ('error_estimate'); text_length = len(error_estimate)
      case ('file'); text_length = len(file)
      case ('fields'); text_length = len(fields)
      case ('kind'); text_length = len(kind)
      case ('record_file'); text_length = len(record_file)
      case ('combine'); text_length = len(combine)
      case ('invalid'); text_length = len(invalid)
      case ('spacing'); text_length = len(spacing)
      case ('name'); text_length = len(name)
      case default; text_length = 0
      end select
    end function text_length

    !> The namelist variables as they stand.
    type(namelist_values_t) function current() result(now)
      now%param = table_values
      now%method = method
      now%error_estimate = error_estimate
      now%t_end = t_end
      now%interval = interval
      now%file = file
      now%fields = fields
      now%compression = compression
      now%kind = kind
      now%record_file = record_file
      now%factor = factor
      now%combine = combine
      now%invalid = invalid
      now%spacing = spacing
      now%samples = samples
      now%seed = seed
      now%name = name
      now%values = values
      now%start = start
      now%stop = stop
      now%low = low
      now%high = high
      now%count = count
    end function current
  end subroutine read_groups

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

  logical function names_known(rd, gi) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=20), allocatable :: table_names(:)
    integer :: p
    associate (group => rd%file%groups(gi)%name)
      allocate (table_names, source=pack(params%variable, params%group == group .and. &
                                           [(param_component(p) <= 1, p = 1, param_count)]))
      select case (group)
      case ('integration'); ok = check_names(rd, gi, [table_names, [character(len=20) :: 'method', 't_end', &
                                                      'error_estimate']])
      case ('output'); ok = check_names(rd, gi, [character(len=20) :: 'file', 'interval', 'fields', &
                                                 'compression'])
      case ('excitation'); ok = check_names(rd, gi, [table_names, [character(len=20) :: 'kind', 'record_file']])
      case ('campaign'); ok = check_names(rd, gi, [character(len=20) :: 'combine', 'samples', 'seed', &
                                                   'invalid'])
      case ('sweep'); ok = check_names(rd, gi, [character(len=20) :: 'name', 'values', 'start', 'stop', &
                                                'count', 'spacing'])
      case ('sample'); ok = check_names(rd, gi, [character(len=20) :: 'name', 'low', 'high', 'spacing'])
      case ('record'); ok = check_names(rd, gi, [character(len=20) :: 'name', 'record_file', 'factor'])
      case default; ok = check_names(rd, gi, table_names)
      end select
    end associate
  end function names_known

  !> Row p's namelist variable holds finite numbers in their rows' ranges
  !> (a scalar, or a vector from its first row), and is given if `needed`.
  logical function check_variable(rd, gi, p, table_values, needed) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi, p
    real(wp), intent(in) :: table_values(:)
    logical, intent(in) :: needed
    character(len=:), allocatable :: variable, units
    integer :: width, k
    variable = trim(params(p)%variable)
    width = param_width(p)
    ok = .false.
    units = trim(params(p)%unit)
    if (needed .and. .not. rd%given(gi, variable)) then
      if (width == 1) then
        call rd%fail_missing(gi, variable, 'add ' // variable // ' = <value> (' // units // ') to &' // &
                             trim(params(p)%group))
      else
        call rd%fail_missing(gi, variable, 'add ' // variable // ' = <x>, <y>, <z> (' // units // ') to &' // &
                             trim(params(p)%group))
      end if
    else if (.not. all(ieee_is_finite(table_values(p:p + width - 1)))) then
      if (width == 1) then
        call rd%fail_value(gi, variable, 'must be a finite number')
      else
        call rd%fail_value(gi, variable, 'three finite numbers are needed (x, y, z in ' // units // ')')
      end if
    else
      do k = p, p + width - 1
        if (table_values(k) < params(k)%low .or. table_values(k) > params(k)%high) then
          if (params(k)%positive .and. table_values(k) > 0 .and. table_values(k) < params(k)%low) then
            call rd%fail_value(gi, variable, 'is below ' // format_real(params(k)%low) // &
                               ', the least normal number; ' // range_text(k))
          else
            call rd%fail_value(gi, variable, range_text(k))
          end if
          return
        end if
      end do
      ok = .true.
    end if
  end function check_variable

  !> The rows of the parameter table given directly: every required one is
  !> there (weight or mass, and dt unless the method is adaptive), all are
  !> finite. The excitation's rows are taken with their kind.
  subroutine build_base(rd, v, cs)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(inout) :: v
    type(case_t), intent(out) :: cs
    integer :: gi, p
    do p = 1, param_count
      if (param_component(p) > 1 .or. params(p)%group == 'excitation') cycle
      if (any(p == [p_weight, p_mass, p_dt])) cycle
      gi = rd%group(trim(params(p)%group), params(p)%required)
      if (gi == 0 .and. params(p)%required) return
      if (gi == 0) cycle
      if (.not. check_variable(rd, gi, p, v%param, params(p)%required)) return
      if (p == p_radius) then           ! the ball's size, then its weight or mass
        if (.not. weight_or_mass(rd, v%param, cs)) return
      end if
    end do
    gi = rd%group('integration', .true.)
    if (gi == 0) return
    v%method = lower(adjustl(v%method))
    if (index(' ' // method_names() // ' ', ' ' // trim(v%method) // ' ') == 0 .or. len_trim(v%method) == 0) then
      call rd%fail_value(gi, 'method', 'unknown method (known: ' // method_names() // ')')
      return
    end if
    if (.not. rd%require(gi, 't_end', v%t_end)) return
    ! an adaptive method chooses its steps; dt, if given, is the largest
    if (.not. (adaptive_method(v%method) .and. .not. rd%given(gi, 'dt'))) then
      if (.not. check_variable(rd, gi, p_dt, v%param, .true.)) return
    end if
    select case (lower(adjustl(v%error_estimate)))
    case ('none'); cs%error_estimate = .false.
    case ('reference'); cs%error_estimate = .true.
    case default
      call rd%fail_value(gi, 'error_estimate', "must be 'none' or 'reference'")
      return
    end select
    if (v%t_end <= 0 .or. v%t_end > 1.0e9_wp) then
      call rd%fail_value(gi, 't_end', 'must be > 0 and <= 1e9 s')
      return
    end if
    do p = 1, param_count
      if (params(p)%group /= 'excitation' .and. p /= p_weight .and. p /= p_mass) call set_param(cs, p, v%param(p))
    end do
    cs%method = v%method; cs%t_end = v%t_end
    call finalize_case(cs)
  end subroutine build_base

  !> Exactly one of weight and mass, into the case.
  logical function weight_or_mass(rd, table_values, cs) result(ok)
    type(reader_t), intent(inout) :: rd
    real(wp), intent(in) :: table_values(:)
    type(case_t), intent(inout) :: cs
    integer :: gi
    ok = .false.
    gi = rd%group('ball', .true.)
    if (rd%given(gi, 'weight') .and. rd%given(gi, 'mass')) then
      call rd%fail_value(gi, 'mass', 'give exactly one of weight (N) and mass (kg), not both')
    else if (rd%given(gi, 'weight')) then
      if (.not. check_variable(rd, gi, p_weight, table_values, .true.)) return
      cs%weight = table_values(p_weight)
      ok = .true.
    else if (rd%given(gi, 'mass')) then
      if (.not. check_variable(rd, gi, p_mass, table_values, .true.)) return
      cs%mass = table_values(p_mass)
      ok = .true.
    else
      call rd%fail_missing(gi, 'weight', 'give exactly one of weight (N) and mass (kg)')
    end if
  end function weight_or_mass

  !> The cup's motion: its kind, and the inputs of that kind (a harmonic's
  !> amplitude, frequency and phase; a record's files, or a suite's &record
  !> groups, and scale).
  subroutine build_excitation(rd, v, suite, cs, files_note)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    logical, intent(in) :: suite            !< &record groups give the records
    type(case_t), intent(inout) :: cs
    character(len=:), allocatable, intent(inout) :: files_note   !< the record's files (note_files)
    integer :: gi, p, k
    character(len=:), allocatable :: reason
    character(len=1024), allocatable :: paths(:)
    character(len=40), allocatable :: fingerprints(:)
    real(wp), allocatable :: times(:), values(:, :)
    gi = rd%group('excitation', .false.)
    if (gi == 0) then
      if (suite) cs%excitation%kind = excitation_record
      return
    end if
    if (suite .and. lower(adjustl(v%kind)) /= 'record') then
      call rd%fail_value(gi, 'kind', "must be 'record' with &record groups (a suite of records)")
      return
    end if
    select case (lower(adjustl(v%kind)))
    case ('none')
      cs%excitation%kind = excitation_none
      if (.not. only_for_kind(rd, gi, 'none')) return
    case ('harmonic')
      cs%excitation%kind = excitation_harmonic
      if (.not. only_for_kind(rd, gi, 'harmonic')) return
      do p = 1, param_count
        if (params(p)%group /= 'excitation' .or. p == p_scale) cycle
        if (param_component(p) <= 1) then
          if (.not. check_variable(rd, gi, p, v%param, .false.)) return
        end if
        call set_param(cs, p, v%param(p))
      end do
    case ('record')
      cs%excitation%kind = excitation_record
      if (.not. only_for_kind(rd, gi, 'record')) return
      if (.not. check_variable(rd, gi, p_scale, v%param, .false.)) return
      cs%excitation%scale = v%param(p_scale)
      if (suite) then
        if (rd%given(gi, 'record_file')) call rd%fail_value(gi, 'record_file', &
            'the &record groups give the records; record_file here is for a single record')
        return
      end if
      if (.not. record_files(rd, gi, v%record_file, paths)) return
      allocate (fingerprints(size(paths)))
      call load_ground_motion(paths, cs%t_end, 1.0_wp, times, values, reason, fingerprints)
      if (len(reason) > 0) then
        call rd%fail_value(gi, 'record_file', reason)
        return
      end if
      call note_files([character(len=1024) :: (adjustl(v%record_file(k)), k = 1, size(paths))], fingerprints, &
                      files_note)
      call set_record(cs%excitation, times, values)
    case default
      call rd%fail_value(gi, 'kind', "must be 'none', 'harmonic' or 'record'")
    end select
  end subroutine build_excitation

  !> The inputs of &excitation that belong to another kind are refused.
  logical function only_for_kind(rd, gi, kind) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: kind
    character(len=*), parameter :: harmonic_inputs(3) = [character(len=9) :: 'amplitude', 'frequency', 'phase']
    character(len=*), parameter :: record_inputs(2) = [character(len=11) :: 'record_file', 'scale']
    integer :: k
    ok = .false.
    do k = 1, size(harmonic_inputs)
      if (kind /= 'harmonic' .and. rd%given(gi, trim(harmonic_inputs(k)))) then
        call rd%fail_value(gi, trim(harmonic_inputs(k)), "applies to kind = 'harmonic' only")
        return
      end if
    end do
    do k = 1, size(record_inputs)
      if (kind /= 'record' .and. rd%given(gi, trim(record_inputs(k)))) then
        call rd%fail_value(gi, trim(record_inputs(k)), "applies to kind = 'record' only")
        return
      end if
    end do
    ok = .true.
  end function only_for_kind

  subroutine build_plan(rd, v, output_override, cs, plan)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    character(len=*), intent(in) :: output_override
    type(case_t), intent(inout) :: cs
    type(output_plan_t), intent(inout) :: plan
    integer :: gi, k, f
    real(wp) :: bytes_per_sample
    character(len=32) :: field
    gi = rd%group('output', .true.)
    if (gi == 0) return
    ! (len first: a caller's constant '' then removes the copy at link time,
    ! which GCC's link-time optimiser would otherwise flag as an overread)
    if (len(output_override) > 0 .and. len_trim(output_override) > 0) then
      plan%file = trim(output_override)
    else if (len_trim(v%file) > 0) then
      plan%file = trim(adjustl(v%file))
    else
      call rd%fail_missing(gi, 'file', 'name the HDF5 file to write (or pass -o FILE)')
      return
    end if
    if (.not. rd%require(gi, 'interval', v%interval)) return
    if (v%interval <= 0 .or. v%interval > cs%t_end) then
      call rd%fail_value(gi, 'interval', 'must be > 0 and <= t_end = ' // format_real(cs%t_end) // ' s')
      return
    end if
    if (cs%t_end > max_steps * v%interval) then       ! (not t_end / interval: it may overflow)
      call rd%fail_value(gi, 'interval', 'must be at least t_end / ' // format_real(max_steps) // ' = ' // &
                         format_real(cs%t_end / max_steps) // ' s: no case stores more samples than steps')
      return
    end if
    if (.not. is_multiple(cs%t_end, v%interval)) then
      call rd%fail_value(gi, 'interval', 't_end = ' // format_real(cs%t_end) // &
                         ' s must be a whole number of output intervals')
      return
    end if
    plan%interval = v%interval
    plan%n_samples = nint(cs%t_end / v%interval, i8) + 1
    if (ieee_is_nan(cs%dt)) cs%dt = cs%t_end       ! adaptive, no dt given: steps limited by accuracy alone

    ! the cup's acceleration is stored only when the cup moves
    plan%fields(field_base_acceleration) = cs%excitation%kind /= excitation_none
    if (rd%given(gi, 'fields')) then
      plan%fields = .false.
      do k = 1, max_fields
        field = lower(adjustl(v%fields(k)))
        if (len_trim(field) == 0 .or. field == 'none') cycle
        if (field == 'all') then
          plan%fields = .true.
          cycle
        end if
        f = findloc(field_names, trim(field), dim=1)
        if (f == 0) then
          call rd%fail_value(gi, 'fields', "unknown field '" // trim(field) // "' (known: " // &
                             join(field_names) // ', all, none)')
          return
        end if
        plan%fields(f) = .true.
      end do
    end if
    if (v%compression < 0 .or. v%compression > 9) then
      call rd%fail_value(gi, 'compression', 'must be 0 (none) to 9 (deflate level, with shuffle)')
      return
    end if
    plan%compression = v%compression
    bytes_per_sample = 8.0_wp * sum(field_ncomp, mask=plan%fields)
    if (bytes_per_sample * real(plan%n_samples, wp) > max_case_buffer_bytes) then
      call rd%fail_value(gi, 'interval', 'the trajectory of one case would need ' // &
          format_real(bytes_per_sample * real(plan%n_samples, wp) / 2.0_wp**30) // &
          ' GiB; raise interval or select fewer fields')
    end if
  end subroutine build_plan

  !> The base case must be valid whatever the sweeps do; its messages point
  !> at the variable's line.
  subroutine check_base(rd, cs, plan)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(inout) :: plan
    integer :: param, gi
    character(len=:), allocatable :: reason, variable
    call check_case(cs, plan%interval, param, reason)
    if (param /= 0) then
      gi = rd%group(trim(params(param)%group), .true.)
      variable = trim(params(param)%variable)
      if (variable == 'dt' .and. index(reason, 'output interval') > 0) then
        gi = rd%group('output', .true.)
        variable = 'interval'
        reason = 'must be a whole number of steps dt = ' // format_real(cs%dt) // ' s'
      end if
      call rd%fail_value(gi, variable, reason)
      return
    end if
  end subroutine check_base


  !> The message for an invalid case of a campaign: its index, the values
  !> that were varied, and what is wrong.
  subroutine describe_invalid(inp, cs, param, reason, text)
    type(run_input_t), intent(in) :: inp
    type(case_t), intent(in) :: cs
    integer, intent(in) :: param
    character(len=*), intent(in) :: reason
    character(len=:), allocatable, intent(out) :: text
    character(len=:), allocatable :: varied
    integer :: k
    varied = ''
    do k = 1, size(inp%campaign%sweeps) + size(inp%campaign%samples)
      if (k > 1) varied = varied // ', '
      varied = varied // setting(varied_param(k))
    end do
    text = inp%path // ': case ' // itoa(cs%index)
    if (len(varied) > 0) text = text // ' (' // varied // ')'
    text = text // ': ' // setting(param) // ': ' // reason
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
  pure subroutine canonical_text(file, text)
    type(nml_file_t), intent(in) :: file
    character(len=:), allocatable, intent(out) :: text
    integer :: gi, k
    text = ''
    do gi = 1, size(file%groups)
      text = text // '&' // file%groups(gi)%name
      do k = 1, size(file%groups(gi)%items)
        text = text // ' ' // file%groups(gi)%items(k)%name // '=' // file%groups(gi)%items(k)%value
      end do
      text = text // ' /' // achar(10)
    end do
  end subroutine canonical_text



  real(wp) function nan()
    nan = ieee_value(0.0_wp, ieee_quiet_nan)
  end function nan
end module ellroll_input
