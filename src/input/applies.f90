!> Which inputs apply to a case: the inputs of &excitation that belong to
!> one kind, and the inputs a &sweep or &sample varies that change no case
!> (or make every case invalid) with the rest of the input as it is. A
!> single value of an input of another excitation kind is refused with the
!> same words as a varied one.
module ellroll_applies
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_strings, only: join, format_real
  use ellroll_cases, only: case_t, adaptive_method
  use ellroll_excitation, only: excitation_harmonic, excitation_kind_names
  use ellroll_integrators, only: methods
  use ellroll_params, only: params, p_velocity_x, p_velocity_z, p_rtol, p_atol, p_settle, p_rolling_resistance
  implicit none
  private

  public :: excitation_inputs, kind_of_input, varied_input_reason

  !> The variables of &excitation that belong to one kind (kind_of_input).
  character(len=*), parameter :: excitation_inputs(6) = [character(len=11) :: 'amplitude', 'frequency', 'phase', &
                                                          'record_file', 'scale', 'sa_periods']

contains

  !> The excitation kind that &excitation `variable` belongs to:
  !> 'harmonic', 'record', or blank for one of every kind.
  pure function kind_of_input(variable) result(kind)
    character(len=*), intent(in) :: variable
    character(len=8) :: kind
    select case (variable)
    case ('amplitude', 'frequency', 'phase'); kind = 'harmonic'
    case ('record_file', 'scale', 'sa_periods'); kind = 'record'
    case default; kind = ''
    end select
  end function kind_of_input

  !> Why varying row p of the parameter table in a campaign on `base`
  !> changes no case, or makes every case invalid; '' where it applies.
  !> varied(q): row q is varied too (a varied rolling resistance makes
  !> settle apply; three varied components make a velocity).
  subroutine varied_input_reason(p, base, varied, reason)
    integer, intent(in) :: p
    type(case_t), intent(in) :: base
    logical, intent(in) :: varied(:)
    character(len=:), allocatable, intent(out) :: reason
    character(len=:), allocatable :: kind, base_kind
    reason = ''
    base_kind = trim(excitation_kind_names(base%excitation%kind))
    if (params(p)%group == 'excitation') then
      kind = trim(kind_of_input(trim(params(p)%variable)))
      if (len(kind) > 0 .and. kind /= base_kind) reason = "applies to kind = '" // kind // "' only; " // &
          "&excitation kind is '" // base_kind // "'"
    else if (p >= p_velocity_x .and. p <= p_velocity_z) then
      if (.not. base%slide) then
        reason = "an initial velocity starts the ball sliding: it needs &ball slip = 'slide'"
      else if (ieee_is_nan(base%param(p_velocity_x)) .and. .not. all(varied(p_velocity_x:p_velocity_z))) then
        reason = 'the initial velocity needs all three components: give &initial velocity = vx, vy, vz (m/s) ' // &
                 'or vary all three'
      end if
    else if (p == p_rtol .or. p == p_atol) then
      if (.not. adaptive_method(base%method)) reason = 'applies to the adaptive methods only (' // &
          join(pack(methods%name, methods%adaptive)) // "); &integration method is '" // trim(base%method) // "'"
    else if (p == p_settle) then
      ! (the ball comes to rest for good only where the cup does, and a couple holds it)
      if (base%excitation%kind == excitation_harmonic) then
        reason = "applies where the cup comes to rest only (&excitation kind = 'none' or 'record'); " // &
                 "&excitation kind is 'harmonic'"
      else if (.not. varied(p_rolling_resistance) .and. .not. base%param(p_rolling_resistance) > 0) then
        reason = 'applies with rolling resistance only (&ball rolling_resistance > 0); rolling_resistance is ' // &
                 format_real(base%param(p_rolling_resistance))
      end if
    end if
  end subroutine varied_input_reason
end module ellroll_applies
