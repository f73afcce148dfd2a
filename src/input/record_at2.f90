!> Ground-acceleration records as PEER NGA .AT2 files (one per axis): the
!> header's unit, NPTS and DT, then the values, checked value by value,
!> each problem named with the file and line. Velocity and displacement
!> records (.VT2, .DT2) are refused.
module ellroll_record_at2
  use ellroll_kinds, only: wp
  use ellroll_exact, only: is_zero
  use ellroll_strings, only: itoa, format_real, lower
  use ellroll_decimal, only: decimal_value, decimal_ok, decimal_too_long, longest_decimal
  use ellroll_record_text, only: text_file_t, take_line, is_blank, next_word, names_nonfinite, quoted, first_word
  use ellroll_record_units, only: unit_t, unit_of, within_bound, beyond_bound, max_record_points, known_units
  implicit none
  private

  public :: is_at2, refuse_other_quantities, load_at2

  character(len=*), parameter :: lf = achar(10)

contains

  !> Velocity (.VT2) and displacement (.DT2) records are refused by name.
  subroutine refuse_other_quantities(file, reason)
    type(text_file_t), intent(in) :: file
    character(len=:), allocatable, intent(out) :: reason
    character(len=4) :: extension
    reason = ''
    extension = lower(file%path(max(1, len(file%path) - 3):))
    if (extension == '.vt2') then
      reason = file%path // ': a velocity record (.VT2); ellroll reads ground acceleration (a PEER .AT2 file ' // &
               'or a CSV)'
    else if (extension == '.dt2') then
      reason = file%path // ': a displacement record (.DT2); ellroll reads ground acceleration (a PEER .AT2 ' // &
               'file or a CSV)'
    end if
  end subroutine refuse_other_quantities

  !> A PEER file: by its extension, or by 'NPTS' on its fourth line.
  logical function is_at2(file)
    type(text_file_t), intent(in) :: file
    integer :: first, last, k
    is_at2 = lower(file%path(max(1, len(file%path) - 3):)) == '.at2'
    if (is_at2) return
    last = 0
    do k = 1, 4
      first = last + 1
      if (first > len(file%text)) return
      last = index(file%text(first:), lf) + first - 1
      if (last < first) last = len(file%text) + 1
    end do
    is_at2 = index(lower(file%text(first:last - 1)), 'npts') > 0
  end function is_at2

  !> A PEER NGA .AT2 record: four header lines, the third naming the unit
  !> ('ACCELERATION TIME SERIES IN UNITS OF G'), the fourth giving NPTS and
  !> DT ('NPTS=  1999, DT=   .0100 SEC', with any text after, or the older
  !> '3930 0.00500 NPTS, DT'), then NPTS accelerations, any number to a
  !> line, and after them only zeros padding the last one's line, then
  !> blank lines. Upper or
  !> lower case, LF or CRLF line ends. acc is in m/s^2.
  subroutine load_at2(file, factor, dt, acc, reason)
    type(text_file_t), intent(inout) :: file
    real(wp), intent(in) :: factor
    real(wp), intent(out) :: dt
    real(wp), allocatable, intent(out) :: acc(:)
    character(len=:), allocatable, intent(out) :: reason
    integer :: first(4), last(4), npts, got, k, word_first, word_last, code, n, pos, line
    logical :: found
    type(unit_t) :: unit
    real(wp) :: value
    character(len=:), allocatable :: why
    reason = ''
    dt = 0
    do k = 1, 4
      call take_line(file, first(k), last(k), found)
      if (.not. found) then
        reason = file%path // ':' // itoa(k) // ': the file ends in its header (four lines, the fourth ' // &
                 'giving NPTS and DT)'
        allocate (acc(0))
        return
      end if
    end do
    call header_counts(blanked_header(file%text(first(4):last(4))), npts, dt, why)
    if (len(why) > 0) then
      reason = file%path // ':4: ' // why
      allocate (acc(0))
      return
    end if
    call at2_unit(file, first(:3), last(:3), unit, reason)
    if (len(reason) > 0) then
      allocate (acc(0))
      return
    end if
    allocate (acc(npts), stat=code)
    if (code /= 0) then
      reason = file%path // ': no memory for NPTS = ' // itoa(npts) // ' values'
      allocate (acc(0))
      return
    end if
    ! One pass over the values, line feeds counted as they pass; after the
    ! NPTS values nothing but blanks and line ends
    n = len(file%text)
    pos = file%next
    line = file%line + 1                  ! the line holding pos
    got = 0
    do while (got < npts)
      call value_word(file%text, pos, line, word_first, word_last)
      if (word_first == 0) then
        if (file%next > n) line = line - 1              ! no line after the header
        if (file%next <= n .and. ichar(file%text(n:n)) == 10) line = line - 1   ! nothing after the last line feed
        reason = file%path // ':' // itoa(line) // ': the file ends after ' // itoa(got) // ' of NPTS = ' // &
                 itoa(npts) // ' values (truncated, or NPTS disagrees with the values)'
        return
      end if
      code = decimal_value(file%text(word_first:word_last), value)
      if (code /= decimal_ok) then
        if (names_nonfinite(file%text(word_first:word_last))) then
          reason = file%path // ':' // itoa(line) // ': value ' // itoa(got + 1) // ' is not finite: ' // &
                   file%text(word_first:word_last)
        else
          reason = file%path // ':' // itoa(line) // ': ' // quoted(file%text(word_first:word_last)) // &
                   ' is not a number (value ' // itoa(got + 1) // ' of ' // itoa(npts)
          if (code == decimal_too_long) reason = reason // ', longer than ' // itoa(longest_decimal) // ' characters'
          reason = reason // ')'
        end if
        return
      end if
      got = got + 1
      if (.not. within_bound(value, unit, factor, acc(got))) then
        call beyond_bound(file%text(word_first:word_last), value, unit, factor, why)
        reason = file%path // ':' // itoa(line) // ': value ' // itoa(got) // ' of ' // itoa(npts) // ', ' // why
        return
      end if
    end do
    call refuse_beyond_npts(file, pos, line, npts, reason)
  end subroutine load_at2

  !> The next word of text from pos (blanks, tabs, CRs and line feeds
  !> between words; line counts the line feeds passed): text(first:last),
  !> pos after it; first = 0 at the end of the text.
  pure subroutine value_word(text, pos, line, first, last)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: pos, line
    integer, intent(out) :: first, last
    integer :: code
    first = 0
    last = 0
    do while (pos <= len(text))           ! to the next word
      code = ichar(text(pos:pos))
      if (code > 32) exit
      if (code == 10) then
        line = line + 1
      else if (code /= 32 .and. code /= 9 .and. code /= 13) then
        exit                              ! another control character: in a word
      end if
      pos = pos + 1
    end do
    if (pos > len(text)) return
    first = pos
    do while (pos <= len(text))           ! to the word's end
      code = ichar(text(pos:pos))
      if (code == 32 .or. code == 9 .or. code == 13 .or. code == 10) exit
      pos = pos + 1
    end do
    last = pos - 1
  end subroutine value_word

  !> After the NPTS values the file holds nothing but zeros on the line of the
  !> last (the fixed five-a-line layout pads that line) and blanks: more
  !> values (NPTS disagrees with them, as with fewer) or any text are refused,
  !> at the line of the first word beyond, with the counts.
  subroutine refuse_beyond_npts(file, pos, line, npts, reason)
    type(text_file_t), intent(in) :: file
    integer, intent(inout) :: pos, line
    integer, intent(in) :: npts
    character(len=:), allocatable, intent(inout) :: reason
    integer :: first, last, extra, first_line, last_value_line
    real(wp) :: value
    logical :: padding
    extra = 0
    first_line = 0
    last_value_line = line
    padding = .true.
    do
      call value_word(file%text, pos, line, first, last)
      if (first == 0) exit
      if (extra == 0) first_line = line
      if (decimal_value(file%text(first:last), value) /= decimal_ok) then
        reason = file%path // ':' // itoa(line) // ': ' // quoted(file%text(first:last)) // ' after the NPTS = ' // &
                 itoa(npts) // ' values'
        if (extra > 0) reason = reason // ' and ' // itoa(extra) // ' more'
        reason = reason // ' (the values end at NPTS; text only in the four header lines)'
        return
      end if
      extra = extra + 1
      padding = padding .and. line == last_value_line .and. is_zero(value)
    end do
    if (extra > 0 .and. .not. padding) reason = file%path // ':' // itoa(first_line) // ': ' // &
        itoa(npts + extra) // ' values where NPTS = ' // itoa(npts) // ' (NPTS disagrees with the values)'
  end subroutine refuse_beyond_npts

  !> The unit of an AT2 file from its header (lines 1 to 3, text(first(k):
  !> last(k))): the word after 'UNITS OF' on the line that says UNITS (the
  !> third in PEER's files). A velocity or displacement record is refused.
  subroutine at2_unit(file, first, last, unit, reason)
    type(text_file_t), intent(in) :: file
    integer, intent(in) :: first(3), last(3)
    type(unit_t), intent(out) :: unit
    character(len=:), allocatable, intent(out) :: reason
    character(len=16) :: quantity
    integer :: k, line, at
    character(len=:), allocatable :: text, shown, original
    reason = ''
    line = 0
    do k = 3, 1, -1
      if (index(lower(file%text(first(k):last(k))), 'units') > 0) then
        line = k
        if (k == 3) exit
      end if
    end do
    if (line == 0) then
      shown = trim(blanked_header(file%text(first(3):min(last(3), first(3) + 119))))
      reason = file%path // ":3: the header names no unit after the word UNITS (PEER's third line reads e.g. " // &
               "'ACCELERATION TIME SERIES IN UNITS OF G'): '" // shown // "'"
      return
    end if
    original = blanked_header(file%text(first(line):last(line)))
    text = lower(original)
    shown = trim(original(:min(len(original), 120)))
    if (index(text, 'velocity') > 0) then
      reason = file%path // ':' // itoa(line) // ': a velocity record (' // shown // '); ellroll reads ' // &
               'ground acceleration'
      return
    else if (index(text, 'displacement') > 0) then
      reason = file%path // ':' // itoa(line) // ': a displacement record (' // shown // '); ellroll reads ' // &
               'ground acceleration'
      return
    end if
    at = index(text, 'units') + 5                 ! 'UNITS OF G', 'UNITS: G', 'UNITS = G'
    at = at + verify(text(at:) // 'x', ' ') - 1
    if (scan(text(at:min(at, len(text))), ':=') == 1) at = at + 1
    at = at + verify(text(at:) // 'x', ' ') - 1
    if (text(at:min(at + 2, len(text))) == 'of' .or. text(at:min(at + 2, len(text))) == 'of ') at = at + 2
    original = original(min(at, len(original) + 1):)
    call unit_of(first_word(original), unit, quantity)
    select case (quantity)
    case ('acceleration')
    case ('velocity', 'displacement')
      reason = file%path // ':' // itoa(line) // ": '" // first_word(original) // "' is a unit of " // &
               trim(quantity) // ' (' // shown // '); ellroll reads ground acceleration'
    case default
      reason = file%path // ':' // itoa(line) // ": unknown unit '" // first_word(original) // "' (known: " // &
               known_units // '): ' // shown
    end select
  end subroutine at2_unit

  !> Tabs and carriage returns as blanks.
  pure function blanked_header(text) result(out)
    character(len=*), intent(in) :: text
    character(len=len(text)) :: out
    integer :: k
    out = text
    do k = 1, len(out)
      if (is_blank(out(k:k), .false.)) out(k:k) = ' '
    end do
  end function blanked_header

  !> NPTS and DT from an AT2 file's fourth line.
  subroutine header_counts(text, npts, dt, reason)
    character(len=*), intent(in) :: text
    integer, intent(out) :: npts
    real(wp), intent(out) :: dt
    character(len=:), allocatable, intent(out) :: reason
    character(len=len(text)) :: line, number
    character(len=:), allocatable :: unit
    integer :: at, ios, code, first, last
    line = lower(text)
    reason = ''
    npts = 0
    dt = 0
    at = index(line, 'npts')
    if (at == 0) then
      reason = "no NPTS on the fourth line (expected 'NPTS= n, DT= dt SEC' or 'n dt NPTS, DT')"
      return
    else if (index(line(at + 4:), 'npts') > 0) then
      reason = 'NPTS is given twice: ' // trim(line)
      return
    end if
    if (index(adjustl(line(at + 4:)), '=') == 1) then           ! NPTS= n, DT= dt SEC
      number = number_after(line, at + 4)
      read (number, *, iostat=ios) npts
      if (ios /= 0) then
        reason = 'NPTS is not a whole number: ' // trim(line)
        return
      end if
      at = index(line, 'dt')
      if (at == 0) then
        reason = "no DT on the fourth line (expected 'NPTS= n, DT= dt SEC')"
        return
      end if
      number = number_after(line, at + 2)
      call unit_after(line, at + 2, number, unit)
      if (len(unit) > 0 .and. all(unit /= [character(len=7) :: 's', 'sec', 'secs', 'second', 'seconds'])) then
        reason = "DT's unit '" // unit // "' is not seconds; write DT in SEC ('NPTS= n, DT= dt SEC')"
        return
      end if
      call drop_seconds(number)
      code = decimal_value(trim(number), dt)
    else                                                        ! n dt NPTS, DT
      call next_word(line(:at - 1), 1, .true., first, last)
      ios = 1
      if (last >= first) read (line(first:last), *, iostat=ios) npts
      call next_word(line(:at - 1), last + 1, .true., first, last)
      code = decimal_value(line(first:last), dt)
      if (ios /= 0) code = 1
    end if
    if (code /= decimal_ok) then
      reason = 'DT is missing or not a number: ' // trim(line)
    else if (npts < 2 .or. npts > max_record_points) then
      reason = 'NPTS = ' // itoa(npts) // ' must be between 2 and ' // itoa(max_record_points)
    else if (.not. (dt >= 1.0e-6_wp .and. dt <= 1.0e3_wp)) then
      reason = 'DT = ' // format_real(dt) // ' s must be between 1e-6 and 1000 s'
    end if
  end subroutine header_counts

  !> Blanks the unit written against a number's text ('0.01sec', '0.01s').
  pure subroutine drop_seconds(number)
    character(len=*), intent(inout) :: number
    integer :: last
    last = len_trim(number)
    if (last > 3) then
      if (number(last - 2:last) == 'sec') then
        number(last - 2:) = ' '
        last = last - 3
      end if
    end if
    if (last > 1) then
      if (number(last:last) == 's') number(last:) = ' '
    end if
  end subroutine drop_seconds

  !> The unit of the number (its text: number, as number_after found it
  !> after position `from`): the letters written against its end ('0.01sec'),
  !> else the letters that start the next word ('0.01 sec,'), else '' (also
  !> where the number's text is letters alone).
  pure subroutine unit_after(line, from, number, unit)
    character(len=*), intent(in) :: line, number
    integer, intent(in) :: from
    character(len=:), allocatable, intent(out) :: unit
    character(len=*), parameter :: letters = 'abcdefghijklmnopqrstuvwxyz'
    integer :: last, rest, stop, digits
    unit = ''
    last = len_trim(number)
    digits = verify(number(:last), letters, back=.true.)
    if (digits == 0) return                 ! (letters alone: not a number, said so after)
    unit = number(digits + 1:last)
    if (len(unit) > 0) return
    rest = from + index(line(from:), number(:last)) + last - 1      ! just past the number
    rest = rest - 1 + verify(line(rest:) // '#', ' ,')
    if (rest > len(line)) return
    stop = verify(line(rest:) // '#', letters)
    unit = line(rest:rest + stop - 2)
  end subroutine unit_after

  !> The text of the number after position `from` and an optional '=' (up
  !> to a blank or a comma), or '?'.
  pure function number_after(line, from) result(number)
    character(len=*), intent(in) :: line
    integer, intent(in) :: from
    character(len=max(1, len(line) - from + 1)) :: number
    integer :: last
    number = adjustl(line(from:))
    if (number(1:1) == '=') number = adjustl(number(2:))
    last = scan(number, ' ,')
    if (last > 1) number = number(:last - 1)
    if (len_trim(number) == 0) number = '?'
  end function number_after
end module ellroll_record_at2
