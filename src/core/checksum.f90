!> A rotate-xor checksum of 64-bit words: cheap (two operations a word) and
!> enough to tell a record or a label torn, never written or left from
!> other data, from an intact one. Not a defence against a crafted file.
module ellroll_checksum
  use ellroll_kinds, only: wp, i8
  implicit none
  private

  public :: checksum, checksum_start, fold_reals

  integer(i8), parameter :: checksum_start = 1469598103934665603_i8

contains

  pure integer(i8) function checksum(words)
    integer(i8), intent(in) :: words(:)
    integer :: k
    checksum = checksum_start
    do k = 1, size(words)
      checksum = ieor(ishftc(checksum, 7), words(k))
    end do
  end function checksum

  !> Fold the bits of n reals into sum (from checksum_start): `values` may be
  !> an array of any shape, taken in array element order.
  pure subroutine fold_reals(sum, values, n)
    integer(i8), intent(inout) :: sum
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: values(n)
    integer(i8) :: k
    do k = 1, n
      sum = ieor(ishftc(sum, 7), transfer(values(k), 0_i8))
    end do
  end subroutine fold_reals
end module ellroll_checksum
