!> The journal of a run: a binary file beside the output that records each
!> finished case (status and summary) as soon as it is done, written to the
!> operating system. A run killed at any moment loses nothing that is in the
!> journal; `--resume` reads the valid records back.
!>
!> Trajectories written in place in the output file (uncompressed, the
!> default) stay there: a record holds their checksum, and a resume reads
!> them back from the killed run's file (ellroll_trajectory_store), keeping
!> the case only if they match it. A thread writes its cases' trajectories
!> before their records, so a record's trajectories are in the file unless
!> the system lost writes (a power cut): then they fail the check and the
!> case runs again. Compressed trajectories go through HDF5, whose file a
!> kill may damage, so their records hold them whole.
!>
!> A record is a part of one size (status, summary, trajectories held
!> whole) and the case's switches of regime (their count, times and kinds:
!> none but for a case that slid). Threads reserve places one after the
!> other (under a lock, a few nanoseconds) and write their records there at
!> the same time (pwrite). A kill may leave a place unwritten or a record
!> torn; it fails its marker or checksum and is skipped (the next record is
!> found by its marker), and its case is run again.
module ellroll_journal
  use, intrinsic :: iso_c_binding, only: c_loc
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input, err_output
  use ellroll_records, only: named_value_t, kind_int
  use ellroll_cases, only: field_count, field_ncomp
  use ellroll_results, only: case_result_t, summary_record, set_summary_value, add_switch
  use ellroll_checksum, only: checksum, checksum_start, fold_reals
  use ellroll_system, only: open_for_writing, open_for_reading, write_pieces_at, read_at, close_descriptor, &
      system_error_text
  use ellroll_files, only: create_new_file, file_size, one_name
  use ellroll_suite_input, only: changed_files
  implicit none
  private

  public :: journal_t, journal_header_t, journal_is_torn

  character(len=8), parameter :: magic = 'ELLROLL8'
  integer(i8), parameter :: record_marker = 7310312871522813004_i8
  !> The header: magic, then these words (the campaign id's 64 bytes, the
  !> writer's 128 (the program, its version and build), n_slots,
  !> n_samples, the shard's two numbers, a flag per field for the stored and
  !> for the in-place fields, the note's length in words), then their
  !> checksum; then the note of the input's files (their fingerprints), blank
  !> padded to whole words, and its checksum; then the records.
  integer, parameter :: id_words = 8, writer_words = 16
  integer, parameter :: header_words = id_words + writer_words + 4 + 2 * field_count + 1
  integer, parameter :: header_bytes = 8 + 8 * (header_words + 1)
  integer, parameter :: eexist = 17            !< (errno: a file is there)

  !> What a journal must agree on with the run that resumes it.
  type :: journal_header_t
    character(len=64) :: campaign_id = ''          !< the campaign's id, then the id of the input's text alone
    !> the program that wrote it: 'ellroll VERSION (BUILD build)'; a resume
    !> by another would mix the results of two programs in one file
    character(len=8 * writer_words) :: writer = ''
    character(len=:), allocatable :: input_files   !< the input's files and their fingerprints, a line each
    integer(i8) :: n_slots = 0
    integer(i8) :: n_samples = 0
    integer :: shard(2) = [0, 1]
    logical :: fields(field_count) = .false.       !< the stored fields
    logical :: in_place(field_count) = .false.     !< those written in place in the output file, not here
  end type journal_header_t

  type :: journal_t
    integer :: fd = -1
    character(len=:), allocatable :: path
    type(journal_header_t) :: header
    integer(i8) :: record_words = 0
    integer(i8) :: next_position = 0     !< byte position (1-based) of the next record
    integer(i8) :: records_start = 0     !< that of the first record
    integer(i8) :: n_damaged = 0          !< records read back that failed their checksum
  contains
    procedure :: create
    procedure :: open_existing
    procedure :: index_records
    procedure :: record_at
    procedure :: record => encode_record
    procedure :: record_size
    procedure :: fingerprint
    procedure :: reserve
    procedure :: write_records
    procedure :: holds_records
    procedure :: close => close_journal
  end type journal_t

contains

  !> Create the journal (where nothing is: the caller has removed a stale
  !> one) and write its header.
  subroutine create(self, path, header, err)
    class(journal_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(journal_header_t), intent(in) :: header
    type(error_t), intent(inout) :: err
    integer(i8), target :: start(header_bytes / 8)
    integer(i8), allocatable, target :: note(:)
    character(len=8), target :: magic_text
    integer :: code
    self%path = path
    self%header = header
    self%record_words = words_per_record(header)
    self%fd = create_new_file(path)
    if (self%fd < 0) then
      call set_error(err, err_output, path // ': cannot create the journal: ' // system_error_text(-self%fd))
      return
    end if
    note = note_words(header%input_files)
    magic_text = magic
    start(1) = transfer(magic_text, 0_i8)
    start(2:header_words + 1) = encode_header(header, size(note, kind=i8) - 1)
    start(header_words + 2) = checksum(start(2:header_words + 1))
    code = write_pieces_at(self%fd, [c_loc(start), c_loc(note)], [int(header_bytes, i8), 8 * size(note, kind=i8)], &
                           0_i8)
    if (code /= 0) then
      call set_error(err, err_output, path // ': cannot write the journal: ' // system_error_text(code))
      return
    end if
    self%next_position = header_bytes + 8 * size(note) + 1
    self%records_start = self%next_position
  end subroutine create

  !> A note as whole words, blank-padded, and their checksum after them.
  pure function note_words(note) result(words)
    character(len=*), intent(in) :: note
    integer(i8), allocatable :: words(:)
    character(len=8 * ((len(note) + 7) / 8)) :: padded
    padded = note
    allocate (words(len(padded) / 8 + 1))
    if (len(padded) > 0) words(:size(words) - 1) = transfer(padded, 0_i8, size(words) - 1)
    words(size(words)) = checksum(words(:size(words) - 1))
  end function note_words

  !> Whether the journal at path ends before its header does: the run was
  !> killed before it had written the header, so nothing it did is kept.
  logical function journal_is_torn(path)
    character(len=*), intent(in) :: path
    integer(i8), target :: start(header_bytes / 8)
    integer(i8) :: bytes
    integer :: fd, code
    bytes = file_size(path)
    journal_is_torn = bytes >= 0 .and. bytes < header_bytes
    if (journal_is_torn .or. bytes < 0) return
    ! the header whole, but not the note of the input's files after it
    fd = open_for_reading(path)
    if (fd < 0) return
    code = read_at(fd, c_loc(start), int(header_bytes, i8), 0_i8)
    if (code == 0 .and. start(header_words + 2) == checksum(start(2:header_words + 1))) &
      journal_is_torn = bytes < header_bytes + 8 * (start(header_words + 1) + 1)
    code = close_descriptor(fd)
  end function journal_is_torn

  function encode_header(header, n_note) result(words)
    type(journal_header_t), intent(in) :: header
    integer(i8), intent(in) :: n_note          !< words of the note of the input's files
    integer(i8) :: words(header_words)
    integer, parameter :: w = id_words + writer_words
    words(:id_words) = transfer(header%campaign_id, 0_i8, id_words)
    words(id_words + 1:w) = transfer(header%writer, 0_i8, writer_words)
    words(w + 1:w + 4) = [header%n_slots, header%n_samples, int(header%shard, i8)]
    words(w + 5:header_words - 1) = [merge(1_i8, 0_i8, header%fields), merge(1_i8, 0_i8, header%in_place)]
    words(header_words) = n_note
  end function encode_header

  function decode_header(words) result(header)
    integer(i8), intent(in) :: words(header_words)
    type(journal_header_t) :: header
    integer, parameter :: w = id_words + writer_words
    header%campaign_id = transfer(words(:id_words), header%campaign_id)
    header%writer = transfer(words(id_words + 1:w), header%writer)
    header%n_slots = words(w + 1)
    header%n_samples = words(w + 2)
    header%shard = int(words(w + 3:w + 4))
    header%fields = words(w + 5:w + 4 + field_count) == 1
    header%in_place = words(w + 5 + field_count:header_words - 1) == 1
  end function decode_header

  !> Whether a read of the journal at path failed in the system (code > 0:
  !> its errno; -1 is a short read, 0 none): err says so, and that the
  !> journal is left as it is for a resume once the disk reads (its cases are
  !> not judged on a read that failed).
  logical function unreadable(path, code, err)
    character(len=*), intent(in) :: path
    integer, intent(in) :: code
    type(error_t), intent(inout) :: err
    unreadable = code > 0
    if (unreadable) call set_error(err, err_output, path // ': cannot read it: ' // system_error_text(code) // &
        '; the journal is left as it is: resume again once the disk reads it')
  end function unreadable

  !> Open a journal to resume it; refuse one written for another campaign.
  subroutine open_existing(self, path, expected, err)
    class(journal_t), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(journal_header_t), intent(in) :: expected
    type(error_t), intent(inout) :: err
    integer(i8), target :: start(header_bytes / 8)
    character(len=8) :: found_magic
    type(journal_header_t) :: found
    integer :: code, shared
    self%path = path
    self%fd = open_for_writing(path)
    if (self%fd < 0) then
      call set_error(err, err_output, path // ': cannot open the journal: ' // system_error_text(-self%fd))
      return
    end if
    code = read_at(self%fd, c_loc(start), 8_i8, 0_i8)
    if (unreadable(path, code, err)) return
    found_magic = transfer(start(1), found_magic)
    if (code == 0 .and. found_magic(:7) == magic(:7) .and. found_magic /= magic) then
      call set_error(err, err_input, path // ': this run was started by another version of ellroll (journal ' // &
          'format ' // found_magic(8:) // ', not ' // magic(8:) // '); this is ' // trim(expected%writer) // &
          ', and a resume would mix the results of two programs: resume it with the ellroll that started it, ' // &
          'or start over with --overwrite')
      return
    end if
    if (code == 0) code = read_at(self%fd, c_loc(start), int(header_bytes, i8), 0_i8)
    if (unreadable(path, code, err)) return
    if (code /= 0 .or. found_magic /= magic) then
      call set_error(err, err_output, path // ': not a journal of this version of ellroll; start over ' // &
                     'with --overwrite')
      return
    end if
    if (start(header_words + 2) /= checksum(start(2:header_words + 1))) then
      call set_error(err, err_output, path // ': the journal''s header is damaged (its checksum does not ' // &
                     'match), so none of its cases can be trusted; start over with --overwrite')
      return
    end if
    found = decode_header(start(2:header_words + 1))
    call read_note(self%fd, start(header_words + 1), found%input_files, code)
    if (unreadable(path, code, err)) return
    if (code /= 0) then
      call set_error(err, err_output, path // ': the journal''s note of the input''s files is damaged, so none ' // &
                     'of its cases can be trusted; start over with --overwrite')
      return
    end if
    if (found%writer /= expected%writer) then
      call set_error(err, err_input, path // ': this run was started by ' // trim(found%writer) // '; this is ' // &
          trim(expected%writer) // ', and a resume would mix the results of two programs: resume it with the ' // &
          'ellroll that started it, or start over with --overwrite')
      return
    end if
    if (found%campaign_id /= expected%campaign_id) then
      call explain_other_campaign(path, found, expected, err)
      return
    end if
    if (found%n_slots /= expected%n_slots .or. found%n_samples /= expected%n_samples .or. &
        any(found%shard /= expected%shard) .or. any(found%fields .neqv. expected%fields) .or. &
        any(found%in_place .neqv. expected%in_place)) then
      call set_error(err, err_input, path // ': this run was started with other options (shard, output ' // &
          'or case count); resume it with the same command, or start over with --overwrite')
      return
    end if
    ! (a backup made with ln or cp -al keeps its journal as it is)
    code = one_name(self%fd, path, path // '.new')
    if (code == -eexist) then
      call set_error(err, err_output, path // ': it has another name (a backup made with ln or cp -al?), ' // &
          'and its copy for this resume to write to cannot be made: ' // path // '.new is there and is not ' // &
          'a copy of it; move that file away')
      return
    else if (code < 0) then
      call set_error(err, err_output, path // ': it has another name (a backup made with ln or cp -al?), ' // &
          'and its copy for this resume to write to cannot be made at ' // path // '.new: ' // &
          system_error_text(-code))
      return
    end if
    if (code /= self%fd) then
      shared = self%fd
      self%fd = code
      code = close_descriptor(shared)
      if (code /= 0) then
        call set_error(err, err_output, path // ': cannot close the journal''s other name: ' // system_error_text(code))
        return
      end if
    end if
    self%header = found
    self%record_words = words_per_record(found)
    self%next_position = header_bytes + 8 * (start(header_words + 1) + 1) + 1
    self%records_start = self%next_position
  end subroutine open_existing

  !> The note of n words (and its checksum) after the header; code /= 0 when
  !> it cannot be read or fails its checksum.
  subroutine read_note(fd, n, note, code)
    integer, intent(in) :: fd
    integer(i8), intent(in) :: n
    character(len=:), allocatable, intent(out) :: note
    integer, intent(out) :: code
    integer(i8), allocatable, target :: words(:)
    note = ''
    code = -1
    if (n < 0 .or. n > 2_i8**24) return
    allocate (words(n + 1))
    code = read_at(fd, c_loc(words), 8 * (n + 1), int(header_bytes, i8))
    if (code /= 0) return
    if (words(n + 1) /= checksum(words(:n))) then
      code = -1
      return
    end if
    note = repeat(' ', 8 * int(n))
    if (n > 0) note = transfer(words(:n), note)
    note = trim(note)
  end subroutine read_note

  !> Why a journal is of another campaign: the input's text differs, or
  !> (the text the same) a file it reads has changed since the run began.
  subroutine explain_other_campaign(path, found, expected, err)
    character(len=*), intent(in) :: path
    type(journal_header_t), intent(in) :: found, expected
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: changed
    if (found%campaign_id(17:32) /= expected%campaign_id(17:32)) then
      call set_error(err, err_input, path // ': the input differs from the one this run was started with; ' // &
          'resume with the same input, or start over with --overwrite')
      return
    end if
    call changed_files(found%input_files, expected%input_files, changed)
    call set_error(err, err_input, path // ': ' // changed // ' changed since this run began (its size or ' // &
        'contents differ); resume with the file as it was, or start over with --overwrite')
  end subroutine explain_other_campaign


  !> Where each slot's valid record lies (places(slot), -1 for none), to
  !> read them back in slot order with record_at; the journal's records are
  !> in the order the cases finished. Places never written and damaged
  !> records (counted in n_damaged: their cases run again) are skipped; a
  !> torn last record ends the journal, and the next record reserved goes
  !> in its place. Of two records of one slot the first counts.
  subroutine index_records(self, places)
    class(journal_t), intent(inout) :: self
    integer(i8), intent(out) :: places(0:)
    integer(i8), allocatable :: words(:)
    integer(i8) :: bytes, start
    logical :: found, written, moved
    places = -1
    bytes = file_size(self%path)
    do
      call read_record(self, self%next_position, bytes, words, found, written)
      if (found) then
        if (places(words(2)) < 0) places(words(2)) = self%next_position
        self%next_position = self%next_position + 8 * size(words, kind=i8)
        cycle
      end if
      ! the next record, if any, is found by its marker; none: the next
      ! record reserved goes here
      start = self%next_position
      moved = next_marker(self, bytes)
      ! damaged: a stretch counts as the whole records of a case that did
      ! not slide it could hold, at least one (a place reserved but never
      ! written reads as zeros)
      if (written) self%n_damaged = self%n_damaged + &
          max(1_i8, (merge(self%next_position, bytes + 1, moved) - start) / (8 * (self%record_words + 2)))
      if (.not. moved) exit
    end do
  end subroutine index_records

  !> The valid record at `position` (found), whole with its checksum in
  !> `words`; `written`: some word there is not zero.
  subroutine read_record(self, position, bytes, words, found, written)
    type(journal_t), intent(in) :: self
    integer(i8), intent(in) :: position, bytes     !< the record's place (1-based), the journal's size
    integer(i8), allocatable, target, intent(out) :: words(:)
    logical, intent(out) :: found, written
    integer(i8), allocatable, target :: head(:)
    integer(i8) :: n_switches, n_words
    found = .false.
    written = .false.
    allocate (head(self%record_words + 1))
    if (read_at(self%fd, c_loc(head), 8 * size(head, kind=i8), position - 1) /= 0) then
      if (position <= bytes) written = .true.      ! a torn record at the journal's end
      return
    end if
    written = any(head /= 0)
    n_switches = head(size(head))
    if (head(1) /= record_marker .or. n_switches < 0 .or. &
        n_switches > (bytes - position + 1) / 16) return
    n_words = self%record_words + 2 + 2 * n_switches
    allocate (words(n_words))
    if (read_at(self%fd, c_loc(words), 8 * n_words, position - 1) /= 0) return
    found = is_valid(self, words)
  end subroutine read_record

  !> Move next_position to the next word after it that is a record's
  !> marker; false (next_position unchanged) where none is.
  logical function next_marker(self, bytes) result(moved)
    type(journal_t), intent(inout) :: self
    integer(i8), intent(in) :: bytes
    integer(i8), parameter :: chunk = 4096
    integer(i8), target :: words(chunk)
    integer(i8) :: at, n, k
    moved = .false.
    at = self%next_position + 8
    do while (at + 7 <= bytes)
      n = min(chunk, (bytes - at + 1) / 8)
      if (read_at(self%fd, c_loc(words), 8 * n, at - 1) /= 0) return
      k = findloc(words(:n), record_marker, dim=1)
      if (k > 0) then
        self%next_position = at + 8 * (k - 1)
        moved = .true.
        return
      end if
      at = at + 8 * n
    end do
  end function next_marker

  !> The record at a place from index_records (found: it reads back valid
  !> still). The trajectories written in place are not in res: `in_place`
  !> is their fingerprint, to compare with that of the ones read back.
  subroutine record_at(self, place, res, in_place, found)
    class(journal_t), intent(in) :: self
    integer(i8), intent(in) :: place
    type(case_result_t), intent(out) :: res
    integer(i8), intent(out) :: in_place
    logical, intent(out) :: found
    integer(i8), allocatable :: words(:)
    integer(i8) :: slot
    logical :: written
    call read_record(self, place, file_size(self%path), words, found, written)
    if (found) call unpack_record(self%header, words, slot, res, in_place)
  end subroutine record_at

  logical function is_valid(self, words)
    type(journal_t), intent(in) :: self
    integer(i8), intent(in) :: words(:)      !< a record and its checksum
    is_valid = .false.
    if (words(1) /= record_marker .or. words(size(words)) /= checksum(words(:size(words) - 1))) return
    is_valid = words(2) >= 0 .and. words(2) < self%header%n_slots
  end function is_valid

  !> A case's record, checksum included: made by the thread that integrated
  !> the case, which also writes it (write_records).
  function encode_record(self, slot, res) result(words)
    class(journal_t), intent(in) :: self
    integer(i8), intent(in) :: slot
    type(case_result_t), intent(in) :: res
    integer(i8), allocatable :: words(:)
    integer(i8) :: n, at
    allocate (words(self%record_size(res)))
    call pack_record(self%header, slot, res, self%fingerprint(res), words(:self%record_words))
    n = res%n_switches
    at = self%record_words + 1
    words(at) = n
    if (n > 0) then
      words(at + 1:at + n) = transfer(res%switch_time(:n), 0_i8, n)
      words(at + n + 1:at + 2 * n) = int(res%switch_kind(:n), i8)
    end if
    words(size(words)) = checksum(words(:size(words) - 1))
  end function encode_record

  !> The words of res's record (encode_record), its checksum included.
  pure integer(i8) function record_size(self, res)
    class(journal_t), intent(in) :: self
    type(case_result_t), intent(in) :: res
    record_size = self%record_words + 2 + 2 * int(res%n_switches, i8)
  end function record_size

  !> A checksum of the case's trajectories written in place, not in its record.
  pure integer(i8) function fingerprint(self, res)
    class(journal_t), intent(in) :: self
    type(case_result_t), intent(in) :: res
    integer :: f
    fingerprint = checksum_start
    do f = 1, field_count
      if (.not. self%header%in_place(f)) cycle
      if (allocated(res%fields(f)%values)) &
        call fold_reals(fingerprint, res%fields(f)%values, size(res%fields(f)%values, kind=i8))
    end do
  end function fingerprint

  !> The place (a byte offset from 0) of the next n_words words of records
  !> made by encode_record. One thread at a time: the caller's lock.
  integer(i8) function reserve(self, n_words) result(offset)
    class(journal_t), intent(inout) :: self
    integer(i8), intent(in) :: n_words
    offset = self%next_position - 1
    self%next_position = self%next_position + 8 * n_words
  end function reserve

  !> Write records made by encode_record at a place from reserve. Threads
  !> may write their places at the same time.
  subroutine write_records(self, offset, words, err)
    class(journal_t), intent(in) :: self
    integer(i8), intent(in) :: offset
    integer(i8), intent(in), target, contiguous :: words(:)
    type(error_t), intent(inout) :: err
    integer :: code
    code = write_pieces_at(self%fd, [c_loc(words)], [storage_size(words, kind=i8) / 8 * size(words, kind=i8)], offset)
    if (code /= 0) call set_error(err, err_output, self%path // ': cannot write the journal: ' // &
                                  system_error_text(code))
  end subroutine write_records

  !> Whether the journal holds (or has places taken for) any record.
  pure logical function holds_records(self)
    class(journal_t), intent(in) :: self
    holds_records = self%next_position > self%records_start
  end function holds_records

  !> Close the journal (it stays: ellroll_output_files removes it when the
  !> output is in place); err reports a failed close (a delayed write error)
  !> unless it holds an error already.
  subroutine close_journal(self, err)
    class(journal_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    integer :: code
    if (self%fd < 0) return
    code = close_descriptor(self%fd)
    self%fd = -1
    if (code /= 0 .and. .not. err%failed()) &
      call set_error(err, err_output, self%path // ': cannot write the journal: ' // system_error_text(code))
  end subroutine close_journal

  ! ------------------------------------------------------------ layout

  integer(i8) function words_per_record(header)
    type(journal_header_t), intent(in) :: header
    type(case_result_t) :: empty
    words_per_record = 3 + 3 * size(summary_record(empty)) + 1 + &
        header%n_samples * sum(field_ncomp, mask=in_record(header))
  end function words_per_record

  !> The fields a record holds whole.
  pure function in_record(header)
    type(journal_header_t), intent(in) :: header
    logical :: in_record(field_count)
    in_record = header%fields .and. .not. header%in_place
  end function in_record

  !> The words of a record (words_per_record of them), its checksum aside.
  subroutine pack_record(header, slot, res, in_place, words)
    type(journal_header_t), intent(in) :: header
    integer(i8), intent(in) :: slot
    type(case_result_t), intent(in) :: res
    integer(i8), intent(in) :: in_place       !< the fingerprint of the trajectories written in place
    integer(i8), intent(out) :: words(:)
    type(named_value_t), allocatable :: rec(:)
    integer :: k, f
    integer(i8) :: at, n
    logical :: whole(field_count)
    whole = in_record(header)
    words(1:3) = [record_marker, slot, int(res%status, i8)]
    rec = summary_record(res)
    ! three words per summary entry: an integer, or up to three reals
    do k = 1, size(rec)
      if (rec(k)%kind == kind_int) then
        words(3 * k + 1:3 * k + 3) = [rec(k)%int, 0_i8, 0_i8]
      else
        words(3 * k + 1:3 * k + 3) = transfer(rec(k)%reals, 0_i8, 3)
      end if
    end do
    at = 3 + 3 * size(rec) + 1
    words(at) = in_place
    do f = 1, field_count
      if (.not. whole(f)) cycle
      n = field_ncomp(f) * header%n_samples
      words(at + 1:at + n) = transfer(res%fields(f)%values, 0_i8, n)
      at = at + n
    end do
  end subroutine pack_record

  subroutine unpack_record(header, words, slot, res, in_place)
    type(journal_header_t), intent(in) :: header
    integer(i8), intent(in) :: words(:)
    integer(i8), intent(out) :: slot
    type(case_result_t), intent(out) :: res
    integer(i8), intent(out) :: in_place
    type(named_value_t), allocatable :: rec(:)
    integer :: k, f
    integer(i8) :: at, n
    logical :: whole(field_count)
    whole = in_record(header)
    slot = words(2)
    res%status = int(words(3))
    rec = summary_record(res)
    do k = 1, size(rec)
      if (rec(k)%kind == kind_int) then
        rec(k)%int = words(3 * k + 1)
      else
        rec(k)%reals = transfer(words(3 * k + 1:3 * k + 3), 0.0_wp, 3)
      end if
      call set_summary_value(res, k, rec(k))
    end do
    at = 3 + 3 * size(rec) + 1
    in_place = words(at)
    do f = 1, field_count
      if (.not. whole(f)) cycle
      n = field_ncomp(f) * header%n_samples
      res%fields(f)%values = reshape(transfer(words(at + 1:at + n), 0.0_wp, n), &
                                     [int(field_ncomp(f), i8), header%n_samples])
      at = at + n
    end do
    n = words(at + 1)             ! the switches of regime, after the part of one size
    do k = 1, int(n)
      call add_switch(res, transfer(words(at + 1 + k), 0.0_wp), int(words(at + 1 + n + k)))
    end do
  end subroutine unpack_record
end module ellroll_journal
