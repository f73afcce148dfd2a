!> The files of one output, and the only place that makes, checks, moves and
!> removes them. For output OUT:
!>   OUT           the finished file, moved into place when complete
!>   OUT.partial   the file being written (HDF5, trajectories in place)
!>   OUT.partial.new  a resume's new file, moved over OUT.partial
!>   OUT.journal   every finished case, the durable record of a run
!>   OUT.lock      held (fcntl) by the one process writing OUT, with its note
!> A process takes the lock before it looks at or touches any of them, so a
!> second run, resume or merge of the same output is refused at once and
!> the first one's files are left alone. No name is followed if it is a
!> symbolic link, and no file is removed or replaced unless it is one of
!> ellroll's (its first bytes say so) and not the input.
!>
!> The lock is an fcntl lock: it holds between processes on one machine and,
!> over NFS (v3 with its lock manager, v4), between machines; on Lustre
!> between machines only with the `flock` mount option (`localflock` locks
!> per node). Where the file system has no locks the run goes on with a
!> warning.
module ellroll_output_files
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_errors, only: error_t, set_error, err_output, err_input
  use ellroll_strings, only: itoa
  use ellroll_system, only: system_error_text, folder_of, utc_timestamp, shown_command_line
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_trajectory_store, only: label_marker, label_search_bytes
  use ellroll_kinds, only: i8
  use ellroll_files, only: path_kind, same_file, remove_path, rename_path, rename_new, sticky_refusal, sync_path, &
      file_identity, sync_folder, read_head, lock_output, unlock_output, unlock_keeping, holder_line, descriptor_is_at, &
      host_name, process_id, kind_missing, kind_regular, kind_link, kind_folder
  implicit none
  private

  public :: output_files_t, check_replace, work_partial, work_journal, work_target, work_lock

  !> What a file at a work name must be for ellroll to remove or replace it.
  integer, parameter :: work_partial = 1, work_journal = 2, work_target = 3, work_lock = 4

  !> The longest command a lock's note holds (ellroll_system's shown_command_line)
  integer, parameter :: lock_note_command = 400

  integer, parameter :: eperm = 1, enoent = 2, eagain = 11, eexist = 17, enolck = 37, enosys = 38, eopnotsupp = 95

  type :: output_files_t
    character(len=:), allocatable :: target, partial, resumed, journal, lock
    character(len=:), allocatable :: input          !< the input file (never written), '' if none
    integer :: lock_fd = -1
    !> the identities (device, inode; 0: none) of the output checked when
    !> the run began, of the file it writes and of its journal: the end
    !> moves and removes only these (another file moved to one of their
    !> names while the run wrote stays where it is)
    integer(i8) :: target_identity(2) = 0, written_identity(2) = 0, journal_identity(2) = 0
    !> the run is making the file it writes (from just before HDF5 creates it
    !> to note_written): one left half made is this run's own, with no case
    logical :: laying_out = .false.
    !> the note of a killed run's lock file this process took over: put
    !> back where it is refused before it touches a file (it names the
    !> command that finishes that run)
    character(len=:), allocatable :: killed_note
  contains
    procedure :: name => name_files
    procedure :: note_target, note_written, note_journal
    procedure :: acquire
    procedure :: release
    procedure :: check
    procedure :: discard
    procedure :: commit
    procedure :: lock_lost
  end type output_files_t

contains

  !> The names of the files of output `target`, written from input `input`.
  subroutine name_files(self, target, input)
    class(output_files_t), intent(inout) :: self
    character(len=*), intent(in) :: target, input
    self%target = target
    self%partial = target // '.partial'
    self%resumed = self%partial // '.new'
    self%journal = target // '.journal'
    self%lock = target // '.lock'
    self%input = input
  end subroutine name_files

  !> The output at the target's name as it was checked (none: 0).
  subroutine note_target(self)
    class(output_files_t), intent(inout) :: self
    self%target_identity = file_identity(self%target)
  end subroutine note_target

  !> The file this process writes is the one of this identity (its writer's:
  !> whatever is moved to its name later is not it).
  subroutine note_written(self, identity)
    class(output_files_t), intent(inout) :: self
    integer(i8), intent(in) :: identity(2)
    self%written_identity = identity
    self%laying_out = .false.
  end subroutine note_written

  !> The journal at its name is this run's (just made or opened).
  subroutine note_journal(self)
    class(output_files_t), intent(inout) :: self
    self%journal_identity = file_identity(self%journal)
  end subroutine note_journal

  !> Take the output's lock; refuse (exit 3) where another process holds
  !> it, naming it, or where the lock's name holds something else. Its note
  !> names this process's command line (shown_command_line), after
  !> `launcher` where given (mpirun's).
  subroutine acquire(self, err, launcher)
    class(output_files_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    character(len=*), intent(in), optional :: launcher
    character(len=:), allocatable :: me, holder, host, stamp, command
    integer :: fd
    call shown_command_line(lock_note_command, command)
    if (present(launcher)) command = launcher // ' ' // command
    call self%check(self%lock, work_lock, err)
    if (err%failed()) return
    call host_name(host)
    call utc_timestamp(stamp)
    me = 'ellroll lock' // achar(10) // 'host ' // host // ', pid ' // itoa(int(process_id())) // &
         ', started ' // stamp // ': ' // command // achar(10)
    call lock_output(self%lock, me, fd, holder)
    if (fd >= 0) then
      self%lock_fd = fd
      self%killed_note = holder
    else if (fd == -eagain) then
      call holder_line(holder)
      call set_error(err, err_output, self%target // ': another ellroll process writes this output (' // &
          holder // '); nothing of its files was touched: wait for it to end, or choose another output')
    else if (fd == -eexist) then
      call set_error(err, err_output, self%lock // ': exists and is not a lock file of ellroll''s (a link, a ' // &
          'folder or another file); it is never replaced: remove it, or choose another output')
    else if (any(-fd == [enolck, enosys, eopnotsupp])) then
      write (error_unit, '(a)') 'ellroll: warning: ' // self%lock // ': the file system cannot lock files (' // &
          system_error_text(-fd) // '); make sure no other run writes this output'
    else
      call set_error(err, err_output, self%lock // ': cannot take the output''s lock: ' // system_error_text(-fd))
    end if
  end subroutine acquire

  !> Release the output's lock (its file removed); err reports a failure
  !> unless it holds an error already.
  subroutine release(self, err, refused)
    class(output_files_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    logical, intent(in), optional :: refused     !< before it touched a file (a killed run's note put back)
    integer :: code
    logical :: restore
    if (self%lock_fd < 0) return
    restore = .false.
    if (present(refused) .and. allocated(self%killed_note)) restore = refused .and. len(self%killed_note) > 0
    if (restore) then
      code = unlock_keeping(self%lock_fd, self%lock, self%killed_note)
      self%lock_fd = -1
      if (code /= 0 .and. .not. err%failed()) &
        call set_error(err, err_output, self%lock // ': cannot put back the note of the run it names: ' // &
                       system_error_text(code))
      return
    end if
    code = unlock_output(self%lock_fd, self%lock)
    self%lock_fd = -1
    if (code /= 0 .and. .not. err%failed()) &
      call set_error(err, err_output, self%lock // ': cannot remove the output''s lock: ' // system_error_text(code))
  end subroutine release

  !> Whether what is at `path` may be read, replaced or removed as a file of
  !> kind `what` (work_partial, work_journal, work_target): nothing there,
  !> or a regular file of that kind that is not the input. Else err (exit 3)
  !> says what is there and that it is left alone.
  subroutine check(self, path, what, err)
    class(output_files_t), intent(in) :: self
    character(len=*), intent(in) :: path
    integer, intent(in) :: what
    type(error_t), intent(inout) :: err
    integer :: kind
    logical :: is_input, ours
    character(len=:), allocatable :: unread
    if (err%failed()) return
    kind = path_kind(path)
    if (kind == kind_missing) return
    is_input = .false.
    if (len(self%input) > 0) is_input = same_file(path, self%input)
    if (kind < 0) then
      call set_error(err, err_output, path // ': cannot look at it: ' // system_error_text(-kind))
    else if (kind == kind_link) then
      call set_error(err, err_output, path // ': is a symbolic link; ellroll never writes through one: ' // &
                     'remove it, or choose another output name')
    else if (kind == kind_folder) then
      call set_error(err, err_output, path // ': is a folder; choose another output name')
    else if (kind /= kind_regular) then
      call set_error(err, err_output, path // ': is not a regular file (a FIFO, a device or a socket); ' // &
                     'choose another output name')
    else if (is_input) then
      call set_error(err, err_output, path // ': is the input file; it is never written: choose another ' // &
                     'output name')
    else
      call look_at(path, what, ours, unread)
      if (len(unread) > 0) then              ! no verdict on a file that cannot be read
        call set_error(err, err_output, unread)
      else if (.not. ours) then
        call not_ours_text(what, unread)
        call set_error(err, err_output, path // ': exists and is not ' // unread // &
                     '; it is never replaced, even with --overwrite: remove it, or choose another output name')
      end if
    end if
  end subroutine check

  !> What a file at a work name is not, when check refuses it.
  pure subroutine not_ours_text(what, text)
    integer, intent(in) :: what
    character(len=:), allocatable, intent(out) :: text
    if (what == work_target) then
      text = 'an ellroll output file (not HDF5, not ellroll''s, or a copy of one by another program: its ' // &
             'file_identity does not match its layout)'
    else
      text = 'an ellroll work file'
    end if
  end subroutine not_ours_text

  !> Whether the file at `path` may be replaced (renamed over) or removed
  !> by this process: in a folder with the sticky bit (/tmp, a shared
  !> scratch folder) only the owner of the file or of the folder may. Else
  !> err (exit 3), before any case runs.
  subroutine check_replace(path, err)
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    integer :: code, owner
    if (err%failed()) return
    code = sticky_refusal(path, folder_of(path), owner)
    if (code == eperm) then
      call set_error(err, err_output, path // ': cannot be replaced by this user: it belongs to user id ' // &
          itoa(owner) // ', and its folder ' // folder_of(path) // ' has the sticky bit (only the owner of the ' // &
          'file or of the folder may replace it); choose another output name')
    else if (code /= 0) then
      call set_error(err, err_output, path // ': cannot look at it: ' // system_error_text(code))
    end if
  end subroutine check_replace

  !> Remove a work file (checked first: ours, not a link, not the input);
  !> nothing there is no error. Where this process's lock was removed
  !> (lock_lost) nothing is removed: the file may be another run's.
  subroutine discard(self, path, what, err, made)
    class(output_files_t), intent(in) :: self
    character(len=*), intent(in) :: path
    integer, intent(in) :: what
    type(error_t), intent(inout) :: err
    !> this process made the file (a failed run's cleanup): a regular file
    !> there goes whatever it holds so far
    logical, intent(in), optional :: made
    integer :: code
    logical :: ours
    if (self%lock_lost()) return          ! (the file at path may be another run's)
    ours = .false.
    if (present(made)) then
      if (made) ours = path_kind(path) == kind_regular
    end if
    if (.not. ours) call self%check(path, what, err)
    if (err%failed()) return
    if (path_kind(path) == kind_missing) return
    code = remove_path(path)
    if (code /= 0 .and. code /= enoent) call set_error(err, err_output, path // ': cannot remove it: ' // &
                                                       system_error_text(code))
  end subroutine discard

  !> Whether the output's lock file this process holds is no longer at its
  !> name (removed by hand): another run may hold the output now, and the
  !> files at its names be that run's.
  logical function lock_lost(self)
    class(output_files_t), intent(in) :: self
    lock_lost = .false.
    if (self%lock_fd >= 0) lock_lost = .not. descriptor_is_at(self%lock_fd, self%lock)
  end function lock_lost

  !> The finished file (`finished`, closed) to the disk and moved over the
  !> output, then the journal removed: the output is in place, complete,
  !> before the record of its cases goes. A failure leaves both (a resume
  !> then finds the output complete, and removes the journal).
  subroutine commit(self, finished, err)
    class(output_files_t), intent(inout) :: self
    character(len=*), intent(in) :: finished
    type(error_t), intent(inout) :: err
    integer :: code
    logical :: replacing
    if (err%failed()) return
    if (self%lock_lost()) then
      if (path_kind(folder_of(finished)) == kind_missing) then     ! (the lock went with its folder)
        call say_folder_lost(finished, self%target // ': cannot move the finished file ' // finished // &
                             ' into place', err)
      else
        call set_error(err, err_output, self%lock // ': the output''s lock was removed while this process ' // &
            'wrote it (another run may write ' // self%target // ' now); ' // finished // ' is not moved into ' // &
            'place, and no file at its names is touched')
      end if
      return
    end if
    call self%check(self%target, work_target, err)
    if (err%failed()) return
    if (any(self%written_identity /= 0)) then
      if (any(file_identity(finished) /= self%written_identity)) then
        call set_error(err, err_output, finished // ': not the file this run wrote (another file was moved to ' // &
            'its name while it ran); nothing is moved into place or removed')
        return
      end if
    end if
    ! the output checked when the run began is replaced, and only it; where
    ! none was, none made since (by another process) is
    replacing = any(self%target_identity /= 0)
    if (replacing) replacing = path_kind(self%target) /= kind_missing
    if (replacing) then
      if (any(file_identity(self%target) /= self%target_identity)) then
        call set_error(err, err_output, self%target // ': not the output this run was to replace (another file ' // &
            'was moved to its name while it ran); it stays, and ' // finished // ' is not moved into place')
        return
      end if
    end if
    code = sync_path(finished)
    if (code == enoent) then
      call say_folder_lost(finished, finished // ': cannot write it to the disk', err)
      return
    end if
    if (code /= 0) then
      call set_error(err, err_output, finished // ': cannot write it to the disk: ' // system_error_text(code))
      return
    end if
    if (replacing) then
      code = rename_path(finished, self%target)
    else
      code = rename_new(finished, self%target)
    end if
    if (code == enoent) then
      call say_folder_lost(finished, self%target // ': cannot move the finished file ' // finished // ' into place', &
                           err)
      return
    end if
    if (code == eexist) then
      call set_error(err, err_output, self%target // ': a file was made at its name while this run wrote it; ' // &
          'it stays, and ' // finished // ' is not moved into place')
      return
    end if
    if (code /= 0) then
      call set_error(err, err_output, self%target // ': cannot move the finished file ' // finished // &
                     ' into place: ' // system_error_text(code))
      return
    end if
    code = sync_folder(folder_of(self%target))
    if (code /= 0) then
      call set_error(err, err_output, self%target // ': in place, but its folder''s entry cannot be written ' // &
                     'to the disk: ' // system_error_text(code))
      return
    end if
    if (all(self%journal_identity == 0)) return            ! (a merge has none)
    if (any(file_identity(self%journal) /= self%journal_identity)) then
      write (error_unit, '(a)') 'ellroll: warning: ' // self%journal // ': not the journal this run wrote ' // &
          '(another file was moved to its name while it ran); left as it is'
      return
    end if
    code = remove_path(self%journal)
    if (code /= 0 .and. code /= enoent) call set_error(err, err_output, self%journal // ': the output is ' // &
        'complete, but the journal at its name cannot be removed: ' // system_error_text(code) // '; remove it by hand')
  end subroutine commit

  !> err for a finished file that is not where it was written (`doing`
  !> failed): its folder gone, or the file no longer in that folder.
  subroutine say_folder_lost(finished, doing, err)
    character(len=*), intent(in) :: finished, doing
    type(error_t), intent(inout) :: err
    if (path_kind(folder_of(finished)) == kind_missing) then
      call set_error(err, err_output, doing // ': its folder ' // folder_of(finished) // &
          ' is gone (moved or removed while ellroll wrote in it)')
    else
      call set_error(err, err_output, doing // ': it is no longer in its folder ' // folder_of(finished) // &
          ' (the folder moved and another made at its name, or the file removed, while ellroll wrote in it)')
    end if
  end subroutine say_folder_lost

  !> Whether the regular file at path is a file ellroll made of kind `what`
  !> (ours): an output is an HDF5 file that says it is ellroll's and whose
  !> file_identity matches where its objects lie (not a copy by another
  !> program: ellroll_hdf5_common's file_identity); a work file
  !> is told by its first bytes: an HDF5 file (signature at byte 0, or at 512
  !> behind the trajectories' label), a label of trajectories in place (a
  !> resume keeps only them), a journal, or an empty or torn beginning of
  !> one of these (a run killed as it created it: nothing, or zeros).
  !> unread: '' or, where the file cannot be read, why ('PATH: cannot read
  !> it: REASON'), and ours is then false.
  subroutine look_at(path, what, ours, unread)
    character(len=*), intent(in) :: path
    integer, intent(in) :: what
    logical, intent(out) :: ours
    character(len=:), allocatable, intent(out) :: unread
    character(len=*), parameter :: hdf5_signature = char(137) // 'HDF' // achar(13) // achar(10) // &
        achar(26) // achar(10)
    character(len=*), parameter :: label = 'ellroll:', journal_magic = 'ELLROLL', lock_mark = 'ellroll lock'
    character(len=520) :: head
    character(len=label_search_bytes) :: window
    integer :: n
    type(h5_input_t) :: output
    type(error_t) :: not_ours
    ours = .false.
    unread = ''
    if (what == work_target) then
      call output%open(path, not_ours)
      ours = .not. not_ours%failed()
      if (ours) ours = output%made_here()
      call output%close()
      ! (err_output: it could not be read, or a process writes it)
      if (not_ours%code == err_output) unread = not_ours%message
      return
    end if
    call read_head(path, head, n)
    if (n < 0) then
      unread = path // ': cannot read it: ' // system_error_text(-n)
      return
    end if
    if (verify(head(:n), char(0)) == 0) then          ! empty, or never written
      ours = .true.
      return
    end if
    select case (what)
    case (work_journal)
      ours = head(1:min(n, len(journal_magic))) == journal_magic(:min(n, len(journal_magic)))
    case (work_lock)
      ours = head(1:min(n, len(lock_mark))) == lock_mark(:min(n, len(lock_mark)))
    case default
      ours = head(1:min(n, 8)) == hdf5_signature(:min(n, 8)) .or. head(1:min(n, 8)) == label(:min(n, 8))
      if (n >= 520) ours = ours .or. (verify(head(:512), char(0)) == 0 .and. head(513:520) == hdf5_signature)
      ! an HDF5 file without the trajectories' label that opens whole and is
      ! another program's is not a work file (ellroll's has the label from its
      ! start on, or is open for write, torn, or says it is ellroll's)
      if (ours .and. n >= 8 .and. head(1:min(n, 8)) == hdf5_signature) then
        call read_head(path, window, n)
        if (index(window(:max(n, 0)), label_marker) == 0) then
          call output%open(path, not_ours)
          call output%close()
          if (not_ours%code == err_input) ours = index(not_ours%message, 'not an ellroll file') == 0
        end if
      end if
    end select
  end subroutine look_at
end module ellroll_output_files
