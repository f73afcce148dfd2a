!> Prescribed translation of the cup: its acceleration a_base(t). In the
!> cup's frame this replaces g_vec by g_vec - a_base(t) (docs/model.md).
module ellroll_excitation
  use ellroll_kinds, only: wp, two_pi
  use ellroll_exact, only: equals, is_zero
  use ellroll_record_store, only: record_samples, store_record
  implicit none
  private

  public :: excitation_t, base_acceleration, set_record, excitation_end, step_to_sample, longest_step
  public :: excitation_none, excitation_harmonic, excitation_record, excitation_kind_names

  integer, parameter :: excitation_none = 0, excitation_harmonic = 1, excitation_record = 2
  character(len=8), parameter :: excitation_kind_names(0:2) = [character(len=8) :: 'none', 'harmonic', 'record']

  type :: excitation_t
    integer :: kind = excitation_none
    real(wp) :: amplitude(3) = 0        !< harmonic: m/s^2
    real(wp) :: frequency = 0           !< harmonic: Hz
    real(wp) :: phase = 0               !< harmonic: rad
    real(wp) :: scale = 1               !< record: factor on its values
    !> record: its samples' place in the record store (record_samples(record)%times,
    !> s, strictly increasing, and %values, (3, n) m/s^2), shared by copies
    integer :: record = 0
    real(wp) :: step = 0                !< record: times(k) = (k - 1) step exactly, or 0
  end type excitation_t

contains

  !> The cup moved by a record of these samples, stored once (ellroll_
  !> record_store; held false where there is no place or memory left for
  !> them); a grid of equal steps is found by its index.
  subroutine set_record(exc, times, values, held)
    type(excitation_t), intent(inout) :: exc
    real(wp), intent(in) :: times(:), values(:, :)
    logical, intent(out) :: held
    integer :: k
    call store_record(times, values, exc%record)
    held = exc%record > 0
    if (.not. held) return
    exc%kind = excitation_record
    exc%step = times(2)
    do k = 1, size(times)
      if (.not. equals(times(k), real(k - 1, wp) * exc%step)) exc%step = 0
    end do
  end subroutine set_record

  !> The time from which the cup is at rest for ever: 0 for a fixed cup, the
  !> last sample of a record (records end at rest: ellroll_record_file), 0
  !> for one scaled by 0, never (huge) for a harmonic forcing, 0 for one of
  !> zero amplitude.
  pure real(wp) function excitation_end(exc) result(t)
    type(excitation_t), intent(in) :: exc
    select case (exc%kind)
    case (excitation_harmonic)
      t = merge(0.0_wp, huge(1.0_wp), all(is_zero(exc%amplitude)))
    case (excitation_record)
      associate (times => record_samples(exc%record)%times, values => record_samples(exc%record)%values)
        t = huge(1.0_wp)
        if (all(is_zero(values(:, size(times))))) t = times(size(times))
        if (is_zero(exc%scale)) t = 0
      end associate
    case default
      t = 0
    end select
  end function excitation_end

  !> a_base(t): amplitude sin(2 pi f t + phase), or scale times the record
  !> interpolated linearly.
  pure function base_acceleration(exc, t) result(a)
    type(excitation_t), intent(in) :: exc
    real(wp), intent(in) :: t
    real(wp) :: a(3)
    integer :: low, high
    real(wp) :: weight
    select case (exc%kind)
    case (excitation_harmonic)
      a = exc%amplitude * sin(two_pi * exc%frequency * t + exc%phase)
    case (excitation_record)
      associate (times => record_samples(exc%record)%times, values => record_samples(exc%record)%values)
        low = 1
        high = size(times)
        if (t <= times(low)) then
          a = exc%scale * values(:, low)
          return
        else if (t >= times(high)) then
          a = exc%scale * values(:, high)
          return
        end if
        low = sample_before(exc, t)
        high = low + 1
        weight = (t - times(low)) / (times(high) - times(low))
        a = exc%scale * ((1 - weight) * values(:, low) + weight * values(:, high))
      end associate
    case default
      a = 0
    end select
  end function base_acceleration

  !> The index of a record's last sample at or before t, for
  !> times(1) < t < times(n): by its index on a grid of equal steps, else
  !> by bisection.
  pure integer function sample_before(exc, t) result(low)
    type(excitation_t), intent(in) :: exc
    real(wp), intent(in) :: t
    integer :: high, mid
    associate (times => record_samples(exc%record)%times)
      low = 1
      high = size(times)
      if (exc%step > 0) then
        low = min(max(int(t * (1 / exc%step)) + 1, 1), high - 1)
        if (times(low) > t) low = low - 1
        if (times(low + 1) <= t) low = low + 1
        high = low + 1
      end if
      do while (high - low > 1)
        mid = (low + high) / 2
        if (times(mid) <= t) then
          low = mid
        else
          high = mid
        end if
      end do
    end associate
  end function sample_before

  !> The step h from t, cut to end at the record's next sample where it
  !> would pass it: the interpolated record's slope jumps there, and an
  !> embedded pair's step across such a kink loses its order (its error
  !> stays above the tolerance). A t within 4 units in the last place of a
  !> sample is at it.
  !> The longest step an embedded pair takes in this cup: half a period of
  !> harmonic shaking, else no limit. The reaction follows the shaking at
  !> once, however smooth the state is (a ball at rest takes long steps), and
  !> a step of half a period holds one dip of N at most (N < 0 lasts less
  !> than half a period), which the search of the step's dense output for a
  !> lift-off (reaction_inside: 5 points, 1/8 of a period apart at most)
  !> brackets; a longer step can hold two, and the crossing located would be
  !> either.
  pure real(wp) function longest_step(exc)
    type(excitation_t), intent(in) :: exc
    longest_step = huge(1.0_wp)
    if (exc%kind == excitation_harmonic .and. exc%frequency >= tiny(1.0_wp)) longest_step = 0.5_wp / exc%frequency
  end function longest_step

  pure real(wp) function step_to_sample(exc, t, h) result(step)
    type(excitation_t), intent(in) :: exc
    real(wp), intent(in) :: t, h
    integer :: next, n
    real(wp) :: kink
    step = h
    if (exc%kind /= excitation_record) return
    associate (times => record_samples(exc%record)%times)
      n = size(times)
      if (t < times(1)) then
        next = 1
      else if (t < times(n)) then
        next = sample_before(exc, t) + 1
      else
        return
      end if
      kink = times(next)
      if (kink - t <= 4 * spacing(kink)) then
        if (next == n) return
        kink = times(next + 1)
      end if
      if (t + h > kink) step = kink - t
    end associate
  end function step_to_sample
end module ellroll_excitation
