!> Reading and validating the input namelist file into a resolved case and an
!> output plan. Every message a user sees about input is written here; each
!> names the file, line, group, variable and value.
module ellroll_input
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite, ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_namelist_scan, only: nml_file_t, nml_group_t, scan_namelist_file
  use ellroll_strings, only: lower, itoa, join, format_real
  use ellroll_cases, only: case_t, output_plan_t, field_count, field_names, field_ncomp
  use ellroll_ellipsoid, only: new_ellipsoid, principal_radii, normal_from_contact
  use ellroll_integrators, only: method_names
  implicit none
  private

  public :: run_input_t, read_input

  type :: run_input_t
    type(case_t) :: base
    type(output_plan_t) :: plan
    character(len=:), allocatable :: path
    character(len=:), allocatable :: text     !< the input file, verbatim
  end type run_input_t

  character(len=*), parameter :: known_groups(6) = [character(len=12) :: &
      'geometry', 'ball', 'environment', 'initial', 'integration', 'output']

  ! Bounds that keep every derived quantity finite (squares, products, s^4).
  real(wp), parameter :: length_min = 1.0e-6_wp, length_max = 1.0e6_wp
  !> Largest memory one case's output buffers may take.
  real(wp), parameter :: max_case_buffer_bytes = 2.0_wp**31

  type :: reader_t
    type(nml_file_t) :: file
    type(error_t) :: err
  contains
    procedure :: group => find_group
    procedure :: check_names
    procedure :: read_failed
    procedure :: fail_value
    procedure :: fail_missing
    procedure :: given
    procedure :: require_real
    procedure :: require_range
  end type reader_t

contains

  subroutine read_input(path, output_override, inp, err)
    character(len=*), intent(in) :: path
    character(len=*), intent(in) :: output_override   !< '' when not given
    type(run_input_t), intent(out) :: inp
    type(error_t), intent(inout) :: err
    type(reader_t) :: rd
    integer :: k

    call scan_namelist_file(path, rd%file, rd%err)
    if (.not. rd%err%failed()) then
      do k = 1, size(rd%file%groups)
        if (.not. any(known_groups == rd%file%groups(k)%name)) then
          call set_error(rd%err, err_input, path // ':' // itoa(rd%file%groups(k)%line) // &
              ': unknown group &' // rd%file%groups(k)%name // ' (known groups: ' // &
              join(known_groups) // ')')
          exit
        end if
      end do
    end if
    if (.not. rd%err%failed()) call read_geometry(rd, inp%base)
    if (.not. rd%err%failed()) call read_environment(rd, inp%base)
    if (.not. rd%err%failed()) call read_ball(rd, inp%base)
    if (.not. rd%err%failed()) call read_initial(rd, inp%base)
    if (.not. rd%err%failed()) call read_integration(rd, inp%base)
    if (.not. rd%err%failed()) call read_output(rd, inp%base, output_override, inp%plan)
    if (.not. rd%err%failed()) call check_start(rd, inp%base)
    if (rd%err%failed()) then
      err = rd%err
      return
    end if
    inp%path = path
    inp%text = rd%file%text
  end subroutine read_input

  ! ---------------------------------------------------------------- groups

  subroutine read_geometry(rd, cs)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(inout) :: cs
    real(wp) :: a, b, c
    namelist /geometry/ a, b, c
    integer :: gi, k, ios
    character(len=512) :: msg
    character(len=:), allocatable :: lines(:)
    a = nan(); b = nan(); c = nan()
    gi = rd%group('geometry', required=.true.)
    if (gi == 0) return
    if (.not. rd%check_names(gi, [character(len=16) :: 'a', 'b', 'c'])) return
    do k = 1, size(rd%file%groups(gi)%items)
      lines = assignment_lines(rd%file%groups(gi), k)
      read (lines, nml=geometry, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call rd%read_failed(gi, k, msg)
        return
      end if
    end do
    if (.not. rd%require_range(gi, 'a', a, length_min, length_max, 'm')) return
    if (.not. rd%require_range(gi, 'b', b, length_min, length_max, 'm')) return
    if (.not. rd%require_range(gi, 'c', c, length_min, length_max, 'm')) return
    cs%a = a; cs%b = b; cs%c = c
  end subroutine read_geometry

  subroutine read_environment(rd, cs)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(inout) :: cs
    real(wp) :: g
    namelist /environment/ g
    integer :: gi, k, ios
    character(len=512) :: msg
    character(len=:), allocatable :: lines(:)
    g = 9.81_wp
    gi = rd%group('environment', required=.false.)
    if (gi /= 0) then
      if (.not. rd%check_names(gi, [character(len=16) :: 'g'])) return
      do k = 1, size(rd%file%groups(gi)%items)
        lines = assignment_lines(rd%file%groups(gi), k)
      read (lines, nml=environment, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call rd%read_failed(gi, k, msg)
          return
        end if
      end do
      if (.not. rd%require_range(gi, 'g', g, 0.0_wp, 1.0e4_wp, 'm/s^2')) return
    end if
    cs%g = g
  end subroutine read_environment

  subroutine read_ball(rd, cs)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(inout) :: cs
    real(wp) :: radius, weight, mass, mu, inertia_factor
    namelist /ball/ radius, weight, mass, mu, inertia_factor
    integer :: gi, k, ios
    character(len=512) :: msg
    character(len=:), allocatable :: lines(:)
    radius = nan(); weight = nan(); mass = nan(); mu = nan(); inertia_factor = 0.4_wp
    gi = rd%group('ball', required=.true.)
    if (gi == 0) return
    if (.not. rd%check_names(gi, [character(len=16) :: 'radius', 'weight', 'mass', 'mu', &
                                  'inertia_factor'])) return
    do k = 1, size(rd%file%groups(gi)%items)
      lines = assignment_lines(rd%file%groups(gi), k)
      read (lines, nml=ball, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call rd%read_failed(gi, k, msg)
        return
      end if
    end do
    if (.not. rd%require_range(gi, 'radius', radius, length_min, length_max, 'm')) return
    if (rd%given(gi, 'weight') .and. rd%given(gi, 'mass')) then
      call rd%fail_value(gi, 'mass', 'give exactly one of weight (N) and mass (kg), not both')
      return
    else if (.not. (rd%given(gi, 'weight') .or. rd%given(gi, 'mass'))) then
      call rd%fail_missing(gi, 'weight', 'give exactly one of weight (N) and mass (kg)')
      return
    end if
    if (rd%given(gi, 'weight')) then
      if (.not. rd%require_range(gi, 'weight', weight, tiny(1.0_wp), 1.0e12_wp, 'N')) return
      if (cs%g <= 0) then
        call rd%fail_value(gi, 'weight', 'a weight cannot give the mass when g = 0; give mass instead')
        return
      end if
      cs%mass = weight / cs%g
    else
      if (.not. rd%require_range(gi, 'mass', mass, tiny(1.0_wp), 1.0e12_wp, 'kg')) return
      cs%mass = mass
    end if
    if (rd%given(gi, 'mu')) then
      if (.not. rd%require_range(gi, 'mu', mu, tiny(1.0_wp), 1.0e6_wp, '')) return
      cs%mu = mu
    else
      cs%mu = 0
    end if
    if (.not. rd%require_range(gi, 'inertia_factor', inertia_factor, tiny(1.0_wp), 2.0_wp/3, '')) return
    cs%radius = radius
    cs%inertia_factor = inertia_factor
  end subroutine read_ball

  subroutine read_initial(rd, cs)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(inout) :: cs
    real(wp) :: x, y, omega(3)
    namelist /initial/ x, y, omega
    integer :: gi, k, ios
    character(len=512) :: msg
    character(len=:), allocatable :: lines(:)
    x = 0; y = 0; omega = nan()
    gi = rd%group('initial', required=.true.)
    if (gi == 0) return
    if (.not. rd%check_names(gi, [character(len=16) :: 'x', 'y', 'omega'])) return
    do k = 1, size(rd%file%groups(gi)%items)
      lines = assignment_lines(rd%file%groups(gi), k)
      read (lines, nml=initial, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call rd%read_failed(gi, k, msg)
        return
      end if
    end do
    if (.not. rd%require_range(gi, 'x', x, -length_max, length_max, 'm')) return
    if (.not. rd%require_range(gi, 'y', y, -length_max, length_max, 'm')) return
    if (.not. rd%given(gi, 'omega')) then
      call rd%fail_missing(gi, 'omega', 'give the initial angular velocity, omega = wx, wy, wz (rad/s)')
      return
    end if
    if (.not. all(ieee_is_finite(omega))) then
      call rd%fail_value(gi, 'omega', 'three finite numbers are needed (wx, wy, wz in rad/s)')
      return
    end if
    if (any(abs(omega) > 1.0e6_wp)) then
      call rd%fail_value(gi, 'omega', 'each component must lie within +-1e6 rad/s')
      return
    end if
    cs%x0 = x; cs%y0 = y; cs%omega0 = omega
  end subroutine read_initial

  subroutine read_integration(rd, cs)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(inout) :: cs
    character(len=32) :: method
    real(wp) :: dt, t_end, fit_margin
    namelist /integration/ method, dt, t_end, fit_margin
    integer :: gi, k, ios
    character(len=512) :: msg
    character(len=:), allocatable :: lines(:)
    method = 'rk4'; dt = nan(); t_end = nan(); fit_margin = 1.0e-6_wp
    gi = rd%group('integration', required=.true.)
    if (gi == 0) return
    if (.not. rd%check_names(gi, [character(len=16) :: 'method', 'dt', 't_end', 'fit_margin'])) return
    do k = 1, size(rd%file%groups(gi)%items)
      lines = assignment_lines(rd%file%groups(gi), k)
      read (lines, nml=integration, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call rd%read_failed(gi, k, msg)
        return
      end if
    end do
    method = lower(adjustl(method))
    if (index(' ' // method_names // ' ', ' ' // trim(method) // ' ') == 0 .or. len_trim(method) == 0) then
      call rd%fail_value(gi, 'method', 'unknown method (known: ' // method_names // ')')
      return
    end if
    if (.not. rd%require_range(gi, 't_end', t_end, tiny(1.0_wp), 1.0e9_wp, 's')) return
    if (.not. rd%require_range(gi, 'dt', dt, tiny(1.0_wp), t_end, 's')) return
    if (t_end / dt > 1.0e15_wp) then
      call rd%fail_value(gi, 'dt', 'more than 1e15 steps to t_end = ' // format_real(t_end) // ' s')
      return
    end if
    if (.not. is_multiple(t_end, dt)) then
      call rd%fail_value(gi, 't_end', 'must be a whole number of steps dt = ' // format_real(dt) // ' s')
      return
    end if
    if (.not. rd%require_range(gi, 'fit_margin', fit_margin, 0.0_wp, 0.5_wp, '')) return
    cs%method = method
    cs%dt = dt
    cs%t_end = t_end
    cs%fit_margin = fit_margin
  end subroutine read_integration

  subroutine read_output(rd, cs, output_override, plan)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(in) :: cs
    character(len=*), intent(in) :: output_override
    type(output_plan_t), intent(inout) :: plan
    character(len=1024) :: file
    real(wp) :: interval
    integer, parameter :: max_fields = 32
    character(len=32) :: fields(max_fields)
    namelist /output/ file, interval, fields
    integer :: gi, k, ios, f
    character(len=512) :: msg
    character(len=:), allocatable :: lines(:)
    real(wp) :: bytes_per_sample
    character(len=32) :: name

    file = ''; interval = nan(); fields = ''
    gi = rd%group('output', required=.true.)
    if (gi == 0) return
    if (.not. rd%check_names(gi, [character(len=16) :: 'file', 'interval', 'fields'])) return
    do k = 1, size(rd%file%groups(gi)%items)
      lines = assignment_lines(rd%file%groups(gi), k)
      read (lines, nml=output, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call rd%read_failed(gi, k, msg)
        return
      end if
    end do
    if (len_trim(output_override) > 0) then
      plan%file = trim(output_override)
    else if (len_trim(file) > 0) then
      plan%file = trim(adjustl(file))
    else
      call rd%fail_missing(gi, 'file', 'name the HDF5 file to write (or pass -o FILE)')
      return
    end if
    if (.not. rd%require_range(gi, 'interval', interval, cs%dt, cs%t_end, 's')) return
    if (.not. is_multiple(interval, cs%dt)) then
      call rd%fail_value(gi, 'interval', 'must be a whole number of steps dt = ' // &
                         format_real(cs%dt) // ' s')
      return
    end if
    if (.not. is_multiple(cs%t_end, interval)) then
      call rd%fail_value(gi, 'interval', 't_end = ' // format_real(cs%t_end) // &
                         ' s must be a whole number of output intervals')
      return
    end if
    plan%interval = interval
    plan%steps_per_sample = nint(interval / cs%dt, i8)
    plan%n_samples = nint(cs%t_end / interval, i8) + 1

    if (rd%given(gi, 'fields')) then
      plan%fields = .false.
      do k = 1, max_fields
        name = lower(adjustl(fields(k)))
        if (len_trim(name) == 0 .or. name == 'none') cycle
        if (name == 'all') then
          plan%fields = .true.
          cycle
        end if
        f = findloc(field_names, trim(name), dim=1)
        if (f == 0) then
          call rd%fail_value(gi, 'fields', "unknown field '" // trim(name) // "' (known: " // &
                             join(field_names) // ', all, none)')
          return
        end if
        plan%fields(f) = .true.
      end do
    end if
    bytes_per_sample = 8.0_wp * sum(field_ncomp, mask=plan%fields)
    if (bytes_per_sample * real(plan%n_samples, wp) > max_case_buffer_bytes) then
      call rd%fail_value(gi, 'interval', 'the trajectory of one case would need ' // &
          format_real(bytes_per_sample * real(plan%n_samples, wp) / 2.0_wp**30) // &
          ' GiB; raise interval or select fewer fields')
      return
    end if
  end subroutine read_output

  !> The start must lie inside the lower half, and the ball must fit there.
  subroutine check_start(rd, cs)
    type(reader_t), intent(inout) :: rd
    type(case_t), intent(in) :: cs
    real(wp) :: level, radii(2)
    integer :: gi
    gi = rd%group('initial', required=.true.)
    level = (cs%x0 / cs%a)**2 + (cs%y0 / cs%b)**2
    if (level >= 1) then
      call rd%fail_value(gi, merge('x', 'y', rd%given(gi, 'x')), &
          'the start (x, y) = (' // format_real(cs%x0) // ', ' // format_real(cs%y0) // &
          ') is not inside the cup: (x/a)^2 + (y/b)^2 = ' // format_real(level) // ' must be < 1')
      return
    end if
    radii = principal_radii(new_ellipsoid(cs%a, cs%b, cs%c), normal_from_contact( &
        new_ellipsoid(cs%a, cs%b, cs%c), cs%x0, cs%y0))
    if (radii(1) / cs%radius - 1 <= cs%fit_margin) then
      call rd%fail_value(rd%group('ball', required=.true.), 'radius', &
          'the ball does not fit the cup at the start: the principal radii of curvature there are ' // &
          format_real(radii(1)) // ' m and ' // format_real(radii(2)) // &
          ' m, and radius must be below ' // format_real(radii(1)) // ' m')
    end if
  end subroutine check_start

  ! --------------------------------------------------------------- helpers

  integer function find_group(rd, name, required) result(gi)
    class(reader_t), intent(inout) :: rd
    character(len=*), intent(in) :: name
    logical, intent(in) :: required
    gi = rd%file%group_index(name)
    if (gi == 0 .and. required) then
      call set_error(rd%err, err_input, rd%file%path // ': group &' // name // &
                     ' is missing (it is required)')
    end if
  end function find_group

  !> Unknown and repeated variable names in group gi.
  logical function check_names(rd, gi, known) result(ok)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: known(:)
    integer :: k, j
    ok = .false.
    associate (grp => rd%file%groups(gi))
      do k = 1, size(grp%items)
        if (.not. any(known == grp%items(k)%base)) then
          call set_error(rd%err, err_input, where(rd, gi, k) // ': unknown variable ' // &
              grp%items(k)%name // ' = ' // grp%items(k)%value // ' (known in &' // grp%name // &
              ': ' // join(known) // ')')
          return
        end if
        do j = 1, k - 1
          if (grp%items(j)%name == grp%items(k)%name) then
            call set_error(rd%err, err_input, where(rd, gi, k) // ': ' // grp%items(k)%name // &
                ' = ' // grp%items(k)%value // ': given twice (also at line ' // &
                itoa(grp%items(j)%line) // ')')
            return
          end if
        end do
      end do
    end associate
    ok = .true.
  end function check_names

  subroutine read_failed(rd, gi, k, msg)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi, k
    character(len=*), intent(in) :: msg
    associate (item => rd%file%groups(gi)%items(k))
      call set_error(rd%err, err_input, where(rd, gi, k) // ': ' // item%name // ' = ' // &
          item%value // ': not a valid value for this variable (wrong type, or more items than it ' // &
          'holds; gfortran says: ' // trim(msg) // ')')
    end associate
  end subroutine read_failed

  subroutine fail_value(rd, gi, name, reason)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name, reason
    integer :: k
    k = rd%file%groups(gi)%find(name)
    if (k == 0) then
      call set_error(rd%err, err_input, rd%file%path // ':' // itoa(rd%file%groups(gi)%line) // &
          ': &' // rd%file%groups(gi)%name // ': ' // name // ' (default): ' // reason)
    else
      call set_error(rd%err, err_input, where(rd, gi, k) // ': ' // &
          rd%file%groups(gi)%items(k)%name // ' = ' // rd%file%groups(gi)%items(k)%value // &
          ': ' // reason)
    end if
  end subroutine fail_value

  subroutine fail_missing(rd, gi, name, hint)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name, hint
    call set_error(rd%err, err_input, rd%file%path // ':' // itoa(rd%file%groups(gi)%line) // &
        ': &' // rd%file%groups(gi)%name // ': ' // name // ' is required but not given: ' // hint)
  end subroutine fail_missing

  logical function given(rd, gi, name)
    class(reader_t), intent(in) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name
    given = rd%file%groups(gi)%find(name) > 0
  end function given

  !> A required scalar: given and finite.
  logical function require_real(rd, gi, name, value) result(ok)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name
    real(wp), intent(in) :: value
    ok = .false.
    if (ieee_is_nan(value) .and. .not. rd%given(gi, name)) then
      call rd%fail_missing(gi, name, 'add ' // name // ' = <value> to &' // rd%file%groups(gi)%name)
    else if (.not. ieee_is_finite(value)) then
      call rd%fail_value(gi, name, 'must be a finite number')
    else
      ok = .true.
    end if
  end function require_real

  !> A required scalar within [low, high].
  logical function require_range(rd, gi, name, value, low, high, units) result(ok)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name, units
    real(wp), intent(in) :: value, low, high
    character(len=:), allocatable :: unit_text
    ok = rd%require_real(gi, name, value)
    if (.not. ok) return
    if (value < low .or. value > high) then
      unit_text = ''
      if (len(units) > 0) unit_text = ' ' // units
      if (low == tiny(1.0_wp)) then
        call rd%fail_value(gi, name, 'must be > 0 and <= ' // format_real(high) // unit_text)
      else
        call rd%fail_value(gi, name, 'must be between ' // format_real(low) // ' and ' // &
                           format_real(high) // unit_text)
      end if
      ok = .false.
    end if
  end function require_range

  !> 'file:line: &group' of assignment k of group gi.
  function where(rd, gi, k) result(text)
    type(reader_t), intent(in) :: rd
    integer, intent(in) :: gi, k
    character(len=:), allocatable :: text
    text = rd%file%path // ':' // itoa(rd%file%groups(gi)%items(k)%line) // ': &' // &
           rd%file%groups(gi)%name
  end function where

  !> The records of a one-assignment namelist: '&group', the assignment's lines, '/'.
  function assignment_lines(grp, k) result(lines)
    type(nml_group_t), intent(in) :: grp
    integer, intent(in) :: k
    character(len=:), allocatable :: lines(:)
    character(len=:), allocatable :: source
    integer :: n_lines, width, start, pos, m
    source = grp%items(k)%source
    n_lines = count([(source(pos:pos) == achar(10), pos = 1, len(source))]) + 1
    width = max(len(source), len(grp%name) + 1) + 2
    allocate (character(len=width) :: lines(n_lines + 2))
    lines(1) = '&' // grp%name
    start = 1
    m = 1
    do pos = 1, len(source)
      if (source(pos:pos) == achar(10)) then
        m = m + 1
        lines(m) = source(start:pos-1)
        start = pos + 1
      end if
    end do
    lines(m + 1) = source(start:)
    lines(n_lines + 2) = '/'
  end function assignment_lines

  logical pure function is_multiple(whole, part)
    real(wp), intent(in) :: whole, part
    real(wp) :: ratio
    ratio = whole / part
    is_multiple = abs(ratio - anint(ratio)) <= 1.0e-9_wp * max(1.0_wp, ratio) .and. anint(ratio) >= 1
  end function is_multiple

  real(wp) function nan()
    nan = ieee_value(0.0_wp, ieee_quiet_nan)
  end function nan
end module ellroll_input
