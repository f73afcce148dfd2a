!> Merging the shard files of a campaign into one file equal to a
!> single-process run: the shards must belong to the same campaign, be
!> complete, and cover every case exactly once.
module ellroll_merge
  use ellroll_kinds, only: i8
  use ellroll_errors, only: error_t, set_error, err_input, err_output
  use ellroll_strings, only: itoa
  use ellroll_status, only: status_pending
  use ellroll_input, only: run_input_t, read_input_text
  use ellroll_results, only: case_result_t
  use ellroll_hdf5_writer, only: h5_output_t, provenance_t
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_run_campaign, only: shard_slots, campaign_id
  use ellroll_system, only: rename_file, remove_file
  implicit none
  private

  public :: merge_shards

contains

  subroutine merge_shards(target, shard_paths, prov_in, err)
    character(len=*), intent(in) :: target
    character(len=*), intent(in) :: shard_paths(:)
    type(provenance_t), intent(in) :: prov_in
    type(error_t), intent(inout) :: err
    type(h5_input_t), allocatable :: shards(:)
    integer, allocatable :: shard_of(:)           ! shard file for each shard index
    integer :: k, index, count, n_shards
    character(len=:), allocatable :: id, spec
    type(run_input_t) :: inp
    type(h5_output_t) :: out
    type(provenance_t) :: prov
    type(case_result_t) :: res
    integer(i8), allocatable :: slots(:), statuses(:), all_cases(:)
    integer(i8) :: slot, i
    character(len=:), allocatable :: partial

    allocate (shards(size(shard_paths)))
    do k = 1, size(shard_paths)
      call shards(k)%open(trim(shard_paths(k)), err)
      if (err%failed()) return
    end do
    id = shards(1)%text_attribute('campaign_id')
    spec = shards(1)%text_attribute('shard')
    n_shards = shard_count(spec)
    if (n_shards < 1) then
      call set_error(err, err_input, trim(shard_paths(1)) // ': not a shard file (shard = ''' // spec // ''')')
      return
    end if
    allocate (shard_of(0:n_shards - 1))
    shard_of = 0
    do k = 1, size(shards)
      spec = shards(k)%text_attribute('shard')
      if (shards(k)%text_attribute('campaign_id') /= id) then
        call set_error(err, err_input, trim(shard_paths(k)) // ': belongs to another campaign than ' // &
                       trim(shard_paths(1)))
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
      call set_error(err, err_input, 'shards missing: ' // missing_list(shard_of) // ' of ' // itoa(n_shards))
      return
    end if

    call read_input_text(shards(1)%text_attribute('input_file'), shards(1)%text_attribute('input_namelist'), &
                         target, inp, err)
    if (err%failed()) return
    if (campaign_id(inp) /= id) then
      call set_error(err, err_input, trim(shard_paths(1)) // ': the stored input does not match its campaign id')
      return
    end if

    prov = prov_in
    prov%input_file = shards(1)%text_attribute('input_file')
    prov%input_namelist = shards(1)%text_attribute('input_namelist')
    prov%campaign_id = id
    prov%n_cases_total = inp%campaign%n_cases()
    prov%shard = '0/1'
    partial = target // '.partial'
    all_cases = [(i, i = 0, inp%campaign%n_cases() - 1)]
    call out%create(partial, all_cases, shards(1)%real_column('time', err), inp%plan%fields, inp%campaign%base, &
                    prov, inp%campaign%coordinates(all_cases), err, inp%plan%compression)
    do index = 0, n_shards - 1
      slots = shard_slots(inp%campaign%n_cases(), [index, n_shards])
      if (size(slots, kind=i8) /= shards(shard_of(index))%n_cases .and. .not. err%failed()) &
        call set_error(err, err_input, trim(shard_paths(shard_of(index))) // ': holds ' // &
            itoa(shards(shard_of(index))%n_cases) // ' cases; shard ' // itoa(index) // ' should hold ' // &
            itoa(size(slots)))
      do slot = 0, size(slots, kind=i8) - 1
        if (err%failed()) exit
        call shards(shard_of(index))%read_case_result(slot, inp%plan%n_samples, res, err)
        call out%write_case(slots(slot + 1), inp%campaign%case_at(slots(slot + 1)), res, err)
      end do
    end do
    call out%close(err)
    do k = 1, size(shards)
      call shards(k)%close()
    end do
    if (.not. err%failed()) then
      if (.not. rename_file(partial, target)) &
        call set_error(err, err_output, target // ': cannot move the merged file into place')
    end if
    if (err%failed()) call remove_file(partial)
  end subroutine merge_shards

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

  function missing_list(shard_of) result(text)
    integer, intent(in) :: shard_of(0:)
    character(len=:), allocatable :: text
    integer :: k
    text = ''
    do k = 0, size(shard_of) - 1
      if (shard_of(k) /= 0) cycle
      if (len(text) > 0) text = text // ', '
      text = text // itoa(k)
    end do
  end function missing_list
end module ellroll_merge
