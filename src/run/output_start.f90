!> How a run begins on the files of its output: checked before anything
!> runs (check_output_target), then, under the output's lock, whether it
!> starts afresh, resumes or has nothing to do (decide_start), and the
!> output file and journal opened for it (open_outputs). A complete output
!> is told by holds_this_run.
module ellroll_output_start
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_output
  use ellroll_strings, only: itoa, text_hash
  use ellroll_status, only: status_pending
  use ellroll_input, only: run_input_t
  use ellroll_hdf5_writer, only: h5_output_t, provenance_t, written_in_place, describe_writer
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_journal, only: journal_t, journal_header_t, journal_is_torn
  use ellroll_resume, only: open_for_resume, copy_journaled_cases, discard_unneeded_partial
  use ellroll_system, only: folder_write_error, folder_of, system_error_text
  use ellroll_files, only: path_kind, kind_regular, kind_missing
  use ellroll_output_files, only: output_files_t, check_replace, work_partial, work_journal, work_target
  use ellroll_shards, only: shard_slots, campaign_id
  implicit none
  private

  public :: check_output_target, decide_start, holds_this_run, open_outputs

contains

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

  !> Whether the run starts afresh or resumes, from the files there and the
  !> options; nothing_to_do for a resume of a complete run. Every file of the
  !> output is ellroll's or absent (else the run is refused, and nothing is
  !> touched). A journal beside a complete output of this campaign, with no
  !> work file (.partial, .partial.new) beside it, is left from a run killed
  !> between moving its file into place and removing the journal: it goes.
  !> Where a work file is there, the journal's run never moved its file into
  !> place (an --overwrite of a complete output of the same campaign,
  !> interrupted): it resumes. A journal killed before its header was
  !> complete holds nothing finished, and the run starts afresh.
  subroutine decide_start(inp, shard, resume_asked, overwrite, files, resume, nothing_to_do, err)
    type(run_input_t), intent(in) :: inp
    integer, intent(in) :: shard(2)
    logical, intent(in) :: resume_asked, overwrite     !< --resume, --overwrite
    type(output_files_t), intent(in) :: files
    logical, intent(out) :: resume, nothing_to_do
    type(error_t), intent(inout) :: err
    logical :: journal_exists, target_exists, target_complete, target_ours, work_exists
    nothing_to_do = .false.
    resume = resume_asked
    call files%check(files%target, work_target, err)
    call files%check(files%partial, work_partial, err)
    call files%check(files%resumed, work_partial, err)
    call files%check(files%journal, work_journal, err)
    if (err%failed()) return
    target_exists = path_kind(files%target) == kind_regular
    journal_exists = path_kind(files%journal) == kind_regular
    target_complete = .false.
    target_ours = .false.
    if (target_exists) target_complete = holds_this_run(files%target, inp, shard, err, target_ours)
    if (err%failed()) return
    ! (the run that wrote the output moved its work file onto it: a work file
    ! there belongs to a run that has not finished; a resume of a journal
    ! alone makes .partial.new before it removes .partial)
    work_exists = path_kind(files%partial) /= kind_missing
    if (.not. work_exists) work_exists = path_kind(files%resumed) /= kind_missing
    if (journal_exists .and. target_complete .and. .not. work_exists) then
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
    else if (.not. resume .and. .not. overwrite) then
      if (journal_exists) then
        call set_error(err, err_output, files%target // ': an interrupted run of this output exists (' // &
            files%journal // '); pass --resume to finish it, or --overwrite to start over')
      else if (target_exists) then
        call set_error(err, err_output, files%target // ': output file exists; pass --overwrite to replace it')
      end if
    end if
    ! a resume replaces only an output of its own campaign (an --overwrite
    ! stopped half way, of any shard): another input's is somebody's result
    if (resume .and. journal_exists .and. target_exists .and. .not. (target_ours .or. err%failed())) &
      call set_error(err, err_output, files%target // ': holds the output of another input, which a resume ' // &
          'never replaces; move it away, then resume')
    ! the finished file goes over the output at the end: refused now where
    ! it could not (a sticky folder, another user's file), not after the run
    if (target_exists .and. .not. nothing_to_do) call check_replace(files%target, err)
    if (err%failed() .or. nothing_to_do .or. resume) return
    ! afresh: what an earlier run left goes (the output itself stays until the new one replaces it)
    call files%discard(files%resumed, work_partial, err)
    call files%discard(files%partial, work_partial, err)
    call files%discard(files%journal, work_journal, err)
  end subroutine decide_start

  !> Whether the output at path is complete and of this campaign and shard.
  !> A file that cannot be read (a read error) is no answer: with `err`,
  !> that is an error (exit 3).
  logical function holds_this_run(path, inp, shard, err, campaign) result(holds)
    character(len=*), intent(in) :: path
    type(run_input_t), intent(in) :: inp
    integer, intent(in) :: shard(2)
    type(error_t), intent(inout), optional :: err
    logical, intent(out), optional :: campaign     !< whether it is of this campaign, any shard, complete or not
    type(h5_input_t) :: existing
    type(error_t) :: unreadable
    character(len=:), allocatable :: id, spec
    integer(i8), allocatable :: status(:)
    logical :: read_error
    holds = .false.
    if (present(campaign)) campaign = .false.
    call existing%open(path, unreadable)
    if (.not. unreadable%failed()) then
      call existing%text_attribute('campaign_id', id)
      call existing%text_attribute('shard', spec)
      allocate (status, source=existing%int_column('summary/status', unreadable))
      read_error = existing%read_failed(unreadable)     ! (unreadable then says why)
      call existing%close()
      holds = .not. unreadable%failed() .and. id == campaign_id(inp) .and. &
              spec == itoa(shard(1)) // '/' // itoa(shard(2)) .and. .not. any(status == status_pending)
      if (present(campaign)) campaign = .not. unreadable%failed() .and. id == campaign_id(inp)
    end if
    if (present(err) .and. unreadable%code == err_output) err = unreadable
  end function holds_this_run

  !> Create the output file and the journal, or on a resume the file into
  !> which the journaled cases go (they are then done). done: a slot per
  !> case of the shard, allocated once the file is made.
  subroutine open_outputs(inp, shard, prov_in, files, resume, out, journal, done, err)
    type(run_input_t), intent(in) :: inp
    integer, intent(in) :: shard(2)
    type(provenance_t), intent(in) :: prov_in
    type(output_files_t), intent(inout) :: files
    logical, intent(in) :: resume
    type(h5_output_t), intent(inout) :: out
    type(journal_t), intent(inout) :: journal
    logical, allocatable, intent(out) :: done(:)
    type(error_t), intent(inout) :: err
    integer(i8), allocatable :: globals(:), journal_places(:)
    real(wp), allocatable :: times(:)
    type(journal_header_t) :: header
    type(provenance_t) :: prov
    character(len=:), allocatable :: writing, writer
    integer(i8) :: n_slots
    allocate (globals, source=shard_slots(inp%campaign%n_cases(), shard))
    n_slots = size(globals, kind=i8)
    prov = prov_in
    prov%campaign_id = campaign_id(inp)
    prov%input_files = inp%input_files
    prov%n_cases_total = inp%campaign%n_cases()
    prov%shard = itoa(shard(1)) // '/' // itoa(shard(2))
    header = journal_header_t(campaign_id=campaign_id(inp) // text_hash(inp%canonical), &
                              n_slots=n_slots, n_samples=inp%plan%n_samples, shard=shard, &
                              fields=inp%plan%fields, in_place=written_in_place(inp%plan%fields, inp%plan%compression))
    ! (assigned apart: gfortran 12 copies a deferred-length component of a
    ! structure constructor into a buffer of one byte)
    header%input_files = inp%input_files
    if (allocated(prov_in%build)) then
      call describe_writer(prov_in%version, prov_in%build, writer)
    else
      call describe_writer(prov_in%version, '', writer)
    end if
    header%writer = writer
    if (resume) then
      call open_for_resume(journal, files, header, journal_places, err)
      if (err%failed()) return
      call files%note_journal()
    end if
    times = inp%plan%times()
    writing = files%partial
    if (resume) writing = files%resumed      ! moved over partial once the journaled cases are in it
    files%laying_out = .true.
    call out%create(writing, globals, times, inp%plan%fields, inp%campaign%base, prov, &
                    inp%campaign%coordinates(globals), err, inp%plan%compression)
    deallocate (globals)          ! from here on, memory does not grow with the case count
    if (err%failed()) return          ! (the run, abandoned, closes the file and removes it)
    call files%note_written(out%identity)
    allocate (done(0:n_slots - 1))
    done = .false.
    if (resume) then
      call discard_unneeded_partial(files, header, err)
      if (err%failed()) return
      call copy_journaled_cases(journal, journal_places, inp%campaign, shard, files, out, done, err)
    else
      call journal%create(files%journal, header, err)
      if (.not. err%failed()) call files%note_journal()
    end if
  end subroutine open_outputs
end module ellroll_output_start
