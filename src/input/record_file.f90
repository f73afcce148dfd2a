!> Ground-acceleration records for a moving cup: the file formats ellroll
!> reads, checked line by line, each problem named with the file and line.
module ellroll_record_file
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_set_halting_mode, ieee_usual
  use, intrinsic :: ieee_exceptions, only: ieee_status_type, ieee_get_status, ieee_set_status
  use ellroll_kinds, only: wp
  use ellroll_strings, only: itoa, format_real
  implicit none
  private

  public :: load_record

contains

  !> Read a ground-acceleration record: lines of 'time, ax, ay[, az]' (commas
  !> or blanks; '#' comments and a header line allowed). reason = '' when it
  !> is usable: finite values, strictly increasing times, covering [0, t_end].
  subroutine load_record(path, t_end, times, values, reason)
    character(len=*), intent(in) :: path
    real(wp), intent(in) :: t_end
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    character(len=:), allocatable, intent(out) :: reason
    integer :: unit, ios, line_number, n, columns, k, width
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
      do k = 1, len_trim(line)
        if (line(k:k) == ',' .or. line(k:k) == ';' .or. iachar(line(k:k)) == 9 .or. iachar(line(k:k)) == 13) &
          line(k:k) = ' '
      end do
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

  pure integer function count_words(text)
    character(len=*), intent(in) :: text
    integer :: k
    count_words = 0
    do k = 1, len_trim(text)
      if (text(k:k) /= ' ' .and. (k == 1 .or. text(max(1, k-1):max(1, k-1)) == ' ')) count_words = count_words + 1
    end do
  end function count_words

end module ellroll_record_file
