!> The ellroll command line: argument parsing, exit codes, messages.
!> Exit codes: 0 ok (also when a case ended at a model limit), 1 internal
!> error, 2 bad input, 3 output error.
program ellroll
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  !$ use omp_lib, only: omp_set_num_threads
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input, err_output, err_interrupted, exit_code
  use ellroll_strings, only: itoa, format_real
  use ellroll_records, only: named_value_t, kind_real, kind_int
  use ellroll_input, only: run_input_t, read_input
  use ellroll_cases, only: case_t, case_record, make_ball, field_count, field_names, field_ncomp, get_param, &
      range_text, check_case
  use ellroll_params, only: params, param_component, p_dt, p_g, p_omega_x, p_omega_z, p_radius, p_x, p_y
  use ellroll_campaign, only: invalid_stop
  use ellroll_ellipsoid, only: principal_radii, normal_from_contact
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, initial_state, observe, state_size
  use ellroll_hdf5_writer, only: provenance_t
  use ellroll_hdf5_common, only: hdf5_close_failed
  use ellroll_run_timings, only: wall_clock
  use ellroll_run_campaign, only: run_options_t, run_campaign, find_invalid_cases, shard_slots, step_size_advice, &
      check_output_target, holds_this_run
  use ellroll_output_files, only: output_files_t, work_target
  use ellroll_files, only: path_kind, kind_regular, kind_missing
  use ellroll_integrators, only: methods
  use ellroll_linear, only: oscillation_periods, no_spin_periods, fits_at_bottom
  use ellroll_merge, only: merge_shards
  use ellroll_report, only: print_summary
  use ellroll_system, only: utc_timestamp, tune_runtime, catch_stop_signals, exit_now
  use ellroll_ranks, only: ranks_start, ranks_all_ok, ranks_stop
  use ellroll_version, only: version_string
  implicit none

  character(len=:), allocatable :: command, output_path, line
  character(len=5) :: summary_format = 'table'          !< ellroll summary --format: table, csv or json
  character(len=8) :: help_topic = ''                   !< ellroll COMMAND --help: that command's help
  character(len=1024), allocatable :: paths(:)
  type(run_options_t) :: opts
  type(error_t) :: err
  integer :: rank, n_ranks, status

  call tune_runtime()
  call ranks_start(rank, n_ranks)
  call parse_arguments()
  !$ if (opts%threads > 0) call omp_set_num_threads(opts%threads)   ! for every parallel loop
  if (.not. err%failed()) then
    select case (command)
    case ('help')
      if (help_topic == '') then
        call print_help()
      else
        call print_command_help(trim(help_topic))
      end if
    case ('version')
      write (output_unit, '(a)') 'ellroll ' // version_string
    case ('check')
      call check_command(err)
    case ('run')
      call run_command(err)
    case ('merge')
      call merge_shards(trim(paths(1)), paths(2:), opts%overwrite, provenance(''), err)
    case ('summary')
      call print_summary(trim(paths(1)), trim(summary_format), err)
    case ('methods')
      call print_methods()
    case ('inputs')
      call print_inputs()
    case ('modes')
      call modes_command(err)
    end select
  end if
  call ranks_stop()
  status = 0
  if (err%code > err_interrupted) then
    call resume_command(line)
    write (error_unit, '(a)') 'ellroll: ' // err%message // '; ''' // line // ''' finishes the rest'
    status = exit_code(err)
  else if (err%failed()) then
    write (error_unit, '(a)') 'ellroll: error: ' // err%message
    status = exit_code(err)
  end if
  ! freed before the exit, which would otherwise leave them to the system:
  ! a sanitizer build's leak check then reports only real leaks
  deallocate (command, output_path, paths)
  err = error_t()
  if (status /= 0 .or. hdf5_close_failed()) then
    ! what was finished is in the journal and the partial file; HDF5's own
    ! exit handler would close files whose writes failed (a full disk), or
    ! that it could not close, and can crash doing so
    flush (output_unit)
    flush (error_unit)
    call exit_now(status)
  end if

contains

  !> This command line with --resume in place of --overwrite: it finishes
  !> an interrupted run (under MPI, on as many ranks).
  subroutine resume_command(line)
    character(len=:), allocatable, intent(out) :: line
    character(len=4096) :: argument
    integer :: k
    line = 'ellroll'
    if (n_ranks > 1) line = 'mpirun -n ' // itoa(n_ranks) // ' ellroll'
    do k = 1, command_argument_count()
      call get_command_argument(k, argument)
      if (argument == '--overwrite' .or. argument == '--resume') cycle
      if (index(trim(argument), ' ') > 0) then
        line = line // ' "' // trim(argument) // '"'
      else
        line = line // ' ' // trim(argument)
      end if
    end do
    line = line // ' --resume'
  end subroutine resume_command

  subroutine parse_arguments()
    integer :: k, n, ios
    character(len=:), allocatable :: arg, value
    command = ''
    output_path = ''
    allocate (paths(0))
    n = command_argument_count()
    k = 1
    do while (k <= n)
      call get_argument(k, arg)
      select case (arg)
      case ('-h', '--help', 'help')
        help_topic = command
        command = 'help'
        return
      case ('-V', '--version', 'version')
        command = 'version'
        return
      case ('-o', '--output', '--threads', '--shard', '--format')
        if (k == n) then
          call usage_error(arg // ' needs a value')
          return
        end if
        k = k + 1
        call get_argument(k, value)
        select case (arg)
        case ('-o', '--output')
          output_path = value
        case ('--threads')
          read (value, *, iostat=ios) opts%threads
          if (ios /= 0 .or. opts%threads < 1) then
            call usage_error('--threads needs a positive number, not ' // value)
            return
          end if
        case ('--format')
          if (all(value /= [character(len=5) :: 'table', 'csv', 'json'])) then
            call usage_error("--format needs table, csv or json, not '" // value // "'")
            return
          end if
          summary_format = value
        case ('--shard')
          if (.not. parse_shard(value)) then
            call usage_error('--shard needs I/N with 0 <= I < N, not ' // value)
            return
          end if
        end select
      case ('--overwrite')
        opts%overwrite = .true.
      case ('--resume')
        opts%resume = .true.
      case ('-q', '--quiet')
        opts%quiet = .true.
      case ('--timings')
        opts%timings = .true.
      case ('run', 'check', 'merge', 'summary', 'methods', 'inputs', 'modes')
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
        paths = [character(len=1024) :: paths, arg]
      end select
      k = k + 1
    end do
    if (len(command) == 0) then
      call usage_error('no command given')
    else if (command == 'methods' .or. command == 'inputs') then
      return
    else if (size(paths) == 0) then
      call usage_error(command // ' needs ' // merge('an output file and shard files', &
                                                     'an input file                 ', command == 'merge'))
    else if (command == 'merge' .and. size(paths) < 2) then
      call usage_error('merge needs an output file and at least one shard file')
    else if (command /= 'merge' .and. size(paths) > 1) then
      call usage_error('more than one input file given (' // trim(paths(1)) // ', ' // trim(paths(2)) // ')')
    else if (opts%resume .and. opts%overwrite) then
      call usage_error('--resume and --overwrite exclude each other')
    end if
  end subroutine parse_arguments

  logical function parse_shard(text) result(ok)
    character(len=*), intent(in) :: text
    integer :: slash, ios1, ios2
    slash = index(text, '/')
    ok = .false.
    if (slash < 2 .or. slash == len(text)) return
    read (text(:slash-1), *, iostat=ios1) opts%shard(1)
    read (text(slash+1:), *, iostat=ios2) opts%shard(2)
    ok = ios1 == 0 .and. ios2 == 0 .and. opts%shard(2) >= 1 .and. opts%shard(1) >= 0 .and. &
         opts%shard(1) < opts%shard(2)
  end function parse_shard

  subroutine usage_error(message)
    character(len=*), intent(in) :: message
    call set_error(err, err_input, message // " (see 'ellroll --help')")
  end subroutine usage_error

  subroutine get_argument(k, arg)
    integer, intent(in) :: k
    character(len=:), allocatable, intent(out) :: arg
    integer :: length
    call get_command_argument(k, length=length)
    allocate (character(len=length) :: arg)
    if (length > 0) call get_command_argument(k, arg)
  end subroutine get_argument

  subroutine print_help()
    write (output_unit, '(a)') &
      'ellroll ' // version_string // ': a heavy ball rolling without slip in a triaxial ellipsoidal cup', &
      '', &
      'usage:', &
      '  ellroll run FILE.nml [-o OUT.h5] [options]   integrate every case, write HDF5', &
      '  ellroll check FILE.nml [-o OUT.h5]           validate, print the cases, write nothing', &
      '  ellroll merge OUT.h5 SHARD.h5...             join the shard files of a campaign', &
      '  ellroll summary OUT.h5 [--format F]          the summary of a file: a table, or one row per', &
      '                                               case as csv or json (NaN as null)', &
      '  ellroll modes FILE.nml                       small-oscillation periods of every case', &
      '  ellroll methods                              the integration methods', &
      '  ellroll inputs                               the inputs a sweep or sample can vary (Markdown)', &
      '  ellroll --version | --help | COMMAND --help', &
      '', &
      'options:', &
      '  -o, --output OUT.h5   write here instead of &output file', &
      '  --overwrite           replace an existing output file', &
      '  --resume              finish an interrupted run (same input, same options)', &
      '  --threads N           OpenMP threads (default: OMP_NUM_THREADS, or all cores)', &
      '  --shard I/N           run only cases I, I+N, I+2N, ... into their own file', &
      '  -q, --quiet           no progress lines on stderr', &
      '  --timings             print where the run''s time went: before, in and after the loop', &
      '                        over cases, and each lock of the loop (held and waited for)', &
      '', &
      'exit codes: 0 ok (also when a case ended at a model limit), 1 internal error,', &
      '            2 bad input, 3 output error, 143 (SIGTERM) or 130 (SIGINT): the run was', &
      '            interrupted and kept its finished cases; run it again with --resume', &
      'The namelist reference is in docs/inputs.md, the HDF5 layout in docs/output.md.'
  end subroutine print_help

  !> `ellroll COMMAND --help`: what the command does and the options it takes.
  subroutine print_command_help(topic)
    character(len=*), intent(in) :: topic
    select case (topic)
    case ('run')
      write (output_unit, '(a)') &
        'usage: ellroll run FILE.nml [-o OUT.h5] [--overwrite | --resume] [--threads N] [--shard I/N]', &
        '                   [-q] [--timings]', &
        '', &
        'Integrates every case of FILE.nml (its sweeps, samples and record suites expand into cases) and', &
        'writes one HDF5 file: /case (the inputs), /trajectory (the stored fields), /summary (status and', &
        'figures per case). A case that reaches a model limit (rim, lift-off, slip) ends there with its', &
        'status; the run still exits 0. The file appears under its name only when complete.', &
        '', &
        '  -o, --output OUT.h5   write here instead of &output file', &
        '  --overwrite           replace an existing output file', &
        '  --resume              finish an interrupted run (same input, same options)', &
        '  --threads N           OpenMP threads (default: OMP_NUM_THREADS, or all cores)', &
        '  --shard I/N           run only cases I, I+N, I+2N, ... into their own file (ellroll merge joins them)', &
        '  -q, --quiet           no progress lines on stderr', &
        '  --timings             print where the run''s time went'
    case ('check')
      write (output_unit, '(a)') &
        'usage: ellroll check FILE.nml [-o OUT.h5]', &
        '', &
        'Reads and validates FILE.nml, prints the resolved cases and the campaign, writes nothing.', &
        'Bad input: a message naming the file, line, namelist group, variable and value; exit 2.'
    case ('merge')
      write (output_unit, '(a)') &
        'usage: ellroll merge OUT.h5 SHARD.h5... [--overwrite]', &
        '', &
        'Joins the files of ''ellroll run --shard I/N'' (all N shards of one input) into OUT.h5, equal', &
        'to the file of the same run unsharded.'
    case ('summary')
      write (output_unit, '(a)') &
        'usage: ellroll summary OUT.h5 [--format table|csv|json]', &
        '', &
        'table (the default): cases per status, steps, integration time, the slowest case.', &
        'csv, json: one row per case: case, the varied inputs, status by name and every figure of', &
        '/summary. The JSON is strict (NaN as null) and gives the units in its "units" object.'
    case ('modes')
      write (output_unit, '(a)') &
        'usage: ellroll modes FILE.nml', &
        '', &
        'The small-oscillation periods of every case about the lowest point of its cup (docs/model.md).'
    case ('methods')
      write (output_unit, '(a)') &
        'usage: ellroll methods', &
        '', &
        'The integration methods: name, kind (fixed step, adaptive or symmetric), order and when to pick it.'
    case ('inputs')
      write (output_unit, '(a)') &
        'usage: ellroll inputs', &
        '', &
        'The real inputs (namelist group, variable, unit, range, default) as a Markdown table;', &
        'each may be varied by &sweep or &sample under the name in its first column.'
    end select
  end subroutine print_command_help

  subroutine print_methods()
    integer :: k
    character(len=10) :: name, kind
    character(len=30) :: order
    write (output_unit, '(a)') 'method    kind      order                         use for'
    do k = 1, size(methods)
      name = methods(k)%name
      kind = methods(k)%kind
      order = methods(k)%order
      write (output_unit, '(a)') name // kind // order // trim(methods(k)%use_for)
    end do
  end subroutine print_methods

  !> The parameter table as a Markdown table (docs/inputs.md holds it).
  subroutine print_inputs()
    integer :: k
    character(len=:), allocatable :: default, variable
    write (output_unit, '(a)') '| name | group | variable | unit | valid range | default | varied | description |'
    write (output_unit, '(a)') '| --- | --- | --- | --- | --- | --- | --- | --- |'
    do k = 1, size(params)
      associate (p => params(k))
        default = format_real(p%default)
        if (p%required) default = 'required'
        variable = trim(p%variable)
        if (param_component(k) > 0) variable = variable // '(' // itoa(param_component(k)) // ')'
        write (output_unit, '(a)') '| `' // trim(p%name) // '` | `&' // trim(p%group) // '` | `' // variable // &
            '` | ' // trim(p%unit) // ' | ' // range_text(k) // ' | ' // default // ' | ' // &
            trim(merge('yes', 'no ', p%sweepable)) // ' | ' // trim(p%description) // ' |'
      end associate
    end do
  end subroutine print_inputs

  !> The linearised small-oscillation periods about the bottom, spinning at
  !> sigma = omega0 . n0, beside the no-spin formula 2 pi sqrt((1+k)(rho-R)/g).
  subroutine modes_command(err)
    type(error_t), intent(inout) :: err
    type(run_input_t) :: inp
    type(case_t) :: cs
    type(rolling_ball_t) :: ball
    real(wp) :: n0(3), periods(2), no_spin(2)
    integer(i8) :: i
    integer :: param
    character(len=160) :: line
    character(len=:), allocatable :: reason
    call read_input(trim(paths(1)), output_path, inp, err)
    if (err%failed()) return
    write (output_unit, '(a)') '    case   sigma rad/s    period 1 s    period 2 s  no spin: x-z s         y-z s'
    do i = 0, inp%campaign%n_cases() - 1
      cs = inp%campaign%case_at(i)
      ! an invalid case has no cup or ball to analyse: its reason instead
      call check_case(cs, inp%plan%interval, param, reason)
      if (param /= 0) then
        write (line, '(i8)') i
        write (output_unit, '(a)') trim(line) // '  invalid: ' // trim(params(param)%name) // ' = ' // &
            format_real(get_param(cs, param)) // ': ' // reason
        cycle
      end if
      ball = make_ball(cs)
      n0 = normal_from_contact(ball%cup, cs%param(p_x), cs%param(p_y))
      periods = oscillation_periods(ball, dot_product(cs%param(p_omega_x:p_omega_z), n0))
      no_spin = no_spin_periods(ball)
      write (line, '(i8, f14.4, 4a)') i, dot_product(cs%param(p_omega_x:p_omega_z), n0), period_column(periods(1)), &
          period_column(periods(2)), period_column(no_spin(1)), period_column(no_spin(2))
      write (output_unit, '(a)') trim(line)
    end do
  end subroutine modes_command

  !> A period in a column of `modes`, right-aligned with a blank before it
  !> whatever its size: six decimals, or six digits and an exponent (from a
  !> cup of 1e6 m to a ball 1e-6 m under the cup's radius of curvature).
  function period_column(x) result(text)
    real(wp), intent(in) :: x
    character(len=14) :: text
    ! NaN apart: an ordered comparison with it traps where invalid traps
    if (ieee_is_nan(x)) then
      write (text, '(f14.6)') x
    else if (abs(x) >= 1.0e-4_wp .and. abs(x) < 1.0e5_wp) then
      write (text, '(f14.6)') x
    else
      write (text, '(es14.5e3)') x
    end if
  end function period_column

  subroutine check_command(err)
    type(error_t), intent(inout) :: err
    type(run_input_t) :: inp
    logical, allocatable :: invalid(:)
    character(len=:), allocatable :: messages
    call read_input(trim(paths(1)), output_path, inp, err)
    if (err%failed()) return
    call check_output_target(inp%plan%file, inp%path, err)
    if (err%failed()) return
    call describe(inp)
    call step_size_advice(inp, messages)
    if (len(messages) > 0) write (error_unit, '(a)') messages
    call find_invalid_cases(inp, invalid, messages)
    if (any(invalid)) then
      if (inp%campaign%invalid == invalid_stop) then
        call set_error(err, err_input, itoa(count(invalid)) // ' of ' // itoa(size(invalid)) // &
            ' cases are invalid (set &campaign invalid = ''skip'' to run the others):' // messages)
        return
      end if
      write (output_unit, '(a)') itoa(count(invalid)) // ' invalid cases will be skipped:' // messages
    end if
    write (output_unit, '(a)') trim(paths(1)) // ': ok'
  end subroutine check_command

  subroutine run_command(err)
    type(error_t), intent(inout) :: err
    type(error_t) :: unread
    type(run_input_t) :: inp
    character(len=:), allocatable :: advice
    call read_input(trim(paths(1)), output_path, inp, err)
    if (err%failed()) return
    call check_output_target(inp%plan%file, inp%path, err)
    if (err%failed()) return
    call catch_stop_signals()
    opts%advice_seconds = wall_clock()
    call step_size_advice(inp, advice)
    opts%advice_seconds = wall_clock() - opts%advice_seconds
    if (len(advice) > 0 .and. rank == 0) write (error_unit, '(a)') advice
    if (n_ranks > 1) then
      call run_ranks(inp, err)
    else
      call check_rank_files(inp%plan%file, 1, err)
      if (.not. err%failed()) call run_campaign(inp, opts, provenance(inp%text), err)
    end if
    if (err%failed() .or. rank /= 0) return
    ! the output is complete: a summary that cannot be read back is a warning
    call print_summary(inp%plan%file, 'table', unread)
    if (unread%failed()) write (error_unit, '(a)') 'ellroll: warning: cannot print the summary: ' // unread%message
  end subroutine run_command

  !> Under MPI: rank r runs shard r/N into OUT.rankR.h5; when every rank has
  !> succeeded, rank 0 merges the shards into OUT and removes them.
  subroutine run_ranks(inp, err)
    type(run_input_t), intent(inout) :: inp
    type(error_t), intent(inout) :: err
    type(output_files_t) :: files
    character(len=:), allocatable :: target
    character(len=1024), allocatable :: shard_files(:)
    integer :: r
    logical :: shard_done, complete, all_ok, to_run
    if (opts%shard(2) > 1) then
      call set_error(err, err_input, '--shard cannot be combined with MPI ranks (each rank is a shard)')
      return
    end if
    target = inp%plan%file
    shard_files = [character(len=1024) :: (target // '.rank' // itoa(r) // '.h5', r = 0, n_ranks - 1)]
    ! rank 0 holds the output's lock until the shards are merged into it
    complete = .false.
    if (rank == 0) then
      call files%name(target, inp%path)
      call files%acquire('mpirun -n ' // itoa(n_ranks) // ' ellroll run ' // inp%path, err)
      call files%check(target, work_target, err)
      call check_rank_files(target, n_ranks, err)
      if (.not. err%failed()) then
        if (path_kind(target) == kind_regular) then
          if (opts%resume) complete = holds_this_run(target, inp, [0, 1])
          if (.not. (opts%overwrite .or. complete)) &
            call set_error(err, err_output, target // ': output file exists; pass --overwrite to replace it')
        end if
      end if
    end if
    ! (every rank takes part in both collectives, whatever they answer)
    all_ok = ranks_all_ok(.not. err%failed())
    to_run = ranks_all_ok(.not. complete)
    if (.not. all_ok .or. .not. to_run) then
      if (all_ok .and. rank == 0) &
        write (error_unit, '(a)') 'ellroll: ' // target // ': this run is already complete; nothing to do'
      call files%release(err)
      return
    end if
    opts%shard = [rank, n_ranks]
    opts%quiet = opts%quiet .or. rank /= 0
    inp%plan%file = trim(shard_files(rank + 1))
    ! a rank whose shard finished before an interruption has nothing to resume
    shard_done = .false.
    if (opts%resume) shard_done = holds_this_run(inp%plan%file, inp, opts%shard)
    if (.not. shard_done) call run_campaign(inp, opts, provenance(inp%text), err)
    inp%plan%file = target
    if (.not. ranks_all_ok(.not. err%failed())) then
      if (.not. err%failed()) call set_error(err, err_output, 'another rank failed; see its message')
      call files%release(err)
      return
    end if
    if (rank == 0) then
      call merge_shards(target, shard_files, .true., provenance(inp%text), err, locked=files)
      do r = 1, n_ranks
        if (.not. err%failed()) call files%discard(trim(shard_files(r)), work_target, err)
      end do
      call files%release(err)
    end if
  end subroutine run_ranks


  !> Files of an earlier run of this output on another number of MPI ranks
  !> are refused: this run could not finish them. Its rank files stop at
  !> rank n_ranks - 1: none of rank n_ranks (more ranks before), and some of
  !> rank n_ranks - 1 wherever rank 0 has some (fewer ranks before).
  subroutine check_rank_files(target, n_ranks, err)
    character(len=*), intent(in) :: target
    integer, intent(in) :: n_ranks
    type(error_t), intent(inout) :: err
    if (err%failed()) return
    if (any_rank_file(target, n_ranks)) then
      call set_error(err, err_output, target // '.rank' // itoa(n_ranks) // '.h5: the files of a run of this ' // &
          'output on more than ' // itoa(n_ranks) // ' MPI ranks are here; finish it on as many ranks as it ' // &
          'was started on (--resume), or remove its .rank files')
    else if (n_ranks > 1) then
      if (any_rank_file(target, 0)) then
        if (.not. any_rank_file(target, n_ranks - 1)) call set_error(err, err_output, target // &
          '.rank0.h5: the files of a run of this output on fewer than ' // itoa(n_ranks) // ' MPI ranks are ' // &
          'here; finish it on as many ranks as it was started on (--resume), or remove its .rank files')
      end if
    end if
  end subroutine check_rank_files

  !> Whether any file of rank r of an MPI run of output `target` is there.
  logical function any_rank_file(target, r)
    character(len=*), intent(in) :: target
    integer, intent(in) :: r
    character(len=*), parameter :: suffixes(3) = [character(len=8) :: '', '.partial', '.journal']
    integer :: k
    any_rank_file = .false.
    do k = 1, size(suffixes)
      if (path_kind(target // '.rank' // itoa(r) // '.h5' // trim(suffixes(k))) /= kind_missing) &
        any_rank_file = .true.
    end do
  end function any_rank_file

  function provenance(input_text) result(prov)
    character(len=*), intent(in) :: input_text
    type(provenance_t) :: prov
    integer :: length
    character(len=:), allocatable :: line
    call get_command(length=length)
    allocate (character(len=length) :: line)
    call get_command(line)
    prov%program = 'ellroll'
    prov%version = version_string
    call utc_timestamp(prov%created)
    prov%input_file = trim(paths(1))
    prov%input_namelist = input_text
    prov%command_line = line
  end function provenance

  !> The base case, what the campaign varies, and what a run will produce.
  subroutine describe(inp)
    type(run_input_t), intent(in) :: inp
    type(rolling_ball_t) :: ball
    type(case_t) :: cs
    type(observation_t) :: obs
    real(wp) :: y(state_size), f(state_size), n0(3), radii(2), periods(2), bytes
    integer(i8) :: n_cases, i, n_local
    integer :: k
    character(len=:), allocatable :: line
    cs = inp%campaign%base
    ball = make_ball(cs)
    write (output_unit, '(a)') 'base case (resolved input):'
    call print_values(case_record(cs))
    n0 = normal_from_contact(ball%cup, cs%param(p_x), cs%param(p_y))
    radii = principal_radii(ball%cup, n0)
    y = initial_state(ball, cs%param(p_x), cs%param(p_y), cs%param(p_omega_x:p_omega_z))
    call ball%rhs(0.0_wp, y, f)
    call observe(ball, 0.0_wp, y, f, obs)
    write (output_unit, '(a)') 'derived:'
    write (output_unit, '(a)') '  z0 = ' // format_real(obs%contact(3)) // ' m'
    write (output_unit, '(a)') '  principal radii of curvature at the start = ' // &
        format_real(radii(1)) // ', ' // format_real(radii(2)) // ' m (radius ' // format_real(cs%param(p_radius)) // ' m)'
    write (output_unit, '(a)') '  spin omega . n at the start = ' // format_real(dot_product(y(4:6), n0)) // ' rad/s'
    write (output_unit, '(a)') '  energy at the start = ' // format_real(obs%energy) // ' J'
    if (cs%param(p_g) > 0) then
      periods = no_spin_periods(ball)
      if (fits_at_bottom(ball)) then
        write (output_unit, '(a)') '  small-oscillation periods at the bottom without spin (x-z, y-z) = ' // &
            format_real(periods(1)) // ', ' // format_real(periods(2)) // ' s'
      else
        write (output_unit, '(a)') '  small-oscillation periods at the bottom without spin (x-z, y-z) = ' // &
            format_real(periods(1)) // ', ' // format_real(periods(2)) // ' s (undefined: the ball does not fit ' // &
            'at the bottom, radius >= a^2/c or b^2/c)'
      end if
    end if

    n_cases = inp%campaign%n_cases()
    n_local = size(shard_slots(n_cases, opts%shard), kind=i8)
    write (output_unit, '(a)') 'campaign: ' // itoa(n_cases) // ' cases'
    if (opts%shard(2) > 1) write (output_unit, '(a)') '  this shard (' // itoa(opts%shard(1)) // '/' // &
        itoa(opts%shard(2)) // '): ' // itoa(n_local) // ' cases'
    do k = 1, size(inp%campaign%sweeps)
      write (output_unit, '(a)') '  sweep ' // trim(params(inp%campaign%sweeps(k)%param)%name) // ': ' // &
          itoa(size(inp%campaign%sweeps(k)%values)) // ' values from ' // &
          format_real(inp%campaign%sweeps(k)%values(1)) // ' to ' // &
          format_real(inp%campaign%sweeps(k)%values(size(inp%campaign%sweeps(k)%values)))
    end do
    do k = 1, size(inp%campaign%samples)
      write (output_unit, '(a)') '  sample ' // trim(params(inp%campaign%samples(k)%param)%name) // &
          ' in [' // format_real(inp%campaign%samples(k)%low) // ', ' // &
          format_real(inp%campaign%samples(k)%high) // '], ' // &
          merge('log   ', 'linear', inp%campaign%samples(k)%log_spacing) // ' spacing'
    end do
    if (size(inp%campaign%sweeps) + size(inp%campaign%samples) > 0) then
      do i = 0, min(n_cases, 5_i8) - 1
        cs = inp%campaign%case_at(i)
        line = '  case ' // itoa(i) // ':'
        do k = 1, size(inp%campaign%sweeps)
          line = line // ' ' // trim(params(inp%campaign%sweeps(k)%param)%name) // ' = ' // &
                 format_real(get_param(cs, inp%campaign%sweeps(k)%param))
        end do
        do k = 1, size(inp%campaign%samples)
          line = line // ' ' // trim(params(inp%campaign%samples(k)%param)%name) // ' = ' // &
                 format_real(get_param(cs, inp%campaign%samples(k)%param))
        end do
        write (output_unit, '(a)') line
      end do
      if (n_cases > 5) write (output_unit, '(a)') '  ...'
    end if

    write (output_unit, '(a)') 'output:'
    write (output_unit, '(a)') '  file = ' // inp%plan%file
    write (output_unit, '(a)') '  steps per case = ' // itoa(nint(inp%campaign%base%t_end / &
        inp%campaign%base%param(p_dt), i8)) // ', samples = ' // itoa(inp%plan%n_samples) // ' every ' // &
        format_real(inp%plan%interval) // ' s'
    line = '  fields ='
    do k = 1, field_count
      if (inp%plan%fields(k)) line = line // ' ' // trim(field_names(k))
    end do
    write (output_unit, '(a)') line
    bytes = 8.0_wp * real(inp%plan%n_samples, wp) * sum(field_ncomp, mask=inp%plan%fields) * real(n_local, wp)
    call size_text(bytes, line)
    write (output_unit, '(a)') '  trajectory data before compression = ' // line // ' (' // itoa(n_local) // ' cases)'
  end subroutine describe

  !> bytes in KiB (whole), MiB or GiB (one decimal).
  subroutine size_text(bytes, text)
    real(wp), intent(in) :: bytes
    character(len=:), allocatable, intent(out) :: text
    if (bytes < 2.0_wp**20) then
      text = format_real(real(nint(bytes / 1024), wp)) // ' KiB'
    else if (bytes < 2.0_wp**30) then
      text = format_real(real(nint(10 * bytes / 2.0_wp**20), wp) / 10) // ' MiB'
    else
      text = format_real(real(nint(10 * bytes / 2.0_wp**30), wp) / 10) // ' GiB'
    end if
  end subroutine size_text

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
        text = itoa(rec(k)%int)
      case default                         ! text
        text = "'" // trim(rec(k)%text) // "'"
      end select
      if (trim(rec(k)%units) /= '1') text = text // ' ' // trim(rec(k)%units)
      write (output_unit, '(a)') '  ' // trim(rec(k)%name) // ' = ' // text
    end do
  end subroutine print_values
end program ellroll
