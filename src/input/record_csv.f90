!> Ground-acceleration records as CSV: lines of time and two or three
!> components, checked value by value, each problem named with the file
!> and line.
module ellroll_record_csv
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp
  use ellroll_strings, only: itoa, format_real, lower
  use ellroll_exact, only: equals
  use ellroll_decimal, only: decimal_value, decimal_ok
  use ellroll_record_text, only: text_file_t, take_line, next_word, names_nonfinite, count_lines, line_prefix, &
      first_word, empty_column
  use ellroll_record_units, only: unit_t, unit_of, within_bound, beyond_bound, max_record_points, known_units
  implicit none
  private

  public :: load_csv

  !> A CSV's times: within +-1e10 s (t_end <= 1e9 s), each at least 1e-6 s
  !> after the one before (an AT2's smallest DT), which keeps 1 / step finite.
  real(wp), parameter :: max_record_time = 1.0e10_wp, min_record_step = 1.0e-6_wp

contains

  !> Read a ground-acceleration record: lines of 'time, ax, ay[, az]' (commas
  !> or blanks; '#' comments and a header line allowed; '# units: g' before
  !> the first sample gives the unit of the accelerations, else m/s^2).
  !> reason = '' when it is usable: finite values within their bounds,
  !> times increasing from 0 or before. Past its last sample the record
  !> falls to zero over one more step (its last) and stays there, as an
  !> AT2 file does, whatever t_end: a case that runs past it (settle) sees
  !> the ground at rest.
  subroutine load_csv(file, factor, times, values, reason)
    type(text_file_t), intent(inout) :: file
    real(wp), intent(in) :: factor
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    character(len=:), allocatable, intent(out) :: reason
    integer :: first, last, hash, n, columns, width, rows, word_first, word_last, code, k, word_at(2, 4)
    real(wp) :: row(4)
    logical :: found, header_allowed, not_numbers, nonfinite, unit_given
    real(wp) :: first_value
    type(unit_t) :: unit
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
    ! (a UTF-8 byte order mark, as a spreadsheet's "CSV UTF-8" begins a file, is no part of the first line)
    if (file%next == 1 .and. len(file%text) >= 3) then
      if (iachar(file%text(1:1)) == 239 .and. iachar(file%text(2:2)) == 187 .and. iachar(file%text(3:3)) == 191) &
        file%next = 4
    end if
    do
      call take_line(file, first, last, found, hash)
      if (.not. found) exit
      if (hash > 0) then
        call take_comment(file, file%text(first + hash:last), n > 0, unit, unit_given, reason)
        if (len(reason) > 0) exit
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
      ! (a line with a number among its words is a sample, not a header: its error is its own)
      do k = 1, min(width, 4)
        if (header_allowed) header_allowed = decimal_value(file%text(word_at(1, k):word_at(2, k)), first_value) &
                                             /= decimal_ok
      end do
      if (width < 3 .or. width > 4) then
        if (header_allowed .and. n == 0) then
          header_allowed = .false.
          cycle
        end if
        reason = line_prefix(file) // 'expected 3 or 4 numbers (time, ax, ay[, az]), found ' // itoa(width)
        exit
      end if
      call read_row(file%text, word_at, width, row, not_numbers, nonfinite)
      if (not_numbers) then
        if (header_allowed .and. n == 0) then
          header_allowed = .false.
          cycle
        end if
        reason = line_prefix(file) // 'not numbers: ' // trim(adjustl(file%text(first:min(last, first + 199))))
        exit
      end if
      header_allowed = .false.
      if (empty_column(file%text(first:last)) > 0) then
        reason = line_prefix(file) // 'column ' // itoa(empty_column(file%text(first:last))) // ' is empty, and ' // &
                 'the values after it would move into its place; give 0 where the ground does not move'
        exit
      end if
      if (columns == 0) columns = width
      call check_row(file, word_at, width, columns, nonfinite, unit, factor, row, reason)
      if (len(reason) > 0) exit
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
    call end_at_rest(file%path, n, times, values, reason)
  end subroutine load_csv

  !> A '#' comment of a CSV: one units line ('# units: g') before the
  !> first sample gives the unit of the accelerations; other comments say
  !> nothing. `samples_before`: a sample came before it.
  subroutine take_comment(file, comment, samples_before, unit, unit_given, reason)
    type(text_file_t), intent(in) :: file
    character(len=*), intent(in) :: comment
    logical, intent(in) :: samples_before
    type(unit_t), intent(inout) :: unit
    logical, intent(inout) :: unit_given
    character(len=:), allocatable, intent(inout) :: reason
    character(len=:), allocatable :: why
    if (.not. names_units(comment)) return
    if (samples_before .or. unit_given) then
      reason = line_prefix(file) // 'a units line comes only once, before the first sample'
      return
    end if
    call units_line_unit(comment, unit, why)
    if (len(why) > 0) then
      reason = line_prefix(file) // why
      return
    end if
    unit_given = .true.
  end subroutine take_comment

  !> The numbers of a row's `width` words (text(word_at(1, k):word_at(2,
  !> k))), 0 where there is none; not_numbers when a word is no number,
  !> nonfinite when one is NaN or infinite.
  subroutine read_row(text, word_at, width, row, not_numbers, nonfinite)
    character(len=*), intent(in) :: text
    integer, intent(in) :: word_at(2, 4), width
    real(wp), intent(out) :: row(4)
    logical, intent(out) :: not_numbers, nonfinite
    integer :: k, code
    row = 0
    not_numbers = .false.
    nonfinite = .false.
    do k = 1, width
      code = decimal_value(text(word_at(1, k):word_at(2, k)), row(k))
      if (code /= decimal_ok) then
        if (names_nonfinite(text(word_at(1, k):word_at(2, k)))) then
          nonfinite = .true.
        else
          not_numbers = .true.
        end if
      else if (.not. ieee_is_finite(row(k))) then
        nonfinite = .true.
      end if
    end do
  end subroutine read_row

  !> A row of numbers on its own: as many as the first row has, finite, its
  !> time and accelerations within their bounds (the accelerations then in
  !> m/s^2). reason = '' when it is usable.
  subroutine check_row(file, word_at, width, columns, nonfinite, unit, factor, row, reason)
    type(text_file_t), intent(in) :: file
    integer, intent(in) :: word_at(2, 4), width, columns
    logical, intent(in) :: nonfinite
    type(unit_t), intent(in) :: unit
    real(wp), intent(in) :: factor
    real(wp), intent(inout) :: row(4)
    character(len=:), allocatable, intent(inout) :: reason
    integer :: k
    real(wp) :: si
    if (width /= columns) then
      reason = line_prefix(file) // itoa(width) // ' columns where the first row has ' // itoa(columns)
      return
    end if
    if (nonfinite) then
      do k = 1, width
        if (names_nonfinite(file%text(word_at(1, k):word_at(2, k)))) then
          reason = line_prefix(file) // 'value ' // itoa(k) // ' is not finite: ' // &
                   file%text(word_at(1, k):word_at(2, k))
          return
        end if
      end do
    end if
    if (.not. abs(row(1)) <= max_record_time) then
      reason = line_prefix(file) // 'time ' // format_real(row(1)) // ' s is beyond +-' // &
               format_real(max_record_time) // ' s'
      return
    end if
    do k = 2, width
      if (.not. within_bound(row(k), unit, factor, si)) exit
      row(k) = si
    end do
    if (k <= width) call beyond_row(file, file%text(word_at(1, k):word_at(2, k)), row(k), unit, factor, reason)
  end subroutine check_row

  !> Why a row's sample (`word`, `value` in `unit`) is beyond its bound.
  subroutine beyond_row(file, word, value, unit, factor, reason)
    type(text_file_t), intent(in) :: file
    character(len=*), intent(in) :: word
    real(wp), intent(in) :: value, factor
    type(unit_t), intent(in) :: unit
    character(len=:), allocatable, intent(inout) :: reason
    character(len=:), allocatable :: why
    call beyond_bound(word, value, unit, factor, why)
    reason = line_prefix(file) // why
  end subroutine beyond_row

  !> The record's n samples checked as a whole (two at least, from t = 0
  !> or before), and a sample of zero one step past the last (the step of
  !> a uniform grid, else the last one); times and values cut to the
  !> samples.
  subroutine end_at_rest(path, n, times, values, reason)
    character(len=*), intent(in) :: path
    integer, intent(inout) :: n
    real(wp), allocatable, intent(inout) :: times(:), values(:, :)
    character(len=:), allocatable, intent(inout) :: reason
    real(wp) :: step
    integer :: k
    if (n < 2) then
      reason = path // ': fewer than two samples'
      return
    else if (times(1) > 0) then
      reason = path // ': the record starts at ' // format_real(times(1)) // ' s; it must cover t = 0'
      return
    end if
    step = times(2)                       ! at rest one step past its end
    do k = 1, n
      if (.not. equals(times(k), real(k - 1, wp) * step)) step = 0
    end do
    n = n + 1
    times(n) = merge(real(n - 1, wp) * step, times(n - 1) + (times(n - 1) - times(n - 2)), step > 0)
    values(:, n) = 0
    times = times(:n)
    values = values(:, :n)
  end subroutine end_at_rest

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
end module ellroll_record_csv
