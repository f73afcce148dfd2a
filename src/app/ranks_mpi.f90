!> Process ranks of an MPI build (-DELLROLL_MPI=ON): each rank runs one
!> shard of the campaign; they meet only to agree that all succeeded.
module ellroll_ranks
  use mpi_f08, only: MPI_Init, MPI_Finalize, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, &
      MPI_COMM_WORLD, MPI_LOGICAL, MPI_LAND, MPI_Initialized
  implicit none
  private
  public :: ranks_start, ranks_all_ok, ranks_stop

contains

  subroutine ranks_start(rank, n_ranks)
    integer, intent(out) :: rank, n_ranks
    logical :: started
    call MPI_Initialized(started)
    if (.not. started) call MPI_Init()
    call MPI_Comm_rank(MPI_COMM_WORLD, rank)
    call MPI_Comm_size(MPI_COMM_WORLD, n_ranks)
  end subroutine ranks_start

  !> True on every rank when ok is true on every rank (a barrier too).
  logical function ranks_all_ok(ok)
    logical, intent(in) :: ok
    call MPI_Allreduce(ok, ranks_all_ok, 1, MPI_LOGICAL, MPI_LAND, MPI_COMM_WORLD)
  end function ranks_all_ok

  subroutine ranks_stop()
    call MPI_Finalize()
  end subroutine ranks_stop
end module ellroll_ranks
