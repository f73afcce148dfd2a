!> Prescribed translation of the cup: its acceleration a_base(t). In the
!> cup's frame this replaces g_vec by g_vec - a_base(t) (docs/model.md).
module ellroll_excitation
  use ellroll_kinds, only: wp, two_pi
  implicit none
  private

  public :: excitation_t, base_acceleration
  public :: excitation_none, excitation_harmonic, excitation_record, excitation_kind_names

  integer, parameter :: excitation_none = 0, excitation_harmonic = 1, excitation_record = 2
  character(len=8), parameter :: excitation_kind_names(0:2) = [character(len=8) :: 'none', 'harmonic', 'record']

  type :: excitation_t
    integer :: kind = excitation_none
    real(wp) :: amplitude(3) = 0        !< harmonic: m/s^2
    real(wp) :: frequency = 0           !< harmonic: Hz
    real(wp) :: phase = 0               !< harmonic: rad
    real(wp), allocatable :: times(:)   !< record: s, strictly increasing
    real(wp), allocatable :: values(:, :)  !< record: (3, n) m/s^2
  end type excitation_t

contains

  !> a_base(t): amplitude sin(2 pi f t + phase), or the record interpolated linearly.
  pure function base_acceleration(exc, t) result(a)
    type(excitation_t), intent(in) :: exc
    real(wp), intent(in) :: t
    real(wp) :: a(3)
    integer :: low, high, mid
    real(wp) :: weight
    select case (exc%kind)
    case (excitation_harmonic)
      a = exc%amplitude * sin(two_pi * exc%frequency * t + exc%phase)
    case (excitation_record)
      low = 1
      high = size(exc%times)
      if (t <= exc%times(low)) then
        a = exc%values(:, low)
        return
      else if (t >= exc%times(high)) then
        a = exc%values(:, high)
        return
      end if
      do while (high - low > 1)
        mid = (low + high) / 2
        if (exc%times(mid) <= t) then
          low = mid
        else
          high = mid
        end if
      end do
      weight = (t - exc%times(low)) / (exc%times(high) - exc%times(low))
      a = (1 - weight) * exc%values(:, low) + weight * exc%values(:, high)
    case default
      a = 0
    end select
  end function base_acceleration
end module ellroll_excitation
