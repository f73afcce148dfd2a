!> The parameter table: every real input that a case holds, one row each,
!> with its namelist group and variable, unit, valid range, default, whether
!> a sweep or a sample may vary it, and a one-line description. It drives
!> the namelist defaults, the range checks and their messages, the names a
!> sweep may use, the units and long names of /case, and `ellroll inputs`
!> (docs/inputs.md). Adding such an input is a row here, a named index
!> below, its place in case_t (get/set in ellroll_cases) and its use in
!> the model.
module ellroll_params
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: param_t, params, param_count, param_index, param_default, param_component, param_width
  public :: p_a, p_b, p_c, p_radius, p_weight, p_mass, p_mu, p_inertia_factor, p_g, p_x, p_y, &
            p_omega_x, p_omega_y, p_omega_z, p_dt, p_fit_margin, p_rtol, p_atol, &
            p_excitation_frequency, p_excitation_phase, p_excitation_amplitude_x, &
            p_excitation_amplitude_y, p_excitation_amplitude_z, p_scale, p_rolling_resistance

  type :: param_t
    character(len=22) :: name            !< as a sweep or a sample names it
    character(len=11) :: group           !< its namelist group
    character(len=20) :: variable        !< its namelist variable (a vector's, for a component)
    character(len=5) :: unit             !< '1': dimensionless
    real(wp) :: low, high                !< valid range
    logical :: positive                  !< low is the least positive number: the range is (0, high]
    logical :: required                  !< no default: the input must give it (weight and mass: one of them)
    real(wp) :: default                  !< unless required
    logical :: sweepable                 !< a sweep or a sample may vary it
    character(len=64) :: description
  end type param_t

  ! Bounds keep every derived quantity finite (squares, products, s^4).
  real(wp), parameter :: length_max = 1.0e6_wp, length_min = 1.0e-6_wp
  real(wp), parameter :: least = tiny(1.0_wp)

  integer, parameter :: p_a = 1, p_b = 2, p_c = 3, p_radius = 4, p_weight = 5, p_mass = 6, p_mu = 7, &
      p_inertia_factor = 8, p_g = 9, p_x = 10, p_y = 11, p_omega_x = 12, p_omega_y = 13, p_omega_z = 14, &
      p_dt = 15, p_fit_margin = 16, p_rtol = 17, p_atol = 18, p_excitation_frequency = 19, &
      p_excitation_phase = 20, p_excitation_amplitude_x = 21, p_excitation_amplitude_y = 22, &
      p_excitation_amplitude_z = 23, p_scale = 24, p_rolling_resistance = 25
  integer, parameter :: param_count = 25

  type(param_t), parameter :: params(param_count) = [ &
      param_t('a', 'geometry', 'a', 'm', length_min, length_max, .false., .true., 0.0_wp, .true., &
              'semi-axis of the cup along x'), &
      param_t('b', 'geometry', 'b', 'm', length_min, length_max, .false., .true., 0.0_wp, .true., &
              'semi-axis of the cup along y'), &
      param_t('c', 'geometry', 'c', 'm', length_min, length_max, .false., .true., 0.0_wp, .true., &
              'semi-axis of the cup along z (cup depth)'), &
      param_t('radius', 'ball', 'radius', 'm', length_min, length_max, .false., .true., 0.0_wp, .true., &
              'ball radius R'), &
      param_t('weight', 'ball', 'weight', 'N', least, 1.0e12_wp, .true., .true., 0.0_wp, .true., &
              'ball weight m g'), &
      param_t('mass', 'ball', 'mass', 'kg', least, 1.0e12_wp, .true., .true., 0.0_wp, .true., &
              'ball mass m'), &
      param_t('mu', 'ball', 'mu', '1', 0.0_wp, 1.0e6_wp, .false., .false., 0.0_wp, .true., &
              'friction coefficient (NaN: not limited)'), &
      param_t('inertia_factor', 'ball', 'inertia_factor', '1', least, 2.0_wp / 3, .true., .false., 0.4_wp, .true., &
              'J / (m R^2); 0.4 for a homogeneous ball'), &
      param_t('g', 'environment', 'g', 'm/s^2', 0.0_wp, 1.0e4_wp, .false., .false., 9.81_wp, .true., &
              'gravitational acceleration'), &
      param_t('x', 'initial', 'x', 'm', -length_max, length_max, .false., .false., 0.0_wp, .true., &
              'initial contact point x'), &
      param_t('y', 'initial', 'y', 'm', -length_max, length_max, .false., .false., 0.0_wp, .true., &
              'initial contact point y'), &
      param_t('omega_x', 'initial', 'omega', 'rad/s', -1.0e6_wp, 1.0e6_wp, .false., .true., 0.0_wp, .true., &
              'initial angular velocity, x component'), &
      param_t('omega_y', 'initial', 'omega', 'rad/s', -1.0e6_wp, 1.0e6_wp, .false., .true., 0.0_wp, .true., &
              'initial angular velocity, y component'), &
      param_t('omega_z', 'initial', 'omega', 'rad/s', -1.0e6_wp, 1.0e6_wp, .false., .true., 0.0_wp, .true., &
              'initial angular velocity, z component'), &
      param_t('dt', 'integration', 'dt', 's', least, 1.0e9_wp, .true., .true., 0.0_wp, .true., &
              'integration step'), &
      param_t('fit_margin', 'integration', 'fit_margin', '1', 0.0_wp, 0.5_wp, .false., .false., 1.0e-6_wp, .true., &
              'case ends when r_min / R - 1 falls to this'), &
      param_t('rtol', 'integration', 'rtol', '1', 1.0e-14_wp, 0.1_wp, .false., .false., 1.0e-9_wp, .true., &
              'relative tolerance (adaptive method)'), &
      param_t('atol', 'integration', 'atol', '1', 0.0_wp, 1.0_wp, .false., .false., 1.0e-12_wp, .true., &
              'absolute tolerance (adaptive method)'), &
      param_t('excitation_frequency', 'excitation', 'frequency', 'Hz', 0.0_wp, 1.0e6_wp, .false., .false., 0.0_wp, &
              .true., 'harmonic: frequency'), &
      param_t('excitation_phase', 'excitation', 'phase', 'rad', -1.0e3_wp, 1.0e3_wp, .false., .false., 0.0_wp, &
              .true., 'harmonic: phase'), &
      param_t('excitation_amplitude_x', 'excitation', 'amplitude', 'm/s^2', -1.0e4_wp, 1.0e4_wp, .false., .false., &
              0.0_wp, .true., 'harmonic: amplitude of the cup acceleration, x'), &
      param_t('excitation_amplitude_y', 'excitation', 'amplitude', 'm/s^2', -1.0e4_wp, 1.0e4_wp, .false., .false., &
              0.0_wp, .true., 'harmonic: amplitude of the cup acceleration, y'), &
      param_t('excitation_amplitude_z', 'excitation', 'amplitude', 'm/s^2', -1.0e4_wp, 1.0e4_wp, .false., .false., &
              0.0_wp, .true., 'harmonic: amplitude of the cup acceleration, z'), &
      param_t('scale', 'excitation', 'scale', '1', 0.0_wp, 1.0e3_wp, .false., .false., 1.0_wp, .true., &
              'record: factor on the ground acceleration'), &
      param_t('rolling_resistance', 'ball', 'rolling_resistance', 'm', 0.0_wp, 0.1_wp, .false., .false., 0.0_wp, &
              .true., 'delta: a couple delta N opposes the rolling')]

contains

  !> The row named `name`, or 0.
  pure integer function param_index(name)
    character(len=*), intent(in) :: name
    param_index = findloc(params%name, name, dim=1)
  end function param_index

  !> What a namelist variable holds before the input sets it: the row's
  !> default, or NaN for a required input (its absence is then found).
  pure real(wp) function param_default(p)
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
    integer, intent(in) :: p
    param_default = params(p)%default
    if (params(p)%required) param_default = ieee_value(1.0_wp, ieee_quiet_nan)
  end function param_default

  !> Which component of its namelist variable row p is (1, 2, 3 for a
  !> vector's, as omega_x, omega_y, omega_z), or 0 for a scalar.
  pure integer function param_component(p)
    integer, intent(in) :: p
    param_component = 0
    if (param_width(p) > 1) &
      param_component = p - findloc(params%variable, params(p)%variable, dim=1) + 1
  end function param_component

  !> How many rows row p's namelist variable sets: 1 for a scalar, 3 for a
  !> vector.
  pure integer function param_width(p)
    integer, intent(in) :: p
    param_width = count(params%variable == params(p)%variable)
  end function param_width
end module ellroll_params
