!> Small text helpers shared by the input checks, the messages and the writer.
!>
!> No function in ellroll returns a `character(len=:), allocatable` result:
!> gfortran 12 keeps the length of such a result in a static variable of the
!> caller, so two threads calling it at once corrupt each other's text (a
!> format string, a message). Results here have their length given by a
!> pure function of the arguments instead (tests/python/test_source_rules.py
!> checks the rule).
module ellroll_strings
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero, equals
  implicit none
  private

  public :: lower, itoa, join, format_real, format_computed, real_text, text_hash, excerpt, size_text
  ! the lengths of itoa and format_real, for a caller's own result length
  ! (gfortran 12 cannot nest len(itoa(x)) of a derived type's component there)
  public :: decimal_width, real_text_length, json_text

  !> An integer as text, without blanks.
  interface itoa
    module procedure itoa_default, itoa_long
  end interface itoa

  !> The longest text a message quotes whole (excerpt).
  integer, parameter :: excerpt_max = 200

  !> The longest text real_text writes ('-1.2345678901234567e-308' and
  !> fixed-point forms up to 10 integer digits and 20 decimals).
  integer, parameter :: real_text_max = 40

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

  !> The number of characters of i in decimal (a sign included).
  pure integer function decimal_width(i)
    integer(i8), intent(in) :: i
    integer(i8) :: rest
    if (i == -huge(i) - 1) then
      decimal_width = 20
      return
    end if
    decimal_width = merge(2, 1, i < 0)
    rest = abs(i)
    do while (rest >= 10)
      rest = rest / 10
      decimal_width = decimal_width + 1
    end do
  end function decimal_width

  pure function itoa_default(i) result(s)
    integer, intent(in) :: i
    character(len=decimal_width(int(i, i8))) :: s
    write (s, '(i0)') i
  end function itoa_default

  pure function itoa_long(i) result(s)
    integer(i8), intent(in) :: i
    character(len=decimal_width(i)) :: s
    write (s, '(i0)') i
  end function itoa_long

  pure integer function excerpt_length(text) result(n)
    character(len=*), intent(in) :: text
    n = len(text)
    if (n > excerpt_max) n = excerpt_max - 40 + 6 + decimal_width(int(n, i8)) + 12
  end function excerpt_length

  !> A text for a message: itself up to excerpt_max characters; longer, its
  !> start and its length (a value may be megabytes long).
  pure function excerpt(text) result(out)
    character(len=*), intent(in) :: text
    character(len=excerpt_length(text)) :: out
    if (len(text) <= excerpt_max) then
      out = text
    else
      out = text(:excerpt_max - 40) // ' ... (' // itoa(len(text)) // ' characters)'
    end if
  end function excerpt

  !> The words, trimmed, joined by ', '.
  pure function join(words) result(text)
    character(len=*), intent(in) :: words(:)
    character(len=max(0, sum(len_trim(words)) + 2 * (size(words) - 1))) :: text
    integer :: k, at
    if (size(words) == 0) return
    text(:len_trim(words(1))) = words(1)
    at = len_trim(words(1))
    do k = 2, size(words)
      text(at + 1:at + 2 + len_trim(words(k))) = ', ' // words(k)(:len_trim(words(k)))
      at = at + 2 + len_trim(words(k))
    end do
  end function join

  pure integer function real_text_length(x) result(n)
    real(wp), intent(in) :: x
    character(len=real_text_max) :: buffer
    call real_text(x, buffer, n)
  end function real_text_length

  !> The shortest text that reads back as x: 0.2, 30, 1e-06, 2620.
  pure function format_real(x) result(text)
    real(wp), intent(in) :: x
    character(len=real_text_length(x)) :: text
    character(len=real_text_max) :: buffer
    integer :: n
    call real_text(x, buffer, n)
    text = buffer(:n)
  end function format_real

  !> A size of bytes in KiB (whole), MiB or GiB (one decimal).
  pure subroutine size_text(bytes, text)
    real(wp), intent(in) :: bytes
    character(len=:), allocatable, intent(out) :: text
    if (bytes < 2.0_wp**20) then
      text = format_real(real(nint(bytes / 1024), wp)) // ' KiB'
    else if (bytes < 2.0_wp**30) then
      text = format_real(real(nint(10 * bytes / 2.0_wp**20), wp) / 10) // ' MiB'
    else
      text = format_real(real(nint(10 * bytes / 2.0_wp**30), wp) / 10) // ' GiB'
    end if
  end subroutine size_text

  !> The double nearest x rounded to 10 significant digits (x itself where
  !> not finite, or so large that the rounding could pass huge()).
  pure real(wp) function ten_digits(x) result(rounded)
    real(wp), intent(in) :: x
    character(len=24) :: work
    integer :: ios
    rounded = x
    if (.not. ieee_is_finite(x)) return
    if (abs(x) > 1.0e300_wp) return
    write (work, '(es24.9e3)') x
    read (work, '(es24.0)', iostat=ios) rounded
    if (ios /= 0) rounded = x
  end function ten_digits

  !> A value a message computes (mu radius, t_end / max_steps), to at most 10
  !> significant digits: 1.9e-07, where the shortest text that reads back
  !> would show the product's binary noise (1.8999999999999998e-07).
  pure function format_computed(x) result(text)
    real(wp), intent(in) :: x
    character(len=real_text_length(ten_digits(x))) :: text
    text = format_real(ten_digits(x))
  end function format_computed

  !> format_real's text of x in buffer(:n) (for a caller that writes many,
  !> such as a table of numbers, without building each twice).
  pure subroutine real_text(x, buffer, n)
    real(wp), intent(in) :: x
    character(len=real_text_max), intent(out) :: buffer
    integer, intent(out) :: n
    character(len=*), parameter :: scientific(15:17) = [character(len=12) :: &
        '(es40.14e3)', '(es40.15e3)', '(es40.16e3)']
    character(len=40) :: work
    character(len=16) :: fixed
    real(wp) :: back
    real(wp), parameter :: near_huge = huge(1.0_wp) * (1 - 1.0e-14_wp)
    integer :: digits, exponent10, ios, mark, last
    buffer = ''
    if (.not. ieee_is_finite(x)) then
      write (work, '(es12.3)') x
      buffer = adjustl(work)
      n = len_trim(buffer)
      return
    end if
    if (is_zero(x)) then
      buffer = '0'
      n = 1
      return
    end if
    ! 15 significant digits that read back as x are the shortest such text
    ! padded with zeros (x is within half an ulp of it); else 16 or 17.
    ! Within 1e-14 of huge() 15 or 16 digits may round up past it, and
    ! reading that back would overflow (a trap in the Debug build): 17
    ! digits, which always read back, are taken at once
    if (abs(x) >= near_huge) then
      write (work, scientific(17)) x
    else
      do digits = 15, 17
        write (work, scientific(digits)) x
        read (work, '(es40.0)', iostat=ios) back
        if (ios == 0 .and. equals(back, x)) exit
      end do
    end if
    ! the mantissa without its trailing zeros (and without a bare '.')
    work = adjustl(work)
    mark = index(work, 'E') - 1
    last = mark
    do while (work(last:last) == '0')
      last = last - 1
    end do
    if (work(last:last) == '.') last = last - 1
    digits = last - merge(1, 0, index(work(:last), '.') > 0) - merge(1, 0, work(1:1) == '-')
    ! the exponent of the digits written (rounding may carry into the next
    ! power of ten: 9.9999999999999999e22 is written 1.00000000000000E+023)
    read (work(mark + 2:), *) exponent10
    if (exponent10 >= -4 .and. exponent10 < 10) then
      write (fixed, '(a, i0, a)') '(f40.', max(0, digits - 1 - exponent10), ')'
      write (buffer, fixed) x
      buffer = adjustl(buffer)
      n = len_trim(buffer)
      if (buffer(n:n) == '.') n = n - 1
      if (buffer(1:1) == '.') then
        buffer = '0' // buffer(:n)
        n = n + 1
      else if (buffer(1:2) == '-.') then
        buffer = '-0' // buffer(2:n)
        n = n + 1
      end if
    else
      write (fixed, '(i2.2)') abs(exponent10)
      if (abs(exponent10) >= 100) write (fixed, '(i3)') abs(exponent10)
      buffer = work(:last) // 'e' // merge('-', '+', exponent10 < 0) // trim(fixed)
      n = len_trim(buffer)
    end if
  end subroutine real_text

  pure integer function json_length(raw) result(length)
    character(len=*), intent(in) :: raw
    integer :: k, n
    length = 0
    k = 1
    do while (k <= len(raw))
      n = utf8_length(raw, k)
      length = length + piece_length(raw, k, n)
      k = k + max(n, 1)
    end do
  end function json_length

  !> The length in JSON of the character at raw(k:), a UTF-8 sequence of n
  !> bytes (0: not one).
  pure integer function piece_length(raw, k, n) result(length)
    character(len=*), intent(in) :: raw
    integer, intent(in) :: k, n
    integer :: code
    code = iachar(raw(k:k))
    if (raw(k:k) == '"' .or. raw(k:k) == '\' .or. code == 10 .or. code == 9 .or. code == 13) then
      length = 2
    else if (code < 32) then
      length = 6
    else if (n == 0) then
      length = 6                  ! \ufffd
    else
      length = n
    end if
  end function piece_length

  !> The bytes of the well-formed UTF-8 sequence that begins at raw(k:)
  !> (1 to 4; 0 where none does: a stray continuation byte, an overlong
  !> form, a surrogate, beyond U+10FFFF, or cut short).
  pure integer function utf8_length(raw, k) result(n)
    character(len=*), intent(in) :: raw
    integer, intent(in) :: k
    integer :: lead, second, low, high, j
    lead = iachar(raw(k:k))
    n = 0
    if (lead < 128) then
      n = 1
      return
    end if
    low = 128
    high = 191
    select case (lead)
    case (194:223); n = 2
    case (224); n = 3; low = 160
    case (225:236, 238:239); n = 3
    case (237); n = 3; high = 159
    case (240); n = 4; low = 144
    case (241:243); n = 4
    case (244); n = 4; high = 143
    case default; return
    end select
    if (k + n - 1 > len(raw)) then
      n = 0
      return
    end if
    second = iachar(raw(k + 1:k + 1))
    if (second < low .or. second > high) n = 0
    do j = k + 2, k + n - 1
      if (iachar(raw(j:j)) < 128 .or. iachar(raw(j:j)) > 191) n = 0
    end do
  end function utf8_length
  !> raw as the inside of a JSON string (RFC 8259): quote and backslash
  !> escaped, control characters as \u00XX (\n, \t, \r by name), UTF-8
  !> sequences as they are, and each byte of anything else (a name in
  !> another encoding) as U+FFFD: the text stays valid UTF-8, as JSON must.
  pure function json_text(raw) result(text)
    character(len=*), intent(in) :: raw
    character(len=json_length(raw)) :: text
    integer :: k, at, n, code
    character(len=*), parameter :: hex = '0123456789abcdef', replacement = '\ufffd'
    k = 1
    at = 0
    do while (k <= len(raw))
      code = iachar(raw(k:k))
      n = utf8_length(raw, k)
      if (raw(k:k) == '"' .or. raw(k:k) == '\') then
        text(at + 1:at + 2) = '\' // raw(k:k)
      else if (code == 10 .or. code == 9 .or. code == 13) then
        text(at + 1:at + 2) = '\' // merge('n', merge('t', 'r', code == 9), code == 10)
      else if (code < 32) then
        text(at + 1:at + 6) = '\u00' // hex(code / 16 + 1:code / 16 + 1) // hex(mod(code, 16) + 1:mod(code, 16) + 1)
      else if (n == 0) then
        text(at + 1:at + len(replacement)) = replacement
      else
        text(at + 1:at + n) = raw(k:k + n - 1)
      end if
      at = at + piece_length(raw, k, n)
      k = k + max(n, 1)
    end do
  end function json_text

end module ellroll_strings
