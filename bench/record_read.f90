!> Reading ground-motion records: ellroll's reader (load_ground_motion, as
!> `ellroll check` and `run` call it) on the files given, each read as a
!> record of its own, in-process. Prints the best processor time and the
!> best wall time over the repetitions of reading them all, in seconds, and
!> the number of samples of the records read.
!> bench/records.py writes the files and sets this beside numpy.
!> Usage: build/bench_record_read repeats FILE...
program record_read
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use bench_args, only: repeats_argument
  use ellroll_kinds, only: wp, i8
  use ellroll_record_file, only: load_ground_motion
  use ellroll_system, only: tune_runtime
  implicit none
  integer :: repeats, k, f
  integer(i8) :: start, finish, rate, samples
  real(wp) :: best, best_cpu, seconds, cpu_start, cpu_finish, sink
  real(wp), allocatable :: times(:), values(:, :)
  character(len=:), allocatable :: reason
  character(len=1024), allocatable :: paths(:)

  call tune_runtime()
  repeats = repeats_argument(default=5)
  allocate (paths(command_argument_count() - 1))
  do f = 1, size(paths)
    call get_command_argument(f + 1, paths(f))
  end do
  best = huge(1.0_wp)
  best_cpu = huge(1.0_wp)
  sink = 0
  do k = 1, repeats
    samples = 0
    call cpu_time(cpu_start)
    call system_clock(start, rate)
    do f = 1, size(paths)
      call load_ground_motion(paths(f:f), 1.0_wp, times, values, reason)
      if (len(reason) > 0) then
        write (error_unit, '(a)') reason
        stop 1
      end if
      samples = samples + size(times)
      sink = sink + values(1, 1)
    end do
    call system_clock(finish)
    call cpu_time(cpu_finish)
    seconds = real(finish - start, wp) / real(rate, wp)
    best = min(best, seconds)
    best_cpu = min(best_cpu, cpu_finish - cpu_start)
  end do
  write (output_unit, '(2(es12.5, 1x), i0, 1x, es10.3)') best_cpu, best, samples, sink
end program record_read
