!> Running a campaign (or one shard of it) into one HDF5 file: OpenMP over
!> blocks of cases with dynamic scheduling, a single writer of the table
!> rows (HDF5's Fortran API is not thread-safe) while each thread writes
!> its cases' trajectories and journal records in place, a journal that
!> makes an interruption lose nothing, progress and timings. How the run
!> begins on the files there (afresh, resumed, nothing to do) is
!> ellroll_output_start's; which cases are invalid, ellroll_invalid_cases'.
!>
!> Files, for output OUT: OUT.partial (the HDF5 file being written, moved to
!> OUT when complete) and OUT.journal (every finished case, the durable
!> record; deleted when OUT is in place). A resume builds OUT.partial.new
!> from the journal and the killed run's OUT.partial, which holds the
!> journaled cases' trajectories, and moves it over OUT.partial
!> (ellroll_resume).
module ellroll_run_campaign
  use ellroll_threads, only: team_size
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_interrupted, err_input
  use ellroll_strings, only: itoa
  use ellroll_status, only: status_invalid
  use ellroll_cases, only: case_t
  use ellroll_results, only: case_result_t
  use ellroll_input, only: run_input_t
  use ellroll_block_run, only: simulate_block, uses_batches, lanes
  use ellroll_hdf5_writer, only: h5_output_t, provenance_t, window_list_t
  use ellroll_file_layout, only: file_row
  use ellroll_records, only: named_value_t
  use ellroll_journal, only: journal_t
  use ellroll_progress, only: progress_t
  use ellroll_system, only: stop_signal, signal_name, file_exists, folder_of
  use ellroll_files, only: path_kind, kind_missing
  use ellroll_output_files, only: output_files_t, work_partial, work_journal
  use ellroll_output_start, only: decide_start, open_outputs
  use ellroll_invalid_cases, only: find_invalid_cases, refuse_invalid_cases
  use ellroll_run_timings, only: run_timings_t, wall_clock, lock_journal, lock_keep, lock_writer, &
      writes_trajectories, writes_journal
  implicit none
  private

  public :: run_options_t, run_campaign

  type :: run_options_t
    integer :: threads = 0               !< 0: OMP_NUM_THREADS or all cores
    logical :: quiet = .false.
    logical :: resume = .false.
    logical :: overwrite = .false.
    logical :: timings = .false.         !< print where the time went (phases, locks)
    real(wp) :: advice_seconds = 0       !< time of step_size_advice before the run (parallel), for the timings
    integer :: shard(2) = [0, 1]         !< this shard's index I and the count N
  end type run_options_t

  !> What the threads of a run share: the file and journal they write, the
  !> slots done, progress, timings and the loop's first error.
  type :: run_state_t
    integer :: shard(2) = [0, 1]
    integer(i8) :: n_slots = 0
    logical :: use_batches = .false.
    integer(i8) :: block_slots = 1             !< slots a block of the loop holds
    logical :: resumed = .false.               !< a resume: the killed run's files are kept whatever happens
    logical, allocatable :: done(:)
    type(h5_output_t) :: out
    type(journal_t) :: journal
    type(progress_t) :: progress
    type(run_timings_t) :: timings
    !> the loop's first error, set under its lock (record_failure); `failed`
    !> tells the other blocks to stop, read and written atomically
    type(error_t) :: first_err
    integer :: failed = 0
  contains
    procedure :: global_index
    procedure :: record_failure
    procedure :: loop_failed
  end type run_state_t

contains

  subroutine run_campaign(inp, opts, prov_in, err, ran)
    type(run_input_t), intent(in) :: inp
    type(run_options_t), intent(in) :: opts
    type(provenance_t), intent(in) :: prov_in
    type(error_t), intent(inout) :: err
    integer(i8), intent(out), optional :: ran      !< the cases this call integrated
    character(len=:), allocatable :: messages
    logical, allocatable :: invalid(:)
    logical :: resume, nothing_to_do, orphan, opened
    type(output_files_t) :: files
    type(run_state_t) :: run

    run%timings%started = wall_clock()
    opened = .false.
    call files%name(inp%plan%file, inp%path)

    ! invalid cases: stop before any work, or skip them
    call find_invalid_cases(inp, invalid, messages)
    run%timings%advice = opts%advice_seconds
    run%timings%checked = wall_clock()
    call refuse_invalid_cases(inp, invalid, messages, err)
    if (err%failed()) return
    if (present(ran)) ran = 0
    call files%acquire(err)
    if (err%failed()) return
    orphan = file_exists(files%partial)
    call decide_start(inp, opts%shard, opts%resume, opts%overwrite, files, resume, nothing_to_do, err)
    if (.not. (err%failed() .or. nothing_to_do)) then
      call files%note_target()
      run%shard = opts%shard
      run%resumed = resume
      ! (a mistyped -o, or a journal lost: said, so that a campaign run again from its start is no surprise)
      if (opts%resume .and. .not. (resume .or. opts%quiet)) then
        if (orphan) then
          write (error_unit, '(a)') 'ellroll: resuming ' // files%target // ': no journal ' // files%journal // &
              ' (the work file ' // files%partial // ' without it holds no case a resume can trust); running all cases'
        else
          write (error_unit, '(a)') 'ellroll: resuming ' // files%target // ': no journal ' // files%journal // &
              ', so no case is kept; running all cases'
        end if
      end if
      opened = .true.
      call open_outputs(inp, opts%shard, prov_in, files, resume, run%out, run%journal, run%done, err)
      if (.not. err%failed()) then
        run%n_slots = size(run%done, kind=i8)
        if (resume .and. .not. opts%quiet) write (error_unit, '(a)') 'ellroll: resuming ' // files%target // &
            ': kept ' // itoa(count(run%done, kind=i8)) // ' of ' // itoa(run%n_slots) // &
            ' cases from the journal; running ' // itoa(run%n_slots - count(run%done, kind=i8))
        call record_invalid(inp, invalid, run, err)
      end if
      if (err%failed()) then
        call abandon(run, files, err)
      else
        if (present(ran)) ran = -count(run%done, kind=i8)
        call run_blocks(inp, opts, run)
        if (present(ran)) ran = ran + run%progress%done
        call finish(run, files, opts, err)
      end if
    end if
    ! (a command refused before it opened the outputs, or for its input,
    ! leaves a killed run's lock as it found it: its note names the command
    ! that finishes that run)
    call files%release(err, refused=err%failed() .and. (.not. opened .or. err%code == err_input))
  end subroutine run_campaign

  !> Invalid cases skipped: recorded, never integrated.
  subroutine record_invalid(inp, invalid, run, err)
    type(run_input_t), intent(in) :: inp
    logical, intent(in) :: invalid(0:)
    type(run_state_t), intent(inout) :: run
    type(error_t), intent(inout) :: err
    type(case_result_t) :: res
    integer(i8) :: slot
    do slot = 0, run%n_slots - 1
      if (err%failed()) exit
      if (run%done(slot) .or. .not. invalid(run%global_index(slot))) cycle
      res = case_result_t(status=status_invalid)
      call run%out%write_case(slot, inp%campaign%case_at(run%global_index(slot)), res, err)
      run%done(slot) = .true.
    end do
  end subroutine record_invalid

  !> Every block not done, over the threads, until all are done, one fails
  !> or a stop signal comes.
  subroutine run_blocks(inp, opts, run)
    type(run_input_t), intent(in) :: inp
    type(run_options_t), intent(in) :: opts
    type(run_state_t), intent(inout) :: run
    integer(i8) :: chunk
    integer :: n_threads
    n_threads = team_size(opts%threads, run%n_slots)
    call run%progress%start(run%n_slots, count(run%done, kind=i8), opts%quiet)
    ! In a campaign that batches (uses_batches), blocks of `lanes` slots
    ! whose batchable cases run together across SIMD lanes (simulate_block).
    ! Cases that run one by one may be grouped in any way: blocks of up to
    ! `lanes` of them (the locks and writes taken once per block), fewer
    ! where that gives every thread at least four blocks.
    run%use_batches = uses_batches(inp%campaign)
    run%block_slots = lanes
    if (.not. run%use_batches) run%block_slots = max(1_i8, min(int(lanes, i8), run%n_slots / (4_i8 * n_threads)))
    run%timings%loop_started = wall_clock()
    !$omp parallel do schedule(dynamic, 1) num_threads(n_threads) default(shared) private(chunk)
    do chunk = 0, (run%n_slots - 1) / run%block_slots
      if (.not. run%loop_failed()) then
        if (stop_signal() == 0) call run_block(run, inp, chunk)
      end if
    end do
    !$omp end parallel do
    run%timings%loop_ended = wall_clock()
    call run%progress%finish()
  end subroutine run_blocks

  !> After the loop: the first error, an interruption, or the finished file
  !> moved into place and its journal deleted.
  subroutine finish(run, files, opts, err)
    type(run_state_t), intent(inout) :: run
    type(output_files_t), intent(inout) :: files
    type(run_options_t), intent(in) :: opts
    type(error_t), intent(inout) :: err
    logical :: lock_lost
    if (run%first_err%failed()) then
      err = run%first_err
      call abandon(run, files, err)
      return
    end if
    if (run%progress%done < run%n_slots) then          ! asked to stop (SIGTERM, SIGINT)
      call set_error(err, err_interrupted + stop_signal(), 'interrupted by ' // signal_name(stop_signal()) // &
          ' after ' // itoa(run%progress%done) // ' of ' // itoa(run%n_slots) // ' cases')
      call keep_finished(run, files)
      return
    end if
    call run%out%close(err)
    call run%journal%close(err)
    lock_lost = files%lock_lost()       ! (commit then moves nothing, and says why)
    call files%commit(files%partial, err)
    ! (a lock gone with its folder: the run's files went there too, and the
    ! advice below says how to finish it; a lock removed by hand: none)
    if (lock_lost) then
      if (.not. folder_gone(files)) return
    end if
    ! a write error before the finished file moved into place (closing it:
    ! /switches, metadata; or its sync or rename): the journal keeps every
    ! case, and abandon says so as for an error in the loop; after it,
    ! commit's own message says what is left to do
    if (err%failed()) then
      if (file_exists(files%partial)) then
        call abandon(run, files, err)
      else if (moved_away(files)) then
        ! (its journal and partial file went with it, wherever it went; a
        ! folder made at its name since holds neither)
        err%message = err%message // achar(10) // '  ' // files%journal // ', in that folder, keeps the cases ' // &
            'finished so far: run again with -o naming the output in the folder''s new place and --resume'
      end if
      return
    end if
    run%timings%ended = wall_clock()
    if (opts%timings) call run%timings%report()
  end subroutine finish

  !> Whether the output's folder is gone, or another is at its name: its
  !> journal is not there.
  logical function moved_away(files)
    type(output_files_t), intent(in) :: files
    moved_away = folder_gone(files)
    if (.not. moved_away) moved_away = path_kind(files%journal) == kind_missing
  end function moved_away

  !> Whether the output's folder is gone (moved or removed, no other at its name).
  logical function folder_gone(files)
    type(output_files_t), intent(in) :: files
    folder_gone = path_kind(folder_of(files%target)) == kind_missing
  end function folder_gone

  !> Integrate the slots of one block not done yet, write their trajectories
  !> and journal records, then hand their table rows to the writer: each
  !> lock taken once per block.
  subroutine run_block(run, inp, chunk)
    type(run_state_t), intent(inout) :: run
    type(run_input_t), intent(in) :: inp
    integer(i8), intent(in) :: chunk
    type(case_t) :: cases(lanes)
    type(case_result_t) :: results(lanes)
    type(error_t) :: case_err, write_err
    type(window_list_t) :: full
    integer(i8) :: slots(lanes), slot
    integer :: n, n_done, j, run_start
    integer(i8), allocatable :: records(:)    !< the journal records of the block, one after the other
    type(named_value_t), allocatable :: rows(:, :)
    real(wp) :: asked, taken
    integer(i8) :: place, record_size
    n = 0
    do slot = chunk * run%block_slots, min(run%n_slots, (chunk + 1) * run%block_slots) - 1
      if (run%done(slot)) cycle
      n = n + 1
      slots(n) = slot
      cases(n) = inp%campaign%case_at(run%global_index(slot))
    end do
    if (n == 0) return
    call simulate_block(cases(:n), run%use_batches, inp%plan, results(:n), n_done, case_err)
    if (stop_signal() /= 0) return       ! cases cut short: the block runs again on --resume
    ! the trajectories go to their place in the file, one write per run of
    ! consecutive slots; records and table rows are built here: all outside the locks
    asked = wall_clock()
    run_start = 1
    do j = 1, n_done
      if (j < n_done) then
        if (slots(j + 1) == slots(j) + 1) cycle
      end if
      call run%out%put_trajectories(slots(run_start), results(run_start:j), write_err)
      run_start = j + 1
    end do
    if (n_done > 0) call run%timings%add_write(writes_trajectories, asked)
    record_size = 0
    do j = 1, n_done
      record_size = record_size + run%journal%record_size(results(j))
    end do
    ! (a row's size, its checksum aside: the rows below hold theirs)
    allocate (records(record_size), rows(size(file_row(cases(1), results(1), 0_i8)), n_done))
    record_size = 0
    do j = 1, n_done
      records(record_size + 1:record_size + run%journal%record_size(results(j))) = &
          run%journal%record(slots(j), results(j))
      record_size = record_size + run%journal%record_size(results(j))
      rows(:, j) = run%out%row(cases(j), results(j))
    end do
    ! the journal: places taken under its lock, the records written there
    ! outside it, after the trajectories (a resume takes a journaled case's
    ! trajectories from the file)
    if (n_done > 0 .and. .not. write_err%failed()) then
      asked = wall_clock()
      !$omp critical (ellroll_journal)
      taken = wall_clock()
      place = run%journal%reserve(size(records, kind=i8))
      call run%timings%tally(lock_journal, asked, taken)
      !$omp end critical (ellroll_journal)
      asked = wall_clock()
      call run%journal%write_records(place, records, write_err)
      call run%timings%add_write(writes_journal, asked)
    end if
    if (case_err%failed()) then
      call run%record_failure(case_err)
    else
      call run%record_failure(write_err)
    end if
    if (n_done == 0) return
    asked = wall_clock()
    !$omp critical (ellroll_keep)
    taken = wall_clock()
    do j = 1, n_done
      call run%out%keep_case(slots(j), rows(:, j), results(j), full)
      call run%progress%advance()
    end do
    call run%timings%tally(lock_keep, asked, taken)
    !$omp end critical (ellroll_keep)
    if (full%n == 0) return
    asked = wall_clock()
    !$omp critical (ellroll_writer)
    taken = wall_clock()
    if (.not. run%loop_failed()) call run%out%write_windows(full, write_err)
    call run%timings%tally(lock_writer, asked, taken)
    !$omp end critical (ellroll_writer)
    call run%record_failure(write_err)
    asked = wall_clock()
    !$omp critical (ellroll_keep)
    taken = wall_clock()
    call run%out%recycle(full)
    call run%timings%tally(lock_keep, asked, taken)
    !$omp end critical (ellroll_keep)
  end subroutine run_block

  !> Keep err as the loop's first error (if it is one and none came
  !> before), and tell the other blocks to stop.
  subroutine record_failure(self, err)
    class(run_state_t), intent(inout) :: self
    type(error_t), intent(in) :: err
    if (.not. err%failed()) return
    !$omp critical (ellroll_first_error)
    if (.not. self%first_err%failed()) self%first_err = err
    !$omp end critical (ellroll_first_error)
    !$omp atomic write
    self%failed = 1
  end subroutine record_failure

  !> Whether a block has failed (the loop then starts no more blocks).
  logical function loop_failed(self)
    class(run_state_t), intent(inout) :: self
    integer :: flag
    !$omp atomic read
    flag = self%failed
    loop_failed = flag /= 0
  end function loop_failed

  !> The campaign's index of the case in this shard's `slot`.
  pure integer(i8) function global_index(self, slot)
    class(run_state_t), intent(in) :: self
    integer(i8), intent(in) :: slot
    global_index = self%shard(1) + slot * self%shard(2)
  end function global_index

  !> After a failure, keep what is finished, and say where it is; a run
  !> that finished nothing (and is no resume) leaves no file behind.
  subroutine abandon(run, files, err)
    type(run_state_t), intent(inout) :: run
    type(output_files_t), intent(in) :: files
    type(error_t), intent(inout) :: err
    type(error_t) :: cleanup
    logical :: kept
    kept = run%journal%holds_records() .or. run%resumed
    call keep_finished(run, files)
    ! (files at the output's names may be another run's: none is touched)
    if (files%lock_lost()) return
    ! a journal its resume refused stays as it is, and the refusal alone says
    ! what to do (a resume again would meet it again)
    if (run%resumed .and. run%journal%record_words == 0) return
    if (kept) then
      ! a resume's file that it failed to lay out (HDF5 made it, never
      ! whole) holds no case: it goes, or the next resume would meet a work
      ! file that is not yet an ellroll file (one a killed resume left, whose
      ! cases could not all be taken back before, stays)
      if (run%resumed .and. files%laying_out) call files%discard(files%resumed, work_partial, cleanup, made=.true.)
      err%message = err%message // achar(10) // '  ' // files%journal // ' keeps the cases finished so ' // &
                    'far; fix the cause and run again with --resume'
      if (cleanup%failed()) err%message = err%message // achar(10) // '  ' // cleanup%message
    else
      call files%discard(files%partial, work_partial, cleanup, made=.true.)
      call files%discard(files%resumed, work_partial, cleanup, made=.true.)
      call files%discard(files%journal, work_journal, cleanup, made=.true.)
      if (cleanup%failed()) err%message = err%message // achar(10) // '  ' // cleanup%message
    end if
  end subroutine abandon

  !> Keep what is finished: the journal holds every case done so far, and
  !> the partial file shows them; --resume takes it from there.
  subroutine keep_finished(run, files)
    type(run_state_t), intent(inout) :: run
    type(output_files_t), intent(in) :: files
    type(error_t) :: ignored
    call run%out%close(ignored)
    ! a resume that failed while copying: the next one takes back what it holds
    if (allocated(run%out%path)) then
      if (run%out%path == files%resumed .and. .not. any(run%journal%header%in_place)) &
        call files%discard(files%resumed, work_partial, ignored)
    end if
    call run%journal%close(ignored)
  end subroutine keep_finished
end module ellroll_run_campaign
