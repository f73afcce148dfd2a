!> Integrating one block of a campaign's cases, as every way of running a
!> campaign does (into a file, into memory): the block's batchable cases
!> together across SIMD lanes, one batch per method, the others one by one
!> (and a batched case whose lane result is not its own: lane_result_stands).
!> Whether cases share lanes depends on the campaign only (uses_batches),
!> never on threads, shards or resumption, so results stay bitwise the same.
module ellroll_block_run
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_cases, only: case_t, output_plan_t
  use ellroll_results, only: case_result_t
  use ellroll_campaign, only: campaign_t
  use ellroll_simulate, only: simulate_case, simulate_batch, batchable, lane_result_stands, lanes
  implicit none
  private

  public :: simulate_block, uses_batches, lanes

contains

  !> Whether a campaign runs its batchable cases in lanes: one of at least
  !> `lanes` cases (a batch costs all its lanes whether they are filled or
  !> not, so the paper's single case runs alone).
  pure logical function uses_batches(campaign)
    type(campaign_t), intent(in) :: campaign
    uses_batches = campaign%n_cases() >= lanes .and. batchable(campaign%base)
  end function uses_batches

  !> The cases of a block (at most `lanes`), into results; n_done: the
  !> cases finished, all of them unless a case failed (err).
  subroutine simulate_block(cases, use_batches, plan, results, n_done, err)
    type(case_t), intent(in) :: cases(:)
    logical, intent(in) :: use_batches
    type(output_plan_t), intent(in) :: plan
    type(case_result_t), intent(inout) :: results(:)
    integer, intent(out) :: n_done
    type(error_t), intent(inout) :: err
    type(case_result_t) :: batch_results(lanes)
    type(case_t), allocatable :: batch_cases(:)
    integer :: n, j, in_batch(lanes), n_batch, first
    logical :: waiting(lanes)
    real(wp) :: lane_time
    n = size(cases)
    waiting(:n) = [(in_lanes(cases(j)), j = 1, n)]
    do while (any(waiting(:n)))
      first = findloc(waiting(:n), .true., dim=1)
      n_batch = 0
      do j = first, n
        if (.not. waiting(j) .or. cases(j)%method /= cases(first)%method) cycle
        n_batch = n_batch + 1
        in_batch(n_batch) = j
        waiting(j) = .false.
      end do
      if (n_batch == n) then           ! the whole block: no copy of the results
        call simulate_batch(cases, plan, results(:n))
      else
        ! a named copy: gfortran 12 leaks the allocatable components of a
        ! vector-subscripted actual argument's temporary
        batch_cases = cases(in_batch(:n_batch))
        call simulate_batch(batch_cases, plan, batch_results(:n_batch))
        results(in_batch(:n_batch)) = batch_results(:n_batch)
      end if
    end do
    n_done = n
    do j = 1, n
      lane_time = 0
      if (in_lanes(cases(j))) then
        if (lane_result_stands(cases(j), results(j))) cycle
        lane_time = results(j)%wall_time        ! (the integration time counts both runs)
      end if
      call simulate_case(cases(j), plan, results(j), err)
      results(j)%wall_time = results(j)%wall_time + lane_time
      if (err%failed()) then
        n_done = j - 1
        exit
      end if
    end do
  contains
    pure logical function in_lanes(cs)
      type(case_t), intent(in) :: cs
      in_lanes = use_batches .and. batchable(cs)
    end function in_lanes
  end subroutine simulate_block
end module ellroll_block_run
