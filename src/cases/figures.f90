!> The summary table: every figure of /summary, one row each, in the order of
!> the file: its name, unit and long name, whether it is a real number or a
!> count, its components (two: one per oscillation mode), and how it is made.
!> It drives where case_result_t keeps the figure, summary_record (the
!> writer's /summary, its units and long names, the reader, the journal's
!> record, merge, resume and `ellroll summary`) and the accumulation of the
!> figures made from the step ends (ellroll_running, the same code for one
!> case and for a batch's lanes). Adding a figure of a step-end quantity is
!> a row here; a figure the integration makes itself (`from_run`) is set
!> where it is computed, at its row of case_result_t (its named index).
module ellroll_figures
  use ellroll_records, only: kind_real, kind_int
  use ellroll_params, only: p_capacity
  use ellroll_quantities, only: quantity_count, q_displacement, q_horizontal_force_scaled, q_reaction_normal, &
      q_friction_needed, q_energy, q_surface_residual
  implicit none
  private

  integer :: k        ! (of implied loops in constant expressions)


  public :: figure_t, figures, figure_count, real_slots, figure_slots, timed, lasting, beyond

  !> How a figure is made.
  integer, parameter, public :: &
      from_counter = 1, &      !< an integration counter, a component of case_result_t (t_final, n_steps, ...)
      from_run = 2, &          !< set by the code that computes it, at its row of case_result_t
      from_maximum = 3, &      !< the largest value of a step-end quantity (of its change, for a changing one)
      from_maximum_time = 4, & !< the time of that largest value
      from_last = 5, &         !< the quantity at the last step end
      from_time_beyond = 6     !< the time it exceeds the input `threshold`, crossings
                               !< located by linear interpolation between step ends, or the pairs' dense output
                               !< (NaN where the input is unset)
  !> What is done to the accumulated value at the end of the case.
  integer, parameter, public :: finish_none = 0, &
      finish_force = 1, &         !< times 2^exponent(m), m the ball's mass: a force in units of it in N
      finish_per_mass = 2, &      !< divided by fraction(m) = m / 2^exponent(m): that force per unit mass
      finish_per_start = 3        !< divided by |the quantity at t = 0| (NaN where it is 0 or the quotient overflows)

  type :: figure_t
    character(len=30) :: name
    character(len=5) :: unit              !< '1': dimensionless
    character(len=112) :: long_name
    integer :: kind                       !< kind_real or kind_int (a count)
    integer :: ncomp                      !< 1, or 2: one per oscillation mode
    integer :: source                     !< from_counter, from_run, from_maximum, ...
    integer :: quantity = 0               !< the step-end quantity accumulated (ellroll_quantities)
    integer :: finish = finish_none
    integer :: threshold = 0              !< from_time_beyond: the input (parameter table row) it is measured against
  end type figure_t

  type(figure_t), parameter :: figures(*) = [ &
      figure_t('t_final', 's', 'time at which the case ended', kind_real, 1, from_counter), &
      figure_t('n_steps', '1', 'integration steps taken', kind_int, 1, from_counter), &
      figure_t('n_rejected', '1', 'attempts rejected by the step control (adaptive methods)', kind_int, 1, &
               from_counter), &
      figure_t('n_rhs', '1', 'right-hand side evaluations', kind_int, 1, from_counter), &
      figure_t('wall_time', 's', 'wall-clock time of the integration (not reproducible)', kind_real, 1, from_counter), &
      figure_t('theta_max', 'rad', &
               'largest nutation angle (fixed steps: by a parabola through 3 step ends; adaptive: on the dense ' // &
               'output)', kind_real, 1, &
               from_run), &
      figure_t('reaction_normal_max', 'N', 'largest normal force over all steps', kind_real, 1, from_maximum, &
               q_reaction_normal), &
      figure_t('friction_needed_max', '1', 'largest |F_t|/N over all steps (NaN: N = 0 at the start)', kind_real, 1, &
               from_maximum, q_friction_needed), &
      figure_t('energy_drift', '1', 'max |E - E0 + W| / |E0| over the step ends, W the works of ' // &
               'friction and rolling resistance so far', kind_real, 1, from_maximum, q_energy, &
               finish_per_start), &
      figure_t('constraint_error_max', '1', 'max |(x/a)^2+(y/b)^2+((z-c)/c)^2-1| of the contact point over all steps', &
               kind_real, 1, from_maximum, q_surface_residual), &
      figure_t('nutation_period', 's', 'mean interval between successive maxima of Theta (NaN if < 3)', kind_real, 1, &
               from_run), &
      figure_t('nutation_maxima', '1', 'number of maxima of Theta', kind_int, 1, from_run), &
      figure_t('error_contact', 'm', 'max distance of the contact point from the reference run (NaN: none)', &
               kind_real, 1, from_run), &
      figure_t('error_theta', 'rad', 'max |Theta - Theta of the reference run| (NaN: none)', kind_real, 1, from_run), &
      figure_t('error_energy', '1', 'max |E - E of the reference run| / |E0| (NaN: none)', kind_real, 1, from_run), &
      figure_t('n_rhs_reference', '1', 'right-hand side evaluations of the reference run (-1: none)', kind_int, 1, &
               from_run), &
      figure_t('linear_periods', 's', &
               'small-oscillation periods about the bottom of the cup at rest, spinning at omega0 . n0 (linearised)', &
               kind_real, 2, &
               from_run), &
      figure_t('displacement_max', 'm', &
               "largest horizontal distance of the centre from the cup's lowest point (cup frame; dop853/vern9: inside steps)", &
               kind_real, 1, from_maximum, q_displacement), &
      figure_t('displacement_max_time', 's', 'time of displacement_max', kind_real, 1, from_maximum_time, &
               q_displacement), &
      figure_t('residual_displacement', 'm', &
               "horizontal distance of the centre from the cup's lowest point where it came to rest (NaN: not at rest)", &
               kind_real, 1, from_run), &
      figure_t('rest_time', 's', 'time the ball came to rest for good: at rest from then to t_final, the excitation ' // &
               'over (NaN: not)', kind_real, 1, from_run), &
      figure_t('at_rest', '1', '1: at rest for good at t_final (rest_time), 0: moving, or no rolling resistance, ' // &
               'or the cup still moves', kind_int, 1, from_run), &
      figure_t('horizontal_force_max', 'N', 'largest horizontal force of the cup on the ball (dop853/vern9: inside steps)', &
               kind_real, 1, from_maximum, q_horizontal_force_scaled, finish_force), &
      figure_t('absolute_acceleration_max', 'm/s^2', &
               'largest horizontal absolute acceleration of the centre, |horizontal reaction| / m', kind_real, 1, &
               from_maximum, q_horizontal_force_scaled, finish_per_mass), &
      figure_t('absolute_acceleration_max_time', 's', 'time of absolute_acceleration_max', kind_real, 1, &
               from_maximum_time, q_horizontal_force_scaled), &
      figure_t('transmissibility', '1', 'harmonic: horizontal |a_C,absolute| / |a_base| at the forcing frequency, ' // &
               'free modes fitted out (NaN: n/a)', kind_real, 1, from_run), &
      figure_t('time_beyond_capacity', 's', &
               "time the centre's horizontal distance from the cup's lowest point exceeds capacity (NaN: unset)", &
               kind_real, 1, from_time_beyond, q_displacement, threshold=p_capacity), &
      figure_t('peaks_truncated', '1', '1: a model limit ended the case, its peaks are over its path ' // &
               'clear of its singular approach', kind_int, 1, from_run), &
      figure_t('sa_linear_periods', 'm/s^2', 'record: 5 %-damped pseudo-spectral acceleration (RotD100) of the ' // &
               'scaled record at linear_periods (NaN: none)', kind_real, 2, from_run), &
      figure_t('sliding_time', 's', "time the ball slid (slip = 'slide'; 0: it rolled throughout)", kind_real, 1, &
               from_run), &
      figure_t('slip_episodes', '1', 'times the ball began to slide', kind_int, 1, from_run), &
      figure_t('friction_energy', 'J', 'energy the sliding friction dissipated, integral of mu N |u| dt', kind_real, &
               1, from_run), &
      figure_t('slip_speed_max', 'm/s', 'largest slip speed |u| of the contact point (step ends)', kind_real, 1, &
               from_run), &
      figure_t('rolling_resistance_energy', 'J', 'energy the rolling resistance dissipated, integral of ' // &
               'delta N |omega_t| dt', kind_real, 1, from_run)]
  integer, parameter :: figure_count = size(figures)

  ! Each row's named index, found by its name (0 if misspelt: the Debug
  ! build's bounds checks stop at its first use).
  integer, parameter, public :: fig_t_final = findloc(figures%name, 't_final', dim=1), &
      fig_n_steps = findloc(figures%name, 'n_steps', dim=1), &
      fig_n_rejected = findloc(figures%name, 'n_rejected', dim=1), &
      fig_n_rhs = findloc(figures%name, 'n_rhs', dim=1), &
      fig_wall_time = findloc(figures%name, 'wall_time', dim=1), &
      fig_theta_max = findloc(figures%name, 'theta_max', dim=1), &
      fig_nutation_period = findloc(figures%name, 'nutation_period', dim=1), &
      fig_nutation_maxima = findloc(figures%name, 'nutation_maxima', dim=1), &
      fig_error_contact = findloc(figures%name, 'error_contact', dim=1), &
      fig_error_theta = findloc(figures%name, 'error_theta', dim=1), &
      fig_error_energy = findloc(figures%name, 'error_energy', dim=1), &
      fig_n_rhs_reference = findloc(figures%name, 'n_rhs_reference', dim=1), &
      fig_linear_periods = findloc(figures%name, 'linear_periods', dim=1), &
      fig_transmissibility = findloc(figures%name, 'transmissibility', dim=1), &
      fig_residual_displacement = findloc(figures%name, 'residual_displacement', dim=1), &
      fig_rest_time = findloc(figures%name, 'rest_time', dim=1), &
      fig_at_rest = findloc(figures%name, 'at_rest', dim=1), &
      fig_time_beyond_capacity = findloc(figures%name, 'time_beyond_capacity', dim=1), &
      fig_sa_linear_periods = findloc(figures%name, 'sa_linear_periods', dim=1), &
      fig_peaks_truncated = findloc(figures%name, 'peaks_truncated', dim=1), &
      fig_sliding_time = findloc(figures%name, 'sliding_time', dim=1), &
      fig_slip_episodes = findloc(figures%name, 'slip_episodes', dim=1), &
      fig_friction_energy = findloc(figures%name, 'friction_energy', dim=1), &
      fig_slip_speed_max = findloc(figures%name, 'slip_speed_max', dim=1), &
      fig_rolling_resistance_energy = findloc(figures%name, 'rolling_resistance_energy', dim=1)
  ! the accumulated figures that the tests name
  integer, parameter, public :: fig_reaction_normal_max = findloc(figures%name, 'reaction_normal_max', dim=1), &
      fig_friction_needed_max = findloc(figures%name, 'friction_needed_max', dim=1), &
      fig_energy_drift = findloc(figures%name, 'energy_drift', dim=1), &
      fig_constraint_error_max = findloc(figures%name, 'constraint_error_max', dim=1), &
      fig_displacement_max = findloc(figures%name, 'displacement_max', dim=1), &
      fig_horizontal_force_max = findloc(figures%name, 'horizontal_force_max', dim=1)

  !> Which statistics the figures take of each quantity (its largest value,
  !> or its change's, is always kept): the running state updates only these.
  logical, parameter :: timed(quantity_count) = [(any(figures%source == from_maximum_time .and. figures%quantity == k), &
                                                  k = 1, quantity_count)]
  logical, parameter :: lasting(quantity_count) = [(any(figures%source == from_last .and. figures%quantity == k), &
                                                    k = 1, quantity_count)]
  logical, parameter :: beyond(quantity_count) = [(any(figures%source == from_time_beyond .and. &
                                                       figures%quantity == k), k = 1, quantity_count)]
  !> case_result_t's real slots: one per row (a real figure at its row), and
  !> the further components of the per-mode figures after them.
  integer, parameter :: real_slots = figure_count + sum(figures%ncomp - 1)

  ! The table checked as it compiles (a false check divides by zero in a
  ! constant expression): every row has a known source, finish and kind;
  ! a step-end figure names a quantity, a made one none; a time beyond
  ! names its input, at most one per quantity.
  logical, parameter :: table_valid = all(figures%source >= from_counter .and. figures%source <= from_time_beyond) &
      .and. all(figures%finish >= finish_none .and. figures%finish <= finish_per_start) &
      .and. all(figures%kind == kind_real .or. figures%kind == kind_int) &
      .and. all((figures%source >= from_maximum) .eqv. (figures%quantity >= 1 .and. figures%quantity <= quantity_count)) &
      .and. all((figures%source == from_time_beyond) .eqv. (figures%threshold > 0)) &
      .and. all([(count(figures%source == from_time_beyond .and. figures%quantity == k) <= 1, k = 1, quantity_count)])
  integer, parameter :: table_check = 1 / merge(1, 0, table_valid)

contains

  !> The slots of case_result_t%reals that hold row k's components.
  pure function figure_slots(k) result(slots)
    integer, intent(in) :: k
    integer :: slots(figures(k)%ncomp)
    integer :: c
    slots(1) = k
    do c = 2, figures(k)%ncomp
      slots(c) = figure_count + sum(figures(:k - 1)%ncomp - 1) + c - 1
    end do
  end function figure_slots
end module ellroll_figures
