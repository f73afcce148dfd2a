!> Decimal numbers read from text to the nearest double, fast (src/core/decimal.c).
module ellroll_decimal
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_double
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: decimal_value, decimal_ok, decimal_invalid, decimal_too_long, longest_decimal

  integer, parameter :: decimal_ok = 0, decimal_invalid = 1, decimal_too_long = 2
  !> Most characters of a number.
  integer, parameter :: longest_decimal = 100

  interface
    integer(c_int) function c_decimal_value(text, length, value) bind(c, name='ellroll_decimal_value')
      import :: c_int, c_char, c_double
      character(kind=c_char), intent(in) :: text(*)
      integer(c_int), value :: length
      real(c_double), intent(out) :: value
    end function c_decimal_value
  end interface

contains

  !> The value of text, a decimal number ([+-] digits [. digits] or
  !> [+-] . digits, then optionally [eEdD] [+-] digits or [+-] digits, as
  !> Fortran writes exponents beyond 99; no blanks), to the
  !> nearest double: the value Fortran's read gives. Beyond the doubles it
  !> is +-Inf (or 0), and no floating-point exception is raised. Returns
  !> decimal_ok, decimal_invalid (value 0), or decimal_too_long (over
  !> longest_decimal characters).
  integer function decimal_value(text, value) result(code)
    character(len=*), intent(in) :: text
    real(wp), intent(out) :: value
    real(c_double) :: got
    code = c_decimal_value(text, int(len(text), c_int), got)
    value = 0
    if (code == decimal_ok) value = got
  end function decimal_value
end module ellroll_decimal
