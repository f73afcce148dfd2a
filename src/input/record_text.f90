!> The text of a record file, read whole into memory, and the pieces a
!> reader takes it apart with: lines (each with its number, for messages),
!> words, a word as a message quotes it.
module ellroll_record_text
  use ellroll_kinds, only: i8
  use ellroll_strings, only: itoa, lower, decimal_width
  use ellroll_system, only: read_whole_file
  implicit none
  private

  public :: text_file_t, max_record_bytes, read_record_text, take_line, is_blank, next_word, names_nonfinite, &
            empty_column, quoted, count_lines, line_prefix, first_word

  !> Largest record file, bytes (1 GiB): it is read whole into memory.
  integer(i8), parameter :: max_record_bytes = 2_i8**30

  !> A record file's text, taken line by line.
  type :: text_file_t
    character(len=:), allocatable :: path
    character(len=:), allocatable :: text
    integer :: next = 1          !< first character of the next line
    integer :: line = 0          !< number of the line last taken
  end type text_file_t

contains

  !> The whole text of a record file: a regular file (a FIFO would block,
  !> a device never end) of at most max_record_bytes.
  subroutine read_record_text(path, file, reason)
    character(len=*), intent(in) :: path
    type(text_file_t), intent(out) :: file
    character(len=:), allocatable, intent(out) :: reason
    file%path = path
    call read_whole_file(path, 'a record file', max_record_bytes, '1 GiB', file%text, reason)
    if (len(reason) == 0) call refuse_binary(file, reason)
  end subroutine read_record_text

  !> A record is text: a file that begins as gzip's do (1f 8b), or with a NUL
  !> in its first 64 KiB (a binary file), is refused, named by its bytes, not
  !> quoted. (Other control characters are a text's, quoted by the line
  !> that holds them.)
  subroutine refuse_binary(file, reason)
    type(text_file_t), intent(in) :: file
    character(len=:), allocatable, intent(inout) :: reason
    integer :: nul
    if (len(file%text) >= 2) then
      if (iachar(file%text(1:1)) == 31 .and. iachar(file%text(2:2)) == 139) then
        reason = file%path // ': gzip-compressed (it begins 1f 8b): decompress it; a record is a CSV or PEER ' // &
                 '.AT2 text file'
        return
      end if
    end if
    nul = index(file%text(:min(len(file%text), 65536)), achar(0))
    if (nul > 0) reason = file%path // ': not a text file (byte ' // itoa(nul) // ' is a NUL); a record is a CSV ' // &
                          'or PEER .AT2 text file'
  end subroutine refuse_binary

  !> The next line of the file: its characters first .. last (without the
  !> line feed); found = .false. at the end. hash: where its first '#' is,
  !> or 0 (one pass over the line finds both).
  subroutine take_line(file, first, last, found, hash)
    type(text_file_t), intent(inout) :: file
    integer, intent(out) :: first, last
    logical, intent(out) :: found
    integer, intent(out), optional :: hash
    integer :: code, at
    first = file%next
    last = first - 1
    found = first <= len(file%text)
    at = 0
    if (found) then
      do last = first, len(file%text)           ! (a loop: index() costs a call per line)
        code = ichar(file%text(last:last))
        if (code == 10) exit
        if (code == 35 .and. at == 0) at = last - first + 1
      end do
      last = last - 1
      file%next = last + 2
      file%line = file%line + 1
    end if
    if (present(hash)) hash = at
  end subroutine take_line

  !> Blanks, tabs and carriage returns (CRLF line ends) part words; in a CSV
  !> also commas and semicolons. (By character code: c == ' ' costs a call
  !> of len_trim.)
  elemental logical function is_blank(c, csv)
    character, intent(in) :: c
    logical, intent(in) :: csv
    integer :: code
    code = ichar(c)
    is_blank = code == 32 .or. code == 9 .or. code == 13 .or. (csv .and. (code == 44 .or. code == 59))
  end function is_blank

  !> The next word of text from position `from`: text(first:last), with
  !> last < first when there is none.
  pure subroutine next_word(text, from, csv, first, last)
    character(len=*), intent(in) :: text
    integer, intent(in) :: from
    logical, intent(in) :: csv
    integer, intent(out) :: first, last
    integer :: k, code
    first = len(text) + 1
    last = len(text)
    if (csv) then
      do k = from, len(text)
        code = ichar(text(k:k))
        if (code /= 32 .and. code /= 9 .and. code /= 13 .and. code /= 44 .and. code /= 59) exit
      end do
      first = k
      do k = first, len(text)
        code = ichar(text(k:k))
        if (code == 32 .or. code == 9 .or. code == 13 .or. code == 44 .or. code == 59) exit
      end do
    else
      do k = from, len(text)
        code = ichar(text(k:k))
        if (code /= 32 .and. code /= 9 .and. code /= 13) exit
      end do
      first = k
      do k = first, len(text)
        code = ichar(text(k:k))
        if (code == 32 .or. code == 9 .or. code == 13) exit
      end do
    end if
    last = k - 1
  end subroutine next_word

  !> In a line whose values a comma or semicolon parts, the column of the
  !> first empty value that a value follows ('0,,1.5,0': 2), else 0. Such a
  !> line's words would shift its later values into the column before them.
  pure integer function empty_column(line) result(column)
    character(len=*), intent(in) :: line
    integer :: k, field
    logical :: empty
    column = 0
    if (scan(line, ',;') == 0) return
    field = 1
    empty = .true.
    do k = 1, len(line)
      select case (line(k:k))
      case (',', ';')
        if (empty .and. column == 0) column = field
        field = field + 1
        empty = .true.
      case (' ', achar(9), achar(13))
      case default
        empty = .false.
        if (column > 0) return               ! (a value after the empty one)
      end select
    end do
    column = 0                               ! (empty values at the end shift nothing)
  end function empty_column

  !> 'nan', 'inf', 'infinity' with any sign and case: numbers, but not finite.
  pure logical function names_nonfinite(word)
    character(len=*), intent(in) :: word
    integer :: start
    start = 1
    if (len(word) > 0) then
      if (word(1:1) == '+' .or. word(1:1) == '-') start = 2
    end if
    names_nonfinite = any(lower(word(start:)) == [character(len=8) :: 'nan', 'inf', 'infinity'])
  end function names_nonfinite

  !> A word as a message quotes it: at most 40 characters.
  pure function quoted(word) result(text)
    character(len=*), intent(in) :: word
    character(len=min(len(word), 40) + merge(5, 2, len(word) > 40)) :: text
    if (len(word) > 40) then
      text = "'" // word(:40) // "...'"
    else
      text = "'" // word // "'"
    end if
  end function quoted

  !> Lines of a text, the last counted whether or not a line feed ends it,
  !> and one more (room for the rest past a record's end).
  pure integer function count_lines(text) result(n)
    character(len=*), intent(in) :: text
    integer :: k
    n = 2
    do k = 1, len(text)
      if (iachar(text(k:k)) == 10) n = n + 1
    end do
  end function count_lines

  !> 'path:line: ' of the line last taken.
  pure function line_prefix(file) result(text)
    type(text_file_t), intent(in) :: file
    character(len=len(file%path) + decimal_width(int(file%line, i8)) + 3) :: text
    text = file%path // ':' // itoa(file%line) // ': '
  end function line_prefix

  !> The length of first_word(text).
  pure integer function word_length(text)
    character(len=*), intent(in) :: text
    integer :: start, length
    start = verify(text, ' ')
    word_length = 0
    if (start == 0) return
    length = scan(text(start:), ' ,') - 1
    if (length < 0) length = len(text) - start + 1
    word_length = length
  end function word_length

  !> The first word of a text (up to a blank or a comma), or ''.
  pure function first_word(text) result(word)
    character(len=*), intent(in) :: text
    character(len=word_length(text)) :: word
    integer :: start
    start = verify(text, ' ')
    word = ''
    if (start > 0) word = text(start:)
  end function first_word
end module ellroll_record_text
