!> The parameter table: every real input that a case holds, one row each,
!> with its namelist group and variable, unit, valid range, default, whether
!> a sweep or a sample may vary it, and a one-line description. It drives
!> the namelist defaults, the range checks and their messages, the names a
!> sweep may use, where a case holds the input (case_t%param, at its row),
!> the datasets of /case with their units, long names and input names, and
!> `ellroll inputs` (docs/inputs.md). Adding such an input is a row here,
!> its named index below, and its use in the model (make_ball).
module ellroll_params
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp, i8
  implicit none
  private

  public :: param_t, params, param_count, param_index, param_default, param_component, param_width, &
            param_unset_allowed, param_dataset, param_dataset_description, dataset_inputs, &
            param_datasets

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
  !> The default of an input that may be left unset: the case then holds NaN there.
  real(wp), parameter :: none = transfer(9221120237041090560_i8, 1.0_wp)

  !> A vector's rows follow one another, named NAME_x, NAME_y, NAME_z and
  !> described 'LONG NAME, x ...': /case holds them as one dataset NAME, (ncase, 3), long name LONG NAME.
  type(param_t), parameter :: params(*) = [ &
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
      param_t('mu', 'ball', 'mu', '1', least, 1.0e6_wp, .true., .false., none, .true., &
              'friction coefficient (NaN: not limited)'), &
      ! (below 1e-3 a point mass, whose spin answers the friction
      ! 1 / inertia_factor times as fast as its centre: docs/model.md)
      param_t('inertia_factor', 'ball', 'inertia_factor', '1', 1.0e-3_wp, 2.0_wp / 3, .false., .false., 0.4_wp, .true., &
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
      param_t('velocity_x', 'initial', 'velocity', 'm/s', -1.0e6_wp, 1.0e6_wp, .false., .false., none, .true., &
              'initial velocity of the centre, x (unset: a rolling start)'), &
      param_t('velocity_y', 'initial', 'velocity', 'm/s', -1.0e6_wp, 1.0e6_wp, .false., .false., none, .true., &
              'initial velocity of the centre, y (unset: a rolling start)'), &
      param_t('velocity_z', 'initial', 'velocity', 'm/s', -1.0e6_wp, 1.0e6_wp, .false., .false., none, .true., &
              'initial velocity of the centre, z (unset: a rolling start)'), &
      param_t('dt', 'integration', 'dt', 's', least, 1.0e9_wp, .true., .true., 0.0_wp, .true., &
              'integration step'), &
      param_t('fit_margin', 'integration', 'fit_margin', '1', 0.0_wp, 0.5_wp, .false., .false., 1.0e-6_wp, .true., &
              'case ends when r_min / R - 1 falls to this'), &
      param_t('rtol', 'integration', 'rtol', '1', 1.0e-14_wp, 0.1_wp, .false., .false., 1.0e-9_wp, .true., &
              'relative tolerance (adaptive method)'), &
      param_t('atol', 'integration', 'atol', '1', 0.0_wp, 1.0_wp, .false., .false., 1.0e-12_wp, .true., &
              'absolute tolerance (adaptive method)'), &
      param_t('settle', 'integration', 'settle', 's', 0.0_wp, 1.0e9_wp, .false., .false., 0.0_wp, .true., &
              'past t_end, on until the ball is at rest, at most this long'), &
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
              .true., 'delta: a couple delta N opposes the rolling'), &
      param_t('capacity', 'output', 'capacity', 'm', least, length_max, .true., .false., none, .true., &
              'displacement capacity of time_beyond_capacity (unset: NaN)')]

  integer, parameter :: param_count = size(params)
  !> The datasets of /case that hold rows (a vector's rows in one).
  integer, parameter :: param_datasets = param_count - count(params(2:)%variable == params(:param_count - 1)%variable)
  ! Each row's named index, found by its name (0 if misspelt: the Debug build's bounds checks stop at
  ! its first use).
  integer, parameter, public :: p_a = findloc(params%name, 'a', dim=1), p_b = findloc(params%name, 'b', dim=1), &
      p_c = findloc(params%name, 'c', dim=1)
  integer, parameter, public :: p_radius = findloc(params%name, 'radius', dim=1)
  integer, parameter, public :: p_weight = findloc(params%name, 'weight', dim=1)
  integer, parameter, public :: p_mass = findloc(params%name, 'mass', dim=1)
  integer, parameter, public :: p_mu = findloc(params%name, 'mu', dim=1)
  integer, parameter, public :: p_inertia_factor = findloc(params%name, 'inertia_factor', dim=1)
  integer, parameter, public :: p_g = findloc(params%name, 'g', dim=1)
  integer, parameter, public :: p_x = findloc(params%name, 'x', dim=1), p_y = findloc(params%name, 'y', dim=1)
  integer, parameter, public :: p_omega_x = findloc(params%name, 'omega_x', dim=1), &
      p_omega_y = findloc(params%name, 'omega_y', dim=1), p_omega_z = findloc(params%name, 'omega_z', dim=1)
  integer, parameter, public :: p_velocity_x = findloc(params%name, 'velocity_x', dim=1), &
      p_velocity_z = findloc(params%name, 'velocity_z', dim=1)
  integer, parameter, public :: p_dt = findloc(params%name, 'dt', dim=1)
  integer, parameter, public :: p_fit_margin = findloc(params%name, 'fit_margin', dim=1)
  integer, parameter, public :: p_rtol = findloc(params%name, 'rtol', dim=1)
  integer, parameter, public :: p_atol = findloc(params%name, 'atol', dim=1)
  integer, parameter, public :: p_settle = findloc(params%name, 'settle', dim=1)
  integer, parameter, public :: p_excitation_frequency = findloc(params%name, 'excitation_frequency', dim=1)
  integer, parameter, public :: p_excitation_phase = findloc(params%name, 'excitation_phase', dim=1)
  integer, parameter, public :: p_excitation_amplitude_x = findloc(params%name, 'excitation_amplitude_x', dim=1), &
      p_excitation_amplitude_y = findloc(params%name, 'excitation_amplitude_y', dim=1), &
      p_excitation_amplitude_z = findloc(params%name, 'excitation_amplitude_z', dim=1)
  integer, parameter, public :: p_scale = findloc(params%name, 'scale', dim=1)
  integer, parameter, public :: p_rolling_resistance = findloc(params%name, 'rolling_resistance', dim=1)
  integer, parameter, public :: p_capacity = findloc(params%name, 'capacity', dim=1)

contains

  !> The row named `name`, or 0.
  pure integer function param_index(name)
    character(len=*), intent(in) :: name
    param_index = findloc(params%name, name, dim=1)
  end function param_index

  !> What a namelist variable holds before the input sets it: the row's
  !> default, or NaN for a required input (its absence is then found) and
  !> for one that may be left unset (param_unset_allowed).
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

  !> Whether row p's input may be left unset: its default is none (NaN),
  !> and a case without it holds NaN there.
  pure logical function param_unset_allowed(p)
    integer, intent(in) :: p
    param_unset_allowed = .not. params(p)%required .and. ieee_is_nan(params(p)%default)
  end function param_unset_allowed

  !> The /case dataset of row p: its name, or a vector's (its name without
  !> the component's '_x').
  pure function param_dataset(p) result(name)
    integer, intent(in) :: p
    character(len=len(params%name)) :: name
    name = params(p)%name
    if (param_width(p) > 1) name = name(:index(name, '_', back=.true.) - 1)
  end function param_dataset

  !> The long name of row p's /case dataset: its description, or a
  !> vector's (its description up to the component's ', x').
  pure function param_dataset_description(p) result(text)
    integer, intent(in) :: p
    character(len=len(params%description)) :: text
    text = params(p)%description
    if (param_width(p) > 1) text = text(:index(text, ',', back=.true.) - 1)
  end function param_dataset_description

  !> The names of the inputs /case/`dataset` holds, one per component, as a
  !> sweep names them (blank: a dataset of no row).
  pure function dataset_inputs(dataset) result(names)
    character(len=*), intent(in) :: dataset
    character(len=3 * (len(params%name) + 1)) :: names
    integer :: p
    names = ''
    do p = 1, param_count
      if (param_dataset(p) == dataset) names = trim(names) // ' ' // params(p)%name
    end do
    names = adjustl(names)
  end function dataset_inputs
end module ellroll_params
