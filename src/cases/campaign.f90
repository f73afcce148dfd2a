!> A campaign: the base case expanded by sweeps (grid or zip) and random
!> samples into n cases, each built from its global index alone, so that
!> any subset (a shard, the cases left after an interruption) can be made
!> without the others, identically on every machine and thread count.
module ellroll_campaign
  use ellroll_kinds, only: wp, i8
  use ellroll_cases, only: case_t, set_param, get_param, finalize_case
  use ellroll_params, only: params
  use ellroll_excitation, only: excitation_t
  use ellroll_intensity, only: record_intensity_t
  implicit none
  private

  public :: campaign_t, sweep_t, sample_t, suite_record_t, coordinate_t, use_record, uniform_hash
  public :: combine_grid, combine_zip, invalid_stop, invalid_skip, max_cases

  integer, parameter :: combine_grid = 1, combine_zip = 2
  integer, parameter :: invalid_stop = 1, invalid_skip = 2
  !> The most cases a campaign holds (and so an ellroll file's rows).
  integer(i8), parameter :: max_cases = 100000000_i8
  integer(i8), parameter :: mask32 = 4294967295_i8

  type :: sweep_t
    integer :: param = 0
    real(wp), allocatable :: values(:)
    integer :: line = 0                  !< where the &sweep group starts
  end type sweep_t

  type :: sample_t
    integer :: param = 0
    real(wp) :: low = 0, high = 0
    logical :: log_spacing = .false.
    integer :: line = 0
  end type sample_t

  !> A ground-motion record of a suite (&record): its name, its factor and
  !> the motion of the cup it gives (its samples, the factor applied).
  type :: suite_record_t
    character(len=32) :: name = ''
    real(wp) :: factor = 1
    type(excitation_t) :: motion
    type(record_intensity_t) :: intensity    !< of motion (the factor in, no scale)
  end type suite_record_t

  !> An input that varies between the cases of a campaign (a swept or
  !> sampled one, or a suite's record), with its value in each of some cases:
  !> a coordinate of the case dimension in the output file.
  type :: coordinate_t
    character(len=32) :: name = ''
    character(len=5) :: unit = ''
    character(len=64) :: description = ''
    real(wp), allocatable :: values(:)            !< a real input's
    character(len=32), allocatable :: texts(:)    !< the record's name
  end type coordinate_t

  type :: campaign_t
    type(case_t) :: base
    type(suite_record_t), allocatable :: records(:)   !< a suite: one more dimension, the slowest
    type(sweep_t), allocatable :: sweeps(:)
    type(sample_t), allocatable :: samples(:)
    integer :: combine = combine_grid
    integer(i8) :: n_draws = 0           !< random cases per sweep point; 0: no sampling
    integer(i8) :: seed = 0
    integer :: invalid = invalid_stop
  contains
    procedure :: n_cases
    procedure :: case_at
    procedure :: coordinates
    procedure :: record_places
  end type campaign_t

contains

  pure integer(i8) function n_sweep_points(self)
    class(campaign_t), intent(in) :: self
    integer :: k
    n_sweep_points = 1
    if (size(self%sweeps) == 0) return
    if (self%combine == combine_zip) then
      n_sweep_points = size(self%sweeps(1)%values, kind=i8)
    else
      do k = 1, size(self%sweeps)
        n_sweep_points = n_sweep_points * size(self%sweeps(k)%values, kind=i8)
      end do
    end if
  end function n_sweep_points

  pure integer function n_records(self)
    class(campaign_t), intent(in) :: self
    n_records = 0
    if (allocated(self%records)) n_records = size(self%records)
  end function n_records

  pure integer(i8) function n_cases(self)
    class(campaign_t), intent(in) :: self
    n_cases = n_sweep_points(self) * max(1_i8, self%n_draws) * max(1, n_records(self))
  end function n_cases

  !> Case `index` (0-based). Samples vary fastest, then the last sweep, ...,
  !> then the first sweep, then the record of a suite.
  pure function case_at(self, index) result(cs)
    class(campaign_t), intent(in) :: self
    integer(i8), intent(in) :: index
    type(case_t) :: cs
    integer(i8) :: point, rest, n, per_record
    integer :: k
    real(wp) :: u
    cs = self%base
    cs%index = index
    per_record = n_sweep_points(self) * max(1_i8, self%n_draws)
    if (n_records(self) > 0) call use_record(cs, self%records(index / per_record + 1))
    point = mod(index, per_record) / max(1_i8, self%n_draws)
    if (self%combine == combine_zip) then
      do k = 1, size(self%sweeps)
        call set_param(cs, self%sweeps(k)%param, self%sweeps(k)%values(point + 1))
      end do
    else
      rest = point
      do k = size(self%sweeps), 1, -1
        n = size(self%sweeps(k)%values, kind=i8)
        call set_param(cs, self%sweeps(k)%param, self%sweeps(k)%values(mod(rest, n) + 1))
        rest = rest / n
      end do
    end if
    do k = 1, size(self%samples)
      u = uniform_hash(self%seed, index, k)
      associate (s => self%samples(k))
        if (s%log_spacing) then
          call set_param(cs, s%param, s%low * (s%high / s%low)**u)
        else
          call set_param(cs, s%param, s%low + (s%high - s%low) * u)
        end if
      end associate
    end do
    call finalize_case(cs)
  end function case_at

  !> The inputs that vary between the cases, in the order of the input
  !> (sweeps, samples, then the record of a suite), at the cases `indices`.
  function coordinates(self, indices) result(coords)
    class(campaign_t), intent(in) :: self
    integer(i8), intent(in) :: indices(:)
    type(coordinate_t), allocatable :: coords(:)
    type(case_t) :: cs
    integer, allocatable :: varied(:)
    integer :: k, n_real
    integer(i8) :: slot
    allocate (varied, source=[self%sweeps%param, self%samples%param])
    n_real = size(varied)
    allocate (coords(n_real + merge(1, 0, n_records(self) > 0)))
    do k = 1, n_real
      associate (p => params(varied(k)))
        coords(k) = coordinate_t(p%name, p%unit, p%description, values=[(0.0_wp, slot = 1, size(indices))])
      end associate
    end do
    if (size(coords) > n_real) coords(n_real + 1) = coordinate_t('record', '', &
        'record of a suite (&record name)', texts=[(repeat(' ', 32), slot = 1, size(indices))])
    do slot = 1, size(indices, kind=i8)
      cs = self%case_at(indices(slot))
      do k = 1, n_real
        coords(k)%values(slot) = get_param(cs, varied(k))
      end do
      if (size(coords) > n_real) coords(n_real + 1)%texts(slot) = cs%record_name
    end do
  end function coordinates

  !> The places in the record store (ellroll_record_store) of every record
  !> the campaign reads (0 where none), to give them back after its run.
  pure function record_places(self) result(places)
    class(campaign_t), intent(in) :: self
    integer, allocatable :: places(:)
    integer :: k
    places = [self%base%excitation%record]
    if (allocated(self%records)) places = [places, (self%records(k)%motion%record, k = 1, size(self%records))]
  end function record_places

  !> The case shaken by record `rec` of the suite (at the case's own scale).
  pure subroutine use_record(cs, rec)
    type(case_t), intent(inout) :: cs
    type(suite_record_t), intent(in) :: rec
    cs%excitation%kind = rec%motion%kind
    cs%excitation%record = rec%motion%record
    cs%excitation%step = rec%motion%step
    cs%record_name = rec%name
    cs%record_factor = rec%factor
    cs%intensity = rec%intensity
  end subroutine use_record

  !> A uniform number in [0, 1) from (seed, index, stream): a counter-based
  !> generator built on a 32-bit integer hash, in exact integer arithmetic
  !> (every product fits in 63 bits), so every machine draws the same numbers.
  pure real(wp) function uniform_hash(seed, index, stream) result(u)
    integer(i8), intent(in) :: seed, index
    integer, intent(in) :: stream
    integer(i8) :: h, high_bits, low_bits
    h = mix(mix(mix(mix(iand(seed, mask32)) + ishft(seed, -32)) + iand(index, mask32)) + &
            ishft(index, -32))
    h = mix(h + stream)
    high_bits = ishft(mix(h + 1), -5)      ! 27 bits
    low_bits = ishft(mix(h + 2), -6)       ! 26 bits
    u = real(high_bits * 2_i8**26 + low_bits, wp) / 2.0_wp**53
  end function uniform_hash

  !> The "lowbias32" integer hash of Chris Wellons on the low 32 bits.
  pure integer(i8) function mix(x) result(h)
    integer(i8), intent(in) :: x
    h = iand(x, mask32)
    h = ieor(h, ishft(h, -16))
    h = mul32(h, int(z'7feb352d', i8))
    h = ieor(h, ishft(h, -15))
    h = mul32(h, int(z'846ca68b', i8))
    h = ieor(h, ishft(h, -16))
  end function mix

  !> (x * m) mod 2^32 for x, m < 2^32, without 64-bit overflow.
  pure integer(i8) function mul32(x, m)
    integer(i8), intent(in) :: x, m
    mul32 = iand(x * iand(m, 65535_i8) + ishft(iand(x * ishft(m, -16), 65535_i8), 16), mask32)
  end function mul32
end module ellroll_campaign
