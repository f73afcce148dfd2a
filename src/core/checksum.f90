!> CRC-32C checksums of 64-bit words and reals (src/core/crc32c.c): they
!> catch every error of up to 3 bits in a journal record, a trajectory
!> label or a case's trajectories, and every burst up to 32 bits. The value
!> is the CRC zero-extended to 64 bits; a checksum over several arrays
!> starts at checksum_start and continues with fold_reals and fold_words.
module ellroll_checksum
  use, intrinsic :: iso_c_binding, only: c_int32_t, c_size_t, c_char
  use ellroll_kinds, only: wp, i8
  implicit none
  private

  public :: checksum, checksum_start, fold_reals, fold_words, text_checksum

  integer(i8), parameter :: checksum_start = 0

  interface
    !> (the same C function on text: a character scalar passes as its characters)
    pure integer(c_int32_t) function c_crc32c_text(crc, data, bytes) bind(c, name='ellroll_crc32c')
      import :: c_int32_t, c_size_t, c_char
      integer(c_int32_t), value :: crc
      character(kind=c_char), intent(in) :: data(*)
      integer(c_size_t), value :: bytes
    end function c_crc32c_text
    pure integer(c_int32_t) function c_crc32c(crc, data, bytes) bind(c, name='ellroll_crc32c')
      import :: c_int32_t, c_size_t
      integer(c_int32_t), value :: crc
      type(*), intent(in) :: data(*)
      integer(c_size_t), value :: bytes
    end function c_crc32c
  end interface

contains

  pure integer(i8) function checksum(words)
    integer(i8), intent(in) :: words(:)
    checksum = checksum_start
    call fold(checksum, words, size(words, kind=i8))
  end function checksum

  !> The CRC-32C of a text's bytes (a file's contents, its fingerprint).
  pure integer(i8) function text_checksum(text)
    character(len=*), intent(in) :: text
    integer(c_int32_t) :: crc
    crc = c_crc32c_text(0_c_int32_t, text, int(len(text), c_size_t))
    text_checksum = iand(int(crc, i8), 4294967295_i8)
  end function text_checksum

  !> Continue the checksum sum over n reals: `values` may be an array of any
  !> shape, taken in array element order.
  pure subroutine fold_reals(sum, values, n)
    integer(i8), intent(inout) :: sum
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: values(n)
    call fold(sum, values, n)
  end subroutine fold_reals

  !> Continue the checksum sum over 64-bit words.
  pure subroutine fold_words(sum, words)
    integer(i8), intent(inout) :: sum
    integer(i8), intent(in) :: words(:)
    call fold(sum, words, size(words, kind=i8))
  end subroutine fold_words

  pure subroutine fold(sum, data, n)
    integer(i8), intent(inout) :: sum
    type(*), intent(in) :: data(*)
    integer(i8), intent(in) :: n
    integer(c_int32_t) :: crc
    ! the low 32 bits of sum, as C's uint32_t passes them
    crc = c_crc32c(int(sum - merge(4294967296_i8, 0_i8, sum >= 2147483648_i8), c_int32_t), data, int(8 * n, c_size_t))
    sum = iand(int(crc, i8), 4294967295_i8)
  end subroutine fold
end module ellroll_checksum
