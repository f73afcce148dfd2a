!> Ground-acceleration records for a moving cup: the file formats ellroll
!> reads (a CSV of time and components; PEER NGA .AT2 files, one per axis),
!> checked line by line, each problem named with the file and line.
module ellroll_record_file
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_set_halting_mode, ieee_usual
  use, intrinsic :: ieee_exceptions, only: ieee_status_type, ieee_get_status, ieee_set_status
  use ellroll_kinds, only: wp
  use ellroll_strings, only: itoa, format_real, lower
  use ellroll_exact, only: equals
  implicit none
  private

  public :: load_ground_motion, standard_gravity

  !> m/s^2 per g: an AT2 file's unit (CGPM 1901).
  real(wp), parameter :: standard_gravity = 9.80665_wp
  !> Most samples one AT2 file may declare (a day at 1 kHz).
  integer, parameter :: max_at2_points = 100000000

  !> One axis of a record: samples at t = (k - 1) step, in m/s^2.
  type :: axis_record_t
    real(wp) :: step = 0
    real(wp), allocatable :: values(:)
  end type axis_record_t

contains

  !> The ground acceleration of a record case on one time grid: a CSV file
  !> (time and two or three components), or one AT2 file per axis (x, y[, z]).
  !> reason = '' when it is usable.
  subroutine load_ground_motion(paths, t_end, times, values, reason)
    character(len=*), intent(in) :: paths(:)
    real(wp), intent(in) :: t_end
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    character(len=:), allocatable, intent(out) :: reason
    type(axis_record_t) :: axes(3)
    integer :: k
    if (size(paths) == 1) then
      if (.not. is_at2(trim(paths(1)))) then
        call load_record(trim(paths(1)), t_end, times, values, reason)
        return
      end if
    end if
    do k = 1, size(paths)
      if (.not. is_at2(trim(paths(k)))) then
        reason = trim(paths(k)) // ': not a PEER .AT2 file (its fourth line gives no NPTS); a CSV record holds ' // &
                 'every axis, so give it alone'
        return
      end if
      call load_at2(trim(paths(k)), axes(k)%step, axes(k)%values, reason)
      if (len(reason) > 0) return
    end do
    do k = size(paths) + 1, 3
      axes(k)%step = axes(1)%step            ! an axis without a file: at rest
      allocate (axes(k)%values(0))
    end do
    call merge_axes(axes, times, values)
  end subroutine load_ground_motion

  !> Read a ground-acceleration record: lines of 'time, ax, ay[, az]' (commas
  !> or blanks; '#' comments and a header line allowed). reason = '' when it
  !> is usable: finite values, strictly increasing times, covering [0, t_end].
  subroutine load_record(path, t_end, times, values, reason)
    character(len=*), intent(in) :: path
    real(wp), intent(in) :: t_end
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    character(len=:), allocatable, intent(out) :: reason
    integer :: unit, ios, line_number, n, columns, width
    character(len=4096) :: line
    real(wp) :: row(4)
    logical :: header_allowed
    type(ieee_status_type) :: fp_state
    reason = ''
    allocate (times(0), values(3, 0))
    open (newunit=unit, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) then
      reason = 'cannot open ' // path
      return
    end if
    line_number = 0
    n = 0
    columns = 0
    header_allowed = .true.
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      line_number = line_number + 1
      if (index(line, '#') > 0) line = line(:index(line, '#') - 1)
      line = blanked(line, ',;')
      if (len_trim(line) == 0) cycle
      width = count_words(line)
      if (width < 3 .or. width > 4) then
        if (header_allowed .and. n == 0) then
          header_allowed = .false.
          cycle
        end if
        reason = path // ':' // itoa(line_number) // ': expected 3 or 4 numbers (time, ax, ay[, az]), found ' // &
                 itoa(width)
        exit
      end if
      row = 0
      call ieee_get_status(fp_state)
      call ieee_set_halting_mode(ieee_usual, .false.)   ! 1e309 reads as Inf, named below
      read (line, *, iostat=ios) row(:width)
      call ieee_set_status(fp_state)
      if (ios /= 0) then
        if (header_allowed .and. n == 0) then
          header_allowed = .false.
          cycle
        end if
        reason = path // ':' // itoa(line_number) // ': not numbers: ' // trim(adjustl(line))
        exit
      end if
      header_allowed = .false.
      if (columns == 0) columns = width
      if (width /= columns) then
        reason = path // ':' // itoa(line_number) // ': ' // itoa(width) // ' columns where the first row has ' // &
                 itoa(columns)
        exit
      end if
      if (.not. all(ieee_is_finite(row(:width)))) then
        reason = path // ':' // itoa(line_number) // ': a value is not finite'
        exit
      end if
      if (n > 0) then
        if (row(1) <= times(n)) then
          reason = path // ':' // itoa(line_number) // ': time ' // format_real(row(1)) // &
                   ' s does not increase (previous ' // format_real(times(n)) // ' s)'
          exit
        end if
      end if
      n = n + 1
      times = [times, row(1)]
      values = reshape([values, row(2:4)], [3, n])
    end do
    close (unit)
    if (len(reason) > 0) return
    if (n < 2) then
      reason = path // ': fewer than two samples'
    else if (times(1) > 0 .or. times(n) < t_end) then
      reason = path // ': the record covers ' // format_real(times(1)) // ' to ' // format_real(times(n)) // &
               ' s, not 0 to t_end = ' // format_real(t_end) // ' s'
    end if
  end subroutine load_record

  !> A PEER file: by its extension, or by 'NPTS' on its fourth line.
  logical function is_at2(path)
    character(len=*), intent(in) :: path
    character(len=4096) :: line
    integer :: unit, ios, k
    is_at2 = lower(path(max(1, len(path) - 3):)) == '.at2'
    if (is_at2) return
    open (newunit=unit, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) return
    do k = 1, 4
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
    end do
    close (unit)
    is_at2 = ios == 0 .and. index(lower(line), 'npts') > 0
  end function is_at2

  !> A PEER NGA .AT2 record: four header lines, the fourth giving NPTS and
  !> DT ('NPTS=  1999, DT=   .0100 SEC', with any text after, or the older
  !> '3930 0.00500 NPTS, DT'), then NPTS accelerations in g, any number to a
  !> line (the line holding the last may be padded beyond NPTS). Upper or
  !> lower case, LF or CRLF line ends. acc is in m/s^2.
  subroutine load_at2(path, dt, acc, reason)
    character(len=*), intent(in) :: path
    real(wp), intent(out) :: dt
    real(wp), allocatable, intent(out) :: acc(:)
    character(len=:), allocatable, intent(out) :: reason
    character(len=4096) :: line
    integer :: unit, ios, line_number, npts, got
    reason = ''
    dt = 0
    allocate (acc(0))
    open (newunit=unit, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) then
      reason = 'cannot open ' // path
      return
    end if
    do line_number = 1, 4
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) then
        reason = path // ':' // itoa(line_number) // ': the file ends in its header (four lines, the fourth ' // &
                 "giving NPTS and DT)"
        close (unit)
        return
      end if
    end do
    line_number = 4
    call header_counts(blanked(line, ''), npts, dt, reason)
    if (len(reason) > 0) then
      reason = path // ':4: ' // reason
      close (unit)
      return
    end if
    deallocate (acc)
    allocate (acc(npts))
    got = 0
    do while (got < npts)
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) then
        reason = path // ':' // itoa(line_number) // ': the file ends after ' // itoa(got) // ' of NPTS = ' // &
                 itoa(npts) // ' values (truncated, or NPTS disagrees with the values)'
        exit
      end if
      line_number = line_number + 1
      call read_values(blanked(line, ''), acc, got, reason)
      if (len(reason) > 0) then
        reason = path // ':' // itoa(line_number) // ': ' // reason
        exit
      end if
    end do
    do while (len(reason) == 0)       ! after the line holding the last value: nothing but blank lines
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      line_number = line_number + 1
      if (len_trim(blanked(line, '')) > 0) reason = path // ':' // itoa(line_number) // &
          ': values beyond NPTS = ' // itoa(npts) // ' (NPTS disagrees with the values)'
    end do
    close (unit)
    acc = acc * standard_gravity
  end subroutine load_at2

  !> NPTS and DT from an AT2 file's fourth line (lower-cased here).
  subroutine header_counts(text, npts, dt, reason)
    character(len=*), intent(in) :: text
    integer, intent(out) :: npts
    real(wp), intent(out) :: dt
    character(len=:), allocatable, intent(out) :: reason
    character(len=:), allocatable :: line, number
    integer :: at, ios
    character(len=256) :: msg
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
      call number_after(line, at + 4, number)
      read (number, *, iostat=ios, iomsg=msg) npts
      if (ios /= 0) then
        reason = 'NPTS is not a whole number: ' // trim(line)
        return
      end if
      at = index(line, 'dt')
      if (at == 0) then
        reason = "no DT on the fourth line (expected 'NPTS= n, DT= dt SEC')"
        return
      end if
      call number_after(line, at + 2, number)
      read (number, *, iostat=ios, iomsg=msg) dt
    else                                                        ! n dt NPTS, DT
      read (line(:at - 1), *, iostat=ios, iomsg=msg) npts, dt
    end if
    if (ios /= 0) then
      reason = 'DT is missing or not a number: ' // trim(line)
    else if (npts < 2 .or. npts > max_at2_points) then
      reason = 'NPTS = ' // itoa(npts) // ' must be between 2 and ' // itoa(max_at2_points)
    else if (.not. (dt >= 1.0e-6_wp .and. dt <= 1.0e3_wp)) then
      reason = 'DT = ' // format_real(dt) // ' s must be between 1e-6 and 1000 s'
    end if
  end subroutine header_counts

  !> The text of the number after position `from` and an optional '='.
  pure subroutine number_after(line, from, number)
    character(len=*), intent(in) :: line
    integer, intent(in) :: from
    character(len=:), allocatable, intent(out) :: number
    integer :: last
    number = adjustl(line(from:))
    if (number(1:1) == '=') number = adjustl(number(2:))
    last = scan(number, ' ,')
    if (last > 1) number = number(:last - 1)
    number = trim(number)
    if (len(number) == 0) number = '?'
  end subroutine number_after

  !> The values of one data line, into acc(got + 1:); what follows NPTS on
  !> the line is padding.
  subroutine read_values(line, acc, got, reason)
    character(len=*), intent(in) :: line
    real(wp), intent(inout) :: acc(:)
    integer, intent(inout) :: got
    character(len=:), allocatable, intent(out) :: reason
    integer :: first, last, ios
    real(wp) :: value
    type(ieee_status_type) :: fp_state
    reason = ''
    last = 0
    do while (got < size(acc))
      first = verify(line(last + 1:), ' ') + last
      if (first == last) exit                                   ! the rest is blank
      last = index(line(first:), ' ') + first - 2
      if (last < first) last = len(line)
      call ieee_get_status(fp_state)
      call ieee_set_halting_mode(ieee_usual, .false.)           ! 1e309 reads as Inf, named below
      read (line(first:last), '(f40.0)', iostat=ios) value
      call ieee_set_status(fp_state)
      if (ios /= 0 .or. last - first >= 40) then
        reason = "'" // line(first:last) // "' is not a number (value " // itoa(got + 1) // ' of ' // &
                 itoa(size(acc)) // ')'
        return
      end if
      if (.not. ieee_is_finite(value)) then
        reason = 'value ' // itoa(got + 1) // ' is not finite: ' // line(first:last)
        return
      end if
      got = got + 1
      acc(got) = value
    end do
  end subroutine read_values

  !> Tabs, carriage returns (CRLF line ends) and the given separators as blanks.
  pure function blanked(line, separators) result(text)
    character(len=*), intent(in) :: line, separators
    character(len=len(line)) :: text
    integer :: k
    text = line
    do k = 1, len_trim(text)
      if (iachar(text(k:k)) == 9 .or. iachar(text(k:k)) == 13 .or. index(separators, text(k:k)) > 0) text(k:k) = ' '
    end do
  end function blanked

  !> The axes on one grid: the union of their sample times. Each axis is
  !> linear between its samples and, past its last, falls to zero over one
  !> step and stays there (the ground at rest). Axes sampled alike share
  !> their grid exactly.
  subroutine merge_axes(axes, times, values)
    type(axis_record_t), intent(in) :: axes(3)
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    real(wp), allocatable :: grid(:)
    integer :: k, a
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

  pure integer function count_words(text)
    character(len=*), intent(in) :: text
    integer :: k
    count_words = 0
    do k = 1, len_trim(text)
      if (text(k:k) /= ' ' .and. (k == 1 .or. text(max(1, k-1):max(1, k-1)) == ' ')) count_words = count_words + 1
    end do
  end function count_words

end module ellroll_record_file
