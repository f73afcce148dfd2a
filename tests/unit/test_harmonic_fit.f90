!> The harmonic fit separates the steady response at the forcing frequency
!> from free oscillations at the modes' frequencies: on synthetic signals
!> (a sine at the forcing frequency, two free sines of comparable size, a
!> constant), sampled at a fixed step and at uneven steps, the ratio of the
!> response's amplitude to the forcing's is the one built in, to the
!> trapezoid rule's error (measured 1e-15: a sum of sines is fitted exactly);
!> a plain Fourier projection over the same window is off by 10 % here.
program test_harmonic_fit
  use ellroll_kinds, only: wp, two_pi
  use ellroll_harmonic_fit, only: harmonic_fit_t
  use testing
  implicit none
  real(wp), parameter :: forcing = two_pi * 0.3_wp, modes(2) = [two_pi / 5.2_wp, two_pi / 1.84_wp]
  real(wp), parameter :: expected = 0.37_wp, t_end = 60.0_wp
  type(harmonic_fit_t) :: fit
  real(wp) :: t, h, start, projection(2), base_projection(2), response(2), ground(2)
  integer :: k, n

  start = t_end - floor(0.5_wp * t_end * forcing / two_pi) * two_pi / forcing     ! whole forcing periods
  ! a fixed step
  call fit%begin(forcing, modes, start, t_end - start)
  h = 1.0e-3_wp
  n = nint(t_end / h)
  projection = 0
  base_projection = 0
  do k = 0, n
    t = k * h
    call fit%add(t, ball(t), base(t))
    if (t >= start) then
      response = ball(t)
      ground = base(t)
      projection = projection + h * response(1) * [cos(forcing * t), sin(forcing * t)]
      base_projection = base_projection + h * ground(1) * [cos(forcing * t), sin(forcing * t)]
    end if
  end do
  call check_close(fit%ratio(), expected, 1.0e-6_wp, 'the fit at a fixed step')
  call check(abs(norm2(projection) / norm2(base_projection) - expected) > 1.0e-2_wp * expected, &
             'a plain Fourier projection leaks the free oscillation (off by more than 1 %)')
  print '(a, es10.3)', 'Fourier projection''s relative error: ', &
      abs(norm2(projection) / norm2(base_projection) - expected) / expected

  ! uneven steps (an adaptive method's)
  fit = harmonic_fit_t()
  call fit%begin(forcing, modes, start, t_end - start)
  t = 0
  k = 0
  do while (t < t_end)
    call fit%add(t, ball(t), base(t))
    k = k + 1
    t = min(t_end, t + 2.0e-3_wp * (1 + 0.5_wp * sin(0.37_wp * k)))
  end do
  call fit%add(t, ball(t), base(t))
  call check_close(fit%ratio(), expected, 1.0e-5_wp, 'the fit at uneven steps')

  ! a mode at the forcing frequency cannot be told apart: it is left out
  fit = harmonic_fit_t()
  call fit%begin(forcing, [forcing * (1 + 1.0e-4_wp)], start, t_end - start)
  call check(fit%n_basis == 3, 'a mode within a window''s resolution of the forcing is left out')
  call finish('harmonic_fit')

contains

  !> the horizontal absolute acceleration of the ball: the steady part at
  !> the forcing frequency (both components), two free oscillations, a constant
  pure function ball(time) result(a)
    real(wp), intent(in) :: time
    real(wp) :: a(2)
    a(1) = expected * 1.5_wp * cos(forcing * time + 0.4_wp) + 4.0_wp * cos(modes(1) * time + 1.1_wp) &
           + 0.05_wp
    a(2) = expected * 0.5_wp * sin(forcing * time) + 0.3_wp * cos(modes(2) * time)
  end function ball

  pure function base(time) result(a)
    real(wp), intent(in) :: time
    real(wp) :: a(2)
    a = [1.5_wp * cos(forcing * time + 0.9_wp), 0.5_wp * sin(forcing * time + 0.5_wp)]
  end function base
end program test_harmonic_fit
