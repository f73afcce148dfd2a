!> Running a campaign (or one shard of it) into one HDF5 file: OpenMP over
!> cases with dynamic scheduling, a single writer of the table rows (HDF5's
!> Fortran API is not thread-safe) while each thread writes its cases'
!> trajectories and journal records in place, a journal that makes an
!> interruption lose nothing, resume, and the decisions about existing outputs.
!>
!> Files, for output OUT: OUT.partial (the HDF5 file being written, moved to
!> OUT when complete) and OUT.journal (every finished case, the durable
!> record; deleted when OUT is in place). A resume builds OUT.partial.new
!> from the journal and the killed run's OUT.partial, which holds the
!> journaled cases' trajectories, and moves it over OUT.partial
!> (ellroll_resume).
module ellroll_run_campaign
  !$ use omp_lib, only: omp_get_max_threads
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input, err_output, err_interrupted
  use ellroll_strings, only: itoa, text_hash, format_real
  use ellroll_status, only: status_invalid, status_pending
  use ellroll_cases, only: case_t, check_case, case_problem, make_ball, adaptive_method, is_multiple
  use ellroll_rolling_ball, only: rolling_ball_t, initial_state
  use ellroll_linear, only: fastest_rate
  use ellroll_integrators, only: integrator_t, new_integrator, stability_limit
  use ellroll_campaign, only: campaign_t, invalid_stop
  use ellroll_results, only: case_result_t
  use ellroll_input, only: run_input_t, describe_invalid
  use ellroll_simulate, only: simulate_case, simulate_batch, batchable, lanes
  use ellroll_hdf5_writer, only: h5_output_t, provenance_t, window_list_t, table_row, written_in_place
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_records, only: named_value_t
  use ellroll_journal, only: journal_t, journal_header_t, journal_is_torn
  use ellroll_resume, only: open_for_resume, copy_journaled_cases
  use ellroll_progress, only: progress_t
  use ellroll_system, only: folder_write_error, folder_of, system_error_text, stop_signal, signal_name
  use ellroll_files, only: path_kind, kind_regular
  use ellroll_output_files, only: output_files_t, work_partial, work_journal, work_target
  use ellroll_run_timings, only: run_timings_t, wall_clock, lock_journal, lock_keep, lock_writer, &
      writes_trajectories, writes_journal
  use ellroll_params, only: p_dt, p_omega_x, p_omega_z, p_x, p_y
  implicit none
  private

  public :: run_options_t, run_campaign, shard_slots, find_invalid_cases, campaign_id, step_size_advice, &
            check_output_target, holds_this_run

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
  !> slots done, progress, timings and the first errors (one from a block,
  !> one from the writer).
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
    procedure :: in_lanes
    procedure :: global_index
    procedure :: record_failure
    procedure :: loop_failed
  end type run_state_t

contains

  !> The id that ties a file, its journal and its shards to one campaign.
  !> (A record file changed gives another id: its fingerprint is part of it.)
  function campaign_id(inp) result(id)
    type(run_input_t), intent(in) :: inp
    character(len=16) :: id
    id = text_hash(inp%canonical // inp%input_files)
  end function campaign_id

  !> Checked before any case runs: files can be created in the output's
  !> folder, and every file of the output (the output itself, its partial
  !> file, journal and resume file) is absent or ellroll's: neither
  !> --overwrite nor a resume ever replaces the input, a link or any other file.
  subroutine check_output_target(path, input, err)
    character(len=*), intent(in) :: path, input
    type(error_t), intent(inout) :: err
    type(output_files_t) :: files
    integer :: code
    code = folder_write_error(folder_of(path))
    if (code /= 0) then
      call set_error(err, err_output, path // ': cannot create files in folder ' // folder_of(path) // ': ' // &
                     system_error_text(code))
      return
    end if
    call files%name(path, input)
    call files%check(files%target, work_target, err)
    call files%check(files%partial, work_partial, err)
    call files%check(files%resumed, work_partial, err)
    call files%check(files%journal, work_journal, err)
  end subroutine check_output_target

  !> Global indices of shard I of N: I, I + N, I + 2N, ... (round robin, so
  !> that every shard gets a fair share of a sweep's cheap and dear cases).
  function shard_slots(n_total, shard) result(indices)
    integer(i8), intent(in) :: n_total
    integer, intent(in) :: shard(2)
    integer(i8), allocatable :: indices(:)
    integer(i8) :: j
    ! floor division: a shard past the last case gets none (truncation gave it one)
    indices = [(int(shard(1), i8) + j * shard(2), j = 0, floor(real(n_total - shard(1) - 1, wp) / shard(2), i8))]
  end function shard_slots

  !> Every invalid case of the campaign, with the message for the first few.
  subroutine find_invalid_cases(inp, invalid, messages)
    type(run_input_t), intent(in) :: inp
    logical, allocatable, intent(out) :: invalid(:)
    character(len=:), allocatable, intent(out) :: messages
    integer(i8) :: i, n_bad
    integer :: param
    character(len=:), allocatable :: reason, description
    type(case_t) :: cs
    allocate (invalid(0:inp%campaign%n_cases() - 1))
    ! every case checked (in parallel: a sweep may hold millions), then the
    ! messages of the first five in case order
    !$omp parallel do schedule(dynamic, 256)
    do i = 0, inp%campaign%n_cases() - 1
      invalid(i) = case_is_invalid(i)
    end do
    !$omp end parallel do
    messages = ''
    n_bad = 0
    do i = 0, inp%campaign%n_cases() - 1
      if (.not. invalid(i)) cycle
      n_bad = n_bad + 1
      if (n_bad > 5) cycle
      cs = inp%campaign%case_at(i)
      call check_case(cs, inp%plan%interval, param, reason)
      call describe_invalid(inp, cs, param, reason, description)
      messages = messages // achar(10) // '  ' // description
    end do
    if (n_bad > 5) messages = messages // achar(10) // '  ... and ' // itoa(n_bad - 5) // ' more'
  contains
    logical function case_is_invalid(index)
      integer(i8), intent(in) :: index
      case_is_invalid = case_problem(inp%campaign%case_at(index), inp%plan%interval) /= 0
    end function case_is_invalid
  end subroutine find_invalid_cases

  !> Warnings (or ''), each line starting 'ellroll: warning:', for the
  !> fixed-step cases whose dt is large against the fastest rate of their
  !> linearised motion at the start (spin and curvature): beyond the method's
  !> stability (dt rate above its limit; such a case ends 'unstable'), listed
  !> case by case, the first few, each with a dt that would do; or coarse
  !> (dt rate > 0.1), counted, the fastest named.
  subroutine step_size_advice(inp, message)
    type(run_input_t), intent(in) :: inp
    character(len=:), allocatable, intent(out) :: message
    real(wp), parameter :: warn_above = 0.1_wp, aim = 0.05_wp
    integer, parameter :: listed = 5
    real(wp) :: worst_rate, limit
    real(wp), allocatable :: rates(:), steps(:)
    integer(i8) :: i, worst, n_coarse, n_unstable
    character(len=:), allocatable :: unstable_cases, cases_of
    class(integrator_t), allocatable :: integrator
    type(error_t) :: err
    message = ''
    if (adaptive_method(inp%campaign%base%method)) return
    call new_integrator(trim(inp%campaign%base%method), integrator, err)
    if (err%failed()) return
    limit = stability_limit(integrator)
    allocate (rates(0:inp%campaign%n_cases() - 1), steps(0:inp%campaign%n_cases() - 1))
    !$omp parallel do schedule(dynamic, 256)
    do i = 0, inp%campaign%n_cases() - 1
      call start_rate(i, rates(i), steps(i))
    end do
    !$omp end parallel do
    n_coarse = 0
    n_unstable = 0
    unstable_cases = ''
    worst_rate = 0
    worst = 0
    do i = 0, inp%campaign%n_cases() - 1
      if (steps(i) * rates(i) > limit) then
        n_unstable = n_unstable + 1
        if (n_unstable <= listed) unstable_cases = unstable_cases // achar(10) // '  case ' // itoa(i) // &
            ': dt = ' // format_real(steps(i)) // ' s, dt * rate = ' // format_real(hundredths(steps(i) * rates(i))) // &
            '; dt <= ' // format_real(nice_step(aim / rates(i), inp%plan%interval)) // ' s would do'
      else if (steps(i) * rates(i) > warn_above) then
        n_coarse = n_coarse + 1
        if (rates(i) > worst_rate) then
          worst_rate = rates(i)
          worst = i
        end if
      end if
    end do
    cases_of = ' of ' // itoa(inp%campaign%n_cases()) // ' cases: '
    if (n_unstable > 0) then
      message = 'ellroll: warning: ' // itoa(n_unstable) // cases_of // 'dt is beyond ' // &
          trim(inp%campaign%base%method) // '''s stability for their spin and curvature (dt * rate > ' // &
          format_real(hundredths(limit)) // ', rate the fastest of the motion at the start); they will end ''unstable'':' // &
          unstable_cases
      if (n_unstable > listed) message = message // achar(10) // '  ... and ' // itoa(n_unstable - listed) // &
          ' more'
    end if
    if (n_coarse == 0) return
    if (len(message) > 0) message = message // achar(10)
    message = message // 'ellroll: warning: ' // itoa(n_coarse) // cases_of // &
        'dt is large for their fastest time scale (case ' // itoa(worst) // ': dt = ' // &
        format_real(steps(worst)) // ' s, 1/rate = ' // format_real(1 / worst_rate) // ' s); suggested dt <= ' // &
        format_real(nice_step(aim / worst_rate, inp%plan%interval)) // ' s, or method = ''dop853'''
  contains
    !> Case `index`'s fastest rate at the start and its step; where a bound on
    !> the rate is within the limit, the bound (the rate is only compared with it).
    subroutine start_rate(index, rate, dt)
      integer(i8), intent(in) :: index
      real(wp), intent(out) :: rate, dt
      type(case_t) :: one
      type(rolling_ball_t) :: ball
      one = inp%campaign%case_at(index)
      ! an invalid case (set aside later, with its message) is never large:
      ! its start may not be a state at all
      rate = 0
      dt = 0
      if (case_problem(one, inp%plan%interval) /= 0) return
      ball = make_ball(one)
      dt = one%param(p_dt)
      rate = fastest_rate(ball, initial_state(ball, one%param(p_x), one%param(p_y), &
          one%param(p_omega_x:p_omega_z)), enough=warn_above / dt)
    end subroutine start_rate

    !> The largest 1, 2 or 5 times a power of ten <= limit that divides interval
    !> (a power below 1 divided by, so that 5e-6 is the double nearest 5e-6).
    real(wp) function nice_step(limit, interval) result(step)
      real(wp), intent(in) :: limit, interval
      real(wp), parameter :: mantissas(3) = [1.0_wp, 2.0_wp, 5.0_wp]
      integer :: k, m, exponent10
      do k = 0, 30
        exponent10 = floor(log10(limit)) - k
        do m = 3, 1, -1
          if (exponent10 < 0) then
            step = mantissas(m) / 10.0_wp**(-exponent10)
          else
            step = mantissas(m) * 10.0_wp**exponent10
          end if
          if (step > limit) cycle
          if (is_multiple(interval, step)) return
        end do
      end do
      step = limit
    end function nice_step

    !> x rounded to two decimals, for a message
    pure real(wp) function hundredths(x)
      real(wp), intent(in) :: x
      hundredths = anint(100 * x) / 100
    end function hundredths
  end subroutine step_size_advice

  subroutine run_campaign(inp, opts, prov_in, err)
    type(run_input_t), intent(in) :: inp
    type(run_options_t), intent(in) :: opts
    type(provenance_t), intent(in) :: prov_in
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: messages
    logical, allocatable :: invalid(:)
    logical :: resume, nothing_to_do
    type(output_files_t) :: files
    type(run_state_t) :: run

    run%timings%started = wall_clock()
    call files%name(inp%plan%file, inp%path)

    ! invalid cases: stop before any work, or skip them
    call find_invalid_cases(inp, invalid, messages)
    run%timings%advice = opts%advice_seconds
    run%timings%checked = wall_clock()
    if (any(invalid) .and. inp%campaign%invalid == invalid_stop) then
      call set_error(err, err_input, itoa(count(invalid)) // ' of ' // itoa(size(invalid)) // &
          ' cases are invalid (set &campaign invalid = ''skip'' to run the others):' // messages)
      return
    end if
    call files%acquire('ellroll run ' // inp%path // trim(merge(' --resume', '         ', opts%resume)), err)
    if (err%failed()) return
    call decide_start(inp, opts, files, resume, nothing_to_do, err)
    if (.not. (err%failed() .or. nothing_to_do)) then
      call open_outputs(inp, opts, prov_in, files, resume, run, err)
      if (.not. err%failed()) call record_invalid(inp, invalid, run, err)
      if (err%failed()) then
        call abandon(run, files, err)
      else
        call run_blocks(inp, opts, run)
        call finish(run, files, opts, err)
      end if
    end if
    call files%release(err)
  end subroutine run_campaign

  !> Whether the run starts afresh or resumes, from the files there and the
  !> options; nothing_to_do for a resume of a complete run. Every file of the
  !> output is ellroll's or absent (else the run is refused, and nothing is
  !> touched). A journal beside a complete output of this campaign is left
  !> from a run killed between moving its file into place and removing the
  !> journal: it goes. A journal killed before its header was complete holds
  !> nothing finished, and the run starts afresh.
  subroutine decide_start(inp, opts, files, resume, nothing_to_do, err)
    type(run_input_t), intent(in) :: inp
    type(run_options_t), intent(in) :: opts
    type(output_files_t), intent(in) :: files
    logical, intent(out) :: resume, nothing_to_do
    type(error_t), intent(inout) :: err
    logical :: journal_exists, target_exists, target_complete
    nothing_to_do = .false.
    resume = opts%resume
    call files%check(files%target, work_target, err)
    call files%check(files%partial, work_partial, err)
    call files%check(files%resumed, work_partial, err)
    call files%check(files%journal, work_journal, err)
    if (err%failed()) return
    target_exists = path_kind(files%target) == kind_regular
    journal_exists = path_kind(files%journal) == kind_regular
    target_complete = .false.
    if (target_exists) target_complete = holds_this_run(files%target, inp, opts%shard)
    if (journal_exists .and. target_complete) then
      write (error_unit, '(a)') 'ellroll: ' // files%target // ': complete; removing the journal of the run ' // &
          'that wrote it (' // files%journal // ')'
      call files%discard(files%journal, work_journal, err)
      call files%discard(files%partial, work_partial, err)
      call files%discard(files%resumed, work_partial, err)
      if (err%failed()) return
      journal_exists = .false.
    end if
    if (journal_exists) then
      if (journal_is_torn(files%journal)) then
        write (error_unit, '(a)') 'ellroll: warning: ' // files%journal // ': the interrupted run finished ' // &
            'no case (killed before the journal''s header was written); starting afresh'
        call files%discard(files%journal, work_journal, err)
        call files%discard(files%partial, work_partial, err)
        call files%discard(files%resumed, work_partial, err)
        if (err%failed()) return
        journal_exists = .false.
        resume = .false.
      end if
    else if (.not. target_exists) then
      resume = .false.          ! nothing begun: a resume is the first run (a requeued job's)
    end if
    if (resume .and. .not. journal_exists) then          ! the output is there
      nothing_to_do = .true.
      if (target_complete) then
        write (error_unit, '(a)') 'ellroll: ' // files%target // ': this run is already complete; nothing to do'
      else
        call set_error(err, err_output, files%target // ': holds the output of another input or shard; ' // &
                       'nothing to resume')
      end if
    else if (.not. resume .and. .not. opts%overwrite) then
      if (journal_exists) then
        call set_error(err, err_output, files%target // ': an interrupted run of this output exists (' // &
            files%journal // '); pass --resume to finish it, or --overwrite to start over')
      else if (target_exists) then
        call set_error(err, err_output, files%target // ': output file exists; pass --overwrite to replace it')
      end if
    end if
    if (err%failed() .or. nothing_to_do .or. resume) return
    ! afresh: what an earlier run left goes (the output itself stays until the new one replaces it)
    call files%discard(files%resumed, work_partial, err)
    call files%discard(files%partial, work_partial, err)
    call files%discard(files%journal, work_journal, err)
  end subroutine decide_start

  !> Whether the output at path is complete and of this campaign and shard.
  logical function holds_this_run(path, inp, shard) result(holds)
    character(len=*), intent(in) :: path
    type(run_input_t), intent(in) :: inp
    integer, intent(in) :: shard(2)
    type(h5_input_t) :: existing
    type(error_t) :: unreadable
    character(len=:), allocatable :: id, spec
    integer(i8), allocatable :: status(:)
    holds = .false.
    call existing%open(path, unreadable)
    if (unreadable%failed()) return
    call existing%text_attribute('campaign_id', id)
    call existing%text_attribute('shard', spec)
    allocate (status, source=existing%int_column('summary/status', unreadable))
    call existing%close()
    holds = .not. unreadable%failed() .and. id == campaign_id(inp) .and. &
            spec == itoa(shard(1)) // '/' // itoa(shard(2)) .and. .not. any(status == status_pending)
  end function holds_this_run

  !> Create the output file and the journal, or on a resume the file into
  !> which the journaled cases go (they are then done).
  subroutine open_outputs(inp, opts, prov_in, files, resume, run, err)
    type(run_input_t), intent(in) :: inp
    type(run_options_t), intent(in) :: opts
    type(provenance_t), intent(in) :: prov_in
    type(output_files_t), intent(in) :: files
    logical, intent(in) :: resume
    type(run_state_t), intent(inout) :: run
    type(error_t), intent(inout) :: err
    integer(i8), allocatable :: globals(:), journal_places(:)
    real(wp), allocatable :: times(:)
    type(journal_header_t) :: header
    type(provenance_t) :: prov
    character(len=:), allocatable :: writing
    integer(i8) :: i
    allocate (globals, source=shard_slots(inp%campaign%n_cases(), opts%shard))
    run%n_slots = size(globals, kind=i8)
    run%shard = opts%shard
    prov = prov_in
    prov%campaign_id = campaign_id(inp)
    prov%input_files = inp%input_files
    prov%n_cases_total = inp%campaign%n_cases()
    prov%shard = itoa(opts%shard(1)) // '/' // itoa(opts%shard(2))
    header = journal_header_t(campaign_id=campaign_id(inp) // text_hash(inp%canonical), &
                              n_slots=run%n_slots, n_samples=inp%plan%n_samples, shard=opts%shard, &
                              fields=inp%plan%fields, in_place=written_in_place(inp%plan%fields, inp%plan%compression))
    ! (assigned apart: gfortran 12 copies a deferred-length component of a
    ! structure constructor into a buffer of one byte)
    header%input_files = inp%input_files
    run%resumed = resume
    if (resume) then
      call open_for_resume(run%journal, files, header, journal_places, err)
      if (err%failed()) return
    end if
    times = [(real(i, wp) * inp%plan%interval, i = 0, inp%plan%n_samples - 1)]
    writing = files%partial
    if (resume) writing = files%resumed      ! moved over partial once the journaled cases are in it
    call run%out%create(writing, globals, times, inp%plan%fields, inp%campaign%base, prov, &
                        inp%campaign%coordinates(globals), err, inp%plan%compression)
    deallocate (globals)          ! from here on, memory does not grow with the case count
    if (err%failed()) return          ! (abandon closes the file and removes it)
    allocate (run%done(0:run%n_slots - 1))
    run%done = .false.
    if (resume) then
      call copy_journaled_cases(run%journal, journal_places, inp%campaign, opts%shard, files, run%out, run%done, err)
    else
      call run%journal%create(files%journal, header, err)
    end if
  end subroutine open_outputs

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
    n_threads = 1
    !$ n_threads = omp_get_max_threads()
    if (opts%threads > 0) n_threads = opts%threads
    call run%progress%start(run%n_slots, count(run%done, kind=i8), opts%quiet)
    ! In a campaign of at least `lanes` batchable cases, blocks of `lanes`
    ! slots whose batchable cases run together across SIMD lanes (the others
    ! one by one): whether cases share lanes depends on the campaign only,
    ! never on threads, shards or resumption, so results stay bitwise the
    ! same. Cases that run one by one may be grouped in any way: blocks of up
    ! to `lanes` of them (the locks and writes taken once per block), fewer
    ! where that gives every thread at least four blocks.
    run%use_batches = inp%campaign%n_cases() >= lanes .and. batchable(inp%campaign%base)
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
    call files%commit(files%partial, err)
    if (err%failed()) return
    run%timings%ended = wall_clock()
    if (opts%timings) call run%timings%report()
  end subroutine finish

  !> Integrate the slots of one block not done yet, write their trajectories
  !> and journal records, then hand their table rows to the writer: each
  !> lock taken once per block.
  subroutine run_block(run, inp, chunk)
    type(run_state_t), intent(inout) :: run
    type(run_input_t), intent(in) :: inp
    integer(i8), intent(in) :: chunk
    type(case_t) :: cases(lanes)
    type(case_result_t) :: results(lanes), batch_results(lanes)
    type(error_t) :: case_err, write_err
    type(window_list_t) :: full
    integer(i8) :: slots(lanes), slot
    integer :: n, n_done, j, in_batch(lanes), n_batch, first, run_start
    logical :: waiting(lanes)
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
    ! one batch per method among the block's batchable cases
    waiting(:n) = [(run%in_lanes(cases(j)), j = 1, n)]
    do while (any(waiting(:n)))
      first = findloc(waiting(:n), .true., dim=1)
      n_batch = 0
      do j = first, n
        if (.not. waiting(j) .or. cases(j)%method /= cases(first)%method) cycle
        n_batch = n_batch + 1
        in_batch(n_batch) = j
        waiting(j) = .false.
      end do
      if (n_batch == n) then           ! the whole block: no copy of the results
        call simulate_batch(cases(:n), inp%plan, results(:n))
      else
        call simulate_batch(cases(in_batch(:n_batch)), inp%plan, batch_results(:n_batch))
        results(in_batch(:n_batch)) = batch_results(:n_batch)
      end if
    end do
    n_done = n
    do j = 1, n
      if (run%in_lanes(cases(j))) cycle
      call simulate_case(cases(j), inp%plan, results(j), case_err)
      if (case_err%failed()) then
        n_done = j - 1
        exit
      end if
    end do
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
    record_size = run%journal%record_words + 1
    allocate (records(record_size * n_done), rows(size(table_row(cases(1), results(1))), n_done))
    do j = 1, n_done
      records((j - 1) * record_size + 1:j * record_size) = run%journal%record(slots(j), results(j))
      rows(:, j) = table_row(cases(j), results(j))
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

  !> A case of a small campaign (the paper's single case, say) runs alone:
  !> a batch costs all its lanes whether they are filled or not.
  pure logical function in_lanes(self, cs)
    class(run_state_t), intent(in) :: self
    type(case_t), intent(in) :: cs
    in_lanes = self%use_batches .and. batchable(cs)
  end function in_lanes

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
    if (kept) then
      err%message = err%message // achar(10) // '  ' // files%journal // ' keeps the cases finished so ' // &
                    'far; fix the cause and run again with --resume'
    else
      call files%discard(files%partial, work_partial, cleanup)
      call files%discard(files%resumed, work_partial, cleanup)
      call files%discard(files%journal, work_journal, cleanup)
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
