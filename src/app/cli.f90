!> The ellroll command line: its arguments parsed into a command, its
!> files and options; the provenance a command writes into its outputs; and
!> the command line that finishes an interrupted run.
module ellroll_cli
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_strings, only: itoa, excerpt
  use ellroll_hdf5_writer, only: provenance_t
  use ellroll_run_campaign, only: run_options_t
  use ellroll_system, only: utc_timestamp
  use ellroll_version, only: version_string, build_string
  use ellroll_suggest, only: did_you_mean
  use ellroll_files, only: output_name_problem, path_length
  use ellroll_threads, only: threads_per_processor
  implicit none
  private

  public :: cli_t, parse_arguments, provenance, resume_line

  character(len=*), parameter :: commands(*) = [character(len=7) :: &
      'run', 'check', 'merge', 'summary', 'methods', 'inputs', 'modes', 'help', 'version']
  character(len=*), parameter :: options(*) = [character(len=11) :: &
      '--output', '--threads', '--shard', '--format', '--overwrite', '--resume', '--quiet', '--timings', &
      '--suite', '--help', '--version']
  !> The options each command takes (long names, blank-separated); any
  !> other is refused: one ignored would do something else than asked.
  character(len=*), parameter :: command_options(*) = [character(len=80) :: &
      'run --output --overwrite --resume --threads --shard --quiet --timings', &
      'check --output --shard --threads', 'merge --overwrite', 'summary --format --suite', &
      'methods', 'inputs', 'modes', 'version']

  !> What the command line asks for.
  type :: cli_t
    character(len=:), allocatable :: command              !< run, check, ..., help or version
    character(len=:), allocatable :: output_path          !< -o, --output; '' when not given
    character(len=5) :: summary_format = 'table'          !< ellroll summary --format: table, csv or json
    logical :: suite = .false.                            !< ellroll summary --suite: the statistics per stripe
    character(len=8) :: help_topic = ''                   !< ellroll COMMAND --help: that command's help
    character(len=path_length), allocatable :: paths(:)   !< the files after the command
    type(run_options_t) :: opts
  end type cli_t

contains

  !> The command line's arguments; err (bad input, with a pointer to
  !> --help) names the first that makes no sense.
  subroutine parse_arguments(cli, err)
    type(cli_t), intent(out) :: cli
    type(error_t), intent(inout) :: err
    integer :: k, n
    character(len=:), allocatable :: arg, value, hint
    character(len=11), allocatable :: given(:)     ! the options given, as written
    cli%command = ''
    cli%output_path = ''
    allocate (cli%paths(0), given(0))
    n = command_argument_count()
    k = 1
    do while (k <= n)
      call get_argument(k, arg)
      select case (arg)
      case ('-h', '--help', 'help')
        cli%help_topic = cli%command
        cli%command = 'help'
        return
      case ('-V', '--version', 'version')
        if (len(cli%command) > 0) then
          call usage_error(err, 'more than one command given (' // cli%command // ', ' // arg // ')')
          return
        end if
        cli%command = 'version'
      case ('-o', '--output', '--threads', '--shard', '--format')
        if (given_before(given, arg)) then
          call usage_error(err, arg // ' given twice; give it once')
          return
        end if
        given = [character(len=11) :: given, arg]
        if (k == n) then
          call usage_error(err, arg // ' needs a value')
          return
        end if
        k = k + 1
        call get_argument(k, value)
        if (value(1:min(1, len(value))) == '-' .and. any(value == [options, '-o         ', '-q         '])) then
          call usage_error(err, arg // ' needs a value, not the option ' // value)
          return
        end if
        call take_value(cli, arg, value, err)
        if (err%failed()) return
      case ('--overwrite', '--resume', '-q', '--quiet', '--timings', '--suite')
        given = [character(len=11) :: given, arg]
        call take_switch(cli, arg)
      case ('run', 'check', 'merge', 'summary', 'methods', 'inputs', 'modes')
        if (len(cli%command) > 0) then
          call usage_error(err, 'more than one command given (' // cli%command // ', ' // arg // ')')
          return
        end if
        cli%command = arg
      case default
        if (arg(1:min(1, len(arg))) == '-') then
          call did_you_mean(arg, options, '', hint)
          call usage_error(err, 'unknown option ' // arg // hint)
          return
        end if
        if (len(cli%command) == 0) then
          call did_you_mean(arg, commands, 'ellroll ', hint)
          call usage_error(err, "unknown command '" // arg // "'" // hint)
          return
        end if
        if (len(arg) > path_length) then
          call usage_error(err, 'a path of ' // itoa(len(arg)) // ' characters (' // arg(:40) // '...); at most ' // &
                           itoa(path_length) // ' (the system''s limit)')
          return
        end if
        if (ends_in_blank(arg, err)) return
        cli%paths = [character(len=path_length) :: cli%paths, arg]
      end select
      k = k + 1
    end do
    call check_options(cli%command, given, err)
    if (.not. err%failed()) call check_arguments(cli, err)
  end subroutine parse_arguments

  !> Whether the option (short or long) is among those given so far.
  pure logical function given_before(given, option)
    character(len=*), intent(in) :: given(:), option
    given_before = any(long_name(given) == long_name(option))
  end function given_before

  !> An option's long name (-o: --output, -q: --quiet).
  elemental function long_name(option) result(long)
    character(len=*), intent(in) :: option
    character(len=11) :: long
    long = option
    if (option == '-o') long = '--output'
    if (option == '-q') long = '--quiet'
  end function long_name

  !> An option that takes no value.
  subroutine take_switch(cli, option)
    type(cli_t), intent(inout) :: cli
    character(len=*), intent(in) :: option
    select case (option)
    case ('--overwrite')
      cli%opts%overwrite = .true.
    case ('--resume')
      cli%opts%resume = .true.
    case ('-q', '--quiet')
      cli%opts%quiet = .true.
    case ('--timings')
      cli%opts%timings = .true.
    case ('--suite')
      cli%suite = .true.
    end select
  end subroutine take_switch

  !> The first option given that the command does not take.
  subroutine check_options(command, given, err)
    character(len=*), intent(in) :: command
    character(len=*), intent(in) :: given(:)
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: long
    integer :: k, c
    if (len(command) == 0) return
    ! (the command is the first word of its entry)
    c = findloc([(index(command_options(k), command // ' ') == 1, k = 1, size(command_options))], .true., dim=1)
    if (c == 0) return
    do k = 1, size(given)
      long = trim(long_name(given(k)))
      if (index(trim(command_options(c)) // ' ', ' ' // long // ' ') == 0) then
        call set_error(err, err_input, command // ' does not take ' // trim(given(k)) // " (see 'ellroll " // &
                       command // " --help')")
        return
      end if
    end do
  end subroutine check_options

  !> The value of an option that takes one.
  subroutine take_value(cli, option, value, err)
    type(cli_t), intent(inout) :: cli
    character(len=*), intent(in) :: option, value
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: reason
    integer :: ios
    select case (option)
    case ('-o', '--output')
      if (len_trim(value) == 0) then
        call usage_error(err, option // ' needs a file name, not an empty text')
        return
      end if
      if (ends_in_blank(value, err)) return
      call output_name_problem(value, reason)
      if (len(reason) > 0) call usage_error(err, option // ' ' // excerpt(value) // ': ' // reason)
      cli%output_path = value
    case ('--threads')
      ios = 1
      if (is_digits(value)) read (value, *, iostat=ios) cli%opts%threads
      if (ios /= 0 .and. is_digits(value) .and. verify(value, '0') > 0) then    ! (digits beyond a default integer)
        call usage_error(err, '--threads ' // value // ': too large (at most ' // itoa(huge(1)) // &
            '; a run uses at most ' // itoa(threads_per_processor) // ' threads per processor)')
      else if (ios /= 0 .or. cli%opts%threads < 1) then
        call usage_error(err, '--threads needs a positive number, not ' // value)
      end if
    case ('--format')
      if (all(value /= [character(len=5) :: 'table', 'csv', 'json'])) then
        call usage_error(err, "--format needs table, csv or json, not '" // value // "'")
        return
      end if
      cli%summary_format = value
    case ('--shard')
      if (parse_shard(value, cli%opts%shard)) return
      if (shard_too_large(value)) then
        call usage_error(err, '--shard ' // value // ': too large (N at most ' // itoa(huge(1)) // ')')
      else
        call usage_error(err, '--shard needs I/N with 0 <= I < N, not ' // value)
      end if
    end select
  end subroutine take_value

  !> The files a command needs, and options that exclude each other.
  subroutine check_arguments(cli, err)
    type(cli_t), intent(in) :: cli
    type(error_t), intent(inout) :: err
    if (len(cli%command) == 0) then
      call usage_error(err, 'no command given')
    else if (any(cli%command == [character(len=7) :: 'methods', 'inputs', 'version'])) then
      if (size(cli%paths) > 0) call usage_error(err, cli%command // ' takes no argument (' // trim(cli%paths(1)) // ')')
    else if (size(cli%paths) == 0) then
      ! (merge pads its shorter text with blanks: trimmed)
      call usage_error(err, cli%command // ' needs ' // trim(merge('an output file and shard files', &
                                                                  'an input file                 ', cli%command == 'merge')))
    else if (cli%command == 'merge' .and. size(cli%paths) < 2) then
      call usage_error(err, 'merge needs an output file and at least one shard file')
    else if (cli%command /= 'merge' .and. size(cli%paths) > 1) then
      call usage_error(err, 'more than one input file given (' // trim(cli%paths(1)) // ', ' // &
                       trim(cli%paths(2)) // ')')
    else if (cli%opts%resume .and. cli%opts%overwrite) then
      call usage_error(err, '--resume and --overwrite exclude each other')
    end if
  end subroutine check_arguments

  !> I/N of --shard.
  logical function parse_shard(text, shard) result(ok)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: shard(2)
    integer :: slash, ios1, ios2
    slash = index(text, '/')
    ok = .false.
    ! digits alone on either side: a list-directed read would stop at a
    ! second '/', a comma or a blank and take 1/2/3 as 1/2
    if (slash < 2 .or. slash == len(text)) return
    if (.not. (is_digits(text(:slash-1)) .and. is_digits(text(slash+1:)))) return
    read (text(:slash-1), *, iostat=ios1) shard(1)
    read (text(slash+1:), *, iostat=ios2) shard(2)
    ok = ios1 == 0 .and. ios2 == 0 .and. shard(2) >= 1 .and. shard(1) >= 0 .and. shard(1) < shard(2)
  end function parse_shard

  !> Whether text is I/N in digits with N beyond a default integer (an I
  !> beyond it is not below N: the usual message says so).
  logical function shard_too_large(text) result(large)
    character(len=*), intent(in) :: text
    integer :: slash
    slash = index(text, '/')
    large = .false.
    if (slash < 2 .or. slash == len(text)) return
    if (is_digits(text(:slash-1)) .and. is_digits(text(slash+1:))) &
      large = beyond_integer(text(slash+1:))
  contains
    pure logical function beyond_integer(digits)
      character(len=*), intent(in) :: digits
      character(len=:), allocatable :: significant, most
      significant = digits(min(verify(digits, '0'), len(digits)):)
      if (verify(digits, '0') == 0) significant = '0'
      most = itoa(huge(1))
      beyond_integer = len(significant) > len(most)
      if (len(significant) == len(most)) beyond_integer = significant > most
    end function beyond_integer
  end function shard_too_large

  !> Whether text is one or more decimal digits and nothing else.
  pure logical function is_digits(text)
    character(len=*), intent(in) :: text
    is_digits = len(text) > 0 .and. verify(text, '0123456789') == 0
  end function is_digits

  !> A file name that ends in a blank is refused: the paths are Fortran
  !> texts, whose trailing blanks do not count, so another file would be
  !> read or written.
  logical function ends_in_blank(path, err) result(refused)
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    refused = len(path) > len_trim(path)
    if (refused) call usage_error(err, "'" // path // "': a file name that ends in a blank; " // &
                                  "ellroll takes no such name (rename the file)")
  end function ends_in_blank

  subroutine usage_error(err, message)
    type(error_t), intent(inout) :: err
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

  !> What an output records of the command that wrote it: the program, its
  !> version, the time, the input file and its text, the command line.
  function provenance(input_file, input_text) result(prov)
    character(len=*), intent(in) :: input_file, input_text
    type(provenance_t) :: prov
    integer :: length
    character(len=:), allocatable :: line
    call get_command(length=length)
    allocate (character(len=length) :: line)
    call get_command(line)
    prov%program = 'ellroll'
    prov%version = version_string
    prov%build = build_string
    call utc_timestamp(prov%created)
    prov%input_file = input_file
    prov%input_namelist = input_text
    prov%command_line = line
  end function provenance

  !> This command line with --resume in place of --overwrite: it finishes
  !> an interrupted run (under MPI, on as many ranks).
  subroutine resume_line(n_ranks, line)
    integer, intent(in) :: n_ranks
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
  end subroutine resume_line
end module ellroll_cli
