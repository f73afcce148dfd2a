!> One-step integrators behind one interface (after rklib): each is a type
!> that knows its name, kind and order. A step receives f(t, y) from the
!> caller (the previous step's end-point derivative, which the run loop
!> needs anyway for derived outputs).
!>
!>   rk4     classical Runge-Kutta, fixed step, order 4 (the source paper's method)
!>   dop853  Dormand-Prince 8(5,3), adaptive, with 7th-order dense output
!>   gauss4  2-stage Gauss-Legendre, implicit, symmetric, order 4 (simplified
!>           Newton, LAPACK LU): bounded energy error over long runs
module ellroll_integrators
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero, equals
  use ellroll_lapack, only: dgetrf, dgetrs
  use ellroll_ode, only: ode_system_t, stage_limit, no_step_solution
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_dop853_tableau, only: stages, stages_dense, end_stage, first_dense_stage, c853, a_value, a_column, a_row, &
      e5, bhh, d853, in_error_estimate, in_dense_output
  implicit none
  private

  public :: integrator_t, rk4_t, dop853_t, gauss4_t, new_integrator, method_names, stability_limit
  public :: method_info_t, methods, method_info

  !> Largest system the integrators take: their work arrays are fixed-size
  !> (on the stack), so a step allocates nothing. DOP853 works on whole
  !> columns of this length, entries past the system's size kept zero: the
  !> loops have a length known at compile time (unrolled, vectorized) and
  !> the system's entries come out as if computed alone.
  integer, parameter, public :: max_equations = 8

  !> What a method is, for users and for the code that picks how to run it.
  type :: method_info_t
    character(len=8) :: name
    character(len=10) :: kind          !< fixed, adaptive or symmetric
    character(len=24) :: order         !< the order, as a user reads it
    logical :: adaptive                !< the step is chosen by error control (dt is the largest step)
  end type method_info_t

  type(method_info_t), parameter :: methods(3) = [ &
      method_info_t('rk4', 'fixed', '4', .false.), &
      method_info_t('dop853', 'adaptive', '8(5,3), dense output 7', .true.), &
      method_info_t('gauss4', 'symmetric', '4', .false.)]

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

  !> The step of an adaptive method is an attempt: it also returns the error
  !> norm (<= 1: accept) and keeps f at the new point as its last stage
  !> (k(:, end_stage)). Dense output covers the last attempted step. The
  !> stage arithmetic is public (stage_input, finish_attempt, build_dense,
  !> dense_value) so that a fused step of one system shares it.
  type, extends(integrator_t) :: dop853_t
    real(wp) :: rtol = 1.0e-9_wp, atol = 1.0e-12_wp
    real(wp) :: error_norm = 0
    real(wp) :: k(max_equations, 16) = 0      !< stages of the last attempt
    real(wp) :: y_old(max_equations) = 0, y_new(max_equations) = 0
    !> the interpolant y_old + sum_i c(:, i - 1) theta^i, theta = (t - t_old) / h
    real(wp) :: dense_coefficients(max_equations, 0:6) = 0
    real(wp) :: t_old = 0, h = 0
    logical :: dense_ready = .false.
    !> the dense-output stages are in k already (computed with other lanes of a batch)
    logical :: dense_stages_ready = .false.
  contains
    procedure :: step => dop853_step
    procedure :: dense => dop853_dense
    procedure :: initial_step => dop853_initial_step
    procedure :: stage_input => dop853_stage_input
    procedure :: finish_attempt => dop853_finish_attempt
    procedure :: hold_attempt => dop853_hold_attempt
    procedure :: build_dense => dop853_build_dense
    procedure :: dense_value => dop853_dense_value
    procedure :: dense_rate => dop853_dense_rate
    procedure, nopass :: info => dop853_info
  end type dop853_t

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

  ! =========================================================== DOP853

  !> One attempt of size h; sets self%error_norm (accept when <= 1) and
  !> self%k(:, end_stage) = f(t + h, y_new); dense output is prepared lazily.
  subroutine dop853_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(dop853_t), intent(inout) :: self
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
    do s = 2, end_stage                       ! the last stage input is y_new
      call self%stage_input(s, start, h, stage)
      call sys%rhs(t + c853(s) * h, stage(:n), self%k(:n, s))
    end do
    y_new = stage(:n)
    n_rhs = n_rhs + stages
    call self%finish_attempt(n, t, start, h, stage)
  end subroutine dop853_step

  !> The input of stage s: y + h sum_j a(s, j) k_j over the nonzero a(s, j)
  !> (s = end_stage: the new solution; s > end_stage: dense-output stages,
  !> from y = y_old). The sum runs in a local, so that it stays in registers
  !> and its first term loads y directly: a copy of y into point first cost
  !> a stalled store-to-load forward per stage.
  pure subroutine dop853_stage_input(self, s, y, h, point)
    class(dop853_t), intent(in) :: self
    integer, intent(in) :: s
    real(wp), intent(in) :: y(max_equations), h
    real(wp), intent(out) :: point(max_equations)
    real(wp) :: total(max_equations)
    integer :: m
    m = a_row(s)
    total = y + (h * a_value(m)) * self%k(:, a_column(m))
    do m = a_row(s) + 1, a_row(s + 1) - 1
      total = total + (h * a_value(m)) * self%k(:, a_column(m))
    end do
    point = total
  end subroutine dop853_stage_input

  !> Error norm of the attempt y -> y_new of an n-equation system (stages 1
  !> to end_stage in self%k): Hairer's mix of the 5th- and 3rd-order estimates.
  pure subroutine dop853_finish_attempt(self, n, t, y, h, y_new)
    class(dop853_t), intent(inout) :: self
    integer, intent(in) :: n
    real(wp), intent(in) :: t, y(max_equations), h, y_new(max_equations)
    real(wp) :: err5(max_equations), err3(max_equations), scale(max_equations), e5_norm2, e3_norm2, error_norm
    integer :: s
    err5 = 0
    !GCC$ unroll 16
    do s = 1, end_stage                  ! unrolled, the tests on e5 fold away
      if (in_error_estimate(s)) err5 = err5 + e5(s) * self%k(:, s)
    end do
    err3 = (y_new - y) / h - bhh(1) * self%k(:, 1) - bhh(2) * self%k(:, 9) - bhh(3) * self%k(:, 12)
    scale(:n) = self%atol + max(abs(y(:n)), abs(y_new(:n))) * self%rtol
    e5_norm2 = sum((err5(:n) / scale(:n))**2)
    e3_norm2 = sum((err3(:n) / scale(:n))**2)
    if (is_zero(e5_norm2) .and. is_zero(e3_norm2)) then
      error_norm = 0
    else
      error_norm = abs(h) * e5_norm2 / sqrt((e5_norm2 + 0.01_wp * e3_norm2) * n)
    end if
    call self%hold_attempt(t, h, y, y_new, error_norm, dense_stages_ready=.false.)
  end subroutine dop853_finish_attempt

  !> Keep the attempt y -> y_new from t with step h and its error norm as
  !> the last one, whose dense output is prepared on demand;
  !> dense_stages_ready: its dense-output stages are in k already.
  pure subroutine dop853_hold_attempt(self, t, h, y, y_new, error_norm, dense_stages_ready)
    class(dop853_t), intent(inout) :: self
    real(wp), intent(in) :: t, h, y(:), y_new(:), error_norm
    logical, intent(in) :: dense_stages_ready
    self%y_old(:size(y)) = y
    self%y_new(:size(y_new)) = y_new
    self%t_old = t
    self%h = h
    self%error_norm = error_norm
    self%dense_ready = .false.
    self%dense_stages_ready = dense_stages_ready
  end subroutine dop853_hold_attempt

  !> y(t_old + theta h), theta in [0, 1], for the last attempted step.
  subroutine dop853_dense(self, sys, theta, y, n_rhs)
    class(dop853_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(:)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: stage(max_equations)
    integer :: s, n
    n = size(y)
    if (.not. self%dense_ready) then
      if (.not. self%dense_stages_ready) then
        do s = first_dense_stage, stages_dense
          call self%stage_input(s, self%y_old, self%h, stage)
          call sys%rhs(self%t_old + c853(s) * self%h, stage(:n), self%k(:n, s))
        end do
      end if
      n_rhs = n_rhs + (stages_dense - end_stage)
      call self%build_dense()
    end if
    call self%dense_value(theta, stage)
    y = stage(:n)
  end subroutine dop853_dense

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
    rows(:, 3) = 2 * delta - self%h * (self%k(:, end_stage) + self%k(:, 1))
    do s = 1, stages_dense
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

  !> Hairer's starting step: first guess from |y|/|f|, refined with one Euler step.
  subroutine dop853_initial_step(self, sys, t, y, f0, h_max, h, n_rhs)
    class(dop853_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h_max
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: h
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: scale(size(y)), f1(size(y)), d0, d1, d2, h0, h1
    scale = self%atol + abs(y) * self%rtol
    d0 = sqrt(sum((y / scale)**2) / size(y))
    d1 = sqrt(sum((f0 / scale)**2) / size(y))
    if (d0 < 1.0e-5_wp .or. d1 < 1.0e-5_wp) then
      h0 = 1.0e-6_wp
    else
      h0 = 0.01_wp * d0 / d1
    end if
    h0 = min(h0, h_max)
    call sys%rhs(t + h0, y + h0 * f0, f1)
    n_rhs = n_rhs + 1
    d2 = sqrt(sum(((f1 - f0) / scale)**2) / size(y)) / h0
    if (max(d1, d2) <= 1.0e-15_wp) then
      h1 = max(1.0e-6_wp, h0 * 1.0e-3_wp)
    else
      h1 = (0.01_wp / max(d1, d2))**(1.0_wp / 8)
    end if
    h = min(100 * h0, h1, h_max)
  end subroutine dop853_initial_step

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
  !> the Gauss method is A-stable; DOP853 controls its steps.
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

  pure type(method_info_t) function gauss4_info() result(info)
    info = methods(3)
  end function gauss4_info

  !> The methods' names, for messages: 'rk4 dop853 gauss4'.
  pure function method_names() result(names)
    character(len=:), allocatable :: names
    integer :: k
    names = trim(methods(1)%name)
    do k = 2, size(methods)
      names = names // ' ' // trim(methods(k)%name)
    end do
  end function method_names

  !> The row of methods named `name` (name blank where there is none).
  pure type(method_info_t) function method_info(name) result(info)
    character(len=*), intent(in) :: name
    integer :: k
    info = method_info_t('', '', '', .false.)
    k = findloc(methods%name, name, dim=1)
    if (k > 0) info = methods(k)
  end function method_info
end module ellroll_integrators
