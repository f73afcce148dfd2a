!> What a moving cup and rolling resistance cost a case, measured side by
!> side in one run: the paper's cup and ball started off the bottom, RK4,
!> 30 s at dt = 1e-3 (30,000 steps), summary only, one case on the
!> single-case path (simulate_case), best of several repetitions:
!>   fixed cup            the reference
!>   record               a ground-motion record of 30 s at 0.01 s (3,001
!>                        samples, equal steps: found by index), as read from
!>                        an .AT2 file
!>   record, uneven       the same record on uneven times (found by bisection)
!>   harmonic             a harmonic base acceleration
!>   rolling resistance   the fixed cup with delta = 1e-4 m (its stops are events)
!> Ratios are to the fixed cup. Usage: build/bench_scene_cost [repeats]
program scene_cost
  use, intrinsic :: iso_fortran_env, only: output_unit
  use bench_args, only: repeats_argument
  use ellroll_kinds, only: wp, i8, two_pi
  use ellroll_errors, only: error_t
  use ellroll_cases, only: case_t, output_plan_t
  use ellroll_results, only: case_result_t
  use ellroll_simulate, only: simulate_case
  use ellroll_system, only: tune_runtime
  use ellroll_excitation, only: excitation_harmonic, set_record
  use ellroll_params, only: p_a, p_b, p_c, p_dt, p_excitation_amplitude_x, p_excitation_amplitude_z, &
      p_excitation_frequency, p_g, p_mass, p_omega_x, p_omega_z, p_radius, p_x, p_y, p_rolling_resistance
  implicit none
  integer, parameter :: n_scenes = 5, n_record = 3001
  character(len=*), parameter :: names(n_scenes) = [character(len=24) :: 'fixed cup', 'record', &
      'record, uneven times', 'harmonic', 'rolling resistance']
  type(case_t) :: scenes(n_scenes)
  type(output_plan_t) :: plan
  type(case_result_t) :: res
  type(error_t) :: err
  real(wp) :: best(n_scenes), seconds, times(n_record), values(3, n_record)
  integer :: repeats, k, s
  logical :: held

  call tune_runtime()
  repeats = repeats_argument(default=5)
  scenes(1)%param(p_a) = 1
  scenes(1)%param(p_b) = 0.4_wp
  scenes(1)%param(p_c) = 0.2_wp
  scenes(1)%param(p_radius) = 0.2_wp
  scenes(1)%param(p_g) = 9.81_wp; scenes(1)%param(p_mass) = 2620 / 9.81_wp
  scenes(1)%param(p_x) = 0.05_wp
  scenes(1)%param(p_y) = 0.03_wp
  scenes(1)%param(p_omega_x:p_omega_z) = [0.0_wp, 0.0_wp, 0.5_wp]
  scenes(1)%param(p_dt) = 1.0e-3_wp; scenes(1)%t_end = 30
  scenes(2:) = scenes(1)
  do k = 1, n_record
    times(k) = real(k - 1, wp) * 0.01_wp
    values(:, k) = 0.3_wp * [sin(two_pi * 0.7_wp * times(k)), cos(two_pi * 1.1_wp * times(k)), 0.0_wp]
  end do
  call set_record(scenes(2)%excitation, times, values, held)
  times(2:n_record - 1) = times(2:n_record - 1) + 1.0e-4_wp * sin(real([(k, k = 2, n_record - 1)], wp))
  call set_record(scenes(3)%excitation, times, values, held)
  if (.not. held) error stop 'no room for the records'
  scenes(4)%excitation%kind = excitation_harmonic
  scenes(4)%param(p_excitation_amplitude_x:p_excitation_amplitude_z) = [0.3_wp, 0.2_wp, 0.0_wp]
  scenes(4)%param(p_excitation_frequency) = 0.7_wp
  scenes(5)%param(p_rolling_resistance) = 1.0e-4_wp
  plan%interval = 30
  plan%n_samples = 2
  plan%fields = .false.

  best = huge(1.0_wp)
  do k = 1, repeats
    do s = 1, n_scenes
      seconds = timed(scenes(s))
      best(s) = min(best(s), seconds)
    end do
  end do
  write (output_unit, '(a)') 'One case, RK4, 30 s at dt = 1e-3 (30,000 steps), summary only, best of repeats, one core'
  write (output_unit, '(a24, a12, a16)') 'scene', 'ns/step', 'vs fixed cup'
  do s = 1, n_scenes
    write (output_unit, '(a24, f12.1, f15.3, a)') names(s), 1.0e9_wp * best(s) / 30000, best(s) / best(1), 'x'
  end do
  write (output_unit, '(a, f6.3, a)') 'a record case costs ', best(2) / best(1), 'x a fixed-cup case (target <= 1.2x)'

contains

  real(wp) function timed(cs) result(seconds)
    type(case_t), intent(in) :: cs
    integer(i8) :: start, finish, rate
    call system_clock(start, rate)
    call simulate_case(cs, plan, res, err)
    call system_clock(finish)
    seconds = real(finish - start, wp) / rate
    if (err%failed() .or. res%n_steps /= 30000) error stop 'scene_cost: a case did not run to its end'
  end function timed
end program scene_cost
