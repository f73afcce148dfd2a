!> The cups of a batch's lanes moved by their excitations (ellroll_excitation),
!> one per SIMD lane: the cup's acceleration a_base(t) of every lane at each
!> lane's time, the arithmetic of base_acceleration lane by lane. A
!> harmonic lane's sine is taken for all harmonic lanes in one loop (the
!> vector sine of the C library's libmvec where there is one); a record
!> lane keeps the sample interval it last used (a cursor), so that a time
!> next to the last one finds its interval in a step or two, on even and
!> uneven records alike, and interpolates it as base_acceleration does.
module ellroll_excitation_lanes
  use ellroll_kinds, only: wp, two_pi
  use ellroll_excitation, only: excitation_t, excitation_none, excitation_harmonic, excitation_record
  use ellroll_ball_lanes, only: lanes
  use ellroll_record_store, only: record_samples
  implicit none
  private

  public :: excitation_lanes_t

  !> Each lane's excitation, and which kinds the batch holds.
  type :: excitation_lanes_t
    logical :: moving = .false.           !< some lane's cup moves
    logical :: harmonic = .false.         !< some lane is harmonic
    logical :: record = .false.           !< some lane follows a record
    integer :: kind(lanes) = excitation_none
    real(wp) :: amplitude(lanes, 3) = 0, frequency(lanes) = 0, phase(lanes) = 0
    type(excitation_t) :: records(lanes)  !< a record lane's excitation
    integer :: cursor(lanes) = 1          !< a record lane's last interval
  contains
    procedure :: set => set_excitation_lane
    procedure :: at => lanes_base_acceleration
  end type excitation_lanes_t

contains

  !> Lane l's cup moved by exc.
  pure subroutine set_excitation_lane(self, l, exc)
    class(excitation_lanes_t), intent(inout) :: self
    integer, intent(in) :: l
    type(excitation_t), intent(in) :: exc
    self%kind(l) = exc%kind
    self%amplitude(l, :) = 0
    self%frequency(l) = 0
    self%phase(l) = 0
    self%cursor(l) = 1
    select case (exc%kind)
    case (excitation_harmonic)
      self%amplitude(l, :) = exc%amplitude
      self%frequency(l) = exc%frequency
      self%phase(l) = exc%phase
    case (excitation_record)
      self%records(l) = exc
    end select
    self%moving = any(self%kind /= excitation_none)
    self%harmonic = any(self%kind == excitation_harmonic)
    self%record = any(self%kind == excitation_record)
  end subroutine set_excitation_lane

  !> a_base at each lane's time t (0 on a lane whose cup does not move).
  pure subroutine lanes_base_acceleration(self, t, base)
    class(excitation_lanes_t), intent(inout) :: self
    real(wp), intent(in) :: t(lanes)
    real(wp), intent(out) :: base(lanes, 3)
    real(wp) :: wave(lanes)
    integer :: l, i
    base = 0
    if (self%harmonic) then
      do l = 1, lanes
        wave(l) = sin(two_pi * self%frequency(l) * t(l) + self%phase(l))
      end do
      do i = 1, 3
        do l = 1, lanes
          base(l, i) = merge(self%amplitude(l, i) * wave(l), 0.0_wp, self%kind(l) == excitation_harmonic)
        end do
      end do
    end if
    if (self%record) then
      do l = 1, lanes
        if (self%kind(l) == excitation_record) &
          call record_at(self%records(l), self%cursor(l), t(l), base(l, 1), base(l, 2), base(l, 3))
      end do
    end if
  end subroutine lanes_base_acceleration

  !> A record's a_base at t (base_acceleration's interpolation), its
  !> interval searched from the cursor and left there.
  pure subroutine record_at(exc, cursor, t, a1, a2, a3)
    type(excitation_t), intent(in) :: exc
    integer, intent(inout) :: cursor
    real(wp), intent(in) :: t
    real(wp), intent(out) :: a1, a2, a3
    integer :: n, low
    real(wp) :: weight
    associate (times => record_samples(exc%record)%times, values => record_samples(exc%record)%values)
      n = size(times)
      if (t <= times(1)) then
        low = 1
        weight = 0
      else if (t >= times(n)) then
        low = n
        weight = 0
      else
        ! times(1) < t < times(n): both searches stop inside the record
        low = min(max(cursor, 1), n - 1)
        do while (times(low) > t)
          low = low - 1
        end do
        do while (times(low + 1) <= t)
          low = low + 1
        end do
        cursor = low
        weight = (t - times(low)) / (times(low + 1) - times(low))
        a1 = exc%scale * ((1 - weight) * values(1, low) + weight * values(1, low + 1))
        a2 = exc%scale * ((1 - weight) * values(2, low) + weight * values(2, low + 1))
        a3 = exc%scale * ((1 - weight) * values(3, low) + weight * values(3, low + 1))
        return
      end if
      a1 = exc%scale * values(1, low)
      a2 = exc%scale * values(2, low)
      a3 = exc%scale * values(3, low)
    end associate
  end subroutine record_at
end module ellroll_excitation_lanes
