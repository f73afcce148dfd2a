!> Small text helpers shared by the input checks, the messages and the writer.
module ellroll_strings
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_set_halting_mode, ieee_usual
  use, intrinsic :: ieee_exceptions, only: ieee_status_type, ieee_get_status, ieee_set_status
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero, equals
  implicit none
  private

  public :: lower, itoa, join, format_real, text_hash

  !> An integer as text, without blanks.
  interface itoa
    module procedure itoa_default, itoa_long
  end interface itoa

contains

  !> A 64-bit hash of a text as 16 hex digits: two 32-bit FNV-1a lanes, in
  !> exact integer arithmetic, the same on every machine.
  pure function text_hash(text) result(hex)
    character(len=*), intent(in) :: text
    character(len=16) :: hex
    integer(i8), parameter :: prime = 16777619_i8, mask = 4294967295_i8
    integer(i8) :: lane(2)
    integer :: k
    lane = [2166136261_i8, 3735928559_i8]
    do k = 1, len(text)
      lane(1) = iand(ieor(lane(1), int(iachar(text(k:k)), i8)) * prime, mask)
      lane(2) = iand(ieor(lane(2), int(iachar(text(k:k)), i8) + 97_i8) * prime, mask)
    end do
    write (hex, '(2z8.8)') lane
  end function text_hash

  pure function lower(text) result(out)
    character(len=*), intent(in) :: text
    character(len=len(text)) :: out
    integer :: k
    out = text
    do k = 1, len(text)
      if (text(k:k) >= 'A' .and. text(k:k) <= 'Z') out(k:k) = achar(iachar(text(k:k)) + 32)
    end do
  end function lower

  pure function itoa_default(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    s = itoa_long(int(i, i8))
  end function itoa_default

  pure function itoa_long(i) result(s)
    integer(i8), intent(in) :: i
    character(len=:), allocatable :: s
    character(len=24) :: buf
    write (buf, '(i0)') i
    s = trim(buf)
  end function itoa_long
  pure function join(words) result(text)
    character(len=*), intent(in) :: words(:)
    character(len=:), allocatable :: text
    integer :: k
    text = trim(words(1))
    do k = 2, size(words)
      text = text // ', ' // trim(words(k))
    end do
  end function join

  !> The shortest text that reads back as x: 0.2, 30, 1e-06, 2620.
  function format_real(x) result(text)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=40) :: buf
    real(wp) :: back
    character(len=:), allocatable :: mantissa
    integer :: digits, exponent10, ios
    type(ieee_status_type) :: fp_state
    if (.not. ieee_is_finite(x)) then
      write (buf, '(es12.3)') x
      text = trim(adjustl(buf))
      return
    end if
    if (is_zero(x)) then
      text = '0'
      return
    end if
    ! 15 significant digits that read back as x are the shortest such text
    ! padded with zeros (x is within half an ulp of it); else 16 or 17.
    ! Near huge() the rounded text reads back as an overflow, which must
    ! not stop a build that traps on it: it only means more digits
    call ieee_get_status(fp_state)
    call ieee_set_halting_mode(ieee_usual, .false.)
    do digits = 15, 17
      write (buf, '(es40.' // itoa(digits - 1) // 'e3)') x
      read (buf, '(es40.0)', iostat=ios) back
      if (ios == 0 .and. equals(back, x)) exit
    end do
    call ieee_set_status(fp_state)
    mantissa = strip_mantissa(trim(adjustl(buf(:index(buf, 'E') - 1))))
    digits = len(mantissa) - merge(1, 0, index(mantissa, '.') > 0) - merge(1, 0, mantissa(1:1) == '-')
    exponent10 = floor(log10(abs(x)))
    if (exponent10 >= -4 .and. exponent10 < 10) then
      write (buf, '(f40.' // itoa(max(0, digits - 1 - exponent10)) // ')') x
      text = trim(adjustl(buf))
      if (text(len(text):len(text)) == '.') text = text(:len(text)-1)
      if (index(text, '.') == 1) text = '0' // text
      if (index(text, '-.') == 1) text = '-0' // text(2:)
    else
      text = mantissa // 'e' // exponent_text(exponent10)
    end if
  contains
    pure function strip_mantissa(m) result(out)
      character(len=*), intent(in) :: m
      character(len=:), allocatable :: out
      out = m
      if (index(out, '.') > 0) then
        do while (out(len(out):len(out)) == '0')
          out = out(:len(out)-1)
        end do
        if (out(len(out):len(out)) == '.') out = out(:len(out)-1)
      end if
    end function strip_mantissa
    pure function exponent_text(e) result(out)
      integer, intent(in) :: e
      character(len=:), allocatable :: out
      out = itoa(abs(e))
      if (len(out) < 2) out = '0' // out
      out = merge('-', '+', e < 0) // out
    end function exponent_text
  end function format_real

end module ellroll_strings
