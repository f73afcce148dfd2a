!> The few operating-system services the program needs, through the C library.
module ellroll_system
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_long, c_size_t, c_ptr, &
      c_null_ptr, c_associated, c_int64_t, c_loc, c_long_long
  use ellroll_kinds, only: wp, i8
  use ellroll_strings, only: itoa
  implicit none
  private

  public :: rename_file, remove_file, utc_timestamp, file_exists, tune_runtime, folder_write_error, folder_of
  public :: open_for_writing, open_for_reading, write_pieces_at, read_at, release_range, close_descriptor, &
      system_error_text, open_regular_file, read_text, file_type_words, read_whole_file
  public :: open_files_room, memory_room
  public :: catch_stop_signals, stop_signal, request_stop, signal_name, exit_now, shown_command_line, read_watchdog

  interface
    integer(c_int) function c_rename(old, new) bind(c, name='rename')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: old(*), new(*)
    end function c_rename
    integer(c_int) function c_remove(path) bind(c, name='remove')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_remove
    integer(c_long) function c_time(tloc) bind(c, name='time')
      import :: c_long, c_ptr
      type(c_ptr), value :: tloc
    end function c_time
    type(c_ptr) function c_gmtime(t) bind(c, name='gmtime')
      import :: c_ptr, c_long
      integer(c_long), intent(in) :: t
    end function c_gmtime
    integer(c_size_t) function c_strftime(buf, size, format, tm) bind(c, name='strftime')
      import :: c_size_t, c_char, c_ptr
      character(kind=c_char), intent(out) :: buf(*)
      integer(c_size_t), value :: size
      character(kind=c_char), intent(in) :: format(*)
      type(c_ptr), value :: tm
    end function c_strftime
    !> Process-wide runtime settings, once at start (src/core/runtime.c):
    !> the heap keeps freed memory for reuse; SIGXFSZ is ignored.
    subroutine tune_runtime() bind(c, name='ellroll_tune_runtime')
    end subroutine tune_runtime
    !> From here on SIGTERM, SIGINT and SIGHUP (unless ignored) only ask the run to stop (stop_signal);
    !> a second one ends the process; SIGPIPE is ignored (src/core/signals.c).
    subroutine catch_stop_signals() bind(c, name='ellroll_catch_stop_signals')
    end subroutine catch_stop_signals
    !> Room for `needed` open files: the soft limit raised towards the hard
    !> one where it is lower; the soft limit after it (-1: unknown).
    integer(c_long) function open_files_room(needed) bind(c, name='ellroll_open_files_room')
      import :: c_long
      integer(c_long), value :: needed
    end function open_files_room
    !> The memory this process may hold, bytes: the machine's, or ulimit -v
    !> where lower (-1: unknown).
    integer(c_long_long) function memory_room() bind(c, name='ellroll_memory_room')
      import :: c_long_long
    end function memory_room
    !> End the process at once with status, without the exit handlers: after
    !> a failed write, HDF5's handler would close a file whose writes failed
    !> and can crash doing so. The caller flushes its units first.
    subroutine exit_now(status) bind(c, name='_exit')
      import :: c_int
      integer(c_int), value :: status
    end subroutine exit_now
    !> After `seconds`, write message (null-terminated) and end with exit 2;
    !> 0 seconds: disarmed (src/core/signals.c, for a read HDF5 may never finish).
    subroutine c_read_watchdog(message, seconds) bind(c, name='ellroll_read_watchdog')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: message(*)
      integer(c_int), value :: seconds
    end subroutine c_read_watchdog
    !> The signal that asked the run to stop, or 0.
    integer(c_int) function stop_signal() bind(c, name='ellroll_stop_signal')
      import :: c_int
    end function stop_signal
    !> Ask the runs under way to stop as if signal sig had come; 0: go on again.
    subroutine request_stop(sig) bind(c, name='ellroll_request_stop')
      import :: c_int
      integer(c_int), value :: sig
    end subroutine request_stop
    ! positioned writes and reads (src/core/positioned_io.c)
    integer(c_int) function c_open_descriptor(path, writing) bind(c, name='ellroll_open_descriptor')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: writing
    end function c_open_descriptor
    integer(c_int) function c_write_pieces_at(fd, pieces, bytes, count, offset) &
        bind(c, name='ellroll_write_pieces_at')
      import :: c_int, c_ptr, c_int64_t
      integer(c_int), value :: fd, count
      type(c_ptr), intent(in) :: pieces(*)
      integer(c_int64_t), intent(in) :: bytes(*)
      integer(c_int64_t), value :: offset
    end function c_write_pieces_at
    integer(c_int) function c_read_at(fd, buffer, bytes, offset) bind(c, name='ellroll_read_at')
      import :: c_int, c_ptr, c_int64_t
      integer(c_int), value :: fd
      type(c_ptr), value :: buffer
      integer(c_int64_t), value :: bytes, offset
    end function c_read_at
    integer(c_int64_t) function c_release_range(fd, from, to) bind(c, name='ellroll_release_range')
      import :: c_int, c_int64_t
      integer(c_int), value :: fd
      integer(c_int64_t), value :: from, to
    end function c_release_range
    integer(c_int) function c_close_descriptor(fd) bind(c, name='ellroll_close_descriptor')
      import :: c_int
      integer(c_int), value :: fd
    end function c_close_descriptor
    integer(c_int) function c_folder_write_error(path) bind(c, name='ellroll_folder_write_error')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_folder_write_error
    integer(c_int) function c_open_regular_file(path, fd, bytes, file_type) bind(c, name='ellroll_open_regular_file')
      import :: c_int, c_char, c_int64_t
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), intent(out) :: fd
      integer(c_int64_t), intent(out) :: bytes
      character(kind=c_char), intent(out) :: file_type
    end function c_open_regular_file
    integer(c_int) function c_read_text(fd, text, bytes) bind(c, name='ellroll_read_text')
      import :: c_int, c_char, c_int64_t
      integer(c_int), value :: fd
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int64_t), value :: bytes
    end function c_read_text
    pure subroutine c_error_text(code, text, size) bind(c, name='ellroll_error_text')
      import :: c_int, c_char, c_size_t
      integer(c_int), value :: code
      character(kind=c_char), intent(out) :: text(*)
      integer(c_size_t), value :: size
    end subroutine c_error_text
  end interface

contains

  !> From now, a read that has not ended after `seconds` ends the process:
  !> message on standard error, exit 2 (HDF5 loops for ever on some damaged
  !> global heaps, inside one call). Only where nothing is being written
  !> (ellroll summary); 0 seconds: disarmed.
  subroutine read_watchdog(message, seconds)
    character(len=*), intent(in) :: message
    integer, intent(in) :: seconds
    call c_read_watchdog(message // c_null_char, int(seconds, c_int))
  end subroutine read_watchdog

  pure function padded_signal_name(signal) result(name)
    integer, intent(in) :: signal
    character(len=8) :: name
    select case (signal)
    case (1)
      name = 'SIGHUP'
    case (2)
      name = 'SIGINT'
    case (15)
      name = 'SIGTERM'
    case default
      name = 'a signal'
    end select
  end function padded_signal_name

  !> The name of a stop signal (POSIX numbers), for messages.
  pure function signal_name(signal) result(name)
    integer, intent(in) :: signal
    character(len=len_trim(padded_signal_name(signal))) :: name
    name = padded_signal_name(signal)
  end function signal_name

  !> Atomically replace `new` by `old` (POSIX rename). True on success.
  logical function rename_file(old, new)
    character(len=*), intent(in) :: old, new
    rename_file = c_rename(old // c_null_char, new // c_null_char) == 0
  end function rename_file

  !> 0 when files can be created in folder `path`, else the errno value
  !> that says why (system_error_text words it).
  integer function folder_write_error(path)
    character(len=*), intent(in) :: path
    folder_write_error = c_folder_write_error(path // c_null_char)
  end function folder_write_error

  pure integer function folder_length(path)
    character(len=*), intent(in) :: path
    folder_length = max(1, index(path, '/', back=.true.) - 1)
  end function folder_length

  !> The folder of a file's path: what precedes its last '/', or '.'.
  pure function folder_of(path) result(folder)
    character(len=*), intent(in) :: path
    character(len=folder_length(path)) :: folder
    if (index(path, '/', back=.true.) == 0) then
      folder = '.'
    else
      folder = path(:len(folder))
    end if
  end function folder_of

  logical function file_exists(path)
    character(len=*), intent(in) :: path
    inquire (file=path, exist=file_exists)
  end function file_exists

  subroutine remove_file(path)
    character(len=*), intent(in) :: path
    integer(c_int) :: rc
    rc = c_remove(path // c_null_char)
  end subroutine remove_file

  !> A descriptor of existing file `path` open for writing, and reading
  !> (>= 0), or a negative errno value.
  integer function open_for_writing(path) result(fd)
    character(len=*), intent(in) :: path
    fd = c_open_descriptor(path // c_null_char, 1_c_int)
  end function open_for_writing

  !> A descriptor of `path` open for reading, when it is a regular file
  !> (links followed), and its size: 0; an errno value; or -1 when it is
  !> something else, which `file_type` names (file_type_words). A FIFO or a
  !> device is not opened: a FIFO would wait for a writer.
  integer function open_regular_file(path, fd, bytes, file_type) result(code)
    character(len=*), intent(in) :: path
    integer, intent(out) :: fd
    integer(i8), intent(out) :: bytes
    character, intent(out) :: file_type
    integer(c_int) :: descriptor
    code = c_open_regular_file(path // c_null_char, descriptor, bytes, file_type)
    fd = descriptor
  end function open_regular_file

  !> What a file_type of open_regular_file is, in words.
  pure function file_type_words(file_type) result(words)
    character, intent(in) :: file_type
    character(len=22) :: words
    select case (file_type)
    case ('d'); words = 'a folder'
    case ('p'); words = 'a FIFO (named pipe)'
    case ('c'); words = 'a character device'
    case ('b'); words = 'a block device'
    case ('s'); words = 'a socket'
    case ('r'); words = 'a regular file'
    case default; words = 'not a regular file'
    end select
  end function file_type_words

  !> The whole text of `path`, a regular file (links followed) of at most
  !> max_bytes (limit_words says how much that is); a FIFO, which would wait
  !> for a writer, or a device, which may never end, is not opened. reason:
  !> '' or why not, naming the path and what the file is (`what`, e.g. 'an
  !> input file').
  subroutine read_whole_file(path, what, max_bytes, limit_words, text, reason)
    character(len=*), intent(in) :: path, what, limit_words
    integer(i8), intent(in) :: max_bytes
    character(len=:), allocatable, intent(out) :: text, reason
    integer :: code, fd
    integer(i8) :: bytes
    character :: file_type
    reason = ''
    text = ''
    code = open_regular_file(path, fd, bytes, file_type)
    if (code > 0) then
      reason = 'cannot open ' // path // ': ' // system_error_text(code)
      return
    else if (code < 0) then
      reason = path // ': ' // trim(file_type_words(file_type)) // ', not a regular file; ' // what // &
               ' is read from a regular file'
      return
    end if
    if (bytes > max_bytes) then
      reason = path // ': ' // itoa(bytes) // ' bytes, more than ' // what // ' may hold (' // limit_words // ')'
    else
      deallocate (text)
      allocate (character(len=bytes) :: text, stat=code)
      if (code /= 0) then
        reason = path // ': no memory for its ' // itoa(bytes) // ' bytes'
        text = ''
      else
        code = read_text(fd, text)
        if (code > 0) reason = 'cannot read ' // path // ': ' // system_error_text(code)
        if (code < 0) reason = path // ': the file shrank while it was read'
        if (code == 0) then
          if (.not. ends_at(fd, bytes)) reason = path // ': the file holds more than its size (' // &
              itoa(bytes) // ' bytes): it grew while it was read, or it is not a file on a disk (/proc, /sys); ' // &
              what // ' is read from a regular file'
        end if
      end if
    end if
    code = close_descriptor(fd)
  end subroutine read_whole_file

  !> Whether the file open as fd ends at byte `bytes` (nothing there to read).
  logical function ends_at(fd, bytes)
    integer, intent(in) :: fd
    integer(i8), intent(in) :: bytes
    character(kind=c_char), target :: past(1)
    ends_at = read_at(fd, c_loc(past), 1_i8, bytes) /= 0
  end function ends_at

  !> The first len(text) bytes of the file open as fd: 0, an errno value,
  !> or -1 where the file ends first.
  integer function read_text(fd, text) result(code)
    integer, intent(in) :: fd
    character(len=*), intent(out) :: text
    code = c_read_text(int(fd, c_int), text, int(len(text), c_int64_t))
  end function read_text

  !> The same, for reading.
  integer function open_for_reading(path) result(fd)
    character(len=*), intent(in) :: path
    fd = c_open_descriptor(path // c_null_char, 0_c_int)
  end function open_for_reading

  !> Write pieces of memory (bytes(k) bytes at pieces(k)) one after the
  !> other from byte `offset` (from 0), in one system call; 0, or an errno
  !> value. Threads may write disjoint regions of one file at the same time.
  integer function write_pieces_at(fd, pieces, bytes, offset) result(code)
    integer, intent(in) :: fd
    type(c_ptr), intent(in) :: pieces(:)
    integer(i8), intent(in) :: bytes(:), offset
    code = c_write_pieces_at(fd, pieces, bytes, size(pieces), offset)
  end function write_pieces_at

  !> Read `bytes` bytes from byte `offset` (from 0) into `buffer`: 0, an
  !> errno value, or -1 where the file ends first.
  integer function read_at(fd, buffer, bytes, offset) result(code)
    integer, intent(in) :: fd
    type(c_ptr), intent(in) :: buffer
    integer(i8), intent(in) :: bytes, offset
    code = c_read_at(fd, buffer, bytes, offset)
  end function read_at

  !> Free the storage of bytes `from` .. `to` - 1 of a file open for
  !> writing, which then read as zeros, up to the last whole block of the
  !> file system before `to` (or the file's end): where the freed bytes end (`from` when no
  !> whole block lies in between), or a negative errno value (-EOPNOTSUPP
  !> where the file system cannot).
  integer(i8) function release_range(fd, from, to) result(freed_to)
    integer, intent(in) :: fd
    integer(i8), intent(in) :: from, to
    freed_to = c_release_range(fd, from, to)
  end function release_range

  !> Close a descriptor of open_for_writing or open_for_reading: 0, or an errno value.
  integer function close_descriptor(fd) result(code)
    integer, intent(in) :: fd
    code = c_close_descriptor(fd)
  end function close_descriptor

  pure integer function error_text_length(code) result(n)
    integer, intent(in) :: code
    character(kind=c_char) :: buffer(200)
    call error_words(code, buffer)
    n = findloc(buffer, c_null_char, dim=1) - 1
    if (n < 0) n = size(buffer)
  end function error_text_length

  !> The system's words for errno value `code`.
  function system_error_text(code) result(text)
    integer, intent(in) :: code
    character(len=error_text_length(code)) :: text
    character(kind=c_char) :: buffer(200)
    call error_words(code, buffer)
    text = transfer(buffer(:len(text)), text)
  end function system_error_text

  pure subroutine error_words(code, buffer)
    integer, intent(in) :: code
    character(kind=c_char), intent(out) :: buffer(200)
    call c_error_text(code, buffer, size(buffer, kind=c_size_t))
  end subroutine error_words

  !> Current time as ISO 8601 UTC, e.g. 2026-11-23T03:22:15Z ('' if the
  !> system cannot tell).
  subroutine utc_timestamp(stamp)
    character(len=:), allocatable, intent(out) :: stamp
    character(kind=c_char) :: buf(32)
    integer(c_long) :: now
    integer(c_size_t) :: n
    type(c_ptr) :: tm
    integer :: i
    now = c_time(c_null_ptr)
    tm = c_gmtime(now)
    stamp = ''
    if (.not. c_associated(tm)) return
    n = c_strftime(buf, size(buf, kind=c_size_t), '%Y-%m-%dT%H:%M:%SZ' // c_null_char, tm)
    stamp = repeat(' ', int(n))
    do i = 1, int(n)
      stamp(i:i) = buf(i)
    end do
  end subroutine utc_timestamp

  !> This process's command line as others may read it (the output's lock
  !> note): 'ellroll' and each argument, in single quotes where it holds
  !> more than letters, digits and ./_-=:+,@%, a control character shown as
  !> '?', the whole cut to `limit` characters (its end then '...').
  subroutine shown_command_line(limit, line)
    integer, intent(in) :: limit
    character(len=:), allocatable, intent(out) :: line
    character(len=:), allocatable :: arg
    character(len=*), parameter :: plain = 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789./_-=:+,@%'
    integer :: k, length, pos
    line = 'ellroll'
    do k = 1, command_argument_count()
      if (len(line) > limit) exit
      call get_command_argument(k, length=length)
      allocate (character(len=length) :: arg)
      if (length > 0) call get_command_argument(k, arg)
      do pos = 1, length
        if (iachar(arg(pos:pos)) < 32 .or. iachar(arg(pos:pos)) == 127) arg(pos:pos) = '?'
      end do
      if (length == 0 .or. verify(arg, plain) > 0) then
        do pos = length, 1, -1             ! ' inside single quotes: '\''
          if (arg(pos:pos) == "'") arg = arg(:pos - 1) // "'\''" // arg(pos + 1:)
        end do
        arg = "'" // arg // "'"
      end if
      line = line // ' ' // arg
      deallocate (arg)
    end do
    if (len(line) > limit) line = line(:max(0, limit - 3)) // '...'
  end subroutine shown_command_line

end module ellroll_system
