!> The checksum of a case's stored results (/summary/checksum): the CRC-32C
!> (ellroll_checksum) of what a reader gets back for the case from an output
!> file (ellroll_hdf5_reader's read_case_result, with the case's switches
!> of regime from /switches), so that a file read back as input (a shard
!> to merge) is checked case by case. It folds, in this order:
!> - the stored fields' trajectories, field after field in the order of
!>   field_names, each in array element order (NaN for a case never
!>   integrated, as the file holds);
!> - the status and the summary's figures, wall_time aside, one 64-bit word
!>   per count and per real component;
!> - the number of switches of regime, their times and their kinds.
!> wall_time differs from one run of a case to the next; without it the
!> checksum depends on the case's results alone, the same on any thread
!> count, shard split or resume.
module ellroll_case_checksum
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: named_value_t, kind_int
  use ellroll_cases, only: field_count, field_ncomp
  use ellroll_figures, only: fig_wall_time
  use ellroll_results, only: case_result_t, summary_record
  use ellroll_checksum, only: checksum_start, fold_reals, fold_words
  implicit none
  private

  public :: case_checksum

contains

  !> The checksum of res as a file that stores `fields` (n_samples samples
  !> each) holds it: from 0 to 2^32 - 1.
  pure integer(i8) function case_checksum(res, fields, n_samples) result(sum)
    type(case_result_t), intent(in) :: res
    logical, intent(in) :: fields(field_count)      !< the stored fields
    integer(i8), intent(in) :: n_samples
    type(named_value_t), allocatable :: rec(:)
    real(wp), allocatable :: never_integrated(:)
    integer(i8), allocatable :: words(:)
    integer :: f, k, n, at
    sum = checksum_start
    do f = 1, field_count
      if (.not. fields(f)) cycle
      if (allocated(res%fields(f)%values)) then
        call fold_reals(sum, res%fields(f)%values, size(res%fields(f)%values, kind=i8))
      else
        if (.not. allocated(never_integrated)) &
          allocate (never_integrated(maxval(field_ncomp) * n_samples), source=ieee_value(0.0_wp, ieee_quiet_nan))
        call fold_reals(sum, never_integrated, field_ncomp(f) * n_samples)
      end if
    end do
    rec = summary_record(res)
    n = res%n_switches
    allocate (words(1 + 3 * size(rec) + 1 + 2 * n))
    words(1) = int(res%status, i8)
    at = 1
    do k = 1, size(rec)
      if (k == fig_wall_time) cycle
      if (rec(k)%kind == kind_int) then
        words(at + 1) = rec(k)%int
        at = at + 1
      else
        words(at + 1:at + rec(k)%ncomp) = transfer(rec(k)%reals(:rec(k)%ncomp), 0_i8, rec(k)%ncomp)
        at = at + rec(k)%ncomp
      end if
    end do
    words(at + 1) = int(n, i8)
    if (n > 0) then
      words(at + 2:at + 1 + n) = transfer(res%switch_time(:n), 0_i8, n)
      words(at + 2 + n:at + 1 + 2 * n) = int(res%switch_kind(:n), i8)
    end if
    call fold_words(sum, words(:at + 1 + 2 * n))
  end function case_checksum
end module ellroll_case_checksum
