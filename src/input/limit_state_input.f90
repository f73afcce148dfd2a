!> User limit states: one &limit_state group each (its name, the /summary
!> figure it bounds, its capacity in that figure's unit), checked.
module ellroll_limit_state_input
  use ellroll_strings, only: itoa, join, lower
  use ellroll_suggest, only: did_you_mean
  use ellroll_figures, only: figures
  use ellroll_limit_states, only: limit_state_t, limit_state_figures
  use ellroll_input_reader, only: reader_t, namelist_values_t
  use ellroll_status, only: status_count, status_name
  implicit none
  private

  public :: add_limit_state

contains

  !> A &limit_state group's name (an identifier, not taken), figure (a real
  !> single-valued /summary figure) and capacity (finite, >= 0), after `states`.
  subroutine add_limit_state(rd, v, gi, states, lines)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    integer, intent(in) :: gi
    type(limit_state_t), allocatable, intent(inout) :: states(:)
    integer, allocatable, intent(inout) :: lines(:)      !< where each of states is
    type(limit_state_t) :: state
    character(len=:), allocatable :: name, figure, hint
    character(len=len(figures%name)), allocatable :: known(:)
    integer :: k
    name = trim(adjustl(v%name))
    if (len(name) == 0) then
      call rd%fail_missing(gi, 'name', "name the limit state, e.g. name = 'drift' (its dataset in /limit_state)")
      return
    end if
    if (.not. is_identifier(name)) then
      call rd%fail_value(gi, 'name', 'must be an identifier: a letter, then letters, digits or _')
      return
    end if
    if (reserved(name)) then
      call rd%fail_value(gi, 'name', "is a name the suite statistics take for their own columns (model_limit, " // &
                         "cases, completed, limit, unresolved, a status, undefined_...): choose another")
      return
    end if
    do k = 1, size(states)
      if (states(k)%name == name) then
        call rd%fail_value(gi, 'name', 'already names the &limit_state at line ' // itoa(lines(k)))
        return
      end if
    end do
    figure = lower(trim(adjustl(v%figure)))
    known = limit_state_figures()
    if (len(figure) == 0) then
      call rd%fail_missing(gi, 'figure', "name the /summary figure it bounds, e.g. figure = 'displacement_max'")
      return
    end if
    if (.not. any(known == figure)) then
      call did_you_mean(figure, known, '', hint)
      call rd%fail_value(gi, 'figure', "unknown figure '" // figure // "'" // hint // ' (known: ' // join(known) // ')')
      return
    end if
    if (.not. rd%require(gi, 'capacity', v%limit_capacity)) return     ! (given and finite)
    ! every figure it can bound is >= 0: below 0 every defined one exceeds it
    ! (0 has a meaning: any value above 0, as a sliding_time, exceeds it)
    if (v%limit_capacity < 0) then
      call rd%fail_value(gi, 'capacity', "must be >= 0 (the figures a limit state bounds are >= 0; 0: any " // &
                         "value above 0 exceeds it)")
      return
    end if
    state%name = name
    do k = 1, size(figures)
      if (figures(k)%name == figure) state%figure = k
    end do
    state%capacity = v%limit_capacity
    states = [states, state]
    lines = [lines, rd%file%groups(gi)%line]
  end subroutine add_limit_state

  !> Whether a limit state of this name would take a column or a fragility
  !> of the suite statistics' own (n_NAME, fraction_NAME beside n_cases,
  !> n_liftoff, fraction_limit, n_undefined_STATE; the model_limit fragility).
  pure logical function reserved(name)
    character(len=*), intent(in) :: name
    character(len=*), parameter :: own(*) = [character(len=11) :: 'model_limit', 'cases', 'completed', 'limit', &
                                             'unresolved']
    integer :: k
    reserved = any(own == lower(name)) .or. index(lower(name), 'undefined_') == 1
    do k = 0, status_count - 1
      if (lower(name) == status_name(k)) reserved = .true.
    end do
  end function reserved

  pure logical function is_identifier(text)
    character(len=*), intent(in) :: text
    integer :: k
    is_identifier = verify(text(1:1), 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ') == 0
    do k = 2, len(text)
      if (verify(text(k:k), 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_') /= 0) &
        is_identifier = .false.
    end do
  end function is_identifier
end module ellroll_limit_state_input
