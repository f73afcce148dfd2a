!> Reading namelist groups for ellroll's input: finding a group, checking
!> its variable names, and every message about a value, which names the
!> file, line, group, variable and value. Also the values read, as one
!> record the builders of the case, plan and campaign take.
module ellroll_input_reader
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_namelist_scan, only: nml_file_t, nml_assignment_t
  use ellroll_strings, only: itoa, join, format_real, excerpt
  use ellroll_params, only: param_count, params
  use ellroll_suggest, only: did_you_mean
  use ellroll_intensity, only: max_sa_periods
  implicit none
  private

  public :: reader_t, namelist_values_t, check_names, count_given, is_not_given, not_given, not_finite_entry, resolve_path, &
            max_values, max_fields, has_unquoted

  integer, parameter :: max_values = 10000, max_fields = 32

  !> The bits of what a list entry holds until the input gives it
  !> (not_given): a quiet NaN whose payload no namelist read makes
  !> (gfortran reads every spelling of NaN, NaN(...) included, as the
  !> default NaN), so that a NaN the input writes, also as the list's last
  !> value, is told apart from an entry not given.
  integer(i8), parameter :: not_given_bits = 9221120240777019119_i8     ! z'7FF80000DEADBEEF'

  type :: reader_t
    type(nml_file_t) :: file
    type(error_t) :: err
  contains
    procedure :: group => find_group
    procedure :: fail_at
    procedure :: fail_value
    procedure :: fail_missing
    procedure :: given
    procedure :: require
    procedure :: require_all
  end type reader_t

  !> Every namelist variable as read: the defaults of the parameter table
  !> (NaN where required) where the input says nothing.
  type :: namelist_values_t
    real(wp) :: param(param_count)         !< the rows of the parameter table
    character(len=32) :: method, error_estimate, slip
    real(wp) :: t_end, interval
    character(len=1024) :: file
    character(len=32) :: fields(max_fields)
    integer :: compression
    character(len=16) :: kind
    character(len=1024) :: record_file(3)
    real(wp) :: factor
    real(wp) :: sa_periods(max_sa_periods)  !< &excitation: periods of the stored Sa (not_given where not given)
    character(len=16) :: combine, invalid, spacing
    integer(i8) :: samples, seed
    character(len=32) :: name
    character(len=32) :: figure                 !< &limit_state
    real(wp) :: limit_capacity                  !< &limit_state capacity
    real(wp) :: values(max_values), start, stop, low, high
    integer :: count
  end type namelist_values_t

contains

  integer function find_group(rd, name, required) result(gi)
    class(reader_t), intent(inout) :: rd
    character(len=*), intent(in) :: name
    logical, intent(in) :: required
    character(len=:), allocatable :: needs
    gi = rd%file%group_index(name)
    if (gi == 0 .and. required .and. .not. rd%err%failed()) then
      call group_needs(name, needs)
      call set_error(rd%err, err_input, rd%file%path // ': group &' // name // ' is missing (it is required' // &
                     needs // ')')
    end if
  end function find_group

  !> What a required group needs: its required variables (of the parameter
  !> table, a vector once, and of its own) and a line that gives them.
  pure subroutine group_needs(name, text)
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(out) :: text
    character(len=:), allocatable :: needed, example
    integer :: p
    needed = ''
    do p = 1, param_count
      if (params(p)%group /= name .or. .not. params(p)%required) cycle
      if (index(' ' // needed // ',', ' ' // trim(params(p)%variable) // ',') > 0) cycle
      if (params(p)%variable == 'mass') then
        needed = needed // ' or mass'
        cycle
      end if
      if (len(needed) > 0) needed = needed // ','
      needed = needed // ' ' // trim(params(p)%variable)
    end do
    select case (name)
    case ('geometry'); example = '&geometry a = 1.0, b = 0.4, c = 0.2 /'
    case ('ball'); example = '&ball radius = 0.2, weight = 2620.0 /'
    case ('initial'); example = '&initial omega = 0.0, 0.0, 20.0 /'
    case ('integration')
      needed = needed // ' (for rk4 and gauss4), t_end'
      example = "&integration method = 'rk4', dt = 1.0e-3, t_end = 30.0 /"
    case ('output')
      needed = needed // ' file, interval'
      example = "&output file = 'out.h5', interval = 0.01 /"
    case default; example = ''
    end select
    text = ''
    if (len(needed) > 0) text = '; it needs' // needed
    if (len(example) > 0) text = text // '; add a line such as: ' // example
  end subroutine group_needs

  !> Unknown and repeated variable names in group gi.
  logical function check_names(rd, gi, known) result(ok)
    type(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: known(:)
    integer :: k, j
    character(len=:), allocatable :: hint
    ok = .false.
    associate (grp => rd%file%groups(gi))
      do k = 1, size(grp%items)
        if (.not. any(known == grp%items(k)%base)) then
          call did_you_mean(grp%items(k)%base, known, '', hint)
          call rd%fail_at(grp%items(k)%line, '&' // grp%name // ': unknown variable ' // grp%items(k)%name // &
              ' = ' // grp%items(k)%value // hint // ' (known in &' // grp%name // ': ' // join(known) // ')')
          return
        end if
        do j = 1, k - 1
          if (sets_same(grp%items(j), grp%items(k))) then
            call rd%fail_at(grp%items(k)%line, '&' // grp%name // ': ' // grp%items(k)%name // &
                ' = ' // grp%items(k)%value // ': given twice (also at line ' // itoa(grp%items(j)%line) // ')')
            return
          end if
        end do
      end do
    end associate
    ok = .true.
  end function check_names

  !> Two assignments that set the same variable, or the same element of
  !> one: the same name, or a whole vector beside one of its elements.
  pure logical function sets_same(first, second)
    type(nml_assignment_t), intent(in) :: first, second
    sets_same = first%name == second%name
    if (first%base == second%base) sets_same = sets_same .or. first%name == first%base .or. second%name == second%base
  end function sets_same

  subroutine fail_at(rd, line, message)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: line
    character(len=*), intent(in) :: message
    if (.not. rd%err%failed()) call set_error(rd%err, err_input, rd%file%path // ':' // itoa(line) // ': ' // message)
  end subroutine fail_at

  subroutine fail_value(rd, gi, name, reason)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name, reason
    integer :: k
    k = rd%file%groups(gi)%find(name)
    if (k == 0) then
      call rd%fail_at(rd%file%groups(gi)%line, '&' // rd%file%groups(gi)%name // ': ' // name // &
                      ' (default): ' // reason)
    else
      associate (item => rd%file%groups(gi)%items(k))
        call rd%fail_at(item%line, '&' // rd%file%groups(gi)%name // ': ' // item%name // ' = ' // &
                        excerpt(item%value) // ': ' // reason)
      end associate
    end if
  end subroutine fail_value

  subroutine fail_missing(rd, gi, name, hint)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name, hint
    call rd%fail_at(rd%file%groups(gi)%line, '&' // rd%file%groups(gi)%name // ': ' // name // &
                    ' is required but not given: ' // hint)
  end subroutine fail_missing

  logical function given(rd, gi, name)
    class(reader_t), intent(in) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name
    given = .false.
    if (gi > 0) given = rd%file%groups(gi)%find(name) > 0
  end function given

  !> A required scalar: given and finite (the range is checked with the case).
  logical function require(rd, gi, name, value) result(ok)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: name
    real(wp), intent(in) :: value
    ok = .false.
    if (.not. rd%given(gi, name)) then
      call rd%fail_missing(gi, name, 'add ' // name // ' = <value> to &' // rd%file%groups(gi)%name)
    else if (.not. ieee_is_finite(value)) then
      call rd%fail_value(gi, name, 'must be a finite number')
    else
      ok = .true.
    end if
  end function require

  !> require for each name in turn, up to the first that fails.
  logical function require_all(rd, gi, names, values) result(ok)
    class(reader_t), intent(inout) :: rd
    integer, intent(in) :: gi
    character(len=*), intent(in) :: names(:)
    real(wp), intent(in) :: values(:)
    integer :: k
    ok = .true.
    do k = 1, size(names)
      ok = rd%require(gi, trim(names(k)), values(k))
      if (.not. ok) return
    end do
  end function require_all

  !> Entries of a list that starts as not_given, up to the last given.
  pure integer function count_given(list)
    real(wp), intent(in) :: list(:)
    integer :: k
    count_given = 0
    do k = 1, size(list)
      if (.not. is_not_given(list(k))) count_given = k
    end do
  end function count_given

  !> Why entry k of a list is not a finite number, for a message: 'value K
  !> is NaN' (or Inf, -Inf), or 'value K is not given' for a gap (`1, , 3`).
  subroutine not_finite_entry(list, k, text)
    real(wp), intent(in) :: list(:)
    integer, intent(in) :: k
    character(len=:), allocatable, intent(out) :: text
    if (is_not_given(list(k))) then
      text = 'value ' // itoa(k) // ' is not given'
    else
      text = 'value ' // itoa(k) // ' is ' // format_real(list(k))
    end if
  end subroutine not_finite_entry

  !> The value of a list entry not given (not_given_bits). A function of a
  !> variable: gfortran folds the transfer of a constant into a real
  !> constant without the NaN's payload.
  pure real(wp) function not_given()
    integer(i8) :: bits
    bits = not_given_bits
    not_given = transfer(bits, not_given)
  end function not_given

  !> Whether x is not_given, bit for bit (a comparison would not tell NaNs apart).
  elemental logical function is_not_given(x)
    real(wp), intent(in) :: x
    is_not_given = transfer(x, 1_i8) == not_given_bits
  end function is_not_given
  !> How much of input_path (its folder, with the '/') goes before path: none
  !> for an absolute path or an input in the current folder.
  pure integer function folder_prefix_length(path, input_path) result(n)
    character(len=*), intent(in) :: path, input_path
    n = index(input_path, '/', back=.true.)
    if (len(path) > 0) then
      if (path(1:1) == '/') n = 0
    end if
  end function folder_prefix_length

  !> A path relative to the input file's folder (absolute paths unchanged).
  pure function resolve_path(path, input_path) result(resolved)
    character(len=*), intent(in) :: path, input_path
    character(len=len(path) + folder_prefix_length(path, input_path)) :: resolved
    resolved = input_path(:folder_prefix_length(path, input_path)) // path
  end function resolve_path

  !> Whether a text variable's value list holds an item outside quotes
  !> (after its repeat count r*, if any). gfortran's namelist read takes an
  !> unquoted number (file = 0.5) as a text but refuses an unquoted word
  !> (file = NaN): both are refused alike, texts go in quotes.
  pure logical function has_unquoted(value)
    character(len=*), intent(in) :: value
    character(len=*), parameter :: separators = ' ,' // achar(9) // achar(10) // achar(13)
    integer :: pos, first, star
    character :: quote
    has_unquoted = .false.
    quote = ' '
    first = 1
    do pos = 1, len(value) + 1
      if (pos <= len(value)) then
        if (quote /= ' ') then
          if (value(pos:pos) == quote) quote = ' '        ! (a doubled quote closes and opens again)
          cycle
        end if
        if (value(pos:pos) == "'" .or. value(pos:pos) == '"') quote = value(pos:pos)
        if (index(separators, value(pos:pos)) == 0) cycle
      end if
      if (pos > first) then                                 ! an item: value(first:pos - 1)
        star = index(value(first:pos - 1), '*')
        if (star > 1) then
          if (verify(value(first:first + star - 2), '0123456789') == 0) first = first + star
        end if
        if (pos > first) then
          if (value(first:first) /= "'" .and. value(first:first) /= '"') has_unquoted = .true.
        end if
      end if
      first = pos + 1
    end do
  end function has_unquoted

end module ellroll_input_reader
