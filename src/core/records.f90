!> A named, documented value: the one description of a quantity that the
!> writer stores, `ellroll check` prints and the tests read back.
module ellroll_records
  use ellroll_kinds, only: wp, i8
  implicit none
  private

  public :: named_value_t, real_value, vector_value, int_value, text_value
  public :: kind_real, kind_int, kind_text

  integer, parameter :: kind_real = 1, kind_int = 2, kind_text = 3

  type :: named_value_t
    character(len=32) :: name = ''
    character(len=16) :: units = ''
    character(len=160) :: description = ''
    integer :: kind = kind_real
    integer :: ncomp = 1                !< 1 (scalar), 2 (one value per mode) or 3 (vector)
    real(wp) :: reals(3) = 0
    integer(i8) :: int = 0
    character(len=64) :: text = ''
  end type named_value_t

contains

  pure function real_value(name, units, description, value) result(v)
    character(len=*), intent(in) :: name, units, description
    real(wp), intent(in) :: value
    type(named_value_t) :: v
    v = named_value_t(name=name, units=units, description=description, kind=kind_real)
    v%reals(1) = value
  end function real_value

  pure function vector_value(name, units, description, value) result(v)
    character(len=*), intent(in) :: name, units, description
    real(wp), intent(in) :: value(:)                !< 2 or 3 components
    type(named_value_t) :: v
    v = named_value_t(name=name, units=units, description=description, kind=kind_real, ncomp=size(value))
    v%reals(:size(value)) = value
  end function vector_value

  pure function int_value(name, units, description, value) result(v)
    character(len=*), intent(in) :: name, units, description
    integer(i8), intent(in) :: value
    type(named_value_t) :: v
    v = named_value_t(name=name, units=units, description=description, kind=kind_int)
    v%int = value
  end function int_value

  pure function text_value(name, description, value) result(v)
    character(len=*), intent(in) :: name, description, value
    type(named_value_t) :: v
    v = named_value_t(name=name, units='1', description=description, kind=kind_text)
    v%text = value
  end function text_value
end module ellroll_records
