!> `ellroll summary OUT.h5 --suite`: the statistics of a record suite per
!> stripe (the cases that share every varied input but the record), as
!> ellroll_post.suite.suite_statistics computes them: the counts of cases,
!> completed, at each model limit and unresolved, the fraction at a model
!> limit and past each user limit state (of the cases with a physical
!> outcome; for a user limit state less those whose figure is undefined,
!> flag -1, counted apart as n_undefined_NAME), and the 16th, 50th and 84th percentiles (numpy's linear ones)
!> of each response figure over the completed cases.
module ellroll_cmd_suite
  use ellroll_standard_output, only: put_line
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan, ieee_value, ieee_quiet_nan
  use, intrinsic :: iso_fortran_env, only: error_unit
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_strings, only: itoa, real_text, json_text
  use ellroll_status, only: status_name, status_pending, status_completed, status_rim, status_no_fit, status_slip, &
      status_liftoff
  use ellroll_hdf5_reader, only: h5_input_t
  use ellroll_system, only: read_watchdog
  use ellroll_lapack, only: dlasrt
  use ellroll_exact, only: equals
  use ellroll_fragility_mle, only: fit_stripes
  use ellroll_limit_states, only: flag_exceeded, flag_undefined
  implicit none
  private

  public :: print_suite

  !> The response figures, in this order where the file holds them (ellroll_post.suite.RESPONSE_FIGURES).
  character(len=*), parameter :: responses(*) = [character(len=25) :: 'displacement_max', &
      'absolute_acceleration_max', 'horizontal_force_max', 'residual_displacement', 'rest_time', 'theta_max', &
      'reaction_normal_max', 'friction_needed_max']
  integer, parameter :: model_limits(*) = [status_rim, status_no_fit, status_slip, status_liftoff]

  !> A column of the result: a value per stripe, its units.
  type :: column_t
    character(len=64) :: name = ''
    character(len=16) :: units = '1'
    logical :: count = .false.
    real(wp), allocatable :: values(:)
  end type column_t

contains

  subroutine print_suite(path, format, err)
    character(len=*), intent(in) :: path, format
    type(error_t), intent(inout) :: err
    type(h5_input_t) :: file
    character(len=:), allocatable :: coordinates, units, fragility
    character(len=64), allocatable :: inputs(:), states(:), members(:), figures(:)
    character(len=16), allocatable :: input_units(:), figure_units(:)
    real(wp), allocatable :: keys(:, :), values(:, :)
    integer(i8), allocatable :: status(:), flags(:, :)
    integer :: k, first, last
    call file%open(path, err)
    if (err%failed()) return
    allocate (status, source=file%int_column('summary/status', err))
    call warn_part(file, path, count(status /= status_pending))
    call file%text_attribute('coordinates', coordinates, 'summary/status')
    allocate (inputs(0), input_units(0), states(0), figures(0), figure_units(0))
    first = 1
    do while (first <= len(coordinates))
      last = index(coordinates(first:) // ' ', ' ') + first - 2
      if (last >= first) then
        if (coordinates(first:last) /= 'record' .and. coordinates(first:last) /= 'record_factor') then
          call file%text_attribute('units', units, 'summary/' // coordinates(first:last))
          inputs = [character(len=64) :: inputs, coordinates(first:last)]
          input_units = [character(len=16) :: input_units, units]
        end if
      end if
      first = last + 2
    end do
    allocate (keys(size(status), size(inputs)))
    do k = 1, size(inputs)
      keys(:, k) = file%real_column('summary/' // trim(inputs(k)), err)
    end do
    call file%members('limit_state', members)
    do k = 1, size(members)
      if (trim(members(k)) == 'case' .or. any(inputs == members(k)) .or. trim(members(k)) == 'record') cycle
      if (file%dataset_length('limit_state/' // trim(members(k))) /= size(status)) cycle
      states = [character(len=64) :: states, members(k)]
    end do
    allocate (flags(size(status), size(states)))
    do k = 1, size(states)
      flags(:, k) = file%int_column('limit_state/' // trim(states(k)), err)
    end do
    do k = 1, size(responses)
      if (.not. file%has('summary/' // trim(responses(k)))) cycle
      call file%text_attribute('units', units, 'summary/' // trim(responses(k)))
      figures = [character(len=64) :: figures, responses(k)]
      figure_units = [character(len=16) :: figure_units, units]
    end do
    allocate (values(size(status), size(figures)))
    do k = 1, size(figures)
      values(:, k) = file%real_column('summary/' // trim(figures(k)), err)
    end do
    call file%close()
    call read_watchdog('', 0)         ! (read: the time its rows take to print, to a pipe read late, is not HDF5's)
    if (err%failed()) return
    call fragility_json(inputs, keys, int(status), states, flags, fragility)
    call print_columns(path, format, inputs, stripe_columns(inputs, input_units, keys, int(status), states, flags, &
                                                            figures, figure_units, values), fragility)
  end subroutine print_suite

  !> A file that holds part of its campaign's cases only (a shard's, an
  !> unfinished run's): one warning line on standard error, as ellroll-plot's
  !> (its statistics are over those cases).
  subroutine warn_part(file, path, finished)
    type(h5_input_t), intent(in) :: file
    character(len=*), intent(in) :: path
    integer, intent(in) :: finished
    character(len=:), allocatable :: shard, why
    integer :: total
    total = file%int_attribute('n_cases_total')
    if (.not. finished < total) return
    call file%text_attribute('shard', shard)
    if (len(shard) > 0 .and. shard /= '0/1') then
      why = 'shard ' // shard // ' (merge the shards first: ellroll merge)'
    else
      why = 'an unfinished run (finish it: ellroll run --resume)'
    end if
    write (error_unit, '(a)') 'ellroll: warning: ' // path // ': over ' // itoa(finished) // ' of the campaign''s ' // &
        itoa(total) // ' cases only: ' // why
  end subroutine warn_part

  !> The lognormal fragilities in the scale (ellroll_post.suite.suite_fragility
  !> without its bootstrap): per limit state (the model's, then each user
  !> limit state) and per value of the other varied inputs, the maximum
  !> likelihood theta and beta over the stripes, as JSON objects; none
  !> without a scale among the varied inputs.
  subroutine fragility_json(inputs, keys, status, states, flags, text)
    character(len=*), intent(in) :: inputs(:), states(:)
    real(wp), intent(in) :: keys(:, :)
    integer, intent(in) :: status(:)
    integer(i8), intent(in) :: flags(:, :)
    character(len=:), allocatable, intent(out) :: text
    integer, allocatable :: order(:)
    integer :: i_scale, k, j, g, m, state
    logical :: known(size(status)), hit(size(status)), group(size(status)), limit(size(status))
    logical :: defined(size(status))
    real(wp), allocatable :: levels(:), other(:, :)
    integer, allocatable :: n(:), z(:)
    integer :: undefined, at_zero
    real(wp) :: theta, beta, nan
    logical :: separated
    character(len=:), allocatable :: row, note, a, b
    nan = ieee_value(nan, ieee_quiet_nan)
    text = ''
    note = ''
    i_scale = findloc([(trim(inputs(k)) == 'scale', k = 1, size(inputs))], .true., dim=1)
    if (i_scale == 0) return
    other = keys(:, pack([(k, k = 1, size(inputs))], [(k /= i_scale, k = 1, size(inputs))]))
    call sort_cases(other, order)
    limit = [(any(status(j) == model_limits), j = 1, size(status))]
    known = (limit .or. status == status_completed) .and. ieee_is_finite(keys(:, i_scale)) .and. keys(:, i_scale) > 0
    do state = 0, size(states)
      hit = limit
      defined = .true.
      ! a completed case whose figure is undefined has no outcome for this limit state
      if (state > 0) then
        hit = hit .or. flags(:, state) == flag_exceeded
        defined = flags(:, state) /= flag_undefined
      end if
      do g = 1, size(order)
        if (g > 1) then
          if (same_key(other(order(g), :), other(order(g - 1), :))) cycle
        end if
        group = [(same_key(other(j, :), other(order(g), :)), j = 1, size(status))]
        undefined = count(group .and. known .and. .not. defined)
        levels = pack(keys(:, i_scale), group .and. known .and. defined)
        call sorted_unique(levels)
        n = [(count(group .and. known .and. defined .and. equals(keys(:, i_scale), levels(m))), m = 1, size(levels))]
        z = [(count(group .and. known .and. defined .and. hit .and. equals(keys(:, i_scale), levels(m))), &
              m = 1, size(levels))]
        theta = nan
        beta = nan
        separated = .false.
        if (sum(n) == 0 .and. undefined > 0) then
          note = 'no case with a defined figure'
        else if (sum(n) == 0) then
          note = 'no case with a physical outcome'
        else if (sum(z) == 0) then
          note = 'no case exceeds: no fit'
        else if (sum(z) == sum(n)) then
          note = 'every case exceeds: no fit'
        else
          call fit_stripes(levels, n, z, theta, beta, separated)
          note = ''
          if (separated) note = 'the outcomes separate in the intensity: no finite maximum, beta -> 0'
          if (ieee_is_nan(theta)) note = 'no finite maximum: the exceedances do not grow with the intensity'
        end if
        ! P(exceed | 0) = 0 in the lognormal model: no likelihood, so not in n_known
        at_zero = count(group .and. (limit .or. status == status_completed) .and. equals(keys(:, i_scale), 0.0_wp))
        if (at_zero > 0 .and. len(note) > 0) note = note // '; '
        if (at_zero > 0) note = note // itoa(at_zero) // ' cases at intensity 0 left out (no likelihood)'
        row = ' {'
        do k = 1, size(inputs)
          if (k == i_scale) cycle
          call number(keys(order(g), k), a)
          row = row // '"' // trim(inputs(k)) // '": ' // a // ', '
        end do
        if (state == 0) then
          row = row // '"limit_state": "model_limit", '
        else
          row = row // '"limit_state": "' // trim(states(max(state, 1))) // '", '
        end if
        call number(theta, a)
        call number(beta, b)
        row = row // '"im": "scale", "theta": ' // a // ', "beta": ' // b // &
            ', "n_points": ' // itoa(size(levels)) // ', "n_known": ' // itoa(sum(n)) // &
            ', "n_exceeded": ' // itoa(sum(z)) // ', "n_undefined": ' // itoa(undefined) // &
            ', "note": "' // note // '"}'
        if (len(text) > 0) text = text // ',' // new_line('a')
        text = text // row
      end do
    end do
  contains
    subroutine number(value, out)
      real(wp), intent(in) :: value
      character(len=:), allocatable, intent(out) :: out
      character(len=40) :: buffer
      integer :: length
      if (ieee_is_nan(value)) then
        out = 'null'
      else
        call real_text(value, buffer, length)
        out = buffer(:length)
      end if
    end subroutine number
  end subroutine fragility_json

  !> values sorted increasing, each once.
  subroutine sorted_unique(values)
    real(wp), allocatable, intent(inout) :: values(:)
    integer :: info, j, kept
    if (size(values) > 1) call dlasrt('I', size(values), values, info)
    kept = min(size(values), 1)
    do j = 2, size(values)
      if (.not. equals(values(j), values(kept))) then
        kept = kept + 1
        values(kept) = values(j)
      end if
    end do
    values = values(:kept)
  end subroutine sorted_unique

  !> The table, a column per statistic and a value per stripe (the order of
  !> suite_statistics's DataFrame).
  function stripe_columns(inputs, input_units, keys, status, states, flags, figures, figure_units, values) &
      result(columns)
    character(len=*), intent(in) :: inputs(:), input_units(:), states(:), figures(:), figure_units(:)
    real(wp), intent(in) :: keys(:, :), values(:, :)
    integer, intent(in) :: status(:)
    integer(i8), intent(in) :: flags(:, :)
    type(column_t), allocatable :: columns(:)
    integer, allocatable :: order(:), starts(:)
    logical :: present_limits(size(model_limits))
    logical :: stripe(size(status)), inside(size(status)), beyond(size(status))
    real(wp), allocatable :: chosen(:)
    real(wp) :: known, nan
    integer :: n_stripes, s, k, c, j, info
    nan = ieee_value(nan, ieee_quiet_nan)
    call sort_cases(keys, order)
    ! a stripe begins where the key changes
    allocate (starts(0))
    do j = 1, size(order)
      if (j == 1) then
        starts = [starts, j]
      else if (.not. same_key(keys(order(j), :), keys(order(j - 1), :))) then
        starts = [starts, j]
      end if
    end do
    n_stripes = size(starts)
    starts = [starts, size(order) + 1]
    present_limits = [(any(status == model_limits(k)), k = 1, size(model_limits))]
    allocate (columns(size(inputs) + 5 + count(present_limits) + 3 * size(states) + 4 * size(figures)))
    do k = 1, size(columns)
      allocate (columns(k)%values(n_stripes))
    end do
    do s = 1, n_stripes
      stripe = .false.
      stripe(order(starts(s):starts(s + 1) - 1)) = .true.
      inside = stripe .and. status == status_completed
      beyond = stripe .and. [(any(status(j) == model_limits), j = 1, size(status))]
      known = real(count(inside) + count(beyond), wp)
      c = 0
      do k = 1, size(inputs)
        call put(inputs(k), input_units(k), .false., keys(order(starts(s)), k))
      end do
      call put('n_cases', '1', .true., real(count(stripe), wp))
      call put('n_completed', '1', .true., real(count(inside), wp))
      call put('n_limit', '1', .true., real(count(beyond), wp))
      do k = 1, size(model_limits)
        if (present_limits(k)) &
          call put('n_' // status_name(model_limits(k)), '1', .true., real(count(stripe .and. status == model_limits(k)), wp))
      end do
      call put('n_unresolved', '1', .true., real(count(stripe), wp) - known)
      call put('fraction_limit', '1', .false., merge(real(count(beyond), wp) / max(known, 1.0_wp), nan, known > 0))
      do k = 1, size(states)
        ! the completed cases whose figure is undefined (flag -1) have no outcome here
        associate (hit => real(count(inside .and. flags(:, k) == flag_exceeded) + count(beyond), wp), &
                   undefined => real(count(inside .and. flags(:, k) == flag_undefined), wp))
          call put('n_' // trim(states(k)), '1', .true., hit)
          call put('n_undefined_' // trim(states(k)), '1', .true., undefined)
          call put('fraction_' // trim(states(k)), '1', .false., &
                   merge(hit / max(known - undefined, 1.0_wp), nan, known - undefined > 0))
        end associate
      end do
      do k = 1, size(figures)
        chosen = pack(values(:, k), inside .and. ieee_is_finite(values(:, k)))
        if (size(chosen) > 1) call dlasrt('I', size(chosen), chosen, info)
        call put(trim(figures(k)) // '_n', '1', .true., real(size(chosen), wp))
        call put(trim(figures(k)) // '_p16', figure_units(k), .false., percentile(chosen, 16))
        call put(trim(figures(k)) // '_p50', figure_units(k), .false., percentile(chosen, 50))
        call put(trim(figures(k)) // '_p84', figure_units(k), .false., percentile(chosen, 84))
      end do
    end do
  contains
    subroutine put(name, units, is_count, value)
      character(len=*), intent(in) :: name, units
      logical, intent(in) :: is_count
      real(wp), intent(in) :: value
      c = c + 1
      columns(c)%name = name
      columns(c)%units = units
      columns(c)%count = is_count
      columns(c)%values(s) = value
    end subroutine put
  end function stripe_columns

  !> numpy's percentile of sorted values, method 'linear' (Hyndman and Fan's
  !> type 7), in its arithmetic: the index (n - 1) q, q = p / 100, and the
  !> interpolation from the nearer end (numpy's _lerp); NaN of none.
  pure real(wp) function percentile(sorted, p) result(value)
    real(wp), intent(in) :: sorted(:)
    integer, intent(in) :: p
    real(wp) :: h, gamma, a, b, q
    integer :: low
    value = ieee_value(value, ieee_quiet_nan)
    if (size(sorted) == 0) return
    q = real(p, wp) / 100
    h = real(size(sorted) - 1, wp) * q
    low = int(floor(h))
    gamma = h - low
    a = sorted(low + 1)
    b = sorted(min(low + 2, size(sorted)))
    if (gamma >= 0.5_wp) then
      value = b - (b - a) * (1 - gamma)
    else
      value = a + (b - a) * gamma
    end if
  end function percentile

  pure logical function same_key(a, b)
    real(wp), intent(in) :: a(:), b(:)
    integer :: k
    same_key = .true.
    do k = 1, size(a)
      if (ieee_is_nan(a(k)) .or. ieee_is_nan(b(k))) then
        same_key = same_key .and. (ieee_is_nan(a(k)) .and. ieee_is_nan(b(k)))
      else
        same_key = same_key .and. equals(a(k), b(k))
      end if
    end do
  end function same_key

  !> Whether key a sorts before key b: by the first input, then the next
  !> (numpy's unique over rows; NaN last).
  pure logical function before(a, b)
    real(wp), intent(in) :: a(:), b(:)
    integer :: k
    before = .false.
    do k = 1, size(a)
      if (ieee_is_nan(a(k)) .and. ieee_is_nan(b(k))) cycle
      if (ieee_is_nan(a(k))) return
      if (ieee_is_nan(b(k))) then
        before = .true.
        return
      end if
      if (a(k) < b(k)) then
        before = .true.
        return
      end if
      if (a(k) > b(k)) return
    end do
  end function before

  !> The cases (1-based) in the order of their keys, equal keys by index: a
  !> merge sort (O(n log n)), bottom up.
  subroutine sort_cases(keys, order)
    real(wp), intent(in) :: keys(:, :)
    integer, allocatable, intent(out) :: order(:)
    integer, allocatable :: merged(:)
    integer :: n, width, low, middle, high, i, j, k
    logical :: take_left
    n = size(keys, 1)
    allocate (order(n), merged(n))
    order = [(k, k = 1, n)]
    width = 1
    do while (width < n)
      do low = 1, n, 2 * width
        middle = min(low + width, n + 1)
        high = min(low + 2 * width, n + 1)
        i = low
        j = middle
        do k = low, high - 1
          take_left = i < middle
          if (take_left .and. j < high) take_left = .not. before(keys(order(j), :), keys(order(i), :))
          if (take_left) then
            merged(k) = order(i)
            i = i + 1
          else
            merged(k) = order(j)
            j = j + 1
          end if
        end do
      end do
      order = merged
      width = 2 * width
    end do
  end subroutine sort_cases

  !> The columns as text (a row per stripe), CSV (a header row, NaN as nan)
  !> or strict JSON ({file, percentiles, stripe_inputs, units, stripes}, NaN
  !> as null).
  subroutine print_columns(path, format, inputs, columns, fragility)
    character(len=*), intent(in) :: path, format, fragility
    character(len=*), intent(in) :: inputs(:)
    type(column_t), intent(in) :: columns(:)
    character(len=:), allocatable :: line, text
    integer :: s, k, n
    n = 0
    if (size(columns) > 0) n = size(columns(1)%values)
    select case (format)
    case ('json')
      line = '{"file": "' // json_text(path) // '", "percentiles": "linear", "stripe_inputs": ['
      do k = 1, size(inputs)
        if (k > 1) line = line // ', '
        line = line // '"' // trim(inputs(k)) // '"'
      end do
      line = line // '], "units": {'
      do k = 1, size(columns)
        if (k > 1) line = line // ', '
        line = line // '"' // trim(columns(k)%name) // '": "' // trim(columns(k)%units) // '"'
      end do
      call put_line(line // '}, "stripes": [')
      do s = 1, n
        line = ' {'
        do k = 1, size(columns)
          if (k > 1) line = line // ', '
          call cell(columns(k), s, 'null', text)
          line = line // '"' // trim(columns(k)%name) // '": ' // text
        end do
        call put_line(line // trim(merge('}, ', '}  ', s < n)))
      end do
      ! the fragilities: maximum likelihood theta and beta in the scale, no bootstrap
      call put_line('], "fragility": [')
      if (len(fragility) > 0) call put_line(fragility)
      call put_line(']}')
    case ('csv')
      line = ''
      do k = 1, size(columns)
        if (k > 1) line = line // ','
        line = line // trim(columns(k)%name)
      end do
      call put_line(line)
      do s = 1, n
        line = ''
        do k = 1, size(columns)
          if (k > 1) line = line // ','
          call cell(columns(k), s, 'NaN', text)
          line = line // text
        end do
        call put_line(line)
      end do
    case default
      call put_line(path // ': ' // itoa(n) // ' stripes; each figure''s median, 16th and 84th ' // &
          'percentile (numpy''s linear) over the completed cases; fraction_* of the cases with a physical outcome')
      do s = 1, n
        line = ''
        do k = 1, size(columns)
          call cell(columns(k), s, 'nan', text)
          line = line // '  ' // trim(columns(k)%name) // ' = ' // text
          if (.not. columns(k)%count .and. trim(columns(k)%units) /= '1') line = line // ' ' // trim(columns(k)%units)
        end do
        call put_line('stripe ' // itoa(s) // ':' // line)
      end do
    end select
  end subroutine print_columns

  !> Value s of a column: a count as a whole number, a real as its shortest
  !> text, `missing` where it is NaN.
  subroutine cell(column, s, missing, text)
    type(column_t), intent(in) :: column
    integer, intent(in) :: s
    character(len=*), intent(in) :: missing
    character(len=:), allocatable, intent(out) :: text
    character(len=40) :: number
    integer :: n
    if (ieee_is_nan(column%values(s))) then
      text = missing
    else if (column%count) then
      text = itoa(nint(column%values(s), i8))
    else
      call real_text(column%values(s), number, n)
      text = number(:n)
    end if
  end subroutine cell
end module ellroll_cmd_suite
