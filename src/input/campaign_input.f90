!> The campaign part of the input: &sweep and &sample groups (which
!> inputs vary, over which values) and &campaign (how they combine, how
!> many random cases, what to do with invalid ones).
module ellroll_campaign_input
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: equals
  use ellroll_strings, only: lower, itoa, join, format_real
  use ellroll_campaign, only: campaign_t, sweep_t, sample_t, combine_grid, combine_zip, invalid_stop, &
      invalid_skip, max_cases
  use ellroll_params, only: params, param_count, param_index, p_weight, p_mass
  use ellroll_input_reader, only: reader_t, namelist_values_t, count_given, not_finite_entry, max_values
  use ellroll_suggest, only: did_you_mean
  use ellroll_applies, only: varied_input_reason
  implicit none
  private

  public :: add_sweep, add_sample, build_campaign

contains

  subroutine add_sweep(rd, v, gi, sweeps, draws)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    type(sweep_t), allocatable, intent(inout) :: sweeps(:)
    type(sample_t), intent(in) :: draws(:)
    integer, intent(in) :: gi
    type(sweep_t) :: sw
    integer :: n, k
    logical :: listed, ranged
    character(len=:), allocatable :: what
    sw%line = rd%file%groups(gi)%line
    sw%param = swept_param(rd, v, gi, sweeps, draws)
    if (sw%param == 0) return
    listed = rd%given(gi, 'values')
    ranged = rd%given(gi, 'start') .or. rd%given(gi, 'stop') .or. rd%given(gi, 'count')
    if (listed .and. ranged) then
      do k = 1, 3
        what = trim(merge('start', 'stop ', k == 1))
        if (k == 3) what = 'count'
        if (rd%given(gi, what)) exit
      end do
      call rd%fail_value(gi, what, 'values is given too: give either values = v1, v2, ... or start, stop ' // &
                         'and count, not both')
      return
    else if (.not. listed .and. .not. ranged) then
      call rd%fail_missing(gi, 'values', 'give either values = v1, v2, ... or start, stop and count')
      return
    end if
    if (listed) then
      n = count_given(v%values)
      if (n == 0) then
        call rd%fail_value(gi, 'values', 'a list of finite numbers is needed')
        return
      end if
      do k = 1, n
        if (ieee_is_finite(v%values(k))) cycle
        call not_finite_entry(v%values, k, what)
        call rd%fail_value(gi, 'values', what // ': a list of finite numbers is needed')
        return
      end do
      sw%values = v%values(:n)
    else
      if (.not. rd%require_all(gi, [character(len=6) :: 'start', 'stop'], [v%start, v%stop])) return
      if (.not. spaceable(rd, gi, 'stop', 'start', v%start, v%stop, lower(v%spacing) == 'log')) return
      if (.not. rd%given(gi, 'count')) then
        call rd%fail_missing(gi, 'count', 'give count = N, how many values from start to stop')
        return
      end if
      if (v%count < 1 .or. v%count > max_values * 1000) then
        call rd%fail_value(gi, 'count', 'must be between 1 and ' // itoa(max_values * 1000))
        return
      end if
      if (v%count == 1 .and. .not. equals(v%start, v%stop)) then
        call rd%fail_value(gi, 'count', 'one value cannot run from start to stop (' // format_real(v%start) // &
                           ' to ' // format_real(v%stop) // '): give count >= 2, or stop = start')
        return
      end if
      select case (lower(v%spacing))
      case ('linear')
        sw%values = [(v%start + (v%stop - v%start) * real(k, wp) / max(1, v%count - 1), k = 0, v%count - 1)]
      case ('log')
        if (v%start <= 0 .or. v%stop <= 0) then
          call rd%fail_value(gi, 'start', "spacing = 'log' needs start > 0 and stop > 0")
          return
        end if
        allocate (sw%values(v%count))
        ! evenly spaced exponents of ten, so that decades are exact (0.01, 0.1,
        ! 1, 10: log10 and 10** are exact there); the scalar pow in every
        ! build: libmvec's vector pow can differ in the last bit, and a value
        ! must not depend on the compiler's choice
        !GCC$ novector
        do k = 0, v%count - 1
          sw%values(k + 1) = 10.0_wp**(log10(v%start) + (log10(v%stop) - log10(v%start)) * real(k, wp) &
                                       / max(1, v%count - 1))
        end do
      case default
        call rd%fail_value(gi, 'spacing', "must be 'linear' or 'log'")
        return
      end select
      sw%values(1) = v%start                               ! exactly the ends the user wrote
      if (v%count > 1) sw%values(v%count) = v%stop
    end if
    sweeps = [sweeps, sw]
  end subroutine add_sweep

  subroutine add_sample(rd, v, gi, sweeps, draws)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    type(sweep_t), intent(in) :: sweeps(:)
    type(sample_t), allocatable, intent(inout) :: draws(:)
    integer, intent(in) :: gi
    type(sample_t) :: s
    s%line = rd%file%groups(gi)%line
    s%param = swept_param(rd, v, gi, sweeps, draws)
    if (s%param == 0) return
    if (.not. rd%require_all(gi, [character(len=6) :: 'low', 'high'], [v%low, v%high])) return
    if (.not. v%high > v%low) then
      call rd%fail_value(gi, 'high', 'must be greater than low = ' // format_real(v%low))
      return
    end if
    if (.not. spaceable(rd, gi, 'high', 'low', v%low, v%high, lower(v%spacing) == 'log')) return
    select case (lower(v%spacing))
    case ('linear')
      s%log_spacing = .false.
    case ('log')
      if (v%low <= 0) then
        call rd%fail_value(gi, 'low', "spacing = 'log' needs low > 0")
        return
      end if
      s%log_spacing = .true.
    case default
      call rd%fail_value(gi, 'spacing', "must be 'linear' or 'log'")
      return
    end select
    s%low = v%low; s%high = v%high
    draws = [draws, s]
  end subroutine add_sample

  !> The values between `first` and `last` can be spaced in double
  !> precision: last - first (linear) or last / first (log, both > 0) is a
  !> normal number. Else the group is refused, naming `last`.
  logical function spaceable(rd, gi, last_name, first_name, first, last, log_spacing) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: last_name, first_name
    real(wp), intent(in) :: first, last
    logical, intent(in) :: log_spacing
    real(wp) :: decades
    ok = .true.
    if (log_spacing) then
      if (.not. (first > 0 .and. last > 0)) return        ! refused with the spacing's own message
      ! (logs: the ratio itself may overflow)
      decades = log(last) - log(first)
      ok = decades <= log(huge(1.0_wp)) .and. decades >= log(tiny(1.0_wp))
      if (.not. ok) call rd%fail_value(gi, last_name, last_name // ' / ' // first_name // ' (' // first_name // &
          ' = ' // format_real(first) // ') is beyond the normal numbers of double precision; narrow the range')
    else
      ! (halves: the difference itself may overflow)
      ok = abs(last / 2 - first / 2) <= huge(1.0_wp) / 2
      if (.not. ok) call rd%fail_value(gi, last_name, last_name // ' - ' // first_name // ' (' // first_name // &
          ' = ' // format_real(first) // ') exceeds the largest number of double precision; narrow the range')
    end if
  end function spaceable

  !> The parameter named by a &sweep or &sample group.
  integer function swept_param(rd, v, gi, sweeps, draws) result(param)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    type(sweep_t), intent(in) :: sweeps(:)
    type(sample_t), intent(in) :: draws(:)
    integer, intent(in) :: gi
    integer :: k
    character(len=:), allocatable :: hint
    param = 0
    if (.not. rd%given(gi, 'name')) then
      call rd%fail_missing(gi, 'name', 'name the input to vary, e.g. name = ''omega_z''')
      return
    end if
    param = param_index(trim(lower(adjustl(v%name))))
    if (param == 0) then
      call did_you_mean(trim(lower(adjustl(v%name))), pack(params%name, params%sweepable), '', hint)
      call rd%fail_value(gi, 'name', 'not an input that can vary' // hint // ' (one of: ' // &
                         join(pack(params%name, params%sweepable)) // ')')
      return
    end if
    do k = 1, size(sweeps)
      if (sweeps(k)%param == param) call rd%fail_value(gi, 'name', 'already varied by the &sweep at line ' // &
                                                       itoa(sweeps(k)%line))
    end do
    do k = 1, size(draws)
      if (draws(k)%param == param) call rd%fail_value(gi, 'name', 'already varied by the &sample at line ' // &
                                                      itoa(draws(k)%line))
    end do
    if (rd%err%failed()) param = 0
  end function swept_param

  subroutine build_campaign(rd, v, sweeps, draws, camp)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    type(sweep_t), intent(in) :: sweeps(:)
    type(sample_t), intent(in) :: draws(:)
    type(campaign_t), intent(inout) :: camp
    integer :: gi, k, param, line
    character(len=:), allocatable :: group
    real(wp) :: cases
    gi = rd%group('campaign', .false.)
    if (gi > 0) then
      select case (lower(v%combine))
      case ('grid'); camp%combine = combine_grid
      case ('zip'); camp%combine = combine_zip
      case default
        call rd%fail_value(gi, 'combine', "must be 'grid' or 'zip'")
        return
      end select
      select case (lower(v%invalid))
      case ('stop'); camp%invalid = invalid_stop
      case ('skip'); camp%invalid = invalid_skip
      case default
        call rd%fail_value(gi, 'invalid', "must be 'stop' or 'skip'")
        return
      end select
      if (v%samples < 0 .or. v%samples > max_cases) then
        call rd%fail_value(gi, 'samples', 'must be between 0 and ' // itoa(max_cases))
        return
      end if
    end if
    if (size(draws) > 0 .and. v%samples == 0) then
      call rd%fail_at(draws(1)%line, '&sample: name = ''' // trim(params(draws(1)%param)%name) // &
                      ''': needs &campaign samples = N (how many random cases)')
      return
    end if
    if (v%samples > 0 .and. size(draws) == 0) then
      call rd%fail_value(gi, 'samples', 'no &sample group says what to draw')
      return
    end if
    camp%n_draws = v%samples
    camp%seed = v%seed
    camp%sweeps = sweeps
    camp%samples = draws
    if (camp%combine == combine_zip) then
      do k = 2, size(sweeps)
        if (size(sweeps(k)%values) /= size(sweeps(1)%values)) then
          call rd%fail_value(gi, 'combine', 'needs sweeps of equal length: the &sweep at line ' // &
              itoa(sweeps(k)%line) // ' has ' // itoa(size(sweeps(k)%values)) // ' values, the one at line ' // &
              itoa(sweeps(1)%line) // ' has ' // itoa(size(sweeps(1)%values)))
          return
        end if
      end do
    end if
    do k = 1, size(sweeps) + size(draws)
      if (k <= size(sweeps)) then
        param = sweeps(k)%param; line = sweeps(k)%line; group = '&sweep'
      else
        param = draws(k - size(sweeps))%param; line = draws(k - size(sweeps))%line; group = '&sample'
      end if
      if (param == p_weight .and. camp%base%param(p_weight) <= 0) call rd%fail_at(line, group // &
          ': name = ''weight'': weight is varied but &ball gives mass; vary mass instead')
      if (param == p_mass .and. camp%base%param(p_weight) > 0) call rd%fail_at(line, group // &
          ': name = ''mass'': mass is varied but &ball gives weight; vary weight instead')
    end do
    if (rd%err%failed()) return
    call check_applies(rd, camp)
    if (rd%err%failed()) return
    ! counted in reals, naming the group that passes the limit: the lengths
    ! of a few sweeps multiply beyond integer(i8)
    cases = max(1, size(camp%records))
    do k = 1, size(sweeps)
      if (camp%combine == combine_zip .and. k > 1) exit
      cases = cases * size(sweeps(k)%values)
      if (cases > max_cases) then
        call rd%fail_at(sweeps(k)%line, '&sweep: name = ''' // trim(params(sweeps(k)%param)%name) // &
            ''': with this sweep the campaign expands to ' // format_real(cases) // ' cases, more than ' // &
            itoa(max_cases))
        return
      end if
    end do
    if (cases * max(1_i8, v%samples) > max_cases) call rd%fail_value(gi, 'samples', 'the campaign expands to ' // &
        format_real(cases * max(1_i8, v%samples)) // ' cases, more than ' // itoa(max_cases))
  end subroutine build_campaign

  !> Every varied input applies to the campaign's cases as a single value
  !> of it would (varied_input_reason): a sweep or a sample of one that
  !> does not is refused at its name, with its values, since its cases
  !> would all be the same (or all invalid).
  subroutine check_applies(rd, camp)
    type(reader_t), intent(inout) :: rd
    type(campaign_t), intent(in) :: camp
    logical :: varied(param_count)
    integer :: k, j, n
    character(len=:), allocatable :: reason, setting
    varied = .false.
    varied(camp%sweeps%param) = .true.
    varied(camp%samples%param) = .true.
    do k = 1, size(camp%sweeps)
      call varied_input_reason(camp%sweeps(k)%param, camp%base, varied, reason)
      if (len(reason) == 0) cycle
      associate (values => camp%sweeps(k)%values)
        n = size(values)
        if (n <= 4) then
          setting = format_real(values(1))
          do j = 2, n
            setting = setting // ', ' // format_real(values(j))
          end do
        else
          setting = format_real(values(1)) // ', ' // format_real(values(2)) // ', ..., ' // &
                    format_real(values(n)) // ' (' // itoa(n) // ' values)'
        end if
      end associate
      call rd%fail_value(group_at(rd, 'sweep', camp%sweeps(k)%line), 'name', reason // ' (values = ' // setting // ')')
      return
    end do
    do k = 1, size(camp%samples)
      call varied_input_reason(camp%samples(k)%param, camp%base, varied, reason)
      if (len(reason) == 0) cycle
      associate (s => camp%samples(k))
        call rd%fail_value(group_at(rd, 'sample', s%line), 'name', reason // ' (low = ' // format_real(s%low) // &
                           ', high = ' // format_real(s%high) // ')')
      end associate
      return
    end do
  end subroutine check_applies

  !> The index of the group `name` that starts at `line`.
  pure integer function group_at(rd, name, line) result(gi)
    type(reader_t), intent(in) :: rd
    character(len=*), intent(in) :: name
    integer, intent(in) :: line
    do gi = 1, size(rd%file%groups)
      if (rd%file%groups(gi)%name == name .and. rd%file%groups(gi)%line == line) return
    end do
    gi = 0
  end function group_at
end module ellroll_campaign_input
