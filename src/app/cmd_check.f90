!> `ellroll check FILE.nml`: an input read and validated, its base case,
!> campaign and output described, its step advice and invalid cases
!> reported; nothing written.
module ellroll_cmd_check
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_standard_output, only: put_line
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa, format_real, size_text
  use ellroll_records, only: named_value_t, kind_real, kind_int
  use ellroll_input, only: run_input_t, read_input
  use ellroll_cases, only: case_t, case_record, make_ball, field_count, field_names, get_param
  use ellroll_params, only: params, p_dt, p_g, p_omega_x, p_omega_z, p_radius, p_x, p_y
  use ellroll_ellipsoid, only: principal_radii, normal_from_contact
  use ellroll_rolling_ball, only: rolling_ball_t, observation_t, initial_state, observe, state_size
  use ellroll_linear, only: no_spin_periods, fits_at_bottom
  use ellroll_shards, only: shard_size
  use ellroll_output_start, only: check_output_target
  use ellroll_step_advice, only: step_size_advice, dt_cap_advice, record_start_advice
  use ellroll_disk_room, only: output_bytes, output_room, disk_room_advice
  use ellroll_invalid_cases, only: find_invalid_cases, refuse_invalid_cases
  use ellroll_cli, only: cli_t
  implicit none
  private

  public :: check_command

contains

  !> Exit 2 for bad input, or invalid cases where the campaign stops on them.
  subroutine check_command(cli, err)
    type(cli_t), intent(in) :: cli
    type(error_t), intent(inout) :: err
    type(run_input_t) :: inp
    logical, allocatable :: invalid(:)
    character(len=:), allocatable :: messages
    call read_input(trim(cli%paths(1)), cli%output_path, inp, err)
    if (err%failed()) return
    call check_output_target(inp%plan%file, inp%path, err)
    if (err%failed()) return
    call describe(inp, cli%opts%shard)
    call step_size_advice(inp, messages)
    if (len(messages) > 0) write (error_unit, '(a)') messages
    call dt_cap_advice(inp, messages)
    if (len(messages) > 0) write (error_unit, '(a)') messages
    call record_start_advice(inp, messages)
    if (len(messages) > 0) write (error_unit, '(a)') messages
    call disk_room_advice(inp, shard_size(inp%campaign%n_cases(), cli%opts%shard(1), cli%opts%shard(2)), messages)
    if (len(messages) > 0) write (error_unit, '(a)') messages
    call find_invalid_cases(inp, invalid, messages)
    call refuse_invalid_cases(inp, invalid, messages, err)
    if (err%failed()) return
    if (any(invalid)) call put_line(itoa(count(invalid)) // ' invalid cases will be skipped:' // messages)
    call put_line(trim(cli%paths(1)) // ': ok')
  end subroutine check_command

  !> The base case, what the campaign varies, and what a run will produce.
  subroutine describe(inp, shard)
    type(run_input_t), intent(in) :: inp
    integer, intent(in) :: shard(2)          !< --shard I/N
    type(rolling_ball_t) :: ball
    type(case_t) :: cs
    type(observation_t) :: obs
    real(wp) :: y(state_size), f(state_size), n0(3), radii(2), periods(2), free
    integer(i8) :: n_cases, i, n_local
    integer :: k
    character(len=:), allocatable :: line, room
    cs = inp%campaign%base
    ball = make_ball(cs)
    call put_line('base case (resolved input):')
    call print_values(case_record(cs))
    n0 = normal_from_contact(ball%cup, cs%param(p_x), cs%param(p_y))
    radii = principal_radii(ball%cup, n0)
    y = initial_state(ball, cs%param(p_x), cs%param(p_y), cs%param(p_omega_x:p_omega_z))
    call ball%rhs(0.0_wp, y, f)
    call observe(ball, 0.0_wp, y, f, obs)
    call put_line('derived:')
    call put_line('  z0 = ' // format_real(obs%contact(3)) // ' m')
    call put_line('  principal radii of curvature at the start = ' // &
        format_real(radii(1)) // ', ' // format_real(radii(2)) // ' m (radius ' // format_real(cs%param(p_radius)) // ' m)')
    call put_line('  spin omega . n at the start = ' // format_real(dot_product(y(4:6), n0)) // ' rad/s')
    call put_line('  energy at the start = ' // format_real(obs%energy) // ' J')
    if (cs%param(p_g) > 0) then
      periods = no_spin_periods(ball)
      if (fits_at_bottom(ball)) then
        call put_line('  small-oscillation periods at the bottom without spin (x-z, y-z) = ' // &
            format_real(periods(1)) // ', ' // format_real(periods(2)) // ' s')
      else
        call put_line('  small-oscillation periods at the bottom without spin (x-z, y-z) = ' // &
            format_real(periods(1)) // ', ' // format_real(periods(2)) // ' s (undefined: the ball does not fit ' // &
            'at the bottom, radius >= a^2/c or b^2/c)')
      end if
    end if

    n_cases = inp%campaign%n_cases()
    n_local = shard_size(n_cases, shard(1), shard(2))
    call put_line('campaign: ' // itoa(n_cases) // ' cases')
    if (shard(2) > 1) call put_line('  this shard (' // itoa(shard(1)) // '/' // &
        itoa(shard(2)) // '): ' // itoa(n_local) // ' cases')
    do k = 1, size(inp%campaign%sweeps)
      call put_line('  sweep ' // trim(params(inp%campaign%sweeps(k)%param)%name) // ': ' // &
          itoa(size(inp%campaign%sweeps(k)%values)) // ' values from ' // &
          format_real(inp%campaign%sweeps(k)%values(1)) // ' to ' // &
          format_real(inp%campaign%sweeps(k)%values(size(inp%campaign%sweeps(k)%values))))
    end do
    do k = 1, size(inp%campaign%samples)
      call put_line('  sample ' // trim(params(inp%campaign%samples(k)%param)%name) // &
          ' in [' // format_real(inp%campaign%samples(k)%low) // ', ' // &
          format_real(inp%campaign%samples(k)%high) // '], ' // &
          merge('log   ', 'linear', inp%campaign%samples(k)%log_spacing) // ' spacing')
    end do
    if (size(inp%campaign%sweeps) + size(inp%campaign%samples) > 0) then
      do i = 0, min(n_cases, 5_i8) - 1
        cs = inp%campaign%case_at(i)
        line = '  case ' // itoa(i) // ':'
        do k = 1, size(inp%campaign%sweeps)
          line = line // ' ' // trim(params(inp%campaign%sweeps(k)%param)%name) // ' = ' // &
                 format_real(get_param(cs, inp%campaign%sweeps(k)%param))
        end do
        do k = 1, size(inp%campaign%samples)
          line = line // ' ' // trim(params(inp%campaign%samples(k)%param)%name) // ' = ' // &
                 format_real(get_param(cs, inp%campaign%samples(k)%param))
        end do
        call put_line(line)
      end do
      if (n_cases > 5) call put_line('  ...')
    end if

    call put_line('output:')
    call put_line('  file = ' // inp%plan%file)
    call put_line('  steps per case = ' // itoa(nint(inp%campaign%base%t_end / &
        inp%campaign%base%param(p_dt), i8)) // ', samples = ' // itoa(inp%plan%n_samples) // ' every ' // &
        format_real(inp%plan%interval) // ' s')
    line = '  fields ='
    do k = 1, field_count
      if (inp%plan%fields(k)) line = line // ' ' // trim(field_names(k))
    end do
    call put_line(line)
    call size_text(inp%plan%case_bytes() * real(n_local, wp), line)
    call put_line('  trajectory data before compression = ' // line // ' (' // itoa(n_local) // ' cases)')
    call size_text(output_bytes(inp, n_local), line)
    free = output_room(inp)
    call size_text(max(free, 0.0_wp), room)
    if (free < 0) room = 'unknown'
    call put_line('  the output and its journal, uncompressed, about ' // line // '; free on its file system ' // room)
  end subroutine describe

  subroutine print_values(rec)
    type(named_value_t), intent(in) :: rec(:)
    integer :: k
    character(len=:), allocatable :: text
    do k = 1, size(rec)
      select case (rec(k)%kind)
      case (kind_real)
        if (rec(k)%ncomp == 1) then
          text = format_real(rec(k)%reals(1))
        else
          text = format_real(rec(k)%reals(1)) // ', ' // format_real(rec(k)%reals(2)) // ', ' // &
                 format_real(rec(k)%reals(3))
        end if
      case (kind_int)
        text = itoa(rec(k)%int)
      case default                         ! text
        text = "'" // trim(rec(k)%text) // "'"
      end select
      if (trim(rec(k)%units) /= '1') text = text // ' ' // trim(rec(k)%units)
      call put_line('  ' // trim(rec(k)%name) // ' = ' // text)
    end do
  end subroutine print_values
end module ellroll_cmd_check
