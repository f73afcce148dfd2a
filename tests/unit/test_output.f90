!> The HDF5 writer keeps cases in windows of consecutive slots and writes a
!> window when it is complete, or the oldest one when all are in use. Cases
!> given in any order (as a resume replays its journal) must all land in
!> their slots: here more windows are open at once than the writer keeps,
!> so windows are written partly filled and later completed.
program test_output
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_status, only: status_completed, status_rim
  use ellroll_cases, only: case_t, field_count, field_names
  use ellroll_results, only: case_result_t
  use ellroll_hdf5, only: h5_output_t, h5_input_t, provenance_t
  use fixtures, only: paper_case
  use testing, only: check, finish
  implicit none
  ! one field of 3 components at n_samples samples is 720 kB a case: the
  ! writer's 4 MiB windows hold 5 cases, and 20 windows are opened at once
  integer(i8), parameter :: n_samples = 30000, n_cases = 100, rows = 5
  character(len=*), parameter :: path = 'test_output.h5'
  integer :: contact
  integer(i8) :: order(n_cases), k, slot, n_wrong
  logical :: fields(field_count)
  real(wp) :: times(n_samples)
  type(case_t) :: cs
  type(case_result_t) :: res, expected
  type(h5_output_t) :: out
  type(h5_input_t) :: file
  type(provenance_t) :: prov
  type(error_t) :: err

  contact = findloc(field_names, 'contact', dim=1)
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
  call out%create(path, [(k, k = 0, n_cases - 1)], times, fields, cs, prov, err)
  do k = 1, n_cases
    slot = order(k)
    cs%index = slot
    call out%write_case(slot, cs, result_of(slot), err)
  end do
  call out%close(err)
  call check(.not. err%failed(), 'written without error: ' // err%message)

  call file%open(path, err)
  n_wrong = 0
  do slot = 0, n_cases - 1
    call file%read_case_result(slot, n_samples, res, err)
    expected = result_of(slot)
    if (res%status /= expected%status .or. res%t_final /= expected%t_final .or. &
        any(res%fields(contact)%values /= expected%fields(contact)%values)) n_wrong = n_wrong + 1
  end do
  call file%close()
  call check(.not. err%failed(), 'read back without error: ' // err%message)
  call check(n_wrong == 0, 'every case in its slot, status, summary and trajectory')
  open (newunit=k, file=path)
  close (k, status='delete')
  call finish('test_output')

contains

  !> A result that names its slot in every value.
  function result_of(slot) result(r)
    integer(i8), intent(in) :: slot
    type(case_result_t) :: r
    integer(i8) :: j
    r%status = merge(status_completed, status_rim, mod(slot, 3_i8) /= 0)
    r%t_final = real(slot, wp) + 0.5_wp
    allocate (r%fields(contact)%values(3, n_samples))
    do j = 1, n_samples
      r%fields(contact)%values(:, j) = real(slot, wp) + [1, 2, 3] * 1.0e-6_wp * real(j, wp)
    end do
  end function result_of
end program test_output
