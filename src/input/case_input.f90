!> The base case, the output plan and the campaign from the namelist values
!> read (ellroll_input reads them): every real input of the parameter table
!> checked against its row, the excitation, the output and the case as a
!> whole, each message naming the file, line, group, variable and value.
module ellroll_case_input
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: lower, join, format_real, format_computed
  use ellroll_cases, only: case_t, output_plan_t, check_case, finalize_case, field_names, field_ncomp, &
      set_param, adaptive_method, out_of_range_reason, max_steps, field_base_acceleration, is_multiple, &
      field_regime, field_slip_speed
  use ellroll_campaign, only: campaign_t, sweep_t, sample_t
  use ellroll_excitation, only: excitation_none, excitation_harmonic, excitation_record, set_record
  use ellroll_record_store, only: record_samples, no_room_for_record
  use ellroll_integrators, only: method_names, methods
  use ellroll_record_file, only: load_ground_motion
  use ellroll_input_reader, only: reader_t, namelist_values_t, max_fields, count_given, not_finite_entry
  use ellroll_suggest, only: did_you_mean
  use ellroll_files, only: output_name_problem, path_length
  use ellroll_intensity, only: intensity_of
  use ellroll_campaign_input, only: build_campaign
  use ellroll_applies, only: excitation_inputs, kind_of_input
  use ellroll_suite_input, only: record_spec_t, load_suite, record_files, note_files
  use ellroll_params, only: params, param_count, param_component, param_width, param_unset_allowed, p_radius, &
      p_weight, p_mass, p_dt, p_scale
  implicit none
  private

  public :: build_input

  !> Largest memory one case's output buffers may take.
  real(wp), parameter :: max_case_buffer_bytes = 2.0_wp**31

contains

  !> The campaign (its base case, records, sweeps and samples), the output
  !> plan and the note of the input's files from the values read.
  subroutine build_input(rd, v, output_override, sweeps, draws, suite, campaign, plan, input_files)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(inout) :: v
    character(len=*), intent(in) :: output_override
    type(sweep_t), intent(in) :: sweeps(:)
    type(sample_t), intent(in) :: draws(:)
    type(record_spec_t), intent(in) :: suite(:)
    type(campaign_t), intent(inout) :: campaign
    type(output_plan_t), intent(inout) :: plan
    character(len=:), allocatable, intent(inout) :: input_files
    call build_base(rd, v, campaign%base)
    if (rd%err%failed()) return
    input_files = ''
    call build_excitation(rd, v, size(suite) > 0, campaign%base, input_files)
    if (rd%err%failed()) return
    call load_suite(rd, suite, campaign%base, campaign%records, input_files)
    if (rd%err%failed()) return
    call set_intensities(rd, v, campaign)
    if (rd%err%failed()) return
    call build_plan(rd, v, output_override, campaign%base, plan)
    if (rd%err%failed()) return
    call check_base(rd, campaign%base, plan)
    if (rd%err%failed()) return
    call build_campaign(rd, v, sweeps, draws, campaign)

  end subroutine build_input

  !> Row p's namelist variable, where given, holds finite numbers in their
  !> rows' ranges (a scalar, or a vector from its first row); it must be
  !> given if `needed`.
  logical function check_variable(rd, gi, p, table_values, needed) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi, p
    real(wp), intent(in) :: table_values(:)
    logical, intent(in) :: needed
    character(len=:), allocatable :: variable, units, reason
    integer :: width, k
    variable = trim(params(p)%variable)
    width = param_width(p)
    ok = .false.
    units = trim(params(p)%unit)
    if (.not. (needed .or. rd%given(gi, variable))) then
      ok = .true.             ! the row's default (none for param_unset_allowed: NaN)
    else if (.not. rd%given(gi, variable)) then
      if (width == 1) then
        call rd%fail_missing(gi, variable, 'add ' // variable // ' = <value> (' // units // ') to &' // &
                             trim(params(p)%group))
      else
        call rd%fail_missing(gi, variable, 'add ' // variable // ' = <x>, <y>, <z> (' // units // ') to &' // &
                             trim(params(p)%group))
      end if
    else if (.not. all(ieee_is_finite(table_values(p:p + width - 1))) .and. &
             .not. (param_unset_allowed(p) .and. any(out_of_range(p, width, table_values)))) then
      if (width == 1) then
        call rd%fail_value(gi, variable, 'must be a finite number')
      else
        call rd%fail_value(gi, variable, 'three finite numbers are needed (x, y, z in ' // units // ')')
      end if
    else
      do k = p, p + width - 1
        if (.not. out_of_range_one(k, table_values(k))) cycle
        if (table_values(k) < params(k)%low .or. table_values(k) > params(k)%high) then
          call out_of_range_reason(k, table_values(k), reason)
          call rd%fail_value(gi, variable, reason)
          return
        end if
      end do
      ok = .true.
    end if
  end function check_variable

  !> Whether each component of row p's variable (width rows) holds a finite
  !> value outside its range: a vector that may be left unset is judged on
  !> the components given before it is asked for all three.
  pure function out_of_range(p, width, table_values) result(outside)
    integer, intent(in) :: p, width
    real(wp), intent(in) :: table_values(:)
    logical :: outside(width)
    integer :: k
    do k = 1, width
      outside(k) = out_of_range_one(p + k - 1, table_values(p + k - 1))
    end do
  end function out_of_range

  pure logical function out_of_range_one(k, value)
    integer, intent(in) :: k
    real(wp), intent(in) :: value
    out_of_range_one = .false.
    if (ieee_is_finite(value)) out_of_range_one = value < params(k)%low .or. value > params(k)%high
  end function out_of_range_one

  !> The rows of the parameter table given directly: every required one is
  !> there (weight or mass, and dt unless the method is adaptive), all are
  !> finite. The excitation's rows are taken with their kind.
  subroutine build_base(rd, v, cs)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(inout) :: v
    type(case_t), intent(out) :: cs
    integer :: gi, p
    character(len=:), allocatable :: hint
    character(len=len(methods%name)) :: method_list(size(methods))
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
      method_list = methods%name          ! (contiguous: no array temporary)
      call did_you_mean(trim(v%method), method_list, '', hint)
      call rd%fail_value(gi, 'method', 'unknown method' // hint // ' (known: ' // method_names() // ')')
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
    ! 'end' by default: a case whose friction falls short ends with status
    ! slip, as the rolling model states; sliding is a regime asked for
    gi = rd%group('ball', .true.)
    if (gi == 0) return
    select case (lower(adjustl(v%slip)))
    case ('end'); cs%slide = .false.
    case ('slide'); cs%slide = .true.
    case default
      call rd%fail_value(gi, 'slip', "must be 'end' or 'slide'")
      return
    end select
    gi = rd%group('integration', .true.)
    if (v%t_end <= 0 .or. v%t_end > 1.0e9_wp) then
      call rd%fail_value(gi, 't_end', 'must be > 0 and <= 1e9 s')
      return
    end if
    do p = 1, param_count
      if (params(p)%group /= 'excitation' .and. p /= p_weight .and. p /= p_mass) call set_param(cs, p, v%param(p))
    end do
    cs%method = v%method; cs%t_end = v%t_end
    ! gauss4's simplified Newton takes its Jacobian by differences at the
    ! step's start: where the slip is zero (the switch into sliding) the
    ! friction's direction turns over the difference, and no stage converges
    if (cs%slide .and. lower(adjustl(cs%method)) == 'gauss4') then
      call rd%fail_value(rd%group('ball', .true.), 'slip', &
                         "does not run with &integration method = 'gauss4': use rk4, dop853 or vern9")
      return
    end if
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
      cs%param(p_weight) = table_values(p_weight)
      ok = .true.
    else if (rd%given(gi, 'mass')) then
      if (.not. check_variable(rd, gi, p_mass, table_values, .true.)) return
      cs%param(p_mass) = table_values(p_mass)
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
    integer :: gi, p
    character(len=:), allocatable :: reason
    character(len=path_length), allocatable :: paths(:)
    character(len=40), allocatable :: fingerprints(:)
    real(wp), allocatable :: times(:), values(:, :)
    logical :: held
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
      cs%param(p_scale) = v%param(p_scale)
      if (suite) then
        if (rd%given(gi, 'record_file')) call rd%fail_value(gi, 'record_file', &
            'the &record groups give the records; record_file here is for a single record')
        return
      end if
      if (.not. record_files(rd, gi, v%record_file, paths)) return
      allocate (fingerprints(size(paths)))
      call load_ground_motion(paths, 1.0_wp, times, values, reason, fingerprints)
      if (len(reason) > 0) then
        call rd%fail_value(gi, 'record_file', reason)
        return
      end if
      call note_files(adjustl(v%record_file(:size(paths))), fingerprints, files_note)
      call set_record(cs%excitation, times, values, held)
      if (.not. held) call rd%fail_value(gi, 'record_file', no_room_for_record)
    case default
      call rd%fail_value(gi, 'kind', "must be 'none', 'harmonic' or 'record'")
    end select
  end subroutine build_excitation

  !> The intensity measures of each record (the suite's, or the single
  !> one), at the periods of &excitation sa_periods: given, each finite,
  !> in (0, max_sa_period] s, increasing.
  subroutine set_intensities(rd, v, campaign)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    type(campaign_t), intent(inout) :: campaign
    real(wp), parameter :: max_sa_period = 1.0e3_wp
    integer :: gi, n, k
    character(len=:), allocatable :: what
    gi = rd%group('excitation', .false.)
    n = count_given(v%sa_periods)
    do k = 1, n
      if (.not. ieee_is_finite(v%sa_periods(k))) then
        call not_finite_entry(v%sa_periods, k, what)
        call rd%fail_value(gi, 'sa_periods', what // ': each period must be a finite number (s)')
        return
      else if (v%sa_periods(k) <= 0 .or. v%sa_periods(k) > max_sa_period) then
        call rd%fail_value(gi, 'sa_periods', 'period ' // format_real(v%sa_periods(k)) // &
                           ' s is outside (0, ' // format_real(max_sa_period) // '] s')
        return
      else if (v%sa_periods(k) <= v%sa_periods(max(1, k - 1)) .and. k > 1) then
        call rd%fail_value(gi, 'sa_periods', 'the periods must increase (' // format_real(v%sa_periods(k)) // &
                           ' s follows ' // format_real(v%sa_periods(max(1, k - 1))) // ' s)')
        return
      end if
    end do
    if (campaign%base%excitation%kind /= excitation_record) return
    if (allocated(campaign%records)) then
      if (size(campaign%records) > 0) then
        do k = 1, size(campaign%records)
          associate (motion => record_samples(campaign%records(k)%motion%record))
            campaign%records(k)%intensity = intensity_of(motion%times, motion%values, v%sa_periods(:n))
          end associate
        end do
        campaign%base%intensity = campaign%records(1)%intensity
        return
      end if
    end if
    associate (motion => record_samples(campaign%base%excitation%record))
      campaign%base%intensity = intensity_of(motion%times, motion%values, v%sa_periods(:n))
    end associate
  end subroutine set_intensities

  !> The inputs of &excitation that belong to another kind are refused
  !> (a &sweep or &sample of one is refused alike: ellroll_applies).
  logical function only_for_kind(rd, gi, kind) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: kind
    character(len=:), allocatable :: belongs
    integer :: k
    ok = .false.
    do k = 1, size(excitation_inputs)
      belongs = trim(kind_of_input(trim(excitation_inputs(k))))
      if (kind /= belongs .and. rd%given(gi, trim(excitation_inputs(k)))) then
        call rd%fail_value(gi, trim(excitation_inputs(k)), "applies to kind = '" // belongs // "' only")
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
    character(len=:), allocatable :: hint
    gi = rd%group('output', .true.)
    if (gi == 0) return
    ! (len first: a caller's constant '' then removes the copy at link time,
    ! which GCC's link-time optimiser would otherwise flag as an overread)
    if (len(output_override) > 0 .and. len_trim(output_override) > 0) then
      plan%file = trim(output_override)
    else if (len_trim(v%file) > 0) then
      plan%file = trim(adjustl(v%file))
      call output_name_problem(plan%file, hint)
      if (len(hint) > 0) then
        call rd%fail_value(gi, 'file', hint)
        return
      end if
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
                         format_computed(cs%t_end / max_steps) // ' s: no case stores more samples than steps')
      return
    end if
    if (.not. is_multiple(cs%t_end, v%interval)) then
      call rd%fail_value(gi, 'interval', 't_end = ' // format_real(cs%t_end) // &
                         ' s must be a whole number of output intervals')
      return
    end if
    plan%interval = v%interval
    plan%n_samples = nint(cs%t_end / v%interval, i8) + 1
    ! adaptive, no dt given: steps limited by accuracy alone
    if (ieee_is_nan(cs%param(p_dt))) cs%param(p_dt) = cs%t_end

    ! the cup's acceleration is stored only when the cup moves
    plan%fields(field_base_acceleration) = cs%excitation%kind /= excitation_none
    ! the regime and the slip speed only when the ball may slide
    plan%fields([field_regime, field_slip_speed]) = cs%slide
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
          call did_you_mean(trim(field), field_names, '', hint)
          call rd%fail_value(gi, 'fields', "unknown field '" // trim(field) // "'" // hint // " (known: " // &
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
          format_computed(bytes_per_sample * real(plan%n_samples, wp) / 2.0_wp**30) // &
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
        reason = 'must be a whole number of steps dt = ' // format_real(cs%param(p_dt)) // ' s'
      end if
      call rd%fail_value(gi, variable, reason)
      return
    end if
  end subroutine check_base
end module ellroll_case_input
