!> What the Fortran benches share: their one argument, the number of
!> repetitions whose best time each figure is.
module bench_args
  use, intrinsic :: iso_fortran_env, only: error_unit
  implicit none
  private

  public :: repeats_argument

contains

  !> The repetitions given as the first argument, else `default`; anything
  !> but a positive whole number stops the bench with its usage.
  integer function repeats_argument(default) result(repeats)
    integer, intent(in) :: default
    character(len=64) :: arg, program
    integer :: ios
    repeats = default
    if (command_argument_count() == 0) return
    call get_command_argument(1, arg)
    read (arg, *, iostat=ios) repeats
    if (ios /= 0 .or. repeats < 1) then
      call get_command_argument(0, program)
      write (error_unit, '(a)') 'usage: ' // trim(program) // ' [repeats]   (a positive whole number, not ''' // &
          trim(arg) // ''')'
      stop 2
    end if
  end function repeats_argument
end module bench_args
