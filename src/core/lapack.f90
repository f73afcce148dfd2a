!> Explicit interfaces for the LAPACK routines ellroll calls (reference
!> LAPACK, double precision), so that every call is checked at compile time.
module ellroll_lapack
  use, intrinsic :: iso_fortran_env, only: dp => real64
  implicit none
  private

  public :: dgetrf, dgetrs, dgesv, dgeev, dsyev, dlasrt

  interface
    !> Sort d(1:n) in increasing (id = 'I') or decreasing ('D') order
    !> (introsort: O(n log n)); d must hold no NaN.
    subroutine dlasrt(id, n, d, info)
      import :: dp
      character(len=1), intent(in) :: id
      integer, intent(in) :: n
      real(dp), intent(inout) :: d(*)
      integer, intent(out) :: info
    end subroutine dlasrt

    !> LU factorisation with partial pivoting of a general m x n matrix.
    subroutine dgetrf(m, n, a, lda, ipiv, info)
      import :: dp
      integer, intent(in) :: m, n, lda
      real(dp), intent(inout) :: a(lda, *)
      integer, intent(out) :: ipiv(*)
      integer, intent(out) :: info
    end subroutine dgetrf

    !> Solve A X = B (trans = 'N') with the LU factors from dgetrf.
    subroutine dgetrs(trans, n, nrhs, a, lda, ipiv, b, ldb, info)
      import :: dp
      character(len=1), intent(in) :: trans
      integer, intent(in) :: n, nrhs, lda, ldb
      real(dp), intent(in) :: a(lda, *)
      integer, intent(in) :: ipiv(*)
      real(dp), intent(inout) :: b(ldb, *)
      integer, intent(out) :: info
    end subroutine dgetrs

    !> Solve A X = B for a general A (LU with partial pivoting).
    subroutine dgesv(n, nrhs, a, lda, ipiv, b, ldb, info)
      import :: dp
      integer, intent(in) :: n, nrhs, lda, ldb
      real(dp), intent(inout) :: a(lda, *)
      integer, intent(out) :: ipiv(*)
      real(dp), intent(inout) :: b(ldb, *)
      integer, intent(out) :: info
    end subroutine dgesv

    !> Eigenvalues (and optionally eigenvectors) of a general n x n matrix.
    subroutine dgeev(jobvl, jobvr, n, a, lda, wr, wi, vl, ldvl, vr, ldvr, work, lwork, info)
      import :: dp
      character(len=1), intent(in) :: jobvl, jobvr
      integer, intent(in) :: n, lda, ldvl, ldvr, lwork
      real(dp), intent(inout) :: a(lda, *)
      real(dp), intent(out) :: wr(*), wi(*)
      real(dp), intent(inout) :: vl(ldvl, *), vr(ldvr, *)
      real(dp), intent(inout) :: work(*)
      integer, intent(out) :: info
    end subroutine dgeev

    !> Eigenvalues (ascending; and optionally eigenvectors) of a symmetric matrix.
    subroutine dsyev(jobz, uplo, n, a, lda, w, work, lwork, info)
      import :: dp
      character(len=1), intent(in) :: jobz, uplo
      integer, intent(in) :: n, lda, lwork
      real(dp), intent(inout) :: a(lda, *)
      real(dp), intent(out) :: w(*)
      real(dp), intent(inout) :: work(*)
      integer, intent(out) :: info
    end subroutine dsyev
  end interface
end module ellroll_lapack
