!> The summary table of an output file: cases per status, the slowest case,
!> totals. Printed at the end of a run and by `ellroll summary`, both from
!> the file itself.
module ellroll_report
  use, intrinsic :: iso_fortran_env, only: output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa, format_real
  use ellroll_status, only: status_count, status_name
  use ellroll_hdf5_reader, only: h5_input_t
  implicit none
  private

  public :: print_summary

  !> The figures of /summary in a row of `ellroll summary --format csv|json`.
  character(len=*), parameter :: row_figures(9) = [character(len=30) :: 't_final', 'theta_max', &
      'nutation_period', 'energy_drift', 'displacement_max', 'residual_displacement', &
      'absolute_acceleration_max', 'transmissibility', 'wall_time']

contains

  !> The summary of a file: the table (format 'text'), or one row per case
  !> of its status and figures ('csv', or 'json' with NaN as null).
  subroutine print_summary(path, format, err)
    character(len=*), intent(in) :: path, format
    type(error_t), intent(inout) :: err
    type(h5_input_t) :: file
    integer(i8), allocatable :: status(:), steps(:), index(:)
    real(wp), allocatable :: wall(:), theta_max(:), figures(:, :)
    integer :: k
    call file%open(path, err)
    if (err%failed()) return
    status = file%int_column('summary/status', err)
    steps = file%int_column('summary/n_steps', err)
    index = file%int_column('summary/case', err)
    wall = file%real_column('summary/wall_time', err)
    theta_max = file%real_column('summary/theta_max', err)
    if (format /= 'text' .and. .not. err%failed()) then
      allocate (figures(size(status), size(row_figures)))
      do k = 1, size(row_figures)
        figures(:, k) = file%real_column('summary/' // trim(row_figures(k)), err)
      end do
    end if
    call file%close()
    if (err%failed()) return
    select case (format)
    case ('csv')
      call print_csv(index, status, steps, figures)
    case ('json')
      call print_json(path, index, status, steps, figures)
    case default
      call print_table(path, status, steps, index, wall, theta_max)
    end select
  end subroutine print_summary

  !> One row per case: index, status, these figures of /summary, n_steps.
  subroutine print_csv(index, status, steps, figures)
    integer(i8), intent(in) :: index(:), status(:), steps(:)
    real(wp), intent(in) :: figures(:, :)
    character(len=:), allocatable :: line
    integer :: i, k
    line = 'case,status'
    do k = 1, size(row_figures)
      line = line // ',' // trim(row_figures(k))
    end do
    write (output_unit, '(a)') line // ',n_steps'
    do i = 1, size(index)
      line = itoa(index(i)) // ',' // status_name(int(status(i)))
      do k = 1, size(row_figures)
        line = line // ',' // format_real(figures(i, k))
      end do
      write (output_unit, '(a)') line // ',' // itoa(steps(i))
    end do
  end subroutine print_csv

  !> The same as strict JSON: {"file": ..., "cases": [{...}, ...]}, NaN as null.
  subroutine print_json(path, index, status, steps, figures)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: index(:), status(:), steps(:)
    real(wp), intent(in) :: figures(:, :)
    character(len=:), allocatable :: line
    integer :: i, k
    write (output_unit, '(a)') '{"file": "' // json_text(path) // '", "cases": ['
    do i = 1, size(index)
      line = ' {"case": ' // itoa(index(i)) // ', "status": "' // status_name(int(status(i))) // '"'
      do k = 1, size(row_figures)
        line = line // ', "' // trim(row_figures(k)) // '": ' // json_number(figures(i, k))
      end do
      line = line // ', "n_steps": ' // itoa(steps(i)) // '}'
      if (i < size(index)) line = line // ','
      write (output_unit, '(a)') line
    end do
    write (output_unit, '(a)') ']}'
  end subroutine print_json

  !> A finite number as JSON reads it (format_real's 1e-06 is valid JSON), else null.
  function json_number(x) result(text)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: text
    if (ieee_is_finite(x)) then
      text = format_real(x)
    else
      text = 'null'
    end if
  end function json_number

  !> Text inside a JSON string: backslashes and quotes escaped.
  function json_text(raw) result(text)
    character(len=*), intent(in) :: raw
    character(len=:), allocatable :: text
    integer :: k
    text = ''
    do k = 1, len(raw)
      if (raw(k:k) == '\' .or. raw(k:k) == '"') text = text // '\'
      text = text // raw(k:k)
    end do
  end function json_text

  subroutine print_table(path, status, steps, index, wall, theta_max)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: status(:), steps(:), index(:)
    real(wp), intent(in) :: wall(:), theta_max(:)
    integer :: s, slowest
    character(len=12) :: label
    write (output_unit, '(a)') path // ': ' // itoa(size(status)) // ' cases'
    do s = 0, status_count - 1
      if (count(status == s) == 0) cycle
      label = status_name(s)
      write (output_unit, '(a, i10)') '  ' // label, count(status == s)
    end do
    if (all(status == 0)) return
    slowest = maxloc(wall, dim=1, mask=status /= 0)
    write (output_unit, '(a)') '  steps, all cases: ' // itoa(sum(steps)) // '; integration time ' // &
        format_real(real(nint(1000 * sum(wall, mask=status /= 0)), wp) / 1000) // ' s (sum over cases)'
    write (output_unit, '(a)') '  slowest case: ' // itoa(index(slowest)) // ' (' // &
        format_real(real(nint(1.0e4_wp * wall(slowest)), wp) / 1.0e4_wp) // ' s, ' // &
        status_name(int(status(slowest))) // ')'
    if (size(status) == 1) write (output_unit, '(a)') '  theta_max: ' // format_real(theta_max(1)) // ' rad'
  end subroutine print_table
end module ellroll_report
