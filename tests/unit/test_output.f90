!> The HDF5 writer keeps cases in windows of consecutive slots and writes a
!> window when it is complete, or the oldest one when all are in use. Cases
!> given in any order (as a resume replays its journal) must all land in
!> their slots: here more windows are open at once than the writer keeps,
!> so windows are written partly filled and later completed. Compressed
!> trajectories go with their windows; uncompressed ones are written in
!> place, case by case, and only the table rows are kept in windows; the
!> file's label leads a reader (a resume) to them without HDF5. A resume
!> moves cases from one file's store to another's piece by piece (1 MiB),
!> and puts a case cut in two by an interrupted move together again.
program test_output
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_status, only: status_completed, status_rim
  use ellroll_cases, only: case_t, field_count, field_names
  use ellroll_results, only: case_result_t
  use ellroll_campaign, only: coordinate_t
  use ellroll_hdf5_writer, only: h5_output_t, provenance_t
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_hdf5_common, only: hdf5_open_ids
  use ellroll_strings, only: itoa
  use ellroll_trajectory_store, only: trajectory_store_t
  use ellroll_system, only: open_for_writing
  use fixtures, only: paper_case
  use testing, only: check, finish
  implicit none
  character(len=*), parameter :: path = 'test_output.h5'
  integer :: contact

  contact = findloc(field_names, 'contact', dim=1)
  ! compressed: one field of 3 components at 30,000 samples is 720 kB a
  ! case, so the writer's 4 MiB windows hold 5 cases: 20 windows at once
  call write_in_any_order_and_read_back(compression=1, n_cases=100_i8, n_samples=30000_i8, rows=5_i8)
  ! in place: windows of 64 rows, 20 of them at once
  call write_in_any_order_and_read_back(compression=0, n_cases=1280_i8, n_samples=10_i8, rows=64_i8)
  call move_between_stores()
  call refusals_leave_nothing_open()
  call finish('test_output')

contains

  subroutine write_in_any_order_and_read_back(compression, n_cases, n_samples, rows)
    integer, intent(in) :: compression
    integer(i8), intent(in) :: n_cases, n_samples, rows
    character(len=*), parameter :: how(0:1) = ['in place  ', 'compressed']
    integer(i8) :: order(n_cases), k, slot, n_wrong
    logical :: fields(field_count)
    real(wp) :: times(n_samples)
    type(case_t) :: cs
    type(case_result_t) :: res, expected
    type(h5_output_t) :: out
    type(h5_input_t) :: file
    type(provenance_t) :: prov
    type(error_t) :: err

    fields = .false.
    fields(contact) = .true.
    times = [(real(k, wp), k = 0, n_samples - 1)]
    ! the first case of every window, then all the others from the last back
    order(:n_cases / rows) = [(k * rows, k = 0, n_cases / rows - 1)]
    order(n_cases / rows + 1:) = pack([(k, k = n_cases - 1, 0, -1)], mod([(k, k = n_cases - 1, 0, -1)], rows) /= 0)
    call check(all([(count(order == k) == 1, k = 0, n_cases - 1)]), 'the order is a permutation of the slots')

    prov = provenance_t(program='ellroll', version='0', created='now', input_file='-', input_namelist='-', &
                        command_line='-', campaign_id='0', n_cases_total=n_cases, shard='0/1')
    cs = paper_case(1.0e-3_wp, 1.0_wp)
    call out%create(path, [(k, k = 0, n_cases - 1)], times, fields, cs, prov, [coordinate_t ::], err, &
                    compression)
    do k = 1, n_cases
      slot = order(k)
      cs%index = slot
      call out%write_case(slot, cs, result_of(slot, n_samples), err)
    end do
    call out%close(err)
    call check(.not. err%failed(), trim(how(compression)) // ': written without error: ' // err%message)

    call file%open(path, err)
    n_wrong = 0
    do slot = 0, n_cases - 1
      call file%read_case_result(slot, n_samples, res, err)
      expected = result_of(slot, n_samples)
      if (res%status /= expected%status .or. .not. same(res%t_final, expected%t_final) .or. &
          .not. all(same(res%fields(contact)%values, expected%fields(contact)%values))) n_wrong = n_wrong + 1
    end do
    call file%close()
    call check(.not. err%failed(), trim(how(compression)) // ': read back without error: ' // err%message)
    call check(n_wrong == 0, trim(how(compression)) // ': every case in its slot, status, summary and trajectory')
    call read_back_in_place(compression == 0, n_cases, n_samples, fields)
    open (newunit=k, file=path)
    close (k, status='delete')
  end subroutine write_in_any_order_and_read_back

  !> The reader refuses a file of another program (root attribute program)
  !> after HDF5 has opened it, and an ellroll file it reads is ellroll's own
  !> (made_here); either way, once closed, no HDF5 object stays open.
  subroutine refusals_leave_nothing_open()
    character(len=*), parameter :: other = 'test_output_other.h5'
    type(h5_output_t) :: out
    type(h5_input_t) :: file
    type(provenance_t) :: prov
    type(error_t) :: err, refusal
    logical :: fields(field_count)
    integer :: unit
    fields = .false.
    prov = provenance_t(program='another', version='0', created='now', input_file='-', input_namelist='-', &
                        command_line='-', campaign_id='0', n_cases_total=1, shard='0/1')
    call out%create(other, [0_i8], [0.0_wp], fields, paper_case(1.0e-3_wp, 1.0_wp), prov, [coordinate_t ::], err)
    call out%close(err)
    call check(.not. err%failed(), 'the file of another program written: ' // err%message)
    call check(hdf5_open_ids() == 0, 'no HDF5 object open after the writer closed its file')
    call file%open(other, refusal)
    call check(index(refusal%message, 'not an ellroll file') > 0, 'another program''s file refused: ' // &
               refusal%message)
    call check(hdf5_open_ids() == 0, 'no HDF5 object open after the refusal (found ' // &
               itoa(hdf5_open_ids()) // ')')
    call file%close()
    prov%program = 'ellroll'
    open (newunit=unit, file=other)
    close (unit, status='delete')
    call out%create(other, [0_i8], [0.0_wp], fields, paper_case(1.0e-3_wp, 1.0_wp), prov, [coordinate_t ::], err)
    call out%close(err)
    call file%open(other, err)
    call check(.not. err%failed(), 'an ellroll file read: ' // err%message)
    call check(file%made_here(), 'an ellroll file is ellroll''s own')
    call file%close()
    call check(hdf5_open_ids() == 0, 'no HDF5 object open after an ellroll file was read and closed')
    open (newunit=unit, file=other)
    close (unit, status='delete')
  end subroutine refusals_leave_nothing_open

  !> The trajectories read back through the file's label, as a resume
  !> does; a file without a label (compressed), or labelled for another
  !> layout, is refused. Freeing the storage of all but the trajectories,
  !> then of the first half of the cases, as a resume does, leaves the
  !> others intact.
  subroutine read_back_in_place(labelled, n_cases, n_samples, fields)
    logical, intent(in) :: labelled
    integer(i8), intent(in) :: n_cases, n_samples
    logical, intent(in) :: fields(field_count)
    type(trajectory_store_t) :: store, other_layout
    type(case_result_t) :: res, expected
    type(error_t) :: err, refusal
    integer(i8) :: slot, n_wrong
    call store%open_existing(path, n_cases, n_samples, fields, .true., err)
    if (.not. labelled) then
      call check(err%failed() .and. index(err%message, 'no trajectory label') > 0, &
                 'compressed: no label, refused: ' // err%message)
      call store%close(err)
      return
    end if
    call store%release_all_but_trajectories()
    n_wrong = 0
    do slot = 0, n_cases - 1
      call store%get(slot, res, err)
      expected = result_of(slot, n_samples)
      if (.not. all(same(res%fields(contact)%values, expected%fields(contact)%values))) n_wrong = n_wrong + 1
    end do
    call check(.not. err%failed() .and. n_wrong == 0, 'in place: every trajectory read back through the label')
    call store%release_to(contact, store%address(contact) + 8 * 3 * n_samples * (n_cases / 2))
    n_wrong = 0
    do slot = n_cases / 2, n_cases - 1
      call store%get(slot, res, err)
      expected = result_of(slot, n_samples)
      if (.not. all(same(res%fields(contact)%values, expected%fields(contact)%values))) n_wrong = n_wrong + 1
    end do
    call store%close(err)
    call check(.not. err%failed() .and. n_wrong == 0, 'in place: the cases after those freed intact')
    call other_layout%open_existing(path, n_cases, n_samples + 1, fields, .false., refusal)
    call check(index(refusal%message, 'laid out for another run') > 0, 'in place: another layout refused')
    call other_layout%close(refusal)
  end subroutine read_back_in_place

  !> Cases of 150,000 values (two pieces of a move: 131,072 and 18,928
  !> values) moved from one store to another arrive whole, and leave the
  !> other cases intact; a case put together from the first piece of one
  !> read and the second of another takes each where it belongs.
  subroutine move_between_stores()
    integer(i8), parameter :: n_cases = 3, n_samples = 50000, piece_values = 131072
    character(len=*), parameter :: from_path = 'test_output_from.bin', to_path = 'test_output_to.bin'
    type(trajectory_store_t) :: from, to
    type(case_result_t) :: res, expected, other
    type(error_t) :: err
    logical :: fields(field_count)
    integer(i8) :: slot, first, count
    integer :: f, n_wrong
    real(wp), allocatable :: joined(:), unchanged(:)
    fields = .false.
    fields(contact) = .true.
    call start_store(from, from_path, n_cases, n_samples, fields, err)
    do slot = 0, n_cases - 1
      call from%put(slot, [result_of(slot, n_samples)], err)
    end do
    call from%close(err)
    call start_store(to, to_path, n_cases, n_samples, fields, err)
    call from%open_existing(from_path, n_cases, n_samples, fields, .true., err)
    call check(to%n_pieces() == 2, 'a case of 150,000 values moves in two pieces')
    call to%piece(2_i8, f, first, count)
    call check(f == contact .and. first == piece_values .and. count == 3 * n_samples - piece_values, &
               'the second piece: the values after the first 1 MiB')
    n_wrong = 0
    do slot = 0, 1
      call from%get(slot, res, err)
      call to%move_in(slot, res, from, err)
      call to%get(slot, res, err)
      expected = result_of(slot, n_samples)
      if (.not. all(same(res%fields(contact)%values, expected%fields(contact)%values))) n_wrong = n_wrong + 1
    end do
    call from%get(2_i8, res, err)
    expected = result_of(2_i8, n_samples)
    if (.not. all(same(res%fields(contact)%values, expected%fields(contact)%values))) n_wrong = n_wrong + 1
    call check(.not. err%failed() .and. n_wrong == 0, 'moved cases whole in the new store, the others intact')
    other = result_of(1_i8, n_samples)
    expected = result_of(0_i8, n_samples)
    call to%take_piece(other, expected, 1_i8)
    joined = reshape(other%fields(contact)%values, [3 * n_samples])
    res = result_of(1_i8, n_samples)
    unchanged = reshape(res%fields(contact)%values, [3 * n_samples])
    call check(all(same(joined(:piece_values), reshape(expected%fields(contact)%values, [piece_values]))) .and. &
               all(same(joined(piece_values + 1:), unchanged(piece_values + 1:))), &
               'a case put together: the first piece from one read, the rest from the other')
    call from%close(err)
    call to%close(err)
    call remove(from_path)
    call remove(to_path)
  end subroutine move_between_stores

  !> A labelled store of one field in a new file: the label at an address
  !> a resume finds by its marker, the field after it.
  subroutine start_store(store, store_path, n_cases, n_samples, fields, err)
    type(trajectory_store_t), intent(inout) :: store
    character(len=*), intent(in) :: store_path
    integer(i8), intent(in) :: n_cases, n_samples
    logical, intent(in) :: fields(field_count)
    type(error_t), intent(inout) :: err
    integer(i8) :: address(field_count)
    integer :: unit
    open (newunit=unit, file=store_path, status='replace')
    close (unit)
    address = merge(1024_i8, -1_i8, fields)
    call store%start(store_path, open_for_writing(store_path), n_cases, n_samples, fields, address, 200_i8, err)
  end subroutine start_store

  subroutine remove(file)
    character(len=*), intent(in) :: file
    integer :: unit
    open (newunit=unit, file=file)
    close (unit, status='delete')
  end subroutine remove

  !> A result that names its slot in every value.
  function result_of(slot, n_samples) result(r)
    integer(i8), intent(in) :: slot, n_samples
    type(case_result_t) :: r
    integer(i8) :: j
    r%status = merge(status_completed, status_rim, mod(slot, 3_i8) /= 0)
    r%t_final = real(slot, wp) + 0.5_wp
    allocate (r%fields(contact)%values(3, n_samples))
    do j = 1, n_samples
      r%fields(contact)%values(:, j) = real(slot, wp) + [1, 2, 3] * 1.0e-6_wp * real(j, wp)
    end do
  end function result_of

  !> Bitwise equality of reals.
  elemental logical function same(a, b)
    real(wp), intent(in) :: a, b
    same = transfer(a, 0_i8) == transfer(b, 0_i8)
  end function same
end program test_output
