!> Locating where inside a step a model limit is first crossed, or where a
!> continuous event function changes sign (a hybrid system's event:
!> event_search_t). Reverse communication: the caller asks for a trial
!> offset, evaluates the state there, and reports back. The searches know
!> nothing of what the limit or event means.
module ellroll_events
  use ellroll_kinds, only: wp
  use ellroll_exact, only: is_zero
  use ellroll_ode, only: hybrid_system_t
  implicit none
  private

  public :: crossing_search_t, root_search_t, event_search_t, peak_search_t

  !> An event search takes at most this many trial states.
  integer, parameter, public :: max_event_trials = 60

  type :: crossing_search_t
    real(wp) :: valid = 0      !< largest offset known to be valid
    real(wp) :: invalid = 0    !< smallest offset known to be past the limit
    real(wp) :: tolerance = 0
  contains
    procedure :: start
    procedure :: trial
    procedure :: report
    procedure :: done
  end type crossing_search_t

  !> A sign change of g between offsets 0 (g > 0) and `high` (g <= 0), by
  !> the Illinois variant of regula falsi (superlinear for a smooth g; a
  !> step of bisection when a trial would not fall inside the bracket).
  type :: root_search_t
    real(wp) :: low = 0, high = 0        !< g(low) > 0 >= g(high)
    real(wp) :: g_low = 1, g_high = -1
    real(wp) :: tolerance = 0
    integer :: last_side = 0             !< 1: low moved last, -1: high
  contains
    procedure :: start => start_root
    procedure :: trial => trial_root
    procedure :: report => report_root
    procedure :: done => root_done
  end type root_search_t

  !> Where event `event` of a hybrid system happens inside a step of size h
  !> from y_start: the root of its event function (g > 0 at the start,
  !> g <= 0 at the step's end), to the event's tolerance, on the states the
  !> caller computes at the trial offsets.
  type, extends(root_search_t) :: event_search_t
    integer :: event = 0
  contains
    procedure :: begin => begin_event_search
    procedure :: report_state
  end type event_search_t

  !> A maximum of a smooth function bracketed by a < b < c (f(b) >= f(a),
  !> f(c)), refined by successive parabolas (a golden section where a
  !> parabola's vertex falls outside the bracket or next to b) until the
  !> bracket is `resolution` wide or max_event_trials trials are spent.
  type :: peak_search_t
    real(wp) :: a = 0, b = 0, c = 0, fa = 0, fb = 0, fc = 0
    real(wp) :: resolution = 0
    integer :: trials = 0
  contains
    procedure :: start => start_peak
    procedure :: trial => trial_peak
    procedure :: report => report_peak
    procedure :: done => peak_done
  end type peak_search_t

contains

  pure subroutine start(self, invalid, tolerance)
    class(crossing_search_t), intent(inout) :: self
    real(wp), intent(in) :: invalid, tolerance
    self%valid = 0
    self%invalid = invalid
    self%tolerance = tolerance
  end subroutine start

  pure real(wp) function trial(self)
    class(crossing_search_t), intent(in) :: self
    trial = self%valid + (self%invalid - self%valid) / 2
  end function trial

  pure subroutine report(self, offset, is_valid)
    class(crossing_search_t), intent(inout) :: self
    real(wp), intent(in) :: offset
    logical, intent(in) :: is_valid
    if (is_valid) then
      self%valid = offset
    else
      self%invalid = offset
    end if
  end subroutine report

  pure logical function done(self)
    class(crossing_search_t), intent(in) :: self
    done = self%invalid - self%valid <= self%tolerance
  end function done

  pure subroutine start_root(self, g_low, high, g_high, tolerance)
    class(root_search_t), intent(inout) :: self
    real(wp), intent(in) :: g_low, high, g_high, tolerance
    self%low = 0
    self%high = high
    self%g_low = g_low
    self%g_high = g_high
    self%tolerance = tolerance
    self%last_side = 0
  end subroutine start_root

  pure real(wp) function trial_root(self) result(offset)
    class(root_search_t), intent(in) :: self
    offset = self%high - self%g_high * (self%high - self%low) / (self%g_high - self%g_low)
    if (.not. (offset > self%low .and. offset < self%high)) offset = self%low + (self%high - self%low) / 2
  end function trial_root

  pure subroutine report_root(self, offset, g)
    class(root_search_t), intent(inout) :: self
    real(wp), intent(in) :: offset, g
    if (g > 0) then
      self%low = offset
      self%g_low = g
      if (self%last_side == 1) self%g_high = self%g_high / 2
      self%last_side = 1
    else
      self%high = offset
      self%g_high = g
      if (self%last_side == -1) self%g_low = self%g_low / 2
      self%last_side = -1
    end if
  end subroutine report_root

  pure logical function root_done(self)
    class(root_search_t), intent(in) :: self
    root_done = self%high - self%low <= self%tolerance
  end function root_done

  !> The search for `event` of sys (its mode set for the step: begin_step)
  !> in the step of size h that ends at y_end (passed: a state past a model
  !> limit, where the event counts as passed, as in report_state).
  pure subroutine begin_event_search(self, sys, event, y_end, h, passed)
    class(event_search_t), intent(inout) :: self
    class(hybrid_system_t), intent(in) :: sys
    integer, intent(in) :: event
    real(wp), intent(in) :: h
    real(wp), intent(in), contiguous :: y_end(:)
    logical, intent(in), optional :: passed
    real(wp) :: g_end
    self%event = event
    g_end = -1
    if (.not. present(passed)) g_end = sys%event_value(event, y_end)
    call self%start(sys%event_start_value(event), h, g_end, sys%event_tolerance(event) * h)
  end subroutine begin_event_search

  !> The state y at offset from the step's start; not valid (a model limit
  !> met on the way there): the event counts as passed.
  pure subroutine report_state(self, sys, offset, y, valid)
    class(event_search_t), intent(inout) :: self
    class(hybrid_system_t), intent(in) :: sys
    real(wp), intent(in) :: offset
    real(wp), intent(in), contiguous :: y(:)
    logical, intent(in) :: valid
    real(wp) :: g
    g = -1
    if (valid) g = sys%event_value(self%event, y)
    call self%report(offset, g)
  end subroutine report_state

  pure subroutine start_peak(self, a, b, c, fa, fb, fc, resolution)
    class(peak_search_t), intent(inout) :: self
    real(wp), intent(in) :: a, b, c, fa, fb, fc, resolution
    self%a = a
    self%b = b
    self%c = c
    self%fa = fa
    self%fb = fb
    self%fc = fc
    self%resolution = resolution
    self%trials = 0
  end subroutine start_peak

  !> The vertex of the parabola through the bracket, or a golden section of
  !> its longer side.
  pure real(wp) function trial_peak(self) result(x)
    class(peak_search_t), intent(in) :: self
    real(wp), parameter :: golden = 0.381966011250105_wp
    real(wp) :: numerator, denominator
    numerator = (self%b - self%a)**2 * (self%fb - self%fc) - (self%b - self%c)**2 * (self%fb - self%fa)
    denominator = (self%b - self%a) * (self%fb - self%fc) - (self%b - self%c) * (self%fb - self%fa)
    x = -1
    if (.not. is_zero(denominator)) x = self%b - 0.5_wp * numerator / denominator
    if (.not. (x > self%a .and. x < self%c) .or. abs(x - self%b) < 0.25_wp * self%resolution) then
      if (self%c - self%b > self%b - self%a) then
        x = self%b + golden * (self%c - self%b)
      else
        x = self%b - golden * (self%b - self%a)
      end if
    end if
  end function trial_peak

  pure subroutine report_peak(self, x, fx)
    class(peak_search_t), intent(inout) :: self
    real(wp), intent(in) :: x, fx
    self%trials = self%trials + 1
    if (fx >= self%fb) then
      if (x > self%b) then
        self%a = self%b
        self%fa = self%fb
      else
        self%c = self%b
        self%fc = self%fb
      end if
      self%b = x
      self%fb = fx
    else if (x > self%b) then
      self%c = x
      self%fc = fx
    else
      self%a = x
      self%fa = fx
    end if
  end subroutine report_peak

  pure logical function peak_done(self)
    class(peak_search_t), intent(in) :: self
    peak_done = self%c - self%a <= self%resolution .or. self%trials >= max_event_trials
  end function peak_done
end module ellroll_events
