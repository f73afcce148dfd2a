!> Cases and plans for the tests, and a helper that runs a case.
module fixtures
  use ellroll_kinds, only: wp, i8
  use ellroll_errors, only: error_t
  use ellroll_cases, only: case_t, output_plan_t
  use ellroll_results, only: case_result_t
  use ellroll_simulate, only: simulate_case
  use ellroll_integrators, only: methods
  use ellroll_params, only: p_a, p_b, p_c, p_dt, p_g, p_mass, p_omega_x, p_omega_z, p_radius, p_x, p_y
  implicit none
  private
  public :: paper_case, plan_for, run_case, other_pair

contains

  !> The adaptive method after `name` in the method table (cyclically): the
  !> peer a pair's results are checked against.
  pure function other_pair(name) result(other)
    character(len=*), intent(in) :: name
    character(len=len(methods%name)) :: other
    integer :: k, j
    k = findloc(methods%name, name, dim=1)
    other = name
    do j = 1, size(methods) - 1
      if (methods(modulo(k + j - 1, size(methods)) + 1)%adaptive) then
        other = methods(modulo(k + j - 1, size(methods)) + 1)%name
        return
      end if
    end do
  end function other_pair

  !> Legeza (1990), section 3.
  function paper_case(dt, t_end) result(cs)
    real(wp), intent(in) :: dt, t_end
    type(case_t) :: cs
    cs%param(p_a) = 1; cs%param(p_b) = 0.4_wp; cs%param(p_c) = 0.2_wp
    cs%param(p_radius) = 0.2_wp
    cs%param(p_g) = 9.81_wp
    cs%param(p_mass) = 2620 / cs%param(p_g)
    cs%param(p_x) = 0; cs%param(p_y) = 0
    cs%param(p_omega_x:p_omega_z) = [-2.0_wp, 2.0_wp, 20.0_wp]
    cs%param(p_dt) = dt
    cs%t_end = t_end
  end function paper_case

  !> Output every `every` steps, all fields.
  function plan_for(cs, every) result(plan)
    type(case_t), intent(in) :: cs
    integer, intent(in) :: every
    type(output_plan_t) :: plan
    plan%interval = every * cs%param(p_dt)
    plan%n_samples = nint(cs%t_end / cs%param(p_dt), i8) / every + 1
    plan%fields = .true.
  end function plan_for

  function run_case(cs, every) result(res)
    type(case_t), intent(in) :: cs
    integer, intent(in) :: every
    type(case_result_t) :: res
    type(error_t) :: err
    call simulate_case(cs, plan_for(cs, every), res, err)
    if (err%failed()) error stop 'run_case: ' // err%message
  end function run_case
end module fixtures
