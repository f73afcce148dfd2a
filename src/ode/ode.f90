!> What an integrator sees of a model: a right-hand side; for a model with
!> limits (limited_system_t) a check of the states a step evaluates the
!> model at (its stages): 0 where the model holds, else the model's code
!> for the limit met, where the case ends; and for a model with non-smooth
!> laws (hybrid_system_t) their per-step mode and their events.
module ellroll_ode
  use ellroll_kinds, only: wp
  implicit none
  private

  public :: ode_system_t, limited_system_t, hybrid_system_t, stage_limit

  !> The code of a step whose implicit equations had no solution near its
  !> start: the method cannot continue there.
  integer, parameter, public :: no_step_solution = -1

  type, abstract :: ode_system_t
  contains
    procedure(rhs_interface), deferred :: rhs
  end type ode_system_t

  type, abstract, extends(ode_system_t) :: limited_system_t
  contains
    procedure(stage_status_interface), deferred :: stage_status
  end type limited_system_t

  !> A model with non-smooth laws (rolling resistance; a sliding regime with
  !> Coulomb friction would be another), declared to the run loops, which
  !> know nothing of what they mean, where they act (nonsmooth):
  !>  - a mode held over each step (begin_step, from the state at its
  !>    start: the direction a friction-like force opposes, the regime), so
  !>    that the flow inside a step stays smooth up to an event;
  !>  - events, each a function g of a state inside the step (event_value,
  !>    relative to the step's mode), positive at the step's start where the
  !>    event can happen (event_start_value); event_crossed tells the first
  !>    whose g is <= 0 at the step's end, and the loops cut the step where
  !>    g crosses zero (a root search on their own trial steps, to
  !>    event_tolerance times the step);
  !>  - what happens there (apply_event): the model sets the state (the ball
  !>    at rest; a switch between rolling and sliding), and the run goes on
  !>    from it in the mode begin_step gives that state, with the derivative
  !>    evaluated afresh.
  !> Where a case ends is a limit's (stage_status, the model's limit status).
  type, abstract, extends(limited_system_t) :: hybrid_system_t
  contains
    procedure(nonsmooth_interface), deferred :: nonsmooth
    procedure(begin_step_interface), deferred :: begin_step
    procedure(event_crossed_interface), deferred :: event_crossed
    procedure(event_start_value_interface), deferred :: event_start_value
    procedure(event_value_interface), deferred :: event_value
    procedure(event_tolerance_interface), deferred, nopass :: event_tolerance
    procedure(apply_event_interface), deferred :: apply_event
  end type hybrid_system_t

  abstract interface
    pure subroutine rhs_interface(self, t, y, dydt)
      import :: ode_system_t, wp
      class(ode_system_t), intent(in) :: self
      real(wp), intent(in) :: t
      real(wp), intent(in) :: y(:)
      real(wp), intent(out) :: dydt(:)
    end subroutine rhs_interface

    pure integer function stage_status_interface(self, t, y, dydt) result(status)
      import :: limited_system_t, wp
      class(limited_system_t), intent(in) :: self
      real(wp), intent(in) :: t, y(:), dydt(:)
    end function stage_status_interface

    !> Whether the model's non-smooth laws act (a case without them steps
    !> as a smooth system: no mode, no events).
    pure logical function nonsmooth_interface(self)
      import :: hybrid_system_t
      class(hybrid_system_t), intent(in) :: self
    end function nonsmooth_interface

    !> The mode for a step from the state y.
    pure subroutine begin_step_interface(self, y)
      import :: hybrid_system_t, wp
      class(hybrid_system_t), intent(inout) :: self
      real(wp), intent(in), contiguous :: y(:)
    end subroutine begin_step_interface

    !> The first event that happens in a step from y_start to y_end (its
    !> event function changes sign), 0 for none.
    pure integer function event_crossed_interface(self, y_start, y_end) result(event)
      import :: hybrid_system_t, wp
      class(hybrid_system_t), intent(in) :: self
      real(wp), intent(in), contiguous :: y_start(:), y_end(:)
    end function event_crossed_interface

    !> The event function g of `event` at the start of the step begun
    !> (begin_step): positive where the event can happen.
    pure real(wp) function event_start_value_interface(self, event) result(g)
      import :: hybrid_system_t, wp
      class(hybrid_system_t), intent(in) :: self
      integer, intent(in) :: event
    end function event_start_value_interface

    !> The event function g of `event` at a state y inside the step begun.
    pure real(wp) function event_value_interface(self, event, y) result(g)
      import :: hybrid_system_t, wp
      class(hybrid_system_t), intent(in) :: self
      integer, intent(in) :: event
      real(wp), intent(in), contiguous :: y(:)
    end function event_value_interface

    !> The part of a step to which `event` is located.
    pure real(wp) function event_tolerance_interface(event) result(tolerance)
      import :: wp
      integer, intent(in) :: event
    end function event_tolerance_interface

    !> What `event` does at the state y where it was located: the state set
    !> (and the model's own regime, should the event switch it).
    pure subroutine apply_event_interface(self, event, y)
      import :: hybrid_system_t, wp
      class(hybrid_system_t), intent(inout) :: self
      integer, intent(in) :: event
      real(wp), intent(inout), contiguous :: y(:)
    end subroutine apply_event_interface
  end interface

contains

  !> The limit a stage at (t, y) with derivative dydt meets: 0 for none,
  !> and always 0 for a model without limits.
  pure integer function stage_limit(sys, t, y, dydt) result(status)
    class(ode_system_t), intent(in) :: sys
    real(wp), intent(in) :: t, y(:), dydt(:)
    select type (sys)
    class is (limited_system_t)
      status = sys%stage_status(t, y, dydt)
    class default
      status = 0
    end select
  end function stage_limit
end module ellroll_ode
