!> The axes of a record on one time grid: each axis sampled at its own
!> step, linear between its samples, at rest one step past its last.
module ellroll_record_axes
  use ellroll_kinds, only: wp
  use ellroll_exact, only: equals
  implicit none
  private

  public :: axis_record_t, merge_axes

  !> One axis of a record: samples at t = (k - 1) step, in m/s^2.
  type :: axis_record_t
    real(wp) :: step = 0
    real(wp), allocatable :: values(:)
  end type axis_record_t

contains

  !> The axes on one grid: the union of their sample times. Each axis is
  !> linear between its samples and, past its last, falls to zero over one
  !> step and stays there (the ground at rest). Axes sampled alike share
  !> their grid exactly: that grid is taken as it is (the same times and
  !> values as the union, without its search).
  subroutine merge_axes(axes, times, values)
    type(axis_record_t), intent(in) :: axes(3)
    real(wp), allocatable, intent(out) :: times(:), values(:, :)
    real(wp), allocatable :: grid(:)
    integer :: k, a, n
    if (all(equals(axes%step, axes(1)%step))) then
      n = maxval([(size(axes(a)%values), a = 1, 3)])
      allocate (times(n + 1), values(3, n + 1))
      do k = 1, n + 1
        times(k) = real(k - 1, wp) * axes(1)%step
      end do
      values = 0
      do a = 1, 3
        values(a, :size(axes(a)%values)) = axes(a)%values
      end do
      return
    end if
    allocate (times(0))
    do a = 1, 3
      grid = [(real(k - 1, wp) * axes(a)%step, k = 1, size(axes(a)%values) + 1)]
      times = union_sorted(times, grid)
    end do
    allocate (values(3, size(times)))
    do a = 1, 3
      do k = 1, size(times)
        values(a, k) = axis_value(axes(a), times(k))
      end do
    end do
  end subroutine merge_axes

  !> Axis a at time t: its samples, linear between them, zero one step past
  !> the last.
  pure real(wp) function axis_value(axis, t) result(value)
    type(axis_record_t), intent(in) :: axis
    real(wp), intent(in) :: t
    real(wp) :: position, weight, left, right
    integer :: k, n
    n = size(axis%values)
    value = 0
    position = t / axis%step
    if (.not. position < n + 1) return     ! at rest (and no integer overflow below)
    k = int(position) + 1                  ! t in [(k - 1) step, k step)
    if (k > 1 .and. real(k - 1, wp) * axis%step > t) k = k - 1
    if (real(k, wp) * axis%step <= t) k = k + 1
    left = 0
    right = 0
    if (k <= n) left = axis%values(k)
    if (k + 1 <= n) right = axis%values(k + 1)
    value = left
    ! (at its own sample, the sample itself: a fused multiply-add in the
    ! weight would leave the product's rounding error there)
    if (equals(t, real(k - 1, wp) * axis%step)) return
    weight = (t - real(k - 1, wp) * axis%step) / axis%step
    value = (1 - weight) * left + weight * right
  end function axis_value

  !> The sorted union of two sorted lists, equal entries once.
  pure function union_sorted(first, second) result(merged)
    real(wp), intent(in) :: first(:), second(:)
    real(wp), allocatable :: merged(:)
    real(wp), allocatable :: buffer(:)
    integer :: i, j, n
    allocate (buffer(size(first) + size(second)))
    i = 1
    j = 1
    n = 0
    do while (i <= size(first) .or. j <= size(second))
      n = n + 1
      if (j > size(second)) then
        buffer(n) = first(i)
        i = i + 1
      else if (i > size(first)) then
        buffer(n) = second(j)
        j = j + 1
      else if (first(i) < second(j)) then
        buffer(n) = first(i)
        i = i + 1
      else
        if (.not. second(j) < first(i)) i = i + 1        ! equal: once
        buffer(n) = second(j)
        j = j + 1
      end if
    end do
    merged = buffer(:n)
  end function union_sorted
end module ellroll_record_axes
