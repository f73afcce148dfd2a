!> An explicit embedded Runge-Kutta pair with dense output, apart from its
!> tableau: the attempt (its stages, the new point, the error norm), the
!> dense output of the last attempt, Hairer's starting step. A pair
!> (ellroll_dop853, ellroll_vern9) gives its tableau's arithmetic: its stage
!> inputs, its scaled error estimates and their norm, its interpolant.
!>
!> The pairs' arithmetic works on columns of `width` values: the components
!> of one system (one column per stage; entries past the system's size kept
!> zero), or one component of `width` systems side by side (SIMD lanes: one
!> column per component and stage). A stage s's values are k(:, i, s), its
!> column i. The loops have a length known at compile time (unrolled,
!> vectorized), and one system's entries come out as if computed alone: a
!> fused step of one system and of several (ellroll_ball_steppers) run the
!> same arithmetic.
module ellroll_embedded_pair
  use ellroll_kinds, only: wp, i8
  use ellroll_ode, only: ode_system_t
  use ellroll_integrator, only: integrator_t, max_equations
  implicit none
  private

  public :: embedded_pair_t, pair_shape_t, floor_limit, packed_stage_columns

  !> The length of a column (see above).
  integer, parameter, public :: width = max_equations

  !> Stages of the largest embedded pair with its dense-output stages (vern9).
  integer, parameter, public :: max_pair_stages = 21

  !> Error estimates of the pair with the most of them (DOP853: its 5th- and 3rd-order ones).
  integer, parameter, public :: max_estimates = 2

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
  !> short enough step of any error: ellroll_step_control's judged_norm).
  real(wp), parameter, public :: tolerance_ratio_cap = 1.0e150_wp

  !> An embedded pair's stage input is held within +-stage_clamp in every
  !> component (every system's: the ball rolling or sliding). Only a step
  !> far too long for the motion leaves that range (|n| is 1 at a step's
  !> start, and no valid case turns at 1e20 rad/s or slides at 1e20 m/s):
  !> Hairer's starting step may move the state by more than its own size,
  !> and the quadratic growth of omega' then takes the later stages past
  !> overflow. Clamped, they stay finite (the model's terms are of degree
  !> five at most in the state), and the error norm rejects the attempt.
  real(wp), parameter, public :: stage_clamp = 1.0e20_wp

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
  !> step. The stage arithmetic is public (stage_columns, finish_attempt,
  !> error_norms_across, build_dense, dense_value) so that a fused step of
  !> one system or of several shares it.
  type, abstract, extends(integrator_t) :: embedded_pair_t
    real(wp) :: rtol = 1.0e-9_wp, atol = 1.0e-12_wp
    real(wp) :: error_norm = 0
    real(wp) :: k(width, max_pair_stages) = 0      !< stages of the last attempt
    real(wp) :: y_old(width) = 0, y_new(width) = 0
    !> the interpolant's coefficients (dop853: y_old + sum_i c(:, i - 1)
    !> theta^i; vern9: y_old + sum_i c(:, i) (2 theta - 1)^i), theta = (t - t_old) / h
    real(wp) :: dense_coefficients(width, 0:8) = 0
    real(wp) :: t_old = 0, h = 0
    logical :: dense_ready = .false.
    !> the dense-output stages are in k already (computed with other lanes of a batch)
    logical :: dense_stages_ready = .false.
  contains
    procedure :: step => pair_step
    procedure :: dense => pair_dense
    procedure :: initial_step => pair_initial_step
    procedure :: hold_attempt => pair_hold_attempt
    procedure :: finish_attempt => pair_finish_attempt
    procedure :: error_norms_across => pair_error_norms_across
    procedure :: end_stage => pair_end_stage
    procedure :: attempt_calls => pair_attempt_calls
    procedure :: dense_calls => pair_dense_calls
    procedure :: control_order => pair_control_order
    procedure(stage_columns_interface), deferred, nopass :: stage_columns
    procedure(scaled_errors_interface), deferred, nopass :: scaled_errors
    procedure(error_norms_interface), deferred, nopass :: error_norms
    procedure(build_dense_interface), deferred :: build_dense
    procedure(dense_value_interface), deferred :: dense_value
    procedure(dense_rate_interface), deferred :: dense_rate
    procedure(node_interface), deferred, nopass :: node
    procedure(shape_interface), deferred, nopass :: shape
  end type embedded_pair_t

  abstract interface
    !> The inputs of stage s = `stage`, y + h sum_j a(s, j) k_j, of `columns`
    !> columns (s = end_stage: the new point; s > end_stage: dense-output
    !> stages, from y = y_old).
    pure subroutine stage_columns_interface(stage, columns, k, y, h, point)
      import :: wp, width
      integer, intent(in) :: stage, columns
      real(wp), intent(in) :: k(width, columns, *), y(width, columns), h(width)
      real(wp), intent(out) :: point(width, columns)
    end subroutine stage_columns_interface
    !> The error estimates of column i of an attempt y -> y_new (stages 1 to
    !> end_stage in k), each in units of its tolerance atol + rtol max(|y|,
    !> |y_new|) and at most tolerance_ratio_cap: errors(:, e) for the pair's
    !> estimates e, 0 for e past them.
    pure subroutine scaled_errors_interface(i, columns, k, y, y_new, h, rtol, atol, errors)
      import :: wp, width, max_estimates
      integer, intent(in) :: i, columns
      real(wp), intent(in) :: k(width, columns, *), y(width, columns), y_new(width, columns)
      real(wp), intent(in) :: h(width), rtol(width), atol(width)
      real(wp), intent(out) :: errors(width, max_estimates)
    end subroutine scaled_errors_interface
    !> The error norm of each attempt of step h(l) from the sums over its n
    !> components of its squared scaled errors, sums(l, e).
    pure subroutine error_norms_interface(n, h, sums, norms)
      import :: wp, width, max_estimates
      integer, intent(in) :: n
      real(wp), intent(in) :: h(width), sums(width, max_estimates)
      real(wp), intent(out) :: norms(width)
    end subroutine error_norms_interface
    !> The interpolant's coefficients, once the dense-output stages are in self%k.
    pure subroutine build_dense_interface(self)
      import :: embedded_pair_t
      class(embedded_pair_t), intent(inout) :: self
    end subroutine build_dense_interface
    !> The interpolant's value at theta.
    pure subroutine dense_value_interface(self, theta, y)
      import :: embedded_pair_t, wp, width
      class(embedded_pair_t), intent(in) :: self
      real(wp), intent(in) :: theta
      real(wp), intent(out) :: y(width)
    end subroutine dense_value_interface
    !> The interpolant's rate dy/dtheta at theta.
    pure subroutine dense_rate_interface(self, theta, rate)
      import :: embedded_pair_t, wp, width
      class(embedded_pair_t), intent(in) :: self
      real(wp), intent(in) :: theta
      real(wp), intent(out) :: rate(width)
    end subroutine dense_rate_interface
    !> c(s): stage s = `stage` is at t + c(s) h.
    pure real(wp) function node_interface(stage)
      import :: wp
      integer, intent(in) :: stage
    end function node_interface
    pure type(pair_shape_t) function shape_interface()
      import :: pair_shape_t
    end function shape_interface
  end interface

contains

  !> One attempt of size h; sets self%error_norm (accept when <= 1) and
  !> self%k(:, end_stage) = f(t + h, y_new); dense output is prepared lazily.
  subroutine pair_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(embedded_pair_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: y_new(:)
    integer(i8), intent(inout) :: n_rhs
    real(wp) :: start(width), stage(width), steps(width)
    integer :: s, n
    n = size(y)
    start = 0
    start(:n) = y
    steps = h
    self%k(:n, 1) = f0
    do s = 2, self%end_stage()                ! the last stage input is y_new
      call self%stage_columns(s, 1, self%k, start, steps, stage)
      if (.not. all(abs(stage(:n)) <= stage_clamp)) stage(:n) = min(max(stage(:n), -stage_clamp), stage_clamp)
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
    real(wp) :: stage(width), steps(width)
    integer :: s, n
    n = size(y)
    if (.not. self%dense_ready) then
      if (.not. self%dense_stages_ready) then
        steps = self%h
        do s = self%end_stage() + 1, self%end_stage() + self%dense_calls()
          call self%stage_columns(s, 1, self%k, self%y_old, steps, stage)
          call sys%rhs(self%t_old + self%node(s) * self%h, stage(:n), self%k(:n, s))
        end do
      end if
      n_rhs = n_rhs + self%dense_calls()
      call self%build_dense()
    end if
    call self%dense_value(theta, stage)
    y = stage(:n)
  end subroutine pair_dense

  !> The error norm of the attempt y -> y_new of an n-equation system
  !> (stages 1 to end_stage in self%k), kept with the attempt (hold_attempt).
  pure subroutine pair_finish_attempt(self, n, t, y, h, y_new)
    class(embedded_pair_t), intent(inout) :: self
    integer, intent(in) :: n
    real(wp), intent(in) :: t, y(width), h, y_new(width)
    real(wp) :: errors(width, max_estimates), sums(width, max_estimates), norms(width), steps(width)
    real(wp) :: rtol(width), atol(width)
    integer :: e
    steps = h
    rtol = self%rtol
    atol = self%atol
    call self%scaled_errors(1, 1, self%k, y, y_new, steps, rtol, atol, errors)
    sums = 0
    do e = 1, max_estimates
      sums(1, e) = sum(errors(:n, e)**2)
    end do
    call self%error_norms(n, steps, sums, norms)
    call self%hold_attempt(t, h, y, y_new, norms(1), dense_stages_ready=.false.)
  end subroutine pair_finish_attempt

  !> The error norms of `width` attempts side by side (SIMD lanes), each of
  !> an n-component system: column i of k (each stage), y and y_new holds
  !> component i of every attempt.
  pure subroutine pair_error_norms_across(self, n, k, y, y_new, h, rtol, atol, norms)
    class(embedded_pair_t), intent(in) :: self
    integer, intent(in) :: n
    real(wp), intent(in) :: k(width, n, *), y(width, n), y_new(width, n), h(width), rtol(width), atol(width)
    real(wp), intent(out) :: norms(width)
    real(wp) :: errors(width, max_estimates), sums(width, max_estimates)
    integer :: i
    sums = 0
    do i = 1, n
      call self%scaled_errors(i, n, k, y, y_new, h, rtol, atol, errors)
      sums = sums + errors**2
    end do
    call self%error_norms(n, h, sums, norms)
  end subroutine pair_error_norms_across

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

  !> The bound on a round-off floor of an error estimate, in units of a
  !> component's tolerance (shortest_h).
  elemental real(wp) function floor_limit(atol, h)
    real(wp), intent(in) :: atol, h
    floor_limit = 1 / merge(max(abs(h), shortest_h), shortest_h, atol <= 0)
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

  !> The inputs of stage s of a pair whose tableau a(s, j) is packed by rows
  !> (its nonzero values, their columns, where each row starts), of
  !> `columns` columns: y + h sum_j a(s, j) k_j. The sum runs in a local,
  !> so that it stays in registers and its first term loads y directly: a
  !> copy of y into point first cost a stalled store-to-load forward per stage.
  pure subroutine packed_stage_columns(s, values, stage_of, rows, columns, k, y, h, point)
    integer, intent(in) :: s, stage_of(*), rows(*), columns
    real(wp), intent(in) :: values(*), k(width, columns, *), y(width, columns), h(width)
    real(wp), intent(out) :: point(width, columns)
    real(wp) :: total(width)
    integer :: i, m
    do i = 1, columns
      m = rows(s)
      total = y(:, i) + (h * values(m)) * k(:, i, stage_of(m))
      do m = rows(s) + 1, rows(s + 1) - 1
        total = total + (h * values(m)) * k(:, i, stage_of(m))
      end do
      point(:, i) = total
    end do
  end subroutine packed_stage_columns
end module ellroll_embedded_pair
