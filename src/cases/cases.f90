!> One fully resolved case, the table of its scalar parameters (the names a
!> sweep or a sample may vary, with their groups, units and bounds), the
!> checks every case must pass, and the output plan shared by all cases.
module ellroll_cases
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite, ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero
  use ellroll_params, only: params, param_count, param_component, param_width, param_unset_allowed, param_dataset, &
      param_dataset_description, param_datasets, p_a, p_b, p_c, p_radius, p_weight, p_mass, p_mu, &
          p_inertia_factor, p_g, p_x, p_y, &
      p_omega_x, p_omega_z, p_dt, p_fit_margin, p_excitation_frequency, p_excitation_phase, &
      p_excitation_amplitude_x, p_excitation_amplitude_z, p_scale, p_rolling_resistance, p_settle, &
      p_velocity_x, p_velocity_z
  use ellroll_records, only: named_value_t, real_value, vector_value, int_value, text_value
  use ellroll_strings, only: format_real, format_computed
  use ellroll_ellipsoid, only: new_ellipsoid, principal_radii, normal_from_contact
  use ellroll_rolling_ball, only: rolling_ball_t
  use ellroll_excitation, only: excitation_t, excitation_kind_names, excitation_record
  use ellroll_intensity, only: record_intensity_t, damping_ratio
  use ellroll_limit_states, only: limit_state_t
  use ellroll_integrators, only: method_info_t, method_info
  implicit none
  private

  public :: case_t, output_plan_t, steps_per_sample, case_record, make_ball, check_case, case_problem, &
            finalize_case, adaptive_method, is_multiple, range_text, out_of_range_reason, problem_setting, max_steps
  public :: get_param, set_param
  public :: field_count, field_names, field_units, field_ncomp, field_descriptions
  public :: field_contact, field_center, field_omega, field_normal, field_nutation, &
            field_reaction, field_energy, field_base_acceleration, field_regime, field_slip_speed

  !> A case: every input of the parameter table at its row (param(p_radius),
  !> ...; the row's default until the input sets it), and the others.
  type :: case_t
    integer(i8) :: index = 0
    !> weight: 0 when the mass was given directly; mass: weight / g when the
    !> weight was given (finalize_case); mu: 0, no friction limit
    real(wp) :: param(param_count) = params%default
    character(len=32) :: method = 'rk4'
    real(wp) :: t_end = 0
    logical :: error_estimate = .false.   !< also run the reference and store error figures
    logical :: slide = .false.            !< &ball slip = 'slide': the ball slides where rolling needs more than mu
    !> the cup's motion: its kind and a record's samples (the harmonic's
    !> amplitude, frequency and phase and the record's scale are rows of
    !> param, which make_ball puts in)
    type(excitation_t) :: excitation
    character(len=32) :: record_name = '' !< a suite's record (&record name)
    real(wp) :: record_factor = 1         !< its factor (in excitation%values)
    !> the record's intensity measures (its factor in, the scale not: /case
    !> stores them times the scale); unset without a record
    type(record_intensity_t) :: intensity
    !> the user's limit states (&limit_state), stored per case in /limit_state
    type(limit_state_t), allocatable :: limit_states(:)
  end type case_t

  ! what find_problem found: one code a message of check_case
  integer, parameter :: problem_not_finite = 1, problem_range = 2, problem_weight_without_g = 3, &
      problem_weight_mass = 4, problem_dt_above_t_end = 5, problem_too_many_steps = 6, problem_interval = 7, &
      problem_outside = 8, problem_no_fit = 9, problem_slide_mu = 10, problem_velocity_rolls = 11, &
      problem_velocity_tangent = 12, problem_velocity_partial = 13, problem_slide_resistance = 14

  ! A case's steps (t_end / dt) are counted in 64-bit integers and would take
  ! days at a million steps per second.
  real(wp), parameter :: max_steps = 1.0e12_wp   !< also the most samples a case stores
  !> An initial velocity is tangent where |v . n| <= this times |v|: a test
  !> of its direction, so relative to the speed (an absolute bound would
  !> pass any direction at a small speed and fail rounding at a large
  !> one). The sliding start takes vx and vy and the contact sets vz, so a
  !> vz farther off would run another start than the one written; a vz
  !> computed in double precision (the message gives it) is within 1e-15.
  real(wp), parameter, public :: tangent_tolerance = 1.0e-9_wp

  integer, parameter :: field_count = 10
  integer, parameter :: field_contact = 1, field_center = 2, field_omega = 3, field_normal = 4, &
                        field_nutation = 5, field_reaction = 6, field_energy = 7, field_base_acceleration = 8, &
                        field_regime = 9, field_slip_speed = 10
  character(len=*), parameter :: field_names(field_count) = [character(len=17) :: &
      'contact', 'center', 'omega', 'normal', 'nutation', 'reaction', 'energy', 'base_acceleration', &
      'regime', 'slip_speed']
  character(len=*), parameter :: field_units(field_count) = [character(len=5) :: &
      'm', 'm', 'rad/s', '1', 'rad', 'N', 'J', 'm/s^2', '1', 'm/s']
  integer, parameter :: field_ncomp(field_count) = [3, 3, 3, 3, 1, 3, 1, 3, 1, 1]
  character(len=*), parameter :: field_descriptions(field_count) = [character(len=80) :: &
      'contact point A of the ball on the cup', &
      'centre C of the ball', &
      'angular velocity of the ball (fixed frame)', &
      'unit normal at A, pointing from A to C', &
      'nutation angle Theta between the normal and the vertical', &
      'force of the cup on the ball at A (normal force plus friction)', &
      'total energy J|w|^2/2 + m|V_C|^2/2 + m g z_C, z from the cup bottom (cup frame)', &
      'acceleration of the cup (inertial frame)', &
      'regime at the sample: 0 rolling, 1 sliding', &
      'slip speed |u| of the ball at A on the cup (0 while rolling)']

  !> What a run writes: shared by all its cases.
  type :: output_plan_t
    character(len=:), allocatable :: file
    real(wp) :: interval = 0
    integer(i8) :: n_samples = 0
    logical :: fields(field_count) = .true.
    integer :: compression = 0          !< deflate level of the trajectories, 0 (none) to 9
  contains
    procedure :: times => output_times
    procedure :: case_bytes => trajectory_bytes
  end type output_plan_t

contains

  !> The output times (/time): n_samples of them, `interval` apart from 0.
  pure function output_times(plan) result(times)
    class(output_plan_t), intent(in) :: plan
    real(wp) :: times(plan%n_samples)
    integer(i8) :: i
    times = [(real(i, wp) * plan%interval, i = 0, plan%n_samples - 1)]
  end function output_times

  !> The bytes of one case's stored trajectories, uncompressed.
  pure real(wp) function trajectory_bytes(plan)
    class(output_plan_t), intent(in) :: plan
    trajectory_bytes = 8 * real(plan%n_samples, wp) * sum(field_ncomp, mask=plan%fields)
  end function trajectory_bytes

  pure real(wp) function get_param(cs, p) result(value)
    type(case_t), intent(in) :: cs
    integer, intent(in) :: p                 !< a row of the parameter table
    value = cs%param(p)
  end function get_param

  pure subroutine set_param(cs, p, value)
    type(case_t), intent(inout) :: cs
    integer, intent(in) :: p                 !< a row of the parameter table
    real(wp), intent(in) :: value
    cs%param(p) = value
  end subroutine set_param

  !> A fixed-step case's steps between output samples: its own dt, which a
  !> sweep may vary (check_case holds the interval to a whole number of them).
  pure integer(i8) function steps_per_sample(cs, plan)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    steps_per_sample = max(1_i8, nint(plan%interval / cs%param(p_dt), i8))
  end function steps_per_sample

  !> Derive what follows from the given values (the mass from a weight).
  pure subroutine finalize_case(cs)
    type(case_t), intent(inout) :: cs
    ! tested before it is used: NaN, or a quotient beyond any valid mass,
    ! would trap here, before check_case names the input
    associate (weight => cs%param(p_weight), g => cs%param(p_g), mass => cs%param(p_mass))
      if (.not. (ieee_is_finite(weight) .and. ieee_is_finite(g))) return
      if (weight <= 0) return
      mass = 0
      if (g > 0 .and. weight / params(p_mass)%high <= g) mass = weight / g
    end associate
  end subroutine finalize_case

  !> The first problem of a case, as the parameter it concerns and why;
  !> param = 0 when the case is valid. Checks every bound, that the start
  !> lies inside the cup, that the ball fits there, and that dt divides the
  !> output interval. Not for parallel loops: its message is built with
  !> functions of deferred-length result, whose length gfortran keeps in one
  !> static variable of the caller (case_problem is for those).
  subroutine check_case(cs, interval, param, reason)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: interval
    integer, intent(out) :: param
    character(len=:), allocatable, intent(out) :: reason
    real(wp) :: value, level, radii(2)
    integer :: problem
    call find_problem(cs, interval, param, problem)
    reason = ''
    if (param == 0) return
    value = get_param(cs, param)
    select case (problem)
    case (problem_not_finite)
      reason = 'must be a finite number'
    case (problem_range)
      call out_of_range_reason(param, value, reason)
    case (problem_weight_without_g)
      reason = 'a weight cannot give the mass when g = 0; give mass instead'
    case (problem_weight_mass)
      reason = 'gives a mass weight / g above ' // format_real(params(p_mass)%high) // ' kg with g = ' // &
               format_real(cs%param(p_g)) // ' m/s^2; give mass instead'
    case (problem_dt_above_t_end)
      reason = 'must not exceed t_end = ' // format_real(cs%t_end) // ' s'
    case (problem_too_many_steps)
      if (cs%param(p_settle) > 0) then
        reason = 'must be at least (t_end + settle) / ' // format_real(max_steps) // ' = ' // &
                 format_computed((cs%t_end + cs%param(p_settle)) / max_steps) // ' s: no case takes more than ' // &
                 format_real(max_steps) // ' steps'
      else
        reason = 'must be at least t_end / ' // format_real(max_steps) // ' = ' // &
                 format_computed(cs%t_end / max_steps) // ' s: no case takes more than ' // format_real(max_steps) // ' steps'
      end if
    case (problem_interval)
      reason = 'the output interval ' // format_real(interval) // ' s must be a whole number of steps'
    case (problem_outside)
      level = start_level(cs)
      reason = 'the start (x, y) = (' // format_real(cs%param(p_x)) // ', ' // format_real(cs%param(p_y)) // &
               ') is not inside the cup: (x/a)^2 + (y/b)^2 = ' // format_computed(level) // ' must be < 1'
    case (problem_no_fit)
      radii = start_radii(cs)
      reason = 'the ball does not fit the cup at the start: the principal radii of curvature there are ' // &
               format_computed(radii(1)) // ' m and ' // format_computed(radii(2)) // &
               ' m, and radius must be below ' // format_computed(radii(1)) // ' m'
      if (cs%param(p_fit_margin) > 0) reason = reason // ' / (1 + fit_margin) = ' // &
          format_computed(radii(1) / (1 + cs%param(p_fit_margin))) // ' m'
    case (problem_slide_mu)
      reason = "slip = 'slide' needs a friction coefficient mu > 0"
    case (problem_slide_resistance)
      reason = "with slip = 'slide' must be below mu radius = " // format_computed(cs%param(p_mu) * cs%param(p_radius)) // &
               ' m: a couple of rolling resistance as large as the greatest of the friction (mu N radius) stops ' // &
               'the rolling of a sliding ball and holds it, a motion the sliding model does not follow'
    case (problem_velocity_partial)
      reason = 'the initial velocity needs all three components (vx, vy, vz in m/s)'
    case (problem_velocity_rolls)
      reason = "an initial velocity starts the ball sliding: it needs &ball slip = 'slide'"
    case (problem_velocity_tangent)
      reason = 'must be tangent to the cup at the start (|v . n| <= ' // format_real(tangent_tolerance) // &
               ' |v|): its component along the normal n there is ' // format_real(start_normal_velocity(cs)) // &
               ' m/s; with these vx, vy the tangent velocity has vz = ' // format_real(tangent_vz(cs)) // ' m/s'
    end select
  end subroutine check_case

  !> The parameter of a case's first problem (check_case), 0 when it is
  !> valid: without the message, so that a parallel loop may call it.
  pure integer function case_problem(cs, interval) result(param)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: interval
    integer :: problem
    call find_problem(cs, interval, param, problem)
  end function case_problem

  !> The checks of check_case, in its order: the parameter and which check
  !> failed (param = 0: none).
  pure subroutine find_problem(cs, interval, param, problem)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: interval
    integer, intent(out) :: param, problem
    real(wp) :: value, level, radii(2)
    integer :: k
    do k = 1, param_count
      param = k
      value = cs%param(k)
      problem = problem_not_finite
      if (ieee_is_nan(value) .and. param_unset_allowed(k)) cycle
      if (.not. ieee_is_finite(value)) return
      if (k == p_weight .and. is_zero(value)) cycle     ! mass given instead
      if (k == p_mass .and. cs%param(p_weight) > 0) cycle
      problem = problem_range
      if (value < params(k)%low .or. value > params(k)%high) return
    end do
    param = p_weight
    problem = problem_weight_without_g
    if (cs%param(p_weight) > 0 .and. cs%param(p_g) <= 0) return
    problem = problem_weight_mass
    if (cs%param(p_weight) > 0 .and. .not. cs%param(p_mass) > 0) return
    param = p_dt
    problem = problem_dt_above_t_end
    if (cs%param(p_dt) > cs%t_end) return
    problem = problem_too_many_steps
    if (cs%t_end + cs%param(p_settle) > max_steps * cs%param(p_dt)) return      ! (not t_end / dt: it may overflow)
    problem = problem_interval
    if (.not. adaptive_method(cs%method) .and. .not. is_multiple(interval, cs%param(p_dt))) return
    level = start_level(cs)
    param = merge(p_x, p_y, .not. is_zero(cs%param(p_x)))
    problem = problem_outside
    if (level >= 1) return
    radii = start_radii(cs)
    param = p_radius
    problem = problem_no_fit
    if (radii(1) / cs%param(p_radius) - 1 <= cs%param(p_fit_margin)) return
    param = p_mu
    problem = problem_slide_mu
    if (cs%slide .and. ieee_is_nan(cs%param(p_mu))) return        ! (a given mu is > 0: checked above)
    param = p_rolling_resistance
    problem = problem_slide_resistance
    if (cs%slide) then        ! (nested: no ordered comparison with an unset mu, NaN, which traps)
      if (cs%param(p_rolling_resistance) > 0 .and. &
          cs%param(p_rolling_resistance) >= cs%param(p_mu) * cs%param(p_radius)) return
    end if
    param = p_velocity_x
    problem = problem_velocity_partial
    if (any(ieee_is_nan(cs%param(p_velocity_x:p_velocity_z))) .and. &
        .not. all(ieee_is_nan(cs%param(p_velocity_x:p_velocity_z)))) return
    problem = problem_velocity_rolls
    if (.not. cs%slide .and. .not. ieee_is_nan(cs%param(p_velocity_x))) return
    problem = problem_velocity_tangent
    if (.not. ieee_is_nan(cs%param(p_velocity_x))) then    ! (an unset velocity compares with nothing)
      if (abs(start_normal_velocity(cs)) > tangent_tolerance * norm2(cs%param(p_velocity_x:p_velocity_z))) return
    end if
    param = 0
    problem = 0
  end subroutine find_problem

  !> V . n of the start's velocity (0 when it is unset).
  pure real(wp) function start_normal_velocity(cs)
    type(case_t), intent(in) :: cs
    start_normal_velocity = 0
    if (ieee_is_nan(cs%param(p_velocity_x))) return
    associate (cup => new_ellipsoid(cs%param(p_a), cs%param(p_b), cs%param(p_c)))
      start_normal_velocity = dot_product(cs%param(p_velocity_x:p_velocity_z), &
                                          normal_from_contact(cup, cs%param(p_x), cs%param(p_y)))
    end associate
  end function start_normal_velocity

  !> The vz that makes the start's velocity tangent with its vx, vy:
  !> v . n = 0 (n_z > 0 at every point inside the cup's rim).
  pure real(wp) function tangent_vz(cs)
    type(case_t), intent(in) :: cs
    real(wp) :: n(3)
    associate (cup => new_ellipsoid(cs%param(p_a), cs%param(p_b), cs%param(p_c)))
      n = normal_from_contact(cup, cs%param(p_x), cs%param(p_y))
    end associate
    tangent_vz = -(cs%param(p_velocity_x) * n(1) + cs%param(p_velocity_x + 1) * n(2)) / n(3)
  end function tangent_vz

  !> 'name = value' of the input a problem of check_case (param /= 0)
  !> concerns: its row, or the whole initial velocity where the problem is
  !> the vector's (given in part, without sliding, not tangent), not the
  !> component the check stopped at.
  subroutine problem_setting(cs, interval, param, text)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: interval
    integer, intent(in) :: param
    character(len=:), allocatable, intent(out) :: text
    integer :: found, problem
    call find_problem(cs, interval, found, problem)
    if (found == param .and. any(problem == [problem_velocity_partial, problem_velocity_rolls, &
                                             problem_velocity_tangent])) then
      text = trim(params(p_velocity_x)%variable) // ' = ' // format_real(cs%param(p_velocity_x)) // ', ' // &
             format_real(cs%param(p_velocity_x + 1)) // ', ' // format_real(cs%param(p_velocity_z))
    else
      text = trim(params(param)%name) // ' = ' // format_real(get_param(cs, param))
    end if
  end subroutine problem_setting

  !> (x/a)^2 + (y/b)^2 of the start: below 1 inside the cup.
  pure real(wp) function start_level(cs)
    type(case_t), intent(in) :: cs
    start_level = (cs%param(p_x) / cs%param(p_a))**2 + (cs%param(p_y) / cs%param(p_b))**2
  end function start_level

  !> The principal radii of curvature of the cup at the start.
  pure function start_radii(cs) result(radii)
    type(case_t), intent(in) :: cs
    real(wp) :: radii(2)
    associate (cup => new_ellipsoid(cs%param(p_a), cs%param(p_b), cs%param(p_c)))
      radii = principal_radii(cup, normal_from_contact(cup, cs%param(p_x), cs%param(p_y)))
    end associate
  end function start_radii

  pure function range_opening(k) result(text)
    integer, intent(in) :: k
    character(len=merge(19, 21 + len(format_real(params(k)%low)), params(k)%positive)) :: text
    if (params(k)%positive) then
      text = 'must be > 0 and <= '
    else
      text = 'must be between ' // format_real(params(k)%low) // ' and '
    end if
  end function range_opening

  !> ' ' and the unit of row k, or nothing for a dimensionless one.
  pure function unit_suffix(k) result(text)
    integer, intent(in) :: k
    character(len=len(params(k)%unit) + 1) :: text
    text = ''
    if (params(k)%unit /= '1') text = ' ' // params(k)%unit
  end function unit_suffix

  !> What row k's valid range is, for a message: 'must be between 0 and 0.5 m'.
  pure function range_text(k) result(text)
    integer, intent(in) :: k
    character(len=len(range_opening(k)) + len(format_real(params(k)%high)) + len_trim(unit_suffix(k))) :: text
    text = range_opening(k) // format_real(params(k)%high) // unit_suffix(k)
  end function range_text

  !> Why `value` of row k is outside the row's range: the range, after
  !> 'is below the least normal number' for a positive row's subnormal, and
  !> for mu = 0 that an unset mu is the unlimited friction.
  pure subroutine out_of_range_reason(k, value, reason)
    integer, intent(in) :: k
    real(wp), intent(in) :: value
    character(len=:), allocatable, intent(out) :: reason
    reason = range_text(k)
    if (params(k)%positive .and. value > 0 .and. value < params(k)%low) reason = 'is below ' // &
        format_real(params(k)%low) // ', the least normal number; ' // reason
    if (k == p_mu .and. is_zero(value)) reason = reason // ' (leave mu out for unlimited friction)'
  end subroutine out_of_range_reason

  !> Methods whose step is chosen by error control (dt is then the largest step).
  logical pure function adaptive_method(method)
    character(len=*), intent(in) :: method
    type(method_info_t) :: info
    info = method_info(trim(method))
    adaptive_method = info%adaptive
  end function adaptive_method

  !> whole is a whole number (>= 1) of parts, to 1e-9 relative.
  logical pure function is_multiple(whole, part)
    real(wp), intent(in) :: whole, part
    real(wp) :: ratio
    ratio = whole / part
    is_multiple = abs(ratio - anint(ratio)) <= 1.0e-9_wp * max(1.0_wp, ratio) .and. anint(ratio) >= 1
  end function is_multiple

  !> The model of a case: its cup, ball and the cup's motion.
  pure function make_ball(cs) result(ball)
    type(case_t), intent(in) :: cs
    type(rolling_ball_t) :: ball
    ball%cup = new_ellipsoid(cs%param(p_a), cs%param(p_b), cs%param(p_c))
    ball%radius = cs%param(p_radius)
    ball%mass = cs%param(p_mass)
    ball%g = cs%param(p_g)
    ball%inertia_factor = cs%param(p_inertia_factor)
    ball%mu = 0                      ! the model's 'not limited': mu unset
    if (.not. ieee_is_nan(cs%param(p_mu))) ball%mu = cs%param(p_mu)
    ball%fit_margin = cs%param(p_fit_margin)
    ball%rolling_resistance = cs%param(p_rolling_resistance)
    ball%excitation = cs%excitation
    ball%excitation%amplitude = cs%param(p_excitation_amplitude_x:p_excitation_amplitude_z)
    ball%excitation%frequency = cs%param(p_excitation_frequency)
    ball%excitation%phase = cs%param(p_excitation_phase)
    ball%excitation%scale = cs%param(p_scale)
  end function make_ball

  !> Every resolved input of a case, as stored under /case/: its index, a
  !> dataset per row of the parameter table (a vector's rows as one), then
  !> the inputs outside the table.
  function case_record(cs) result(rec)
    type(case_t), intent(in) :: cs
    type(named_value_t), allocatable :: rec(:)
    type(named_value_t) :: rows(param_datasets)
    integer :: p, k
    k = 0
    do p = 1, param_count
      if (param_component(p) > 1) cycle
      k = k + 1
      if (param_component(p) == 0) then
        rows(k) = real_value(trim(params(p)%name), trim(params(p)%unit), trim(params(p)%description), &
                             stored_value(cs, p))
      else
        rows(k) = vector_value(trim(param_dataset(p)), trim(params(p)%unit), trim(param_dataset_description(p)), &
                               cs%param(p:p + param_width(p) - 1))
      end if
    end do
    rec = [int_value('index', '1', 'global case index', cs%index), rows, &
      text_value('method', 'integration method', cs%method), &
      real_value('t_end', 's', 'end time', cs%t_end), &
      int_value('error_estimate', '1', '1: error figures from a reference run are in /summary', &
                merge(1_i8, 0_i8, cs%error_estimate)), &
      text_value('excitation_kind', 'motion of the cup: none, harmonic or record', &
                 excitation_kind_names(cs%excitation%kind)), &
      text_value('record', 'record of a suite (&record name; blank: none)', cs%record_name), &
      real_value('record_factor', '1', 'factor of that record (&record factor)', cs%record_factor)]
    if (cs%excitation%kind == excitation_record .and. allocated(cs%intensity%sa)) &
      rec = [rec, intensity_record(cs%intensity, cs%param(p_scale))]
  end function case_record

  !> The intensity measures of a case shaken by a record (its values times
  !> `scale`, as the cup moves): PGA, PGV, PGD of the horizontal motion (the
  !> peak of the vector of both components) and Sa at the user's periods.
  pure function intensity_record(im, scale) result(rec)
    type(record_intensity_t), intent(in) :: im
    real(wp), intent(in) :: scale
    type(named_value_t) :: rec(3 + size(im%sa))
    integer :: k
    rec(1) = real_value('pga', 'm/s^2', 'peak horizontal ground acceleration (of both components together)', &
                        scale * im%pga)
    rec(2) = real_value('pgv', 'm/s', 'peak horizontal ground velocity (of both components together)', &
                        scale * im%pgv)
    rec(3) = real_value('pgd', 'm', 'peak horizontal ground displacement (of both components together)', &
                        scale * im%pgd)
    do k = 1, size(im%sa)
      rec(3 + k) = real_value(sa_name(im%periods(k)), 'm/s^2', 'pseudo-spectral acceleration (RotD100), ' // &
                              format_real(100 * damping_ratio) // ' % damping, at period ' // &
                              format_real(im%periods(k)) // ' s', scale * im%sa(k))
    end do
  end function intensity_record

  !> The /case name of Sa at period t (s): sa_ and its shortest text, sa_0.5, sa_2.
  pure function sa_name(t) result(name)
    real(wp), intent(in) :: t
    character(len=3 + len(format_real(t))) :: name
    name = 'sa_' // format_real(t)
  end function sa_name

  !> Row p's value as /case stores it: the input (NaN where unset), but the
  !> weight as m g, also where the mass was given (NaN where it would
  !> overflow: an invalid case's record holds its inputs as given).
  pure real(wp) function stored_value(cs, p) result(value)
    type(case_t), intent(in) :: cs
    integer, intent(in) :: p
    value = cs%param(p)
    if (p == p_weight) then
      value = ieee_value(value, ieee_quiet_nan)
      if (abs(cs%param(p_mass)) <= huge(value) / max(abs(cs%param(p_g)), 1.0_wp)) &
        value = cs%param(p_mass) * cs%param(p_g)
    end if
  end function stored_value
end module ellroll_cases
