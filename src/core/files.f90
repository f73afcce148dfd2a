!> Files as ellroll makes, opens, removes and locks them (src/core/
!> filesystem.c): a new file is created only where nothing is (O_EXCL), an
!> existing one is opened, removed or renamed without following a link, and
!> every answer is an errno value (0: done) that system_error_text words.
module ellroll_files
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_long, c_long_long, c_size_t, c_int64_t
  use ellroll_kinds, only: i8
  use ellroll_strings, only: itoa
  implicit none
  private

  public :: path_kind, file_size, create_new_file, same_file, descriptor_is_at, remove_path, rename_path, file_identity, &
            descriptor_identity, one_name, rename_new, sticky_refusal, work_suffix, output_name_problem, sync_path, sync_folder, &
            read_head, lock_output, unlock_output, unlock_keeping, lock_held, holder_line, resume_advice, host_name, &
            process_id, text_of, free_bytes
  public :: kind_missing, kind_regular, kind_link, kind_folder, kind_other, path_length, output_name_length

  !> The longest path a command takes (Linux's PATH_MAX less its closing
  !> NUL): the files of its command line and the record files resolved
  !> against the input's folder.
  integer, parameter :: path_length = 4095

  !> The longest output name: its longest work file's name (OUT.partial.new)
  !> must be a path too.
  integer, parameter :: output_name_length = path_length - len('.partial.new')

  !> What path_kind finds at a name (a link is not followed).
  integer, parameter :: kind_missing = 0, kind_regular = 1, kind_link = 2, kind_folder = 3, kind_other = 4

  interface
    integer(c_int) function c_path_kind(path) bind(c, name='ellroll_path_kind')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_path_kind
    integer(c_long_long) function c_file_size(path) bind(c, name='ellroll_file_size')
      import :: c_long_long, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_file_size
    integer(c_int) function c_create_new(path) bind(c, name='ellroll_create_new')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_create_new
    integer(c_int) function c_same_file(a, b) bind(c, name='ellroll_same_file')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: a(*), b(*)
    end function c_same_file
    integer(c_int) function c_descriptor_is_at(fd, path) bind(c, name='ellroll_descriptor_is_at')
      import :: c_int, c_char
      integer(c_int), value :: fd
      character(kind=c_char), intent(in) :: path(*)
    end function c_descriptor_is_at
    integer(c_int) function c_file_identity(path, identity) bind(c, name='ellroll_file_identity')
      import :: c_int, c_char, c_int64_t
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int64_t), intent(out) :: identity(2)
    end function c_file_identity
    integer(c_int) function c_descriptor_identity(fd, identity) bind(c, name='ellroll_descriptor_identity')
      import :: c_int, c_int64_t
      integer(c_int), value :: fd
      integer(c_int64_t), intent(out) :: identity(2)
    end function c_descriptor_identity
    integer(c_int) function c_one_name(fd, path, copy) bind(c, name='ellroll_one_name')
      import :: c_int, c_char
      integer(c_int), value :: fd
      character(kind=c_char), intent(in) :: path(*), copy(*)
    end function c_one_name
    integer(c_int) function c_unlock_keeping(fd, path, note) bind(c, name='ellroll_unlock_keeping')
      import :: c_int, c_char
      integer(c_int), value :: fd
      character(kind=c_char), intent(in) :: path(*), note(*)
    end function c_unlock_keeping
    integer(c_int) function c_remove_path(path) bind(c, name='ellroll_remove_path')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_remove_path
    integer(c_int) function c_rename_path(old, new) bind(c, name='ellroll_rename_path')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: old(*), new(*)
    end function c_rename_path
    integer(c_int) function c_rename_new(old, new) bind(c, name='ellroll_rename_new')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: old(*), new(*)
    end function c_rename_new
    integer(c_int) function c_sticky_refusal(path, folder, owner) bind(c, name='ellroll_sticky_refusal')
      import :: c_int, c_char, c_long
      character(kind=c_char), intent(in) :: path(*), folder(*)
      integer(c_long), intent(out) :: owner
    end function c_sticky_refusal
    integer(c_int) function c_sync_path(path) bind(c, name='ellroll_sync_path')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_sync_path
    integer(c_int) function c_sync_folder(path) bind(c, name='ellroll_sync_folder')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_sync_folder
    integer(c_int) function c_read_head(path, buffer, size) bind(c, name='ellroll_read_head')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      character(kind=c_char), intent(out) :: buffer(*)
      integer(c_int), value :: size
    end function c_read_head
    integer(c_int) function c_lock_output(path, me, holder, size) bind(c, name='ellroll_lock_output')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*), me(*)
      character(kind=c_char), intent(out) :: holder(*)
      integer(c_int), value :: size
    end function c_lock_output
    integer(c_long_long) function free_bytes_c(path) bind(c, name='ellroll_free_bytes')
      import :: c_long_long, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function free_bytes_c
    integer(c_int) function c_lock_held(path, holder, size) bind(c, name='ellroll_lock_held')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      character(kind=c_char), intent(out) :: holder(*)
      integer(c_int), value :: size
    end function c_lock_held
    integer(c_int) function c_unlock_output(fd, path) bind(c, name='ellroll_unlock_output')
      import :: c_int, c_char
      integer(c_int), value :: fd
      character(kind=c_char), intent(in) :: path(*)
    end function c_unlock_output
    subroutine c_host_name(name, size) bind(c, name='ellroll_host_name')
      import :: c_char, c_int
      character(kind=c_char), intent(out) :: name(*)
      integer(c_int), value :: size
    end subroutine c_host_name
    integer(c_long) function process_id() bind(c, name='ellroll_process_id')
      import :: c_long
    end function process_id
  end interface

contains

  !> kind_missing, kind_regular, kind_link, kind_folder or kind_other, or a
  !> negative errno value where the system cannot tell.
  integer function path_kind(path)
    character(len=*), intent(in) :: path
    path_kind = c_path_kind(path // c_null_char)
  end function path_kind

  !> Bytes of the file at path (a link not followed), or a negative errno value.
  integer(c_long_long) function file_size(path)
    character(len=*), intent(in) :: path
    file_size = c_file_size(path // c_null_char)
  end function file_size

  !> A new file at path, where nothing was (O_EXCL, no link followed): a
  !> descriptor open for reading and writing, or a negative errno value.
  integer function create_new_file(path) result(fd)
    character(len=*), intent(in) :: path
    fd = c_create_new(path // c_null_char)
  end function create_new_file

  !> Whether a and b name one file (links followed; false if either is missing).
  logical function same_file(a, b)
    character(len=*), intent(in) :: a, b
    same_file = c_same_file(a // c_null_char, b // c_null_char) == 1
  end function same_file

  !> Whether descriptor fd is the regular file at path (not a link to it).
  logical function descriptor_is_at(fd, path)
    integer, intent(in) :: fd
    character(len=*), intent(in) :: path
    descriptor_is_at = c_descriptor_is_at(fd, path // c_null_char) == 1
  end function descriptor_is_at

  !> The identity (device, inode) of the regular file at path, a link not
  !> followed; 0 where none is there.
  function file_identity(path) result(identity)
    character(len=*), intent(in) :: path
    integer(i8) :: identity(2)
    integer(c_int64_t) :: found(2)
    identity = 0
    if (c_file_identity(path // c_null_char, found) == 1) identity = found
  end function file_identity

  !> The identity (device, inode) of the file open as fd; 0 where unknown.
  function descriptor_identity(fd) result(identity)
    integer, intent(in) :: fd
    integer(i8) :: identity(2)
    integer(c_int64_t) :: found(2)
    identity = 0
    if (c_descriptor_identity(fd, found) == 1) identity = found
  end function descriptor_identity

  !> The file open as fd at path with no other name: fd itself where it has
  !> one; else a descriptor of a copy (made at copy, then moved over path),
  !> which takes fd's place (fd stays open for the caller to close); or
  !> -errno, nothing changed. Writing to it then leaves a backup made with ln
  !> or cp -al as it was.
  integer function one_name(fd, path, copy)
    integer, intent(in) :: fd
    character(len=*), intent(in) :: path, copy
    one_name = c_one_name(fd, path // c_null_char, copy // c_null_char)
  end function one_name

  !> Remove the name path (a link itself, not its target): 0 or an errno value.
  integer function remove_path(path)
    character(len=*), intent(in) :: path
    remove_path = c_remove_path(path // c_null_char)
  end function remove_path

  !> Move old over new in one step (rename): 0 or an errno value.
  integer function rename_path(old, new)
    character(len=*), intent(in) :: old, new
    rename_path = c_rename_path(old // c_null_char, new // c_null_char)
  end function rename_path

  !> Move old to new where nothing is at new, never replacing a file made
  !> there at any moment before (renameat2 RENAME_NOREPLACE, else link and
  !> unlink): 0, EEXIST (17) when something is there, or another errno value.
  integer function rename_new(old, new)
    character(len=*), intent(in) :: old, new
    rename_new = c_rename_new(old // c_null_char, new // c_null_char)
  end function rename_new

  !> 0 when the sticky bit of `folder` lets this process replace or remove
  !> the file at path (or nothing is there); else an errno value: EPERM (1)
  !> when the folder is sticky and neither it nor the file is this user's
  !> (owner: the file's uid).
  integer function sticky_refusal(path, folder, owner)
    character(len=*), intent(in) :: path, folder
    integer, intent(out) :: owner
    integer(c_long) :: uid
    sticky_refusal = c_sticky_refusal(path // c_null_char, folder // c_null_char, uid)
    owner = int(uid)
  end function sticky_refusal

  !> The length of the suffix of ellroll's own work files that path ends
  !> with ('.partial', '.partial.new', '.journal', '.lock'), or 0.
  pure integer function work_suffix(path) result(n)
    character(len=*), intent(in) :: path
    character(len=*), parameter :: suffixes(4) = [character(len=12) :: '.partial.new', '.partial', '.journal', &
                                                   '.lock']
    integer :: k
    do k = 1, size(suffixes)
      n = len_trim(suffixes(k))
      if (len(path) < n) cycle
      if (path(len(path) - n + 1:) == suffixes(k)(:n)) return
    end do
    n = 0
  end function work_suffix

  !> Why path cannot name an output, or '': it ends in a work file's suffix,
  !> or its work files' names would be longer than a path, or a file's own
  !> name (NAME_MAX, 255), can be.
  subroutine output_name_problem(path, reason)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: reason
    integer, parameter :: name_length = 255 - len('.partial.new')
    integer :: own
    own = len(path) - index(path, '/', back=.true.)
    reason = ''
    if (work_suffix(path) > 0) then
      reason = 'ends in ' // path(len(path) - work_suffix(path) + 1:) // ', a suffix of ellroll''s own work ' // &
               'files (.partial, .partial.new, .journal, .lock); choose another output name'
    else if (len(path) > output_name_length) then
      reason = itoa(len(path)) // ' characters; an output''s name has at most ' // itoa(output_name_length) // &
               ' (its work file OUT.partial.new must fit the system''s limit on a path)'
    else if (own > name_length) then
      reason = 'its file''s own name has ' // itoa(own) // ' characters; at most ' // itoa(name_length) // &
               ' (its work file''s, with .partial.new, must fit the system''s limit of 255 on a name)'
    end if
  end subroutine output_name_problem

  !> The file at path to the disk (fsync): 0 or an errno value.
  integer function sync_path(path)
    character(len=*), intent(in) :: path
    sync_path = c_sync_path(path // c_null_char)
  end function sync_path

  !> A folder's entries to the disk, after a rename in it: 0 or an errno value.
  integer function sync_folder(path)
    character(len=*), intent(in) :: path
    sync_folder = c_sync_folder(path // c_null_char)
  end function sync_folder

  !> The first len(head) bytes of the regular file at path (no link
  !> followed), blank-padded; n: how many were read, or a negative errno.
  subroutine read_head(path, head, n)
    character(len=*), intent(in) :: path
    character(len=*), intent(out) :: head
    integer, intent(out) :: n
    character(kind=c_char) :: buffer(len(head))
    integer :: k
    n = c_read_head(path // c_null_char, buffer, len(head))
    head = ''
    do k = 1, max(0, n)
      head(k:k) = buffer(k)
    end do
  end subroutine read_head

  !> Take the lock of an output (its lock file at path), noting `me` in it:
  !> fd >= 0 while held; a negative errno otherwise, with `holder` the note
  !> of the process that holds it (-EAGAIN), or -EEXIST where path is no
  !> lock file of ellroll's.
  subroutine lock_output(path, me, fd, holder)
    character(len=*), intent(in) :: path, me
    integer, intent(out) :: fd
    character(len=:), allocatable, intent(out) :: holder
    character(kind=c_char) :: buffer(1024)     ! (a note: host, pid, time and a command of at most 400)
    fd = c_lock_output(path // c_null_char, me // c_null_char, buffer, size(buffer))
    call text_of(buffer, holder)
  end subroutine lock_output

  !> Release a lock of lock_output with `note` put back in its file (kept):
  !> 0 or an errno value.
  integer function unlock_keeping(fd, path, note)
    integer, intent(in) :: fd
    character(len=*), intent(in) :: path, note
    unlock_keeping = c_unlock_keeping(fd, path // c_null_char, note // c_null_char)
  end function unlock_keeping

  !> Whether another process holds the lock of an output at path (nothing
  !> taken), with the note it left there (holder).
  logical function lock_held(path, holder)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: holder
    character(kind=c_char) :: buffer(1024)
    lock_held = c_lock_held(path // c_null_char, buffer, size(buffer)) == 1
    call text_of(buffer, holder)
  end function lock_held

  !> The note of a lock's holder made its one line: 'host h, pid p, started
  !> t: command' ('starting' before its holder wrote it).
  pure subroutine holder_line(note)
    character(len=:), allocatable, intent(inout) :: note
    note = note(index(note, achar(10)) + 1:)
    if (index(note, achar(10)) > 0) note = note(:index(note, achar(10)) - 1)
    if (len_trim(note) == 0) note = 'starting'
  end subroutine holder_line

  !> How to finish the unfinished run of `output` whose lock's note is
  !> `note` ('' where none could be read): run the command the note names
  !> again with --resume (without --overwrite, which a resume refuses), or
  !> a merge again as it stands.
  pure subroutine resume_advice(output, note, advice)
    character(len=*), intent(in) :: output, note
    character(len=:), allocatable, intent(out) :: advice
    character(len=:), allocatable :: command
    integer :: at
    command = note
    call holder_line(command)
    at = index(command, ': ellroll ')
    if (at == 0) then
      advice = "finish it with 'ellroll run INPUT -o " // output // " --resume' (the run's input and options)"
      return
    end if
    command = trim(command(at + 2:)) // ' '
    if (index(command, 'ellroll merge ') == 1) then
      advice = "finish it by running '" // trim(command) // "' again (the command " // output // &
               ".lock names, from its folder)"
      return
    end if
    at = index(command, ' --overwrite ')
    if (at > 0) command = command(:at) // command(at + len(' --overwrite '):)
    if (index(command, ' --resume ') == 0) command = command // '--resume '
    advice = "finish it with '" // trim(command) // "' (the command " // output // ".lock names, from its folder)"
  end subroutine resume_advice

  !> The bytes free to this user on the file system holding path (-1: unknown).
  integer(c_long_long) function free_bytes(path)
    character(len=*), intent(in) :: path
    free_bytes = free_bytes_c(path // c_null_char)
  end function free_bytes

  !> Release a lock of lock_output (its file removed first): 0 or an errno value.
  integer function unlock_output(fd, path)
    integer, intent(in) :: fd
    character(len=*), intent(in) :: path
    unlock_output = c_unlock_output(fd, path // c_null_char)
  end function unlock_output

  !> The text a C function left in buffer, up to its NUL (all of it where
  !> none ends it).
  pure subroutine text_of(buffer, text)
    character(kind=c_char), intent(in) :: buffer(:)
    character(len=:), allocatable, intent(out) :: text
    integer :: n
    n = findloc(buffer, c_null_char, dim=1) - 1
    if (n < 0) n = size(buffer)
    text = repeat(' ', n)
    text = transfer(buffer(:n), text)
  end subroutine text_of

  !> This machine's host name.
  subroutine host_name(name)
    character(len=:), allocatable, intent(out) :: name
    character(kind=c_char) :: buffer(256)
    call c_host_name(buffer, size(buffer))
    call text_of(buffer, name)
  end subroutine host_name
end module ellroll_files
