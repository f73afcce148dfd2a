!> The edit distance of "did you mean" against known distances (identities,
!> one edit of each kind, a swap of neighbours as one edit, the classic
!> kitten/sitting = 3), its symmetry and bounds over seeded
!> random words, and nearest_name on misspellings of real input names.
program test_suggest
  use ellroll_kinds, only: wp, i8
  use ellroll_suggest, only: edit_distance, nearest_name
  use testing, only: check, finish
  implicit none
  character(len=*), parameter :: names(*) = [character(len=14) :: &
      'omega', 'omega_x', 'omega_z', 'radius', 'weight', 'mass', 'mu', 'inertia_factor', 'threads']
  integer(i8) :: state = 20261125_i8
  character(len=8) :: w(3)
  integer :: k, j, n

  call check(edit_distance('', '') == 0, 'empty strings')
  call check(edit_distance('abc', '') == 3, 'deletions to empty')
  call check(edit_distance('', 'abcd') == 4, 'insertions from empty')
  call check(edit_distance('radius', 'radius') == 0, 'identical')
  call check(edit_distance('radus', 'radius') == 1, 'one insertion')
  call check(edit_distance('radiuss', 'radius') == 1, 'one deletion')
  call check(edit_distance('radiux', 'radius') == 1, 'one substitution')
  call check(edit_distance('raidus', 'radius') == 1, 'a swap of neighbours is one edit')
  call check(edit_distance('omegaz', 'omega_z') == 1, 'omegaz')
  call check(edit_distance('kitten', 'sitting') == 3, 'kitten/sitting')
  call check(edit_distance('ca', 'abc') == 3, 'optimal string alignment: ca/abc')
  call check(edit_distance('flaw', 'lawn') == 2, 'flaw/lawn')

  do k = 1, 2000
    do j = 1, 3
      call random_word(w(j), n)
    end do
    call check(edit_distance(trim(w(1)), trim(w(2))) == edit_distance(trim(w(2)), trim(w(1))), 'symmetric')
    call check(edit_distance(trim(w(1)), trim(w(2))) <= max(len_trim(w(1)), len_trim(w(2))), 'at most the longer')
    call check(edit_distance(trim(w(1)), trim(w(2))) >= abs(len_trim(w(1)) - len_trim(w(2))), &
               'at least the length difference')
  end do

  call check(nearest_name('omegaz', names) == 3, 'omegaz -> omega_z')
  call check(nearest_name('radus', names) == 4, 'radus -> radius')
  call check(nearest_name('thread', names) == 9, 'thread -> threads')
  call check(nearest_name('inertia', names) == 8, 'prefix: inertia -> inertia_factor')
  call check(nearest_name('zzzzzz', names) == 0, 'nothing near')
  call check(nearest_name('m', names) == 0, 'one letter suggests nothing')
  call finish('suggest')
contains
  !> A seeded word of 0 to 8 letters from a small alphabet (many near pairs).
  subroutine random_word(word, n)
    character(len=*), intent(out) :: word
    integer, intent(out) :: n
    integer :: i
    word = ''
    n = int(next() * 9)
    do i = 1, n
      word(i:i) = achar(iachar('a') + int(next() * 4))
    end do
  end subroutine random_word
  real(wp) function next()
    state = modulo(state * 48271_i8, 2147483647_i8)      ! Park-Miller: no overflow in 64 bits
    next = real(state, wp) / 2147483647.0_wp
  end function next
end program test_suggest
