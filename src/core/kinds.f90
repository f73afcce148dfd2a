!> Working precision and physical/mathematical constants shared by every room.
module ellroll_kinds
  use, intrinsic :: iso_fortran_env, only: real64, int32, int64
  implicit none
  private

  public :: wp, i4, i8, pi, two_pi

  integer, parameter :: wp = real64
  integer, parameter :: i4 = int32
  integer, parameter :: i8 = int64

  real(wp), parameter :: pi = 3.14159265358979323846264338327950288_wp
  real(wp), parameter :: two_pi = 2.0_wp * pi
end module ellroll_kinds
