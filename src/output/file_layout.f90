!> What the output's layout is made of, apart from HDF5: the names, units
!> and long names of the datasets that are not rows of a record (the
!> dimension scales, the case index, the status, the checksum), the status's flags, the
!> file's title, and a case's row of the /case and /summary tables. The HDF5
!> writer and the in-memory results of the C interface both lay out from
!> here, so that their names cannot drift apart.
module ellroll_file_layout
  use ellroll_kinds, only: wp, i8
  use ellroll_records, only: named_value_t, int_value
  use ellroll_status, only: status_count, status_name
  use ellroll_cases, only: case_t, case_record
  use ellroll_results, only: case_result_t, summary_record, figure_values
  use ellroll_limit_states, only: exceeded_flag
  use ellroll_figures, only: figures
  use ellroll_strings, only: format_real
  implicit none
  private

  public :: time_entry, xyz_entry, mode_entry, case_entry, status_entry, checksum_entry, file_title, file_references
  public :: table_row, file_row, limit_state_row, status_flag_meanings

  !> the shared dimension scales (at the root), each group's case index,
  !> /summary/status and /summary/checksum (ellroll_case_checksum)
  type(named_value_t), parameter :: time_entry = named_value_t('time', 's', 'output times')
  type(named_value_t), parameter :: xyz_entry = named_value_t('xyz', '1', 'vector component')
  type(named_value_t), parameter :: mode_entry = named_value_t('mode', '1', 'oscillation mode (the longer period first)')
  type(named_value_t), parameter :: case_entry = named_value_t('case', '1', 'global case index')
  type(named_value_t), parameter :: status_entry = named_value_t('status', '1', 'how the case ended')
  type(named_value_t), parameter :: checksum_entry = named_value_t('checksum', '1', &
      'CRC-32C of the case''s stored results (-1: not written, status pending)')

  character(len=*), parameter :: file_title = 'ellroll: a heavy ball rolling without slip in a triaxial ' // &
      'ellipsoidal cup'
  character(len=*), parameter :: file_references = 'V. P. Legeza (1990), Derivation of the equations of ' // &
      'motion of a heavy ball in the cavity of a triaxial ellipsoid and their numerical analysis (in Russian)'

contains

  !> A case's row of the case and summary tables: its inputs (/case), its
  !> summary, then its status (/summary).
  function table_row(cs, res) result(row)
    type(case_t), intent(in) :: cs
    type(case_result_t), intent(in) :: res
    type(named_value_t), allocatable :: row(:)
    row = [case_record(cs), summary_record(res), int_value('status', '', '', int(res%status, i8))]
  end function table_row

  !> A case's row of the output file: table_row, its checksum (/summary),
  !> then its /limit_state flags (the C interface's results hold table_row
  !> alone).
  function file_row(cs, res, checksum) result(row)
    type(case_t), intent(in) :: cs
    type(case_result_t), intent(in) :: res
    integer(i8), intent(in) :: checksum       !< ellroll_case_checksum's
    type(named_value_t), allocatable :: row(:)
    row = [table_row(cs, res), int_value(trim(checksum_entry%name), '', '', checksum), limit_state_row(cs, res)]
  end function file_row

  !> Whether the case exceeded each of its limit states (1), not (0), or
  !> its figure is undefined for it (-1).
  function limit_state_row(cs, res) result(row)
    type(case_t), intent(in) :: cs
    type(case_result_t), intent(in) :: res
    type(named_value_t), allocatable :: row(:)
    integer :: k, n
    real(wp), allocatable :: value(:)
    n = 0
    if (allocated(cs%limit_states)) n = size(cs%limit_states)
    allocate (row(n))
    do k = 1, n
      associate (state => cs%limit_states(k))
        value = figure_values(res, state%figure)
        row(k) = int_value(trim(state%name), '1', '1: ' // trim(figures(state%figure)%name) // ' > ' // &
                           format_real(state%capacity) // ' ' // trim(figures(state%figure)%unit) // &
                           ', or a model limit; 0: not exceeded or no outcome (see status); -1: ' // &
                           trim(figures(state%figure)%name) // ' undefined (NaN)', &
                           exceeded_flag(state, res%status, value(1)))
      end associate
    end do
  end function limit_state_row

  !> CF's flag_meanings of the status: its names, in the order of its values 0, 1, ...
  subroutine status_flag_meanings(meanings)
    character(len=:), allocatable, intent(out) :: meanings
    integer :: s
    meanings = status_name(0)
    do s = 1, status_count - 1
      meanings = meanings // ' ' // status_name(s)
    end do
  end subroutine status_flag_meanings
end module ellroll_file_layout
