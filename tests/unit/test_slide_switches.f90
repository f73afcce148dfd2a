!> The switches of regime of a case that slides (&ball slip = 'slide'),
!> against a reference: the paper's cup shaken harmonically at 1.3 times
!> the linear slip threshold (docs/model.md, "The slip threshold of
!> harmonic shaking"), mu = 0.05, started on the linear steady orbit, slides
!> twice a cycle: 15 switches in 3 s. Against vern9 at rtol = 1e-12 (itself
!> within 1e-11 s of vern9 at 1e-14): rk4 at dt = 1e-4 s gives every one
!> within 5.4e-10 s (the 10th, a stop where rolling needs nearly mu N, the
!> slip's approach slow: a time error of |du| / (mu N (1/m + R^2/J) -
!> |the other forces' du/dt|)); dop853 at rtol 1e-12 every one within
!> 2.2e-13 s. The same number of switches, of the same kinds.
program test_slide_switches
  use ellroll_kinds, only: wp
  use ellroll_cases, only: case_t
  use ellroll_results, only: case_result_t, switch_to_sliding, switch_to_rolling
  use ellroll_status, only: status_completed
  use ellroll_excitation, only: excitation_harmonic
  use fixtures, only: paper_case, run_case
  use testing
  use ellroll_params, only: p_mass, p_mu, p_omega_x, p_omega_z, p_dt, p_rtol, p_excitation_frequency, &
      p_excitation_phase, p_excitation_amplitude_x, p_excitation_amplitude_z
  implicit none
  real(wp), parameter :: pi = acos(-1.0_wp)
  type(case_result_t) :: reference, res
  character(len=40) :: label

  reference = shaken('vern9', 1.0e-12_wp)
  call check(reference%status == status_completed .and. reference%n_switches == 15, &
             'the shaken cup: 15 switches in 3 s')
  call check(all(reference%switch_kind(1:15:2) == switch_to_sliding) .and. &
             all(reference%switch_kind(2:14:2) == switch_to_rolling), 'the switches alternate, sliding first')
  res = shaken('rk4', 1.0e-4_wp)
  call same_switches(res, 5.0e-9_wp, 5.0e-9_wp, 'rk4 dt 1e-4')
  res = shaken('dop853', 1.0e-12_wp)
  call same_switches(res, 1.0e-11_wp, 1.0e-11_wp, 'dop853 rtol 1e-12')
  call finish('test_slide_switches')

contains

  !> The shaken case with `method` at step dt (rk4) or rtol (the pairs).
  function shaken(method, accuracy) result(res)
    character(len=*), intent(in) :: method
    real(wp), intent(in) :: accuracy
    type(case_result_t) :: res
    real(wp), parameter :: mu = 0.05_wp, frequency = 1.25_wp, k = 0.4_wp, g = 9.81_wp, r = 0.2_wp
    real(wp) :: w, direction(2), factors(2), threshold, amplitude, velocity(2)
    type(case_t) :: cs
    w = 2 * pi * frequency
    direction = [2.0_wp, 1.0_wp] / sqrt(5.0_wp)
    factors = direction / ((1 + k) * w**2 - g / [1.0_wp / 0.2_wp - r, 0.16_wp / 0.2_wp - r])
    threshold = mu * g / (k * w**2 * norm2(factors))
    amplitude = 1.3_wp * threshold
    velocity = amplitude * factors * w
    cs = paper_case(1.0e-3_wp, 3.0_wp)
    cs%param(p_mass) = 1
    cs%param(p_mu) = mu
    cs%slide = .true.
    cs%param(p_omega_x:p_omega_z) = [-velocity(2) / r, velocity(1) / r, 0.0_wp]
    cs%excitation%kind = excitation_harmonic
    cs%param(p_excitation_frequency) = frequency
    cs%param(p_excitation_phase) = 0
    cs%param(p_excitation_amplitude_x:p_excitation_amplitude_z) = [amplitude * direction, 0.0_wp]
    cs%method = method
    if (method == 'rk4') then
      cs%param(p_dt) = accuracy
    else
      cs%param(p_rtol) = accuracy
    end if
    res = run_case(cs, 10)
  end function shaken

  !> res has the reference's switches, each of its kind, every one within
  !> tolerance (s) and all but one within most (s).
  subroutine same_switches(res, tolerance, most, what)
    type(case_result_t), intent(in) :: res
    real(wp), intent(in) :: tolerance, most
    character(len=*), intent(in) :: what
    integer :: n
    n = reference%n_switches
    label = what
    call check(res%status == status_completed .and. res%n_switches == n, trim(label) // ': as many switches')
    if (res%n_switches /= n) return
    call check(all(res%switch_kind(:n) == reference%switch_kind(:n)), trim(label) // ': the same kinds')
    call check_below(maxval(abs(res%switch_time(:n) - reference%switch_time(:n))), tolerance, &
                     trim(label) // ': every switch time (s)')
    call check(count(abs(res%switch_time(:n) - reference%switch_time(:n)) > most) <= 1, &
               trim(label) // ': all switch times but one within 1e-9 s')
  end subroutine same_switches
end program test_slide_switches
