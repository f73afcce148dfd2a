!> Ground-acceleration records for a moving cup: the file formats ellroll
!> reads (a CSV of time and components; PEER NGA .AT2 files, one per axis),
!> checked value by value, each problem named with the file and line.
!> A record file is a regular file of at most max_record_bytes, read whole
!> into memory; its numbers are read to the nearest double (ellroll_decimal),
!> the value Fortran's read gives.
module ellroll_record_file
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: itoa, format_real, lower, decimal_width
  use ellroll_checksum, only: text_checksum
  use ellroll_exact, only: equals
  use ellroll_decimal, only: decimal_value, decimal_ok, decimal_too_long, longest_decimal
  use ellroll_system, only: open_regular_file, read_text, close_descriptor, system_error_text, file_type_words
  implicit none
  private

  public :: load_ground_motion, standard_gravity, max_record_acceleration, max_record_bytes

  !> m/s^2 per g (CGPM 1901).
  real(wp), parameter :: standard_gravity = 9.80665_wp
  !> Largest |ground acceleration| of a sample, m/s^2, in SI units and
  !> times its record's factor (about 1000 g, far beyond any recorded
  !> motion). With scale <= 1e3 the cup's acceleration stays below 1e7
  !> m/s^2, so that forces on masses up to 1e12 kg, and their squares, are
  !> finite.
  real(wp), parameter :: max_record_acceleration = 1.0e4_wp
  !> Largest record file, bytes (1 GiB): it is read whole into memory.
  integer(i8), parameter :: max_record_bytes = 2_i8**30
  !> Most samples of one file (a day at 1 kHz).
  integer, parameter :: max_record_points = 100000000
  !> A CSV's times: within +-1e10 s (t_end <= 1e9 s), each at least 1e-6 s
  !> after the one before (an AT2's smallest DT), which keeps 1 / step finite.
  real(wp), parameter :: max_record_time = 1.0e10_wp, min_record_step = 1.0e-6_wp
  !> Numbers beyond this are beyond max_record_acceleration in any unit;
  !> below it, the conversion to SI cannot overflow.
  real(wp), parameter :: far_beyond = 1.0e300_wp

  character(len=*), parameter :: lf = achar(10)
  character(len=*), parameter :: known_units = 'g; cm/s^2 as CM/SEC/SEC, CM/S/S, CM/S^2 or GAL; ' // &
                                               'm/s^2 as M/SEC/SEC, M/S/S or M/S^2'

  !> One axis of a record: samples at t = (k - 1) step, in m/s^2.
  type :: axis_record_t
    real(wp) :: step = 0
    real(wp), allocatable :: values(:)
  end type axis_record_t

  !> A record file's text, taken line by line.
  type :: text_file_t
    character(len=:), allocatable :: path
    character(len=:), allocatable :: text
    integer :: next = 1          !< first character of the next line
    integer :: line = 0          !< number of the line last taken
  end type text_file_t

  !> A unit of acceleration: a value in it is value * multiplier / divisor
  !> m/s^2 (one rounding for g and cm/s^2 alike, none for m/s^2).
  type :: unit_t
    character(len=6) :: name = 'm/s^2'
    real(wp) :: multiplier = 1, divisor = 1
  end type unit_t

contains

  !> The ground acceleration of a record on one time grid: a CSV file (time
  !> and two or three components), or one AT2 file per axis (x, y[, z]).
  !> Every sample is checked against max_record_acceleration as read and
  !> times `factor` (the record's, applied by the caller). reason = '' when
  !> it is usable.
  subroutine load_ground_motion(paths, t_end, factor, times, values, reason, fingerprints)
    character(len=*), intent(in) :: paths(:)
    real(wp), intent(in) :: t_end, factor
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    character(len=:), allocatable, intent(out) :: reason
    !> each file's size and CRC-32C ('1234 bytes, crc32c 0a1b2c3d'): what a
    !> resume and a merge compare to tell a changed file
    character(len=40), intent(out), optional :: fingerprints(size(paths))
    type(axis_record_t) :: axes(3)
    type(text_file_t) :: file
    integer :: k
    do k = 1, size(paths)
      call read_record_text(trim(paths(k)), file, reason)
      if (len(reason) > 0) return
      if (present(fingerprints)) write (fingerprints(k), '(i0, " bytes, crc32c ", z8.8)') len(file%text, kind=i8), &
          text_checksum(file%text)
      call refuse_other_quantities(file, reason)
      if (len(reason) > 0) return
      if (.not. is_at2(file)) then
        if (size(paths) == 1) then
          call load_csv(file, t_end, factor, times, values, reason)
        else
          reason = file%path // ': not a PEER .AT2 file (its fourth line gives no NPTS); a CSV record holds ' // &
                   'every axis, so give it alone'
        end if
        return
      end if
      call load_at2(file, factor, axes(k)%step, axes(k)%values, reason)
      if (len(reason) > 0) return
    end do
    do k = size(paths) + 1, 3
      axes(k)%step = axes(1)%step            ! an axis without a file: at rest
      allocate (axes(k)%values(0))
    end do
    call merge_axes(axes, times, values)
  end subroutine load_ground_motion

  !> The whole text of a record file: a regular file (a FIFO would block,
  !> a device never end) of at most max_record_bytes.
  subroutine read_record_text(path, file, reason)
    character(len=*), intent(in) :: path
    type(text_file_t), intent(out) :: file
    character(len=:), allocatable, intent(out) :: reason
    integer :: code, fd
    integer(i8) :: bytes
    character :: file_type
    reason = ''
    file%path = path
    code = open_regular_file(path, fd, bytes, file_type)
    if (code > 0) then
      reason = 'cannot open ' // path // ': ' // system_error_text(code)
      return
    else if (code < 0) then
      reason = path // ': ' // trim(file_type_words(file_type)) // ', not a regular file; a record is read ' // &
               'from a regular file'
      return
    end if
    if (bytes > max_record_bytes) then
      reason = path // ': ' // itoa(bytes) // ' bytes, more than a record file may hold (1 GiB)'
    else
      allocate (character(len=bytes) :: file%text, stat=code)
      if (code /= 0) then
        reason = path // ': no memory for its ' // itoa(bytes) // ' bytes'
      else
        code = read_text(fd, file%text)
        if (code > 0) reason = 'cannot read ' // path // ': ' // system_error_text(code)
        if (code < 0) reason = path // ': the file shrank while it was read'
      end if
    end if
    code = close_descriptor(fd)
  end subroutine read_record_text

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

  !> The next line of the file: its characters first .. last (without the
  !> line feed); found = .false. at the end. hash: where its first '#' is,
  !> or 0 (one pass over the line finds both).
  subroutine take_line(file, first, last, found, hash)
    type(text_file_t), intent(inout) :: file
    integer, intent(out) :: first, last
    logical, intent(out) :: found
    integer, intent(out), optional :: hash
    integer :: code, at
    first = file%next
    last = first - 1
    found = first <= len(file%text)
    at = 0
    if (found) then
      do last = first, len(file%text)           ! (a loop: index() costs a call per line)
        code = ichar(file%text(last:last))
        if (code == 10) exit
        if (code == 35 .and. at == 0) at = last - first + 1
      end do
      last = last - 1
      file%next = last + 2
      file%line = file%line + 1
    end if
    if (present(hash)) hash = at
  end subroutine take_line

  !> Blanks, tabs and carriage returns (CRLF line ends) part words; in a CSV
  !> also commas and semicolons. (By character code: c == ' ' costs a call
  !> of len_trim.)
  elemental logical function is_blank(c, csv)
    character, intent(in) :: c
    logical, intent(in) :: csv
    integer :: code
    code = ichar(c)
    is_blank = code == 32 .or. code == 9 .or. code == 13 .or. (csv .and. (code == 44 .or. code == 59))
  end function is_blank

  !> The next word of text from position `from`: text(first:last), with
  !> last < first when there is none.
  pure subroutine next_word(text, from, csv, first, last)
    character(len=*), intent(in) :: text
    integer, intent(in) :: from
    logical, intent(in) :: csv
    integer, intent(out) :: first, last
    integer :: k, code
    first = len(text) + 1
    last = len(text)
    if (csv) then
      do k = from, len(text)
        code = ichar(text(k:k))
        if (code /= 32 .and. code /= 9 .and. code /= 13 .and. code /= 44 .and. code /= 59) exit
      end do
      first = k
      do k = first, len(text)
        code = ichar(text(k:k))
        if (code == 32 .or. code == 9 .or. code == 13 .or. code == 44 .or. code == 59) exit
      end do
    else
      do k = from, len(text)
        code = ichar(text(k:k))
        if (code /= 32 .and. code /= 9 .and. code /= 13) exit
      end do
      first = k
      do k = first, len(text)
        code = ichar(text(k:k))
        if (code == 32 .or. code == 9 .or. code == 13) exit
      end do
    end if
    last = k - 1
  end subroutine next_word

  !> 'nan', 'inf', 'infinity' with any sign and case: numbers, but not finite.
  pure logical function names_nonfinite(word)
    character(len=*), intent(in) :: word
    integer :: start
    start = 1
    if (len(word) > 0) then
      if (word(1:1) == '+' .or. word(1:1) == '-') start = 2
    end if
    names_nonfinite = any(lower(word(start:)) == [character(len=8) :: 'nan', 'inf', 'infinity'])
  end function names_nonfinite

  !> A word as a message quotes it: at most 40 characters.
  pure function quoted(word) result(text)
    character(len=*), intent(in) :: word
    character(len=min(len(word), 40) + merge(5, 2, len(word) > 40)) :: text
    if (len(word) > 40) then
      text = "'" // word(:40) // "...'"
    else
      text = "'" // word // "'"
    end if
  end function quoted

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

  !> Read a ground-acceleration record: lines of 'time, ax, ay[, az]' (commas
  !> or blanks; '#' comments and a header line allowed; '# units: g' before
  !> the first sample gives the unit of the accelerations, else m/s^2).
  !> reason = '' when it is usable: finite values within their bounds,
  !> times increasing from 0 or before. Past its last sample, when that
  !> comes before t_end, the record falls to zero over one more step (its
  !> last) and stays there, as an AT2 file does.
  subroutine load_csv(file, t_end, factor, times, values, reason)
    type(text_file_t), intent(inout) :: file
    real(wp), intent(in) :: t_end, factor
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    character(len=:), allocatable, intent(out) :: reason
    integer :: first, last, hash, n, columns, width, rows, k, word_first, word_last, code, word_at(2, 4)
    real(wp) :: row(4), step, si
    logical :: found, header_allowed, not_numbers, nonfinite, unit_given
    type(unit_t) :: unit
    character(len=:), allocatable :: why
    reason = ''
    rows = min(count_lines(file%text), max_record_points + 1)
    allocate (times(rows), values(3, rows), stat=code)
    if (code /= 0) then
      reason = file%path // ': no memory for its ' // itoa(rows) // ' lines'
      return
    end if
    n = 0
    columns = 0
    header_allowed = .true.
    unit_given = .false.
    do
      call take_line(file, first, last, found, hash)
      if (.not. found) exit
      if (hash > 0) then
        if (names_units(file%text(first + hash:last))) then
          if (n > 0 .or. unit_given) then
            reason = line_prefix(file) // 'a units line comes only once, before the first sample'
            exit
          end if
          call units_line_unit(file%text(first + hash:last), unit, why)
          if (len(why) > 0) then
            reason = line_prefix(file) // why
            exit
          end if
          unit_given = .true.
        end if
        last = first + hash - 2
      end if
      width = 0                                  ! the words, and where the first four are
      word_last = first - 1
      do
        call next_word(file%text(:last), word_last + 1, .true., word_first, word_last)
        if (word_last < word_first) exit
        width = width + 1
        if (width <= 4) word_at(:, width) = [word_first, word_last]
      end do
      if (width == 0) cycle
      if (width < 3 .or. width > 4) then
        if (header_allowed .and. n == 0) then
          header_allowed = .false.
          cycle
        end if
        reason = line_prefix(file) // 'expected 3 or 4 numbers (time, ax, ay[, az]), found ' // itoa(width)
        exit
      end if
      row = 0
      not_numbers = .false.
      nonfinite = .false.
      do k = 1, width
        code = decimal_value(file%text(word_at(1, k):word_at(2, k)), row(k))
        if (code /= decimal_ok) then
          if (names_nonfinite(file%text(word_at(1, k):word_at(2, k)))) then
            nonfinite = .true.
          else
            not_numbers = .true.
          end if
        else if (.not. ieee_is_finite(row(k))) then
          nonfinite = .true.
        end if
      end do
      if (not_numbers) then
        if (header_allowed .and. n == 0) then
          header_allowed = .false.
          cycle
        end if
        reason = line_prefix(file) // 'not numbers: ' // trim(adjustl(file%text(first:min(last, first + 199))))
        exit
      end if
      header_allowed = .false.
      if (columns == 0) columns = width
      if (width /= columns) then
        reason = line_prefix(file) // itoa(width) // ' columns where the first row has ' // itoa(columns)
        exit
      end if
      if (nonfinite) then
        reason = line_prefix(file) // 'a value is not finite'
        exit
      end if
      if (.not. abs(row(1)) <= max_record_time) then
        reason = line_prefix(file) // 'time ' // format_real(row(1)) // ' s is beyond +-' // &
                 format_real(max_record_time) // ' s'
        exit
      end if
      do k = 2, width
        if (.not. within_bound(row(k), unit, factor, si)) exit
        row(k) = si
      end do
      if (k <= width) then
        call beyond_bound(file%text(word_at(1, k):word_at(2, k)), row(k), unit, factor, why)
        reason = line_prefix(file) // why
        exit
      end if
      if (n > 0) then
        if (row(1) <= times(n)) then
          reason = line_prefix(file) // 'time ' // format_real(row(1)) // ' s does not increase (previous ' // &
                   format_real(times(n)) // ' s)'
          exit
        else if (row(1) - times(n) < min_record_step) then
          reason = line_prefix(file) // 'time ' // format_real(row(1)) // ' s follows ' // format_real(times(n)) // &
                   ' s by less than ' // format_real(min_record_step) // ' s'
          exit
        end if
      end if
      if (n == max_record_points) then
        reason = line_prefix(file) // 'more than ' // itoa(max_record_points) // ' samples'
        exit
      end if
      n = n + 1
      times(n) = row(1)
      values(:, n) = row(2:4)
    end do
    if (len(reason) > 0) return
    if (n < 2) then
      reason = file%path // ': fewer than two samples'
      return
    else if (times(1) > 0) then
      reason = file%path // ': the record starts at ' // format_real(times(1)) // ' s; it must cover t = 0'
      return
    end if
    if (times(n) < t_end) then            ! at rest one step past its end
      step = times(2)
      do k = 1, n
        if (.not. equals(times(k), real(k - 1, wp) * step)) step = 0
      end do
      n = n + 1
      times(n) = merge(real(n - 1, wp) * step, times(n - 1) + (times(n - 1) - times(n - 2)), step > 0)
      values(:, n) = 0
    end if
    times = times(:n)
    values = values(:, :n)
  end subroutine load_csv

  !> Lines of a text, the last counted whether or not a line feed ends it,
  !> and one more (room for the rest past a record's end).
  pure integer function count_lines(text) result(n)
    character(len=*), intent(in) :: text
    integer :: k
    n = 2
    do k = 1, len(text)
      if (iachar(text(k:k)) == 10) n = n + 1
    end do
  end function count_lines

  !> 'path:line: ' of the line last taken.
  pure function line_prefix(file) result(text)
    type(text_file_t), intent(in) :: file
    character(len=len(file%path) + decimal_width(int(file%line, i8)) + 3) :: text
    text = file%path // ':' // itoa(file%line) // ': '
  end function line_prefix

  !> A comment that gives the unit: 'units: ...' or 'units = ...'.
  pure logical function names_units(comment)
    character(len=*), intent(in) :: comment
    character(len=len(comment)) :: text
    text = adjustl(lower(comment))
    names_units = .false.
    if (len(text) >= 6) names_units = text(1:5) == 'units' .and. scan(adjustl(text(6:)), ':=') == 1
  end function names_units

  !> The unit of a CSV's '# units: UNIT' line (an acceleration unit).
  subroutine units_line_unit(comment, unit, why)
    character(len=*), intent(in) :: comment
    type(unit_t), intent(out) :: unit
    character(len=:), allocatable, intent(out) :: why
    character(len=len(comment)) :: text
    character(len=16) :: quantity
    text = comment
    text = adjustl(text(scan(text, ':=') + 1:))
    call unit_of(first_word(text), unit, quantity)
    why = ''
    if (quantity /= 'acceleration') why = "unknown unit of acceleration '" // trim(text) // "' (known: " // &
        known_units // ')'
  end subroutine units_line_unit

  !> The length of first_word(text).
  pure integer function word_length(text)
    character(len=*), intent(in) :: text
    integer :: start, length
    start = verify(text, ' ')
    word_length = 0
    if (start == 0) return
    length = scan(text(start:), ' ,') - 1
    if (length < 0) length = len(text) - start + 1
    word_length = length
  end function word_length

  !> The first word of a text (up to a blank or a comma), or ''.
  pure function first_word(text) result(word)
    character(len=*), intent(in) :: text
    character(len=word_length(text)) :: word
    integer :: start
    start = verify(text, ' ')
    word = ''
    if (start > 0) word = text(start:)
  end function first_word

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
      reason = file%path // ":3: the header names no unit (PEER's third line reads e.g. 'ACCELERATION TIME " // &
               "SERIES IN UNITS OF G'): '" // shown // "'"
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

  !> A PEER NGA .AT2 record: four header lines, the third naming the unit
  !> ('ACCELERATION TIME SERIES IN UNITS OF G'), the fourth giving NPTS and
  !> DT ('NPTS=  1999, DT=   .0100 SEC', with any text after, or the older
  !> '3930 0.00500 NPTS, DT'), then NPTS accelerations, any number to a
  !> line (the line holding the last may be padded beyond NPTS). Upper or
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
    ! One pass over the values, line feeds counted as they pass: the line
    ! holding the last value may go on (padding), then only blank lines.
    n = len(file%text)
    pos = file%next
    line = file%line + 1                  ! the line holding pos
    got = 0
    do while (got < npts)
      do while (pos <= n)                 ! to the next word
        code = ichar(file%text(pos:pos))
        if (code > 32) exit
        if (code == 10) then
          line = line + 1
        else if (code /= 32 .and. code /= 9 .and. code /= 13) then
          exit                            ! another control character: in a word
        end if
        pos = pos + 1
      end do
      if (pos > n) then
        if (file%next > n) line = line - 1              ! no line after the header
        if (file%next <= n .and. ichar(file%text(n:n)) == 10) line = line - 1   ! nothing after the last line feed
        reason = file%path // ':' // itoa(line) // ': the file ends after ' // itoa(got) // ' of NPTS = ' // &
                 itoa(npts) // ' values (truncated, or NPTS disagrees with the values)'
        return
      end if
      word_first = pos
      do while (pos <= n)                 ! to the word's end
        code = ichar(file%text(pos:pos))
        if (code <= 32) then
          if (code == 32 .or. code == 9 .or. code == 13 .or. code == 10) exit
        end if
        pos = pos + 1
      end do
      word_last = pos - 1
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
    do while (pos <= n)                   ! the rest of the last value's line
      if (ichar(file%text(pos:pos)) == 10) exit
      pos = pos + 1
    end do
    do while (pos <= n)                   ! then nothing but blank lines
      code = ichar(file%text(pos:pos))
      if (code == 10) then
        line = line + 1
      else if (code /= 32 .and. code /= 9 .and. code /= 13) then
        reason = file%path // ':' // itoa(line) // ': values beyond NPTS = ' // itoa(npts) // &
                 ' (NPTS disagrees with the values)'
        return
      end if
      pos = pos + 1
    end do
  end subroutine load_at2

  !> NPTS and DT from an AT2 file's fourth line.
  subroutine header_counts(text, npts, dt, reason)
    character(len=*), intent(in) :: text
    integer, intent(out) :: npts
    real(wp), intent(out) :: dt
    character(len=:), allocatable, intent(out) :: reason
    character(len=len(text)) :: line, number
    integer :: at, ios, code, first, last
    line = lower(text)
    reason = ''
    npts = 0
    dt = 0
    at = index(line, 'npts')
    if (at == 0) then
      reason = "no NPTS on the fourth line (expected 'NPTS= n, DT= dt SEC' or 'n dt NPTS, DT')"
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
      code = decimal_value(trim(number_after(line, at + 2)), dt)
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

  !> The axes on one grid: the union of their sample times. Each axis is
  !> linear between its samples and, past its last, falls to zero over one
  !> step and stays there (the ground at rest). Axes sampled alike share
  !> their grid exactly: that grid is taken as it is (the same times and
  !> values as the union, without its search).
  subroutine merge_axes(axes, times, values)
    type(axis_record_t), intent(in) :: axes(3)
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    real(wp), allocatable :: grid(:)
    integer :: k, a, n
    if (all(equals(axes%step, axes(1)%step))) then
      n = maxval([(size(axes(a)%values), a = 1, 3)])
      times = [(real(k - 1, wp) * axes(1)%step, k = 1, n + 1)]
      allocate (values(3, n + 1))
      values = 0
      do a = 1, 3
        values(a, :size(axes(a)%values)) = axes(a)%values
      end do
      return
    end if
    allocate (times(0))
    do a = 1, 3
      grid = [(real(k - 1, wp) * axes(a)%step, k = 1, size(axes(a)%values) + 1)]
      times = union_sorted(times, grid)
    end do
    allocate (values(3, size(times)))
    do a = 1, 3
      do k = 1, size(times)
        values(a, k) = axis_value(axes(a), times(k))
      end do
    end do
  end subroutine merge_axes

  !> Axis a at time t: its samples, linear between them, zero one step past
  !> the last.
  pure real(wp) function axis_value(axis, t) result(value)
    type(axis_record_t), intent(in) :: axis
    real(wp), intent(in) :: t
    real(wp) :: position, weight, left, right
    integer :: k, n
    n = size(axis%values)
    value = 0
    position = t / axis%step
    if (.not. position < n + 1) return     ! at rest (and no integer overflow below)
    k = int(position) + 1                  ! t in [(k - 1) step, k step)
    if (k > 1 .and. real(k - 1, wp) * axis%step > t) k = k - 1
    if (real(k, wp) * axis%step <= t) k = k + 1
    left = 0
    right = 0
    if (k <= n) left = axis%values(k)
    if (k + 1 <= n) right = axis%values(k + 1)
    value = left
    ! (at its own sample, the sample itself: a fused multiply-add in the
    ! weight would leave the product's rounding error there)
    if (equals(t, real(k - 1, wp) * axis%step)) return
    weight = (t - real(k - 1, wp) * axis%step) / axis%step
    value = (1 - weight) * left + weight * right
  end function axis_value

  !> The sorted union of two sorted lists, equal entries once.
  pure function union_sorted(first, second) result(merged)
    real(wp), intent(in) :: first(:), second(:)
    real(wp), allocatable :: merged(:)
    real(wp), allocatable :: buffer(:)
    integer :: i, j, n
    allocate (buffer(size(first) + size(second)))
    i = 1
    j = 1
    n = 0
    do while (i <= size(first) .or. j <= size(second))
      n = n + 1
      if (j > size(second)) then
        buffer(n) = first(i)
        i = i + 1
      else if (i > size(first)) then
        buffer(n) = second(j)
        j = j + 1
      else if (first(i) < second(j)) then
        buffer(n) = first(i)
        i = i + 1
      else
        if (.not. second(j) < first(i)) i = i + 1        ! equal: once
        buffer(n) = second(j)
        j = j + 1
      end if
    end do
    merged = buffer(:n)
  end function union_sorted

end module ellroll_record_file
