!> Record suites: one &record group per ground motion (its name, its one to
!> three files, its factor), read into the campaign as one more dimension.
module ellroll_suite_input
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp
  use ellroll_strings, only: itoa, format_real
  use ellroll_files, only: path_length
  use ellroll_cases, only: case_t
  use ellroll_campaign, only: suite_record_t, use_record
  use ellroll_excitation, only: set_record
  use ellroll_record_store, only: no_room_for_record
  use ellroll_record_file, only: load_ground_motion
  use ellroll_input_reader, only: reader_t, namelist_values_t, resolve_path
  implicit none
  private

  public :: record_spec_t, add_record_group, load_suite, record_files, note_files, changed_files

  !> A &record group as written (its files resolved against the input's folder).
  type :: record_spec_t
    integer :: group = 0
    character(len=32) :: name = ''
    real(wp) :: factor = 1
    character(len=path_length), allocatable :: files(:)  !< as resolved against the input's folder
    character(len=path_length), allocatable :: names(:)  !< as the input gives them
  end type record_spec_t

  !> Largest factor of a record (as the scale of &excitation).
  real(wp), parameter :: max_factor = 1.0e3_wp

contains

  !> A &record group's name, files and factor, checked.
  subroutine add_record_group(rd, v, gi, specs, n)
    type(reader_t), intent(inout) :: rd
    type(namelist_values_t), intent(in) :: v
    integer, intent(in) :: gi
    !> the groups so far, specs(:n); its size doubles as it fills (a copy per
    !> group would take time growing as the square of their count)
    type(record_spec_t), allocatable, intent(inout) :: specs(:)
    integer, intent(inout) :: n
    type(record_spec_t) :: spec
    type(record_spec_t), allocatable :: grown(:)
    integer :: k
    logical :: valid
    if (len_trim(v%name) == 0) then
      call rd%fail_missing(gi, 'name', "name the record, e.g. name = 'RSN953' (it is stored with each case)")
      return
    end if
    do k = 1, n
      if (specs(k)%name == v%name) then
        call rd%fail_value(gi, 'name', 'already names the &record at line ' // itoa(rd%file%groups(specs(k)%group)%line))
        return
      end if
    end do
    if (.not. record_files(rd, gi, v%record_file, spec%files)) return
    spec%names = adjustl(v%record_file(:size(spec%files)))
    ! (nested: a NaN must not meet the comparisons, which trap in the Debug build)
    valid = ieee_is_finite(v%factor)
    if (valid) valid = v%factor >= 0 .and. v%factor <= max_factor
    if (.not. valid) then
      call rd%fail_value(gi, 'factor', 'must be between 0 and ' // format_real(max_factor))
      return
    end if
    spec%group = gi
    spec%name = v%name
    spec%factor = v%factor
    if (n == size(specs)) then
      allocate (grown(max(8, 2 * n)))
      grown(:n) = specs(:n)
      call move_alloc(grown, specs)
    end if
    n = n + 1
    specs(n) = spec
  end subroutine add_record_group

  !> The files a record_file assignment of group gi names (a CSV, or one
  !> PEER .AT2 file per axis): given, none blank, resolved against the
  !> input file's folder.
  logical function record_files(rd, gi, names, paths) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: names(:)
    character(len=path_length), allocatable, intent(out) :: paths(:)
    character(len=:), allocatable :: resolved
    integer :: n, k
    ok = .false.
    n = count(len_trim(names) > 0)
    if (n == 0) then
      call rd%fail_missing(gi, 'record_file', "name the ground-acceleration file: a CSV (time, ax, ay[, az]) " // &
                           "or one PEER .AT2 file per axis, 'x.AT2', 'y.AT2'[, 'z.AT2']")
      return
    end if
    if (any(len_trim(names(:n)) == 0)) then
      call rd%fail_value(gi, 'record_file', 'an empty name among the files')
      return
    end if
    allocate (paths(n))
    do k = 1, n
      resolved = resolve_path(trim(adjustl(names(k))), rd%file%path)
      if (len(resolved) > path_length) then
        call rd%fail_value(gi, 'record_file', 'resolved against the input''s folder, a path of ' // &
                           itoa(len(resolved)) // ' characters; at most ' // itoa(path_length))
        return
      end if
      paths(k) = resolved
    end do
    ok = .true.
  end function record_files

  !> Every record of the suite read (the factor applied to its values), and
  !> the base case given the first.
  subroutine load_suite(rd, specs, base, records, files_note)
    type(reader_t), intent(inout) :: rd
    type(record_spec_t), intent(in) :: specs(:)
    type(case_t), intent(inout) :: base
    type(suite_record_t), allocatable, intent(out) :: records(:)
    character(len=:), allocatable, intent(inout) :: files_note    !< note_files' lines for each file read
    real(wp), allocatable :: times(:), values(:, :)
    character(len=:), allocatable :: reason
    character(len=40), allocatable :: fingerprints(:)
    integer :: k
    logical :: held
    allocate (records(size(specs)))
    do k = 1, size(specs)
      if (allocated(fingerprints)) deallocate (fingerprints)
      allocate (fingerprints(size(specs(k)%files)))
      call load_ground_motion(specs(k)%files, specs(k)%factor, times, values, reason, fingerprints)
      if (len(reason) > 0) then
        call rd%fail_value(specs(k)%group, 'record_file', reason)
        return
      end if
      call note_files(specs(k)%names, fingerprints, files_note)
      call set_record(records(k)%motion, times, specs(k)%factor * values, held)
      if (.not. held) then
        call rd%fail_value(specs(k)%group, 'record_file', no_room_for_record)
        return
      end if
      records(k)%name = specs(k)%name
      records(k)%factor = specs(k)%factor
    end do
    if (size(records) > 0) call use_record(base, records(1))
  end subroutine load_suite

  !> A line 'NAME: FINGERPRINT' per file read (its name as the input gives
  !> it), after the note's lines so far: what decides, beside the input's
  !> text, whether a resume or a merge meets the same campaign.
  pure subroutine note_files(names, fingerprints, note)
    character(len=*), intent(in) :: names(:), fingerprints(:)
    character(len=:), allocatable, intent(inout) :: note
    integer :: k
    if (.not. allocated(note)) note = ''
    do k = 1, size(fingerprints)
      note = note // trim(names(k)) // ': ' // trim(fingerprints(k)) // achar(10)
    end do
  end subroutine note_files

  !> The names of the files whose lines of two notes of the input's files
  !> differ ('record file X', 'record files X, Y').
  pure subroutine changed_files(before, now, names)
    character(len=*), intent(in) :: before, now
    character(len=:), allocatable, intent(out) :: names
    integer :: first, last, n, cut
    names = ''
    n = 0
    first = 1
    do while (first <= len(now))
      last = index(now(first:), achar(10)) + first - 1
      if (last < first) last = len(now) + 1
      if (index(achar(10) // before // achar(10), achar(10) // now(first:last - 1) // achar(10)) == 0) then
        if (n > 0) names = names // ', '
        ! (the name before the line's last ': ': the fingerprint holds none, a name may)
        cut = index(now(first:last - 1), ': ', back=.true.)
        if (cut == 0) cut = last - first + 1
        names = names // now(first:first + cut - 2)
        n = n + 1
      end if
      first = last + 1
    end do
    if (n == 0) names = 'the list of record files'
    names = 'record file' // trim(merge('s', ' ', n > 1)) // ' ' // names
  end subroutine changed_files
end module ellroll_suite_input
