!> Intensity measures of a record against independent truth:
!>  - PGV and PGD of a sine record against the closed-form integrals of the
!>    sampled (piecewise-linear) acceleration, and of the sine itself;
!>  - Sa(T) against a classical RK4 of the oscillator on the same
!>    piecewise-linear record at 200 steps per sample (an independent
!>    integrator), for several periods, both components;
!>  - the steady state under a long sine (a smooth rise, then constant
!>    amplitude): Sa -> w^2 A / sqrt((w^2 - W^2)^2 + (2 zeta w W)^2);
!>  - isotropy: a record along x and the same record turned by 30 degrees
!>    give the same figures (RotD100: the peak of the vector).
program test_intensity
  use ellroll_kinds, only: wp, pi, two_pi
  use ellroll_intensity, only: record_intensity_t, record_intensity, pseudo_spectral_acceleration
  use testing
  implicit none
  integer, parameter :: n = 4001
  real(wp), parameter :: zeta = 0.05_wp, amplitude = 2.0_wp, forcing = 0.7_wp     ! m/s^2, Hz
  real(wp) :: times(n), values(3, n), turned(3, n), periods(4), sa(4), reference
  real(wp) :: steady(1), expected
  type(record_intensity_t) :: im, im_turned
  integer :: k, p

  ! a sine record at 100 Hz for 40 s
  do k = 1, n
    times(k) = (k - 1) * 0.01_wp
    values(:, k) = [amplitude * sin(two_pi * forcing * times(k)), 0.0_wp, 0.0_wp]
  end do
  im = record_intensity(times, values)
  call check_close(im%pga, amplitude * maxval(abs(sin(two_pi * forcing * times))), 1.0e-14_wp, 'PGA of the samples')
  ! the exact integrals of the piecewise-linear record: v's peak where a
  ! changes sign inside a step, d's (growing) at the end
  call exact_peaks(reference, expected)
  call check_close(im%pgv, reference, 1.0e-6_wp, 'PGV of the piecewise-linear record (m/s)')
  call check_close(im%pgd, expected, 1.0e-12_wp, 'PGD of the piecewise-linear record (m)')
  ! and of the sine itself, to the sampling's error: v = A (1 - cos W t) / W
  ! peaks at 2 A / W; d = A (t / W - sin(W t) / W^2)
  call check_close(im%pgv, 2 * amplitude / (two_pi * forcing), 3.0e-4_wp, 'PGV of a sine from rest (m/s)')
  call check_close(im%pgd, amplitude * (times(n) / (two_pi * forcing) - sin(two_pi * forcing * times(n)) / &
                   (two_pi * forcing)**2), 3.0e-4_wp, 'PGD of a sine from rest (m)')

  ! Sa against an independent integrator of the same piecewise-linear record
  periods = [0.1_wp, 0.5_wp, 1.4285714_wp, 4.0_wp]
  do k = 1, n
    values(2, k) = 0.5_wp * amplitude * cos(two_pi * 1.3_wp * times(k)) * exp(-0.1_wp * times(k))
  end do
  sa = pseudo_spectral_acceleration(times, values, periods, zeta)
  do p = 1, size(periods)
    reference = rk4_sa(periods(p))
    call check_close(sa(p), reference, 2.0e-4_wp, 'Sa against RK4 at 200 steps per sample, T = ' // &
                     trim(number(periods(p))) // ' s')
  end do

  ! isotropy: the same motion turned in the horizontal plane
  turned(1, :) = cos(pi / 6) * values(1, :) - sin(pi / 6) * values(2, :)
  turned(2, :) = sin(pi / 6) * values(1, :) + cos(pi / 6) * values(2, :)
  turned(3, :) = 0
  im = record_intensity(times, values)
  im_turned = record_intensity(times, turned)
  call check_close(im_turned%pga, im%pga, 1.0e-13_wp, 'PGA does not depend on the axes')
  call check_close(im_turned%pgd, im%pgd, 1.0e-12_wp, 'PGD does not depend on the axes')
  steady = pseudo_spectral_acceleration(times, turned, periods(2:2), zeta)
  call check_close(steady(1), sa(2), 1.0e-12_wp, 'Sa does not depend on the axes')

  ! the steady state under a long sine after a smooth rise (sin^2 over 10 s:
  ! its rate is continuous at the end of the rise), the start's free motion
  ! decayed by exp(-zeta w 30 s)
  do k = 1, n
    values(:, k) = [amplitude * sin(two_pi * forcing * times(k)) * merge(sin(pi * times(k) / 20)**2, 1.0_wp, &
                    times(k) < 10), 0.0_wp, 0.0_wp]
  end do
  steady = pseudo_spectral_acceleration(times, values, [0.8_wp], zeta)
  expected = (two_pi / 0.8_wp)**2 * amplitude / sqrt(((two_pi / 0.8_wp)**2 - (two_pi * forcing)**2)**2 + &
             (2 * zeta * (two_pi / 0.8_wp) * (two_pi * forcing))**2)
  call check_close(steady(1), expected, 2.0e-3_wp, 'Sa of the steady state under a sine, T = 0.8 s')
  call finish('intensity')

contains

  !> The peaks of |v| and |d| of the x component, exactly: v at the samples
  !> and where the linear acceleration changes sign inside a step.
  subroutine exact_peaks(pgv, pgd)
    real(wp), intent(out) :: pgv, pgd
    real(wp) :: v, d, h, a0, a1, s
    integer :: i
    v = 0
    d = 0
    pgv = 0
    pgd = 0
    do i = 1, n - 1
      h = times(i + 1) - times(i)
      a0 = values(1, i)
      a1 = values(1, i + 1)
      if (a0 * a1 < 0) then
        s = -a0 * h / (a1 - a0)
        pgv = max(pgv, abs(v + a0 * s + (a1 - a0) * s**2 / (2 * h)))
      end if
      d = d + v * h + (2 * a0 + a1) * h**2 / 6
      v = v + (a0 + a1) * h / 2
      pgv = max(pgv, abs(v))
      pgd = max(pgd, abs(d))
    end do
  end subroutine exact_peaks

  !> Sa by RK4 on the piecewise-linear record, 200 steps per sample, the
  !> peak of |u| at every step.
  real(wp) function rk4_sa(period) result(value)
    real(wp), intent(in) :: period
    integer, parameter :: per_sample = 200
    real(wp) :: omega, h, y(4), k1(4), k2(4), k3(4), k4(4), t, peak
    integer :: i, j
    omega = two_pi / period
    y = 0
    peak = 0
    do i = 1, n - 1
      h = (times(i + 1) - times(i)) / per_sample
      do j = 0, per_sample - 1
        t = j * h
        k1 = rate_at(i, omega, y, t)
        k2 = rate_at(i, omega, y + h / 2 * k1, t + h / 2)
        k3 = rate_at(i, omega, y + h / 2 * k2, t + h / 2)
        k4 = rate_at(i, omega, y + h * k3, t + h)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        peak = max(peak, hypot(y(1), y(3)))
      end do
    end do
    value = omega**2 * peak
  end function rk4_sa

  !> (u_x, v_x, u_y, v_y)' at offset s into sample step i, for rk4_sa
  pure function rate_at(i, omega, state, s) result(dy)
    integer, intent(in) :: i
    real(wp), intent(in) :: omega, state(4), s
    real(wp) :: dy(4), ground(2)
    ground = values(1:2, i) + (values(1:2, i + 1) - values(1:2, i)) * s / (times(i + 1) - times(i))
    dy = [state(2), -2 * zeta * omega * state(2) - omega**2 * state(1) - ground(1), &
          state(4), -2 * zeta * omega * state(4) - omega**2 * state(3) - ground(2)]
  end function rate_at

  function number(x) result(text)
    real(wp), intent(in) :: x
    character(len=16) :: text
    write (text, '(g0.5)') x
  end function number
end program test_intensity
