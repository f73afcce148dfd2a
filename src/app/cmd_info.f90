!> The commands that print what ellroll is and knows: help (the program's
!> and each command's), version, methods (the integrators) and inputs (the
!> parameter table).
module ellroll_cmd_info
  use ellroll_standard_output, only: put_line, put_lines
  use ellroll_strings, only: itoa, format_real
  use ellroll_cases, only: range_text
  use ellroll_params, only: params, param_component, param_unset_allowed
  use ellroll_integrators, only: methods
  use ellroll_version, only: version_string, build_string
  implicit none
  private

  !> the longest line of the help texts (103 characters) and room to spare:
  !> put_lines trims each line's blanks
  integer, parameter :: help_width = 160

  public :: print_help, print_command_help, print_version, print_methods, print_inputs

contains

  !> `ellroll --help`: the commands, the options and the exit codes.
  subroutine print_help()
    call put_lines([character(len=help_width) :: &
      'ellroll ' // version_string // ': a heavy ball rolling without slip in a triaxial ellipsoidal cup', &
      '', &
      'usage:', &
      '  ellroll run FILE.nml [-o OUT.h5] [options]   integrate every case, write HDF5', &
      '  ellroll check FILE.nml [-o OUT.h5] [--shard I/N] [--threads N]', &
      '                                               validate, print the cases, write nothing', &
      '  ellroll merge OUT.h5 SHARD.h5... [--overwrite]', &
      '                                               join the shard files of a campaign', &
      '  ellroll summary OUT.h5 [--format F] [--suite]', &
      '                                               the summary of a file: a table, or one row per', &
      '                                               case (or per stripe) as csv or json (NaN as null)', &
      '  ellroll modes FILE.nml                       small-oscillation periods of every case', &
      '  ellroll methods                              the integration methods', &
      '  ellroll inputs                               the inputs a sweep or sample can vary (Markdown)', &
      '  ellroll --version | --help | COMMAND --help', &
      '', &
      'options (each command takes those its usage lists, and refuses any other):', &
      '  -o, --output OUT.h5   write here instead of &output file', &
      '  --overwrite           replace an existing output file', &
      '  --resume              finish an interrupted run (same input, same options)', &
      '  --threads N           OpenMP threads (default: OMP_NUM_THREADS, or all cores)', &
      '  --shard I/N           run only cases I, I+N, I+2N, ... into their own file (-o)', &
      '  -q, --quiet           no progress lines on stderr', &
      '  --timings             print where the run''s time went: before, in and after the loop', &
      '                        over cases, and each lock of the loop (held and waited for)', &
      '', &
      'exit codes: 0 ok (also when a case ended at a model limit), 1 internal error,', &
      '            2 bad input, 3 output error, 143 (SIGTERM) or 130 (SIGINT): the run was', &
      '            interrupted and kept its finished cases; run it again with --resume', &
      'The namelist reference is in docs/inputs.md, the HDF5 layout in docs/output.md.'])
  end subroutine print_help

  !> `ellroll COMMAND --help`: what the command does and the options it takes.
  subroutine print_command_help(topic)
    character(len=*), intent(in) :: topic
    select case (topic)
    case ('run')
      call put_lines([character(len=help_width) :: &
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
        '  --shard I/N           run only cases I, I+N, I+2N, ... into their own file, -o (ellroll merge joins them)', &
        '  -q, --quiet           no progress lines on stderr', &
        '  --timings             print where the run''s time went'])
    case ('check')
      call put_lines([character(len=help_width) :: &
        'usage: ellroll check FILE.nml [-o OUT.h5] [--shard I/N] [--threads N]', &
        '', &
        'Reads and validates FILE.nml, prints the resolved cases and the campaign, writes nothing.', &
        '-o: the output''s name to check (as for run); --shard I/N: the count of that shard''s cases;', &
        '--threads N: the threads of its checks of every case (the result is the same on any count).', &
        'Bad input: a message naming the file, line, namelist group, variable and value; exit 2.'])
    case ('merge')
      call put_lines([character(len=help_width) :: &
        'usage: ellroll merge OUT.h5 SHARD.h5... [--overwrite]', &
        '', &
        'Joins the files of ''ellroll run --shard I/N'' (all N shards of one input) into OUT.h5, equal', &
        'to the file of the same run unsharded.'])
    case ('summary')
      call put_lines([character(len=help_width) :: &
        'usage: ellroll summary OUT.h5 [--suite] [--format table|csv|json]', &
        '', &
        'table (the default): cases per status, steps, integration time, the slowest case; of a', &
        'campaign, each real figure''s min / median / max over its completed cases (6 digits).', &
        'csv, json: one row per case: case, the varied inputs, status by name and every figure of', &
        '/summary. The JSON is strict (NaN as null) and gives the units in its "units" object.', &
        '--suite: one row per stripe (the cases that share every varied input but the record):', &
        'counts, the fraction at a model limit and past each /limit_state, and each response', &
        'figure''s 16th, 50th and 84th percentile over the completed cases (docs/isolator.md).'])
    case ('modes')
      call put_lines([character(len=help_width) :: &
        'usage: ellroll modes FILE.nml', &
        '', &
        'The small-oscillation periods of every case about the lowest point of its cup (docs/model.md).'])
    case ('methods')
      call put_lines([character(len=help_width) :: &
        'usage: ellroll methods', &
        '', &
        'The integration methods: name, kind (fixed step, adaptive or symmetric), order and when to pick it.'])
    case ('version')
      call put_lines([character(len=help_width) :: &
        'usage: ellroll --version', '', 'The version and the build (Release, Debug, ...) of this ellroll.'])
    case ('inputs')
      call put_lines([character(len=help_width) :: &
        'usage: ellroll inputs', &
        '', &
        'The real inputs (namelist group, variable, unit, range, default) as a Markdown table;', &
        'each may be varied by &sweep or &sample under the name in its first column.'])
    end select
  end subroutine print_command_help

  subroutine print_version()
    call put_line('ellroll ' // version_string // ' (' // build_string // ' build)')
  end subroutine print_version

  !> `ellroll methods`: the methods' table.
  subroutine print_methods()
    integer :: k
    character(len=10) :: name, kind
    character(len=30) :: order
    call put_line('method    kind      order                         use for')
    do k = 1, size(methods)
      name = methods(k)%name
      kind = methods(k)%kind
      order = methods(k)%order
      call put_line(name // kind // order // trim(methods(k)%use_for))
    end do
  end subroutine print_methods

  !> The parameter table as a Markdown table (docs/inputs.md holds it).
  subroutine print_inputs()
    integer :: k
    character(len=:), allocatable :: default, variable
    call put_line('| name | group | variable | unit | valid range | default | varied | description |')
    call put_line('| --- | --- | --- | --- | --- | --- | --- | --- |')
    do k = 1, size(params)
      associate (p => params(k))
        default = format_real(p%default)
        if (p%required) default = 'required'
        if (param_unset_allowed(k)) default = 'unset'
        variable = trim(p%variable)
        if (param_component(k) > 0) variable = variable // '(' // itoa(param_component(k)) // ')'
        call put_line('| `' // trim(p%name) // '` | `&' // trim(p%group) // '` | `' // variable // &
            '` | ' // trim(p%unit) // ' | ' // range_text(k) // ' | ' // default // ' | ' // &
            trim(merge('yes', 'no ', p%sweepable)) // ' | ' // trim(p%description) // ' |')
      end associate
    end do
  end subroutine print_inputs
end module ellroll_cmd_info
