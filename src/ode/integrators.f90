!> One-step integrators behind one interface (after rklib): each is a type
!> that knows its name, kind and order. A step receives f(t, y) from the
!> caller (the previous step's end-point derivative, which the run loop
!> needs anyway for derived outputs).
!>
!>   rk4     classical Runge-Kutta, fixed step, order 4 (the source paper's method)
!>   dop853  Dormand-Prince 8(5,3), adaptive, with 7th-order dense output
!>   vern9   Verner's 9(8) pair, adaptive, with 8th-order dense output
!>   gauss4  2-stage Gauss-Legendre, implicit, symmetric, order 4 (simplified
!>           Newton, LAPACK LU): bounded energy error over long runs
module ellroll_integrators
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero, equals
  use ellroll_lapack, only: dgetrf, dgetrs
  use ellroll_ode, only: ode_system_t, stage_limit, no_step_solution
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_dop853_tableau, only: dop853_end_stage => end_stage, dop853_stages_dense => stages_dense, c853, &
      a_value, a_column, a_row, e5, bhh, d853, in_error_estimate, in_dense_output
  use ellroll_vern9_tableau, only: vern9_end_stage => end_stage, vern9_stages_dense => stages_dense, c9, e8, q98, &
      v9_value => a_value, v9_column => a_column, v9_row => a_row, v9_in_error_estimate => in_error_estimate, &
      v9_in_dense_output => in_dense_output
  implicit none
  private

  public :: integrator_t, rk4_t, embedded_pair_t, dop853_t, vern9_t, gauss4_t, new_integrator, method_names, &
            stability_limit
  public :: method_info_t, methods, method_info

  !> Largest system the integrators take: their work arrays are fixed-size
  !> (on the stack), so a step allocates nothing. The embedded pairs work on whole
  !> columns of this length, entries past the system's size kept zero: the
  !> loops have a length known at compile time (unrolled, vectorized) and
  !> the system's entries come out as if computed alone.
  integer, parameter, public :: max_equations = 8

  !> Stages of the largest embedded pair with its dense-output stages (vern9).
  integer, parameter, public :: max_pair_stages = vern9_stages_dense

  !> Verner's error estimate sum_s e8(s) k_s is taken no smaller than this
  !> times its round-off, eps sum_s |e8(s) k_s|: below, it is noise (e8
  !> cancels k_8 against k_12), and a step chosen from it would be the
  !> noise's (a case alone and in a SIMD batch, whose stages differ by
  !> round-off, would part ways).
  real(wp), parameter, public :: estimate_round_off = 16 * epsilon(1.0_wp)

  !> Under pure relative control (atol = 0) the round-off floor alone never
  !> rejects a step: it counts for at most the component's tolerance (scale
  !> / h). A component that is zero at the start of a step then has the
  !> step's own change as its size, and 16 eps sum_s |e8(s)| = 2.1e-14 of it
  !> as its floor, whatever h: at rtol 1e-14 no first step from n_x = 0
  !> would be accepted (with atol > 0 a short enough step is). The bound is
  !> scale times floor_limit: 1 / h, h taken no shorter than shortest_h (no
  !> overflow); with atol > 0, 1 / shortest_h, which no floor reaches unless
  !> atol is below 1e-250 or so.
  real(wp), parameter, public :: shortest_h = 1.0e-280_wp

  !> A component's error (or, for the starting step, its size) in units of
  !> its tolerance atol + rtol |y| is taken no larger than this, so that its
  !> square does not overflow: an atol below about 1e-150, or atol = 0 (pure
  !> relative control) and a component that is zero at both ends of a step,
  !> whose tolerance is taken as tiny(1.0) (it contributes 0 while it stays
  !> exactly zero). Under pure relative control the run loops reject an
  !> attempt whose norm reaches h times a quarter of the cap whatever its h
  !> (such a component has no tolerance; h times the norm would accept a
  !> short enough step of any error: ellroll_adaptive_run's judged_norm).
  real(wp), parameter, public :: tolerance_ratio_cap = 1.0e150_wp

  !> What a method is, for users and for the code that picks how to run it.
  type :: method_info_t
    character(len=8) :: name
    character(len=10) :: kind          !< fixed, adaptive or symmetric
    character(len=24) :: order         !< the order, as a user reads it
    logical :: adaptive                !< the step is chosen by error control (dt is the largest step)
    character(len=80) :: use_for       !< when to pick it (bench/workprecision.py, bench/pairs.py)
  end type method_info_t

  type(method_info_t), parameter :: methods(4) = [ &
      method_info_t('rk4', 'fixed', '4', .false., &
                    "the paper's; large campaigns at errors of about 1e-3 m (SIMD batches)"), &
      method_info_t('dop853', 'adaptive', '8(5,3), dense output 7', .true., &
                    'accurate runs, rtol 1e-3 to 1e-7; outputs at any interval'), &
      method_info_t('vern9', 'adaptive', '9(8), dense output 8', .true., &
                    'rtol 1e-8 and below: fewer RHS calls and a smaller error than dop853'), &
      method_info_t('gauss4', 'symmetric', '4', .false., &
                    'long runs of a conservative case: energy error bounded, not drifting')]

  type, abstract :: integrator_t
    !> fixed-step methods: 0 when the system's model held at every stage of
    !> the last step (ode_system_t%stage_status), else the code of the first
    !> stage where it did not
    integer :: stage_limit = 0
  contains
    procedure(step_interface), deferred :: step
    procedure(info_interface), deferred, nopass :: info
  end type integrator_t

  abstract interface
    !> Advance y(t) by h. f0 = f(t, y) on entry; n_rhs counts new RHS calls.
    subroutine step_interface(self, sys, t, y, f0, h, y_new, n_rhs)
      import :: integrator_t, ode_system_t, wp, i8
      class(integrator_t), intent(inout) :: self
      class(ode_system_t), intent(in) :: sys
      real(wp), intent(in) :: t, h
      real(wp), intent(in) :: y(:), f0(:)
      real(wp), intent(out) :: y_new(:)
      integer(i8), intent(inout) :: n_rhs
    end subroutine step_interface
    pure function info_interface() result(info)
      import :: method_info_t
      type(method_info_t) :: info
    end function info_interface
  end interface

  type, extends(integrator_t) :: rk4_t
  contains
    procedure :: step => rk4_step
    procedure, nopass :: info => rk4_info
  end type rk4_t

  !> What the run loops need to know of an embedded pair beyond its
  !> arithmetic: stage end_stage is f(t + h, y_new), the dense-output stages
  !> follow it up to stages_dense; the error estimate is O(h^control_order),
  !> the exponent of the step control.
  type :: pair_shape_t
    integer :: end_stage, stages_dense, control_order
  end type pair_shape_t

  !> An explicit embedded Runge-Kutta pair. Its step is an attempt: it also
  !> returns the error norm (<= 1: accept) and keeps f at the new point as
  !> stage end_stage() of k. Dense output covers the last attempted
  !> step. The stage arithmetic is public (stage_input, finish_attempt,
  !> build_dense, dense_value) so that a fused step of one system shares it.
  type, abstract, extends(integrator_t) :: embedded_pair_t
    real(wp) :: rtol = 1.0e-9_wp, atol = 1.0e-12_wp
    real(wp) :: error_norm = 0
    real(wp) :: k(max_equations, max_pair_stages) = 0      !< stages of the last attempt
    real(wp) :: y_old(max_equations) = 0, y_new(max_equations) = 0
    !> the interpolant's coefficients (dop853: y_old + sum_i c(:, i - 1)
    !> theta^i; vern9: y_old + sum_i c(:, i) (2 theta - 1)^i), theta = (t - t_old) / h
    real(wp) :: dense_coefficients(max_equations, 0:8) = 0
    real(wp) :: t_old = 0, h = 0
    logical :: dense_ready = .false.
    !> the dense-output stages are in k already (computed with other lanes of a batch)
    logical :: dense_stages_ready = .false.
  contains
    procedure :: step => pair_step
    procedure :: dense => pair_dense
    procedure :: initial_step => pair_initial_step
    procedure :: hold_attempt => pair_hold_attempt
    procedure :: end_stage => pair_end_stage
    procedure :: attempt_calls => pair_attempt_calls
    procedure :: dense_calls => pair_dense_calls
    procedure :: control_order => pair_control_order
    procedure(stage_input_interface), deferred :: stage_input
    procedure(finish_attempt_interface), deferred :: finish_attempt
    procedure(build_dense_interface), deferred :: build_dense
    procedure(dense_value_interface), deferred :: dense_value
    procedure(dense_rate_interface), deferred :: dense_rate
    procedure(node_interface), deferred, nopass :: node
    procedure(shape_interface), deferred, nopass :: shape
  end type embedded_pair_t

  abstract interface
    !> The input of stage s: y + h sum_j a(s, j) k_j.
    pure subroutine stage_input_interface(self, s, y, h, point)
      import :: embedded_pair_t, wp, max_equations
      class(embedded_pair_t), intent(in) :: self
      integer, intent(in) :: s
      real(wp), intent(in) :: y(max_equations), h
      real(wp), intent(out) :: point(max_equations)
    end subroutine stage_input_interface
    !> The error norm of the attempt y -> y_new of an n-equation system.
    pure subroutine finish_attempt_interface(self, n, t, y, h, y_new)
      import :: embedded_pair_t, wp, max_equations
      class(embedded_pair_t), intent(inout) :: self
      integer, intent(in) :: n
      real(wp), intent(in) :: t, y(max_equations), h, y_new(max_equations)
    end subroutine finish_attempt_interface
    pure subroutine build_dense_interface(self)
      import :: embedded_pair_t
      class(embedded_pair_t), intent(inout) :: self
    end subroutine build_dense_interface
    !> The interpolant's value at theta.
    pure subroutine dense_value_interface(self, theta, y)
      import :: embedded_pair_t, wp, max_equations
      class(embedded_pair_t), intent(in) :: self
      real(wp), intent(in) :: theta
      real(wp), intent(out) :: y(max_equations)
    end subroutine dense_value_interface
    !> The interpolant's rate dy/dtheta at theta.
    pure subroutine dense_rate_interface(self, theta, rate)
      import :: embedded_pair_t, wp, max_equations
      class(embedded_pair_t), intent(in) :: self
      real(wp), intent(in) :: theta
      real(wp), intent(out) :: rate(max_equations)
    end subroutine dense_rate_interface
    !> c(s): stage s is at t + c(s) h.
    pure real(wp) function node_interface(s)
      import :: wp
      integer, intent(in) :: s
    end function node_interface
    pure type(pair_shape_t) function shape_interface()
      import :: pair_shape_t
    end function shape_interface
  end interface

  type, extends(embedded_pair_t) :: dop853_t
  contains
    procedure :: stage_input => dop853_stage_input
    procedure :: finish_attempt => dop853_finish_attempt
    procedure :: build_dense => dop853_build_dense
    procedure :: dense_value => dop853_dense_value
    procedure :: dense_rate => dop853_dense_rate
    procedure, nopass :: node => dop853_node
    procedure, nopass :: shape => dop853_shape
    procedure, nopass :: info => dop853_info
  end type dop853_t

  type, extends(embedded_pair_t) :: vern9_t
  contains
    procedure :: stage_input => vern9_stage_input
    procedure :: finish_attempt => vern9_finish_attempt
    procedure :: build_dense => vern9_build_dense
    procedure :: dense_value => vern9_dense_value
    procedure :: dense_rate => vern9_dense_rate
    procedure, nopass :: node => vern9_node
    procedure, nopass :: shape => vern9_shape
    procedure, nopass :: info => vern9_info
  end type vern9_t

  !> Steps a Jacobian of the implicit method serves, unless Newton's
  !> iteration slows down before.
  integer, parameter :: jacobian_lifetime = 20

  type, extends(integrator_t) :: gauss4_t
    real(wp), allocatable :: jacobian(:, :), lu(:, :)
    integer, allocatable :: pivots(:)
    real(wp) :: lu_h = 0                      !< step the LU was made for
    integer :: steps_since_jacobian = jacobian_lifetime     !< a new Jacobian at the first step
    integer(i8) :: newton_iterations = 0
  contains
    procedure :: step => gauss4_step
    procedure, nopass :: info => gauss4_info
  end type gauss4_t

  ! ---- 2-stage Gauss-Legendre
  real(wp), parameter :: sqrt3_6 = 0.288675134594812882254574390250978727823800875635063438009_wp
  real(wp), parameter :: gl_a(2, 2) = reshape([0.25_wp, 0.25_wp + sqrt3_6, 0.25_wp - sqrt3_6, 0.25_wp], [2, 2])
  real(wp), parameter :: gl_c(2) = [0.5_wp - sqrt3_6, 0.5_wp + sqrt3_6]

contains

  subroutine new_integrator(name, integrator, err)
    character(len=*), intent(in) :: name
    class(integrator_t), allocatable, intent(out) :: integrator
    type(error_t), intent(inout) :: err
    select case (name)
    case ('rk4')
      allocate (rk4_t :: integrator)
    case ('dop853')
      allocate (dop853_t :: integrator)
    case ('vern9')
      allocate (vern9_t :: integrator)
    case ('gauss4')
      allocate (gauss4_t :: integrator)
    case default
      call set_error(err, err_input, "unknown integration method '" // name // "' (known: " // method_names() // ")")
    end select
  end subroutine new_integrator

  ! ============================================================== RK4

  subroutine rk4_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(rk4_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: y_new(:)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: k2(max_equations), k3(max_equations), k4(max_equations), stage(max_equations)
    integer :: n
    n = size(y)
    stage(:n) = y + (h/2) * f0
    call sys%rhs(t + h/2, stage(:n), k2(:n))
    self%stage_limit = stage_limit(sys, t + h/2, stage(:n), k2(:n))
    stage(:n) = y + (h/2) * k2(:n)
    call sys%rhs(t + h/2, stage(:n), k3(:n))
    if (self%stage_limit == 0) self%stage_limit = stage_limit(sys, t + h/2, stage(:n), k3(:n))
    stage(:n) = y + h * k3(:n)
    call sys%rhs(t + h, stage(:n), k4(:n))
    if (self%stage_limit == 0) self%stage_limit = stage_limit(sys, t + h, stage(:n), k4(:n))
    y_new = y + (h/6) * (f0 + 2*(k2(:n) + k3(:n)) + k4(:n))
    n_rhs = n_rhs + 3
  end subroutine rk4_step

  ! ==================================================== embedded pairs

  !> One attempt of size h; sets self%error_norm (accept when <= 1) and
  !> self%k(:, end_stage) = f(t + h, y_new); dense output is prepared lazily.
  subroutine pair_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(embedded_pair_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: y_new(:)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: start(max_equations), stage(max_equations)
    integer :: s, n
    n = size(y)
    start = 0
    start(:n) = y
    self%k(:n, 1) = f0
    do s = 2, self%end_stage()                ! the last stage input is y_new
      call self%stage_input(s, start, h, stage)
      call sys%rhs(t + self%node(s) * h, stage(:n), self%k(:n, s))
    end do
    y_new = stage(:n)
    n_rhs = n_rhs + self%attempt_calls()
    call self%finish_attempt(n, t, start, h, stage)
  end subroutine pair_step

  !> y(t_old + theta h), theta in [0, 1], for the last attempted step.
  subroutine pair_dense(self, sys, theta, y, n_rhs)
    class(embedded_pair_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(:)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: stage(max_equations)
    integer :: s, n
    n = size(y)
    if (.not. self%dense_ready) then
      if (.not. self%dense_stages_ready) then
        do s = self%end_stage() + 1, self%end_stage() + self%dense_calls()
          call self%stage_input(s, self%y_old, self%h, stage)
          call sys%rhs(self%t_old + self%node(s) * self%h, stage(:n), self%k(:n, s))
        end do
      end if
      n_rhs = n_rhs + self%dense_calls()
      call self%build_dense()
    end if
    call self%dense_value(theta, stage)
    y = stage(:n)
  end subroutine pair_dense

  !> Keep the attempt y -> y_new from t with step h and its error norm as
  !> the last one, whose dense output is prepared on demand;
  !> dense_stages_ready: its dense-output stages are in k already.
  pure subroutine pair_hold_attempt(self, t, h, y, y_new, error_norm, dense_stages_ready)
    class(embedded_pair_t), intent(inout) :: self
    real(wp), intent(in) :: t, h, y(:), y_new(:), error_norm
    logical, intent(in) :: dense_stages_ready
    self%y_old(:size(y)) = y
    self%y_new(:size(y_new)) = y_new
    self%t_old = t
    self%h = h
    self%error_norm = error_norm
    self%dense_ready = .false.
    self%dense_stages_ready = dense_stages_ready
  end subroutine pair_hold_attempt

  !> The bound on vern9's round-off floor, in units of a component's
  !> tolerance (shortest_h).
  pure real(wp) function floor_limit(atol, h)
    real(wp), intent(in) :: atol, h
    if (atol <= 0) then
      floor_limit = 1 / max(abs(h), shortest_h)
    else
      floor_limit = 1 / shortest_h
    end if
  end function floor_limit

  !> Hairer's starting step: first guess from |y|/|f|, refined with one Euler step.
  subroutine pair_initial_step(self, sys, t, y, f0, h_max, h, n_rhs)
    class(embedded_pair_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h_max
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: h
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: scale(size(y)), f1(size(y)), d0, d1, d2, h0, h1
    logical :: scaled(size(y))
    scale = self%atol + abs(y) * self%rtol
    ! pure relative control (atol = 0): a component that is exactly zero has
    ! no size to guess a step from (its relative change is infinite at once)
    scaled = scale > 0
    d0 = scaled_rms(y)
    d1 = scaled_rms(f0)
    if (d0 < 1.0e-5_wp .or. d1 < 1.0e-5_wp) then
      h0 = 1.0e-6_wp
    else
      h0 = 0.01_wp * d0 / d1
    end if
    h0 = min(h0, h_max)
    call sys%rhs(t + h0, y + h0 * f0, f1)
    n_rhs = n_rhs + 1
    d2 = scaled_rms(f1 - f0) / h0
    if (max(d1, d2) <= 1.0e-15_wp) then
      h1 = max(1.0e-6_wp, h0 * 1.0e-3_wp)
    else
      h1 = (0.01_wp / max(d1, d2))**(1.0_wp / self%control_order())
    end if
    h = min(100 * h0, h1, h_max)
    if (.not. (h > 0)) h = h0          ! f not finite at the trial point: the first guess
  contains
    !> The root mean square of v in units of scale (its scaled components),
    !> each at most tolerance_ratio_cap.
    pure real(wp) function scaled_rms(v)
      real(wp), intent(in) :: v(:)
      real(wp) :: ratio(size(v))
      ratio = merge(min(abs(v), tolerance_ratio_cap * scale) / merge(scale, 1.0_wp, scaled), 0.0_wp, scaled)
      scaled_rms = sqrt(sum(ratio**2) / size(v))
    end function scaled_rms
  end subroutine pair_initial_step

  !> The stage that is f(t + h, y_new).
  pure integer function pair_end_stage(self)
    class(embedded_pair_t), intent(in) :: self
    associate (shape => self%shape())
      pair_end_stage = shape%end_stage
    end associate
  end function pair_end_stage

  !> RHS calls of an attempt (its stages after the first, which is f0).
  pure integer function pair_attempt_calls(self)
    class(embedded_pair_t), intent(in) :: self
    pair_attempt_calls = self%end_stage() - 1
  end function pair_attempt_calls

  !> RHS calls of the dense output (its stages after end_stage).
  pure integer function pair_dense_calls(self)
    class(embedded_pair_t), intent(in) :: self
    associate (shape => self%shape())
      pair_dense_calls = shape%stages_dense - shape%end_stage
    end associate
  end function pair_dense_calls

  !> The exponent of the step control: the error estimate is O(h^control_order).
  pure integer function pair_control_order(self)
    class(embedded_pair_t), intent(in) :: self
    associate (shape => self%shape())
      pair_control_order = shape%control_order
    end associate
  end function pair_control_order

  !> The input of stage s of a pair whose tableau a(s, j) is packed by rows
  !> (its nonzero values, their columns, where each row starts): y + h sum_j
  !> a(s, j) k_j (s = end_stage: the new solution; s > end_stage:
  !> dense-output stages, from y = y_old). The sum runs in a local, so that
  !> it stays in registers and its first term loads y directly: a copy of y
  !> into point first cost a stalled store-to-load forward per stage.
  pure subroutine packed_stage_input(k, s, values, columns, rows, y, h, point)
    real(wp), intent(in) :: k(max_equations, max_pair_stages), values(*), y(max_equations), h
    integer, intent(in) :: s, columns(*), rows(*)
    real(wp), intent(out) :: point(max_equations)
    real(wp) :: total(max_equations)
    integer :: m
    m = rows(s)
    total = y + (h * values(m)) * k(:, columns(m))
    do m = rows(s) + 1, rows(s + 1) - 1
      total = total + (h * values(m)) * k(:, columns(m))
    end do
    point = total
  end subroutine packed_stage_input

  ! =========================================================== DOP853

  pure type(pair_shape_t) function dop853_shape() result(shape)
    shape = pair_shape_t(end_stage=dop853_end_stage, stages_dense=dop853_stages_dense, control_order=8)
  end function dop853_shape

  pure real(wp) function dop853_node(s)
    integer, intent(in) :: s
    dop853_node = c853(s)
  end function dop853_node

  pure subroutine dop853_stage_input(self, s, y, h, point)
    class(dop853_t), intent(in) :: self
    integer, intent(in) :: s
    real(wp), intent(in) :: y(max_equations), h
    real(wp), intent(out) :: point(max_equations)
    call packed_stage_input(self%k, s, a_value, a_column, a_row, y, h, point)
  end subroutine dop853_stage_input

  !> Error norm of the attempt y -> y_new of an n-equation system (stages 1
  !> to end_stage in self%k): Hairer's mix of the 5th- and 3rd-order
  !> estimates, each component in units of atol + rtol max(|y|, |y_new|)
  !> (tolerance_ratio_cap).
  pure subroutine dop853_finish_attempt(self, n, t, y, h, y_new)
    class(dop853_t), intent(inout) :: self
    integer, intent(in) :: n
    real(wp), intent(in) :: t, y(max_equations), h, y_new(max_equations)
    real(wp) :: err5(max_equations), err3(max_equations), scale(max_equations), e5_norm2, e3_norm2, error_norm
    integer :: s
    err5 = 0
    !GCC$ unroll 16
    do s = 1, dop853_end_stage           ! unrolled, the tests on e5 fold away
      if (in_error_estimate(s)) err5 = err5 + e5(s) * self%k(:, s)
    end do
    err3 = (y_new - y) / h - bhh(1) * self%k(:, 1) - bhh(2) * self%k(:, 9) - bhh(3) * self%k(:, 12)
    scale(:n) = max(self%atol + max(abs(y(:n)), abs(y_new(:n))) * self%rtol, tiny(1.0_wp))
    e5_norm2 = sum((min(abs(err5(:n)), tolerance_ratio_cap * scale(:n)) / scale(:n))**2)
    e3_norm2 = sum((min(abs(err3(:n)), tolerance_ratio_cap * scale(:n)) / scale(:n))**2)
    if (is_zero(e5_norm2) .and. is_zero(e3_norm2)) then
      error_norm = 0
    else
      error_norm = abs(h) * e5_norm2 / sqrt((e5_norm2 + 0.01_wp * e3_norm2) * n)
    end if
    call self%hold_attempt(t, h, y, y_new, error_norm, dense_stages_ready=.false.)
  end subroutine dop853_finish_attempt

  !> The interpolant's coefficients, once the dense-output stages are in
  !> self%k: Hairer's form y_old + theta (r1 + theta1 (r2 + theta (r3 + ...
  !> r7))), theta1 = 1 - theta, rewritten in powers of theta, y_old + sum_i
  !> c_i theta^i, so that a value or a rate is a tree of independent
  !> products (Estrin) rather than a chain of fourteen dependent operations.
  pure subroutine dop853_build_dense(self)
    class(dop853_t), intent(inout) :: self
    real(wp) :: delta(max_equations), rows(max_equations, 7), stage(max_equations)
    integer :: s, i
    delta = self%y_new - self%y_old
    rows = 0                   ! local, fixed-size: kept in registers
    rows(:, 1) = delta
    rows(:, 2) = self%h * self%k(:, 1) - delta
    rows(:, 3) = 2 * delta - self%h * (self%k(:, dop853_end_stage) + self%k(:, 1))
    do s = 1, dop853_stages_dense
      if (.not. in_dense_output(s)) cycle
      stage = self%k(:, s)
      do i = 1, 4
        rows(:, 3 + i) = rows(:, 3 + i) + (self%h * d853(i, s)) * stage
      end do
    end do
    ! theta (r1 + theta1 (r2 + theta (r3 + theta1 (r4 + ... theta r7)))) expanded
    associate (c => self%dense_coefficients)
      c(:, 0) = rows(:, 1) + rows(:, 2)
      c(:, 1) = (rows(:, 3) - rows(:, 2)) + rows(:, 4)
      c(:, 2) = (rows(:, 5) + rows(:, 6)) - (rows(:, 3) + 2 * rows(:, 4))
      c(:, 3) = (rows(:, 4) + rows(:, 7)) - (2 * rows(:, 5) + 3 * rows(:, 6))
      c(:, 4) = (rows(:, 5) + 3 * rows(:, 6)) - 3 * rows(:, 7)
      c(:, 5) = 3 * rows(:, 7) - rows(:, 6)
      c(:, 6) = -rows(:, 7)
    end associate
    self%dense_ready = .true.
  end subroutine dop853_build_dense

  !> y(t_old + theta h), theta in [0, 1], of the last attempt's interpolant.
  pure subroutine dop853_dense_value(self, theta, y)
    class(dop853_t), intent(in) :: self
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(max_equations)
    real(wp) :: theta2, theta4
    theta2 = theta * theta
    theta4 = theta2 * theta2
    associate (c => self%dense_coefficients)
      y = self%y_old + theta * (((c(:, 0) + theta * c(:, 1)) + theta2 * (c(:, 2) + theta * c(:, 3))) &
                                + theta4 * ((c(:, 4) + theta * c(:, 5)) + theta2 * c(:, 6)))
    end associate
  end subroutine dop853_dense_value

  !> dy/dtheta = h dy/dt of the interpolant at t_old + theta h.
  pure subroutine dop853_dense_rate(self, theta, rate)
    class(dop853_t), intent(in) :: self
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: rate(max_equations)
    real(wp) :: theta2, theta4
    theta2 = theta * theta
    theta4 = theta2 * theta2
    associate (c => self%dense_coefficients)
      rate = ((c(:, 0) + (2 * theta) * c(:, 1)) + theta2 * (3 * c(:, 2) + (4 * theta) * c(:, 3))) &
             + theta4 * ((5 * c(:, 4) + (6 * theta) * c(:, 5)) + (7 * theta2) * c(:, 6))
    end associate
  end subroutine dop853_dense_rate

  ! ============================================================ Vern9

  pure type(pair_shape_t) function vern9_shape() result(shape)
    shape = pair_shape_t(end_stage=vern9_end_stage, stages_dense=vern9_stages_dense, control_order=9)
  end function vern9_shape

  pure real(wp) function vern9_node(s)
    integer, intent(in) :: s
    vern9_node = c9(s)
  end function vern9_node

  pure subroutine vern9_stage_input(self, s, y, h, point)
    class(vern9_t), intent(in) :: self
    integer, intent(in) :: s
    real(wp), intent(in) :: y(max_equations), h
    real(wp), intent(out) :: point(max_equations)
    call packed_stage_input(self%k, s, v9_value, v9_column, v9_row, y, h, point)
  end subroutine vern9_stage_input

  !> Error norm of the attempt y -> y_new of an n-equation system (stages 1
  !> to 16 in self%k): the root mean square of h sum_s e8(s) k_s, the
  !> difference of the 8th- and 9th-order solutions (no smaller than
  !> estimate_round_off sum_s |e8(s) k_s|; with atol = 0 up to the
  !> tolerance, shortest_h), in units of atol + rtol max(|y|, |y_new|)
  !> (tolerance_ratio_cap).
  pure subroutine vern9_finish_attempt(self, n, t, y, h, y_new)
    class(vern9_t), intent(inout) :: self
    integer, intent(in) :: n
    real(wp), intent(in) :: t, y(max_equations), h, y_new(max_equations)
    real(wp) :: err(max_equations), noise(max_equations), scale(max_equations), norm2
    integer :: s
    err = 0
    noise = 0
    !GCC$ unroll 16
    do s = 1, size(e8)                   ! unrolled, the tests on e8 fold away
      if (v9_in_error_estimate(s)) then
        err = err + e8(s) * self%k(:, s)
        noise = noise + abs(e8(s) * self%k(:, s))
      end if
    end do
    scale(:n) = max(self%atol + max(abs(y(:n)), abs(y_new(:n))) * self%rtol, tiny(1.0_wp))
    err(:n) = max(abs(err(:n)), min(estimate_round_off * noise(:n), scale(:n) * floor_limit(self%atol, h)))
    norm2 = sum((min(err(:n), tolerance_ratio_cap * scale(:n)) / scale(:n))**2)
    call self%hold_attempt(t, h, y, y_new, abs(h) * sqrt(norm2 / n), dense_stages_ready=.false.)
  end subroutine vern9_finish_attempt

  !> The interpolant's coefficients, once the dense-output stages are in
  !> self%k: c_j = h sum_s q98(j, s) k_s, the coefficient of x^j, x = 2
  !> theta - 1. One coefficient at a time, its sum in registers; the loops
  !> unrolled: the weights are constants, the stages without one fold away.
  pure subroutine vern9_build_dense(self)
    class(vern9_t), intent(inout) :: self
    real(wp) :: total(max_equations)
    integer :: s, j
    !GCC$ unroll 9
    do j = 0, 8
      total = 0
      !GCC$ unroll 21
      do s = 1, vern9_stages_dense
        if (v9_in_dense_output(s)) total = total + q98(j, s) * self%k(:, s)
      end do
      self%dense_coefficients(:, j) = self%h * total
    end do
    self%dense_ready = .true.
  end subroutine vern9_build_dense

  !> y(t_old + theta h), theta in [0, 1], of the last attempt's interpolant
  !> (Estrin's scheme in x = 2 theta - 1).
  pure subroutine vern9_dense_value(self, theta, y)
    class(vern9_t), intent(in) :: self
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(max_equations)
    real(wp) :: x, x2, x4
    x = 2 * theta - 1
    x2 = x * x
    x4 = x2 * x2
    associate (c => self%dense_coefficients)
      y = self%y_old + ((((c(:, 0) + x * c(:, 1)) + x2 * (c(:, 2) + x * c(:, 3))) &
                         + x4 * ((c(:, 4) + x * c(:, 5)) + x2 * (c(:, 6) + x * c(:, 7)))) + (x4 * x4) * c(:, 8))
    end associate
  end subroutine vern9_dense_value

  !> dy/dtheta = h dy/dt of the interpolant at t_old + theta h (dy/dx 2).
  pure subroutine vern9_dense_rate(self, theta, rate)
    class(vern9_t), intent(in) :: self
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: rate(max_equations)
    real(wp) :: x, x2, x4
    x = 2 * theta - 1
    x2 = x * x
    x4 = x2 * x2
    associate (c => self%dense_coefficients)
      rate = 2 * (((c(:, 1) + (2 * x) * c(:, 2)) + x2 * (3 * c(:, 3) + (4 * x) * c(:, 4))) &
                  + x4 * ((5 * c(:, 5) + (6 * x) * c(:, 6)) + x2 * (7 * c(:, 7) + (8 * x) * c(:, 8))))
    end associate
  end subroutine vern9_dense_rate

  ! ========================================================== Gauss4

  !> Stage increments Z solve Z_i = h sum_j a_ij f(y + Z_j) by simplified
  !> Newton with the LU of I - h (A x J), J a forward-difference Jacobian
  !> refreshed every 20 steps or when convergence slows. Iterated to
  !> round-off, so that the method stays symmetric.
  subroutine gauss4_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(gauss4_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: y_new(:)
    integer(i8), intent(inout) :: n_rhs
    integer :: n, iteration, i, j, info
    real(wp) :: z(max_equations, 2), f(max_equations, 2), residual(2 * max_equations, 1), stage(max_equations)
    real(wp) :: scale, size_now, size_before
    n = size(y)
    if (self%steps_since_jacobian >= jacobian_lifetime .or. .not. equals(h, self%lu_h)) call refresh(self)
    self%steps_since_jacobian = self%steps_since_jacobian + 1
    do i = 1, 2
      z(:n, i) = gl_c(i) * h * f0
    end do
    scale = 1.0e-3_wp * max(maxval(abs(y)), tiny(1.0_wp))
    size_before = huge(1.0_wp)
    do iteration = 1, 12
      do i = 1, 2
        stage(:n) = y + z(:n, i)
        call sys%rhs(t + gl_c(i) * h, stage(:n), f(:n, i))
      end do
      n_rhs = n_rhs + 2
      do i = 1, 2
        residual((i - 1) * n + 1:i * n, 1) = -(z(:n, i) - h * (gl_a(i, 1) * f(:n, 1) + gl_a(i, 2) * f(:n, 2)))
      end do
      call dgetrs('N', 2 * n, 1, self%lu, 2 * n, self%pivots, residual, 2 * max_equations, info)
      do i = 1, 2
        z(:n, i) = z(:n, i) + residual((i - 1) * n + 1:i * n, 1)
      end do
      self%newton_iterations = self%newton_iterations + 1
      size_now = maxval(abs(residual(:2 * n, 1)))
      if (size_now <= 4 * epsilon(1.0_wp) * scale .or. (size_now >= size_before .and. iteration > 3)) exit
      size_before = size_now
      if (iteration == 6) self%steps_since_jacobian = jacobian_lifetime     ! slow: new Jacobian next step
    end do
    ! y_new = y + h sum b_i f_i, with f_i from the converged stages
    self%stage_limit = 0
    do i = 1, 2
      stage(:n) = y + z(:n, i)
      call sys%rhs(t + gl_c(i) * h, stage(:n), f(:n, i))
      if (self%stage_limit == 0) self%stage_limit = stage_limit(sys, t + gl_c(i) * h, stage(:n), f(:n, i))
    end do
    n_rhs = n_rhs + 2
    y_new = y + (h / 2) * (f(:n, 1) + f(:n, 2))
    ! the last correction still far above round-off (amplified by the
    ! conditioning of the right-hand side): no solution near the start
    if (size_now > sqrt(epsilon(1.0_wp)) * scale) self%stage_limit = no_step_solution

  contains

    subroutine refresh(self)
      class(gauss4_t), intent(inout) :: self
      real(wp) :: delta, f_plus(max_equations), y_plus(max_equations)
      if (.not. allocated(self%jacobian)) allocate (self%jacobian(n, n), self%lu(2 * n, 2 * n), self%pivots(2 * n))
      do j = 1, n
        delta = sqrt(epsilon(1.0_wp)) * max(abs(y(j)), 1.0_wp)
        y_plus(:n) = y
        y_plus(j) = y(j) + delta
        call sys%rhs(t, y_plus(:n), f_plus(:n))
        self%jacobian(:, j) = (f_plus(:n) - f0) / delta
      end do
      n_rhs = n_rhs + n
      self%lu = 0
      do i = 1, 2
        do j = 1, 2
          self%lu((i - 1) * n + 1:i * n, (j - 1) * n + 1:j * n) = -h * gl_a(i, j) * self%jacobian
        end do
      end do
      do i = 1, 2 * n
        self%lu(i, i) = self%lu(i, i) + 1
      end do
      call dgetrf(2 * n, 2 * n, self%lu, 2 * n, self%pivots, info)
      self%lu_h = h
      self%steps_since_jacobian = 0
    end subroutine refresh
  end subroutine gauss4_step

  !> The largest |lambda h| on the imaginary axis for which the method is
  !> stable (the rolling ball's linearised motion is oscillatory): RK4 2 sqrt(2);
  !> the Gauss method is A-stable; the embedded pairs control their steps.
  pure real(wp) function stability_limit(integrator)
    class(integrator_t), intent(in) :: integrator
    select type (integrator)
    type is (rk4_t)
      stability_limit = 2 * sqrt(2.0_wp)
    class default
      stability_limit = huge(1.0_wp)
    end select
  end function stability_limit

  ! ===================================================== descriptions

  pure type(method_info_t) function rk4_info() result(info)
    info = methods(1)
  end function rk4_info

  pure type(method_info_t) function dop853_info() result(info)
    info = methods(2)
  end function dop853_info

  pure type(method_info_t) function vern9_info() result(info)
    info = methods(3)
  end function vern9_info

  pure type(method_info_t) function gauss4_info() result(info)
    info = methods(4)
  end function gauss4_info

  !> The methods' names, for messages: 'rk4 dop853 vern9 gauss4'.
  pure function method_names() result(names)
    character(len=sum(len_trim(methods%name)) + size(methods) - 1) :: names
    integer :: k, at
    names = methods(1)%name
    at = len_trim(methods(1)%name)
    do k = 2, size(methods)
      names(at + 1:) = ' ' // methods(k)%name
      at = at + 1 + len_trim(methods(k)%name)
    end do
  end function method_names

  !> The row of methods named `name` (name blank where there is none).
  pure type(method_info_t) function method_info(name) result(info)
    character(len=*), intent(in) :: name
    integer :: k
    info = method_info_t('', '', '', .false., '')
    k = findloc(methods%name, name, dim=1)
    if (k > 0) info = methods(k)
  end function method_info
end module ellroll_integrators
