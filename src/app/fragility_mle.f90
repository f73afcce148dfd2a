!> A lognormal fragility P(exceed | IM = x) = Phi(ln(x / theta) / beta)
!> fitted by maximum likelihood to exceedance counts per intensity (Baker,
!> Earthquake Spectra 31(1), 2015: z(j) of n(j) cases exceed at x(j)), as
!> ellroll_post.fragility.fit_stripes fits it. The log-likelihood
!> sum z ln Phi(a + b t) + (n - z) ln Phi(-(a + b t)), t = ln x, is concave
!> in (a, b) (a probit model), so Newton's method with a halving line search
!> reaches its one maximum from any start; theta = exp(-a / b), beta = 1 / b.
!> Counts that separate in the intensity (none exceeds below a level, all
!> above, at most one level with some of each) have no finite maximum: the
!> result is the step there (beta = 0), as separating_step gives it.
!> Counts whose likelihood has its supremum at beta -> infinity (exceedances
!> that do not grow with the intensity) give NaN.
module ellroll_fragility_mle
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: fit_stripes

  real(wp), parameter :: sqrt_half = 0.70710678118654752440_wp
  real(wp), parameter :: sqrt_two_over_pi = 0.79788456080286535588_wp

contains

  !> theta, beta of the counts (x > 0, 0 <= z <= n, some z > 0 and some
  !> z < n: the caller checks); separated where the step is the answer.
  subroutine fit_stripes(x, counts, exceeded, theta, beta, separated)
    real(wp), intent(in) :: x(:)
    integer, intent(in) :: counts(:), exceeded(:)
    real(wp), intent(out) :: theta, beta
    logical, intent(out) :: separated
    real(wp) :: t(size(x)), a, b, step_a, step_b, g(2), h(3), det, now, trial, mean, spread, scale
    real(wp) :: n(size(x)), z(size(x))
    integer :: iteration, halving
    call separating_step(x, counts, exceeded, theta, separated)
    n = real(counts, wp)
    z = real(exceeded, wp)
    beta = 0
    if (separated) return
    t = log(x)
    mean = sum(n * t) / sum(n)
    spread = sqrt(sum(n * (t - mean)**2) / sum(n))
    b = 1 / spread
    a = -b * mean
    now = log_likelihood(a, b)
    do iteration = 1, 200
      call derivatives(a, b, g, h)
      det = h(1) * h(3) - h(2)**2
      if (.not. det > 0) exit
      step_a = (h(3) * g(1) - h(2) * g(2)) / det
      step_b = (h(1) * g(2) - h(2) * g(1)) / det
      scale = 1
      do halving = 1, 60
        if (b + scale * step_b > 0) then
          trial = log_likelihood(a + scale * step_a, b + scale * step_b)
          if (trial >= now) exit
        end if
        scale = scale / 2
      end do
      if (halving > 60) exit
      a = a + scale * step_a
      b = b + scale * step_b
      now = trial
      if (abs(scale * step_a) <= 1e-14_wp * max(1.0_wp, abs(a)) .and. &
          abs(scale * step_b) <= 1e-14_wp * max(1.0_wp, abs(b))) exit
      ! counts that fall with the intensity push b to 0, near-separated ones to infinity
      if (b < 1e-8_wp .or. b > 1e100_wp .or. abs(a) > 1e100_wp) exit
    end do
    theta = ieee_value(theta, ieee_quiet_nan)
    beta = theta
    ! no fragility a number can hold (beta above 1e8: a flat curve); the caller says so
    if (b < 1e-8_wp .or. b > 1e100_wp .or. abs(a / b) > 700) return
    theta = exp(-a / b)
    beta = 1 / b
  contains
    real(wp) function log_likelihood(a, b) result(value)
      real(wp), intent(in) :: a, b
      integer :: j
      value = 0
      do j = 1, size(t)
        value = value + z(j) * log_phi(a + b * t(j)) + (n(j) - z(j)) * log_phi(-(a + b * t(j)))
      end do
    end function log_likelihood

    !> The gradient g and minus the Hessian h (h11, h12, h22) in (a, b).
    subroutine derivatives(a, b, g, h)
      real(wp), intent(in) :: a, b
      real(wp), intent(out) :: g(2), h(3)
      real(wp) :: eta, up, down, w, c
      integer :: j
      g = 0
      h = 0
      do j = 1, size(t)
        eta = a + b * t(j)
        up = mills(eta)
        down = mills(-eta)
        w = z(j) * up - (n(j) - z(j)) * down
        c = z(j) * up * (eta + up) + (n(j) - z(j)) * down * (down - eta)
        g = g + w * [1.0_wp, t(j)]
        h = h + c * [1.0_wp, t(j), t(j)**2]
      end do
    end subroutine derivatives
  end subroutine fit_stripes

  !> ln Phi(u) without cancellation: through erfc_scaled below 0.
  elemental real(wp) function log_phi(u)
    real(wp), intent(in) :: u
    if (u < 0) then
      log_phi = log(0.5_wp * erfc_scaled(-u * sqrt_half)) - 0.5_wp * u**2
    else
      log_phi = log(0.5_wp * erfc(-u * sqrt_half))
    end if
  end function log_phi

  !> phi(u) / Phi(u), the inverse Mills ratio of -u.
  elemental real(wp) function mills(u)
    real(wp), intent(in) :: u
    if (u < 0) then
      mills = sqrt_two_over_pi / erfc_scaled(-u * sqrt_half)
    else
      mills = sqrt_two_over_pi * exp(-0.5_wp * u**2) / erfc(-u * sqrt_half)
    end if
  end function mills

  !> ellroll_post.fragility.separating_step: the step where the counts
  !> separate (the one mixed level, else the geometric mean of the last
  !> level without exceedance and the first with only exceedances).
  subroutine separating_step(x, n, z, theta, separated)
    real(wp), intent(in) :: x(:)
    integer, intent(in) :: n(:), z(:)
    real(wp), intent(out) :: theta
    logical, intent(out) :: separated
    integer :: order(size(x)), j, k, mixed
    real(wp) :: below, above
    order = [(j, j = 1, size(x))]
    do j = 2, size(x)                  ! a few levels: insertion sort by x
      k = j
      do while (k > 1)
        if (.not. x(order(k)) < x(order(k - 1))) exit
        order([k - 1, k]) = order([k, k - 1])
        k = k - 1
      end do
    end do
    theta = 0
    separated = .false.
    mixed = count(z > 0 .and. z < n)
    if (mixed > 1 .or. sum(z) == 0 .or. sum(z) == sum(n)) return
    do j = 2, size(x)
      if (real(z(order(j)), wp) / n(order(j)) < real(z(order(j - 1)), wp) / n(order(j - 1))) return
    end do
    separated = .true.
    if (mixed == 1) then
      do j = 1, size(x)
        if (z(order(j)) > 0 .and. z(order(j)) < n(order(j))) then
          theta = x(order(j))
          return
        end if
      end do
    end if
    below = maxval(x, mask=z == 0)
    above = minval(x, mask=z == n)
    theta = sqrt(below * above)
  end subroutine separating_step
end module ellroll_fragility_mle
