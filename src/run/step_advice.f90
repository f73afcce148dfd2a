!> Advice on the step of a fixed-step campaign, before it runs: the cases
!> whose dt is large against the fastest rate of their linearised motion at
!> the start (spin and curvature), with a step that would do; those whose
!> dt does not resolve the excitation (a harmonic's period, a record's
!> samples); and, for an adaptive method, whether dt (its largest step)
!> caps its steps.
module ellroll_step_advice
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa, format_real, format_computed
  use ellroll_cases, only: case_t, output_plan_t, case_problem, make_ball, adaptive_method, is_multiple
  use ellroll_results, only: case_result_t
  use ellroll_status, only: status_completed
  use ellroll_threads, only: team_size
  use ellroll_simulate, only: simulate_case
  use ellroll_rolling_ball, only: rolling_ball_t, initial_state
  use ellroll_linear, only: fastest_rate
  use ellroll_integrators, only: integrator_t, new_integrator, stability_limit
  use ellroll_input, only: run_input_t
  use ellroll_params, only: p_dt, p_omega_x, p_omega_z, p_x, p_y, p_rtol, p_settle, p_excitation_frequency
  use ellroll_excitation, only: excitation_harmonic, excitation_record
  use ellroll_record_store, only: record_samples
  implicit none
  private

  public :: step_size_advice, dt_cap_advice, dt_cap_after_run, record_start_advice

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
    real(wp), allocatable :: rates(:), steps(:), forcing(:)
    integer(i8) :: i, worst, n_coarse, n_unstable
    character(len=:), allocatable :: unstable_cases, cases_of
    class(integrator_t), allocatable :: integrator
    type(error_t) :: err
    message = ''
    if (adaptive_method(inp%campaign%base%method)) return
    call new_integrator(trim(inp%campaign%base%method), integrator, err)
    if (err%failed()) return
    limit = stability_limit(integrator)
    allocate (rates(0:inp%campaign%n_cases() - 1), steps(0:inp%campaign%n_cases() - 1), &
              forcing(0:inp%campaign%n_cases() - 1))
    !$omp parallel do schedule(dynamic, 256) num_threads(team_size(0, (inp%campaign%n_cases() + 255) / 256))
    do i = 0, inp%campaign%n_cases() - 1
      call start_rate(i, rates(i), steps(i), forcing(i))
    end do
    !$omp end parallel do
    call forcing_advice(inp, steps, forcing, message)
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
      if (len(message) > 0) message = message // achar(10)
      message = message // 'ellroll: warning: ' // itoa(n_unstable) // cases_of // 'dt is beyond ' // &
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
        format_real(steps(worst)) // ' s, 1/rate = ' // format_computed(1 / worst_rate) // ' s); suggested dt <= ' // &
        format_real(nice_step(aim / worst_rate, inp%plan%interval)) // ' s, or method = ''dop853'''
  contains
    !> Case `index`'s fastest rate at the start and its step; where a bound on
    !> the rate is within the limit, the bound (the rate is only compared with it);
    !> forcing: how coarse dt is for its excitation (forcing_advice).
    subroutine start_rate(index, rate, dt, forcing)
      integer(i8), intent(in) :: index
      real(wp), intent(out) :: rate, dt, forcing
      type(case_t) :: one
      type(rolling_ball_t) :: ball
      integer :: n
      one = inp%campaign%case_at(index)
      ! an invalid case (set aside later, with its message) is never large:
      ! its start may not be a state at all
      rate = 0
      dt = 0
      forcing = 0
      if (case_problem(one, inp%plan%interval) /= 0) return
      ball = make_ball(one)
      dt = one%param(p_dt)
      select case (one%excitation%kind)
      case (excitation_harmonic)
        forcing = dt * one%param(p_excitation_frequency)
      case (excitation_record)
        associate (times => record_samples(one%excitation%record)%times)
          n = size(times)
          ! (as a negative: a record's is dt over its shortest sample spacing)
          if (n > 1) forcing = -dt / minval(times(2:) - times(:n - 1))
        end associate
      end select
      rate = fastest_rate(ball, initial_state(ball, one%param(p_x), one%param(p_y), &
          one%param(p_omega_x:p_omega_z)), enough=warn_above / dt)
    end subroutine start_rate
  end subroutine step_size_advice

  !> Warnings (or '') for the fixed-step cases whose dt does not resolve
  !> their excitation: forcing(i) is case i's dt * frequency (harmonic), or
  !> minus dt over its record's shortest sample spacing. A fixed step
  !> samples the cup's acceleration at its stages only: a harmonic over
  !> more than 1/20 of its period per step loses its peaks (a sine sampled
  !> at 40 points per period, the stages' halves, is within 0.3 % of its
  !> peak; rk4's Simpson quadrature of it within 4e-6), and from dt * f =
  !> 1/2 on (Nyquist) the stages see an alias of it, or nothing at all
  !> (dt * f a whole number: every stage at the same phase); a step over
  !> several record samples skips the ones between its stages.
  subroutine forcing_advice(inp, steps, forcing, message)
    type(run_input_t), intent(in) :: inp
    real(wp), intent(in) :: steps(0:), forcing(0:)
    character(len=:), allocatable, intent(out) :: message
    real(wp), parameter :: per_period = 20
    integer(i8) :: n_harmonic, n_record, worst, worst_record
    character(len=:), allocatable :: cases_of, lead
    message = ''
    n_harmonic = count(forcing * per_period > 1)
    n_record = count(-forcing > 1 + 1.0e-9_wp)     ! (a spacing of k dt - (k - 1) dt is dt to round-off)
    cases_of = ' of ' // itoa(size(forcing, kind=i8)) // ' cases: '
    lead = 'ellroll: warning: ' // trim(inp%path) // ': '
    if (n_harmonic > 0) then
      worst = maxloc(forcing, dim=1, kind=i8) - 1
      message = lead // itoa(n_harmonic) // cases_of // '&integration dt does not resolve the harmonic ' // &
          'excitation (more than 1/' // itoa(nint(per_period)) // ' of its period per step; case ' // itoa(worst) // &
          ': &integration dt = ' // format_real(steps(worst)) // ' s, &excitation frequency = ' // &
          format_real(forcing(worst) / steps(worst)) // ' Hz'
      if (forcing(worst) >= 0.5_wp) message = message // ', dt * frequency = ' // &
          format_computed(forcing(worst)) // ' >= 1/2: its stages see an alias of the sine, or none'
      message = message // '); dt <= ' // &
          format_real(nice_step(steps(worst) / (per_period * forcing(worst)), inp%plan%interval)) // &
          ' s would do, or method = ''dop853'''
    end if
    if (n_record == 0) return
    worst_record = minloc(forcing, dim=1, kind=i8) - 1
    if (len(message) > 0) message = message // achar(10)
    message = message // lead // itoa(n_record) // cases_of // '&integration dt is longer than the ' // &
        'spacing of their record''s samples, and a fixed step skips the samples between its stages (case ' // &
        itoa(worst_record) // ': &integration dt = ' // format_real(steps(worst_record)) // ' s, shortest spacing ' // &
        format_computed(-steps(worst_record) / forcing(worst_record)) // ' s); dt <= ' // &
        format_real(nice_step(-steps(worst_record) / forcing(worst_record), inp%plan%interval)) // &
        ' s would do, or method = ''dop853'''
  end subroutine forcing_advice

  !> A warning (or '') for each record of the input whose samples all lie
  !> before t = 0, its fall to rest too: samples before 0 are never felt
  !> (docs/inputs.md), so it shakes no case; most likely its times are
  !> offset.
  subroutine record_start_advice(inp, message)
    type(run_input_t), intent(in) :: inp
    character(len=:), allocatable, intent(out) :: message
    integer :: k, n
    message = ''
    n = 0
    if (allocated(inp%campaign%records)) n = size(inp%campaign%records)
    if (n > 0) then
      do k = 1, n
        call look_at(inp%campaign%records(k)%motion%record, "record '" // trim(inp%campaign%records(k)%name) // "'")
      end do
    else if (inp%campaign%base%excitation%kind == excitation_record) then
      call look_at(inp%campaign%base%excitation%record, 'its record')
    end if
  contains
    subroutine look_at(place, what)
      integer, intent(in) :: place
      character(len=*), intent(in) :: what
      integer :: n
      if (place <= 0) return
      if (.not. allocated(record_samples(place)%times)) return
      n = size(record_samples(place)%times)
      if (n == 0) return
      if (record_samples(place)%times(n) > 0) return
      if (len(message) > 0) message = message // achar(10)
      message = message // 'ellroll: warning: ' // trim(inp%path) // ': ' // what // ' ends before t = 0 (at ' // &
          format_real(record_samples(place)%times(n)) // ' s, at rest after its last sample): samples before 0 ' // &
          'are never felt, so it shakes no case; are its times offset?'
    end subroutine look_at
  end subroutine record_start_advice

  !> A warning (or '') when the method is adaptive and dt, its largest step,
  !> caps its steps: where dt implies at least probe_from steps, the base
  !> case runs a span of probe_spans steps of dt with dt lifted; when it
  !> needs at most half as many steps there, the tolerance would choose
  !> steps above dt, and dt, not rtol, sets the run's cost and accuracy.
  subroutine dt_cap_advice(inp, message)
    type(run_input_t), intent(in) :: inp
    character(len=:), allocatable, intent(out) :: message
    real(wp), parameter :: probe_from = 2000, probe_spans = 100
    type(case_t) :: probe
    type(output_plan_t) :: plan
    type(case_result_t) :: res
    type(error_t) :: err
    real(wp) :: dt, steps
    message = ''
    probe = inp%campaign%base
    if (.not. adaptive_method(probe%method)) return
    if (inp%campaign%n_cases() > 0) probe = inp%campaign%case_at(0_i8)
    if (case_problem(probe, inp%plan%interval) /= 0) return
    dt = probe%param(p_dt)
    if (.not. (probe%t_end >= probe_from * dt)) return
    probe%t_end = probe_spans * dt
    probe%param(p_dt) = probe%t_end
    probe%param(p_settle) = 0                ! the probe's span only
    plan%interval = probe%t_end
    plan%n_samples = 2
    plan%fields = .false.
    call simulate_case(probe, plan, res, err)
    if (err%failed() .or. res%status /= status_completed) return
    if (real(res%n_steps, wp) > probe_spans / 2) return
    steps = probe%t_end / real(max(res%n_steps, 1_i8), wp)
    call cap_message(inp%campaign%base, dt, nint(inp%campaign%base%t_end / dt, i8), ' (at rtol = ' // &
        format_real(probe%param(p_rtol)) // ' its steps would be about ' // format_real(significant(steps)) // &
        ' s at the start)', message)
  end subroutine dt_cap_advice

  !> After a run: a warning (or '') when most completed cases of an adaptive
  !> method took (almost) t_end / dt steps: their steps were dt, the cap.
  subroutine dt_cap_after_run(inp, case_index, status, n_steps, message)
    type(run_input_t), intent(in) :: inp
    integer(i8), intent(in) :: case_index(:), status(:), n_steps(:)
    character(len=:), allocatable, intent(out) :: message
    type(case_t) :: one
    integer(i8) :: k, completed, capped
    real(wp) :: most_steps
    message = ''
    if (.not. adaptive_method(inp%campaign%base%method)) return
    completed = 0
    capped = 0
    do k = 1, size(status)
      if (status(k) /= status_completed) cycle
      completed = completed + 1
      one = inp%campaign%case_at(case_index(k))
      most_steps = one%t_end / one%param(p_dt)
      if (most_steps >= 100 .and. real(n_steps(k), wp) >= 0.9_wp * most_steps) capped = capped + 1
    end do
    if (completed == 0 .or. 2 * capped <= completed) return
    one = inp%campaign%base
    call cap_message(one, one%param(p_dt), -1_i8, ' (' // itoa(capped) // ' of ' // itoa(completed) // &
        ' completed cases took t_end / dt steps: their steps were dt)', message)
  end subroutine dt_cap_after_run

  subroutine cap_message(cs, dt, steps, why, message)
    type(case_t), intent(in) :: cs
    real(wp), intent(in) :: dt
    integer(i8), intent(in) :: steps           !< the least steps dt implies, or < 0 to leave them out
    character(len=*), intent(in) :: why
    character(len=:), allocatable, intent(out) :: message
    message = 'ellroll: warning: dt = ' // format_real(dt) // ' caps ' // trim(cs%method) // '''s steps'
    if (steps >= 0) message = message // ': it will take >= ' // itoa(steps) // ' steps whatever rtol'
    message = message // why // '; raise dt (the largest step) to let rtol decide'
  end subroutine cap_message

  !> x to three significant digits, for a message.
  real(wp) function significant(x)
    real(wp), intent(in) :: x
    real(wp) :: scale
    scale = 10.0_wp**(2 - floor(log10(x)))
    significant = anint(x * scale) / scale
  end function significant

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
