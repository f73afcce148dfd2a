!> `ellroll run FILE.nml`: an input read and checked, its step advice
!> given, its campaign run into its output, then the output's summary
!> printed. Under MPI (more than one rank) each rank runs a shard and rank
!> 0 merges them.
module ellroll_cmd_run
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_errors, only: error_t, set_error, err_input, err_output
  use ellroll_strings, only: itoa
  use ellroll_input, only: run_input_t, read_input
  use ellroll_run_timings, only: wall_clock
  use ellroll_run_campaign, only: run_options_t, run_campaign
  use ellroll_output_start, only: check_output_target, holds_this_run
  use ellroll_output_files, only: output_files_t, check_replace, work_target, work_journal
  use ellroll_step_advice, only: step_size_advice, dt_cap_advice, dt_cap_after_run, record_start_advice
  use ellroll_disk_room, only: disk_room_advice
  use ellroll_shards, only: shard_size
  use ellroll_merge, only: merge_shards
  use ellroll_files, only: path_kind, kind_regular, kind_missing, file_size, path_length
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: format_real
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_status, only: status_invalid
  use ellroll_system, only: catch_stop_signals
  use ellroll_ranks, only: ranks_all_ok
  use ellroll_cli, only: cli_t, provenance
  use ellroll_cmd_summary, only: print_summary
  implicit none
  private

  public :: run_command

contains

  !> Exit 2 for bad input, 3 for an output that cannot be written; a
  !> case that reaches a model limit is a result, not an error.
  subroutine run_command(cli, rank, n_ranks, err)
    type(cli_t), intent(in) :: cli
    integer, intent(in) :: rank, n_ranks      !< this process's MPI rank, of n_ranks (0 of 1 without MPI)
    type(error_t), intent(inout) :: err
    type(error_t) :: unread
    type(run_input_t) :: inp
    type(run_options_t) :: opts
    character(len=:), allocatable :: advice, cap
    real(wp) :: started
    integer(i8) :: ran
    started = wall_clock()
    opts = cli%opts
    call read_input(trim(cli%paths(1)), cli%output_path, inp, err)
    if (err%failed()) return
    ! (every shard would write the one &output file: each needs its own)
    if (opts%shard(2) > 1 .and. len(cli%output_path) == 0) then
      call shard_name(inp%plan%file, opts%shard(1), advice)
      call set_error(err, err_input, '--shard ' // itoa(opts%shard(1)) // '/' // itoa(opts%shard(2)) // &
          ' needs -o naming this shard''s own file (e.g. -o ' // advice // '): every shard of the campaign ' // &
          'would write ' // inp%plan%file)
      return
    end if
    call check_output_target(inp%plan%file, inp%path, err)
    if (err%failed()) return
    call catch_stop_signals()
    opts%advice_seconds = wall_clock()
    call step_size_advice(inp, advice)
    call dt_cap_advice(inp, cap)
    if (len(cap) > 0) advice = trim(advice // achar(10) // cap)
    call record_start_advice(inp, cap)
    if (len(cap) > 0) advice = trim(advice // achar(10) // cap)
    call disk_room_advice(inp, shard_size(inp%campaign%n_cases(), opts%shard(1), opts%shard(2)), cap)
    if (len(cap) > 0) advice = trim(advice // achar(10) // cap)
    if (advice(1:min(1, len(advice))) == achar(10)) advice = advice(2:)
    opts%advice_seconds = wall_clock() - opts%advice_seconds
    if (len(advice) > 0 .and. rank == 0) write (error_unit, '(a)') advice
    ran = -1                                 ! (unknown under MPI: each rank runs a shard)
    if (n_ranks > 1) then
      call run_ranks(inp, opts, trim(cli%paths(1)), rank, n_ranks, err)
    else
      call check_rank_files(inp%plan%file, 1, err)
      if (.not. err%failed()) call run_campaign(inp, opts, provenance(trim(cli%paths(1)), inp%text), err, ran)
    end if
    if (err%failed() .or. rank /= 0) return
    ! the output is complete; a summary that cannot be read back leaves
    ! standard output without it: exit 3, as for standard output that
    ! cannot be written
    call print_summary(inp%plan%file, 'table', unread)
    if (.not. cli%opts%quiet) call final_block(inp, wall_clock() - started, ran, advice)
    if (unread%failed()) call set_error(err, err_output, inp%plan%file // ': complete and in place, but its ' // &
        'summary cannot be printed (' // unread%message // '); ''ellroll summary ' // inp%plan%file // &
        ''' prints it')
  end subroutine run_command

  !> The end of a run, on stderr beside the progress (stdout holds the
  !> file's summary, as `ellroll summary` prints it): its wall time, cases per second, the output's size,
  !> and a recap of the warnings (the advice before the run, invalid cases
  !> skipped, steps that dt capped), the count and the first few.
  subroutine final_block(inp, elapsed, ran, advice)
    type(run_input_t), intent(in) :: inp
    real(wp), intent(in) :: elapsed
    integer(i8), intent(in) :: ran               !< cases integrated by this process; < 0 unknown (MPI)
    character(len=*), intent(in) :: advice       !< warnings printed before the run, a line each
    integer, parameter :: shown = 3
    type(h5_input_t) :: file
    type(error_t) :: unread
    integer(i8), allocatable :: status(:), steps(:), index(:)
    character(len=:), allocatable :: line, warnings, cap
    integer :: n_warnings, start, eol
    integer(i8) :: n_cases
    call file%open(inp%plan%file, unread)
    status = file%int_column('summary/status', unread)
    steps = file%int_column('summary/n_steps', unread)
    index = file%int_column('summary/case', unread)
    call file%close()
    if (unread%failed()) return
    n_cases = size(status, kind=i8)
    if (ran >= 0) n_cases = ran
    line = 'done in ' // format_real(hundredths(elapsed)) // ' s: ' // itoa(n_cases) // &
        trim(merge(' case run ', ' cases run', n_cases == 1))
    if (elapsed > 0) line = line // ', ' // format_real(real(nint(10 * n_cases / elapsed, i8), wp) / 10) // &
        ' cases/s'
    write (error_unit, '(a)') 'ellroll: ' // line // '; ' // inp%plan%file // ': ' // &
        trim(size_text(int(file_size(inp%plan%file), i8)))
    ! the recap: a line per warning, 'ellroll: warning: ' left off
    n_warnings = 0
    warnings = ''
    start = 1
    do while (start <= len(advice))
      eol = index_of_newline(advice, start)
      if (advice(start:min(eol - 1, start + 17)) == 'ellroll: warning: ') call add(advice(start + 18:eol - 1))
      start = eol + 1
    end do
    if (count(status == status_invalid) > 0) call add(itoa(count(status == status_invalid)) // &
        ' invalid cases skipped (status invalid)')
    call dt_cap_after_run(inp, index, status, steps, cap)
    if (len(cap) > 0 .and. index_of_text(advice, ' caps ') == 0) then        ! (not said before the run)
      write (error_unit, '(a)') cap
      call add(cap(19:))
    end if
    if (n_warnings == 0) return
    write (error_unit, '(a)') 'ellroll: warnings: ' // itoa(n_warnings) // warnings
    if (n_warnings > shown) write (error_unit, '(a)') '    ... and ' // itoa(n_warnings - shown) // ' more (above)'
  contains
    subroutine add(text)
      character(len=*), intent(in) :: text
      n_warnings = n_warnings + 1
      if (n_warnings <= shown) warnings = warnings // achar(10) // '    ' // text
    end subroutine add
  end subroutine final_block

  pure integer function index_of_newline(text, start) result(eol)
    character(len=*), intent(in) :: text
    integer, intent(in) :: start
    eol = index(text(start:), achar(10))
    if (eol == 0) then
      eol = len(text) + 1
    else
      eol = start + eol - 1
    end if
  end function index_of_newline

  pure integer function index_of_text(text, part)
    character(len=*), intent(in) :: text, part
    index_of_text = index(text, part)
  end function index_of_text

  pure real(wp) function hundredths(x)
    real(wp), intent(in) :: x
    hundredths = anint(100 * x) / 100
  end function hundredths

  !> A size in bytes as B, KiB, MiB or GiB (one decimal).
  pure function size_text(bytes) result(text)
    integer(i8), intent(in) :: bytes
    character(len=24) :: text
    real(wp) :: b
    b = real(bytes, wp)
    if (b < 1024) then
      write (text, '(i0, a)') bytes, ' B'
    else if (b < 2.0_wp**20) then
      write (text, '(f0.1, a)') b / 1024, ' KiB'
    else if (b < 2.0_wp**30) then
      write (text, '(f0.1, a)') b / 2.0_wp**20, ' MiB'
    else
      write (text, '(f0.1, a)') b / 2.0_wp**30, ' GiB'
    end if
  end function size_text

  !> OUT.h5 with shard I's suffix: OUT.shard_I.h5 (as examples/slurm names them).
  pure subroutine shard_name(file, shard, name)
    character(len=*), intent(in) :: file
    integer, intent(in) :: shard
    character(len=:), allocatable, intent(out) :: name
    name = file // '.shard_' // itoa(shard) // '.h5'
    if (len(file) > 3) then
      if (file(len(file) - 2:) == '.h5') name = file(:len(file) - 3) // '.shard_' // itoa(shard) // '.h5'
    end if
  end subroutine shard_name

  !> Under MPI: rank r runs shard r/N into OUT.rankR.h5; when every rank has
  !> succeeded, rank 0 merges the shards into OUT and removes them.
  subroutine run_ranks(inp, opts, input_file, rank, n_ranks, err)
    type(run_input_t), intent(inout) :: inp
    type(run_options_t), intent(inout) :: opts
    character(len=*), intent(in) :: input_file
    integer, intent(in) :: rank, n_ranks
    type(error_t), intent(inout) :: err
    type(output_files_t) :: files
    character(len=:), allocatable :: target
    character(len=path_length), allocatable :: shard_files(:)
    integer :: r
    logical :: shard_done, complete, all_ok, to_run
    if (opts%shard(2) > 1) then
      call set_error(err, err_input, '--shard cannot be combined with MPI ranks (each rank is a shard)')
      return
    end if
    target = inp%plan%file
    allocate (shard_files(n_ranks))
    do r = 0, n_ranks - 1
      shard_files(r + 1) = target // '.rank' // itoa(r) // '.h5'
    end do
    ! rank 0 holds the output's lock until the shards are merged into it
    complete = .false.
    if (rank == 0) then
      call files%name(target, inp%path)
      call files%acquire(err, launcher='mpirun -n ' // itoa(n_ranks))
      call files%check(target, work_target, err)
      call check_rank_files(target, n_ranks, err)
      if (.not. err%failed()) then
        if (path_kind(target) == kind_regular) then
          if (opts%resume) complete = holds_this_run(target, inp, [0, 1])
          if (.not. (opts%overwrite .or. complete)) &
            call set_error(err, err_output, target // ': output file exists; pass --overwrite to replace it')
          if (.not. complete) call check_replace(target, err)
        end if
      end if
    end if
    ! (every rank takes part in both collectives, whatever they answer)
    all_ok = ranks_all_ok(.not. err%failed())
    to_run = ranks_all_ok(.not. complete)
    if (.not. all_ok .or. .not. to_run) then
      if (all_ok .and. rank == 0) then
        write (error_unit, '(a)') 'ellroll: ' // target // ': this run is already complete; nothing to do'
        do r = 1, n_ranks           ! (merged into it, where a fault after its move into place left them)
          call discard_finished(trim(shard_files(r)), inp%path, err)
        end do
      end if
      call files%release(err)
      return
    end if
    opts%shard = [rank, n_ranks]
    opts%quiet = opts%quiet .or. rank /= 0
    inp%plan%file = trim(shard_files(rank + 1))
    ! a rank whose shard finished before an interruption has nothing to resume
    shard_done = .false.
    if (opts%resume) shard_done = holds_this_run(inp%plan%file, inp, opts%shard)
    if (shard_done) then
      call discard_finished(inp%plan%file, inp%path, err, keep_output=.true.)
    else
      call run_campaign(inp, opts, provenance(input_file, inp%text), err)
    end if
    inp%plan%file = target
    if (.not. ranks_all_ok(.not. err%failed())) then
      if (.not. err%failed()) call set_error(err, err_output, 'another rank failed; see its message')
      call files%release(err)
      return
    end if
    if (rank == 0) then
      call merge_shards(target, shard_files, .true., provenance(input_file, inp%text), err, locked=files)
      do r = 1, n_ranks
        if (.not. err%failed()) call files%discard(trim(shard_files(r)), work_target, err)
      end do
      call files%release(err)
    end if
  end subroutine run_ranks

  !> A rank's output that holds its whole shard: its journal, where a fault
  !> after the output's move into place left it (no work file beside it),
  !> and the output itself unless keep_output (merged into the output
  !> already), removed as the files of a finished run.
  !> (Rank 0 holds the output's lock: no other run of it works on them.)
  subroutine discard_finished(shard_file, input, err, keep_output)
    character(len=*), intent(in) :: shard_file, input
    type(error_t), intent(inout) :: err
    logical, intent(in), optional :: keep_output
    type(output_files_t) :: shard
    call shard%name(shard_file, input)
    if (path_kind(shard%partial) /= kind_missing) return
    if (path_kind(shard%resumed) /= kind_missing) return
    call shard%discard(shard%journal, work_journal, err)
    if (present(keep_output)) then
      if (keep_output) return
    end if
    call shard%discard(shard_file, work_target, err)
  end subroutine discard_finished

  !> Files of an earlier run of this output on another number of MPI ranks
  !> are refused: this run could not finish them. Its rank files stop at
  !> rank n_ranks - 1: none of rank n_ranks (more ranks before), and some of
  !> rank n_ranks - 1 wherever rank 0 has some (fewer ranks before).
  subroutine check_rank_files(target, n_ranks, err)
    character(len=*), intent(in) :: target
    integer, intent(in) :: n_ranks
    type(error_t), intent(inout) :: err
    integer :: last
    if (err%failed()) return
    if (any_rank_file(target, n_ranks)) then
      last = n_ranks
      do while (any_rank_file(target, last + 1))
        last = last + 1
      end do
      call set_error(err, err_output, target // '.rank' // itoa(last) // '.h5: the files of a run of this ' // &
          'output on at least ' // itoa(last + 1) // ' MPI ranks are here (this run has ' // itoa(n_ranks) // &
          '); finish it on as many ranks as it was started on (mpirun -n ' // itoa(last + 1) // ' ... --resume), ' // &
          'or remove its .rank files')
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
      ! (a name the system cannot look at, one too long for it, holds no file)
      if (path_kind(target // '.rank' // itoa(r) // '.h5' // trim(suffixes(k))) > kind_missing) &
        any_rank_file = .true.
    end do
  end function any_rank_file
end module ellroll_cmd_run
