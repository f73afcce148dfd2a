!> The steady response at a forcing frequency, separated from the free
!> oscillation: least squares of a signal's samples over a window on the
!> basis 1, cos W t, sin W t and cos w_k t, sin w_k t for the free modes'
!> frequencies w_k (the linearised model's). The model has no damping, so
!> the free oscillation never decays; a plain Fourier projection at W over
!> whole forcing periods keeps a leak of it (a part of its amplitude that
!> depends on where the window ends), the fit none where the free motion is
!> at the modes' frequencies.
!>
!> The sums are trapezoid rules over the samples given (the step ends), the
!> basis updated by rotation where the step repeats (a fixed step) and
!> computed afresh otherwise and every rotations_per_refresh steps. A sample
!> enters the sums once, with its whole trapezoid weight, when the next one
!> arrives (the last one's half weight is added when the fit is solved), as
!> fixed-length columns that vectorise: a step costs a few vector
!> multiply-adds.
module ellroll_harmonic_fit
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: harmonic_fit_t

  integer, parameter :: max_basis = 7              !< 1, and a cosine and a sine for 3 frequencies
  integer, parameter :: rows = 8                   !< max_basis padded to whole vectors (the last row stays 0)
  integer, parameter :: signals = 4                !< two components of the response, two of the forcing
  integer, parameter :: rotations_per_refresh = 256

  type :: harmonic_fit_t
    real(wp) :: start = huge(1.0_wp)               !< the window's start, s
    integer :: n_basis = 0
    real(wp) :: omega(3) = 0                       !< the forcing's frequency, then the modes' (rad/s)
    real(wp) :: gram(rows, max_basis) = 0          !< without the last sample's half weight
    real(wp) :: moments(rows, signals) = 0
    real(wp) :: t_prev = 0, basis_prev(rows) = 0, values_prev(signals) = 0
    real(wp) :: pending = 0                        !< the last sample's weight so far (half its step)
    real(wp) :: h_prev = -1, rotation(2, 3) = 0    !< cos and sin of omega h for the last step h
    integer :: since_refresh = 0
    logical :: has_prev = .false.
  contains
    procedure :: begin
    procedure :: add
    procedure :: ratio
  end type harmonic_fit_t

contains

  !> A fit over [start, the last sample] at forcing frequency `forcing` (rad/s)
  !> with the free modes' frequencies (rad/s; NaN, 0, or within a window's
  !> resolution of the forcing: left out).
  pure subroutine begin(self, forcing, modes, start, window)
    class(harmonic_fit_t), intent(inout) :: self
    real(wp), intent(in) :: forcing, modes(:), start, window
    integer :: k
    self%start = start
    self%omega(1) = forcing
    self%n_basis = 3
    do k = 1, size(modes)
      if (.not. ieee_is_finite(modes(k))) cycle
      if (.not. modes(k) > 0) cycle
      ! frequencies closer than one cycle per window cannot be told apart
      if (abs(modes(k) - forcing) * window < 8 * atan(1.0_wp)) cycle
      if (self%n_basis == max_basis) exit
      self%omega(self%n_basis / 2 + 1) = modes(k)
      self%n_basis = self%n_basis + 2
    end do
  end subroutine begin

  !> The sample at time t of the response (ball(2)) and of the forcing (base(2)).
  pure subroutine add(self, t, ball, base)
    class(harmonic_fit_t), intent(inout) :: self
    real(wp), intent(in) :: t, ball(2), base(2)
    real(wp) :: basis(rows), half, weight
    if (t < self%start .or. self%n_basis == 0) return
    call self_basis(self, t, basis)
    if (self%has_prev) then            ! trapezoid rule on (t_prev, t]: the last sample is whole
      half = (t - self%t_prev) / 2
      weight = self%pending + half
      call add_sample(self%gram, self%moments, weight, self%basis_prev, self%values_prev)
      self%pending = half
    end if
    self%t_prev = t
    self%basis_prev = basis
    self%values_prev = [ball, base]
    self%has_prev = .true.
  end subroutine add

  !> weight times a sample's products (basis basis^T, basis values^T) added to
  !> the sums: a column (one vector of rows) per basis function and signal.
  pure subroutine add_sample(gram, moments, weight, basis, values)
    real(wp), intent(inout) :: gram(rows, max_basis), moments(rows, signals)
    real(wp), intent(in) :: weight, basis(rows), values(signals)
    real(wp) :: scale(max_basis + signals)
    integer :: i, j
    scale(:max_basis) = weight * basis(:max_basis)
    scale(max_basis + 1:) = weight * values
    ! one vector per column (unrolled, the vectorizer turns the loops inside out)
    !GCC$ unroll 0
    do i = 1, max_basis
      !$omp simd
      do j = 1, rows
        gram(j, i) = gram(j, i) + scale(i) * basis(j)
      end do
    end do
    !GCC$ unroll 0
    do i = 1, signals
      !$omp simd
      do j = 1, rows
        moments(j, i) = moments(j, i) + scale(max_basis + i) * basis(j)
      end do
    end do
  end subroutine add_sample

  !> The basis at t: rotated from the last sample's when the step repeats,
  !> else (and every rotations_per_refresh rotations) computed afresh.
  pure subroutine self_basis(self, t, basis)
    type(harmonic_fit_t), intent(inout) :: self
    real(wp), intent(in) :: t
    real(wp), intent(out) :: basis(rows)
    real(wp) :: h, c, s
    integer :: k, j
    basis = 0
    basis(1) = 1
    h = t - self%t_prev
    ! a fixed step's times are step * dt, so their differences repeat only to
    ! within the rounding of t: each rotation is off by at most omega 4
    ! spacing(t), which the refresh bounds (1e-10 rad at t = 100 s, far below
    ! the fit's own error)
    if (self%has_prev .and. abs(h - self%h_prev) <= 4 * spacing(t) .and. self%since_refresh < rotations_per_refresh) then
      do k = 1, (self%n_basis - 1) / 2
        j = 2 * k
        c = self%basis_prev(j)
        s = self%basis_prev(j + 1)
        basis(j) = c * self%rotation(1, k) - s * self%rotation(2, k)
        basis(j + 1) = s * self%rotation(1, k) + c * self%rotation(2, k)
      end do
      self%since_refresh = self%since_refresh + 1
      return
    end if
    do k = 1, (self%n_basis - 1) / 2
      basis(2 * k) = cos(self%omega(k) * t)
      basis(2 * k + 1) = sin(self%omega(k) * t)
      if (self%has_prev) self%rotation(:, k) = [cos(self%omega(k) * h), sin(self%omega(k) * h)]
    end do
    self%h_prev = merge(h, -1.0_wp, self%has_prev)
    self%since_refresh = 0
  end subroutine self_basis

  !> |response| / |forcing| at the forcing frequency (horizontal vectors'
  !> amplitudes); NaN where the forcing has none or the window holds too
  !> little to fit.
  pure real(wp) function ratio(self)
    class(harmonic_fit_t), intent(in) :: self
    real(wp) :: coefficients(max_basis, signals), response, forcing
    real(wp) :: gram(rows, max_basis), moments(rows, signals)
    logical :: solved
    ratio = ieee_value(0.0_wp, ieee_quiet_nan)
    if (self%n_basis == 0 .or. .not. self%has_prev) return
    gram = self%gram
    moments = self%moments
    call add_sample(gram, moments, self%pending, self%basis_prev, self%values_prev)
    call solve(gram(:self%n_basis, :self%n_basis), moments(:self%n_basis, :), &
               coefficients(:self%n_basis, :), solved)
    if (.not. solved) return
    response = norm2(coefficients(2:3, 1:2))
    forcing = norm2(coefficients(2:3, 3:4))
    if (forcing > 0) ratio = response / forcing
  end function ratio

  !> x of a x = b (a symmetric, positive definite: a Gram matrix) by
  !> Gaussian elimination with partial pivoting; solved false where a is
  !> singular to working precision.
  pure subroutine solve(a, b, x, solved)
    real(wp), intent(in) :: a(:, :), b(:, :)
    real(wp), intent(out) :: x(:, :)
    logical, intent(out) :: solved
    real(wp) :: m(size(a, 1), size(a, 1)), r(size(b, 1), size(b, 2)), row(size(a, 1)), factor
    real(wp) :: rhs(size(b, 2))
    integer :: n, i, j, pivot
    n = size(a, 1)
    m = a
    r = b
    solved = .false.
    do i = 1, n
      pivot = maxloc(abs(m(i:, i)), dim=1) + i - 1
      if (.not. abs(m(pivot, i)) > 1.0e-13_wp * maxval(abs(a))) return
      if (pivot /= i) then
        row = m(i, :)
        m(i, :) = m(pivot, :)
        m(pivot, :) = row
        rhs = r(i, :)
        r(i, :) = r(pivot, :)
        r(pivot, :) = rhs
      end if
      do j = i + 1, n
        factor = m(j, i) / m(i, i)
        m(j, i:) = m(j, i:) - factor * m(i, i:)
        r(j, :) = r(j, :) - factor * r(i, :)
      end do
    end do
    do i = n, 1, -1
      x(i, :) = (r(i, :) - matmul(m(i, i + 1:), x(i + 1:, :))) / m(i, i)
    end do
    solved = .true.
  end subroutine solve
end module ellroll_harmonic_fit
