!> What the journal's CRC-32C costs, side by side with what it protects:
!>   summary record   one case's record without trajectories (64 words)
!>   full record      a record holding the paper case's trajectories (every
!>                    field at 100 Hz over 30 s: 3001 samples x 17 values),
!>                    as a compressed run journals them; the same work as the
!>                    fingerprint of trajectories written in place
!>   the case         the paper case (RK4, dt = 1e-3, 30 s) integrated with
!>                    every field stored at 100 Hz
!> Each figure is the best of several repetitions. Usage: build/bench_journal_checksum [repeats]
program journal_checksum
  use, intrinsic :: iso_fortran_env, only: output_unit
  use bench_args, only: repeats_argument
  use ellroll_kinds, only: wp, i8
  use ellroll_checksum, only: checksum
  use ellroll_errors, only: error_t
  use ellroll_cases, only: case_t, output_plan_t
  use ellroll_results, only: case_result_t
  use ellroll_simulate, only: simulate_case
  use ellroll_system, only: tune_runtime
  use ellroll_params, only: p_a, p_b, p_c, p_dt, p_g, p_mass, p_omega_x, p_omega_z, p_radius
  implicit none
  integer, parameter :: summary_words = 64, full_words = summary_words + 3001 * 17
  integer :: repeats, k, j, inner
  integer(i8), allocatable :: words(:)
  integer(i8) :: sink, start, finish, rate
  real(wp) :: best_summary, best_full, best_case, seconds
  type(case_t) :: cs
  type(output_plan_t) :: plan
  type(case_result_t) :: res
  type(error_t) :: err

  call tune_runtime()
  repeats = repeats_argument(default=7)
  allocate (words(full_words))
  do j = 1, full_words
    words(j) = ieor(shiftl(int(j, i8), 29), int(j, i8))     ! varied bits, no overflow
  end do
  cs%param(p_a) = 1
  cs%param(p_b) = 0.4_wp
  cs%param(p_c) = 0.2_wp
  cs%param(p_radius) = 0.2_wp
  cs%param(p_g) = 9.81_wp
  cs%param(p_mass) = 2620 / 9.81_wp
  cs%param(p_omega_x:p_omega_z) = [-2.0_wp, 2.0_wp, 20.0_wp]; cs%param(p_dt) = 1.0e-3_wp; cs%t_end = 30
  plan%interval = 0.01_wp
  plan%n_samples = 3001
  plan%fields = .true.

  sink = 0
  best_summary = huge(1.0_wp)
  best_full = huge(1.0_wp)
  best_case = huge(1.0_wp)
  inner = 100000
  do k = 1, repeats
    call system_clock(start, rate)
    do j = 1, inner
      words(1) = j
      sink = ieor(sink, checksum(words(:summary_words)))
    end do
    call system_clock(finish)
    best_summary = min(best_summary, real(finish - start, wp) / rate / inner)
    call system_clock(start)
    do j = 1, 100
      words(1) = j
      sink = ieor(sink, checksum(words))
    end do
    call system_clock(finish)
    best_full = min(best_full, real(finish - start, wp) / rate / 100)
    call system_clock(start)
    call simulate_case(cs, plan, res, err)
    call system_clock(finish)
    best_case = min(best_case, real(finish - start, wp) / rate)
  end do
  seconds = best_full
  write (output_unit, '(a)') 'CRC-32C of journal records, best of repeats, one core'
  write (output_unit, '(a, f10.1, a)') '  summary record (512 bytes):     ', 1e9_wp * best_summary, ' ns'
  write (output_unit, '(a, f5.2, a, f8.1, a, f5.2, a)') '  full record (', 8e-6_wp * full_words, ' MB):      ', &
      1e6_wp * seconds, ' us (', 8 * full_words / seconds / 1e9_wp, ' GB/s)'
  write (output_unit, '(a, f10.1, a)') '  the case it protects:           ', 1e3_wp * best_case, ' ms'
  write (output_unit, '(a, es10.2)') '  full record / case:             ', seconds / best_case
  write (output_unit, '(a, es10.2)') '  summary record / case:          ', best_summary / best_case
  if (sink == 42) write (output_unit, '(a)') ''     ! keeps the checksums computed
end program journal_checksum
