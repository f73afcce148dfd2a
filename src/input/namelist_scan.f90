!> Lexical scan of a namelist file before any Fortran namelist READ.
!>
!> gfortran reports several different faults (missing group, stray text,
!> missing newline) as end-of-file, and a READ names neither the line nor the
!> variable. So we split the file ourselves into groups and `name = value`
!> assignments with their line numbers; each assignment is then read on its
!> own (see ellroll_input), which pins every error to one variable.
module ellroll_namelist_scan
  use ellroll_kinds, only: i8
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_strings, only: lower, itoa, excerpt
  use ellroll_files, only: path_kind, kind_folder
  use ellroll_system, only: read_whole_file
  implicit none
  private

  public :: nml_file_t, nml_group_t, nml_assignment_t, scan_namelist_file, scan_namelist_text

  type :: nml_assignment_t
    character(len=:), allocatable :: name    !< lower case, as written: 'omega' or 'omega(3)'
    character(len=:), allocatable :: base    !< lower case, without subscript
    character(len=:), allocatable :: value   !< the value text, blanks collapsed
    character(len=:), allocatable :: source  !< 'name = value', comments blanked, may span lines
    integer :: line = 0
  end type nml_assignment_t

  type :: nml_group_t
    character(len=:), allocatable :: name    !< lower case, without '&'
    integer :: line = 0
    type(nml_assignment_t), allocatable :: items(:)
  contains
    procedure :: find => find_item
  end type nml_group_t

  type :: nml_file_t
    character(len=:), allocatable :: path
    character(len=:), allocatable :: text    !< the file as read, for provenance
    type(nml_group_t), allocatable :: groups(:)
  contains
    procedure :: group_index
  end type nml_file_t

  character, parameter :: lf = achar(10), cr = achar(13), tab = achar(9)
  !> The largest input file read (its positions are default integers).
  integer(i8), parameter :: max_input_bytes = 2_i8**30

  !> Where a scan stands and what it has found.
  type :: scanner_t
    character(len=:), allocatable :: path
    character(len=:), allocatable :: clean         !< the text, its comments blanked as met
    integer :: i = 1                               !< the next character
    integer :: line = 1
    character :: quote = ' '                       !< the open quote, or blank
    logical :: in_group = .false.
    character(len=:), allocatable :: group_name
    integer :: group_line = 0
    integer :: value_start = 0                     !< where the open value (or the group's text) starts
    integer :: item_count = 0
    type(nml_assignment_t), allocatable :: items(:)
    type(nml_group_t), allocatable :: groups(:)
  end type scanner_t

contains

  subroutine scan_namelist_file(path, file, err)
    character(len=*), intent(in) :: path
    type(nml_file_t), intent(out) :: file
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: reason
    logical :: exists

    file%path = path
    inquire (file=path, exist=exists)
    if (.not. exists) then
      call set_error(err, err_input, path // ': input file not found')
      return
    end if
    if (path_kind(path) == kind_folder) then
      call set_error(err, err_input, path // ': a folder, not an input file (give the namelist file in it)')
      return
    end if
    call read_whole_file(path, 'an input file', max_input_bytes, '1 GiB', file%text, reason)
    if (len(reason) > 0) then
      call set_error(err, err_input, reason)
      return
    end if
    if (holds_hdf5_signature(file%text)) then
      call set_error(err, err_input, path // ' is not a namelist file (it looks like an HDF5 file; did you mean ' // &
                     '`ellroll summary ' // path // '`?)')
      return
    else if (index(file%text, achar(0)) > 0) then
      call set_error(err, err_input, path // ' is not a namelist file (it holds binary data; an input file is ' // &
                     'text with groups such as &geometry ... /)')
      return
    end if
    call scan_namelist_text(file, err)
  end subroutine scan_namelist_file

  !> Whether text starts with the HDF5 signature at 0, 512, 1024, 2048, ...
  !> bytes (where HDF5 looks for it: behind a user block).
  pure logical function holds_hdf5_signature(text)
    character(len=*), intent(in) :: text
    character(len=*), parameter :: signature = char(137) // 'HDF' // achar(13) // achar(10) // achar(26) // achar(10)
    integer :: at
    holds_hdf5_signature = .true.
    at = 0
    do while (at + len(signature) <= len(text))
      if (text(at + 1:at + len(signature)) == signature) return
      at = max(512, 2 * at)
    end do
    holds_hdf5_signature = .false.
  end function holds_hdf5_signature

  !> Split file%text into groups and assignments.
  subroutine scan_namelist_text(file, err)
    type(nml_file_t), intent(inout) :: file
    type(error_t), intent(inout) :: err
    type(scanner_t) :: s
    integer :: n

    n = len(file%text)
    s%path = file%path
    if (n == 0) then
      call fail(s, err, 1, 'the file is empty; expected namelist groups such as &geometry ... /')
    else if (file%text(n:n) /= lf) then
      call fail(s, err, count_lines(file%text, n), 'the last line does not end with a newline ' // &
                '(gfortran cannot read a namelist group there); add a line break at the end')
    end if
    if (err%failed()) return

    s%clean = file%text
    ! a UTF-8 byte-order mark (some editors save one) is no text
    if (n >= 3) then
      if (file%text(1:3) == char(239) // char(187) // char(191)) s%clean(1:3) = ''
    end if
    allocate (s%groups(0))
    do while (s%i <= n)
      call scan_character(s, err)
      if (err%failed()) return
    end do
    if (s%in_group) then
      call fail(s, err, s%group_line, '&' // s%group_name // ' is not closed with / before the end of the file')
    else if (size(s%groups) == 0) then
      call fail(s, err, 1, 'no namelist group found; expected groups such as &geometry ... /')
    else
      call move_alloc(s%groups, file%groups)
    end if
  end subroutine scan_namelist_text

  !> The character at s%i: line breaks, quotes and comments anywhere, then
  !> what it means outside or inside a group.
  subroutine scan_character(s, err)
    type(scanner_t), intent(inout) :: s
    type(error_t), intent(inout) :: err
    character :: ch
    ch = s%clean(s%i:s%i)
    if (ch == lf) then
      if (s%quote /= ' ') then
        call fail(s, err, s%line, 'a quoted string is not closed on its line')
        return
      end if
      s%line = s%line + 1
      s%i = s%i + 1
    else if (iachar(ch) < 32 .and. ch /= tab .and. ch /= cr) then
      call fail(s, err, s%line, 'unexpected control character (code ' // itoa(iachar(ch)) // ')')
    else if (s%quote /= ' ') then
      if (ch == s%quote) s%quote = ' '
      s%i = s%i + 1
    else if (ch == '!') then
      call blank_comment(s%clean, s%i)
    else if (s%in_group) then
      call scan_inside_group(s, ch, err)
    else
      call scan_outside_group(s, ch, err)
    end if
  end subroutine scan_character

  !> Outside a group only blanks and the start of a group (&name) may stand.
  subroutine scan_outside_group(s, ch, err)
    type(scanner_t), intent(inout) :: s
    character, intent(in) :: ch
    type(error_t), intent(inout) :: err
    if (ch == '&' .or. ch == '$') then
      s%group_name = lower(name_after(s%clean, s%i))
      if (len(s%group_name) == 0) then
        call fail(s, err, s%line, "'" // ch // "' must be followed by a group name, e.g. &geometry")
      else if (s%group_name == 'end') then
        call fail(s, err, s%line, "'" // ch // "end' without an open group")
      else
        s%in_group = .true.
        s%group_line = s%line
        allocate (s%items(0))
        s%item_count = 0
        s%value_start = s%i + 1 + len(s%group_name)
        s%i = s%value_start
      end if
    else if (ch /= ' ' .and. ch /= tab .and. ch /= cr) then
      call fail(s, err, s%line, 'unexpected text outside a namelist group: "' // snippet(s%clean, s%i) // &
                '" (a group starts with &name and ends with /; comments start with !)')
    else
      s%i = s%i + 1
    end if
  end subroutine scan_outside_group

  !> Inside a group: a quote opens, '/' or '&end' closes the group, '='
  !> ends a name and opens its value.
  subroutine scan_inside_group(s, ch, err)
    type(scanner_t), intent(inout) :: s
    character, intent(in) :: ch
    type(error_t), intent(inout) :: err
    integer :: name_start, eq_pos
    character(len=:), allocatable :: text
    associate (clean => s%clean, i => s%i)
      if (ch == "'" .or. ch == '"') then
        s%quote = ch
      else if (ch == '/' .or. ((ch == '&' .or. ch == '$') .and. lower(clean(i+1:min(len(clean), i+3))) == 'end')) then
        if (.not. close_value(s, err, i - 1)) return
        call append_group(s%groups, s%group_name, s%group_line, s%items)
        s%in_group = .false.
        if (ch /= '/') i = i + 3
      else if (ch == '&' .or. ch == '$') then
        call fail(s, err, s%line, '&' // s%group_name // ' (line ' // itoa(s%group_line) // &
                  ') is not closed with / before the next group starts')
        return
      else if (ch == '=') then
        eq_pos = i
        name_start = find_name_start(clean, eq_pos)
        if (name_start == 0) then
          call fail(s, err, s%line, "'=' without a variable name before it in &" // s%group_name)
          return
        end if
        if (s%item_count == 0 .and. collapsed_length(clean(s%value_start:name_start-1)) > 0) then
          call collapse(clean(s%value_start:name_start-1), text)
          call fail(s, err, s%line, 'unexpected text "' // excerpt(text) // &
                    '" in &' // s%group_name // ' before the first variable')
          return
        end if
        if (.not. close_value(s, err, name_start - 1)) return
        s%item_count = s%item_count + 1
        call collapse(clean(name_start:eq_pos-1), text)
        call append_item(s%items, lower(text), s%line)
        s%items(s%item_count)%source = clean(name_start:eq_pos)    ! value appended by close_value
        s%value_start = eq_pos + 1
      end if
      i = i + 1
    end associate
  end subroutine scan_inside_group

  !> The value of the open assignment ends at position last (a group
  !> without assignments holds only blanks).
  logical function close_value(s, err, last)
    type(scanner_t), intent(inout) :: s
    type(error_t), intent(inout) :: err
    integer, intent(in) :: last
    character(len=:), allocatable :: value
    close_value = .true.
    call collapse(s%clean(s%value_start:last), value)
    if (s%item_count == 0) then
      if (len(value) > 0) then
        call fail(s, err, s%line, 'unexpected text "' // excerpt(value) // '" in &' // s%group_name // &
                  '; expected name = value')
        close_value = .false.
      end if
      return
    end if
    if (len(value) > 0) then
      if (value(len(value):len(value)) == ',') value = trim(value(:len(value)-1))
    end if
    associate (item => s%items(s%item_count))
      if (len(value) == 0) then
        call fail(s, err, item%line, '&' // s%group_name // ': ' // item%name // &
                  ' = (nothing): a value is required after =')
        close_value = .false.
        return
      end if
      item%value = value
      item%source = item%source // s%clean(s%value_start:last)
    end associate
  end function close_value

  subroutine fail(s, err, at_line, message)
    type(scanner_t), intent(in) :: s
    type(error_t), intent(inout) :: err
    integer, intent(in) :: at_line
    character(len=*), intent(in) :: message
    call set_error(err, err_input, s%path // ':' // itoa(at_line) // ': ' // message)
  end subroutine fail

  !> Where the variable name before the '=' at `eq` starts (a subscript
  !> included), or 0 where no name stands there.
  pure integer function find_name_start(clean, eq) result(start)
    character(len=*), intent(in) :: clean
    integer, intent(in) :: eq
    integer :: k, depth
    start = 0
    k = eq - 1
    do while (k >= 1)
      if (clean(k:k) /= ' ' .and. clean(k:k) /= tab .and. clean(k:k) /= cr .and. clean(k:k) /= lf) exit
      k = k - 1
    end do
    if (k < 1) return
    if (clean(k:k) == ')') then
      depth = 0
      do while (k >= 1)
        if (clean(k:k) == ')') depth = depth + 1
        if (clean(k:k) == '(') depth = depth - 1
        if (depth == 0) exit
        if (clean(k:k) == lf) return
        k = k - 1
      end do
      if (k <= 1) return
      k = k - 1
    end if
    if (k < 1) return
    if (.not. is_name_char(clean(k:k))) return
    do while (k >= 1)
      if (.not. is_name_char(clean(k:k))) exit
      k = k - 1
    end do
    start = k + 1
    if (.not. is_letter(clean(start:start))) start = 0
  end function find_name_start

  !> Blank the comment that starts at i, up to its line's end (i ends there).
  pure subroutine blank_comment(clean, i)
    character(len=*), intent(inout) :: clean
    integer, intent(inout) :: i
    do while (i <= len(clean))
      if (clean(i:i) == lf) exit
      clean(i:i) = ' '
      i = i + 1
    end do
  end subroutine blank_comment

  !> Where the name starting after position i of clean ends.
  pure integer function name_end(clean, i) result(j)
    character(len=*), intent(in) :: clean
    integer, intent(in) :: i
    j = i + 1
    do while (j <= len(clean))
      if (.not. is_name_char(clean(j:j))) exit
      j = j + 1
    end do
    j = j - 1
  end function name_end

  !> The name that follows the character at i ('&' or '$'): name characters up to the first other.
  pure function name_after(clean, i) result(name)
    character(len=*), intent(in) :: clean
    integer, intent(in) :: i
    character(len=name_end(clean, i) - i) :: name
    name = clean(i+1:name_end(clean, i))
  end function name_after

  pure integer function snippet_end(clean, pos) result(e)
    character(len=*), intent(in) :: clean
    integer, intent(in) :: pos
    e = pos
    do while (e < len(clean) .and. e < pos + 30)
      if (clean(e+1:e+1) == lf) exit
      e = e + 1
    end do
  end function snippet_end

  !> Up to 31 characters of `clean` from `pos`, to the line's end.
  pure function snippet(clean, pos) result(s)
    character(len=*), intent(in) :: clean
    integer, intent(in) :: pos
    character(len=len_trim(clean(pos:snippet_end(clean, pos)))) :: s
    s = clean(pos:snippet_end(clean, pos))
  end function snippet

  !> The line of position `upto` of text.
  pure integer function count_lines(text, upto)
    character(len=*), intent(in) :: text
    integer, intent(in) :: upto
    integer :: k
    count_lines = 1
    do k = 1, upto - 1
      if (text(k:k) == lf) count_lines = count_lines + 1
    end do
  end function count_lines

  !> Appends a group; the items move into it.
  pure subroutine append_group(groups, name, line, items)
    type(nml_group_t), allocatable, intent(inout) :: groups(:)
    character(len=*), intent(in) :: name
    integer, intent(in) :: line
    type(nml_assignment_t), allocatable, intent(inout) :: items(:)
    type(nml_group_t), allocatable :: grown(:)
    integer :: k
    allocate (grown(size(groups) + 1))
    do k = 1, size(groups)
      call move_group(groups(k), grown(k))
    end do
    grown(size(grown))%name = name
    grown(size(grown))%line = line
    call move_alloc(items, grown(size(grown))%items)
    call move_alloc(grown, groups)
  contains
    pure subroutine move_group(from, to)
      type(nml_group_t), intent(inout) :: from
      type(nml_group_t), intent(inout) :: to
      call move_alloc(from%name, to%name)
      to%line = from%line
      call move_alloc(from%items, to%items)
    end subroutine move_group
  end subroutine append_group

  pure subroutine append_item(items, name, line)
    type(nml_assignment_t), allocatable, intent(inout) :: items(:)
    character(len=*), intent(in) :: name
    integer, intent(in) :: line
    type(nml_assignment_t), allocatable :: grown(:)
    integer :: k
    allocate (grown(size(items) + 1))
    do k = 1, size(items)
      call move_alloc(items(k)%name, grown(k)%name)
      call move_alloc(items(k)%base, grown(k)%base)
      call move_alloc(items(k)%value, grown(k)%value)
      call move_alloc(items(k)%source, grown(k)%source)
      grown(k)%line = items(k)%line
    end do
    grown(size(grown))%name = name
    grown(size(grown))%base = base_name(name)
    grown(size(grown))%value = ''
    grown(size(grown))%source = ''
    grown(size(grown))%line = line
    call move_alloc(grown, items)
  end subroutine append_item

  pure integer function group_index(self, name)
    class(nml_file_t), intent(in) :: self
    character(len=*), intent(in) :: name
    integer :: k
    group_index = 0
    do k = 1, size(self%groups)
      if (self%groups(k)%name == name) then
        group_index = k
        return
      end if
    end do
  end function group_index

  !> Index of the first assignment to `base` in the group, 0 if none.
  pure integer function find_item(self, base)
    class(nml_group_t), intent(in) :: self
    character(len=*), intent(in) :: base
    integer :: k
    find_item = 0
    do k = 1, size(self%items)
      if (self%items(k)%base == base) then
        find_item = k
        return
      end if
    end do
  end function find_item

  pure logical function is_letter(ch)
    character, intent(in) :: ch
    is_letter = (ch >= 'a' .and. ch <= 'z') .or. (ch >= 'A' .and. ch <= 'Z')
  end function is_letter

  pure logical function is_name_char(ch)
    character, intent(in) :: ch
    is_name_char = is_letter(ch) .or. (ch >= '0' .and. ch <= '9') .or. ch == '_'
  end function is_name_char

  pure integer function base_end(name)
    character(len=*), intent(in) :: name
    base_end = index(name, '(') - 1
    if (base_end < 0) base_end = len(name)
  end function base_end

  pure function base_name(name) result(base)
    character(len=*), intent(in) :: name
    character(len=len_trim(name(:base_end(name)))) :: base
    base = name(:base_end(name))
  end function base_name

  !> The length of text with blanks, tabs and line breaks collapsed (collapse).
  pure integer function collapsed_length(text) result(m)
    character(len=*), intent(in) :: text
    call collapse_into(text, m)
  end function collapsed_length

  !> Blanks, tabs and line breaks collapsed to single blanks, ends trimmed;
  !> on the heap, as a value may be megabytes long.
  pure subroutine collapse(text, out)
    character(len=*), intent(in) :: text
    character(len=:), allocatable, intent(out) :: out
    integer :: m
    allocate (character(len=collapsed_length(text)) :: out)
    call collapse_into(text, m, out)
  end subroutine collapse

  !> The collapsed text's length m, and the text itself into out where given.
  pure subroutine collapse_into(text, m, out)
    character(len=*), intent(in) :: text
    integer, intent(out) :: m
    character(len=*), intent(inout), optional :: out
    integer :: k
    logical :: blank_pending
    m = 0
    blank_pending = .false.
    do k = 1, len(text)
      select case (text(k:k))
      case (' ', tab, cr, lf)
        blank_pending = m > 0
      case default
        if (blank_pending) then
          m = m + 1
          if (present(out)) out(m:m) = ' '
          blank_pending = .false.
        end if
        m = m + 1
        if (present(out)) out(m:m) = text(k:k)
      end select
    end do
  end subroutine collapse_into

end module ellroll_namelist_scan
