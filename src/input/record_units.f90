!> Units of ground acceleration as record files name them, and the bounds
!> on a record's samples: every sample within max_record_acceleration, as
!> read and times its record's factor.
module ellroll_record_units
  use ellroll_kinds, only: wp
  use ellroll_strings, only: format_real, lower
  use ellroll_record_text, only: quoted
  implicit none
  private

  public :: unit_t, unit_of, within_bound, beyond_bound
  public :: standard_gravity, max_record_acceleration, max_record_points, known_units

  !> m/s^2 per g (CGPM 1901).
  real(wp), parameter :: standard_gravity = 9.80665_wp
  !> Largest |ground acceleration| of a sample, m/s^2, in SI units and
  !> times its record's factor (about 1000 g, far beyond any recorded
  !> motion). With scale <= 1e3 the cup's acceleration stays below 1e7
  !> m/s^2, so that forces on masses up to 1e12 kg, and their squares, are
  !> finite.
  real(wp), parameter :: max_record_acceleration = 1.0e4_wp
  !> Most samples of one file (a day at 1 kHz).
  integer, parameter :: max_record_points = 100000000
  !> Numbers beyond this are beyond max_record_acceleration in any unit;
  !> below it, the conversion to SI cannot overflow.
  real(wp), parameter :: far_beyond = 1.0e300_wp

  character(len=*), parameter :: known_units = 'g; cm/s^2 as CM/SEC/SEC, CM/S/S, CM/S^2 or GAL; ' // &
                                               'm/s^2 as M/SEC/SEC, M/S/S or M/S^2'

  !> A unit of acceleration: a value in it is value * multiplier / divisor
  !> m/s^2 (one rounding for g and cm/s^2 alike, none for m/s^2).
  type :: unit_t
    character(len=6) :: name = 'm/s^2'
    real(wp) :: multiplier = 1, divisor = 1
  end type unit_t

contains

  !> A unit as PEER files and CSV units lines spell it (any case): g;
  !> cm/s^2 as CM/SEC/SEC, CM/S/S, CM/S^2, CM/SEC2, CM/S**2 or GAL; m/s^2
  !> alike. quantity is 'acceleration', 'velocity' (CM/S, M/S, IN/S),
  !> 'displacement' (CM, M, MM, IN) or '' when the word is not known.
  pure subroutine unit_of(word, unit, quantity)
    character(len=*), intent(in) :: word
    type(unit_t), intent(out) :: unit
    character(len=16), intent(out) :: quantity
    character(len=len(word)) :: text
    integer :: at
    text = lower(word)
    do at = len_trim(text), 1, -1              ! 'G.', 'G,', '(G)'
      if (scan(text(at:at), '.,;:)') == 0) exit
      text(at:at) = ' '
    end do
    if (len(text) > 0) then
      if (text(1:1) == '(') text = text(2:)
    end if
    do                                        ! sec -> s
      at = index(text, 'sec')
      if (at == 0) exit
      text = text(:at) // text(at + 3:)
    end do
    at = index(text, '**2')
    if (at > 0) text = text(:at - 1) // '2' // text(at + 3:)
    at = index(text, '^2')
    if (at > 0) text = text(:at - 1) // '2' // text(at + 2:)
    at = len_trim(text)
    if (at >= 2) then
      if (text(at - 1:at) == 's2') text = text(:at - 1) // '/s'
    end if
    quantity = 'acceleration'
    select case (trim(text))
    case ('g')
      unit = unit_t('g', standard_gravity, 1.0_wp)
    case ('cm/s/s', 'gal')
      unit = unit_t('cm/s^2', 1.0_wp, 100.0_wp)
    case ('m/s/s')
      unit = unit_t('m/s^2', 1.0_wp, 1.0_wp)
    case ('cm/s', 'm/s', 'mm/s', 'in/s', 'ft/s')
      quantity = 'velocity'
    case ('cm', 'm', 'mm', 'in', 'ft')
      quantity = 'displacement'
    case default
      quantity = ''
    end select
  end subroutine unit_of

  !> A sample of ground acceleration, value in `unit`, in m/s^2 (si): true
  !> when it and `factor` times it are within max_record_acceleration.
  logical function within_bound(value, unit, factor, si) result(ok)
    real(wp), intent(in) :: value, factor
    type(unit_t), intent(in) :: unit
    real(wp), intent(out) :: si
    ok = .false.
    si = 0
    if (.not. abs(value) <= far_beyond) return
    si = value * unit%multiplier / unit%divisor
    ok = abs(si) <= max_record_acceleration .and. abs(factor * si) <= max_record_acceleration
  end function within_bound

  !> Why a sample (`word`, its value in `unit`) is beyond the bound.
  subroutine beyond_bound(word, value, unit, factor, reason)
    character(len=*), intent(in) :: word
    real(wp), intent(in) :: value, factor
    type(unit_t), intent(in) :: unit
    character(len=:), allocatable, intent(out) :: reason
    real(wp) :: si
    reason = quoted(word) // ' ' // trim(unit%name) // ' is beyond the bound on ground acceleration, |a| <= ' // &
             format_real(max_record_acceleration) // ' m/s^2 (about 1000 g)'
    if (.not. abs(value) <= far_beyond) return
    si = value * unit%multiplier / unit%divisor
    if (abs(si) <= max_record_acceleration) reason = reason // ' times the factor ' // format_real(factor)
  end subroutine beyond_bound
end module ellroll_record_units
