!> What a batch keeps of its lanes between steps (ellroll_batch_run): the
!> running summary of every lane, and the output samples held a block at a
!> time before they go into each lane's result.
module ellroll_lane_records
  use ellroll_kinds, only: wp, i8
  use ellroll_cases, only: field_count, field_contact, field_center, field_omega, field_normal, field_nutation, &
      field_reaction, field_energy, field_base_acceleration, field_regime, field_slip_speed
  use ellroll_results, only: case_result_t
  use ellroll_quantities, only: q_energy
  use ellroll_figures, only: fig_theta_max
  use ellroll_running, only: running_lanes_t, add_step_ends, get_lane, put_lane
  use ellroll_rolling_ball, only: state_size, nutation_angle
  use ellroll_ball_lanes, only: lanes, lane_outputs_t
  use ellroll_case_run, only: run_state_t
  implicit none
  private

  public :: block_samples, lane_summary_t, lane_sample_block_t

  !> Output samples held per batch lane between flushes into the results
  !> (lane_sample_block_t).
  integer, parameter :: block_samples = 128

  !> The running summary of every lane of a batch (accumulate across lanes):
  !> the largest nutation angle, and the statistics of the step-end
  !> quantities (ellroll_running), a row per lane.
  type :: lane_summary_t
    real(wp), dimension(lanes) :: tan_max = -1, lateral_at_max = 0, normal_z_at_max = 1
    logical :: theta_moved(lanes) = .false.
    type(running_lanes_t) :: stats
  contains
    procedure :: load => load_summary
    procedure :: add => add_to_summary
    procedure :: note_nutation => note_lane_nutation
    procedure :: store => store_summary
  end type lane_summary_t

  !> Output samples of a batch's RK4 lanes, held a block at a time: each
  !> lane's samples (every steps_per_sample of its own dt) go to its next
  !> slot, and its result takes them from the block in one pass (flush).
  !> Stored lane by lane into the eight results, a sample cost about 90 ns
  !> per case; long blocks give each of the 40 streams a flush writes runs
  !> that the prefetcher follows. The block is 139 kB.
  type :: lane_sample_block_t
    integer :: count(lanes) = 0           !< samples held per lane
    integer(i8) :: first(lanes) = 2       !< output sample index of each lane's first one held
    logical :: fields(field_count) = .false.
    real(wp), dimension(lanes, 3, block_samples) :: contact, center, omega, normal, reaction
    real(wp), dimension(lanes, block_samples) :: lateral, energy
    real(wp), dimension(lanes, 3, block_samples) :: base     !< the cup's acceleration
  contains
    procedure :: add => add_lane_samples
    procedure :: flush => flush_lane_samples
  end type lane_sample_block_t

contains

  !> A case's running summary (accumulate), into lane l.
  pure subroutine load_summary(self, l, run)
    class(lane_summary_t), intent(inout) :: self
    integer, intent(in) :: l
    type(run_state_t), intent(in) :: run
    self%tan_max(l) = run%tan_theta_max
    call put_lane(self%stats, l, run%stats)
  end subroutine load_summary

  !> What the accepted lanes' new states (at times t) add to the summary
  !> (accumulate); branch-free (merge), so that the loop vectorizes. works:
  !> each lane's works so far that its energy's balance adds (the couple of
  !> rolling resistance's; energy_drift is the residual of E + W = E0).
  pure subroutine add_to_summary(self, out, t, accepted, works)
    class(lane_summary_t), intent(inout) :: self
    type(lane_outputs_t), intent(in) :: out
    real(wp), intent(in) :: t(lanes)
    logical, intent(in) :: accepted(lanes)
    real(wp), intent(in), optional :: works(lanes)
    real(wp) :: quantity(lanes, size(out%quantity, 2))
    logical :: higher
    integer :: l
    do l = 1, lanes
      higher = accepted(l) .and. out%tan_nutation(l) > self%tan_max(l)
      self%tan_max(l) = merge(out%tan_nutation(l), self%tan_max(l), higher)
      self%lateral_at_max(l) = merge(out%lateral(l), self%lateral_at_max(l), higher)
      self%normal_z_at_max(l) = merge(out%normal(l, 3), self%normal_z_at_max(l), higher)
      self%theta_moved(l) = self%theta_moved(l) .or. higher
    end do
    if (present(works)) then
      quantity = out%quantity
      quantity(:, q_energy) = quantity(:, q_energy) + works
      call add_step_ends(self%stats, quantity, t, accepted)
    else
      call add_step_ends(self%stats, out%quantity, t, accepted)
    end if
  end subroutine add_to_summary

  !> A nutation angle of lane l's case (tan Theta, and the lateral and
  !> vertical components of the unit normal) for the largest Theta.
  pure subroutine note_lane_nutation(self, l, tan_nutation, lateral, normal_z)
    class(lane_summary_t), intent(inout) :: self
    integer, intent(in) :: l
    real(wp), intent(in) :: tan_nutation, lateral, normal_z
    if (tan_nutation > self%tan_max(l)) then
      self%tan_max(l) = tan_nutation
      self%lateral_at_max(l) = lateral
      self%normal_z_at_max(l) = normal_z
      self%theta_moved(l) = .true.
    end if
  end subroutine note_lane_nutation

  !> Lane l's running summary into its result (and run state).
  pure subroutine store_summary(self, l, run, res)
    class(lane_summary_t), intent(in) :: self
    integer, intent(in) :: l
    type(run_state_t), intent(inout) :: run
    type(case_result_t), intent(inout) :: res
    run%tan_theta_max = self%tan_max(l)
    if (self%theta_moved(l)) res%reals(fig_theta_max) = nutation_angle(self%lateral_at_max(l), self%normal_z_at_max(l))
    call get_lane(self%stats, l, run%stats)
  end subroutine store_summary

  !> The values at one output sample of the lanes that take one (sampling)
  !> into each one's next slot of the block.
  pure subroutine add_lane_samples(self, out, y, radius, base, sampling)
    class(lane_sample_block_t), intent(inout) :: self
    type(lane_outputs_t), intent(in) :: out
    real(wp), intent(in) :: y(lanes, state_size), radius(lanes), base(lanes, 3)
    logical, intent(in) :: sampling(lanes)
    integer :: l, j
    do l = 1, lanes
      if (.not. sampling(l)) cycle
      self%count(l) = self%count(l) + 1
      j = self%count(l)
      if (self%fields(field_contact)) self%contact(l, :, j) = out%contact(l, :)
      if (self%fields(field_center)) self%center(l, :, j) = out%contact(l, :) + radius(l) * out%normal(l, :)
      if (self%fields(field_omega)) self%omega(l, :, j) = y(l, 4:6)
      if (self%fields(field_normal) .or. self%fields(field_nutation)) self%normal(l, :, j) = out%normal(l, :)
      if (self%fields(field_nutation)) self%lateral(l, j) = out%lateral(l)
      if (self%fields(field_reaction)) self%reaction(l, :, j) = out%reaction(l, :)
      if (self%fields(field_energy)) self%energy(l, j) = out%quantity(l, q_energy)
      if (self%fields(field_base_acceleration)) self%base(l, :, j) = base(l, :)
    end do
  end subroutine add_lane_samples

  !> Lane l's samples held in the block into its result (Theta from the
  !> lateral and vertical parts of the normal, as store_sample), and the
  !> lane's slots free for the next ones.
  pure subroutine flush_lane_samples(self, l, res)
    class(lane_sample_block_t), intent(inout) :: self
    integer, intent(in) :: l
    type(case_result_t), intent(inout) :: res
    integer(i8) :: first, last
    integer :: n
    n = self%count(l)
    if (n <= 0) return
    first = self%first(l)
    last = first + n - 1
    call put(res, field_contact, self%contact)
    call put(res, field_center, self%center)
    call put(res, field_omega, self%omega)
    call put(res, field_normal, self%normal)
    call put(res, field_reaction, self%reaction)
    if (allocated(res%fields(field_nutation)%values)) call put_nutation(res%fields(field_nutation)%values(1, first:last))
    if (allocated(res%fields(field_energy)%values)) res%fields(field_energy)%values(1, first:last) = self%energy(l, :n)
    call put(res, field_base_acceleration, self%base)
    ! the lanes roll (a case that may slide never runs in them)
    if (allocated(res%fields(field_regime)%values)) res%fields(field_regime)%values(1, first:last) = 0
    if (allocated(res%fields(field_slip_speed)%values)) res%fields(field_slip_speed)%values(1, first:last) = 0
    res%n_recorded = last
    self%first(l) = last + 1
    self%count(l) = 0
  contains
    pure subroutine put(res, field, values)
      type(case_result_t), intent(inout) :: res
      integer, intent(in) :: field
      real(wp), intent(in) :: values(lanes, 3, block_samples)
      if (allocated(res%fields(field)%values)) call copy_lane(values, res%fields(field)%values(:, first:last))
    end subroutine put
    !> Theta of lane l's samples: a loop the compiler vectorizes, with the
    !> vector atan2 of the C library's libmvec where there is one (within a
    !> few units of round-off of the scalar atan2, which took 3 % of a batch
    !> storing every field).
    pure subroutine put_nutation(stored)
      real(wp), intent(inout) :: stored(n)
      real(wp) :: lateral(n), normal_z(n)
      integer :: j
      do j = 1, n
        lateral(j) = self%lateral(l, j)
        normal_z(j) = self%normal(l, 3, j)
      end do
      do j = 1, n
        stored(j) = nutation_angle(lateral(j), normal_z(j))
      end do
    end subroutine put_nutation
    !> Lane l's vectors, explicit loops on explicit shapes: the array
    !> assignment on the strided section was a slow generic loop.
    pure subroutine copy_lane(values, stored)
      real(wp), intent(in) :: values(lanes, 3, block_samples)
      real(wp), intent(inout) :: stored(3, n)
      integer :: j
      do j = 1, n
        stored(1, j) = values(l, 1, j)
        stored(2, j) = values(l, 2, j)
        stored(3, j) = values(l, 3, j)
      end do
    end subroutine copy_lane
  end subroutine flush_lane_samples

end module ellroll_lane_records
