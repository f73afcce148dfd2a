!> Resuming an interrupted run from its journal, in no more room than the
!> final file and the journal take.
!>
!> The killed run's file (OUT.partial) holds the trajectories of its
!> journaled cases in place; the rest of it (HDF5's metadata and tables) is
!> rebuilt from the journal, and its storage is freed first. A resume
!> copies the journaled cases, in slot order, into a new file
!> (OUT.partial.new) and frees the old file's storage behind the copy,
!> piece by piece, where the file system can (Linux: ext4, XFS, Btrfs,
!> tmpfs, ...); then the new file goes over the old one.
!> A resume killed while copying leaves cases whose trajectories are only in
!> the new file: the next resume first copies those back, freeing the new
!> file's storage behind in the same way. At every moment each journaled
!> case's trajectories are in one of the two files, checked against the
!> fingerprint in its record; a case found in neither runs again.
module ellroll_resume
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_kinds, only: i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa
  use ellroll_campaign, only: campaign_t
  use ellroll_results, only: case_result_t
  use ellroll_hdf5_writer, only: h5_output_t
  use ellroll_trajectory_store, only: trajectory_store_t
  use ellroll_journal, only: journal_t, journal_header_t
  use ellroll_files, only: path_kind, kind_regular
  use ellroll_output_files, only: output_files_t, work_partial
  implicit none
  private

  public :: open_for_resume, copy_journaled_cases, discard_unneeded_partial

contains

  !> Open the journal of the interrupted run and find its records (places:
  !> where each slot's record lies, -1 for none). The killed run's file
  !> keeps only its trajectories, and takes back the cases that a resume
  !> killed while copying left in `resumed`; a file with nothing in place
  !> (the records hold the trajectories whole) is not needed at all, and goes
  !> once the resume's file is made (discard_unneeded_partial): till then it
  !> marks the journal as that of an unfinished run (decide_start).
  subroutine open_for_resume(journal, files, header, places, err)
    type(journal_t), intent(inout) :: journal
    type(output_files_t), intent(in) :: files
    type(journal_header_t), intent(in) :: header
    integer(i8), allocatable, intent(out) :: places(:)
    type(error_t), intent(inout) :: err
    type(trajectory_store_t) :: killed_run, copied
    type(error_t) :: unreadable
    call journal%open_existing(files%journal, header, err)
    if (err%failed()) return
    allocate (places(0:header%n_slots - 1))
    call journal%index_records(places)
    if (journal%n_damaged > 0) write (error_unit, '(a)') 'ellroll: warning: ' // files%journal // ': ' // &
        itoa(journal%n_damaged) // ' damaged records skipped (their checksum does not match); ' // &
        itoa(count(places < 0)) // ' of ' // itoa(size(places)) // ' cases have no valid record and run'
    if (any(header%in_place)) then
      call open_trajectories(files%partial, header, killed_run, unreadable)
      if (path_kind(files%resumed) == kind_regular .and. .not. unreadable%failed()) then
        call open_trajectories(files%resumed, header, copied, unreadable)
        if (.not. unreadable%failed()) call take_back_copied_cases(journal, places, copied, killed_run, err)
        call copied%close(unreadable)
      end if
      call killed_run%close(unreadable)
      ! unreadable: the cases not found in partial run again (copy_journaled_cases)
    end if
    ! a take-back the disk had no room for stops here: the cases left in
    ! `resumed` are taken back by the next resume, with more room
    call files%discard(files%resumed, work_partial, err)
  end subroutine open_for_resume

  !> The killed run's file, where nothing is in place: once the resume's
  !> file is made, it is not needed.
  subroutine discard_unneeded_partial(files, header, err)
    type(output_files_t), intent(in) :: files
    type(journal_header_t), intent(in) :: header
    type(error_t), intent(inout) :: err
    if (.not. any(header%in_place)) call files%discard(files%partial, work_partial, err)
  end subroutine discard_unneeded_partial

  !> A file's trajectories, open to be moved out of it; the storage of the
  !> rest of it (HDF5's metadata and tables, rebuilt from the journal) is
  !> freed at once.
  subroutine open_trajectories(path, header, store, err)
    character(len=*), intent(in) :: path
    type(journal_header_t), intent(in) :: header
    type(trajectory_store_t), intent(inout) :: store
    type(error_t), intent(inout) :: err
    call store%open_existing(path, header%n_slots, header%n_samples, header%in_place, .true., err)
    if (.not. err%failed()) call store%release_all_but_trajectories()
  end subroutine open_trajectories

  !> The cases that a killed copy had moved to `copied`, back into
  !> `killed_run`: those it moved whole, and the one it was moving, put
  !> together from its first pieces there and the others left behind (or,
  !> where a take-back was cut short, from its first pieces back here and
  !> the others still there). err: a move the disk had no room for (the
  !> cases stay where they are, for the next resume).
  subroutine take_back_copied_cases(journal, places, copied, killed_run, err)
    type(journal_t), intent(in) :: journal
    integer(i8), intent(in) :: places(0:)
    type(trajectory_store_t), intent(inout) :: copied, killed_run
    type(error_t), intent(inout) :: err
    type(error_t) :: read_err
    type(case_result_t) :: res, moved, left, back
    integer(i8) :: slot, in_place, k
    logical :: found
    do slot = 0, size(places, kind=i8) - 1
      if (err%failed()) exit
      if (places(slot) < 0) cycle
      call journal%record_at(places(slot), res, in_place, found)
      if (.not. found) cycle
      ! (a case that cannot be read in either file is left to run again; it
      ! does not stop the others from being taken back)
      read_err = error_t()
      call killed_run%get(slot, res, read_err)
      if (.not. read_err%failed() .and. journal%fingerprint(res) == in_place) cycle       ! never moved
      read_err = error_t()
      call copied%get(slot, moved, read_err)
      if (read_err%failed()) cycle
      left = res
      back = moved
      do k = 1, copied%n_pieces()
        call copied%take_piece(res, moved, k)        ! its first k pieces from `copied`
        call copied%take_piece(back, left, k)        ! its first k pieces from here
        if (journal%fingerprint(res) == in_place) then
          call killed_run%move_in(slot, res, copied, err)
          exit
        else if (journal%fingerprint(back) == in_place) then
          call killed_run%move_in(slot, back, copied, err)
          exit
        end if
      end do
    end do
  end subroutine take_back_copied_cases

  !> Copy the journaled cases into `out`, their trajectories moved from
  !> `partial` (open_for_resume kept only them there, so nothing else is
  !> freed here), then move `out` over it. A case whose trajectories are missing there or fail their check
  !> (the system lost writes) runs again, with a warning.
  subroutine copy_journaled_cases(journal, places, campaign, shard, files, out, done, err)
    type(journal_t), intent(in) :: journal
    integer(i8), intent(in) :: places(0:)
    type(campaign_t), intent(in) :: campaign
    integer, intent(in) :: shard(2)              !< this run's cases: shard(1), shard(1) + shard(2), ...
    type(output_files_t), intent(in) :: files
    type(h5_output_t), intent(inout) :: out
    logical, intent(inout) :: done(0:)
    type(error_t), intent(inout) :: err
    type(trajectory_store_t) :: killed_run
    type(error_t) :: unreadable, read_err
    type(case_result_t) :: res
    integer(i8) :: slot, in_place, n_lost
    logical :: found, in_place_fields
    in_place_fields = any(journal%header%in_place)
    if (in_place_fields) call killed_run%open_existing(files%partial, journal%header%n_slots, &
                                                       journal%header%n_samples, journal%header%in_place, .true., &
                                                       unreadable)
    n_lost = 0
    do slot = 0, size(places, kind=i8) - 1
      if (err%failed()) exit
      if (places(slot) < 0) cycle
      call journal%record_at(places(slot), res, in_place, found)
      if (.not. found) cycle
      if (in_place_fields) then
        if (.not. unreadable%failed()) call killed_run%get(slot, res, read_err)
        if (unreadable%failed() .or. read_err%failed() .or. journal%fingerprint(res) /= in_place) then
          n_lost = n_lost + 1
          read_err = error_t()
          cycle
        end if
      end if
      call out%write_case(slot, campaign%case_at(shard(1) + slot * shard(2)), res, err, moved_from=killed_run)
      if (err%failed()) exit
      done(slot) = .true.
    end do
    call killed_run%close(read_err)
    if (n_lost > 0) then
      if (.not. unreadable%failed()) unreadable%message = files%partial // ': their trajectories there are damaged'
      write (error_unit, '(a)') 'ellroll: warning: ' // itoa(n_lost) // ' finished cases run again: ' // &
          unreadable%message
    end if
    if (.not. err%failed()) call files%check(files%partial, work_partial, err)
    if (.not. err%failed()) call out%move_to(files%partial, err)
  end subroutine copy_journaled_cases
end module ellroll_resume
