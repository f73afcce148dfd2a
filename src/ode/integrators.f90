!> The integration methods. One table says what each is (its name, kind,
!> order, dense output, whether it runs cases across SIMD lanes, its
!> stability on the imaginary axis, when to use it), and new_integrator
!> builds it. Whatever names, lists, checks or picks a method reads the
!> table: the input's check of `method`, `ellroll methods`, the batches,
!> the step-size advice, the tests that run every method.
!>
!>   rk4     classical Runge-Kutta, fixed step, order 4 (the source paper's method)
!>   dop853  Dormand-Prince 8(5,3), adaptive, with 7th-order dense output
!>   vern9   Verner's 9(8) pair, adaptive, with 8th-order dense output
!>   gauss4  2-stage Gauss-Legendre, implicit, symmetric, order 4 (simplified
!>           Newton, LAPACK LU): bounded energy error over long runs
module ellroll_integrators
  use ellroll_kinds, only: wp
  use ellroll_errors, only: error_t, set_error, err_input
  use ellroll_integrator, only: integrator_t, max_equations
  use ellroll_embedded_pair, only: embedded_pair_t, max_pair_stages, estimate_round_off, shortest_h, tolerance_ratio_cap
  use ellroll_rk4, only: rk4_t
  use ellroll_gauss4, only: gauss4_t
  use ellroll_dop853, only: dop853_t
  use ellroll_vern9, only: vern9_t
  implicit none
  private

  public :: integrator_t, embedded_pair_t, max_equations, max_pair_stages, estimate_round_off, shortest_h, &
            tolerance_ratio_cap
  public :: method_info_t, methods, method_info, method_names, new_integrator, new_pair, stability_limit

  !> What a method is, for users and for the code that picks how to run it.
  type :: method_info_t
    character(len=8) :: name
    character(len=10) :: kind                  !< fixed, adaptive or symmetric
    character(len=24) :: order                 !< the order, as a user reads it
    logical :: adaptive                        !< the step is chosen by error control (dt is the largest step)
    character(len=80) :: use_for               !< when to pick it (bench/workprecision.py, bench/pairs.py)
    integer :: convergence_order = 0           !< p: the error of a run is O(h^p) (measured by the tests)
    integer :: dense_order = 0                 !< the order of its dense output; 0: it has none
    logical :: batches = .false.               !< it runs cases across SIMD lanes (ellroll_batch_run)
    !> the largest |lambda h| on the imaginary axis for which the method is
    !> stable (the rolling ball's linearised motion is oscillatory); huge
    !> where no fixed step limits it (A-stable, or error control)
    real(wp) :: stability_limit = huge(1.0_wp)
  end type method_info_t

  type(method_info_t), parameter :: methods(4) = [ &
      method_info_t('rk4', 'fixed', '4', .false., &
                    "the paper's; large campaigns at errors of about 1e-3 m (SIMD batches)", &
                    convergence_order=4, batches=.true., stability_limit=2 * sqrt(2.0_wp)), &
      method_info_t('dop853', 'adaptive', '8(5,3), dense output 7', .true., &
                    'accurate runs, rtol 1e-3 to 1e-7; outputs at any interval', &
                    convergence_order=8, dense_order=7, batches=.true.), &
      method_info_t('vern9', 'adaptive', '9(8), dense output 8', .true., &
                    'rtol 1e-8 and below: fewer RHS calls and a smaller error than dop853', &
                    convergence_order=9, dense_order=8, batches=.true.), &
      method_info_t('gauss4', 'symmetric', '4', .false., &
                    'long runs of a conservative case: energy error bounded, not drifting', &
                    convergence_order=4)]

contains

  !> A new integrator of the method `name` (a row of methods).
  subroutine new_integrator(name, integrator, err)
    character(len=*), intent(in) :: name
    class(integrator_t), allocatable, intent(out) :: integrator
    type(error_t), intent(inout) :: err
    select case (name)
    case ('rk4'); allocate (rk4_t :: integrator)
    case ('dop853'); allocate (dop853_t :: integrator)
    case ('vern9'); allocate (vern9_t :: integrator)
    case ('gauss4'); allocate (gauss4_t :: integrator)
    case default
      call set_error(err, err_input, "unknown integration method '" // name // "' (known: " // method_names() // ")")
      return
    end select
    integrator%method = findloc(methods%name, name, dim=1)
  end subroutine new_integrator

  !> A new embedded pair of the method `name` (an adaptive row of methods).
  subroutine new_pair(name, pair, err)
    character(len=*), intent(in) :: name
    class(embedded_pair_t), allocatable, intent(out) :: pair
    type(error_t), intent(inout) :: err
    class(integrator_t), allocatable :: integrator
    call new_integrator(name, integrator, err)
    if (err%failed()) return
    select type (integrator)
    class is (embedded_pair_t)
      allocate (pair, source=integrator)
    class default
      call set_error(err, err_input, "integration method '" // name // "' is not an embedded pair")
    end select
  end subroutine new_pair

  !> The largest |lambda h| on the imaginary axis for which the integrator's
  !> method is stable (its row's stability_limit).
  pure real(wp) function stability_limit(integrator)
    class(integrator_t), intent(in) :: integrator
    stability_limit = huge(1.0_wp)
    if (integrator%method > 0) stability_limit = methods(integrator%method)%stability_limit
  end function stability_limit

  !> The methods' names, for messages: 'rk4 dop853 vern9 gauss4'.
  pure function method_names() result(names)
    character(len=sum(len_trim(methods%name)) + size(methods) - 1) :: names
    integer :: k, at
    names = methods(1)%name
    at = len_trim(methods(1)%name)
    do k = 2, size(methods)
      names(at + 1:) = ' ' // methods(k)%name
      at = at + 1 + len_trim(methods(k)%name)
    end do
  end function method_names

  !> The row of methods named `name` (name blank where there is none).
  pure type(method_info_t) function method_info(name) result(info)
    character(len=*), intent(in) :: name
    integer :: k
    info = method_info_t('', '', '', .false., '')
    k = findloc(methods%name, name, dim=1)
    if (k > 0) info = methods(k)
  end function method_info
end module ellroll_integrators
