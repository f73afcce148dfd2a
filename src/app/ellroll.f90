!> The ellroll program: the command line parsed, its command run, the
!> error turned into the exit code. Exit codes: 0 ok (also when a case
!> ended at a model limit), 1 internal error, 2 bad input, 3 output error,
!> 128 + the signal when a run was interrupted.
program ellroll
  use, intrinsic :: iso_fortran_env, only: error_unit
  !$ use omp_lib, only: omp_set_num_threads
  !$ use ellroll_kinds, only: i8
  !$ use ellroll_threads, only: team_size
  use ellroll_errors, only: error_t, err_interrupted, exit_code
  use ellroll_hdf5_common, only: hdf5_close_failed
  use ellroll_system, only: tune_runtime, exit_now
  use ellroll_ranks, only: ranks_start, ranks_stop
  use ellroll_cli, only: cli_t, parse_arguments, resume_line
  use ellroll_cmd_info, only: print_help, print_command_help, print_version, print_methods, print_inputs
  use ellroll_cmd_check, only: check_command
  use ellroll_cmd_run, only: run_command
  use ellroll_cmd_merge, only: merge_command
  use ellroll_cmd_summary, only: summary_command
  use ellroll_cmd_modes, only: modes_command
  use ellroll_standard_output, only: stdout_error
  implicit none

  type(cli_t) :: cli
  type(error_t) :: err
  character(len=:), allocatable :: line
  integer :: rank, n_ranks, status

  call tune_runtime()
  call ranks_start(rank, n_ranks)
  call parse_arguments(cli, err)
  !$ call omp_set_num_threads(team_size(cli%opts%threads, huge(1_i8)))   ! for every parallel loop (capped)
  if (.not. err%failed()) then
    select case (cli%command)
    case ('help')
      if (cli%help_topic == '') then
        call print_help()
      else
        call print_command_help(trim(cli%help_topic))
      end if
    case ('version')
      call print_version()
    case ('check')
      call check_command(cli, err)
    case ('run')
      call run_command(cli, rank, n_ranks, err)
    case ('merge')
      call merge_command(cli, err)
    case ('summary')
      call summary_command(cli, err)
    case ('methods')
      call print_methods()
    case ('inputs')
      call print_inputs()
    case ('modes')
      call modes_command(cli, err)
    end select
  end if
  ! every command's output written (put_line): a failed write or close of
  ! standard output is an output error (exit 3)
  if (.not. err%failed()) call stdout_error(err)
  status = 0
  if (err%code > err_interrupted .and. cli%command == 'merge') then
    ! (a merge keeps nothing of its work: it starts afresh)
    write (error_unit, '(a)') 'ellroll: ' // err%message // '; run it again'
    status = exit_code(err)
  else if (err%code > err_interrupted) then
    call resume_line(n_ranks, line)
    write (error_unit, '(a)') 'ellroll: ' // err%message // '; ''' // line // ''' finishes the rest'
    status = exit_code(err)
  else if (err%failed()) then
    write (error_unit, '(a)') 'ellroll: error: ' // err%message
    status = exit_code(err)
  end if
  ! every rank says why it stops before any leaves: mpirun ends the others
  ! as soon as one exits with an error status
  flush (error_unit)
  call ranks_stop()
  ! freed before the exit, which would otherwise leave them to the system:
  ! a sanitizer build's leak check then reports only real leaks
  deallocate (cli%command, cli%output_path, cli%paths)
  err = error_t()
  if (status /= 0 .or. hdf5_close_failed()) then
    ! what was finished is in the journal and the partial file; HDF5's own
    ! exit handler would close files whose writes failed (a full disk), or
    ! that it could not close, and can crash doing so
    flush (error_unit)
    call exit_now(status)
  end if
end program ellroll
