module oscillator
  use ellroll_kinds, only: wp
  use ellroll_ode, only: ode_system_t
  implicit none
  private
  public :: oscillator_t

  !> y'' = -y + forcing cos 2t as a first-order system, from y = 1, y' = 0:
  !> exact solution (1 + forcing/3) cos t - (forcing/3) cos 2t. Unforced,
  !> y^2 + y'^2 is invariant; forced, the right-hand side depends on t, and
  !> a method's order tests its nodes c too.
  type, extends(ode_system_t) :: oscillator_t
    real(wp) :: forcing = 0
  contains
    procedure :: rhs => oscillator_rhs
    procedure :: exact => oscillator_exact
  end type oscillator_t

contains

  pure subroutine oscillator_rhs(self, t, y, dydt)
    class(oscillator_t), intent(in) :: self
    real(wp), intent(in) :: t
    real(wp), intent(in) :: y(:)
    real(wp), intent(out) :: dydt(:)
    dydt = [y(2), -y(1) + self%forcing * cos(2 * t)]
  end subroutine oscillator_rhs

  !> The exact solution at t.
  pure function oscillator_exact(self, t) result(y)
    class(oscillator_t), intent(in) :: self
    real(wp), intent(in) :: t
    real(wp) :: y(2)
    y = [(1 + self%forcing / 3) * cos(t) - self%forcing / 3 * cos(2 * t), &
         -(1 + self%forcing / 3) * sin(t) + 2 * self%forcing / 3 * sin(2 * t)]
  end function oscillator_exact
end module oscillator

!> Verner's 9(8) coefficients against the order conditions of Runge-Kutta
!> methods (Butcher's rooted trees), in the precision they are stored in.
module vern9_conditions
  use ellroll_kinds, only: wp
  use ellroll_vern9, only: a98, c9, b9, e8, p98, q98, stages, stages_dense
  use testing
  implicit none
  private
  public :: vern9_order_conditions

  integer, parameter :: max_order = 9, n_trees = 2056     ! sum of Catalan(n - 1), n = 1..9
  !> Phi(t) of each tree, the same in absolute values, gamma(t); the trees
  !> of order n are first(n):first(n + 1) - 1.
  real(wp) :: phi(stages_dense, n_trees), phi_abs(stages_dense, n_trees), gamma(n_trees)
  integer :: first(max_order + 1)

contains

  !> Verner's coefficients as stored (in double precision) satisfy the
  !> order conditions to rounding: for every rooted tree t of order |t| <=
  !> 9, sum_s b_s Phi_s(t) = 1 / gamma(t); for the embedded weights b + e8
  !> and for the interpolant's weights b_s(theta) = sum_j q98(j, s) (2 theta
  !> - 1)^j (theta^|t| / gamma(t) for these), the trees up to order 8; and
  !> these weights are Verner's, sum_j p98(j, s) theta^j. The trees
  !> are the Butcher products t1 o t2 (t2 grafted onto t1's root) of smaller
  !> ones: every tree of order >= 2 is one, some several times (1430
  !> products of order 9 for its 286 trees), which only repeats conditions.
  !> Phi(t1 o t2) = Phi(t1) (A Phi(t2)), gamma(t1 o t2) = gamma(t1)
  !> gamma(t2) |t| / |t1|. Rounding: a residual is held to 64 eps times the
  !> same sum taken in absolute values. The order-9 conditions of the
  !> embedded weights and of the interpolant fail: the test can fail.
  subroutine vern9_order_conditions()
    real(wp), parameter :: thetas(3) = [0.3_wp, 0.77_wp, 1.0_wp]
    real(wp) :: a(stages_dense, stages_dense), weights(stages_dense), size_of_terms(stages_dense), x
    real(wp) :: verner(0:8, stages_dense), verner_abs(0:8, stages_dense)     ! p98 from the power 0
    integer :: n, k, i, j, m, q
    verner = 0
    verner(1:, :) = p98
    verner_abs = abs(verner)
    a = 0
    a(:, :stages_dense - 1) = a98
    call check(all(abs(a(1, :)) <= 0) .and. abs(c9(1)) <= 0, 'vern9: the first stage is at t, from y')
    call check_below(maxval(abs(sum(a(2:, :), dim=2) - c9(2:)) / (4 * epsilon(1.0_wp) * sum(abs(a(2:, :)), dim=2))), &
                     1.0_wp, 'vern9: c_s = sum_j a(s, j) (residual / 4 eps sum_j |a(s, j)|, max)')
    phi(:, 1) = 1
    phi_abs(:, 1) = 1
    gamma(1) = 1
    first(1:2) = [1, 2]
    m = 1
    do n = 2, max_order
      do k = 1, n - 1
        do i = first(k), first(k + 1) - 1
          do j = first(n - k), first(n - k + 1) - 1
            m = m + 1
            phi(:, m) = phi(:, i) * matmul(a, phi(:, j))
            phi_abs(:, m) = phi_abs(:, i) * matmul(abs(a), phi_abs(:, j))
            gamma(m) = gamma(i) * gamma(j) * n / k
          end do
        end do
      end do
      first(n + 1) = m + 1
    end do
    call check(m == n_trees, 'vern9: 2056 Butcher products up to order 9')
    weights = 0
    weights(:stages) = b9
    call check_below(rounding_residual(weights, abs(weights), 1.0_wp, 9), 1.0_wp, &
                     'vern9 weights: order conditions to 9 (residual / 64 eps |sum|, max)')
    weights(:stages) = b9 + e8
    call check_below(rounding_residual(weights, abs(weights), 1.0_wp, 8), 1.0_wp, &
                     'vern9 embedded weights: order conditions to 8 (residual / 64 eps |sum|, max)')
    call check(relative_residual(weights, 1.0_wp, 9) > 1.0e-3_wp, 'vern9 embedded weights: not of order 9 (contrast)')
    do q = 1, size(thetas)
      x = 2 * thetas(q) - 1
      call check_below(rounding_residual(interpolant_weights(q98, x), interpolant_weights(abs(q98), abs(x)), &
                                         thetas(q), 8), 1.0_wp, &
                       'vern9 interpolant: order conditions to 8 (residual / 64 eps |sum|, max)')
      size_of_terms = 64 * epsilon(1.0_wp) * interpolant_weights(verner_abs, thetas(q))
      call check_below(maxval(abs(interpolant_weights(q98, x) - interpolant_weights(verner, thetas(q))) &
                              / size_of_terms, mask=size_of_terms > 0), 1.0_wp, &
                       'vern9 interpolant: the weights of Verner''s table (difference / 64 eps |sum|, max)')
    end do
    call check(relative_residual(interpolant_weights(q98, 2 * 0.3_wp - 1), 0.3_wp, 9) > 1.0e-3_wp, &
               'vern9 interpolant: not of order 9 (contrast)')
  end subroutine vern9_order_conditions

  !> The interpolant's weights sum_j c(j, s) x^j: q98 at x = 2 theta - 1,
  !> or Verner's p98 at x = theta (or their absolute values, with |x|).
  function interpolant_weights(c, x) result(w)
    real(wp), intent(in) :: c(0:, :), x
    real(wp) :: w(size(c, 2))
    integer :: power
    w = 0
    do power = lbound(c, 1), ubound(c, 1)
      w = w + c(power, :) * x**power
    end do
  end function interpolant_weights

  !> The largest residual of the conditions of the trees up to order top
  !> (weights w, theta^|t| / gamma(t) the target), over 64 eps times its
  !> sum in absolute values (the weights' own: w_abs).
  real(wp) function rounding_residual(w, w_abs, theta, top)
    real(wp), intent(in) :: w(stages_dense), w_abs(stages_dense), theta
    integer, intent(in) :: top
    integer :: order, tree
    rounding_residual = 0
    do order = 1, top
      do tree = first(order), first(order + 1) - 1
        rounding_residual = max(rounding_residual, abs(dot_product(w, phi(:, tree)) - theta**order / gamma(tree)) &
                                / (64 * epsilon(1.0_wp) * dot_product(w_abs, phi_abs(:, tree))))
      end do
    end do
  end function rounding_residual

  !> The largest relative residual of the conditions of the trees of one order.
  real(wp) function relative_residual(w, theta, order)
    real(wp), intent(in) :: w(stages_dense), theta
    integer, intent(in) :: order
    integer :: tree
    relative_residual = 0
    do tree = first(order), first(order + 1) - 1
      relative_residual = max(relative_residual, abs(dot_product(w, phi(:, tree)) * gamma(tree) / theta**order - 1))
    end do
  end function relative_residual
end module vern9_conditions

!> Every method of the method table, made from its row, its order
!> measured: on the harmonic oscillator (exact solution) and, with a fixed
!> step, on the paper's case (against a much finer run); a fixed step's
!> stability limit on the oscillator; each pair's dense-output order and its
!> achieved error against rtol; gauss4's exact conservation of the
!> oscillator's quadratic invariant (it is symplectic); Verner's
!> coefficients against the order conditions (the pairs' orders on the
!> ball's equations are in test_rolling_ball).
program test_integrators
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use oscillator, only: oscillator_t
  use ellroll_integrators, only: integrator_t, embedded_pair_t, methods, method_names, new_integrator, new_pair, &
      stability_limit, max_pair_stages
  use ellroll_errors, only: error_t
  use ellroll_exact, only: equals
  use ellroll_cases, only: case_t, output_plan_t, field_contact, field_center, field_omega, field_normal, &
      field_nutation, field_energy
  use ellroll_results, only: case_result_t
  use fixtures, only: paper_case, run_case, other_pair
  use ellroll_simulate, only: simulate_case
  use ellroll_step_control, only: step_control_t
  use ellroll_flow_to_limit, only: reference_method
  use vern9_conditions, only: vern9_order_conditions
  use testing
  use ellroll_params, only: p_atol, p_dt, p_rtol
  use ellroll_figures, only: fig_nutation_maxima, fig_nutation_period, fig_theta_max
  implicit none

  class(integrator_t), allocatable :: method
  class(embedded_pair_t), allocatable :: pair
  type(error_t) :: err
  real(wp) :: errors(4), dts(4), reference(6), drift, tolerances(4), slope
  type(case_result_t) :: res
  type(case_t) :: cs
  integer :: k, j
  !> The round-off of a pair's interpolated rate (eps): DOP853's 0.5, Verner's
  !> 270, whose interpolant's weights q98 (up to 60) cancel between its stages.
  real(wp), parameter :: ends_round_off = 1000

  ! every method of the table: it is built from its row, and its orders
  ! (and, where a fixed step limits it, its stability) are measured
  do k = 1, size(methods)
    call new_integrator(trim(methods(k)%name), method, err)
    call check(.not. err%failed() .and. method%method == k, trim(methods(k)%name) // ': made from its row')
    if (err%failed()) cycle
    call check(equals(stability_limit(method), methods(k)%stability_limit), trim(methods(k)%name) // &
               ': its stability limit is its row''s')
    if (methods(k)%adaptive) then
      call new_pair(trim(methods(k)%name), pair, err)
      call check(.not. err%failed() .and. methods(k)%kind == 'adaptive', trim(methods(k)%name) // &
                 ': an adaptive method is an embedded pair')
      if (err%failed()) cycle
      call check(pair%end_stage() + pair%dense_calls() <= max_pair_stages, trim(methods(k)%name) // &
                 ': its stages fit max_pair_stages')
      call orders_on_oscillator(pair, [1.0_wp, 0.5_wp, 0.25_wp], trim(methods(k)%name), &
                                real(methods(k)%convergence_order, wp), at_least=.true.)
      call dense_order(pair, trim(methods(k)%name), methods(k)%dense_order)
    else
      dts = [0.2_wp, 0.1_wp, 0.05_wp, 0.025_wp]
      call orders_on_oscillator(method, dts, trim(methods(k)%name), real(methods(k)%convergence_order, wp), &
                                at_least=.false.)
      call orders_on_paper_case(trim(methods(k)%name), real(methods(k)%convergence_order, wp))
      call stability_on_oscillator(method, methods(k)%stability_limit, trim(methods(k)%name))
    end if
  end do
  call new_integrator('euler', method, err)
  call check(err%failed() .and. index(err%message, method_names()) > 0, 'an unknown method is an input error ' // &
             'that lists the known ones')
  err = error_t()
  call new_pair(reference_method, pair, err)
  call check(.not. err%failed(), 'the reference method (' // reference_method // ') is an embedded pair of the table')

  call new_integrator('gauss4', method, err)
  drift = invariant_drift(method, 0.1_wp, 100000)
  call check_below(drift, 1.0e-12_wp, 'gauss4: |y|^2 of the oscillator over 1e5 steps (exactly conserved)')
  call new_integrator('rk4', method, err)
  call check(invariant_drift(method, 0.1_wp, 100000) > 1.0e-4_wp, 'rk4 drifts on the same run (contrast)')

  call vern9_order_conditions()
  call adaptive_nutation_maxima()
  call step_control_floors()
  call stability_limited_steps()
  call geometry_samples()

  ! each adaptive method's error tracks rtol (paper case, contact point at
  ! 2 s), against another pair at a tight tolerance
  do k = 1, size(methods)
    if (.not. methods(k)%adaptive) cycle
    cs = paper_case(2.0_wp, 2.0_wp)        ! dt = largest step: error control alone decides
    cs%method = other_pair(methods(k)%name)
    cs%param(p_rtol) = 1.0e-13_wp
    cs%param(p_atol) = 1.0e-15_wp
    res = run_case(cs, 1)
    reference(1:3) = res%fields(field_contact)%values(:, 2)
    cs%method = methods(k)%name
    tolerances = [1.0e-5_wp, 1.0e-7_wp, 1.0e-9_wp, 1.0e-11_wp]
    do j = 1, 4
      cs%param(p_rtol) = tolerances(j)
      cs%param(p_atol) = tolerances(j) * 1.0e-3_wp
      res = run_case(cs, 1)
      errors(j) = norm2(res%fields(field_contact)%values(:, 2) - reference(1:3))
      print '(a, es8.1, a, es9.2, a, i0)', trim(methods(k)%name) // ' rtol ', tolerances(j), ': contact error ', &
            errors(j), ' m, RHS evaluations ', res%n_rhs
      call check(errors(j) < 100 * tolerances(j), trim(methods(k)%name) // ' error within 100 rtol')
    end do
    slope = log10(errors(1) / errors(4)) / 6
    call check_close(slope, 1.0_wp, 0.3_wp, trim(methods(k)%name) // ': d log(error) / d log(rtol)')
  end do
  call finish('test_integrators')

contains

  !> Error norms where they are partly round-off choose the same next step
  !> (a case alone and in a SIMD batch must agree), and the controller's
  !> memory of the last error (its proportional part) acts above them.
  subroutine step_control_floors()
    type(step_control_t) :: a, b
    real(wp) :: ha, hb
    a = step_control_t(log_previous_norm=log(0.3_wp))
    b = a
    ha = 1
    hb = 1
    call a%accept(ha, 1.0e-9_wp, 100.0_wp)
    call b%accept(hb, 1.0e-12_wp, 100.0_wp)
    call check_below(abs(ha - hb), 0.0_wp, 'step control: steps after error norms 1e-9 and 1e-12 differ by')
    call check(ha > 2, 'step control: the step grows more than twofold after a tiny error norm')
    a = step_control_t()
    b = step_control_t()
    call a%accept(ha, 1.0e-6_wp, 100.0_wp)
    call b%accept(hb, 3.0e-5_wp, 100.0_wp)
    ha = 1
    hb = 1
    call a%accept(ha, 0.5_wp, 100.0_wp)
    call b%accept(hb, 0.5_wp, 100.0_wp)
    call check_below(abs(ha - hb), 0.0_wp, 'step control: steps after previous error norms 1e-6 and 3e-5 differ by')
    a = step_control_t(log_previous_norm=log(0.1_wp))
    b = step_control_t(log_previous_norm=log(0.9_wp))
    ha = 1
    hb = 1
    call a%accept(ha, 0.5_wp, 100.0_wp)
    call b%accept(hb, 0.5_wp, 100.0_wp)
    call check(ha < hb, 'step control: a rising error norm grows the step less than a falling one')
    call a%reject(ha, 4.0_wp)
    hb = ha
    call a%accept(ha, 1.0e-3_wp, 100.0_wp)
    call check_below(abs(ha - hb), 0.0_wp, 'step control: growth right after a rejection')
  end subroutine step_control_floors

  !> At loose tolerances the paper's case is stability-limited (the step
  !> sits where DOP853's stability region ends): the plain controller
  !> overshoots into rejection on every third attempt (32 % at rtol 1e-3);
  !> the PI controller damps that.
  subroutine stability_limited_steps()
    type(case_t) :: cs
    type(case_result_t) :: res
    real(wp) :: rejected
    cs = paper_case(30.0_wp, 30.0_wp)
    cs%method = 'dop853'
    cs%param(p_rtol) = 1.0e-3_wp
    cs%param(p_atol) = 1.0e-6_wp
    res = run_case(cs, 1)
    rejected = real(res%n_rejected, wp) / real(res%n_steps + res%n_rejected, wp)
    print '(a, i0, a, i0, a)', 'dop853 rtol 1e-3 on the paper case: ', res%n_steps, ' steps, ', res%n_rejected, &
          ' rejected'
    call check_below(rejected, 0.2_wp, 'dop853 rtol 1e-3, stability-limited: fraction of attempts rejected')
  end subroutine stability_limited_steps

  !> A DOP853 sample that stores only geometry (contact, centre, omega,
  !> normal, Theta) computes each value alone from the dense output; it
  !> equals, to round-off, the sample of a run that also stores the energy
  !> (every derived output from the projected state), whichever subset of
  !> the geometry is stored.
  subroutine geometry_samples()
    integer, parameter :: geometry(5) = [field_contact, field_center, field_omega, field_normal, field_nutation]
    type(case_t) :: cs
    type(output_plan_t) :: plan
    type(case_result_t) :: full, part
    type(error_t) :: err
    real(wp) :: worst
    integer :: f, subset, j
    logical :: finite
    cs = paper_case(0.5_wp, 10.0_wp)
    cs%method = 'dop853'
    cs%param(p_rtol) = 1.0e-9_wp
    cs%param(p_atol) = 1.0e-12_wp
    plan%interval = 0.1_wp
    plan%n_samples = 101
    plan%fields = .false.
    plan%fields([geometry, field_energy]) = .true.
    call simulate_case(cs, plan, full, err)
    worst = 0
    finite = .true.
    do subset = 1, 6           ! each geometry field alone, then all of them
      plan%fields = .false.
      plan%fields(geometry) = subset > size(geometry) .or. [(j == subset, j = 1, size(geometry))]
      call simulate_case(cs, plan, part, err)
      do f = 1, 5
        if (.not. plan%fields(geometry(f))) cycle
        finite = finite .and. all(ieee_is_finite(part%fields(geometry(f))%values))
        worst = max(worst, maxval(abs(part%fields(geometry(f))%values - full%fields(geometry(f))%values)) &
                           / maxval(abs(full%fields(geometry(f))%values)))
      end do
    end do
    call check(finite, 'dop853 geometry-only samples are finite, any subset')
    call check_below(worst, 1.0e-14_wp, 'dop853 geometry-only samples vs complete ones, any subset (max rel. diff)')
  end subroutine geometry_samples

  !> The method's stability on the imaginary axis, on the oscillator (its
  !> eigenvalues +-i): over 200 steps of h = 0.99 limit its motion does not
  !> grow, at 1.01 limit it grows tenfold; a method without a limit (huge)
  !> keeps it bounded at h = 100.
  subroutine stability_on_oscillator(method, limit, name)
    class(integrator_t), intent(inout) :: method
    real(wp), intent(in) :: limit
    character(len=*), intent(in) :: name
    if (limit < huge(1.0_wp)) then
      call check(growth(method, 0.99_wp * limit) <= 1, name // ': stable at h |lambda| = 0.99 of its stability limit')
      call check(growth(method, 1.01_wp * limit) > 10, name // ': unstable at h |lambda| = 1.01 of its stability limit')
    else
      call check_below(growth(method, 100.0_wp) - 1, 1.0e-12_wp, name // ': at h |lambda| = 100 (no stability ' // &
                       'limit), growth over 200 steps')
    end if
  end subroutine stability_on_oscillator

  !> |y| of the oscillator after 200 steps of h from |y| = 1.
  real(wp) function growth(method, h)
    class(integrator_t), intent(inout) :: method
    real(wp), intent(in) :: h
    type(oscillator_t) :: osc
    real(wp) :: y(2), f(2), y_new(2)
    integer(i8) :: n_rhs
    integer :: step
    y = [1.0_wp, 0.0_wp]
    n_rhs = 0
    do step = 1, 200
      call osc%rhs(0.0_wp, y, f)
      call method%step(osc, 0.0_wp, y, f, h, y_new, n_rhs)
      y = y_new
    end do
    growth = norm2(y)
  end function growth

  !> The method's order on the oscillator at steps dts: within 5 % of
  !> `order`, or with at_least, no less than 95 % of it and at most 2 more
  !> (a high-order pair approaches its order from above: the next term of its
  !> error is large, and its error reaches round-off first).
  subroutine orders_on_oscillator(method, dts, name, order, at_least)
    class(integrator_t), intent(inout) :: method
    real(wp), intent(in) :: dts(:), order
    character(len=*), intent(in) :: name
    logical, intent(in) :: at_least
    real(wp) :: errors(size(dts)), slope
    integer :: k, forced
    do forced = 0, 1
      do k = 1, size(dts)
        errors(k) = oscillator_error(method, dts(k), real(forced, wp))
      end do
      do k = 1, size(dts) - 1
        slope = log(errors(k) / errors(k+1)) / log(dts(k) / dts(k+1))
        call check_order(slope, order, at_least, &
                         name // ' order on the harmonic oscillator' // trim(merge(', forced', '        ', forced == 1)))
      end do
    end do
  end subroutine orders_on_oscillator

  !> A measured order: within 5 % of `order`, or with at_least in [0.95 order, order + 2].
  subroutine check_order(slope, order, at_least, what)
    real(wp), intent(in) :: slope, order
    logical, intent(in) :: at_least
    character(len=*), intent(in) :: what
    character(len=80) :: line
    if (.not. at_least) then
      call check_close(slope, order, 0.05_wp, what)
      return
    end if
    write (line, '(a, f6.2, a, f5.2, a)') ': ', slope, ' (at least ', order, ')'
    call check(slope >= 0.95_wp * order .and. slope <= order + 2, what // trim(line))
    if (slope >= 0.95_wp * order .and. slope <= order + 2) print '(a)', 'ok: ' // what // trim(line)
  end subroutine check_order

  subroutine orders_on_paper_case(name, order)
    character(len=*), intent(in) :: name
    real(wp), intent(in) :: order
    type(case_t) :: cs
    real(wp) :: errors(4), dts(4), reference(6)
    integer :: k
    cs = paper_case(1.0e-4_wp, 2.0_wp)
    cs%method = name
    res = run_case(cs, 20000)
    reference = [res%fields(field_contact)%values(:, 2), res%fields(field_omega)%values(:, 2)]
    dts = [0.01_wp, 0.005_wp, 0.0025_wp, 0.00125_wp]
    do k = 1, 4
      cs%param(p_dt) = dts(k)
      res = run_case(cs, nint(2 / dts(k)))
      errors(k) = maxval(abs([res%fields(field_contact)%values(:, 2) * 20, &
                              res%fields(field_omega)%values(:, 2) / 20] - &
                             [reference(1:3) * 20, reference(4:6) / 20]))
    end do
    do k = 1, 3
      call check_close(log(errors(k) / errors(k+1)) / log(2.0_wp), order, 0.05_wp, &
                       name // ' order on the paper case')
    end do
  end subroutine orders_on_paper_case

  real(wp) function oscillator_error(method, dt, forcing)
    class(integrator_t), intent(inout) :: method
    real(wp), intent(in) :: dt, forcing
    type(oscillator_t) :: osc
    real(wp) :: y(2), f(2), y_new(2), t
    integer(i8) :: n_rhs
    integer :: step
    osc%forcing = forcing
    y = [1.0_wp, 0.0_wp]
    t = 0
    n_rhs = 0
    do step = 1, nint(10 / dt)
      call osc%rhs(t, y, f)
      call method%step(osc, t, y, f, dt, y_new, n_rhs)
      y = y_new
      t = step * dt
    end do
    oscillator_error = norm2(y - osc%exact(t))
  end function oscillator_error

  real(wp) function invariant_drift(method, dt, n_steps)
    class(integrator_t), intent(inout) :: method
    real(wp), intent(in) :: dt
    integer, intent(in) :: n_steps
    type(oscillator_t) :: osc
    real(wp) :: y(2), f(2), y_new(2)
    integer(i8) :: n_rhs
    integer :: step
    y = [1.0_wp, 0.0_wp]
    n_rhs = 0
    invariant_drift = 0
    do step = 1, n_steps
      call osc%rhs(0.0_wp, y, f)
      call method%step(osc, 0.0_wp, y, f, dt, y_new, n_rhs)
      y = y_new
      invariant_drift = max(invariant_drift, abs(sum(y**2) - 1))
    end do
  end function invariant_drift

  !> One step of a pair from the exact state; its interpolant at 0.37 of
  !> the step against cos (a local error of order `order` + 1, `order` the
  !> interpolant's, or more), and its derivative: h f at both ends of the
  !> step (the interpolant matches them, to round-off: ends_round_off) and,
  !> inside, the exact derivative with the interpolant's order or more.
  subroutine dense_order(pair, name, order)
    class(embedded_pair_t), intent(inout) :: pair
    character(len=*), intent(in) :: name
    integer, intent(in) :: order
    type(oscillator_t) :: osc
    real(wp) :: y(2), f(2), y_new(2), f_new(2), mid(2), rate(8), h, theta, errors(3), rate_errors(3), worst_ends
    integer(i8) :: n_rhs
    integer :: k, i
    n_rhs = 0
    worst_ends = 0
    do i = 1, 3
      h = 0.8_wp / 2**(i - 1)
      y = [1.0_wp, 0.0_wp]
      call osc%rhs(0.0_wp, y, f)
      call pair%step(osc, 0.0_wp, y, f, h, y_new, n_rhs)
      call pair%dense(osc, 0.37_wp, mid, n_rhs)
      errors(i) = norm2(mid - [cos(0.37_wp * h), -sin(0.37_wp * h)])
      call osc%rhs(h, y_new, f_new)
      call pair%dense_rate(0.0_wp, rate)
      worst_ends = max(worst_ends, maxval(abs(rate(1:2) - h * f)) / h)
      call pair%dense_rate(1.0_wp, rate)
      worst_ends = max(worst_ends, maxval(abs(rate(1:2) - h * f_new)) / h)
      rate_errors(i) = 0
      do k = 1, 9
        theta = k / 10.0_wp
        call pair%dense_rate(theta, rate)
        rate_errors(i) = max(rate_errors(i), maxval(abs(rate(1:2) / h - [-sin(theta * h), -cos(theta * h)])))
      end do
    end do
    do i = 1, 2
      call check_order(log(errors(i) / errors(i + 1)) / log(2.0_wp), real(order + 1, wp), .true., &
                       name // ' dense output: local error order (the interpolant''s order + 1)')
      call check_order(log(rate_errors(i) / rate_errors(i + 1)) / log(2.0_wp), real(order, wp), .true., &
                       name // ' dense rate inside the step: error order (the interpolant differentiated)')
    end do
    call check_below(worst_ends / epsilon(1.0_wp), ends_round_off, name // ' dense rate at both ends of the step ' // &
                     'vs h f there (eps)')
  end subroutine dense_order


  !> DOP853 locates the maxima of Theta on its dense output, wherever its
  !> (long) steps end: Theta_max and the nutation period converge with rtol
  !> and agree with fine RK4, whose step ends every 1e-4 s bound Theta_max
  !> from below to Theta'' dt^2 / 8 ~ 2e-8 rad. (Taken at DOP853's step
  !> ends, Theta_max would be some 3e-4 rad low.)
  subroutine adaptive_nutation_maxima()
    type(case_t) :: cs
    type(case_result_t) :: tight, loose, fine_rk4
    real(wp), parameter :: loose_rtol = 1.0e-8_wp
    cs = paper_case(1.0e-4_wp, 3.0_wp)
    fine_rk4 = run_case(cs, 30000)
    cs%method = 'dop853'
    cs%param(p_dt) = cs%t_end
    cs%param(p_rtol) = 1.0e-12_wp
    cs%param(p_atol) = 1.0e-14_wp
    tight = run_case(cs, 1)
    cs%param(p_rtol) = loose_rtol
    cs%param(p_atol) = 1.0e-3_wp * loose_rtol
    loose = run_case(cs, 1)
    call check(all([loose%counts(fig_nutation_maxima), &
        tight%counts(fig_nutation_maxima)] == fine_rk4%counts(fig_nutation_maxima)) &
               .and. fine_rk4%counts(fig_nutation_maxima) == 3, &
                   'dop853: the three maxima of Theta in 3 s that RK4 finds')
    call check_below(abs(loose%reals(fig_theta_max) - tight%reals(fig_theta_max)), 1.0e-8_wp, &
        'dop853 Theta_max, rtol 1e-8 vs 1e-12 (rad)')
    call check_below(abs(loose%reals(fig_nutation_period) / tight%reals(fig_nutation_period) - 1), 10 * loose_rtol, &
                     'dop853 nutation period, rtol 1e-8 vs 1e-12 (rel.; within 10 rtol)')
    call check_below(abs(tight%reals(fig_theta_max) - fine_rk4%reals(fig_theta_max)), 1.0e-10_wp, &
                     'dop853 Theta_max vs RK4 dt = 1e-4 (rad; the latter by parabolas through its step ends)')
    call check_below(abs(tight%reals(fig_nutation_period) / fine_rk4%reals(fig_nutation_period) - 1), 1.0e-8_wp, &
                     'dop853 nutation period vs RK4 dt = 1e-4 (rel.)')
  end subroutine adaptive_nutation_maxima
end program test_integrators
