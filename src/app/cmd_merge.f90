!> `ellroll merge OUT.h5 SHARD.h5...`: the shard files of a campaign joined
!> into one output, equal to the same run unsharded.
module ellroll_cmd_merge
  use ellroll_errors, only: error_t
  use ellroll_merge, only: merge_shards
  use ellroll_cli, only: cli_t, provenance
  implicit none
  private

  public :: merge_command

contains

  subroutine merge_command(cli, err)
    type(cli_t), intent(in) :: cli
    type(error_t), intent(inout) :: err
    ! (merge_shards takes the input file and its text from the shards)
    call merge_shards(trim(cli%paths(1)), cli%paths(2:), cli%opts%overwrite, provenance(trim(cli%paths(1)), ''), err)
  end subroutine merge_command
end module ellroll_cmd_merge
