!> The CRC-32C behind the journal's checksums: the standard check value,
!> the processor's instruction equal to the tables, and every error of up
!> to 3 bits caught in a journal record of 64 words (the summary-only
!> record): exhaustively, through the CRC's linearity (an error pattern e
!> goes undetected only when its syndrome crc(e) xor crc(0) is zero, and the
!> syndrome of a pattern is the xor of those of its bits).
program test_checksum
  use, intrinsic :: iso_c_binding, only: c_int32_t, c_size_t, c_char
  use ellroll_kinds, only: wp, i8
  use ellroll_checksum, only: checksum
  use ellroll_strings, only: itoa
  use testing
  implicit none

  interface
    integer(c_int32_t) function c_crc32c(crc, data, bytes) bind(c, name='ellroll_crc32c')
      import :: c_int32_t, c_size_t
      integer(c_int32_t), value :: crc
      type(*), intent(in) :: data(*)
      integer(c_size_t), value :: bytes
    end function c_crc32c
    integer(c_int32_t) function c_crc32c_tables(crc, data, bytes) bind(c, name='ellroll_crc32c_tables')
      import :: c_int32_t, c_size_t
      integer(c_int32_t), value :: crc
      type(*), intent(in) :: data(*)
      integer(c_size_t), value :: bytes
    end function c_crc32c_tables
  end interface

  integer, parameter :: record_words = 64, bits = 64 * record_words
  character(kind=c_char, len=9), parameter :: check_text = '123456789'
  character(kind=c_char, len=256) :: bytes
  integer(i8) :: words(record_words), damaged(record_words), syndrome(bits), sorted(bits), zero_crc
  integer :: i, j, n, word, undetected_2, undetected_3, missed_direct
  logical :: same
  real(wp) :: u

  ! the check value of CRC-32C (RFC 3720, appendix B.4)
  call check(c_crc32c(0_c_int32_t, [check_text], 9_c_size_t) == int(z'E3069283', c_int32_t), &
             'CRC-32C of "123456789" is E3069283')
  call check(c_crc32c_tables(0_c_int32_t, [check_text], 9_c_size_t) == int(z'E3069283', c_int32_t), &
             'the tables give E3069283 too')
  same = .true.
  do n = 0, 256
    do i = 1, 256
      call random_number(u)
      bytes(i:i) = achar(int(256 * u))
    end do
    if (c_crc32c(7_c_int32_t, [bytes], int(n, c_size_t)) /= c_crc32c_tables(7_c_int32_t, [bytes], int(n, c_size_t))) &
      same = .false.
  end do
  call check(same, 'instruction and tables agree on 257 lengths of random bytes')

  ! syndromes of the single-bit errors of a 64-word record
  words = 0
  zero_crc = checksum(words)
  do i = 1, bits
    damaged = 0
    word = (i - 1) / 64 + 1
    damaged(word) = ibset(0_i8, mod(i - 1, 64))
    syndrome(i) = ieor(checksum(damaged), zero_crc)
  end do
  call check(all(syndrome /= 0), 'every 1-bit error is caught')
  sorted = syndrome
  call sort(sorted)
  undetected_2 = count(sorted(2:) == sorted(:bits - 1))
  call check(undetected_2 == 0, 'every 2-bit error is caught (' // itoa(bits * (bits - 1) / 2) // ' patterns)')
  undetected_3 = 0
  do i = 1, bits
    do j = i + 1, bits
      if (found(ieor(syndrome(i), syndrome(j)))) undetected_3 = undetected_3 + 1
    end do
  end do
  call check(undetected_3 == 0, 'every 3-bit error is caught (all pairs against every third bit)')

  ! and directly, on a record of random words: bit i with bit i + 7 of the
  ! next word (what a rotate-by-7 xor checksum misses), for every i
  do i = 1, record_words
    call random_number(u)
    words(i) = int(u * 9.0e18_wp, i8)
  end do
  missed_direct = 0
  do i = 0, 64 * (record_words - 1) - 1
    damaged = words
    word = i / 64 + 1
    damaged(word) = ieor(damaged(word), ibset(0_i8, mod(i, 64)))
    damaged(word + 1) = ieor(damaged(word + 1), ibset(0_i8, mod(i + 7, 64)))
    if (checksum(damaged) == checksum(words)) missed_direct = missed_direct + 1
  end do
  call check(missed_direct == 0, 'bit i and bit i + 7 of the next word: every pair caught')
  call finish('test_checksum')

contains

  !> Whether s is the syndrome of a single bit (binary search in sorted).
  logical function found(s)
    integer(i8), intent(in) :: s
    integer :: low, high, middle
    found = .false.
    low = 1
    high = bits
    do while (low <= high)
      middle = (low + high) / 2
      if (sorted(middle) == s) then
        found = .true.
        return
      else if (sorted(middle) < s) then
        low = middle + 1
      else
        high = middle - 1
      end if
    end do
  end function found

  subroutine sort(a)
    integer(i8), intent(inout) :: a(:)
    integer :: k, m
    integer(i8) :: v
    do k = 2, size(a)         ! insertion sort: 4096 values
      v = a(k)
      m = k - 1
      do while (m >= 1)
        if (a(m) <= v) exit
        a(m + 1) = a(m)
        m = m - 1
      end do
      a(m + 1) = v
    end do
  end subroutine sort

end program test_checksum
