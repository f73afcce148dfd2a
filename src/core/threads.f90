!> How many threads a parallel loop of the run takes.
module ellroll_threads
  !$ use omp_lib, only: omp_get_max_threads, omp_get_num_procs
  use ellroll_kinds, only: i8
  implicit none
  private

  public :: team_size, threads_per_processor

  !> Threads at most per processor: more only wait on each other, and tens of
  !> thousands exhaust the memory of their stacks (the OpenMP runtime then
  !> ends the process).
  integer, parameter :: threads_per_processor = 16

contains

  !> The team of a loop with `work` units of work (blocks, cases; >= 1) for
  !> `requested` threads (0: OMP_NUM_THREADS or all cores): no more than the
  !> units, nor than threads_per_processor per processor.
  integer function team_size(requested, work) result(n)
    integer, intent(in) :: requested
    integer(i8), intent(in) :: work
    integer :: processors
    n = 1
    processors = 1
    !$ n = omp_get_max_threads()
    !$ processors = omp_get_num_procs()
    if (requested > 0) n = requested
    n = int(max(1_i8, min(int(n, i8), work, int(threads_per_processor, i8) * max(1, processors))))
  end function team_size
end module ellroll_threads
