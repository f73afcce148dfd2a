!> The right-hand side against the paper's own formulation: contact-point
!> velocity from the 3x3 system H r_A' = V_C (LAPACK dgesv), n' = (dn/dr_A) r_A',
!> and the component form of Appell's equations. Plus observe's fit test
!> against the principal radii, and the reaction at rest.
program test_rolling_ball
  use ellroll_kinds, only: wp
  use ellroll_lapack, only: dgesv
  use ellroll_ellipsoid, only: new_ellipsoid, contact_from_normal, principal_radii
  use ellroll_rolling_ball
  use ellroll_errors, only: error_t
  use ellroll_integrators, only: embedded_pair_t, methods, new_pair
  use ellroll_rk4, only: rk4_t
  use ellroll_ball_steppers, only: rk4_ball_step, pair_ball_step, pair_ball_dense
  use ellroll_kinds, only: i8
  use testing
  implicit none
  ! on the heap, as a case's ball is: a ball at a fixed address lets the
  ! link-time optimizer compile a specialised copy of the RHS for some calls
  ! (contracting other products into FMAs), and the fused and generic steps
  ! below must evaluate the one RHS the program runs
  type(rolling_ball_t), allocatable :: ball
  real(wp) :: y(6), f(6), reference(6), u(6), worst, n(3), radii(2), kappa
  type(observation_t) :: obs
  integer :: trial, size_seed, fit_count, misfit_count, wrong, k
  class(embedded_pair_t), allocatable :: fused, generic
  type(error_t) :: err

  allocate (ball)
  ball%cup = new_ellipsoid(1.0_wp, 0.4_wp, 0.2_wp)
  ball%radius = 0.05_wp
  ball%mass = 267.0_wp
  ball%g = 9.81_wp
  call random_seed(size=size_seed)
  call random_seed(put=[(99 + trial, trial = 1, size_seed)])
  ! Both sides solve (R I - K) n' = V_C on the tangent plane, whose condition
  ! kappa = (R + r2) / min |R - r_i| reaches several hundred among these
  ! states (where R nears a principal radius): each agrees with the exact
  ! value to a few kappa eps, so the difference is measured in kappa eps.
  worst = 0
  do trial = 1, 1000
    call random_number(u)
    n = [2 * u(1) - 1, 2 * u(2) - 1, 0.3_wp + u(3)]
    y(1:3) = n / norm2(n)
    y(4:6) = 40 * (u(4:6) - 0.5_wp)
    call ball%rhs(0.0_wp, y, f)
    reference = rhs_from_physics_md(ball, y)
    radii = principal_radii(ball%cup, y(1:3))
    kappa = (ball%radius + radii(2)) / minval(abs(ball%radius - radii))
    worst = max(worst, maxval(abs(f - reference)) / maxval(abs(reference)) / (kappa * epsilon(1.0_wp)))
  end do
  call check_below(worst, 16.0_wp, 'closed-form RHS vs 3x3 solve of the paper (max rel. diff / (kappa eps))')

  ! observe's fit test (tr K and det K from the contact point's 1/s) against
  ! the principal radii computed apart (principal_radii, from the small
  ! deviator): the ball fits where R (1 + margin) is below both. Two balls:
  ! one that fits most of the cup, one larger than both radii near the rim
  ! (where (R - r1)(R - r2) > 0 too). States within 1e-9 of the threshold are
  ! left out; both outcomes must occur.
  fit_count = 0
  misfit_count = 0
  wrong = 0
  do trial = 1, 20000
    ball%radius = merge(0.05_wp, 0.5_wp, trial <= 10000)
    call random_number(u)
    n = [2 * u(1) - 1, 2 * u(2) - 1, 0.05_wp + u(3)]
    y(1:3) = n / norm2(n)
    y(4:6) = 0
    f = 0                 ! the fit test needs no rates (and R near a radius makes them huge)
    call observe(ball, 0.0_wp, y, f, obs)
    radii = principal_radii(ball%cup, y(1:3))
    if (abs(radii(1) / (ball%radius * (1 + ball%fit_margin)) - 1) < 1.0e-9_wp) cycle
    if (radii(1) > ball%radius * (1 + ball%fit_margin)) then
      fit_count = fit_count + 1
      if (.not. obs%fits) wrong = wrong + 1
    else
      misfit_count = misfit_count + 1
      if (obs%fits) wrong = wrong + 1
    end if
  end do
  ball%radius = 0.05_wp
  call check(wrong == 0 .and. fit_count > 1000 .and. misfit_count > 1000, &
             'fit test agrees with the principal radii (both outcomes occur)')

  ! A non-unit normal gives the same motion of the direction (homogeneity).
  y(1:3) = 3 * y(1:3)
  call ball%rhs(0.0_wp, y, reference)
  call ball%rhs(0.0_wp, [y(1:3) / 3, y(4:6)], f)
  call check_below(maxval(abs(reference(1:3) / 3 - f(1:3))) + maxval(abs(reference(4:6) - f(4:6))), &
                   1.0e-13_wp, 'RHS is homogeneous of degree one in |n|')

  ! The fused steps of the ball equal the generic steps on its RHS
  ! (same arithmetic; 1e-13 allows for different instruction scheduling).
  call fused_against_generic()
  do k = 1, size(methods)                 ! every embedded pair of the method table
    if (.not. methods(k)%adaptive) cycle
    call new_pair(methods(k)%name, fused, err)
    call new_pair(methods(k)%name, generic, err)
    call fused_pair_against_generic(fused, generic, trim(methods(k)%name))
    ! the rate at the ends to round-off: Verner's interpolant cancels terms
    ! up to 2 sum_j j |q98(j, s)| = 530 times h k_s
    call order_on_ball(generic, trim(methods(k)%name), methods(k)%convergence_order, methods(k)%dense_order, &
                       1000 * epsilon(1.0_wp))
  end do

  ! At rest at the bottom the cup carries the weight, with no friction.
  y = [0.0_wp, 0.0_wp, 1.0_wp, 0.0_wp, 0.0_wp, 0.0_wp]
  call ball%rhs(0.0_wp, y, f)
  call observe(ball, 0.0_wp, y, f, obs)
  call check_close(obs%reaction_normal, ball%mass * ball%g, 1.0e-15_wp, 'normal force at rest = m g')
  call check_below(obs%friction_needed, 0.0_wp, 'friction needed at rest')
  call check_below(obs%energy_of_motion, 0.0_wp, 'energy of motion at rest')
  call finish('test_rolling_ball')

contains

  subroutine fused_against_generic()
    type(rk4_t) :: generic
    real(wp) :: y_fused(6), y_generic(6), f(6), y_next(6)
    integer(i8) :: n_rhs
    integer :: step, stage_limit, limits_differ
    y_fused = initial_state(ball, 0.01_wp, -0.02_wp, [-2.0_wp, 2.0_wp, 20.0_wp])
    y_generic = y_fused
    n_rhs = 0
    limits_differ = 0
    do step = 1, 5000
      call ball%rhs(0.0_wp, y_fused, f)
      call rk4_ball_step(ball, 0.0_wp, y_fused, f, 1.0e-3_wp, y_next, stage_limit)
      y_fused = y_next
      call ball%rhs(0.0_wp, y_generic, f)
      call generic%step(ball, 0.0_wp, y_generic, f, 1.0e-3_wp, y_next, n_rhs)
      y_generic = y_next
      if (stage_limit /= generic%stage_limit) limits_differ = limits_differ + 1
    end do
    call check(limits_differ == 0, 'fused and generic RK4 steps see the same stage limits')
    call check_below(maxval(abs(y_fused - y_generic)) / maxval(abs(y_generic)), 1.0e-13_wp, &
                     'fused RK4 step vs generic RK4 step over 5000 steps (max rel. diff)')
  end subroutine fused_against_generic

  !> 300 attempts of an embedded pair of growing size (accepted or not, the
  !> fused and the generic path take the same ones) and the dense output of each.
  subroutine fused_pair_against_generic(fused, generic, name)
    class(embedded_pair_t), intent(inout) :: fused, generic
    character(len=*), intent(in) :: name
    real(wp) :: y_fused(6), y_generic(6), f(6), next_fused(6), next_generic(6), mid_fused(6), mid_generic(6)
    real(wp) :: h, worst_state, worst_norm, worst_dense
    integer(i8) :: n_rhs
    integer :: attempt
    logical :: prepared
    y_fused = initial_state(ball, 0.01_wp, -0.02_wp, [-2.0_wp, 2.0_wp, 20.0_wp])
    y_generic = y_fused
    fused%rtol = 1.0e-8_wp; fused%atol = 1.0e-11_wp
    generic%rtol = fused%rtol; generic%atol = fused%atol
    worst_state = 0; worst_norm = 0; worst_dense = 0
    n_rhs = 0
    do attempt = 1, 300
      h = 1.0e-3_wp * (1 + mod(attempt, 40))
      call ball%rhs(0.0_wp, y_fused, f)
      call pair_ball_step(fused, ball, 0.0_wp, y_fused, f, h, next_fused)
      call pair_ball_dense(fused, ball, 0.3_wp, mid_fused, prepared)
      call ball%rhs(0.0_wp, y_generic, f)
      call generic%step(ball, 0.0_wp, y_generic, f, h, next_generic, n_rhs)
      call generic%dense(ball, 0.3_wp, mid_generic, n_rhs)
      worst_state = max(worst_state, maxval(abs(next_fused - next_generic)) / maxval(abs(next_generic)))
      worst_dense = max(worst_dense, maxval(abs(mid_fused - mid_generic)) / maxval(abs(mid_generic)))
      worst_norm = max(worst_norm, abs(fused%error_norm - generic%error_norm) / max(generic%error_norm, tiny(h)))
      y_fused = next_fused / [spread(norm2(next_fused(1:3)), 1, 3), [1, 1, 1] * 1.0_wp]
      y_generic = next_generic / [spread(norm2(next_generic(1:3)), 1, 3), [1, 1, 1] * 1.0_wp]
    end do
    call check_below(worst_state, 1.0e-13_wp, 'fused ' // name // ' attempt vs generic over 300 attempts (max rel. diff)')
    call check_below(worst_norm, 1.0e-12_wp, 'fused ' // name // ' error norm vs generic (max rel. diff)')
    call check_below(worst_dense, 1.0e-13_wp, 'fused ' // name // ' dense output vs generic (max rel. diff)')
  end subroutine fused_pair_against_generic

  !> The pair's order, measured on the ball's equations (nonlinear: every
  !> elementary differential enters) with fixed steps: the state after 1 s
  !> at h = 1/6, 1/9, 1/12 s against h = 1/400 s (the next term of the
  !> error is large on this problem: the slopes approach the order from
  !> above, and are held to within half an order); and its interpolant's:
  !> the dense output at 0.37 h of one step of h = 1/4, 1/6, 1/8 s against
  !> 100 steps to there, a local error of order interpolant_order + 1 at
  !> least (Verner's is of order 10 here, as the step's own: its order-9
  !> defect carries theta^9), its rate at the step's ends h f there to
  !> ends_bound (scaled).
  subroutine order_on_ball(pair, name, order, interpolant_order, ends_bound)
    class(embedded_pair_t), intent(inout) :: pair
    character(len=*), intent(in) :: name
    integer, intent(in) :: order, interpolant_order
    real(wp), intent(in) :: ends_bound
    integer, parameter :: steps(3) = [6, 9, 12], dense_steps(3) = [4, 6, 8]
    real(wp), parameter :: scale(6) = [1, 1, 1, 20, 20, 20]     ! |omega| ~ 20 rad/s
    real(wp) :: reference(6), errors(3), y(6), f(6), y_next(6), mid(6), rate(8), h, ends, slope
    character(len=8) :: text
    integer(i8) :: n_rhs
    integer :: k
    reference = state_after(pair, 400, 1.0_wp)
    do k = 1, 3
      errors(k) = maxval(abs(state_after(pair, steps(k), 1.0_wp) - reference) / scale)
    end do
    do k = 1, 2
      call check_close(log(errors(k) / errors(k + 1)) / log(real(steps(k + 1), wp) / steps(k)), real(order, wp), &
                       0.5_wp / order, name // ' order on the ball, fixed steps')
    end do
    n_rhs = 0
    ends = 0
    do k = 1, 3
      h = 1.0_wp / dense_steps(k)
      y = initial_state(ball, 0.01_wp, -0.02_wp, [-2.0_wp, 2.0_wp, 20.0_wp])
      call ball%rhs(0.0_wp, y, f)
      call pair%step(ball, 0.0_wp, y, f, h, y_next, n_rhs)
      call pair%dense(ball, 0.37_wp, mid, n_rhs)
      errors(k) = maxval(abs(mid - state_after(pair, 100, 0.37_wp * h)) / scale)
      call pair%dense_rate(0.0_wp, rate)
      ends = max(ends, maxval(abs(rate(:6) - h * f) / scale))
      call ball%rhs(h, y_next, f)
      call pair%dense_rate(1.0_wp, rate)
      ends = max(ends, maxval(abs(rate(:6) - h * f) / scale))
    end do
    do k = 1, 2
      slope = log(errors(k) / errors(k + 1)) / log(real(dense_steps(k + 1), wp) / dense_steps(k))
      write (text, '(f6.2)') slope
      call check(slope > interpolant_order + 0.5_wp, name // ' dense output on the ball: local error order ' // &
                 trim(adjustl(text)) // ', at least interpolant order + 1')
    end do
    call check_below(ends, ends_bound, name // ' dense rate at the step''s ends vs h f there (scaled)')
  end subroutine order_on_ball

  !> The state at t_end after n fixed steps of the pair.
  function state_after(pair, n, t_end) result(y)
    class(embedded_pair_t), intent(inout) :: pair
    integer, intent(in) :: n
    real(wp), intent(in) :: t_end
    real(wp) :: y(6), f(6), y_next(6)
    integer(i8) :: n_rhs
    integer :: step
    y = initial_state(ball, 0.01_wp, -0.02_wp, [-2.0_wp, 2.0_wp, 20.0_wp])
    n_rhs = 0
    do step = 1, n
      call ball%rhs(0.0_wp, y, f)
      call pair%step(ball, 0.0_wp, y, f, t_end / n, y_next, n_rhs)
      y = y_next
    end do
  end function state_after

  function rhs_from_physics_md(ball, y) result(dydt)
    type(rolling_ball_t), intent(in) :: ball
    real(wp), intent(in) :: y(6)
    real(wp) :: dydt(6)
    real(wp) :: n(3), omega(3), p(3), q(3), qhat(3), big_q, dn_dr(3, 3), h(3, 3), rhs(3, 1), n_dot(3)
    real(wp) :: d(3), jstar, omega_n
    integer :: ipiv(3), info, i
    n = y(1:3); omega = y(4:6)
    p = contact_from_normal(ball%cup, n)
    d = [1 / ball%cup%a**2, 1 / ball%cup%b**2, 1 / ball%cup%c**2]
    q = [p(1) * d(1), p(2) * d(2), (p(3) - ball%cup%c) * d(3)]
    big_q = norm2(q)
    qhat = q / big_q
    do i = 1, 3
      dn_dr(:, i) = -(merge(1.0_wp, 0.0_wp, [1, 2, 3] == i) - qhat * qhat(i)) * d(i) / big_q
    end do
    h = dn_dr * ball%radius
    do i = 1, 3
      h(i, i) = h(i, i) + 1
    end do
    ! V_C = R (omega x n)
    rhs(:, 1) = ball%radius * [omega(2)*n(3) - omega(3)*n(2), omega(3)*n(1) - omega(1)*n(3), &
                               omega(1)*n(2) - omega(2)*n(1)]
    call dgesv(3, 1, h, 3, ipiv, rhs, 3, info)
    n_dot = matmul(dn_dr, rhs(:, 1))
    jstar = 5.0_wp / 7.0_wp
    omega_n = dot_product(omega, n)
    dydt(1:3) = n_dot
    dydt(4) = jstar * (omega_n * n_dot(1) + ball%g * q(2) / (ball%radius * big_q))
    dydt(5) = jstar * (omega_n * n_dot(2) - ball%g * q(1) / (ball%radius * big_q))
    dydt(6) = jstar * omega_n * n_dot(3)
  end function rhs_from_physics_md
end program test_rolling_ball
