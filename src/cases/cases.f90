!> One fully resolved case, the table of its scalar parameters (the names a
!> sweep or a sample may vary, with their groups, units and bounds), the
!> checks every case must pass, and the output plan shared by all cases.
module ellroll_cases
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: named_value_t, real_value, vector_value, int_value, text_value
  use ellroll_strings, only: format_real
  use ellroll_ellipsoid, only: new_ellipsoid, principal_radii, normal_from_contact
  use ellroll_rolling_ball, only: rolling_ball_t
  use ellroll_excitation, only: excitation_t, excitation_kind_names
  implicit none
  private

  public :: case_t, output_plan_t, steps_per_sample, case_record, make_ball, check_case, finalize_case, &
            adaptive_method, is_multiple, range_text, max_steps
  public :: param_count, param_names, param_groups, param_units, param_index, get_param, set_param
  public :: field_count, field_names, field_units, field_ncomp, field_descriptions
  public :: field_contact, field_center, field_omega, field_normal, field_nutation, &
            field_reaction, field_energy, field_base_acceleration

  type :: case_t
    integer(i8) :: index = 0
    real(wp) :: a = 0, b = 0, c = 0
    real(wp) :: radius = 0
    real(wp) :: weight = 0               !< N; 0 when the mass was given directly
    real(wp) :: mass = 0                 !< kg; weight / g when the weight was given
    real(wp) :: g = 9.81_wp
    real(wp) :: inertia_factor = 0.4_wp
    real(wp) :: mu = 0                   !< 0: no friction limit
    real(wp) :: x0 = 0, y0 = 0
    real(wp) :: omega0(3) = 0
    character(len=32) :: method = 'rk4'
    real(wp) :: dt = 0
    real(wp) :: t_end = 0
    real(wp) :: fit_margin = 1.0e-6_wp
    real(wp) :: rtol = 1.0e-9_wp          !< adaptive method: relative tolerance
    real(wp) :: atol = 1.0e-12_wp         !< adaptive method: absolute tolerance
    logical :: error_estimate = .false.   !< also run the reference and store error figures
    type(excitation_t) :: excitation      !< translation of the cup (none by default)
  end type case_t

  ! The scalar parameters: what a sweep or a sample can vary.
  integer, parameter :: param_count = 23
  character(len=*), parameter :: param_names(param_count) = [character(len=22) :: &
      'a', 'b', 'c', 'radius', 'weight', 'mass', 'mu', 'inertia_factor', 'g', &
      'x', 'y', 'omega_x', 'omega_y', 'omega_z', 'dt', 'fit_margin', 'rtol', 'atol', &
      'excitation_frequency', 'excitation_phase', 'excitation_amplitude_x', 'excitation_amplitude_y', &
      'excitation_amplitude_z']
  character(len=*), parameter :: param_groups(param_count) = [character(len=11) :: &
      'geometry', 'geometry', 'geometry', 'ball', 'ball', 'ball', 'ball', 'ball', 'environment', &
      'initial', 'initial', 'initial', 'initial', 'initial', 'integration', 'integration', &
      'integration', 'integration', 'excitation', 'excitation', 'excitation', 'excitation', 'excitation']
  character(len=*), parameter :: param_units(param_count) = [character(len=5) :: &
      'm', 'm', 'm', 'm', 'N', 'kg', '', '', 'm/s^2', 'm', 'm', 'rad/s', 'rad/s', 'rad/s', 's', '', '', '', &
      'Hz', 'rad', 'm/s^2', 'm/s^2', 'm/s^2']
  ! Bounds keep every derived quantity finite (squares, products, s^4).
  ! A case's steps (t_end / dt) are counted in 64-bit integers and would take
  ! days at a million steps per second.
  real(wp), parameter :: max_steps = 1.0e12_wp   !< also the most samples a case stores
  real(wp), parameter :: length_max = 1.0e6_wp, length_min = 1.0e-6_wp
  real(wp), parameter :: param_low(param_count) = [length_min, length_min, length_min, length_min, &
      tiny(1.0_wp), tiny(1.0_wp), 0.0_wp, tiny(1.0_wp), 0.0_wp, -length_max, -length_max, &
      -1.0e6_wp, -1.0e6_wp, -1.0e6_wp, tiny(1.0_wp), 0.0_wp, 1.0e-14_wp, 0.0_wp, &
      0.0_wp, -1.0e3_wp, -1.0e4_wp, -1.0e4_wp, -1.0e4_wp]
  real(wp), parameter :: param_high(param_count) = [length_max, length_max, length_max, length_max, &
      1.0e12_wp, 1.0e12_wp, 1.0e6_wp, 2.0_wp / 3, 1.0e4_wp, length_max, length_max, &
      1.0e6_wp, 1.0e6_wp, 1.0e6_wp, 1.0e9_wp, 0.5_wp, 0.1_wp, 1.0_wp, &
      1.0e6_wp, 1.0e3_wp, 1.0e4_wp, 1.0e4_wp, 1.0e4_wp]

  integer, parameter :: field_count = 8
  integer, parameter :: field_contact = 1, field_center = 2, field_omega = 3, field_normal = 4, &
                        field_nutation = 5, field_reaction = 6, field_energy = 7, field_base_acceleration = 8
  character(len=*), parameter :: field_names(field_count) = [character(len=17) :: &
      'contact', 'center', 'omega', 'normal', 'nutation', 'reaction', 'energy', 'base_acceleration']
  character(len=*), parameter :: field_units(field_count) = [character(len=5) :: &
      'm', 'm', 'rad/s', '1', 'rad', 'N', 'J', 'm/s^2']
  integer, parameter :: field_ncomp(field_count) = [3, 3, 3, 3, 1, 3, 1, 3]
  character(len=*), parameter :: field_descriptions(field_count) = [character(len=80) :: &
      'contact point A of the ball on the cup', &
      'centre C of the ball', &
      'angular velocity of the ball (fixed frame)', &
      'unit normal at A, pointing from A to C', &
      'nutation angle Theta between the normal and the vertical', &
      'force of the cup on the ball at A (normal force plus friction)', &
      'total energy J|w|^2/2 + m|V_C|^2/2 + m g z_C, z from the cup bottom (cup frame)', &
      'acceleration of the cup (inertial frame)']

  !> What a run writes: shared by all its cases.
  type :: output_plan_t
    character(len=:), allocatable :: file
    real(wp) :: interval = 0
    integer(i8) :: n_samples = 0
    logical :: fields(field_count) = .true.
    integer :: compression = 0          !< deflate level of the trajectories, 0 (none) to 9
  end type output_plan_t

contains

  pure integer function param_index(name)
    character(len=*), intent(in) :: name
    integer :: k
    param_index = 0
    do k = 1, param_count
      if (param_names(k) == name) param_index = k
    end do
  end function param_index

  pure real(wp) function get_param(cs, id) result(value)
    type(case_t), intent(in) :: cs
    integer, intent(in) :: id
    select case (id)
    case (1); value = cs%a
    case (2); value = cs%b
    case (3); value = cs%c
    case (4); value = cs%radius
    case (5); value = cs%weight
    case (6); value = cs%mass
    case (7); value = cs%mu
    case (8); value = cs%inertia_factor
    case (9); value = cs%g
    case (10); value = cs%x0
    case (11); value = cs%y0
    case (12:14); value = cs%omega0(id - 11)
    case (15); value = cs%dt
    case (16); value = cs%fit_margin
    case (17); value = cs%rtol
    case (18); value = cs%atol
    case (19); value = cs%excitation%frequency
    case (20); value = cs%excitation%phase
    case default; value = cs%excitation%amplitude(id - 20)
    end select
  end function get_param

  pure subroutine set_param(cs, id, value)
    type(case_t), intent(inout) :: cs
    integer, intent(in) :: id
    real(wp), intent(in) :: value
    select case (id)
    case (1); cs%a = value
    case (2); cs%b = value
    case (3); cs%c = value
    case (4); cs%radius = value
    case (5); cs%weight = value
    case (6); cs%mass = value
    case (7); cs%mu = value
    case (8); cs%inertia_factor = value
    case (9); cs%g = value
    case (10); cs%x0 = value
    case (11); cs%y0 = value
    case (12:14); cs%omega0(id - 11) = value
    case (15); cs%dt = value
    case (16); cs%fit_margin = value
    case (17); cs%rtol = value
    case (18); cs%atol = value
    case (19); cs%excitation%frequency = value
    case (20); cs%excitation%phase = value
    case default; cs%excitation%amplitude(id - 20) = value
    end select
  end subroutine set_param

  !> A fixed-step case's steps between output samples: its own dt, which a
  !> sweep may vary (check_case holds the interval to a whole number of them).
  pure integer(i8) function steps_per_sample(cs, plan)
    type(case_t), intent(in) :: cs
    type(output_plan_t), intent(in) :: plan
    steps_per_sample = max(1_i8, nint(plan%interval / cs%dt, i8))
  end function steps_per_sample

  !> Derive what follows from the given values (the mass from a weight).
  pure subroutine finalize_case(cs)
    type(case_t), intent(inout) :: cs
    ! tested before it is used: NaN, or a quotient beyond any valid mass,
    ! would trap here, before check_case names the input
    if (.not. (ieee_is_finite(cs%weight) .and. ieee_is_finite(cs%g))) return
    if (cs%weight <= 0) return
    cs%mass = 0
    if (cs%g > 0 .and. cs%weight / param_high(param_index('mass')) <= cs%g) cs%mass = cs%weight / cs%g
  end subroutine finalize_case

  !> The first problem of a case, as the parameter it concerns and why;
  !> param = 0 when the case is valid. Checks every bound, that the start
  !> lies inside the cup, that the ball fits there, and that dt divides the
  !> output interval.
  subroutine check_case(cs, interval, param, reason)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: interval
    integer, intent(out) :: param
    character(len=:), allocatable, intent(out) :: reason
    real(wp) :: value, level, radii(2)
    integer :: k, weight_id, mass_id
    reason = ''
    weight_id = param_index('weight')      ! looked up once: this runs for every case
    mass_id = param_index('mass')
    do k = 1, param_count
      param = k
      value = get_param(cs, k)
      if (.not. ieee_is_finite(value)) then
        reason = 'must be a finite number'
        return
      end if
      if (k == weight_id .and. value == 0) cycle     ! mass given instead
      if (k == mass_id .and. cs%weight > 0) cycle
      if (value < param_low(k) .or. value > param_high(k)) then
        reason = range_text(k)
        return
      end if
    end do
    param = param_index('weight')
    if (cs%weight > 0 .and. cs%g <= 0) then
      reason = 'a weight cannot give the mass when g = 0; give mass instead'
      return
    end if
    if (cs%weight > 0 .and. .not. cs%mass > 0) then
      reason = 'gives a mass weight / g above ' // format_real(param_high(mass_id)) // ' kg with g = ' // &
               format_real(cs%g) // ' m/s^2; give mass instead'
      return
    end if
    param = param_index('dt')
    if (cs%dt > cs%t_end) then
      reason = 'must not exceed t_end = ' // format_real(cs%t_end) // ' s'
      return
    end if
    if (cs%t_end > max_steps * cs%dt) then      ! (not t_end / dt: it may overflow)
      reason = 'must be at least t_end / ' // format_real(max_steps) // ' = ' // &
               format_real(cs%t_end / max_steps) // ' s: no case takes more than ' // format_real(max_steps) // ' steps'
      return
    end if
    if (.not. adaptive_method(cs%method) .and. .not. is_multiple(interval, cs%dt)) then
      reason = 'the output interval ' // format_real(interval) // ' s must be a whole number of steps'
      return
    end if
    level = (cs%x0 / cs%a)**2 + (cs%y0 / cs%b)**2
    if (level >= 1) then
      param = param_index(merge('x', 'y', cs%x0 /= 0))
      reason = 'the start (x, y) = (' // format_real(cs%x0) // ', ' // format_real(cs%y0) // &
               ') is not inside the cup: (x/a)^2 + (y/b)^2 = ' // format_real(level) // ' must be < 1'
      return
    end if
    radii = principal_radii(new_ellipsoid(cs%a, cs%b, cs%c), &
                            normal_from_contact(new_ellipsoid(cs%a, cs%b, cs%c), cs%x0, cs%y0))
    if (radii(1) / cs%radius - 1 <= cs%fit_margin) then
      param = param_index('radius')
      reason = 'the ball does not fit the cup at the start: the principal radii of curvature there are ' // &
               format_real(radii(1)) // ' m and ' // format_real(radii(2)) // &
               ' m, and radius must be below ' // format_real(radii(1)) // ' m'
      return
    end if
    param = 0
  end subroutine check_case

  function range_text(k) result(text)
    integer, intent(in) :: k
    character(len=:), allocatable :: text
    character(len=:), allocatable :: units
    units = ''
    if (len_trim(param_units(k)) > 0) units = ' ' // trim(param_units(k))
    if (param_low(k) == tiny(1.0_wp)) then
      text = 'must be > 0 and <= ' // format_real(param_high(k)) // units
    else
      text = 'must be between ' // format_real(param_low(k)) // ' and ' // format_real(param_high(k)) // units
    end if
  end function range_text

  !> Methods whose step is chosen by error control (dt is then the largest step).
  logical pure function adaptive_method(method)
    character(len=*), intent(in) :: method
    adaptive_method = trim(method) == 'dop853'
  end function adaptive_method

  !> whole is a whole number (>= 1) of parts, to 1e-9 relative.
  logical pure function is_multiple(whole, part)
    real(wp), intent(in) :: whole, part
    real(wp) :: ratio
    ratio = whole / part
    is_multiple = abs(ratio - anint(ratio)) <= 1.0e-9_wp * max(1.0_wp, ratio) .and. anint(ratio) >= 1
  end function is_multiple

  pure function make_ball(cs) result(ball)
    type(case_t), intent(in) :: cs
    type(rolling_ball_t) :: ball
    ball%cup = new_ellipsoid(cs%a, cs%b, cs%c)
    ball%radius = cs%radius
    ball%mass = cs%mass
    ball%g = cs%g
    ball%inertia_factor = cs%inertia_factor
    ball%mu = cs%mu
    ball%fit_margin = cs%fit_margin
    ball%excitation = cs%excitation
  end function make_ball

  !> Every resolved input of a case, as stored under /case/.
  function case_record(cs) result(rec)
    type(case_t), intent(in) :: cs
    type(named_value_t), allocatable :: rec(:)
    real(wp) :: mu
    mu = cs%mu
    if (mu <= 0) mu = ieee_value(mu, ieee_quiet_nan)
    rec = [ &
      int_value('index', '1', 'global case index', cs%index), &
      real_value('a', 'm', 'semi-axis of the cup along x', cs%a), &
      real_value('b', 'm', 'semi-axis of the cup along y', cs%b), &
      real_value('c', 'm', 'semi-axis of the cup along z (cup depth)', cs%c), &
      real_value('radius', 'm', 'ball radius R', cs%radius), &
      real_value('mass', 'kg', 'ball mass m', cs%mass), &
      real_value('weight', 'N', 'ball weight m g', cs%mass * cs%g), &
      real_value('g', 'm/s^2', 'gravitational acceleration', cs%g), &
      real_value('inertia_factor', '1', 'J / (m R^2); 0.4 for a homogeneous ball', cs%inertia_factor), &
      real_value('mu', '1', 'friction coefficient (NaN: not limited)', mu), &
      real_value('x0', 'm', 'initial contact point x', cs%x0), &
      real_value('y0', 'm', 'initial contact point y', cs%y0), &
      vector_value('omega0', 'rad/s', 'initial angular velocity', cs%omega0), &
      text_value('method', 'integration method', cs%method), &
      real_value('dt', 's', 'integration step', cs%dt), &
      real_value('t_end', 's', 'end time', cs%t_end), &
      real_value('fit_margin', '1', 'case ends when r_min / R - 1 falls to this', cs%fit_margin), &
      real_value('rtol', '1', 'relative tolerance (adaptive method)', cs%rtol), &
      real_value('atol', '1', 'absolute tolerance (adaptive method)', cs%atol), &
      int_value('error_estimate', '1', '1: error figures from a reference run are in /summary', &
                merge(1_i8, 0_i8, cs%error_estimate)), &
      text_value('excitation_kind', 'motion of the cup: none, harmonic or record', &
                 excitation_kind_names(cs%excitation%kind)), &
      vector_value('excitation_amplitude', 'm/s^2', 'harmonic: amplitude of the cup acceleration', &
                   cs%excitation%amplitude), &
      real_value('excitation_frequency', 'Hz', 'harmonic: frequency', cs%excitation%frequency), &
      real_value('excitation_phase', 'rad', 'harmonic: phase', cs%excitation%phase) ]
  end function case_record
end module ellroll_cases
