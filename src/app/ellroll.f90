!> The ellroll command line: argument parsing, exit codes, messages.
!> Exit codes: 0 ok (also when a case ended at a model limit), 1 internal
!> error, 2 bad input, 3 output error.
program ellroll
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input, err_output, exit_code
  use ellroll_strings, only: itoa, format_real
  use ellroll_records, only: named_value_t, kind_real, kind_int, kind_text
  use ellroll_input, only: run_input_t, read_input
  use ellroll_cases, only: case_t, output_plan_t, case_record, make_ball, field_count, &
      field_names, field_ncomp
  use ellroll_results, only: case_result_t, summary_record
  use ellroll_simulate, only: simulate_case
  use ellroll_status, only: status_name
  use ellroll_ellipsoid, only: principal_radii, normal_from_contact, contact_from_normal, bottom_radii
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, initial_state, observe, state_size
  use ellroll_h5_writer, only: h5_output_t, provenance_t
  use ellroll_system, only: rename_file, remove_file, utc_timestamp
  use ellroll_version, only: version_string
  implicit none

  character(len=:), allocatable :: command, input_path, output_path
  logical :: overwrite
  type(error_t) :: err

  call parse_arguments(err)
  if (.not. err%failed()) then
    select case (command)
    case ('help')
      call print_help()
    case ('version')
      write (output_unit, '(a)') 'ellroll ' // version_string
    case ('check')
      call check_command(err)
    case ('run')
      call run_command(err)
    end select
  end if
  if (err%failed()) then
    write (error_unit, '(a)') 'ellroll: error: ' // err%message
    call exit(exit_code(err))
  end if

contains

  subroutine parse_arguments(err)
    type(error_t), intent(inout) :: err
    integer :: k, n
    character(len=:), allocatable :: arg
    command = ''
    input_path = ''
    output_path = ''
    overwrite = .false.
    n = command_argument_count()
    k = 1
    do while (k <= n)
      arg = argument(k)
      select case (arg)
      case ('-h', '--help', 'help')
        command = 'help'
        return
      case ('-V', '--version', 'version')
        command = 'version'
        return
      case ('-o', '--output')
        if (k == n) then
          call usage_error(arg // ' needs a file name')
          return
        end if
        k = k + 1
        output_path = argument(k)
      case ('--overwrite')
        overwrite = .true.
      case ('run', 'check')
        if (len(command) > 0) then
          call usage_error('more than one command given (' // command // ', ' // arg // ')')
          return
        end if
        command = arg
      case default
        if (arg(1:min(1, len(arg))) == '-') then
          call usage_error('unknown option ' // arg)
          return
        end if
        if (len(command) == 0) then
          call usage_error("unknown command '" // arg // "'")
          return
        end if
        if (len(input_path) > 0) then
          call usage_error('more than one input file given (' // input_path // ', ' // arg // ')')
          return
        end if
        input_path = arg
      end select
      k = k + 1
    end do
    if (len(command) == 0) then
      call usage_error('no command given')
    else if (len(input_path) == 0) then
      call usage_error(command // ' needs an input file')
    end if
  end subroutine parse_arguments

  subroutine usage_error(message)
    character(len=*), intent(in) :: message
    call set_error(err, err_input, message // " (see 'ellroll --help')")
  end subroutine usage_error

  function argument(k) result(arg)
    integer, intent(in) :: k
    character(len=:), allocatable :: arg
    integer :: length
    call get_command_argument(k, length=length)
    allocate (character(len=length) :: arg)
    if (length > 0) call get_command_argument(k, arg)
  end function argument

  subroutine print_help()
    write (output_unit, '(a)') &
      'ellroll ' // version_string // ': a heavy ball rolling without slip in a triaxial ellipsoidal cup', &
      '', &
      'usage:', &
      '  ellroll run FILE.nml [-o OUT.h5] [--overwrite]   integrate, write HDF5', &
      '  ellroll check FILE.nml [-o OUT.h5]               validate, print the resolved case', &
      '  ellroll --version | --help', &
      '', &
      'options:', &
      '  -o, --output OUT.h5   write here instead of &output file', &
      '  --overwrite           replace an existing output file', &
      '', &
      'exit codes: 0 ok (also when a case ended at a model limit), 1 internal error,', &
      '            2 bad input, 3 output error', &
      'The namelist reference and the HDF5 layout are in README.md.'
  end subroutine print_help

  subroutine check_command(err)
    type(error_t), intent(inout) :: err
    type(run_input_t) :: inp
    call read_input(input_path, output_path, inp, err)
    if (err%failed()) return
    call describe(inp)
    write (output_unit, '(a)') input_path // ': ok'
  end subroutine check_command

  subroutine run_command(err)
    type(error_t), intent(inout) :: err
    type(run_input_t) :: inp
    type(case_result_t) :: res
    type(h5_output_t) :: out
    character(len=:), allocatable :: partial
    logical :: exists
    integer(i8) :: j
    real(wp), allocatable :: times(:)

    call read_input(input_path, output_path, inp, err)
    if (err%failed()) return
    inquire (file=inp%plan%file, exist=exists)
    if (exists .and. .not. overwrite) then
      call set_error(err, err_output, inp%plan%file // &
          ': output file exists; pass --overwrite to replace it')
      return
    end if

    call simulate_case(inp%base, inp%plan, res, err)
    if (err%failed()) return

    ! Write beside the target and rename only when complete, so that a
    ! failed or killed run never leaves a damaged file or touches a good one.
    partial = inp%plan%file // '.partial'
    times = [(real(j, wp) * inp%plan%interval, j = 0, inp%plan%n_samples - 1)]
    call out%create(partial, 1_i8, times, inp%plan%fields, inp%base, provenance(inp), err)
    if (.not. err%failed()) call out%write_case(0_i8, inp%base, res, err)
    call out%close(err)
    if (.not. err%failed()) then
      if (.not. rename_file(partial, inp%plan%file)) &
        call set_error(err, err_output, inp%plan%file // ': cannot move the finished file into place')
    end if
    if (err%failed()) then
      call remove_file(partial)
      return
    end if
    call report(inp, res)
  end subroutine run_command

  function provenance(inp) result(prov)
    type(run_input_t), intent(in) :: inp
    type(provenance_t) :: prov
    integer :: length
    character(len=:), allocatable :: line
    call get_command(length=length)
    allocate (character(len=length) :: line)
    call get_command(line)
    prov%program = 'ellroll'
    prov%version = version_string
    prov%created = utc_timestamp()
    prov%input_file = inp%path
    prov%input_namelist = inp%text
    prov%command_line = line
  end function provenance

  subroutine report(inp, res)
    type(run_input_t), intent(in) :: inp
    type(case_result_t), intent(in) :: res
    write (output_unit, '(a)') inp%plan%file // ': case 0 ' // status_name(res%status) // &
        ' at t = ' // format_real(res%t_final) // ' s'
    call print_values(summary_record(res))
    if (res%wall_time > 0) write (output_unit, '(a)') '  steps per second: ' // &
        format_real(real(nint(real(res%n_steps, wp) / res%wall_time), wp))
  end subroutine report

  !> The resolved case and what a run of it will produce.
  subroutine describe(inp)
    type(run_input_t), intent(in) :: inp
    type(rolling_ball_t) :: ball
    real(wp) :: y(state_size), f(state_size), n0(3), radii(2), periods(2), bytes, contact(3)
    type(observation_t) :: obs
    integer :: k
    ball = make_ball(inp%base)
    write (output_unit, '(a)') 'case 0 (resolved input):'
    call print_values(case_record(inp%base))
    n0 = normal_from_contact(ball%cup, inp%base%x0, inp%base%y0)
    radii = principal_radii(ball%cup, n0)
    y = initial_state(ball, inp%base%x0, inp%base%y0, inp%base%omega0)
    call ball%rhs(0.0_wp, y, f)
    write (output_unit, '(a)') 'derived:'
    contact = contact_from_normal(ball%cup, n0)
    obs = observe(ball, y, f)
    write (output_unit, '(a)') '  z0 = ' // format_real(contact(3)) // ' m'
    write (output_unit, '(a)') '  principal radii of curvature at the start = ' // &
        format_real(radii(1)) // ', ' // format_real(radii(2)) // ' m (radius ' // &
        format_real(inp%base%radius) // ' m)'
    write (output_unit, '(a)') '  spin omega . n at the start = ' // format_real(dot_product(y(4:6), n0)) // ' rad/s'
    write (output_unit, '(a)') '  energy at the start = ' // format_real(obs%energy) // ' J'
    if (inp%base%g > 0) then
      periods = 2 * acos(-1.0_wp) * sqrt((1 + inp%base%inertia_factor) * &
                (bottom_radii(ball%cup) - inp%base%radius) / inp%base%g)
      write (output_unit, '(a)') '  small-oscillation periods at the bottom without spin (x-z, y-z) = ' // &
          format_real(periods(1)) // ', ' // format_real(periods(2)) // ' s'
    end if
    write (output_unit, '(a)') 'output:'
    write (output_unit, '(a)') '  file = ' // inp%plan%file
    write (output_unit, '(a)') '  steps = ' // itoa(int(nint(inp%base%t_end / inp%base%dt, i8))) // &
        ', samples = ' // itoa(int(inp%plan%n_samples)) // ' every ' // format_real(inp%plan%interval) // ' s'
    write (output_unit, '(a)', advance='no') '  fields ='
    do k = 1, field_count
      if (inp%plan%fields(k)) write (output_unit, '(a)', advance='no') ' ' // trim(field_names(k))
    end do
    write (output_unit, '(a)') ''
    bytes = 8.0_wp * real(inp%plan%n_samples, wp) * sum(field_ncomp, mask=inp%plan%fields)
    write (output_unit, '(a)') '  trajectory data before compression = ' // &
        format_real(real(nint(bytes / 1024), wp)) // ' KiB per case, 1 case'
  end subroutine describe

  subroutine print_values(rec)
    type(named_value_t), intent(in) :: rec(:)
    integer :: k
    character(len=:), allocatable :: text
    do k = 1, size(rec)
      select case (rec(k)%kind)
      case (kind_real)
        if (rec(k)%ncomp == 1) then
          text = format_real(rec(k)%reals(1))
        else
          text = format_real(rec(k)%reals(1)) // ', ' // format_real(rec(k)%reals(2)) // ', ' // &
                 format_real(rec(k)%reals(3))
        end if
      case (kind_int)
        text = itoa(int(rec(k)%int))
      case (kind_text)
        text = "'" // trim(rec(k)%text) // "'"
      end select
      if (trim(rec(k)%units) /= '1') text = text // ' ' // trim(rec(k)%units)
      write (output_unit, '(a)') '  ' // trim(rec(k)%name) // ' = ' // text
    end do
  end subroutine print_values
end program ellroll
