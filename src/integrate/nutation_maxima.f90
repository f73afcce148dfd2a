!> The maxima of Theta over a case: from samples (each refined by the
!> parabola through the three around it, a flat top counted where the
!> signal falls after it), from maxima located exactly (an embedded pair's
!> dense output), and from a pair's steps to and from a still state
!> (ellroll_nutation_peaks rest_turn); their count, mean spacing and the
!> largest value.
module ellroll_nutation_maxima
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use ellroll_kinds, only: wp, i8
  use ellroll_exact, only: is_zero, equals
  use ellroll_nutation_peaks, only: rest_reached_rising, rest_reached_falling, rest_left_falling, rest_left_rising
  implicit none
  private

  public :: maxima_t

  !> Local maxima of a sampled signal, each refined by the parabola through
  !> the three samples around it (uneven spacing allowed): its time, and the
  !> largest of its values.
  type :: maxima_t
    real(wp) :: t(3) = 0, v(3) = 0       !< the last three samples
    integer :: n_samples = 0
    integer(i8) :: count = 0
    real(wp) :: first = 0, last = 0      !< times of the first and last maximum
    real(wp) :: top = -1                 !< the largest parabola's vertex value (-1: none)
    !> a flat top's start (a rest held by rolling resistance), a maximum once
    !> Theta falls from it, none where it rises again
    logical :: flat = .false.
    real(wp) :: flat_t = 0, flat_v = 0
    !> a pair's: the lowest value at step ends since the last maximum
    !> counted (or the start), against which a maximum's rise is measured
    !> where the ball was still since (`rested`: a rest, or a stop's turn)
    real(wp) :: low = huge(1.0_wp)
    logical :: rested = .false.
    !> a pair's: the value of the last maximum counted, and whether Theta
    !> fell below it since at a step's end: a maximum no higher, without that
    !> fall, is the same flat top met again by the next step (a crawl of
    !> steps of 3e-10 s)
    real(wp) :: last_value = 0
    logical :: fell = .true.
  contains
    procedure :: add => add_sample
    procedure :: add_peak
    procedure :: add_located
    procedure :: add_rest_turn
    procedure :: note_value
    procedure :: mean_interval
  end type maxima_t

contains

  pure subroutine add_sample(self, t, v)
    class(maxima_t), intent(inout) :: self
    real(wp), intent(in) :: t, v
    real(wp) :: d1, d3, numerator, denominator, t_peak, peak, shift
    ! a state tracked again at its time (a switch of regime, then the step
    ! that ends there) adds nothing: as a third sample it would make a flat
    ! top of a rising Theta
    if (self%n_samples > 0) then
      if (.not. t > self%t(3)) return
    end if
    ! (shifted element by element: the array constructor built temporaries)
    self%t(1) = self%t(2)
    self%t(2) = self%t(3)
    self%t(3) = t
    self%v(1) = self%v(2)
    self%v(2) = self%v(3)
    self%v(3) = v
    self%n_samples = self%n_samples + 1
    if (self%flat) then
      if (self%v(3) < self%v(2)) call self%add_peak(self%flat_t)
      self%flat = equals(self%v(3), self%v(2))
    end if
    if (self%n_samples < 3) return
    if (.not. (self%v(2) > self%v(1) .and. self%v(2) >= self%v(3))) return
    ! vertex of the parabola through the three samples
    d1 = self%t(2) - self%t(1)
    d3 = self%t(2) - self%t(3)
    numerator = d1**2 * (self%v(2) - self%v(3)) - d3**2 * (self%v(2) - self%v(1))
    denominator = d1 * (self%v(2) - self%v(3)) - d3 * (self%v(2) - self%v(1))
    t_peak = self%t(2)
    peak = self%v(2)
    if (.not. is_zero(denominator)) then
      t_peak = self%t(2) - 0.5_wp * numerator / denominator
      ! the vertex's value v2 - c s^2, s = t_peak - t2, c the parabola's
      ! curvature denominator / (d1 d3 (d1 - d3)), in factors of the
      ! samples' size (none of the spacing's powers alone)
      shift = t_peak - self%t(2)
      peak = self%v(2) - (denominator / (d1 * (d1 - d3))) * (shift / d3) * shift
    end if
    self%top = max(self%top, peak)
    if (self%v(2) > self%v(3)) then
      call self%add_peak(t_peak)
    else
      self%flat = .true.
      self%flat_t = t_peak
    end if
  end subroutine add_sample

  !> A maximum located exactly (by the adaptive method's dense output).
  pure subroutine add_peak(self, t_peak)
    class(maxima_t), intent(inout) :: self
    real(wp), intent(in) :: t_peak
    if (self%count == 0) self%first = t_peak
    self%last = t_peak
    self%count = self%count + 1
  end subroutine add_peak

  !> A maximum an embedded pair located (its time and value). Where the
  !> ball was still since the last maximum counted, it counts where the value
  !> rose to it by more than the tolerance from the lowest since: a rise the
  !> steps do not resolve (a ball setting off from a rest: a few units of
  !> round-off) is none. (Elsewhere the lowest at step ends may lie above a
  !> minimum inside a long step: every sign change counts.) A rest before it
  !> is no maximum: Theta turns after it.
  pure subroutine add_located(self, t_peak, v_peak, tolerance)
    class(maxima_t), intent(inout) :: self
    real(wp), intent(in) :: t_peak, v_peak, tolerance
    self%flat = .false.
    if (.not. (self%fell .or. v_peak > self%last_value)) return
    if (self%rested .and. .not. v_peak - self%low > tolerance) return
    call self%add_peak(t_peak)
    self%low = v_peak
    self%rested = .false.
    self%last_value = v_peak
    self%fell = .false.
  end subroutine add_located

  !> A value of a pair's step end (still: the ball still there): the lowest
  !> since the last maximum, and whether Theta fell from it.
  pure subroutine note_value(self, v, still)
    class(maxima_t), intent(inout) :: self
    real(wp), intent(in) :: v
    logical, intent(in) :: still
    self%low = min(self%low, v)
    self%rested = self%rested .or. still
    self%fell = self%fell .or. v < self%last_value
  end subroutine note_value

  !> A pair's step's turn at a still state (ellroll_nutation_peaks
  !> rest_turn, the step ending at t, value v there, with no maximum of Theta
  !> inside it): a rest reached with Theta rising (by more than the
  !> tolerance, as add_located's) is a maximum there once the ball leaves
  !> it falling.
  pure subroutine add_rest_turn(self, turn, t, v, tolerance)
    class(maxima_t), intent(inout) :: self
    integer, intent(in) :: turn
    real(wp), intent(in) :: t, v, tolerance
    select case (turn)
    case (rest_reached_rising)
      self%flat = v - self%low > tolerance
      self%flat_t = t
      self%flat_v = v
    case (rest_left_falling)
      if (self%flat) then
        call self%add_peak(self%flat_t)
        self%low = self%flat_v
        self%rested = .true.            ! (it sets off from that rest)
        self%last_value = self%flat_v
        self%fell = .false.
      end if
      self%flat = .false.
    case (rest_left_rising, rest_reached_falling)
      self%flat = .false.
    end select
  end subroutine add_rest_turn

  pure real(wp) function mean_interval(self)
    class(maxima_t), intent(in) :: self
    if (self%count < 3) then
      mean_interval = ieee_value(0.0_wp, ieee_quiet_nan)
    else
      mean_interval = (self%last - self%first) / real(self%count - 1, wp)
    end if
  end function mean_interval
end module ellroll_nutation_maxima
