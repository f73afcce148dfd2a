!> The 2-stage Gauss-Legendre method: implicit, symmetric, order 4
!> (simplified Newton, LAPACK LU): bounded energy error over long runs.
module ellroll_gauss4
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: equals
  use ellroll_lapack, only: dgetrf, dgetrs
  use ellroll_ode, only: ode_system_t, stage_limit, no_step_solution
  use ellroll_integrator, only: integrator_t, max_equations
  implicit none
  private

  public :: gauss4_t

  !> Steps a Jacobian of the implicit method serves, unless Newton's
  !> iteration slows down before.
  integer, parameter :: jacobian_lifetime = 20
  !> A Newton iterate whose stage increments pass this many times the
  !> state's scale (max(|y|, 1)) has left any solution near the start (a step
  !> far beyond the method's reach): the right-hand side is not evaluated
  !> there (its products would overflow) and the step has no solution.
  real(wp), parameter :: stage_reach = 1.0e6_wp

  type, extends(integrator_t) :: gauss4_t
    real(wp), allocatable :: jacobian(:, :), lu(:, :)
    integer, allocatable :: pivots(:)
    real(wp) :: lu_h = 0                      !< step the LU was made for
    integer :: steps_since_jacobian = jacobian_lifetime     !< a new Jacobian at the first step
    integer(i8) :: newton_iterations = 0
  contains
    procedure :: step => gauss4_step
  end type gauss4_t

  ! ---- 2-stage Gauss-Legendre
  real(wp), parameter :: sqrt3_6 = 0.288675134594812882254574390250978727823800875635063438009_wp
  real(wp), parameter :: gl_a(2, 2) = reshape([0.25_wp, 0.25_wp + sqrt3_6, 0.25_wp - sqrt3_6, 0.25_wp], [2, 2])
  real(wp), parameter :: gl_c(2) = [0.5_wp - sqrt3_6, 0.5_wp + sqrt3_6]

contains

  !> Stage increments Z solve Z_i = h sum_j a_ij f(y + Z_j) by simplified
  !> Newton with the LU of I - h (A x J), J a forward-difference Jacobian
  !> refreshed every 20 steps or when convergence slows. Iterated to
  !> round-off, so that the method stays symmetric. Where the iteration
  !> stalls far above round-off, J is taken again at (t, y), against f(t, y)
  !> itself, and the iteration once more from the start: a hybrid system's
  !> law changes from step to step (rolling resistance: at rest, rolling,
  !> past a stop), and a J from an earlier step, or one differenced against
  !> an f0 in another law, says nothing of this step's equations.
  subroutine gauss4_step(self, sys, t, y, f0, h, y_new, n_rhs)
    class(gauss4_t), intent(inout) :: self
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, h
    real(wp), intent(in) :: y(:), f0(:)
    real(wp), intent(out) :: y_new(:)
    integer(i8), intent(inout) :: n_rhs
    integer :: n, i, j, info
    real(wp) :: z(max_equations, 2), f(max_equations, 2), stage(max_equations), f_here(max_equations)
    real(wp) :: scale, size_now
    n = size(y)
    if (self%steps_since_jacobian >= jacobian_lifetime .or. .not. equals(h, self%lu_h)) call refresh(self, f0)
    self%steps_since_jacobian = self%steps_since_jacobian + 1
    scale = 1.0e-3_wp * max(maxval(abs(y)), tiny(1.0_wp))
    call iterate(self, size_now)
    if (size_now > sqrt(epsilon(1.0_wp)) * scale) then
      call sys%rhs(t, y, f_here(:n))
      n_rhs = n_rhs + 1
      call refresh(self, f_here(:n))
      call iterate(self, size_now)
    end if
    if (.not. size_now < huge(1.0_wp)) then     ! (the iterates left the state's scale)
      y_new = y
      self%stage_limit = no_step_solution
      return
    end if
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

    !> Newton's iteration for Z from Z_i = c_i h f0, with the LU at hand;
    !> size_now: its last correction.
    subroutine iterate(self, size_now)
      class(gauss4_t), intent(inout) :: self
      real(wp), intent(out) :: size_now
      real(wp) :: residual(2 * max_equations, 1), size_before
      integer :: iteration
      do i = 1, 2
        z(:n, i) = gl_c(i) * h * f0
      end do
      size_before = huge(1.0_wp)
      do iteration = 1, 12
        size_now = huge(1.0_wp)
        if (.not. maxval(abs(z(:n, :))) <= stage_reach * max(maxval(abs(y)), 1.0_wp)) exit
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
    end subroutine iterate

    !> J by forward differences at (t, y) against f_base = f(t, y), and the
    !> LU of I - h (A x J).
    subroutine refresh(self, f_base)
      class(gauss4_t), intent(inout) :: self
      real(wp), intent(in) :: f_base(:)
      real(wp) :: delta, f_plus(max_equations), y_plus(max_equations)
      if (.not. allocated(self%jacobian)) allocate (self%jacobian(n, n), self%lu(2 * n, 2 * n), self%pivots(2 * n))
      do j = 1, n
        delta = sqrt(epsilon(1.0_wp)) * max(abs(y(j)), 1.0_wp)
        y_plus(:n) = y
        y_plus(j) = y(j) + delta
        call sys%rhs(t, y_plus(:n), f_plus(:n))
        self%jacobian(:, j) = (f_plus(:n) - f_base) / delta
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
end module ellroll_gauss4
