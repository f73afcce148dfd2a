!> Record values read by ellroll_decimal equal, bit for bit, what Fortran's
!> own read gives for the same text (the F editing of AT2 values, the
!> list-directed read of CSV rows): seeded random texts in the forms records
!> use (E15.7 fields such as '-0.1234567E+00' and '.1234E-02', exponents
!> beyond 99 as Fortran writes them, '.1234567-100', 17 significant
!> digits, long mantissas of up to 60 digits, integers, D exponents) over
!> the whole range of doubles, subnormals and the edges of overflow
!> included, and the hard cases of rounding (halfway between two doubles).
!> Texts that are not numbers are refused, and none raises a floating-point
!> trap (the Debug build traps overflow).
program test_decimal
  use, intrinsic :: ieee_arithmetic, only: ieee_set_halting_mode, ieee_set_flag, ieee_overflow, ieee_all, &
      ieee_is_finite
  use ellroll_kinds, only: wp, i8
  use ellroll_decimal, only: decimal_value, decimal_ok, decimal_invalid, decimal_too_long
  use ellroll_strings, only: itoa
  use testing, only: check, finish
  implicit none
  integer, parameter :: random_texts = 200000
  character(len=*), parameter :: fixed(*) = [character(len=60) :: &
      '.1234E-02', '-0.12345678E+00', '  ', '0', '-0', '+0.0', '-.0E+00', '5.', '.5', '-.5e-3', '+1', &
      '1d-3', '1.5D+03', '-2.0d0', '123456789012345678901234567890', '9007199254740993', &
      '9007199254740993.00000000000000000000000001', '9007199254740992.99999999999999999999999999', &
      '0.1', '0.2', '0.3', '1e23', '8.589973e9', '2.2250738585072011e-308', '2.2250738585072012e-308', &
      '2.2250738585072014E-308', '4.9406564584124654E-324', '2.4703282292062327e-324', &
      '2.4703282292062328e-324', '1e-400', '-1e-400', '1.7976931348623157E+308', &
      '1.7976931348623158e+308', '1.797693134862315807e308', '1.7976931348623159e308', '1e309', '-1e309', &
      '1E+99999', '1e-99999', '0e99999', '7.2057594037927933e16', '5e-324', '3e-324', '1.0000000000000002', &
      '1.00000000000000011102230246251565404236316680908203125', &
      '1.00000000000000011102230246251565404236316680908203124', &
      '0.000000000000000000000000000000000000000000000000001e+50', '1.0+03', '.1000000-100', &
      '-0.1234567+101', '1-5', '2.5-0']
  character(len=*), parameter :: not_numbers(*) = [character(len=12) :: &
      '1e', 'e5', '.', '-', '+', '1.2.3', '1e+', '0x1p3', 'inf', 'nan', '-Infinity', '1,5', '1 5', '--1', &
      '1e5.0', '1.0+', '2*0.5', '1/2', '.e1', '+-1', '1e--3', '1q3', '1_wp', 'E', 'd1']
  integer(i8) :: state = 20260415_i8
  integer :: k, code, n_equal, n_compared, n_compared_f, n_list_equal, n_refused, n_read, n_texts
  real(wp) :: value
  character(len=100) :: text
  character(len=120) :: first_difference

  ! on the edges of overflow, with the Debug build's traps on: no trap
  do k = 1, size(fixed)
    code = decimal_value(trim(adjustl(fixed(k))), value)
  end do
  n_refused = 0
  do k = 1, size(not_numbers)
    if (decimal_value(trim(not_numbers(k)), value) == decimal_invalid) n_refused = n_refused + 1
  end do
  call check(n_refused == size(not_numbers), 'texts that are not decimal numbers are refused: ' // &
             itoa(n_refused) // ' of ' // itoa(size(not_numbers)))
  call check(decimal_value('', value) == decimal_invalid, 'an empty text is refused')
  call check(decimal_value(repeat('1', 101), value) == decimal_too_long, 'a number of 101 characters is refused')
  call check(decimal_value(repeat('1', 100), value) == decimal_ok, 'a number of 100 characters is read')
  code = decimal_value('1e309', value)
  call check(code == decimal_ok .and. .not. ieee_is_finite(value) .and. value > 0, '1e309 reads as +Inf')

  ! Fortran's read raises overflow where it gives Inf: the comparison runs without traps
  call ieee_set_halting_mode(ieee_overflow, .false.)
  n_equal = 0
  n_list_equal = 0
  n_compared = 0
  n_compared_f = 0
  n_read = 0
  first_difference = ''
  n_texts = random_texts
  do k = 1, size(fixed)
    if (len_trim(fixed(k)) == 0) cycle
    call compare(trim(adjustl(fixed(k))))
    n_texts = n_texts + 1
  end do
  do k = 1, random_texts
    call random_text(text)
    call compare(trim(text))
  end do
  print '(a, i0, a, i0, a)', 'compared ', n_compared, ' texts with the list-directed read, ', n_compared_f, &
      ' with the F editing'
  call check(n_read == n_texts .and. n_compared == n_texts .and. n_compared_f >= n_texts - 3, &
             'every text is a number to both (' // itoa(n_read) // ', ' // itoa(n_compared) // ', ' // &
             itoa(n_compared_f) // ' of ' // itoa(n_texts) // ')')
  call ieee_set_flag(ieee_all, .false.)     ! (raised by Fortran's reads beyond the doubles)
  call check(n_equal == n_compared_f, 'every value equals the F editing read bitwise (' // itoa(n_equal) // &
             ' of ' // itoa(n_compared_f) // ')' // trim(first_difference))
  call check(n_list_equal == n_compared, 'every value equals the list-directed read bitwise (' // &
             itoa(n_list_equal) // ' of ' // itoa(n_compared) // ')' // trim(first_difference))
  call finish('test_decimal')

contains

  !> One text read three ways, compared where Fortran's read takes it (F
  !> editing refuses exponents of five digits; the list-directed read
  !> takes them, as ellroll does, giving Inf or 0). The F editing reads a
  !> field of 100 characters.
  subroutine compare(word)
    character(len=*), intent(in) :: word
    real(wp) :: by_f, by_list, fast
    integer :: ios_f, ios_list
    character(len=100) :: field
    field = word
    read (field, '(f100.0)', iostat=ios_f) by_f
    read (field, *, iostat=ios_list) by_list
    code = decimal_value(word, fast)
    if (code == decimal_ok) n_read = n_read + 1
    if (ios_f == 0) then
      n_compared_f = n_compared_f + 1
      if (code == decimal_ok .and. transfer(by_f, 0_i8) == transfer(fast, 0_i8)) then
        n_equal = n_equal + 1
      else if (len_trim(first_difference) == 0) then
        first_difference = ': first difference ' // word
      end if
    end if
    if (ios_list == 0) then
      n_compared = n_compared + 1
      if (code == decimal_ok .and. transfer(by_list, 0_i8) == transfer(fast, 0_i8)) then
        n_list_equal = n_list_equal + 1
      else if (len_trim(first_difference) == 0) then
        first_difference = ': first difference ' // word
      end if
    end if
  end subroutine compare

  !> The next of a seeded sequence (xorshift64: shifts and exclusive ors,
  !> no integer overflow), in [0, n).
  integer function below(n)
    integer, intent(in) :: n
    state = ieor(state, ishft(state, 13))
    state = ieor(state, ishft(state, -7))
    state = ieor(state, ishft(state, 17))
    below = int(modulo(ishft(state, -1), int(n, i8)))
  end function below

  !> n random decimal digits.
  function random_digits(n) result(text)
    integer, intent(in) :: n
    character(len=n) :: text
    integer :: k
    do k = 1, n
      text(k:k) = achar(iachar('0') + below(10))
    end do
  end function random_digits

  !> A number as records write them, in one of several forms, its decimal
  !> exponent anywhere from the subnormals to overflow.
  subroutine random_text(text)
    character(len=*), intent(out) :: text
    character(len=1) :: sign, letter
    integer :: exponent10
    integer(i8) :: spacing, midpoint, bits
    real(wp) :: x
    sign = merge('-', ' ', below(2) == 0)
    if (below(5) == 0) sign = '+'
    letter = 'E'
    if (below(8) == 0) letter = 'e'
    if (below(16) == 0) letter = 'D'
    select case (below(8))
    case (0)             ! PEER's E15.7 and E14.4: '-0.1234567E+00', '.1234E-02'
      exponent10 = below(61) - 30
      text = trim(sign) // trim(merge('0.', '. ', below(2) == 0)) // random_digits(4 + below(5)) // letter // &
             merge('-', '+', exponent10 < 0) // itoa(abs(exponent10) / 10) // itoa(mod(abs(exponent10), 10))
    case (1)             ! a double written with 17 significant digits, anywhere in range
      bits = int(below(2147483647), i8) * 4294967296_i8 + int(below(2147483647), i8)
      if (ibits(bits, 52, 11) == 2047) bits = ibclr(bits, 62)          ! not Inf or NaN
      x = transfer(bits, 1.0_wp)
      write (text, '(es25.16e3)') x
      text = adjustl(text)
    case (2)             ! a long mantissa near the subnormals and near overflow
      exponent10 = merge(-330 + below(30), 280 + below(29), below(2) == 0)
      text = trim(sign) // random_digits(1) // '.' // random_digits(15 + below(45)) // letter // itoa(exponent10)
    case (3)             ! integers, up to 30 digits
      text = trim(sign) // random_digits(1 + below(30))
    case (4)             ! halfway between two doubles (an integer of 16 to 19 digits), or just beside
      exponent10 = 53 + below(10)                       ! the doubles in [2^e, 2^(e+1)) are 2^(e-52) apart
      spacing = 2_i8**(exponent10 - 52)
      midpoint = 2_i8**exponent10 + spacing * int(below(1073741824), i8) + spacing / 2
      select case (below(3))
      case (0)
        text = trim(sign) // itoa(midpoint)
      case (1)
        text = trim(sign) // itoa(midpoint) // '.' // repeat('0', below(30)) // '1'
      case default
        text = trim(sign) // itoa(midpoint - 1) // '.' // repeat('9', 1 + below(30))
      end select
    case (5)             ! decimals with points in odd places
      text = trim(sign) // random_digits(below(8)) // '.' // random_digits(1 + below(12))
      if (below(2) == 0) text = trim(text) // letter // itoa(below(40) - 20)
    case (6)             ! a letterless exponent, as Fortran's E editing writes exponents beyond 99
      exponent10 = below(631) - 330
      text = trim(sign) // '0.' // random_digits(7) // merge('-', '+', exponent10 < 0) // itoa(abs(exponent10))
    case default         ! subnormals with up to 60 digits
      text = trim(sign) // '0.' // random_digits(below(40)) // random_digits(1 + below(20)) // letter // itoa(-290 - below(40))
    end select
  end subroutine random_text
end program test_decimal
