!> The C interface of libellroll: run an input's namelist text into memory
!> (ellroll_memory_run) and read the results back, dataset by dataset, as
!> the output file lays them out. A run gives a handle, whatever happened;
!> its error code is the class `ellroll run` exits with (0 none, 1
!> internal, 2 bad input) and its message the one the program prints after
!> 'ellroll: error: '. Nothing here stops the process or prints; calls on
!> different handles may run at the same time. Free each handle once.
!>
!>   void *ellroll_run(const char *text, int64_t text_length,
!>                     const char *label, int64_t label_length, int threads);
!>   int ellroll_error_code(void *h);
!>   int64_t ellroll_error_message(void *h, char *buffer, int64_t size);
!>   int ellroll_dataset_count(void *h);
!>   int64_t ellroll_dataset_text(void *h, int i, int what, char *buffer, int64_t size);
!>   int64_t ellroll_catalog(void *h, char *buffer, int64_t size);
!>   int ellroll_dataset_info(void *h, int i, int *kind, int *itemsize, int *ndim, int64_t shape[3]);
!>   int ellroll_dataset_read(void *h, int i, void *buffer, int64_t size);
!>   int ellroll_read_all(void *h, int n, void *const *addresses);
!>   int ellroll_take(void *h, int n, const int *want, void **owners, void **addresses);
!>   void ellroll_free_values(void *owner);
!>   void ellroll_free(void *h);
!>   void ellroll_init(void);
!>   void ellroll_stop(int sig);
!>
!> Texts are copied into (buffer, size), cut to size, without a null; the
!> functions return their full length. Datasets count from 0; `what`: 0
!> group ('' for the root), 1 name, 2 units, 3 long name, 4 dimensions
!> (space-separated), 5 other attributes (a line 'NAME<tab>TYPE<tab>VALUE'
!> each, TYPE str, i1, i4 or i8 for integers, f8 for doubles); i = -1 with what = 5: the root's attributes.
!> kind: 1 float64, 2 int64, 3 text (itemsize bytes each, blank-padded);
!> values in C order, shape[0] cases (or samples, components) first. A
!> caller may take a dataset's values out of the run instead of copying
!> them (ellroll_take), and free them on their own, before or after the
!> handle (ellroll_free_values). ellroll_stop(sig) asks every run of the
!> process under way to stop, as `ellroll run` does on that signal (a
!> caller's Ctrl-C): each returns soon with error code 128 + sig and no
!> results; ellroll_stop(0), once none is under way, lets runs go on again.
module ellroll_capi
  use, intrinsic :: iso_c_binding, only: c_ptr, c_associated, c_loc, c_f_pointer, c_int, c_int64_t, &
      c_char, c_double, c_null_char, c_null_ptr
  use ellroll_kinds, only: i8
  use ellroll_errors, only: err_none
  use ellroll_records, only: kind_real, kind_int, kind_text
  use ellroll_system, only: request_stop
  use ellroll_memory_run, only: memory_output_t, memory_dataset_t, run_in_memory, text_width
  implicit none
  private

  public :: ellroll_run, ellroll_error_code, ellroll_error_message, ellroll_dataset_count, ellroll_dataset_text, &
            ellroll_dataset_info, ellroll_dataset_read, ellroll_free, ellroll_init, ellroll_catalog, ellroll_read_all, &
            ellroll_take, ellroll_free_values, ellroll_stop

  !> A dataset's values taken out of its run (ellroll_take): one of them allocated.
  type :: taken_t
    real(c_double), allocatable :: field(:, :)      !< a trajectory, (components, samples)
    real(c_double), allocatable :: reals(:)
    integer(c_int64_t), allocatable :: ints(:)
  end type taken_t

  interface
    subroutine crc32c_init() bind(c, name='ellroll_crc32c_init')
    end subroutine crc32c_init
  end interface

contains

  !> Once, before any run (the checksums of record files choose their code then).
  subroutine ellroll_init() bind(c, name='ellroll_init')
    call crc32c_init()
  end subroutine ellroll_init

  !> Ask every run under way to stop as if signal sig had come; 0: go on again.
  subroutine ellroll_stop(sig) bind(c, name='ellroll_stop')
    integer(c_int), value, intent(in) :: sig
    call request_stop(sig)
  end subroutine ellroll_stop

  type(c_ptr) function ellroll_run(text, text_length, label, label_length, threads) result(handle) &
      bind(c, name='ellroll_run')
    integer(c_int64_t), value, intent(in) :: text_length, label_length
    character(kind=c_char), intent(in) :: text(text_length), label(label_length)
    integer(c_int), value, intent(in) :: threads
    type(memory_output_t), pointer :: out
    ! on the heap: a caller's thread may have a small stack, and a text may be large
    character(len=:), allocatable :: text_string, label_string
    integer(i8) :: k
    allocate (character(len=text_length) :: text_string)
    allocate (character(len=label_length) :: label_string)
    do k = 1, text_length
      text_string(k:k) = text(k)
    end do
    do k = 1, label_length
      label_string(k:k) = label(k)
    end do
    allocate (out)
    call run_in_memory(label_string, text_string, int(max(0_c_int, threads)), out)
    handle = c_loc(out)
  end function ellroll_run

  subroutine ellroll_free(handle) bind(c, name='ellroll_free')
    type(c_ptr), value, intent(in) :: handle
    type(memory_output_t), pointer :: out
    if (.not. c_associated(handle)) return
    call c_f_pointer(handle, out)
    deallocate (out)
  end subroutine ellroll_free

  integer(c_int) function ellroll_error_code(handle) result(code) bind(c, name='ellroll_error_code')
    type(c_ptr), value, intent(in) :: handle
    type(memory_output_t), pointer :: out
    code = err_none
    if (.not. output_of(handle, out)) return
    code = int(out%err%code, c_int)
  end function ellroll_error_code

  integer(c_int64_t) function ellroll_error_message(handle, buffer, size) result(length) &
      bind(c, name='ellroll_error_message')
    type(c_ptr), value, intent(in) :: handle
    integer(c_int64_t), value, intent(in) :: size
    character(kind=c_char), intent(inout) :: buffer(size)
    type(memory_output_t), pointer :: out
    length = 0
    if (.not. output_of(handle, out)) return
    if (.not. out%err%failed()) return
    length = copy_text(out%err%message, buffer)
  end function ellroll_error_message

  integer(c_int) function ellroll_dataset_count(handle) result(n) bind(c, name='ellroll_dataset_count')
    type(c_ptr), value, intent(in) :: handle
    type(memory_output_t), pointer :: out
    n = 0
    if (.not. output_of(handle, out)) return
    n = int(out%n, c_int)
  end function ellroll_dataset_count

  integer(c_int64_t) function ellroll_dataset_text(handle, i, what, buffer, size) result(length) &
      bind(c, name='ellroll_dataset_text')
    type(c_ptr), value, intent(in) :: handle
    integer(c_int), value, intent(in) :: i, what
    integer(c_int64_t), value, intent(in) :: size
    character(kind=c_char), intent(inout) :: buffer(size)
    type(memory_output_t), pointer :: out
    character(len=32) :: dims
    integer :: k
    length = -1
    if (.not. output_of(handle, out)) return
    if (i == -1 .and. what == 5 .and. allocated(out%attributes)) then
      length = copy_text(out%attributes, buffer)
      return
    end if
    if (i < 0 .or. i >= out%n) return
    associate (ds => out%datasets(i + 1))
      select case (what)
      case (0); length = copy_text(trim(ds%group), buffer)
      case (1); length = copy_text(trim(ds%name), buffer)
      case (2); length = copy_text(trim(ds%units), buffer)
      case (3); length = copy_text(trim(ds%long_name), buffer)
      case (4)
        dims = ds%dims(1)
        do k = 2, ds%ndim
          dims = trim(dims) // ' ' // ds%dims(k)
        end do
        length = copy_text(trim(dims), buffer)
      case (5)
        length = 0
        if (allocated(ds%attributes)) length = copy_text(ds%attributes, buffer)
      end select
    end associate
  end function ellroll_dataset_text

  !> Every dataset's description in one text (write_catalog in
  !> ellroll_memory_run): what ellroll_dataset_text and ellroll_dataset_info
  !> give, in one call.
  integer(c_int64_t) function ellroll_catalog(handle, buffer, size) result(length) bind(c, name='ellroll_catalog')
    type(c_ptr), value, intent(in) :: handle
    integer(c_int64_t), value, intent(in) :: size
    character(kind=c_char), intent(inout) :: buffer(size)
    type(memory_output_t), pointer :: out
    length = -1
    if (.not. output_of(handle, out)) return
    length = 0
    if (allocated(out%catalog)) length = copy_text(out%catalog, buffer)
  end function ellroll_catalog

  integer(c_int) function ellroll_dataset_info(handle, i, kind, itemsize, ndim, shape) result(status) &
      bind(c, name='ellroll_dataset_info')
    type(c_ptr), value, intent(in) :: handle
    integer(c_int), value, intent(in) :: i
    integer(c_int), intent(out) :: kind, itemsize, ndim
    integer(c_int64_t), intent(out) :: shape(3)
    type(memory_output_t), pointer :: out
    status = -1
    kind = 0; itemsize = 0; ndim = 0; shape = 0
    if (.not. output_of(handle, out)) return
    if (i < 0 .or. i >= out%n) return
    associate (ds => out%datasets(i + 1))
      kind = int(ds%kind, c_int)
      itemsize = 8
      if (ds%kind == kind_text) itemsize = text_width
      ndim = int(ds%ndim, c_int)
      shape = ds%shape
    end associate
    status = 0
  end function ellroll_dataset_info

  !> Copy dataset i's values into buffer, which holds `size` bytes: exactly
  !> what the dataset holds (else -1, and nothing copied).
  integer(c_int) function ellroll_dataset_read(handle, i, buffer, size) result(status) &
      bind(c, name='ellroll_dataset_read')
    type(c_ptr), value, intent(in) :: handle
    integer(c_int), value, intent(in) :: i
    type(c_ptr), value, intent(in) :: buffer
    integer(c_int64_t), value, intent(in) :: size
    type(memory_output_t), pointer :: out
    status = -1
    if (.not. output_of(handle, out)) return
    if (i < 0 .or. i >= out%n .or. .not. c_associated(buffer)) return
    if (size /= dataset_bytes(out%datasets(i + 1)) .or. out%datasets(i + 1)%taken) return
    call fill(out, i + 1, buffer, .false.)
    status = 0
  end function ellroll_dataset_read

  !> Every dataset's values in one call (what ellroll_dataset_read gives,
  !> dataset by dataset): dataset i into addresses[i], which holds the
  !> bytes its catalog entry's shape and item size make, or nothing for a
  !> NULL there; texts as C strings, without their trailing white space and
  !> NUL after. -1, and nothing copied, for n not the dataset count or an
  !> address given for a dataset taken (ellroll_take).
  integer(c_int) function ellroll_read_all(handle, n, addresses) result(status) bind(c, name='ellroll_read_all')
    type(c_ptr), value, intent(in) :: handle
    integer(c_int), value, intent(in) :: n
    type(c_ptr), intent(in) :: addresses(*)
    type(memory_output_t), pointer :: out
    integer :: d
    status = -1
    if (.not. output_of(handle, out)) return
    if (n /= out%n) return
    do d = 1, out%n
      if (c_associated(addresses(d)) .and. out%datasets(d)%taken) return
    end do
    do d = 1, out%n
      if (c_associated(addresses(d))) call fill(out, d, addresses(d), .true.)
    end do
    status = 0
  end function ellroll_read_all

  !> Values handed over without a copy. Where a dataset wanted (want[i]
  !> /= 0) keeps its values in the library laid out as ellroll_dataset_read
  !> copies them, move them out of the run into an owner of their own,
  !> freed by ellroll_free_values(owner) and by nothing else: owners[i] the
  !> owner, addresses[i] the values, which a caller reads in place as long
  !> as it likes. NULL in both for a dataset not taken (not wanted, empty,
  !> a text, a trajectory of several cases, which exists only when copied
  !> out). A dataset taken reads as nothing after (ellroll_dataset_read and
  !> ellroll_read_all: -1). n: the dataset count (else -1, nothing taken).
  integer(c_int) function ellroll_take(handle, n, want, owners, addresses) result(status) bind(c, name='ellroll_take')
    type(c_ptr), value, intent(in) :: handle
    integer(c_int), value, intent(in) :: n
    integer(c_int), intent(in) :: want(*)
    type(c_ptr), intent(out) :: owners(*), addresses(*)
    type(memory_output_t), pointer :: out
    type(taken_t), pointer :: taken
    integer :: d, f
    status = -1
    if (.not. output_of(handle, out)) return
    if (n /= out%n) return
    do d = 1, out%n
      owners(d) = c_null_ptr
      addresses(d) = c_null_ptr
      if (want(d) == 0 .or. out%datasets(d)%taken) cycle
      f = out%datasets(d)%field
      if (f /= 0) then
        ! (one case: its trajectory is the dataset)
        if (size(out%results) /= 1) cycle
        if (.not. allocated(out%results(0)%fields(f)%values)) cycle
        allocate (taken)
        call move_alloc(out%results(0)%fields(f)%values, taken%field)
        addresses(d) = c_loc(taken%field)
      else if (allocated(out%datasets(d)%reals)) then
        if (size(out%datasets(d)%reals) == 0) cycle       ! (no address to give)
        allocate (taken)
        call move_alloc(out%datasets(d)%reals, taken%reals)
        addresses(d) = c_loc(taken%reals)
      else if (allocated(out%datasets(d)%ints)) then
        if (size(out%datasets(d)%ints) == 0) cycle
        allocate (taken)
        call move_alloc(out%datasets(d)%ints, taken%ints)
        addresses(d) = c_loc(taken%ints)
      else
        cycle
      end if
      out%datasets(d)%taken = .true.
      owners(d) = c_loc(taken)
    end do
    status = 0
  end function ellroll_take

  subroutine ellroll_free_values(owner) bind(c, name='ellroll_free_values')
    type(c_ptr), value, intent(in) :: owner
    type(taken_t), pointer :: taken
    if (.not. c_associated(owner)) return
    call c_f_pointer(owner, taken)
    deallocate (taken)
  end subroutine ellroll_free_values

  pure integer(i8) function dataset_bytes(ds) result(bytes)
    type(memory_dataset_t), intent(in) :: ds
    bytes = product(ds%shape(:ds%ndim))
    if (ds%kind == kind_text) then
      bytes = bytes * text_width
    else
      bytes = bytes * 8
    end if
  end function dataset_bytes

  !> Dataset d's values into the buffer at `address`, which holds them all
  !> (dataset_bytes); texts blank-padded, or as C strings.
  subroutine fill(out, d, address, c_strings)
    type(memory_output_t), intent(in) :: out
    integer, intent(in) :: d
    type(c_ptr), intent(in) :: address
    logical, intent(in) :: c_strings
    real(c_double), pointer :: reals(:)
    integer(c_int64_t), pointer :: ints(:)
    character(kind=c_char, len=text_width), pointer :: texts(:)
    integer(i8) :: n, k
    integer :: last
    associate (ds => out%datasets(d))
      n = product(ds%shape(:ds%ndim))
      select case (ds%kind)
      case (kind_real)
        call c_f_pointer(address, reals, [n])
        call out%read_reals(d, reals)
      case (kind_int)
        call c_f_pointer(address, ints, [n])
        ints = ds%ints
      case (kind_text)
        call c_f_pointer(address, texts, [n])
        if (.not. c_strings) then
          texts = ds%texts
          return
        end if
        do k = 1, n
          ! (white space as C's isspace: blank, tab, newline, VT, FF, CR)
          last = text_width
          do while (last > 0)
            if (all(ds%texts(k)(last:last) /= [' ', achar(9), achar(10), achar(11), achar(12), achar(13)])) exit
            last = last - 1
          end do
          texts(k) = ds%texts(k)(:last)
          texts(k)(last + 1:) = repeat(c_null_char, text_width - last)
        end do
      end select
    end associate
  end subroutine fill

  logical function output_of(handle, out)
    type(c_ptr), intent(in) :: handle
    type(memory_output_t), pointer, intent(out) :: out
    out => null()
    output_of = c_associated(handle)
    if (output_of) call c_f_pointer(handle, out)
  end function output_of

  !> Copy text into buffer, as much as fits; its full length.
  integer(c_int64_t) function copy_text(text, buffer) result(length)
    character(len=*), intent(in) :: text
    character(kind=c_char), intent(inout) :: buffer(:)
    integer(i8) :: k
    length = len(text, kind=c_int64_t)
    do k = 1, min(len(text, kind=i8), size(buffer, kind=i8))
      buffer(k) = text(k:k)
    end do
  end function copy_text
end module ellroll_capi
