!> One fully resolved case, and the output plan shared by every case of a run.
module ellroll_cases
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: named_value_t, real_value, vector_value, int_value, text_value
  use ellroll_ellipsoid, only: new_ellipsoid
  use ellroll_rolling_ball, only: rolling_ball_t
  implicit none
  private

  public :: case_t, output_plan_t, case_record, make_ball
  public :: field_count, field_names, field_units, field_ncomp, field_descriptions
  public :: field_contact, field_center, field_omega, field_normal, field_nutation, &
            field_reaction, field_energy

  type :: case_t
    integer(i8) :: index = 0
    real(wp) :: a = 0, b = 0, c = 0
    real(wp) :: radius = 0
    real(wp) :: mass = 0
    real(wp) :: g = 9.81_wp
    real(wp) :: inertia_factor = 0.4_wp
    real(wp) :: mu = 0                   !< 0: no friction limit
    real(wp) :: x0 = 0, y0 = 0
    real(wp) :: omega0(3) = 0
    character(len=32) :: method = 'rk4'
    real(wp) :: dt = 0
    real(wp) :: t_end = 0
    real(wp) :: fit_margin = 1.0e-6_wp
  end type case_t

  integer, parameter :: field_count = 7
  integer, parameter :: field_contact = 1, field_center = 2, field_omega = 3, field_normal = 4, &
                        field_nutation = 5, field_reaction = 6, field_energy = 7
  character(len=*), parameter :: field_names(field_count) = [character(len=8) :: &
      'contact', 'center', 'omega', 'normal', 'nutation', 'reaction', 'energy']
  character(len=*), parameter :: field_units(field_count) = [character(len=5) :: &
      'm', 'm', 'rad/s', '1', 'rad', 'N', 'J']
  integer, parameter :: field_ncomp(field_count) = [3, 3, 3, 3, 1, 3, 1]
  character(len=*), parameter :: field_descriptions(field_count) = [character(len=80) :: &
      'contact point A of the ball on the cup', &
      'centre C of the ball', &
      'angular velocity of the ball (fixed frame)', &
      'unit normal at A, pointing from A to C', &
      'nutation angle Theta between the normal and the vertical', &
      'force of the cup on the ball at A (normal force plus friction)', &
      'total energy J|w|^2/2 + m|V_C|^2/2 + m g z_C, z from the cup bottom']

  !> What a run writes: shared by all its cases.
  type :: output_plan_t
    character(len=:), allocatable :: file
    real(wp) :: interval = 0
    integer(i8) :: steps_per_sample = 1
    integer(i8) :: n_samples = 0
    logical :: fields(field_count) = .true.
  end type output_plan_t

contains

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
      real_value('fit_margin', '1', 'case ends when r_min / R - 1 falls to this', cs%fit_margin) ]
  end function case_record
end module ellroll_cases
