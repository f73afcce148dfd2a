!> Advice on the step of a fixed-step campaign, before it runs: the cases
!> whose dt is large against the fastest rate of their linearised motion at
!> the start (spin and curvature), with a step that would do.
module ellroll_step_advice
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa, format_real
  use ellroll_cases, only: case_t, case_problem, make_ball, adaptive_method, is_multiple
  use ellroll_rolling_ball, only: rolling_ball_t, initial_state
  use ellroll_linear, only: fastest_rate
  use ellroll_integrators, only: integrator_t, new_integrator, stability_limit
  use ellroll_input, only: run_input_t
  use ellroll_params, only: p_dt, p_omega_x, p_omega_z, p_x, p_y
  implicit none
  private

  public :: step_size_advice

contains

  !> Warnings (or ''), each line starting 'ellroll: warning:', for the
  !> fixed-step cases whose dt is large against the fastest rate of their
  !> linearised motion at the start (spin and curvature): beyond the method's
  !> stability (dt rate above its limit; such a case ends 'unstable'), listed
  !> case by case, the first few, each with a dt that would do; or coarse
  !> (dt rate > 0.1), counted, the fastest named.
  subroutine step_size_advice(inp, message)
    type(run_input_t), intent(in) :: inp
    character(len=:), allocatable, intent(out) :: message
    real(wp), parameter :: warn_above = 0.1_wp, aim = 0.05_wp
    integer, parameter :: listed = 5
    real(wp) :: worst_rate, limit
    real(wp), allocatable :: rates(:), steps(:)
    integer(i8) :: i, worst, n_coarse, n_unstable
    character(len=:), allocatable :: unstable_cases, cases_of
    class(integrator_t), allocatable :: integrator
    type(error_t) :: err
    message = ''
    if (adaptive_method(inp%campaign%base%method)) return
    call new_integrator(trim(inp%campaign%base%method), integrator, err)
    if (err%failed()) return
    limit = stability_limit(integrator)
    allocate (rates(0:inp%campaign%n_cases() - 1), steps(0:inp%campaign%n_cases() - 1))
    !$omp parallel do schedule(dynamic, 256)
    do i = 0, inp%campaign%n_cases() - 1
      call start_rate(i, rates(i), steps(i))
    end do
    !$omp end parallel do
    n_coarse = 0
    n_unstable = 0
    unstable_cases = ''
    worst_rate = 0
    worst = 0
    do i = 0, inp%campaign%n_cases() - 1
      if (steps(i) * rates(i) > limit) then
        n_unstable = n_unstable + 1
        if (n_unstable <= listed) unstable_cases = unstable_cases // achar(10) // '  case ' // itoa(i) // &
            ': dt = ' // format_real(steps(i)) // ' s, dt * rate = ' // format_real(hundredths(steps(i) * rates(i))) // &
            '; dt <= ' // format_real(nice_step(aim / rates(i), inp%plan%interval)) // ' s would do'
      else if (steps(i) * rates(i) > warn_above) then
        n_coarse = n_coarse + 1
        if (rates(i) > worst_rate) then
          worst_rate = rates(i)
          worst = i
        end if
      end if
    end do
    cases_of = ' of ' // itoa(inp%campaign%n_cases()) // ' cases: '
    if (n_unstable > 0) then
      message = 'ellroll: warning: ' // itoa(n_unstable) // cases_of // 'dt is beyond ' // &
          trim(inp%campaign%base%method) // '''s stability for their spin and curvature (dt * rate > ' // &
          format_real(hundredths(limit)) // ', rate the fastest of the motion at the start); they will end ''unstable'':' // &
          unstable_cases
      if (n_unstable > listed) message = message // achar(10) // '  ... and ' // itoa(n_unstable - listed) // &
          ' more'
    end if
    if (n_coarse == 0) return
    if (len(message) > 0) message = message // achar(10)
    message = message // 'ellroll: warning: ' // itoa(n_coarse) // cases_of // &
        'dt is large for their fastest time scale (case ' // itoa(worst) // ': dt = ' // &
        format_real(steps(worst)) // ' s, 1/rate = ' // format_real(1 / worst_rate) // ' s); suggested dt <= ' // &
        format_real(nice_step(aim / worst_rate, inp%plan%interval)) // ' s, or method = ''dop853'''
  contains
    !> Case `index`'s fastest rate at the start and its step; where a bound on
    !> the rate is within the limit, the bound (the rate is only compared with it).
    subroutine start_rate(index, rate, dt)
      integer(i8), intent(in) :: index
      real(wp), intent(out) :: rate, dt
      type(case_t) :: one
      type(rolling_ball_t) :: ball
      one = inp%campaign%case_at(index)
      ! an invalid case (set aside later, with its message) is never large:
      ! its start may not be a state at all
      rate = 0
      dt = 0
      if (case_problem(one, inp%plan%interval) /= 0) return
      ball = make_ball(one)
      dt = one%param(p_dt)
      rate = fastest_rate(ball, initial_state(ball, one%param(p_x), one%param(p_y), &
          one%param(p_omega_x:p_omega_z)), enough=warn_above / dt)
    end subroutine start_rate
  end subroutine step_size_advice

  !> The largest 1, 2 or 5 times a power of ten <= limit that divides interval
  !> (a power below 1 divided by, so that 5e-6 is the double nearest 5e-6).
  real(wp) function nice_step(limit, interval) result(step)
    real(wp), intent(in) :: limit, interval
    real(wp), parameter :: mantissas(3) = [1.0_wp, 2.0_wp, 5.0_wp]
    integer :: k, m, exponent10
    do k = 0, 30
      exponent10 = floor(log10(limit)) - k
      do m = 3, 1, -1
        if (exponent10 < 0) then
          step = mantissas(m) / 10.0_wp**(-exponent10)
        else
          step = mantissas(m) * 10.0_wp**exponent10
        end if
        if (step > limit) cycle
        if (is_multiple(interval, step)) return
      end do
    end do
    step = limit
  end function nice_step

  !> x rounded to two decimals, for a message
  pure real(wp) function hundredths(x)
    real(wp), intent(in) :: x
    hundredths = anint(100 * x) / 100
  end function hundredths
end module ellroll_step_advice
