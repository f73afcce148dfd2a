!> The results of a campaign run into memory, laid out as the file's
!> datasets (ellroll_memory_run fills them): each dataset's description,
!> units, dimensions, attributes and values, the list of them and its
!> catalog, which the C interface (src/capi) hands out.
module ellroll_memory_datasets
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa
  use ellroll_records, only: named_value_t, kind_real, kind_int, kind_text
  use ellroll_cases, only: field_ncomp
  use ellroll_results, only: case_result_t
  use ellroll_file_layout, only: case_entry
  implicit none
  private

  public :: memory_output_t, memory_dataset_t, text_width, tab, newline, field_end, record_end
  public :: add, add_entry, add_attribute, case_scale, name_coordinates, int_list, escaped, write_catalog

  !> characters of a text value (a named_value_t's text)
  type(named_value_t), parameter :: blank_value = named_value_t()
  integer, parameter :: text_width = len(blank_value%text)
  character, parameter :: tab = achar(9), newline = achar(10)
  !> ASCII's unit and record separators, which no name or attribute holds
  character, parameter :: field_end = achar(31), record_end = achar(30)

  !> One dataset as the file holds it, in memory. Shapes and dimensions are
  !> as h5py and numpy show them (C order: the case first), the reverse of
  !> Fortran's; the values are in Fortran's order, which is the same memory.
  type :: memory_dataset_t
    character(len=16) :: group = ''          !< '' (the root), 'case', 'trajectory' or 'summary'
    character(len=32) :: name = ''
    character(len=16) :: units = ''
    character(len=160) :: long_name = ''
    integer :: kind = kind_real
    integer :: ndim = 1
    integer(i8) :: shape(3) = 0
    character(len=8) :: dims(3) = ''
    !> other attributes, a line 'NAME<tab>TYPE<tab>VALUE' each (TYPE: str,
    !> i1 / i4 / i8 for a list of 1- / 4- / 8-byte integers, f8 for a list
    !> of doubles, each the shortest text that reads back as it)
    character(len=:), allocatable :: attributes
    integer :: field = 0                     !< a trajectory: its field, read from the cases' results
    logical :: taken = .false.               !< its values taken out (ellroll_take): nothing to read
    real(wp), allocatable :: reals(:)
    integer(i8), allocatable :: ints(:)
    character(len=text_width), allocatable :: texts(:)
  end type memory_dataset_t

  type :: memory_output_t
    type(error_t) :: err
    integer :: n = 0                         !< datasets
    type(memory_dataset_t), allocatable :: datasets(:)
    type(case_result_t), allocatable :: results(:)   !< by case index (their trajectories)
    integer(i8) :: n_samples = 0
    character(len=:), allocatable :: attributes      !< the root's, as a dataset's
    !> every dataset's description in one text (write_catalog)
    character(len=:), allocatable :: catalog
  contains
    procedure :: read_reals
  end type memory_output_t

contains

  !> The decimal digits of a count.
  pure integer function digit_count(value)
    integer(i8), intent(in) :: value          !< >= 0
    integer(i8) :: rest
    digit_count = 1
    rest = value
    do while (rest >= 10)
      digit_count = digit_count + 1
      rest = rest / 10
    end do
  end function digit_count

  !> Every dataset's description in one text, for a caller that reads
  !> them all: a record each, ended by record_end, of fields ended by
  !> field_end: group, name, units, long name, dimensions (space-separated),
  !> kind (1 real, 2 integer, 3 text), bytes per value, shape
  !> (space-separated), the other attributes.
  subroutine write_catalog(out)
    type(memory_output_t), intent(inout) :: out
    integer :: d, k, itemsize
    integer(i8) :: n
    ! (built in place, without a formatted write: a run of a short case
    ! should not spend as long on this as on integrating)
    allocate (character(len=4096) :: out%catalog)
    n = 0
    do d = 1, out%n
      associate (ds => out%datasets(d))
        itemsize = 8
        if (ds%kind == kind_text) itemsize = text_width
        ! (piece by piece, and substrings rather than trim(): a concatenation
        ! or a trim would allocate a temporary each)
        call append(ds%group(:len_trim(ds%group)), field_end)
        call append(ds%name(:len_trim(ds%name)), field_end)
        call append(ds%units(:len_trim(ds%units)), field_end)
        call append(ds%long_name(:len_trim(ds%long_name)), field_end)
        call append(ds%dims(1)(:len_trim(ds%dims(1))))
        do k = 2, ds%ndim
          call append(' ', ds%dims(k)(:len_trim(ds%dims(k))))
        end do
        call append(field_end, decimal_digits(int(ds%kind, i8)))
        call append(field_end, decimal_digits(int(itemsize, i8)))
        call append(field_end, decimal_digits(ds%shape(1)))
        do k = 2, ds%ndim
          call append(' ', decimal_digits(ds%shape(k)))
        end do
        call append(field_end)
        if (allocated(ds%attributes)) call append(ds%attributes)
        call append(field_end, record_end)
      end associate
    end do
    out%catalog = out%catalog(:n)
  contains
    !> piece, then second (if given), at the end of the catalog
    subroutine append(piece, second)
      character(len=*), intent(in) :: piece
      character(len=*), intent(in), optional :: second
      call append_one(piece)
      if (present(second)) call append_one(second)
    end subroutine append

    subroutine append_one(piece)
      character(len=*), intent(in) :: piece
      character(len=:), allocatable :: grown
      if (n + len(piece) > len(out%catalog)) then
        allocate (character(len=2 * (n + len(piece))) :: grown)
        grown(:n) = out%catalog(:n)
        call move_alloc(grown, out%catalog)
      end if
      out%catalog(n + 1:n + len(piece)) = piece
      n = n + len(piece)
    end subroutine append_one
  end subroutine write_catalog

  !> A count's decimal digits.
  pure function decimal_digits(value) result(text)
    integer(i8), intent(in) :: value
    character(len=digit_count(value)) :: text
    integer(i8) :: rest
    integer :: k
    rest = value
    do k = len(text), 1, -1
      text(k:k) = achar(iachar('0') + int(mod(rest, 10_i8)))
      rest = rest / 10
    end do
  end function decimal_digits

  !> A new dataset of group `group`, described by `entry`, at the end of the list.
  integer function add(out, group, entry, kind, dims, shape) result(d)
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: group
    type(named_value_t), intent(in) :: entry
    integer, intent(in) :: kind
    character(len=*), intent(in) :: dims(:)
    integer(i8), intent(in) :: shape(:)
    type(memory_dataset_t), allocatable :: grown(:)
    integer :: k
    if (out%n == size(out%datasets)) then
      allocate (grown(2 * out%n))
      do k = 1, out%n
        call move_dataset(out%datasets(k), grown(k))
      end do
      call move_alloc(grown, out%datasets)
    end if
    out%n = out%n + 1
    d = out%n
    associate (ds => out%datasets(d))
      ds%group = group
      ds%name = entry%name
      ds%units = entry%units
      ds%long_name = entry%description
      ds%kind = kind
      ds%ndim = size(dims)
      ds%dims(:size(dims)) = dims
      ds%shape(:size(shape)) = shape
    end associate
  end function add

  subroutine move_dataset(from, to)
    type(memory_dataset_t), intent(inout) :: from, to
    to%group = from%group
    to%name = from%name
    to%units = from%units
    to%long_name = from%long_name
    to%kind = from%kind
    to%ndim = from%ndim
    to%shape = from%shape
    to%dims = from%dims
    if (allocated(from%attributes)) call move_alloc(from%attributes, to%attributes)
    to%field = from%field
    to%taken = from%taken
    call move_alloc(from%reals, to%reals)
    call move_alloc(from%ints, to%ints)
    call move_alloc(from%texts, to%texts)
  end subroutine move_dataset

  subroutine add_attribute(ds, name, value, type)
    type(memory_dataset_t), intent(inout) :: ds
    character(len=*), intent(in) :: name, value
    character(len=*), intent(in), optional :: type
    character(len=3) :: value_type
    value_type = 'str'
    if (present(type)) value_type = type
    if (.not. allocated(ds%attributes)) ds%attributes = ''
    ds%attributes = ds%attributes // name // tab // trim(value_type) // tab // value // newline
  end subroutine add_attribute

  pure function int_list(values) result(text)
    integer(i8), intent(in) :: values(:)
    character(len=21 * size(values)) :: text
    integer :: k
    text = ''
    do k = 1, size(values)
      text = trim(text) // ' ' // itoa(values(k))
    end do
    text = adjustl(text)
  end function int_list

  pure integer function count_special(text)
    character(len=*), intent(in) :: text
    integer :: k
    count_special = 0
    do k = 1, len(text)
      if (text(k:k) == '\' .or. text(k:k) == newline) count_special = count_special + 1
    end do
  end function count_special

  !> A text on one line: backslash and newline written as \\ and \n.
  pure function escaped(text) result(line)
    character(len=*), intent(in) :: text
    character(len=len(text) + count_special(text)) :: line
    integer :: k, pos
    pos = 0
    do k = 1, len(text)
      select case (text(k:k))
      case ('\')
        line(pos + 1:pos + 2) = '\\'
        pos = pos + 2
      case (newline)
        line(pos + 1:pos + 2) = '\n'
        pos = pos + 2
      case default
        line(pos + 1:pos + 1) = text(k:k)
        pos = pos + 1
      end select
    end do
  end function escaped

  !> The values of real dataset d, in Fortran's order, into `values`
  !> (a trajectory: each case's samples, NaN for a case never integrated).
  subroutine read_reals(self, d, values)
    class(memory_output_t), intent(in) :: self
    integer, intent(in) :: d
    real(wp), intent(out) :: values(:)
    integer(i8) :: i, per_case
    integer :: f
    associate (ds => self%datasets(d))
      if (ds%field == 0) then
        values = ds%reals
        return
      end if
      f = ds%field
      per_case = field_ncomp(f) * self%n_samples
      do i = 0, size(self%results, kind=i8) - 1
        if (allocated(self%results(i)%fields(f)%values)) then
          call copy_flat(self%results(i)%fields(f)%values, per_case, values(i * per_case + 1:(i + 1) * per_case))
        else
          values(i * per_case + 1:(i + 1) * per_case) = ieee_value(0.0_wp, ieee_quiet_nan)
        end if
      end do
    end associate
  end subroutine read_reals

  !> The values of an array of any shape, in array element order.
  subroutine copy_flat(from, n, to)
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: from(n)
    real(wp), intent(out) :: to(n)
    to = from
  end subroutine copy_flat

  !> A /case or /summary entry of a row as a dataset of `group`: one value,
  !> one per mode or an xyz vector per case.
  integer function add_entry(out, group, entry, n_cases) result(d)
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: group
    type(named_value_t), intent(in) :: entry
    integer(i8), intent(in) :: n_cases
    select case (entry%ncomp)
    case (1)
      d = add(out, group, entry, entry%kind, ['case'], [n_cases])
    case (2)
      d = add(out, group, entry, entry%kind, [character(len=8) :: 'case', 'mode'], [n_cases, 2_i8])
    case default
      d = add(out, group, entry, entry%kind, [character(len=8) :: 'case', 'xyz'], [n_cases, 3_i8])
    end select
  end function add_entry

  !> A group's case scale (the cases' indices).
  subroutine case_scale(out, group, indices)
    type(memory_output_t), intent(inout) :: out
    character(len=*), intent(in) :: group
    integer(i8), intent(in) :: indices(:)
    integer :: d
    d = add(out, group, case_entry, kind_int, ['case'], [size(indices, kind=i8)])
    out%datasets(d)%ints = indices
  end subroutine case_scale

  !> The CF attribute naming a dataset's auxiliary coordinates, if any.
  subroutine name_coordinates(ds, coordinate_names)
    type(memory_dataset_t), intent(inout) :: ds
    character(len=*), intent(in) :: coordinate_names
    if (len(coordinate_names) > 0) call add_attribute(ds, 'coordinates', coordinate_names)
  end subroutine name_coordinates
end module ellroll_memory_datasets
