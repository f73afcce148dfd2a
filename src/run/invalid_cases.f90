!> The cases of a campaign the model cannot start (checked before any
!> runs): found, described, and refused where the campaign says so
!> (&campaign invalid = 'stop', the default) or skipped.
module ellroll_invalid_cases
  use ellroll_kinds, only: i8
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_strings, only: itoa
  use ellroll_cases, only: case_t, check_case, case_problem
  use ellroll_campaign, only: invalid_stop
  use ellroll_input, only: run_input_t, describe_invalid
  implicit none
  private

  public :: find_invalid_cases, refuse_invalid_cases

contains

  !> Every invalid case of the campaign, with the message for the first few.
  subroutine find_invalid_cases(inp, invalid, messages)
    type(run_input_t), intent(in) :: inp
    logical, allocatable, intent(out) :: invalid(:)
    character(len=:), allocatable, intent(out) :: messages
    integer(i8) :: i, n_bad
    integer :: param
    character(len=:), allocatable :: reason, description
    type(case_t) :: cs
    allocate (invalid(0:inp%campaign%n_cases() - 1))
    ! every case checked (in parallel: a sweep may hold millions; a few
    ! cases on this thread alone), then the messages of the first five in
    ! case order
    !$omp parallel do schedule(dynamic, 256) if (inp%campaign%n_cases() > 256)
    do i = 0, inp%campaign%n_cases() - 1
      invalid(i) = case_is_invalid(i)
    end do
    !$omp end parallel do
    messages = ''
    n_bad = 0
    do i = 0, inp%campaign%n_cases() - 1
      if (.not. invalid(i)) cycle
      n_bad = n_bad + 1
      if (n_bad > 5) cycle
      cs = inp%campaign%case_at(i)
      call check_case(cs, inp%plan%interval, param, reason)
      call describe_invalid(inp, cs, param, reason, description)
      messages = messages // achar(10) // '  ' // description
    end do
    if (n_bad > 5) messages = messages // achar(10) // '  ... and ' // itoa(n_bad - 5) // ' more'
  contains
    logical function case_is_invalid(index)
      integer(i8), intent(in) :: index
      case_is_invalid = case_problem(inp%campaign%case_at(index), inp%plan%interval) /= 0
    end function case_is_invalid
  end subroutine find_invalid_cases

  !> err (bad input) when some cases are invalid and the campaign stops on
  !> them; `messages` from find_invalid_cases.
  subroutine refuse_invalid_cases(inp, invalid, messages, err)
    type(run_input_t), intent(in) :: inp
    logical, intent(in) :: invalid(:)
    character(len=*), intent(in) :: messages
    type(error_t), intent(inout) :: err
    if (.not. any(invalid) .or. inp%campaign%invalid /= invalid_stop) return
    call set_error(err, err_input, itoa(count(invalid)) // ' of ' // itoa(size(invalid)) // &
        ' cases are invalid (set &campaign invalid = ''skip'' to run the others):' // messages)
  end subroutine refuse_invalid_cases
end module ellroll_invalid_cases
