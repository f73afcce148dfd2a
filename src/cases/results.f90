!> What integrating one case produced: the sampled trajectories of the fields
!> the run asked for, and the per-case summary.
module ellroll_results
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: named_value_t, real_value, int_value, vector_value
  use ellroll_status, only: status_pending
  use ellroll_cases, only: field_count, field_ncomp
  implicit none
  private

  public :: field_buffer_t, case_result_t, summary_record, set_summary_value, allocate_fields, fill_unrecorded

  !> A NaN for default initialisation (0/0 is not a constant expression).
  real(wp), parameter :: nan_value = transfer(9221120237041090560_i8, 1.0_wp)

  type :: field_buffer_t
    real(wp), allocatable :: values(:, :)    !< (ncomp, n_samples); NaN after the case ended
  end type field_buffer_t

  !> A case's result. Every figure is NaN until the integration sets it: a
  !> case never run (invalid, or pending) holds no number that could pass
  !> for data.
  type :: case_result_t
    integer :: status = status_pending
    real(wp) :: t_final = nan_value
    integer(i8) :: n_steps = 0
    integer(i8) :: n_rejected = 0
    integer(i8) :: n_rhs = 0
    real(wp) :: wall_time = nan_value
    real(wp) :: theta_max = nan_value
    real(wp) :: reaction_normal_max = nan_value
    real(wp) :: friction_needed_max = nan_value
    real(wp) :: energy_drift = nan_value
    real(wp) :: constraint_error_max = nan_value
    real(wp) :: nutation_period = nan_value      !< mean interval between maxima of Theta; NaN if < 3 maxima
    integer(i8) :: nutation_maxima = 0
    real(wp) :: error_contact = nan_value    !< with error_estimate: max |contact - reference|, m
    real(wp) :: error_theta = nan_value      !< max |Theta - reference|, rad
    real(wp) :: error_energy = nan_value     !< max |E - E_reference| / |E0|
    integer(i8) :: n_rhs_reference = 0
    real(wp) :: linear_periods(2) = nan_value  !< small-oscillation periods about the bottom, s
    real(wp) :: displacement_max = nan_value           !< largest |C - (0, 0, R)|, m (cup frame)
    real(wp) :: displacement_max_time = nan_value
    real(wp) :: residual_displacement = nan_value      !< |C horizontal| at t_final, m
    real(wp) :: horizontal_force_max = nan_value       !< largest horizontal force on the ball, N
    real(wp) :: absolute_acceleration_max = nan_value  !< horizontal_force_max / m, m/s^2
    real(wp) :: absolute_acceleration_max_time = nan_value
    real(wp) :: transmissibility = nan_value   !< harmonic: |a_C,abs| / |a_base| at the forcing frequency
    type(field_buffer_t) :: fields(field_count)
    integer(i8) :: n_recorded = 0              !< output samples recorded so far (they come in order)
  end type case_result_t

contains

  !> Buffers in res for the wanted fields only (in place: a function result
  !> would copy every buffer once more); fill_unrecorded makes what the case
  !> did not reach NaN, so that no sample is written twice.
  pure subroutine allocate_fields(res, wanted, n_samples)
    type(case_result_t), intent(inout) :: res
    logical, intent(in) :: wanted(field_count)
    integer(i8), intent(in) :: n_samples
    integer :: f
    do f = 1, field_count
      if (allocated(res%fields(f)%values)) deallocate (res%fields(f)%values)
      if (wanted(f)) then
        allocate (res%fields(f)%values(field_ncomp(f), n_samples))
      end if
    end do
    res%n_recorded = 0
  end subroutine allocate_fields

  !> NaN in every output sample after the last one recorded (the case ended
  !> before it).
  pure subroutine fill_unrecorded(res)
    type(case_result_t), intent(inout) :: res
    integer :: f
    do f = 1, field_count
      if (allocated(res%fields(f)%values)) &
        res%fields(f)%values(:, res%n_recorded + 1:) = ieee_value(0.0_wp, ieee_quiet_nan)
    end do
  end subroutine fill_unrecorded

  !> The per-case summary as stored under /summary/ (status is written apart).
  pure function summary_record(res) result(rec)
    type(case_result_t), intent(in) :: res
    type(named_value_t) :: rec(24)
    rec = [ &
      real_value('t_final', 's', 'time at which the case ended', res%t_final), &
      int_value('n_steps', '1', 'integration steps taken', res%n_steps), &
      int_value('n_rejected', '1', 'attempts rejected by the step control (adaptive methods)', res%n_rejected), &
      int_value('n_rhs', '1', 'right-hand side evaluations', res%n_rhs), &
      real_value('wall_time', 's', 'wall-clock time of the integration (not reproducible)', res%wall_time), &
      real_value('theta_max', 'rad', &
                 'largest nutation angle (at step ends; adaptive methods: located on the dense output)', res%theta_max), &
      real_value('reaction_normal_max', 'N', 'largest normal force over all steps', res%reaction_normal_max), &
      real_value('friction_needed_max', '1', 'largest |F_t|/N over all steps', res%friction_needed_max), &
      real_value('energy_drift', '1', 'max |E - E0| / |E0| over all steps', res%energy_drift), &
      real_value('constraint_error_max', '1', &
                 'max |(x/a)^2+(y/b)^2+((z-c)/c)^2-1| of the contact point over all steps', &
                 res%constraint_error_max), &
      real_value('nutation_period', 's', 'mean interval between successive maxima of Theta (NaN if < 3)', &
                 res%nutation_period), &
      int_value('nutation_maxima', '1', 'number of maxima of Theta', res%nutation_maxima), &
      real_value('error_contact', 'm', 'max distance of the contact point from the reference run (NaN: none)', &
                 res%error_contact), &
      real_value('error_theta', 'rad', 'max |Theta - Theta of the reference run| (NaN: none)', res%error_theta), &
      real_value('error_energy', '1', 'max |E - E of the reference run| / |E0| (NaN: none)', res%error_energy), &
      int_value('n_rhs_reference', '1', 'right-hand side evaluations of the reference run', &
                res%n_rhs_reference), &
      vector_value('linear_periods', 's', &
                   'small-oscillation periods about the bottom spinning at omega0 . n0 (linearised)', &
                   res%linear_periods), &
      real_value('displacement_max', 'm', &
                 "largest horizontal distance of the centre from the cup's lowest point (cup frame, step ends)", &
                 res%displacement_max), &
      real_value('displacement_max_time', 's', 'time of displacement_max', res%displacement_max_time), &
      real_value('residual_displacement', 'm', &
                 "horizontal distance of the centre from the cup's lowest point at t_final", &
                 res%residual_displacement), &
      real_value('horizontal_force_max', 'N', 'largest horizontal force of the cup on the ball (step ends)', &
                 res%horizontal_force_max), &
      real_value('absolute_acceleration_max', 'm/s^2', &
                 'largest horizontal absolute acceleration of the centre, |horizontal reaction| / m', &
                 res%absolute_acceleration_max), &
      real_value('absolute_acceleration_max_time', 's', 'time of absolute_acceleration_max', &
                 res%absolute_acceleration_max_time), &
      real_value('transmissibility', '1', &
                 'harmonic: horizontal |a_C,absolute| / |a_base| at the forcing frequency, last whole periods (NaN: n/a)', &
                 res%transmissibility) ]
  end function summary_record

  !> The inverse of summary_record for one entry (reading a stored summary back).
  pure subroutine set_summary_value(res, value)
    type(case_result_t), intent(inout) :: res
    type(named_value_t), intent(in) :: value
    select case (trim(value%name))
    case ('t_final'); res%t_final = value%reals(1)
    case ('n_steps'); res%n_steps = value%int
    case ('n_rejected'); res%n_rejected = value%int
    case ('n_rhs'); res%n_rhs = value%int
    case ('wall_time'); res%wall_time = value%reals(1)
    case ('theta_max'); res%theta_max = value%reals(1)
    case ('reaction_normal_max'); res%reaction_normal_max = value%reals(1)
    case ('friction_needed_max'); res%friction_needed_max = value%reals(1)
    case ('energy_drift'); res%energy_drift = value%reals(1)
    case ('constraint_error_max'); res%constraint_error_max = value%reals(1)
    case ('nutation_period'); res%nutation_period = value%reals(1)
    case ('nutation_maxima'); res%nutation_maxima = value%int
    case ('error_contact'); res%error_contact = value%reals(1)
    case ('error_theta'); res%error_theta = value%reals(1)
    case ('error_energy'); res%error_energy = value%reals(1)
    case ('n_rhs_reference'); res%n_rhs_reference = value%int
    case ('linear_periods'); res%linear_periods = value%reals(1:2)
    case ('displacement_max'); res%displacement_max = value%reals(1)
    case ('displacement_max_time'); res%displacement_max_time = value%reals(1)
    case ('residual_displacement'); res%residual_displacement = value%reals(1)
    case ('horizontal_force_max'); res%horizontal_force_max = value%reals(1)
    case ('absolute_acceleration_max'); res%absolute_acceleration_max = value%reals(1)
    case ('absolute_acceleration_max_time'); res%absolute_acceleration_max_time = value%reals(1)
    case ('transmissibility'); res%transmissibility = value%reals(1)
    end select
  end subroutine set_summary_value
end module ellroll_results
