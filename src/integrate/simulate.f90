!> Integrate one case from t = 0 to t_end (or to the model limit it meets),
!> sampling the requested fields every output interval: fixed-step methods
!> sample their own steps; the adaptive method samples its dense output.
!> With error_estimate, the case is run again with the reference method
!> (vern9) at a tight tolerance and the differences are its error figures. The one entry
!> point of the integration room: it passes on the batches (ellroll_batch_run).
module ellroll_simulate
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_status, only: status_completed, status_slip, status_liftoff
  use ellroll_cases, only: case_t, output_plan_t, field_count, field_contact, field_nutation, field_energy
  use ellroll_results, only: case_result_t
  use ellroll_figures, only: fig_error_contact, fig_error_theta, fig_error_energy, fig_n_rhs_reference
  use ellroll_rolling_ball, only: state_size
  use ellroll_integrators, only: integrator_t, embedded_pair_t, new_integrator
  use ellroll_case_run, only: run_state_t, start_case, finish_case
  use ellroll_fixed_step_run, only: fixed_step_loop
  use ellroll_adaptive_run, only: adaptive_loop
  use ellroll_slide_run, only: slide_loop
  use ellroll_flow_to_limit, only: reference_method, reference_rtol, reference_atol
  use ellroll_batch_run, only: lanes, batchable, lane_result_stands, simulate_batch
  use ellroll_params, only: p_atol, p_dt, p_rtol, p_settle
  implicit none
  private

  public :: simulate_case, simulate_batch, batchable, lane_result_stands, lanes

contains

  !> One case, with its reference run when it asks for error figures.
  subroutine simulate_case(cs, plan, res, err)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: res
    type(error_t), intent(inout) :: err
    type(output_plan_t) :: own_plan
    type(case_t) :: reference_case
    type(case_result_t) :: reference
    integer :: f
    if (.not. cs%error_estimate) then
      call integrate(cs, plan, res, err)
      return
    end if
    ! the error figures need these fields from both runs, stored or not
    own_plan = plan
    own_plan%fields([field_contact, field_nutation, field_energy]) = .true.
    call integrate(cs, own_plan, res, err)
    reference_case = cs
    reference_case%method = reference_method
    reference_case%param(p_rtol) = reference_rtol
    reference_case%param(p_atol) = reference_atol
    reference_case%param(p_dt) = cs%t_end
    reference_case%param(p_settle) = 0       ! the error figures compare the samples, all up to t_end
    call integrate(reference_case, own_plan, reference, err)
    res%reals(fig_error_contact) = max_difference(res%fields(field_contact)%values, &
                                                  reference%fields(field_contact)%values)
    res%reals(fig_error_theta) = max_difference(res%fields(field_nutation)%values, &
                                                reference%fields(field_nutation)%values)
    ! relative to E0, as energy_drift: NaN where E0 = 0 (at rest, no gravity)
    associate (error_energy => res%reals(fig_error_energy), energy0 => reference%fields(field_energy)%values(1, 1))
      error_energy = max_difference(res%fields(field_energy)%values, reference%fields(field_energy)%values)
      if (error_energy / huge(1.0_wp) < abs(energy0)) then
        error_energy = error_energy / abs(energy0)
      else
        error_energy = ieee_value(0.0_wp, ieee_quiet_nan)
      end if
    end associate
    res%counts(fig_n_rhs_reference) = reference%n_rhs
    do f = 1, field_count
      if (.not. plan%fields(f) .and. allocated(res%fields(f)%values)) deallocate (res%fields(f)%values)
    end do
  contains
    !> Largest distance between two sampled fields where both are defined.
    real(wp) function max_difference(a, b)
      real(wp), intent(in) :: a(:, :), b(:, :)
      integer :: j
      max_difference = 0
      do j = 1, size(a, 2)
        if (all(ieee_is_finite(a(:, j))) .and. all(ieee_is_finite(b(:, j)))) &
          max_difference = max(max_difference, norm2(a(:, j) - b(:, j)))
      end do
    end function max_difference
  end subroutine simulate_case

  !> One case with its own method, timed (res%wall_time).
  subroutine integrate(cs, plan, res, err)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(out) :: res
    type(error_t), intent(inout) :: err
    class(integrator_t), allocatable :: integrator
    type(run_state_t) :: run
    real(wp) :: y(state_size), f(state_size)
    integer(i8) :: clock_start, clock_end, clock_rate

    call system_clock(clock_start, clock_rate)
    call new_integrator(trim(cs%method), integrator, err)
    if (err%failed()) return
    call start_case(cs, plan, run, res, y, f)
    ! a start that may slide: whether it slips or lifts off is the slide loop's
    ! to say (a given velocity of the centre changes both)
    if (cs%slide .and. any(res%status == [status_completed, status_slip, status_liftoff])) then
      select type (integrator)
      class is (embedded_pair_t)
        integrator%rtol = cs%param(p_rtol)
        integrator%atol = cs%param(p_atol)
      end select
      call slide_loop(integrator, cs, plan, run, y, f, res)
    else if (res%status == status_completed) then
      select type (integrator)
      class is (embedded_pair_t)
        integrator%rtol = cs%param(p_rtol)
        integrator%atol = cs%param(p_atol)
        call adaptive_loop(integrator, cs, plan, run, y, f, res)
      class default
        call fixed_step_loop(integrator, cs, plan, run, y, f, res)
      end select
    end if
    call finish_case(cs, run, res)
    call system_clock(clock_end)
    res%wall_time = real(clock_end - clock_start, wp) / real(clock_rate, wp)
  end subroutine integrate
end module ellroll_simulate
