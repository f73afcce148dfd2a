!> "Did you mean": the nearest of a list of known names to a name given,
!> within two edits (Damerau-Levenshtein, optimal string alignment: an
!> insertion, deletion, substitution or swap of two neighbours is one edit),
!> or one that starts or ends with it (or it with one).
module ellroll_suggest
  implicit none
  private

  public :: edit_distance, nearest_name, did_you_mean

  integer, parameter, public :: suggest_within = 2

contains

  !> Edits from a to b (case-sensitive; trailing blanks count).
  pure integer function edit_distance(a, b) result(d)
    character(len=*), intent(in) :: a, b
    integer :: row(0:len(b)), prev(0:len(b)), prev2(0:len(b))
    integer :: i, j, cost
    prev2 = 0
    prev = [(j, j = 0, len(b))]
    row = prev
    do i = 1, len(a)
      row(0) = i
      do j = 1, len(b)
        cost = merge(0, 1, a(i:i) == b(j:j))
        row(j) = min(prev(j) + 1, row(j - 1) + 1, prev(j - 1) + cost)
        if (i > 1 .and. j > 1) then
          if (a(i:i) == b(j-1:j-1) .and. a(i-1:i-1) == b(j:j)) row(j) = min(row(j), prev2(max(j - 2, 0)) + 1)
        end if
      end do
      prev2 = prev
      prev = row
    end do
    d = prev(len(b))
  end function edit_distance

  !> The index in known of the name nearest to name (trailing blanks of both
  !> ignored): the fewest edits, at most suggest_within and fewer than the
  !> name's length; else the first that starts or ends with name or that
  !> name starts or ends with (names of 3 characters or more); else 0. Of
  !> names equally near, the first that holds every letter of name in order.
  pure integer function nearest_name(name, known) result(best)
    character(len=*), intent(in) :: name
    character(len=*), intent(in) :: known(:)
    integer :: k, d, best_d, n, m
    best = 0
    n = len_trim(name)
    if (n == 0) return
    best_d = suggest_within + 1
    do k = 1, size(known)
      m = len_trim(known(k))
      if (m == 0) cycle
      d = edit_distance(name(:n), known(k)(:m))
      if (d >= n .or. d == 0 .or. d > best_d .or. d > suggest_within) cycle
      ! a tie goes to a name that holds every letter given (letters left out
      ! are the commoner slip): omegaz is omega_z rather than omega
      if (d == best_d) then
        if (.not. subsequence(name(:n), known(k)(:m)) .or. subsequence(name(:n), trim(known(best)))) cycle
      end if
      best = k
      best_d = d
    end do
    if (best > 0 .or. n < 3) return
    do k = 1, size(known)
      m = len_trim(known(k))
      if (m < 3 .or. known(k)(:m) == name(:n)) cycle
      if (affix(name(:n), known(k)(:m)) .or. affix(known(k)(:m), name(:n))) then
        best = k
        return
      end if
    end do
  contains
    !> Whether short's letters appear in long in order.
    pure logical function subsequence(short, long)
      character(len=*), intent(in) :: short, long
      integer :: i, j
      j = 1
      do i = 1, len(long)
        if (j > len(short)) exit
        if (long(i:i) == short(j:j)) j = j + 1
      end do
      subsequence = j > len(short)
    end function subsequence

    pure logical function affix(short, long)
      character(len=*), intent(in) :: short, long
      affix = .false.
      if (len(short) >= len(long)) return
      affix = long(:len(short)) == short .or. long(len(long) - len(short) + 1:) == short
    end function affix
  end function nearest_name

  !> '; did you mean PREFIX//NEAREST?' for the nearest known name, or ''.
  pure subroutine did_you_mean(name, known, prefix, text)
    character(len=*), intent(in) :: name, prefix
    character(len=*), intent(in) :: known(:)
    character(len=:), allocatable, intent(out) :: text
    integer :: k
    k = nearest_name(name, known)
    text = ''
    if (k > 0) text = '; did you mean ' // prefix // trim(known(k)) // '?'
  end subroutine did_you_mean
end module ellroll_suggest
