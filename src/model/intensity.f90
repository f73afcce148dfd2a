!> Intensity measures of a ground-motion record: the peaks of the horizontal
!> ground acceleration, velocity and displacement (PGA, PGV, PGD) and the
!> pseudo-spectral acceleration Sa(T) = (2 pi / T)^2 max |u| of a damped
!> linear oscillator u'' + 2 zeta w u' + w^2 u = -a_g(t), isotropic in the
!> horizontal plane (the peak of |u|, the vector of both components: RotD100).
!>
!> The record is piecewise linear between its samples (as the model reads
!> it), so each response is exact over a sample step: the oscillator's state
!> advances by the exponential of the augmented system
!>     d/ds (u, v, f, f') = [[0, 1, 0, 0], [-w^2, -2 zeta w, 1, 0],
!>                          [0, 0, 0, 1], [0, 0, 0, 0]] (u, v, f, f'),
!> f = -a_g linear over the step (Nigam and Jennings' recurrence, in matrix
!> form); velocity and displacement are the exact integrals of the linear
!> acceleration. The peaks of PGV and PGD are taken on the exact solution at
!> `refinement` points per sample step, those of Sa at points at most
!> max_phase_step of the oscillator's phase apart, with the Hermite cubic's
!> peak between them.
module ellroll_intensity
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: record_intensity_t, record_intensity, pseudo_spectral_acceleration, refinement, intensity_of, &
            felt_spectral_acceleration, damping_ratio, max_sa_periods

  !> The damping ratio of the spectral accelerations stored (the 5 % of the
  !> design spectra of ASCE 7 and Eurocode 8).
  real(wp), parameter :: damping_ratio = 0.05_wp
  !> The most user-given periods of Sa (&excitation sa_periods).
  integer, parameter :: max_sa_periods = 16

  !> Points per sample step at which the peaks of velocity and displacement
  !> are taken (the solution is exact there): a peak between them is missed
  !> by at most about
  !> (w h / refinement)^2 / 8 of itself, h the sample step.
  integer, parameter :: refinement = 16
  !> Largest phase step (omega h, rad) between the exact points of Sa's
  !> oscillator (oscillator_sub_steps).
  real(wp), parameter :: max_phase_step = 0.05_wp
  !> Most exact points per sample step. An oscillator whose period is far
  !> below the sample step (it would need more) follows the piecewise-linear
  !> record quasi-statically apart from the transient that each kink of the
  !> record starts, of relative size about its period over the step; that
  !> transient has died out by exp(-zeta max_phase_step max_sub_steps) =
  !> exp(-10) after max_sub_steps - 1 points at max_phase_step, and the rest
  !> of the step is one exact step (whose |u|, a line there, peaks at an
  !> end): stiff_sample_step.
  integer, parameter :: max_sub_steps = 4000
  !> The stiffest oscillator computed (rad/s; a period of 5.2e-24 s): at a
  !> shorter period Sa is its value here. Sa exceeds its limit T -> 0 by
  !> the lag and overshoot after each kink of the record, at most about
  !> 4 (1 + 2 zeta) / (omega h) of PGA (slopes change by at most 4 PGA / h,
  !> h >= 1e-6 s the shortest sample step): below 4e-18 of it here, under
  !> round-off; and omega^2 (1.5e48) stays far from overflow, its inverse
  !> far from underflow, as the scaled variables need.
  real(wp), parameter :: max_omega = 2.0_wp**80

  !> stiff_sample_step's propagator over its fine step (h_fine < 0: none yet)
  type :: stiff_propagators_t
    real(wp) :: h_fine = -1
    real(wp) :: fine(4, 4) = 0
  end type stiff_propagators_t

  type :: record_intensity_t
    real(wp) :: pga = 0     !< m/s^2, peak of |a_g| (horizontal)
    real(wp) :: pgv = 0     !< m/s
    real(wp) :: pgd = 0     !< m
    real(wp), allocatable :: periods(:)   !< s, of sa
    real(wp), allocatable :: sa(:)        !< m/s^2, at damping_ratio
  end type record_intensity_t

contains

  !> Every intensity measure of the record: PGA, PGV, PGD and Sa at `periods`,
  !> of its part from t = 0, where a case starts (at rest, shaken by the
  !> record's value there): samples before 0 are never felt.
  pure function intensity_of(times, values, periods) result(im)
    real(wp), intent(in) :: times(:), values(:, :), periods(:)
    type(record_intensity_t) :: im
    real(wp), allocatable :: felt_times(:), felt_values(:, :)
    if (times(1) >= 0) then
      im = record_intensity(times, values)
    else
      call from_time_zero(times, values, felt_times, felt_values)
      im = record_intensity(felt_times, felt_values)
    end if
    im%sa = felt_spectral_acceleration(times, values, periods)
    im%periods = periods
  end function intensity_of

  !> Sa at `periods` (damping_ratio) of the record's part from t = 0, as
  !> intensity_of takes it: samples before 0 are never felt.
  pure function felt_spectral_acceleration(times, values, periods) result(sa)
    real(wp), intent(in) :: times(:), values(:, :), periods(:)
    real(wp) :: sa(size(periods))
    real(wp), allocatable :: felt_times(:), felt_values(:, :)
    if (times(1) >= 0) then
      sa = pseudo_spectral_acceleration(times, values, periods, damping_ratio)
    else
      call from_time_zero(times, values, felt_times, felt_values)
      sa = pseudo_spectral_acceleration(felt_times, felt_values, periods, damping_ratio)
    end if
  end function felt_spectral_acceleration

  !> The record from t = 0 on (times(1) < 0): its value at 0 interpolated
  !> as the case reads it (ellroll_excitation's base_acceleration: linear,
  !> the last sample's value past the end), then its samples after 0.
  pure subroutine from_time_zero(times, values, felt_times, felt_values)
    real(wp), intent(in) :: times(:), values(:, :)
    real(wp), allocatable, intent(out) :: felt_times(:), felt_values(:, :)
    real(wp) :: weight
    integer :: first, n
    n = size(times)
    first = n + 1                          ! the first sample after 0
    do while (first > 1)
      if (.not. times(first - 1) > 0) exit
      first = first - 1
    end do
    allocate (felt_times(n - first + 2), felt_values(size(values, 1), n - first + 2))
    felt_times(1) = 0
    if (first > n) then
      felt_values(:, 1) = values(:, n)
    else
      weight = (0 - times(first - 1)) / (times(first) - times(first - 1))
      felt_values(:, 1) = (1 - weight) * values(:, first - 1) + weight * values(:, first)
    end if
    felt_times(2:) = times(first:)
    felt_values(:, 2:) = values(:, first:)
  end subroutine from_time_zero

  !> PGA, PGV and PGD of the horizontal components (rows 1 and 2 of values,
  !> m/s^2, at times, s), from rest at the first sample.
  pure function record_intensity(times, values) result(im)
    real(wp), intent(in) :: times(:), values(:, :)
    type(record_intensity_t) :: im
    real(wp) :: v(2), d(2), v_next(2), d_next(2), v_start(2), d_start(2), a0(2), a1(2), h, s, s_prev
    integer :: k, j
    v = 0
    d = 0
    im%pga = norm2(values(1:2, 1))
    do k = 1, size(times) - 1
      h = times(k + 1) - times(k)
      a0 = values(1:2, k)
      a1 = values(1:2, k + 1)
      ! |a| is convex on the step: its peak is at a sample
      im%pga = max(im%pga, norm2(a1))
      v_start = v
      d_start = d
      do j = 1, refinement
        s = h * j / refinement
        s_prev = h * (j - 1) / refinement
        v_next = v_start + a0 * s + (a1 - a0) * s**2 / (2 * h)
        d_next = d_start + v_start * s + a0 * s**2 / 2 + (a1 - a0) * s**3 / (6 * h)
        ! v is quadratic and d cubic in s: Hermite's cubic on a sub-step is exact
        im%pgv = max(im%pgv, norm2(v_next), &
                     hermite_peak(v, a0 + (a1 - a0) * (s_prev / h), v_next, a0 + (a1 - a0) * (s / h), s - s_prev))
        im%pgd = max(im%pgd, norm2(d_next), hermite_peak(d, v, d_next, v_next, s - s_prev))
        v = v_next
        d = d_next
      end do
    end do
  end function record_intensity

  !> Sa(T) = (2 pi / T)^2 max |u| for each period (s) at damping ratio zeta,
  !> the oscillator at rest at the first sample (NaN at a period that is not
  !> positive and finite).
  pure function pseudo_spectral_acceleration(times, values, periods, zeta) result(sa)
    real(wp), intent(in) :: times(:), values(:, :), periods(:), zeta
    real(wp) :: sa(size(periods))
    real(wp) :: omega, peak, x(2, 2), x_prev(2, 2), h, h_step, f0(2), f1(2), slope(2), propagator(4, 4)
    type(stiff_propagators_t) :: stiff
    integer :: p, k, j, sub_steps
    do p = 1, size(periods)
      if (.not. (periods(p) > 0 .and. periods(p) < huge(1.0_wp))) then
        sa(p) = ieee_value(0.0_wp, ieee_quiet_nan)
        cycle
      end if
      if (periods(p) > 8 * atan(1.0_wp) / max_omega) then
        omega = 8 * atan(1.0_wp) / periods(p)
      else
        omega = max_omega
      end if
      x = 0                                 ! (u, v) of each horizontal component
      peak = 0
      h_step = -1
      stiff = stiff_propagators_t()
      do k = 1, size(times) - 1
        sub_steps = oscillator_sub_steps(omega, times(k + 1) - times(k))
        f0 = -values(1:2, k)
        f1 = -values(1:2, k + 1)
        slope = (f1 - f0) / (times(k + 1) - times(k))
        if (sub_steps > max_sub_steps) then
          call stiff_sample_step(omega, zeta, times(k + 1) - times(k), spacing(times(k + 1)), f0, slope, x, peak, stiff)
          cycle
        end if
        h = (times(k + 1) - times(k)) / sub_steps
        ! records on an even grid: once (their times k dt repeat the step
        ! only to the round-off of t, whose effect on the propagator is
        ! round-off too)
        if (.not. abs(h - h_step) <= 4 * spacing(times(k + 1))) then
          propagator = exponential(oscillator(omega, zeta) * h)
          h_step = h
        end if
        do j = 1, sub_steps
          x_prev = x
          x = advance(propagator, x, f0 + slope * (h * (j - 1)), slope)
          peak = max(peak, sub_step_peak(x_prev, x, h))
        end do
      end do
      sa(p) = omega**2 * peak
    end do
  end function pseudo_spectral_acceleration

  !> The largest |u| of a sub-step of size piece from the exact state x_prev
  !> to x: at its end or, between them, on Hermite's cubic of u from u and u'
  !> (error of order (omega piece)^4 of the peak).
  pure real(wp) function sub_step_peak(x_prev, x, piece) result(peak)
    real(wp), intent(in) :: x_prev(2, 2), x(2, 2), piece
    real(wp) :: u_prev(2), v_prev(2), u_now(2), v_now(2)
    u_prev = x_prev(1, :)      ! (contiguous: no array temporaries)
    v_prev = x_prev(2, :)
    u_now = x(1, :)
    v_now = x(2, :)
    peak = max(hypot(x(1, 1), x(1, 2)), hermite_peak(u_prev, v_prev, u_now, v_now, piece))
  end function sub_step_peak

  !> A sample step of length step (spacing_end: its end time's) of the
  !> oscillator omega, zeta far stiffer than the step (max_sub_steps), from
  !> its state x (u, v of each component) with forcing f0 at its start and
  !> slope df/dt: max_sub_steps - 1 points max_phase_step apart and one exact
  !> step to the end (long_scaled_step), in the variables (omega^2 u, omega
  !> v), whose propagator's entries are of order omega h (those of (u, v)
  !> span omega^2 h to h^2 / 2: round-off would swamp the small ones); peak:
  !> the largest |u| so far.
  pure subroutine stiff_sample_step(omega, zeta, step, spacing_end, f0, slope, x, peak, cache)
    real(wp), intent(in) :: omega, zeta, step, spacing_end, f0(2), slope(2)
    real(wp), intent(inout) :: x(2, 2), peak
    type(stiff_propagators_t), intent(inout) :: cache
    real(wp) :: xs(2, 2), xs_prev(2, 2), h, h_rest
    integer :: j
    h = max_phase_step / omega
    h_rest = step - (max_sub_steps - 1) * h
    if (.not. abs(h - cache%h_fine) <= 4 * spacing_end) then
      cache%fine = exponential(scaled_oscillator(omega, zeta) * h)
      cache%h_fine = h
    end if
    xs(1, :) = omega**2 * x(1, :)
    xs(2, :) = omega * x(2, :)
    do j = 1, max_sub_steps
      xs_prev = xs
      if (j < max_sub_steps) then
        xs = advance(cache%fine, xs, f0 + slope * (h * (j - 1)), slope)
        peak = max(peak, scaled_peak(xs_prev, xs, omega, h) / omega**2)
      else
        ! a line (the transient is gone): it peaks at an end. Hermite's
        ! cubic would take omega (omega v)'s round-off (eps |omega^2 u|
        ! omega) over h_rest: a false peak once omega h_rest nears 1 / eps
        xs = long_scaled_step(xs, omega, zeta, f0 + slope * (h * (j - 1)), slope, h_rest)
        peak = max(peak, hypot(xs(1, 1), xs(1, 2)) / omega**2)
      end if
    end do
    x(1, :) = xs(1, :) / omega**2
    x(2, :) = xs(2, :) / omega
  end subroutine stiff_sample_step

  !> The state (omega^2 u, omega v) of each component after time tau from
  !> x, the forcing f + slope t over it, in closed form: the particular
  !> solution (f - 2 zeta slope / omega, slope / omega) plus the damped free
  !> oscillation of the difference (a matrix exponential over omega tau >=
  !> 200 would lose the small entries to its squarings' round-off).
  pure function long_scaled_step(x, omega, zeta, f, slope, tau) result(next)
    real(wp), intent(in) :: x(2, 2), omega, zeta, f(2), slope(2), tau
    real(wp) :: next(2, 2), d0, e0, decay, c, s, root
    integer :: k
    root = sqrt(1 - zeta**2)
    decay = exp(-zeta * omega * tau)
    c = cos(root * omega * tau)
    s = sin(root * omega * tau)
    do k = 1, 2
      d0 = x(1, k) - (f(k) - 2 * zeta * slope(k) / omega)
      e0 = x(2, k) - slope(k) / omega
      next(1, k) = (f(k) + slope(k) * tau - 2 * zeta * slope(k) / omega) + decay * (d0 * c + (e0 + zeta * d0) / root * s)
      next(2, k) = slope(k) / omega + decay * (e0 * c - (d0 + zeta * e0) / root * s)
    end do
  end function long_scaled_step

  !> sub_step_peak in the variables (omega^2 u, omega v) of x_prev and x:
  !> the largest omega^2 |u|.
  pure real(wp) function scaled_peak(x_prev, x, omega, piece) result(peak)
    real(wp), intent(in) :: x_prev(2, 2), x(2, 2), omega, piece
    real(wp) :: u_prev(2), q_prev(2), u_now(2), q_now(2)
    u_prev = x_prev(1, :)
    q_prev = omega * x_prev(2, :)       ! (omega^2 u)' = omega (omega v)
    u_now = x(1, :)
    q_now = omega * x(2, :)
    peak = max(hypot(x(1, 1), x(1, 2)), hermite_peak(u_prev, q_prev, u_now, q_now, piece))
  end function scaled_peak

  !> Exact points per sample step of length h for the oscillator of angular
  !> frequency omega: at most max_phase_step radians apart, so that the
  !> Hermite cubic between them misses a peak by about max_phase_step^4 /
  !> 384 of it (2e-8) where the oscillator's own motion drives the cubic's
  !> error (up to 3e-7 at long periods, where the ground drives it:
  !> docs/output.md); at least one; max_sub_steps + 1
  !> where it would be more than max_sub_steps (no integer overflow).
  pure integer function oscillator_sub_steps(omega, h)
    real(wp), intent(in) :: omega, h
    if (omega * h / max_phase_step > max_sub_steps) then
      oscillator_sub_steps = max_sub_steps + 1
    else
      oscillator_sub_steps = max(1, ceiling(omega * h / max_phase_step))
    end if
  end function oscillator_sub_steps

  !> The largest |p(s)| inside [0, delta] of the cubic Hermite interpolant
  !> of a plane vector p with values p0, p1 and derivatives q0, q1 at the
  !> ends, where |p| has a maximum inside (d|p|^2/ds falls from > 0 to
  !> <= 0); else 0 (the ends are taken apart). A golden-section search: |p|
  !> is unimodal on a sub-step that short.
  pure real(wp) function hermite_peak(p0, q0, p1, q1, delta) result(peak)
    real(wp), intent(in) :: p0(2), q0(2), p1(2), q1(2), delta
    real(wp), parameter :: ratio = 0.6180339887498949_wp
    real(wp) :: low, high, s1, s2, f1, f2
    integer :: it
    peak = 0
    if (.not. (dot_product(p0, q0) > 0 .and. dot_product(p1, q1) <= 0)) return
    low = 0
    high = 1
    s1 = high - ratio * (high - low)
    s2 = low + ratio * (high - low)
    f1 = at(s1)
    f2 = at(s2)
    do it = 1, 60
      if (f1 < f2) then
        low = s1
        s1 = s2
        f1 = f2
        s2 = low + ratio * (high - low)
        f2 = at(s2)
      else
        high = s2
        s2 = s1
        f2 = f1
        s1 = high - ratio * (high - low)
        f1 = at(s1)
      end if
    end do
    peak = sqrt(max(f1, f2))
  contains
    !> |p|^2 at the fraction t of the sub-step
    pure real(wp) function at(t)
      real(wp), intent(in) :: t
      real(wp) :: p(2)
      p = (2 * t**3 - 3 * t**2 + 1) * p0 + (t**3 - 2 * t**2 + t) * delta * q0 + (-2 * t**3 + 3 * t**2) * p1 + &
          (t**3 - t**2) * delta * q1
      at = dot_product(p, p)
    end function at
  end function hermite_peak

  !> The state (u, v) of each component after one sub-step, from its start
  !> x with forcing f there and slope df/dt.
  pure function advance(propagator, x, f, slope) result(next)
    real(wp), intent(in) :: propagator(4, 4), x(2, 2), f(2), slope(2)
    real(wp) :: next(2, 2)
    integer :: c
    do c = 1, 2
      next(:, c) = matmul(propagator(1:2, :), [x(1, c), x(2, c), f(c), slope(c)])
    end do
  end function advance

  !> oscillator's matrix in the variables (omega^2 u, omega v, f, f')
  pure function scaled_oscillator(omega, zeta) result(a)
    real(wp), intent(in) :: omega, zeta
    real(wp) :: a(4, 4)
    a = 0
    a(1, 2) = omega
    a(2, 1) = -omega
    a(2, 2) = -2 * zeta * omega
    a(2, 3) = omega
    a(3, 4) = 1
  end function scaled_oscillator

  pure function oscillator(omega, zeta) result(a)
    real(wp), intent(in) :: omega, zeta
    real(wp) :: a(4, 4)
    a = 0
    a(1, 2) = 1
    a(2, 1) = -omega**2
    a(2, 2) = -2 * zeta * omega
    a(2, 3) = 1
    a(3, 4) = 1
  end function oscillator

  !> exp(a) of a small matrix: scaled to a norm below 1/2, a Taylor series
  !> to round-off, squared back.
  pure function exponential(a) result(e)
    real(wp), intent(in) :: a(:, :)
    real(wp) :: e(size(a, 1), size(a, 2)), term(size(a, 1), size(a, 2)), scaled(size(a, 1), size(a, 2))
    integer :: squarings, k, i
    squarings = max(0, exponent(maxval(sum(abs(a), dim=1))) + 1)
    scaled = a / 2.0_wp**squarings
    e = 0
    term = 0
    do i = 1, size(a, 1)
      e(i, i) = 1
      term(i, i) = 1
    end do
    do k = 1, 30
      term = matmul(term, scaled) / k
      e = e + term
      if (maxval(abs(term)) <= epsilon(1.0_wp) * maxval(abs(e)) * 1.0e-2_wp) exit
    end do
    do k = 1, squarings
      e = matmul(e, e)
    end do
  end function exponential
end module ellroll_intensity
