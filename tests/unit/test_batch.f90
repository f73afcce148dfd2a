!> The batch path (simulate_batch: cases across SIMD lanes) against the
!> one-case path (simulate_case) on cases that differ in everything a lane
!> holds: geometry, ball, spin, step, length, and how they end (completed,
!> rim, no_fit, slip). One step of each path from the same state agrees to
!> round-off: the right-hand side, the observed outputs, an embedded pair's
!> stages, new point and error norm (the compiler fuses multiply-adds
!> differently in the vector and the scalar code). RK4 then takes the same
!> steps on both paths, and every summary figure and stored sample agrees to
!> 1e-13 relative. DOP853 and Verner's 9(8) (each lane its own step control)
!> take the same steps until a step decision falls within that round-off of
!> its threshold; after it the two are runs of one method at one tolerance:
!> the same status, step counts within 1 + 2 %, results within 100 rtol.
!> A case's result does not depend on its lane or on the other cases of its
!> batch (bitwise). The same holds for moving cups (harmonic and recorded
!> excitations, each lane its own), with a fixed cup among them computing
!> bitwise what it computes in a batch of fixed cups.
program test_batch
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_status, only: status_completed, status_rim, status_no_fit, status_slip, status_liftoff
  use ellroll_excitation, only: excitation_none, excitation_harmonic, set_record, base_acceleration
  use ellroll_excitation_lanes, only: excitation_lanes_t
  use ellroll_cases, only: case_t, output_plan_t, field_count, make_ball
  use ellroll_results, only: case_result_t, figure_values
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, state_size, initial_state, ball_derivative, observe
  use ellroll_ball_lanes, only: ball_lanes_t, lane_outputs_t, set_lane, lanes_derivative, lanes_observe
  use ellroll_quantities, only: q_energy
  use ellroll_integrators, only: embedded_pair_t, methods, method_info_t, method_info, new_pair, max_pair_stages
  use ellroll_embedded_pair, only: width
  use ellroll_ball_steppers, only: pair_ball_step, lanes_pair_attempt
  use ellroll_simulate, only: simulate_case, simulate_batch, batchable, lanes
  use fixtures, only: paper_case
  use testing
  use ellroll_params, only: p_atol, p_dt, p_omega_x, p_omega_z, p_rtol, p_x, p_y, p_a, p_b, p_c, p_g, &
      p_inertia_factor, p_mass, p_mu, p_radius, p_excitation_frequency, p_excitation_phase, &
      p_excitation_amplitude_x, p_excitation_amplitude_y, p_excitation_amplitude_z, p_scale, &
      p_rolling_resistance, p_settle
  use ellroll_figures, only: fig_constraint_error_max, fig_displacement_max, fig_energy_drift, &
      fig_friction_needed_max, fig_horizontal_force_max, fig_linear_periods, fig_nutation_maxima, &
      fig_nutation_period, fig_reaction_normal_max, fig_theta_max, fig_rest_time, fig_at_rest, &
      fig_residual_displacement, fig_rolling_resistance_energy
  implicit none
  integer, parameter :: n_cases = lanes
  type(case_t) :: cases(n_cases)
  type(output_plan_t) :: plan
  integer :: l, k

  ! output every 0.01 s of the longest case; shorter cases leave NaN after their end
  plan%interval = 0.01_wp
  plan%n_samples = 301
  plan%fields = .true.

  ! the embedded pairs' columns are the lanes
  call check(lanes == width, 'a batch has as many lanes as an embedded pair''s columns have entries')
  cases = make_cases()
  call one_step(cases)
  do k = 1, size(methods)                 ! every method of the table that batches
    if (.not. methods(k)%batches) cycle
    cases = make_cases()
    cases%method = methods(k)%name
    if (.not. methods(k)%adaptive) then
      call compare_paths(cases, trim(methods(k)%name))
      ! a sample at every step: the step that crosses a limit is a sample step
      ! (its sample is past the limit, not the case's), and the batch's sample
      ! blocks fill and flush many times
      plan%interval = 1.0e-3_wp
      plan%n_samples = 3001
      call compare_paths(cases, trim(methods(k)%name) // ', a sample every step')
      plan%interval = 0.01_wp
      plan%n_samples = 301
    else
      ! each lane its own tolerances and largest step
      do l = 1, n_cases
        cases(l)%param(p_rtol) = 10.0_wp**(-6 - l / 2)
        cases(l)%param(p_atol) = cases(l)%param(p_rtol) * 1.0e-3_wp
        cases(l)%param(p_dt) = merge(0.05_wp, 0.5_wp, mod(l, 2) == 0)
      end do
      call compare_paths(cases, trim(methods(k)%name))
    end if
  end do
  call parted_runs()
  call moving_cups()
  call rolling_resistance_lanes()
  call finish('test_batch')

contains

  !> One step of each path from the same states (the cases' starts, the
  !> normals tilted and the spins changed by seeded random amounts): the
  !> right-hand side and the observed outputs (the reaction from omega',
  !> the contact point, the energy) agree to 8 eps of their size; an attempt
  !> of each pair, 2 to 50 ms long (stages up to the new point, each from the
  !> ones before), to 1e-13 of the stages' size, and its error norm to the
  !> round-off of its estimate, a difference of stages (eps sum_s |k_s|,
  !> scaled as the norm).
  subroutine one_step(cases)
    type(case_t), intent(in) :: cases(lanes)
    type(rolling_ball_t) :: ball(lanes)
    type(ball_lanes_t) :: balls
    type(lane_outputs_t) :: out
    type(observation_t) :: obs
    class(embedded_pair_t), allocatable :: pair
    real(wp), dimension(lanes, state_size) :: y, f, f_lanes, y_raw
    real(wp) :: k(lanes, state_size, max_pair_stages), h(lanes), rtol(lanes), atol(lanes), norm(lanes), u(state_size)
    real(wp) :: y_new(state_size), noise(state_size), scale(state_size), stages, y_lane(state_size), f_lane(state_size)
    real(wp) :: rhs_worst, observe_worst, stage_worst, norm_worst
    type(error_t) :: err
    integer :: l, seed_size, row, s
    call random_seed(size=seed_size)
    call random_seed(put=[(1990 + 11 * l, l = 1, seed_size)])
    rhs_worst = 0
    observe_worst = 0
    do l = 1, lanes
      ball(l) = make_ball(cases(l))
      call set_lane(balls, l, ball(l))
      call random_number(u)
      y(l, :) = initial_state(ball(l), cases(l)%param(p_x), cases(l)%param(p_y), cases(l)%param(p_omega_x:p_omega_z))
      y(l, 1:2) = y(l, 1:2) + 0.2_wp * (u(1:2) - 0.5_wp)
      y(l, 4:6) = y(l, 4:6) + 4 * (u(4:6) - 0.5_wp)
      h(l) = 0.002_wp + 0.048_wp * u(3)
      rtol(l) = cases(l)%param(p_rtol)
      atol(l) = cases(l)%param(p_atol)
    end do
    call lanes_derivative(balls, y, f_lanes)
    call lanes_observe(balls, y, f_lanes, out)
    do l = 1, lanes
      y_lane = y(l, :)               ! contiguous rows for the one-case routines
      call ball_derivative(ball(l), 0.0_wp, y_lane, f_lane)
      f(l, :) = f_lane
      rhs_worst = max(rhs_worst, maxval(abs(f_lanes(l, :) - f_lane)) / maxval(abs(f_lane)))
      call observe(ball(l), 0.0_wp, y_lane, f_lane, obs)
      observe_worst = max(observe_worst, maxval(abs(out%reaction(l, :) - obs%reaction)) / norm2(obs%reaction), &
                          maxval(abs(out%contact(l, :) - obs%contact)) / norm2(obs%contact), &
                          abs(out%quantity(l, q_energy) - obs%energy) / abs(obs%energy))
    end do
    call check_below(rhs_worst / epsilon(1.0_wp), 8.0_wp, 'one state: batch vs one case, right-hand side (eps)')
    call check_below(observe_worst / epsilon(1.0_wp), 8.0_wp, &
                     'one state: batch vs one case, contact, reaction and energy (eps)')
    do row = 1, size(methods)             ! every embedded pair of the method table that batches
      if (.not. (methods(row)%adaptive .and. methods(row)%batches)) cycle
      call new_pair(methods(row)%name, pair, err)
      stage_worst = 0
      norm_worst = 0
      call lanes_pair_attempt(pair, balls, y, f, h, rtol, atol, k, y_raw, norm)
      do l = 1, lanes
        pair%rtol = rtol(l)
        pair%atol = atol(l)
        y_lane = y(l, :)
        f_lane = f(l, :)
        call pair_ball_step(pair, ball(l), 0.0_wp, y_lane, f_lane, h(l), y_new)
        stages = maxval(abs(pair%k(:state_size, :pair%end_stage())))
        do s = 2, pair%end_stage()
          stage_worst = max(stage_worst, maxval(abs(k(l, :, s) - pair%k(:state_size, s))) / stages)
        end do
        stage_worst = max(stage_worst, maxval(abs(y_raw(l, :) - y_new)) / maxval(abs(y_new)))
        noise = sum(abs(pair%k(:state_size, :pair%end_stage())), dim=2)
        scale = atol(l) + max(abs(y(l, :)), abs(y_new)) * rtol(l)
        norm_worst = max(norm_worst, abs(norm(l) - pair%error_norm) / &
                         (epsilon(1.0_wp) * (h(l) * sqrt(sum((noise / scale)**2) / state_size) + pair%error_norm)))
      end do
      call check_below(stage_worst, 1.0e-13_wp, trim(methods(row)%name) // &
                       ' attempt: batch vs one case, stages and new point (rel. to the stages)')
      call check_below(norm_worst, 1.0_wp, trim(methods(row)%name) // &
                       ' attempt: batch vs one case, error norm (in units of its round-off)')
      deallocate (pair)
    end do
  end subroutine one_step

  !> The paper's case with dop853 at rtol = atol = 1e-6 over 30 s, alone
  !> and in a batch of its own copies. Where the compiler fuses
  !> multiply-adds (-march=native on an FMA processor) the batch's round-off
  !> turns one step decision the other way and the runs part (175 steps, 13
  !> rejected, against 174 and 12 alone); without (the Debug build) both take
  !> 175 and 12. Either way both complete, within 1 step and 1 rejection,
  !> their samples within 100 rtol of each other.
  subroutine parted_runs()
    type(case_t) :: cs, cases(lanes)
    type(case_result_t) :: res, batch(lanes)
    type(output_plan_t) :: plan_30
    type(error_t) :: err
    real(wp) :: worst
    logical :: parted, close
    integer :: l
    cs = paper_case(30.0_wp, 30.0_wp)
    cs%method = 'dop853'
    cs%param(p_rtol) = 1.0e-6_wp
    cs%param(p_atol) = 1.0e-6_wp
    plan_30%interval = 0.01_wp
    plan_30%n_samples = 3001
    plan_30%fields = .true.
    call simulate_case(cs, plan_30, res, err)
    cases = cs
    call simulate_batch(cases, plan_30, batch)
    parted = .false.
    close = .true.
    worst = 0
    do l = 1, lanes
      parted = parted .or. batch(l)%n_steps /= res%n_steps .or. batch(l)%n_rejected /= res%n_rejected
      close = close .and. batch(l)%status == status_completed .and. abs(batch(l)%n_steps - res%n_steps) <= 1 &
              .and. abs(batch(l)%n_rejected - res%n_rejected) <= 1
      worst = max(worst, sample_difference(res, batch(l)))
    end do
    print '(a, i0, a, i0, a, i0, a, i0, a)', 'dop853 rtol = atol = 1e-6, 30 s: alone ', res%n_steps, ' steps (', &
          res%n_rejected, ' rejected), in a batch ', batch(1)%n_steps, ' (', batch(1)%n_rejected, ')'
    if (parted) print '(a)', 'dop853 rtol = atol = 1e-6, 30 s: the batch and the one-case run parted (round-off)'
    call check(close .and. res%status == status_completed, &
               'dop853 rtol = atol = 1e-6, 30 s: both complete, steps and rejected steps within 1')
    call check_below(worst, 100 * cs%param(p_rtol), &
        'dop853 rtol = atol = 1e-6, 30 s: samples, batch vs one case (max rel. diff)')
  end subroutine parted_runs

  !> The batch of these cases against each case on the one-case path, and
  !> the lanes' independence.
  !>
  !> RK4 takes the same steps on both paths, so everything agrees to
  !> round-off. The pairs' step sizes carry the round-off of their error
  !> estimates (one_step), and a step decision that falls within it of its
  !> threshold parts the two runs: over 30 s of the paper's case at 8 spins
  !> and rtol 1e-2 to 1e-12, one in 40 cases took other steps (at most 1
  !> step and 2 rejections more or fewer); over 300 s, steps within 2.4 %.
  !> Once parted, they are two runs at one tolerance: the same status, and
  !> results within that tolerance's error (the contact points apart by
  !> less than either's distance to a run at rtol 1e-13; here held to 100
  !> rtol, the accuracy test_integrators holds each pair to).
  subroutine compare_paths(cases, label, designed_ends, reference)
    type(case_t), intent(in) :: cases(n_cases)
    character(len=*), intent(in) :: label
    !> the statuses the cases are designed to end with (make_cases' when absent)
    integer, intent(in), optional :: designed_ends(n_cases)
    !> runs of the cases far more accurate than the pairs' (moving_cups)
    type(case_result_t), intent(in), optional :: reference(n_cases)
    ! summary figures (as in figures()): those located independently of the
    ! steps, the round-off-sized ones, and those taken at step ends
    integer, parameter :: located(5) = [1, 2, 7, 8, 9], round_off(2) = [5, 6], at_step_ends(4) = [3, 4, 10, 11]
    integer, parameter :: forces(3) = [3, 4, 11]
    type(case_result_t) :: single(n_cases), batch(n_cases), reordered(n_cases), alone(1)
    type(case_t) :: reversed(n_cases)
    type(method_info_t) :: method
    type(error_t) :: err
    real(wp) :: allowed, step_ends_bound
    real(wp) :: worst_located, worst_step_ends, worst_samples, worst_at_limit, worst_end_time, difference(11)
    integer :: l, order(n_cases), parted
    logical :: same_status, same_counts, close_counts, lane_independent, adaptive, at_limit, same_steps

    method = method_info(cases(1)%method)
    adaptive = method%adaptive
    ! (an embedded pair that took the same steps: dop853 1.3e-7, vern9 6.9e-6)
    step_ends_bound = merge(1.0e-5_wp, 1.0e-13_wp, adaptive)
    do l = 1, n_cases
      call check(batchable(cases(l)), label // ': test case is batchable')
      call simulate_case(cases(l), plan, single(l), err)
    end do
    call simulate_batch(cases, plan, batch)

    same_status = .true.
    same_counts = .true.
    close_counts = .true.
    parted = 0
    worst_located = 0
    worst_step_ends = 0
    worst_samples = 0
    worst_at_limit = 0
    worst_end_time = 0
    do l = 1, n_cases
      ! round-off for RK4; 100 rtol once a pair's two runs part
      allowed = merge(100 * cases(l)%param(p_rtol), 1.0e-13_wp, adaptive)
      same_status = same_status .and. single(l)%status == batch(l)%status
      difference = abs(figures(single(l)) - figures(batch(l))) / max(abs(figures(batch(l))), tiny(1.0_wp))
      if (present(reference) .and. adaptive) then
        ! against a far more accurate run: the batch's samples no further
        ! from it than twice the one-case path's, and 100 rtol (two parted
        ! runs may err on either side)
        worst_samples = max(worst_samples, sample_difference(reference(l), batch(l)) / &
                                           (2 * sample_difference(reference(l), single(l)) + allowed))
      else
        worst_samples = max(worst_samples, sample_difference(single(l), batch(l)) / allowed)
      end if
      at_limit = single(l)%status == status_no_fit .or. single(l)%status == status_rim
      worst_end_time = max(worst_end_time, abs(single(l)%t_final - batch(l)%t_final) / merge(allowed, 1.0e-12_wp, adaptive))
      if (at_limit .and. adaptive) cycle       ! below
      same_steps = single(l)%n_steps == batch(l)%n_steps .and. single(l)%n_rhs == batch(l)%n_rhs &
                   .and. single(l)%n_rejected == batch(l)%n_rejected
      same_counts = same_counts .and. same_steps .and. single(l)%counts(fig_nutation_maxima) == batch(l)%counts(fig_nutation_maxima)
      close_counts = close_counts .and. abs(single(l)%n_steps - batch(l)%n_steps) <= 1 + single(l)%n_steps / 50 &
                     .and. abs(single(l)%n_rejected - batch(l)%n_rejected) <= 2 + single(l)%n_steps / 50 &
                     .and. abs(single(l)%counts(fig_nutation_maxima) - batch(l)%counts(fig_nutation_maxima)) <= 1
      worst_located = max(worst_located, maxval(difference(located)) / allowed, maxval(difference(round_off)) / allowed)
      if (at_limit) then
        worst_at_limit = max(worst_at_limit, maxval(difference(forces)))
        difference(forces) = 0
      end if
      ! at lift-off N falls to 0 and the friction needed, |F_t| / N, is
      ! round-off over round-off at the last step
      if (single(l)%status == status_liftoff) difference(4) = 0
      ! the figures taken at step ends sample the motion where each run's steps end
      if (same_steps) then
        worst_step_ends = max(worst_step_ends, maxval(difference(at_step_ends)))
      else
        parted = parted + 1
      end if
    end do
    call check(same_status, label // ' batch: every case ends with the status of the one-case path')
    if (adaptive) then
      print '(a, i0, a)', label // ' batch: ', parted, ' of the completed or slipping cases took other steps alone'
      call check(close_counts, label // ' batch: steps within 1 + 2 %, rejected ones within 2 + 2 %, maxima of ' // &
                 'Theta within 1 per case')
    else
      call check(same_counts, label // ' batch: same steps, RHS calls and maxima of Theta per case')
    end if
    call check_below(worst_located, 1.0_wp, label // ' batch vs one case: Theta_max, periods, end time, energy ' // &
                     'drift (max rel. diff, in units of ' // trim(merge('100 rtol ', 'round-off', adaptive)) // ')')
    call check_below(worst_step_ends, step_ends_bound, label // ' batch vs one case, cases that took the same ' // &
                     'steps: maxima of forces and displacement (max rel. diff)')
    if (present(reference) .and. adaptive) then
      call check_below(worst_samples, 1.0_wp, label // ' batch: stored samples'' distance from a vern9 run at ' // &
                       'rtol 1e-13 (in units of twice the one-case path''s + 100 rtol)')
    else
      call check_below(worst_samples, 1.0_wp, label // ' batch vs one case: stored samples (max rel. diff, in units ' // &
                       'of ' // trim(merge('100 rtol ', 'round-off', adaptive)) // ')')
    end if
    call check_below(worst_end_time, 1.0_wp, label // ' batch vs one case: end time (in units of ' // &
                     trim(merge('100 rtol', '1e-12 s ', adaptive)) // ')')
    if (.not. adaptive) then
      ! A case that stops at no_fit or at the rim has its largest forces at the
      ! stop, where the model turns singular: at no_fit det L = (R - r1)(R - r2)
      ! ~ 1e-6 R^2 (fit_margin) and n' ~ 1/det L, so the reaction amplifies the
      ! round-off difference of the two paths' states (1e-14, above) by about
      ! R^2 / det L = 1e6; at the rim n_z -> 0 and the friction needed grows
      ! without bound. There the force maxima (normal, horizontal, friction) are
      ! checked at that conditioning. With DOP853 the step control itself
      ! meets that singularity (its error estimate is round-off there), so
      ! such a case is held to its status and end time only.
      call check_below(worst_at_limit, 1.0e-6_wp, &
                       label // ' batch vs one case, cases ending at no_fit or rim: force maxima (max rel. diff)')
    end if
    if (present(designed_ends)) then
      call check(all(batch%status == designed_ends), label // ': the cases end as designed')
    else
      call check(count(batch%status == status_rim) == 1 .and. count(batch%status == status_no_fit) == 1 &
                      .and. count(batch%status == status_slip) == 1 .and. count(batch%status == status_completed) == 5, &
                      label // ': the cases end as designed (5 completed, rim, no_fit, slip)')
    end if

    ! lanes are independent: reversed order, and each case alone in a batch
    order = [(n_cases + 1 - l, l = 1, n_cases)]
    ! (a named copy: gfortran leaks the allocatable components, a record's
    ! samples, of the temporary an actual argument cases(order) makes)
    reversed = cases(order)
    call simulate_batch(reversed, plan, reordered)
    lane_independent = .true.
    do l = 1, n_cases
      lane_independent = lane_independent .and. identical(reordered(n_cases + 1 - l), batch(l))
      call simulate_batch(cases(l:l), plan, alone)
      lane_independent = lane_independent .and. identical(alone(1), batch(l))
    end do
    call check(lane_independent, label // ' batch: a result does not depend on its lane or its neighbours (bitwise)')
  end subroutine compare_paths

  !> Moving cups in lanes: the cups' accelerations of the lanes against
  !> base_acceleration's at random times (harmonic lanes to the vector
  !> sine's few units of round-off, record lanes, whose cursors move back
  !> and forth, bitwise); one state's right-hand side and observation
  !> against the one-case path's (8 eps); then every batchable method's
  !> batch of harmonic and record cases, with a fixed cup among them,
  !> against the one-case path as compare_paths does (the same bounds as
  !> for fixed cups), and the fixed cup's lane bitwise as in a batch of
  !> fixed cups.
  subroutine moving_cups()
    type(case_t) :: cases(n_cases), fixed(n_cases), reference_cases(n_cases)
    type(case_result_t) :: mixed(n_cases), fixed_results(n_cases), reference(n_cases)
    type(error_t) :: err
    type(rolling_ball_t) :: ball(lanes)
    type(ball_lanes_t) :: balls
    type(excitation_lanes_t) :: cups
    type(lane_outputs_t) :: out
    type(observation_t) :: obs
    real(wp) :: t(lanes), base(lanes, 3), u(lanes), y(lanes, state_size), f_lanes(lanes, state_size)
    real(wp) :: y_lane(state_size), f_lane(state_size), exact(3), harmonic_worst, record_worst, rhs_worst, observe_worst
    integer :: designed(n_cases), l, j, row, seed_size
    call random_seed(size=seed_size)
    call random_seed(put=[(2024 + 7 * l, l = 1, seed_size)])
    cases = moving_cases()
    harmonic_worst = 0
    record_worst = 0
    do l = 1, lanes
      ball(l) = make_ball(cases(l))
      call set_lane(balls, l, ball(l))
      call cups%set(l, ball(l)%excitation)
    end do
    do j = 1, 400                      ! times forwards and back, before and past the records
      call random_number(u)
      t = 5 * u - 0.5_wp
      if (j > 200) t = 0.5_wp + 1.0e-3_wp * j + 1.0e-4_wp * u   ! close to the last ones
      call cups%at(t, base)
      do l = 1, lanes
        exact = base_acceleration(ball(l)%excitation, t(l))
        if (ball(l)%excitation%kind == excitation_harmonic) then
          harmonic_worst = max(harmonic_worst, maxval(abs(base(l, :) - exact)) / maxval(abs(ball(l)%excitation%amplitude)))
        else
          record_worst = max(record_worst, maxval(abs(base(l, :) - exact)))
        end if
      end do
    end do
    call check_below(harmonic_worst / epsilon(1.0_wp), 8.0_wp, &
                     'moving cups: harmonic lanes'' a_base vs base_acceleration (eps of the amplitude)')
    call check(.not. record_worst > 0, 'moving cups: record lanes'' a_base equals base_acceleration''s (bitwise)')
    ! one state each, the stages' times random
    rhs_worst = 0
    observe_worst = 0
    call random_number(u)
    t = 3 * u
    call cups%at(t, base)
    do l = 1, lanes
      call random_number(y_lane)
      y(l, :) = initial_state(ball(l), cases(l)%param(p_x), cases(l)%param(p_y), cases(l)%param(p_omega_x:p_omega_z))
      y(l, 1:2) = y(l, 1:2) + 0.2_wp * (y_lane(1:2) - 0.5_wp)
      y(l, 4:6) = y(l, 4:6) + 4 * (y_lane(4:6) - 0.5_wp)
    end do
    call lanes_derivative(balls, y, f_lanes, base=base)
    call lanes_observe(balls, y, f_lanes, out, base)
    do l = 1, lanes
      y_lane = y(l, :)
      call ball_derivative(ball(l), t(l), y_lane, f_lane)
      rhs_worst = max(rhs_worst, maxval(abs(f_lanes(l, :) - f_lane)) / maxval(abs(f_lane)))
      call observe(ball(l), t(l), y_lane, f_lane, obs)
      observe_worst = max(observe_worst, maxval(abs(out%reaction(l, :) - obs%reaction)) / norm2(obs%reaction), &
                          maxval(abs(out%center_acceleration(l, :) - obs%center_acceleration)) / &
                          norm2(obs%center_acceleration), abs(out%quantity(l, q_energy) - obs%energy) / abs(obs%energy))
    end do
    call check_below(rhs_worst / epsilon(1.0_wp), 8.0_wp, 'moving cups, one state: batch vs one case, right-hand side (eps)')
    call check_below(observe_worst / epsilon(1.0_wp), 8.0_wp, &
                     'moving cups, one state: batch vs one case, reaction, centre acceleration, energy (eps)')

    designed = status_completed
    designed(6) = status_liftoff
    do row = 1, size(methods)
      if (.not. methods(row)%batches) cycle
      cases = moving_cases()
      cases%method = methods(row)%name
      if (methods(row)%adaptive) then
        do l = 1, n_cases
          cases(l)%param(p_rtol) = 10.0_wp**(-6 - l / 2)
          cases(l)%param(p_atol) = cases(l)%param(p_rtol) * 1.0e-3_wp
        end do
      end if
      if (methods(row)%adaptive) then
        do l = 1, n_cases
          reference_cases(l) = cases(l)
          reference_cases(l)%method = 'vern9'
          reference_cases(l)%param(p_rtol) = 1.0e-13_wp
          reference_cases(l)%param(p_atol) = 1.0e-16_wp
          call simulate_case(reference_cases(l), plan, reference(l), err)
        end do
        call compare_paths(cases, trim(methods(row)%name) // ', moving cups', designed, reference)
      else
        call compare_paths(cases, trim(methods(row)%name) // ', moving cups', designed)
      end if
      ! the fixed cup (lane 1) computes in a batch of moving cups bitwise what
      ! it computes in a batch of fixed cups
      call simulate_batch(cases, plan, mixed)
      fixed = cases(1)
      fixed(1)%param(p_omega_z) = 40
      call simulate_batch(fixed, plan, fixed_results)
      call check(identical(mixed(1), fixed_results(2)), trim(methods(row)%name) // &
                 ': a fixed cup in a batch of moving cups, bitwise as in a batch of fixed cups')
    end do
  end subroutine moving_cups

  !> Rolling resistance in lanes (rk4; a batch of cases that roll to rest
  !> through rest events, that are held at their start, that settle past
  !> t_end on a fixed cup and after a record, on a harmonic cup, and one
  !> without resistance): against the one-case path as compare_paths does
  !> (the same bounds: each lane's mode per step and its rest events, the
  !> step through an event taken with the one-case code, give the same
  !> steps), a result independent of its lane and neighbours (bitwise);
  !> and the rest figures (when and where the ball came to rest, the
  !> couple's work) to round-off of the one-case path's.
  subroutine rolling_resistance_lanes()
    type(case_t) :: cases(n_cases)
    type(case_result_t) :: single(n_cases), batch(n_cases)
    type(error_t) :: err
    integer :: designed(n_cases), l
    real(wp) :: worst_rest, worst_work
    logical :: same_rest
    cases = resisting_cases()
    designed = status_completed
    call compare_paths(cases, 'rk4, rolling resistance', designed)
    call simulate_batch(cases, plan, batch)
    same_rest = .true.
    worst_rest = 0
    worst_work = 0
    do l = 1, n_cases
      call simulate_case(cases(l), plan, single(l), err)
      same_rest = same_rest .and. single(l)%counts(fig_at_rest) == batch(l)%counts(fig_at_rest)
      if (batch(l)%counts(fig_at_rest) == 1) worst_rest = max(worst_rest, &
          abs(single(l)%reals(fig_rest_time) - batch(l)%reals(fig_rest_time)), &
          abs(single(l)%reals(fig_residual_displacement) - batch(l)%reals(fig_residual_displacement)))
      worst_work = max(worst_work, abs(single(l)%reals(fig_rolling_resistance_energy) - &
                       batch(l)%reals(fig_rolling_resistance_energy)) / &
                       max(abs(single(l)%reals(fig_rolling_resistance_energy)), tiny(1.0_wp)))
    end do
    call check(count(batch%counts(fig_at_rest) == 1) == 5 .and. same_rest, &
               'rolling resistance batch: the same 5 cases end at rest as on the one-case path')
    call check_below(worst_rest, 1.0e-12_wp, &
                     'rolling resistance batch vs one case: rest time (s) and residual displacement (m)')
    call check_below(worst_work, 1.0e-12_wp, 'rolling resistance batch vs one case: the couple''s work (rel.)')
  end subroutine rolling_resistance_lanes

  !> Cases with rolling resistance for one batch (rolling_resistance_lanes).
  function resisting_cases() result(cs)
    type(case_t) :: cs(n_cases)
    integer, parameter :: n_record = 201
    real(wp) :: times(n_record), values(3, n_record)
    integer :: k
    logical :: held
    cs = paper_case(1.0e-3_wp, 3.0_wp)
    cs%param(p_rolling_resistance) = 2.0e-3_wp
    cs(1)%param(p_omega_x:p_omega_z) = [-2.0_wp, 2.0_wp, 0.0_wp]           ! rolls, turns, stops
    cs(1)%param(p_rolling_resistance) = 1.0e-2_wp
    cs(2)%param(p_x) = 0.15_wp; cs(2)%param(p_omega_x:p_omega_z) = 0       ! released off the bottom
    cs(2)%param(p_rolling_resistance) = 5.0e-3_wp
    cs(3)%param(p_rolling_resistance) = 1.0e-4_wp                            ! spins on
    cs(4)%param(p_x) = 0.01_wp; cs(4)%param(p_omega_x:p_omega_z) = 0       ! held where it starts
    cs(4)%param(p_rolling_resistance) = 1.0e-2_wp
    cs(5)%param(p_dt) = 2.0e-3_wp; cs(5)%t_end = 2.0_wp                     ! another step and length
    cs(5)%param(p_x) = -0.1_wp; cs(5)%param(p_y) = 0.05_wp; cs(5)%param(p_omega_x:p_omega_z) = 0
    cs(5)%param(p_settle) = 5                                               ! on past t_end until at rest
    do k = 1, n_record                                                      ! a record that ends at rest
      times(k) = (k - 1) * 0.01_wp
      values(:, k) = [1.5_wp * sin(5.0_wp * times(k)), 0.8_wp * sin(3.0_wp * times(k)), 0.0_wp] &
                     * merge(1.0_wp, 0.0_wp, k < n_record)
    end do
    call set_record(cs(6)%excitation, times, values, held)
    if (.not. held) error stop 'no room for the records'
    cs(6)%param(p_settle) = 5
    cs(6)%param(p_rolling_resistance) = 1.0e-2_wp
    cs(6)%t_end = 1.0_wp
    cs(7)%excitation%kind = excitation_harmonic                              ! a harmonic cup
    cs(7)%param(p_excitation_frequency) = 0.8_wp
    cs(7)%param(p_excitation_amplitude_x) = 0.6_wp
    cs(7)%param(p_excitation_amplitude_y) = 0.3_wp
    cs(7)%param(p_omega_x:p_omega_z) = [1.0_wp, 1.0_wp, 5.0_wp]
    cs(8)%param(p_rolling_resistance) = 0                                    ! none among them
  end function resisting_cases

  !> Harmonic cups (other frequencies, phases, amplitudes, one lifting the
  !> ball off), cups following an even and an uneven record at two
  !> scales, and a fixed cup: one batch.
  function moving_cases() result(cs)
    type(case_t) :: cs(n_cases)
    integer, parameter :: n_even = 401, n_uneven = 300
    real(wp) :: times(n_even), values(3, n_even), uneven(n_uneven), jitter(n_uneven)
    integer :: k
    logical :: held
    cs = paper_case(1.0e-3_wp, 3.0_wp)
    do k = 1, 5
      cs(k)%excitation%kind = excitation_harmonic
      cs(k)%param(p_excitation_frequency) = 0.4_wp + 0.3_wp * k
      cs(k)%param(p_excitation_phase) = 0.7_wp * k
      cs(k)%param(p_excitation_amplitude_x) = 0.3_wp * k
      cs(k)%param(p_excitation_amplitude_y) = 0.2_wp * (3 - k)
      cs(k)%param(p_excitation_amplitude_z) = 0.5_wp
    end do
    cs(2)%param(p_omega_x:p_omega_z) = [1.0_wp, -3.0_wp, 45.0_wp]
    cs(3)%param(p_dt) = 2.0e-3_wp; cs(3)%t_end = 2.0_wp                 ! another step and length
    cs(4)%param(p_a) = 0.8_wp; cs(4)%param(p_b) = 0.5_wp; cs(4)%param(p_c) = 0.3_wp
    cs(4)%param(p_x) = 0.05_wp; cs(4)%param(p_y) = -0.03_wp
    cs(5)%param(p_excitation_amplitude_z) = -3.0_wp
    cs(6) = cs(1)                                                     ! the cup drops faster than g
    cs(6)%param(p_excitation_amplitude_z) = 12.0_wp
    cs(6)%param(p_excitation_frequency) = 2.0_wp
    do k = 1, n_even
      times(k) = (k - 1) * 0.01_wp
      values(:, k) = [0.8_wp * sin(3.1_wp * times(k)) + 0.3_wp * cos(17.0_wp * times(k)), &
                      0.5_wp * cos(2.3_wp * times(k)), 0.2_wp * sin(9.0_wp * times(k))]
    end do
    call random_number(jitter)
    uneven = [(0.0135_wp * (k - 1) + 0.006_wp * jitter(k), k = 1, n_uneven)]
    uneven(1) = 0
    call set_record(cs(7)%excitation, times, values, held)
    cs(7)%param(p_scale) = 1.5_wp
    call set_record(cs(8)%excitation, uneven, values(:, :n_uneven), held)
    if (.not. held) error stop 'no room for the records'
    cs(8)%param(p_scale) = 0.7_wp
    cs(8)%param(p_omega_x:p_omega_z) = [2.0_wp, 1.0_wp, 30.0_wp]
    cs(1)%excitation%kind = excitation_none                            ! a fixed cup among them
    cs(1)%param(p_excitation_amplitude_x:p_excitation_amplitude_z) = 0
  end function moving_cases

  function make_cases() result(cs)
    type(case_t) :: cs(n_cases)
    cs = paper_case(1.0e-3_wp, 3.0_wp)
    cs(2)%param(p_omega_x:p_omega_z) = [1.0_wp, -3.0_wp, 45.0_wp]                 ! faster spin
    cs(3)%param(p_a) = 0.8_wp; cs(3)%param(p_b) = 0.5_wp; cs(3)%param(p_c) = 0.3_wp       ! another cup
    cs(3)%param(p_x) = 0.05_wp; cs(3)%param(p_y) = -0.03_wp
    cs(4)%param(p_dt) = 2.0e-3_wp; cs(4)%t_end = 2.0_wp                 ! another step and length
    cs(5)%param(p_radius) = 0.05_wp; cs(5)%param(p_mass) = 100 / 9.81_wp         ! reaches the rim
    cs(5)%param(p_omega_x:p_omega_z) = [-29.05_wp, 0.0_wp, 0.0_wp]
    cs(6)%param(p_radius) = 0.7_wp; cs(6)%param(p_mass) = 100 / 9.81_wp          ! stops fitting the cup
    cs(6)%param(p_omega_x:p_omega_z) = [-1.0_wp, 0.0_wp, 0.0_wp]
    cs(7)%param(p_mu) = 0.085_wp                                        ! slips
    cs(8)%param(p_inertia_factor) = 2.0_wp / 3; cs(8)%param(p_g) = 3.71_wp       ! hollow ball on Mars
  end function make_cases

  !> The summary figures; round-off-sized ones (drift, residual) + 1, so
  !> that they compare in absolute terms; NaN (no nutation period) as 0.
  function figures(a) result(x)
    type(case_result_t), intent(in) :: a
    real(wp) :: x(11)
    x = [a%t_final, a%reals(fig_theta_max), a%reals(fig_reaction_normal_max), a%reals(fig_friction_needed_max), &
        a%reals(fig_energy_drift) + 1, &
         a%reals(fig_constraint_error_max) + 1, a%reals(fig_nutation_period), figure_values(a, &
             fig_linear_periods), a%reals(fig_displacement_max), &
         a%reals(fig_horizontal_force_max)]
    where (ieee_is_nan(x)) x = 0
  end function figures

  real(wp) function sample_difference(a, b)
    type(case_result_t), intent(in) :: a, b
    integer :: f
    sample_difference = 0
    do f = 1, field_count
      if (.not. allocated(a%fields(f)%values)) cycle
      associate (u => a%fields(f)%values, v => b%fields(f)%values)
        if (any(ieee_is_nan(u) .neqv. ieee_is_nan(v))) then
          sample_difference = huge(1.0_wp)       ! NaN in one only
        else
          sample_difference = max(sample_difference, &
              maxval(abs(u - v), mask=.not. ieee_is_nan(u)) / &
              max(maxval(abs(v), mask=.not. ieee_is_nan(v)), tiny(1.0_wp)))
        end if
      end associate
    end do
  end function sample_difference

  logical function identical(a, b)
    type(case_result_t), intent(in) :: a, b
    integer :: f
    identical = a%status == b%status .and. a%n_steps == b%n_steps .and. a%n_rejected == b%n_rejected .and. &
        same(a%t_final, b%t_final) .and. same(a%reals(fig_theta_max), b%reals(fig_theta_max)) .and. &
        same(a%reals(fig_energy_drift), b%reals(fig_energy_drift)) .and. same(a%reals(fig_friction_needed_max), &
            b%reals(fig_friction_needed_max)) .and. &
        same(a%reals(fig_displacement_max), &
            b%reals(fig_displacement_max)) .and. same(a%reals(fig_nutation_period), b%reals(fig_nutation_period))
    do f = 1, field_count
      if (allocated(a%fields(f)%values)) identical = identical .and. &
          all(transfer(a%fields(f)%values, 1_i8, size(a%fields(f)%values)) == &
              transfer(b%fields(f)%values, 1_i8, size(b%fields(f)%values)))
    end do
  end function identical

  logical function same(x, y)
    real(wp), intent(in) :: x, y
    same = transfer(x, 1_i8) == transfer(y, 1_i8)
  end function same
end program test_batch
