!> The summary table of an output file: cases per status, the slowest case,
!> totals. Printed at the end of a run and by `ellroll summary`, both from
!> the file itself.
module ellroll_report
  use, intrinsic :: iso_fortran_env, only: output_unit
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa, format_real
  use ellroll_status, only: status_count, status_name
  use ellroll_hdf5_reader, only: h5_input_t
  implicit none
  private

  public :: print_summary

contains

  subroutine print_summary(path, err)
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    type(h5_input_t) :: file
    integer(i8), allocatable :: status(:), steps(:), index(:)
    real(wp), allocatable :: wall(:), theta_max(:)
    call file%open(path, err)
    if (err%failed()) return
    status = file%int_column('summary/status', err)
    steps = file%int_column('summary/n_steps', err)
    index = file%int_column('summary/case', err)
    wall = file%real_column('summary/wall_time', err)
    theta_max = file%real_column('summary/theta_max', err)
    call file%close()
    if (err%failed()) return
    call print_table(path, status, steps, index, wall, theta_max)
  end subroutine print_summary

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
