!> Merging the shard files of a campaign into one file equal to a
!> single-process run: the shards must belong to the same campaign, be
!> complete, and cover every case exactly once. Each case read from a
!> shard must match its checksum there (/summary/checksum, of everything
!> the shard stores of the case: ellroll_case_checksum) before it is
!> written: a damaged shard is refused, and no output is left.
module ellroll_merge
  use, intrinsic :: iso_c_binding, only: c_long
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input, err_output, err_interrupted
  use ellroll_system, only: catch_stop_signals, stop_signal, signal_name, open_files_room
  use ellroll_strings, only: itoa, excerpt
  use ellroll_status, only: status_pending
  use ellroll_input, only: run_input_t, read_input_text
  use ellroll_results, only: case_result_t, add_switch
  use ellroll_hdf5_writer, only: h5_output_t, provenance_t, describe_writer
  use ellroll_case_checksum, only: case_checksum
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_suite_input, only: changed_files
  use ellroll_shards, only: shard_slots, campaign_id
  use ellroll_files, only: same_file, path_kind, kind_missing, output_name_problem
  use ellroll_output_files, only: output_files_t, check_replace, work_partial, work_target
  use ellroll_hdf5_common, only: system_failure
  implicit none
  private

  public :: merge_shards

  !> Open files a merge needs beside its shards: the output, its work file
  !> and lock, the standard streams, HDF5's and the libraries' own.
  integer, parameter :: spare_files = 64

contains

  !> Merge the shards into target: under the output's lock, into its
  !> partial file, moved into place when complete. An existing target is
  !> replaced only with `overwrite`, and only if it is an ellroll output
  !> (never a shard being merged, an input or any other file).
  !> `locked`: the caller holds the output's lock (MPI's rank 0) and keeps it.
  subroutine merge_shards(target, shard_paths, overwrite, prov_in, err, locked)
    character(len=*), intent(in) :: target
    character(len=*), intent(in) :: shard_paths(:)
    logical, intent(in) :: overwrite
    type(provenance_t), intent(in) :: prov_in
    type(error_t), intent(inout) :: err
    type(output_files_t), intent(in), optional :: locked
    type(output_files_t) :: files
    type(error_t) :: cleanup
    character(len=:), allocatable :: reason
    integer :: k
    call output_name_problem(target, reason)
    if (len(reason) > 0) then
      call set_error(err, err_input, 'merge: output ' // excerpt(target) // ': ' // reason)
      return
    end if
    call files%name(target, '')
    do k = 1, size(shard_paths)
      if (target == trim(shard_paths(k))) then
        call set_error(err, err_input, target // ': is also given as a shard to merge; choose another output')
        return
      end if
      if (same_file(target, trim(shard_paths(k)))) then
        call set_error(err, err_input, target // ': is also given as a shard to merge; choose another output')
        return
      end if
    end do
    if (.not. present(locked)) then
      ! SIGTERM and SIGINT stop the merge between cases: its work file and lock go
      call catch_stop_signals()
      call files%acquire(err)
    end if
    call files%check(files%target, work_target, err)
    if (.not. (err%failed() .or. overwrite)) then
      if (path_kind(files%target) /= kind_missing) &
        call set_error(err, err_output, target // ': output file exists; pass --overwrite to replace it')
    end if
    if (path_kind(files%target) /= kind_missing) call check_replace(files%target, err)
    call files%note_target()
    call files%discard(files%partial, work_partial, err)
    if (.not. err%failed()) then
      call merge_into(files, shard_paths, prov_in, err)
      if (err%code == err_input) call read_error_instead(err)
      if (.not. err%failed()) call files%commit(files%partial, err)
      ! a merge has no journal to resume from: its work file goes on any
      ! failure (cleanup apart from err, which says why the merge failed)
      if (err%failed()) call files%discard(files%partial, work_partial, cleanup, made=.true.)
    end if
    if (.not. present(locked)) call files%release(err)
  end subroutine merge_shards

  !> A shard that could not be read (a read error: EIO) is no verdict on
  !> what it holds: where a system call of HDF5's failed during the merge,
  !> err says that, not what the shard seemed to hold.
  subroutine read_error_instead(err)
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: words, file
    if (.not. system_failure(words, file)) return
    if (len(file) == 0) file = 'a shard'
    call set_error(err, err_output, file // ': cannot read it: ' // words)
  end subroutine read_error_instead

  !> The shards merged into files%partial: every shard opened, merged, and closed
  !> again whatever failed.
  subroutine merge_into(files, shard_paths, prov_in, err)
    type(output_files_t), intent(inout) :: files
    character(len=*), intent(in) :: shard_paths(:)
    type(provenance_t), intent(in) :: prov_in
    type(error_t), intent(inout) :: err
    type(h5_input_t), allocatable :: shards(:)
    integer :: k
    integer(c_long) :: room
    room = open_files_room(int(size(shard_paths), c_long) + spare_files)
    if (room >= 0 .and. room < size(shard_paths) + spare_files) then
      call set_error(err, err_output, itoa(size(shard_paths)) // ' shards: a merge holds every shard open and ' // &
          'needs about ' // itoa(size(shard_paths) + spare_files) // ' open files, where this process may open ' // &
          itoa(int(room)) // ' (the hard limit, ulimit -Hn): raise it')
      return
    end if
    allocate (shards(size(shard_paths)))
    do k = 1, size(shard_paths)
      call shards(k)%open(trim(shard_paths(k)), err)
      ! a killed run's work file given as a shard is bad input, as a damaged shard is
      if (shards(k)%unfinished) err%code = err_input
      if (err%failed()) exit
    end do
    if (.not. err%failed()) call merge_opened(shards, files, shard_paths, prov_in, err)
    do k = 1, size(shards)
      call shards(k)%close()
    end do
  end subroutine merge_into

  subroutine merge_opened(shards, files, shard_paths, prov_in, err)
    type(h5_input_t), intent(in) :: shards(:)
    type(output_files_t), intent(inout) :: files
    character(len=*), intent(in) :: shard_paths(:)
    type(provenance_t), intent(in) :: prov_in
    type(error_t), intent(inout) :: err
    integer, allocatable :: shard_of(:)           ! shard file for each shard index
    integer :: k, index, count, n_shards
    character(len=:), allocatable :: id, spec, other_id, stored_file, stored_namelist
    type(run_input_t) :: inp
    type(h5_output_t) :: out
    type(provenance_t) :: prov
    integer(i8), allocatable :: slots(:), statuses(:), all_cases(:)
    integer(i8) :: i

    call shards(1)%text_attribute('campaign_id', id)
    call shards(1)%text_attribute('shard', spec)
    n_shards = shard_count(spec)
    if (n_shards < 1) then
      call set_error(err, err_input, trim(shard_paths(1)) // ': not a shard file (shard = ''' // spec // ''')')
      return
    end if
    allocate (shard_of(0:n_shards - 1))
    shard_of = 0
    do k = 1, size(shards)
      call shards(k)%text_attribute('shard', spec)
      call shards(k)%text_attribute('campaign_id', other_id)
      if (other_id /= id) then
        call explain_other_campaign(shards(1), shards(k), trim(shard_paths(1)), trim(shard_paths(k)), err)
        return
      end if
      if (shard_count(spec) /= n_shards) then
        call set_error(err, err_input, trim(shard_paths(k)) // ': shard ' // spec // ' is of a split into ' // &
            itoa(shard_count(spec)) // ', not ' // itoa(n_shards))
        return
      end if
      index = shard_index(spec)
      if (shard_of(index) /= 0) then
        call set_error(err, err_input, trim(shard_paths(k)) // ': shard ' // spec // ' given twice (also ' // &
                       trim(shard_paths(shard_of(index))) // ')')
        return
      end if
      shard_of(index) = k
      call check_writer(shards(k), trim(shard_paths(k)), prov_in, err)
      if (err%failed()) return
      statuses = shards(k)%int_column('summary/status', err)
      if (err%failed()) return
      count = int(count_pending(statuses))
      if (count > 0) then
        call set_error(err, err_input, trim(shard_paths(k)) // ': ' // itoa(count) // &
            ' cases were never run (an unfinished shard); finish it with --resume first')
        return
      end if
    end do
    if (any(shard_of == 0)) then
      call missing_text(shard_of, spec)
      call set_error(err, err_input, spec)
      return
    end if

    call shards(1)%text_attribute('input_file', prov%input_file)
    call shards(1)%text_attribute('input_namelist', prov%input_namelist)
    call read_input_text(prov%input_file, prov%input_namelist, files%partial, inp, err)
    if (err%failed()) then
      ! (the files it names are read again, from where its path leads from here)
      err%message = 'merge reads again the input ' // trim(shard_paths(1)) // ' stores, with its files, from ' // &
          'this folder: ' // err%message // '; run the merge from the folder the shards ran in (where ' // &
          prov%input_file // ' is)'
      return
    end if
    if (campaign_id(inp) /= id) then
      call set_error(err, err_input, trim(shard_paths(1)) // ': the input it stores, read again from this ' // &
          'folder with its files, is not the campaign it ran (a file it reads, such as a record, differs from the ' // &
          "one the shards read): run the merge from the folder the shards ran in, with the files they read")
      return
    end if

    call move_alloc(prov%input_file, stored_file)
    call move_alloc(prov%input_namelist, stored_namelist)
    prov = prov_in
    call move_alloc(stored_file, prov%input_file)
    call move_alloc(stored_namelist, prov%input_namelist)
    prov%campaign_id = id
    call shards(1)%text_attribute('input_files', prov%input_files)
    prov%n_cases_total = inp%campaign%n_cases()
    prov%shard = '0/1'
    all_cases = [(i, i = 0, inp%campaign%n_cases() - 1)]
    call out%create(files%partial, all_cases, inp%plan%times(), inp%plan%fields, inp%campaign%base, &
                    prov, inp%campaign%coordinates(all_cases), err, inp%plan%compression)
    if (.not. err%failed()) call files%note_written(out%identity)
    do index = 0, n_shards - 1
      if (err%failed()) exit
      slots = shard_slots(inp%campaign%n_cases(), [index, n_shards])
      call copy_shard(shards(shard_of(index)), trim(shard_paths(shard_of(index))), index, slots, inp, out, err)
    end do
    call out%close(err)
  end subroutine merge_opened

  !> Copy the cases of shard `index` (its file at `path`) into `out`, each
  !> checked against its checksum there first.
  subroutine copy_shard(shard, path, index, slots, inp, out, err)
    type(h5_input_t), intent(in) :: shard
    character(len=*), intent(in) :: path
    integer, intent(in) :: index
    integer(i8), intent(in) :: slots(:)           !< the global index of each of its cases
    type(run_input_t), intent(in) :: inp
    type(h5_output_t), intent(inout) :: out
    type(error_t), intent(inout) :: err
    type(case_result_t) :: res
    integer(i8), allocatable :: sw_first(:), sw_count(:), sw_kind(:), sums(:), statuses(:)
    real(wp), allocatable :: sw_time(:)
    integer(i8) :: slot, i
    logical :: per_case
    if (size(slots, kind=i8) /= shard%n_cases) then
      call set_error(err, err_input, path // ': holds ' // itoa(shard%n_cases) // ' cases; shard ' // itoa(index) // &
                     ' should hold ' // itoa(size(slots)))
      return
    end if
    if (inp%campaign%base%slide) then
      call shard_switches(shard, sw_first, sw_count, sw_time, sw_kind, err)
      if (err%failed()) return
    else                                          ! (no switches: none per case)
      allocate (sw_first(size(slots)), sw_count(size(slots)), sw_time(0), sw_kind(0))
      sw_first = 0
      sw_count = 0
    end if
    allocate (sums, source=shard%int_column('summary/checksum', err))
    allocate (statuses, source=shard%int_column('summary/status', err))
    if (err%failed()) return
    per_case = size(sums) == size(slots) .and. size(statuses) == size(slots) .and. size(sw_first) == size(slots)
    if (.not. per_case) then
      call set_error(err, err_input, path // ': its /summary/status, /summary/checksum or /switches does not ' // &
                     'hold a value per case')
      return
    end if
    do slot = 0, size(slots, kind=i8) - 1
      if (stop_signal() /= 0) then
        call set_error(err, err_interrupted + stop_signal(), 'merge interrupted by ' // signal_name(stop_signal()))
        return
      end if
      call shard%read_case_result(slot, inp%plan%n_samples, res, err)
      if (err%failed()) return
      do i = sw_first(slot + 1) + 1, sw_first(slot + 1) + sw_count(slot + 1)
        call add_switch(res, sw_time(i), int(sw_kind(i)))
      end do
      ! (the status as stored, all 64 bits: res holds it as a default integer)
      if (case_checksum(res, inp%plan%fields, inp%plan%n_samples) /= sums(slot + 1) .or. &
          int(res%status, i8) /= statuses(slot + 1)) then
        call set_error(err, err_input, path // ': case ' // itoa(slots(slot + 1)) // ' is damaged (what the ' // &
            'file holds of it does not match its checksum, /summary/checksum); run this shard again')
        return
      end if
      call out%write_case(slots(slot + 1), inp%campaign%case_at(slots(slot + 1)), res, err)
      if (err%failed()) return
    end do
  end subroutine copy_shard

  !> A shard written by another program than this one (another version or
  !> build: their results differ in the last bits) is refused: the merged
  !> file would mix them under one version.
  subroutine check_writer(shard, path, prov_in, err)
    type(h5_input_t), intent(in) :: shard
    character(len=*), intent(in) :: path
    type(provenance_t), intent(in) :: prov_in
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: version, build, found, this
    call shard%text_attribute('version', version)
    call shard%text_attribute('build', build)
    call describe_writer(version, build, found)
    if (allocated(prov_in%build)) then
      call describe_writer(prov_in%version, prov_in%build, this)
    else
      call describe_writer(prov_in%version, '', this)
    end if
    if (found /= this) call set_error(err, err_input, path // ': written by ' // found // '; this is ' // this // &
        ', and a merge would mix the results of two programs: merge the shards with the ellroll that wrote ' // &
        'them, or run this shard again with this one')
  end subroutine check_writer

  !> A shard's /switches: each case's first switch (0-based) and count, and
  !> every switch's time and kind.
  subroutine shard_switches(shard, first, count, times, kinds, err)
    type(h5_input_t), intent(in) :: shard
    integer(i8), allocatable, intent(out) :: first(:), count(:), kinds(:)
    real(wp), allocatable, intent(out) :: times(:)
    type(error_t), intent(inout) :: err
    first = shard%int_column('switches/first', err)
    count = shard%int_column('switches/count', err)
    if (err%failed()) return
    if (shard%dataset_length('switches/switch_time') > 0) then
      times = shard%real_column('switches/switch_time', err)
      kinds = shard%int_column('switches/switch_kind', err)
    else
      allocate (times(0), kinds(0))
    end if
    if (size(first) /= size(count) .or. size(times) /= size(kinds) .or. &
        any(count > 0 .and. (first < 0 .or. first + count > size(times)))) then
      if (.not. err%failed()) call set_error(err, err_input, shard%path // ': /switches does not index its switches')
    end if
  end subroutine shard_switches

  !> Two shards of other campaigns: their inputs differ, or (the input the
  !> same) a file it reads differed when they ran.
  subroutine explain_other_campaign(first, other, first_path, other_path, err)
    type(h5_input_t), intent(in) :: first, other
    character(len=*), intent(in) :: first_path, other_path
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: text_1, text_2, files_1, files_2, names
    call first%text_attribute('input_namelist', text_1)
    call other%text_attribute('input_namelist', text_2)
    call first%text_attribute('input_files', files_1)
    call other%text_attribute('input_files', files_2)
    if (text_1 /= text_2 .or. files_1 == files_2) then
      call set_error(err, err_input, other_path // ': belongs to another campaign than ' // first_path)
      return
    end if
    call changed_files(files_1, files_2, names)
    call set_error(err, err_input, other_path // ': ran with other contents of ' // names // ' than ' // &
                   first_path // '; run every shard with the same files')
  end subroutine explain_other_campaign

  integer function shard_index(spec)
    character(len=*), intent(in) :: spec
    integer :: ios
    read (spec(:max(1, index(spec, '/') - 1)), *, iostat=ios) shard_index
    if (ios /= 0) shard_index = -1
  end function shard_index

  integer function shard_count(spec)
    character(len=*), intent(in) :: spec
    integer :: ios
    shard_count = -1
    if (index(spec, '/') == 0) return
    read (spec(index(spec, '/') + 1:), *, iostat=ios) shard_count
    if (ios /= 0) shard_count = -1
  end function shard_count

  pure integer(i8) function count_pending(statuses)
    integer(i8), intent(in) :: statuses(:)
    count_pending = count(statuses == status_pending)
  end function count_pending

  !> 'missing shard 0/3 (given: 1/3, 2/3): run it with --shard 0/3 -o FILE
  !> (a file of its own) and merge again', from the shard file given for
  !> each shard index (0: none).
  pure subroutine missing_text(shard_of, text)
    integer, intent(in) :: shard_of(0:)
    character(len=:), allocatable, intent(out) :: text
    character(len=:), allocatable :: missing, given, options
    integer :: k, n
    missing = ''
    given = ''
    options = ''
    n = size(shard_of)
    do k = 0, n - 1
      if (shard_of(k) == 0) then
        missing = missing // ', ' // itoa(k) // '/' // itoa(n)
        options = options // ', --shard ' // itoa(k) // '/' // itoa(n) // ' -o FILE'
      else
        given = given // ', ' // itoa(k) // '/' // itoa(n)
      end if
    end do
    if (count(shard_of == 0) == 1) then
      text = 'missing shard ' // missing(3:) // ' (given: ' // given(3:) // '): run it with' // options(2:) // &
          ' (a file of its own) and merge again'
    else
      text = 'missing shards ' // missing(3:) // ' (given: ' // given(3:) // '): run them with' // options(2:) // &
          ' (each a file of its own) and merge again'
    end if
  end subroutine missing_text
end module ellroll_merge
