!> `ellroll modes FILE.nml`: the small-oscillation periods of every case of
!> an input (docs/model.md).
module ellroll_cmd_modes
  use ellroll_standard_output, only: put_line
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: format_real
  use ellroll_input, only: run_input_t, read_input
  use ellroll_cases, only: case_t, make_ball, check_case, problem_setting
  use ellroll_params, only: params, p_omega_x, p_omega_z, p_x, p_y
  use ellroll_ellipsoid, only: normal_from_contact
  use ellroll_rolling_ball, only: rolling_ball_t
  use ellroll_linear, only: oscillation_periods, no_spin_periods
  use ellroll_cli, only: cli_t
  implicit none
  private

  public :: modes_command

contains

  !> The linearised small-oscillation periods about the bottom, spinning at
  !> sigma = omega0 . n0, beside the no-spin formula 2 pi sqrt((1+k)(rho-R)/g).
  subroutine modes_command(cli, err)
    type(cli_t), intent(in) :: cli
    type(error_t), intent(inout) :: err
    type(run_input_t) :: inp
    type(case_t) :: cs
    type(rolling_ball_t) :: ball
    real(wp) :: n0(3), periods(2), no_spin(2)
    integer(i8) :: i
    integer :: param
    character(len=160) :: line
    character(len=:), allocatable :: reason, subject
    call read_input(trim(cli%paths(1)), cli%output_path, inp, err)
    if (err%failed()) return
    call put_line('    case   sigma rad/s    period 1 s    period 2 s  no spin: x-z s         y-z s')
    do i = 0, inp%campaign%n_cases() - 1
      cs = inp%campaign%case_at(i)
      ! an invalid case has no cup or ball to analyse: its reason instead
      call check_case(cs, inp%plan%interval, param, reason)
      if (param /= 0) then
        write (line, '(i8)') i
        call problem_setting(cs, inp%plan%interval, param, subject)
        call put_line(trim(line) // '  invalid: ' // subject // ': ' // reason)
        cycle
      end if
      ball = make_ball(cs)
      n0 = normal_from_contact(ball%cup, cs%param(p_x), cs%param(p_y))
      periods = oscillation_periods(ball, dot_product(cs%param(p_omega_x:p_omega_z), n0))
      no_spin = no_spin_periods(ball)
      write (line, '(i8, f14.4, 4a)') i, dot_product(cs%param(p_omega_x:p_omega_z), n0), period_column(periods(1)), &
          period_column(periods(2)), period_column(no_spin(1)), period_column(no_spin(2))
      call put_line(trim(line))
    end do
  end subroutine modes_command

  !> A period in a column of `modes`, right-aligned with a blank before it
  !> whatever its size: six decimals, or six digits and an exponent (from a
  !> cup of 1e6 m to a ball 1e-6 m under the cup's radius of curvature).
  function period_column(x) result(text)
    real(wp), intent(in) :: x
    character(len=14) :: text
    ! NaN apart: an ordered comparison with it traps where invalid traps
    if (ieee_is_nan(x)) then
      write (text, '(f14.6)') x
    else if (abs(x) >= 1.0e-4_wp .and. abs(x) < 1.0e5_wp) then
      write (text, '(f14.6)') x
    else
      write (text, '(es14.5e3)') x
    end if
  end function period_column
end module ellroll_cmd_modes
