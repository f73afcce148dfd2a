!> How a campaign is split and told apart: the cases of shard I of N, and
!> the id that ties a file, its journal and its shards to one campaign
!> (what a run, a resume and a merge compare).
module ellroll_shards
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: text_hash
  use ellroll_input, only: run_input_t
  implicit none
  private

  public :: shard_slots, shard_size, campaign_id

contains

  !> Global indices of shard I of N: I, I + N, I + 2N, ... (round robin, so
  !> that every shard gets a fair share of a sweep's cheap and dear cases).
  function shard_slots(n_total, shard) result(indices)
    integer(i8), intent(in) :: n_total
    integer, intent(in) :: shard(2)
    integer(i8), allocatable :: indices(:)
    integer(i8) :: j
    ! floor division: a shard past the last case gets none (truncation gave it one)
    indices = [(int(shard(1), i8) + j * shard(2), j = 0, floor(real(n_total - shard(1) - 1, wp) / shard(2), i8))]
  end function shard_slots

  !> How many cases shard I of N has (shard_slots' size, not made).
  elemental integer(i8) function shard_size(n_total, index, count)
    integer(i8), intent(in) :: n_total
    integer, intent(in) :: index, count
    shard_size = 0
    if (index < n_total .and. count > 0) shard_size = (n_total - 1 - index) / count + 1
  end function shard_size

  !> The id of the campaign of an input. (A record file changed gives
  !> another id: its fingerprint is part of it.)
  function campaign_id(inp) result(id)
    type(run_input_t), intent(in) :: inp
    character(len=16) :: id
    id = text_hash(inp%canonical // inp%input_files)
  end function campaign_id
end module ellroll_shards
