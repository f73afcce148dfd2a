!> The input reader in-process (no program run): the parameter table's
!> defaults reach the case, and every row's range is enforced with a message
!> that names the file, line, group, variable and range; a missing required
!> input is named with its group.
program test_input
  use ellroll_kinds, only: wp
  use ellroll_errors, only: error_t
  use ellroll_exact, only: equals
  use ellroll_input, only: run_input_t, read_input_text
  use ellroll_cases, only: get_param, range_text
  use ellroll_params, only: params, param_count, param_default, param_component, param_unset_allowed, p_mass
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_strings, only: format_real
  use testing, only: check, finish
  implicit none
  character(len=*), parameter :: nl = achar(10)
  character(len=*), parameter :: base = &
      '&geometry a = 1.0, b = 0.4, c = 0.2 /' // nl // &
      '&ball radius = 0.2, weight = 2620.0 /' // nl // &
      '&initial omega = -2.0, 2.0, 20.0 /' // nl // &
      '&integration dt = 1.0e-3, t_end = 1.0 /' // nl // &
      '&output file = ''out.h5'', interval = 0.01 /' // nl
  type(run_input_t) :: inp
  type(error_t) :: err
  integer :: p, n_defaults, n_enforced, n_named
  character(len=:), allocatable :: expected

  call read_input_text('base.nml', base, '', inp, err)
  call check(.not. err%failed(), 'the base input reads: ' // err%message)
  n_defaults = 0
  do p = 1, param_count
    if (params(p)%required .or. .not. params(p)%sweepable) cycle
    if (param_unset_allowed(p)) then          ! unset: NaN
      if (ieee_is_nan(get_param(inp%campaign%base, p))) n_defaults = n_defaults + 1
    else if (equals(get_param(inp%campaign%base, p), param_default(p))) then
      n_defaults = n_defaults + 1
    end if
  end do
  call check(n_defaults == count(.not. params%required), 'every input not given takes its table default')

  n_enforced = 0
  n_named = 0
  do p = 1, param_count
    call read_input_text('bad.nml', with_value(p, 2 * params(p)%high), '', inp, err)
    if (err%failed()) n_enforced = n_enforced + 1
    expected = range_text(p)
    if (index(err%message, 'bad.nml:') == 1 .and. index(err%message, '&' // trim(params(p)%group) // ': ' // &
        trim(params(p)%variable)) > 0 .and. index(err%message, expected) > 0) n_named = n_named + 1
    err = error_t()
  end do
  call check(n_enforced == param_count, 'every row: a value above its range is refused')
  call check(n_named == param_count, 'every row: the message names the file, group, variable and range')

  call read_input_text('missing.nml', base(index(base, nl) + 1:), '', inp, err)
  call check(index(err%message, '&geometry is missing') > 0, 'a missing group is named: ' // err%message)
  call finish('test_input')

contains

  !> The base input with row p's variable set to value: its assignment
  !> replaces the base's one (a vector's component joins the base's other
  !> two), or joins its group, which is added where the base has none.
  function with_value(p, value) result(text)
    integer, intent(in) :: p
    real(wp), intent(in) :: value
    character(len=:), allocatable :: text, group, variable, written
    character(len=48) :: items(3)
    real(wp) :: vector(3)
    integer :: component
    group = trim(params(p)%group)
    variable = trim(params(p)%variable)
    written = format_real(value)
    component = param_component(p)
    if (component > 0) then
      vector = merge([-2.0_wp, 2.0_wp, 20.0_wp], [0.0_wp, 0.0_wp, 0.0_wp], variable == 'omega')
      vector(component) = value
      write (items, '(es24.16)') vector
      written = trim(adjustl(items(1))) // ', ' // trim(adjustl(items(2))) // ', ' // trim(adjustl(items(3)))
    end if
    text = ''
    text = text // line('geometry', 'a = 1.0, b = 0.4, c = 0.2', group, variable, written)
    text = text // line('ball', 'radius = 0.2, ' // merge('mass = 267.0    ', 'weight = 2620.0 ', p == p_mass), &
                          group, variable, written)
    text = text // line('initial', 'omega = -2.0, 2.0, 20.0', group, variable, written)
    text = text // line('integration', 'dt = 1.0e-3, t_end = 1.0', group, variable, written)
    text = text // line('output', 'file = ''out.h5'', interval = 0.01', group, variable, written)
    if (index(text, '&' // group // ' ') == 0) then
      text = text // '&' // group // ' ' // variable // ' = ' // written
      if (group == 'excitation') text = text // merge(', kind = ''record'', record_file = ''absent.csv''', &
                                                      ', kind = ''harmonic''                          ', &
                                                      variable == 'scale')
      text = text // ' /' // nl
    end if
  end function with_value

  !> A group's line; in `group`, `variable` set to `written` (its base
  !> assignment replaced).
  function line(name, assignments, group, variable, written) result(l)
    character(len=*), intent(in) :: name, assignments, group, variable, written
    character(len=:), allocatable :: l, rest
    integer :: at, comma
    rest = trim(assignments)
    if (name == group) then
      at = index(', ' // rest, ', ' // variable // ' =')
      if (at > 0) then
        comma = index(rest(at:), ', ')
        if (variable == 'omega' .or. comma == 0) comma = len(rest) - at + 2
        rest = rest(:at - 1) // rest(at + comma + 1:)
      end if
      if (len_trim(rest) > 0) rest = rest // ', '
      rest = rest // variable // ' = ' // written
    end if
    l = '&' // name // ' ' // rest // ' /' // nl
  end function line
end program test_input
