!> Process ranks for a build without MPI: one process, rank 0 of 1.
module ellroll_ranks
  implicit none
  private
  public :: ranks_start, ranks_all_ok, ranks_stop

contains

  subroutine ranks_start(rank, n_ranks)
    integer, intent(out) :: rank, n_ranks
    rank = 0
    n_ranks = 1
  end subroutine ranks_start

  logical function ranks_all_ok(ok)
    logical, intent(in) :: ok
    ranks_all_ok = ok
  end function ranks_all_ok

  subroutine ranks_stop()
  end subroutine ranks_stop
end module ellroll_ranks
