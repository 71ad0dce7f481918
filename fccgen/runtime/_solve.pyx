# cython: language_level=3
"""The dense constrained solve (engine/fcc_dense.c) from Python, and the table of
LAPACK and BLAS routines the C engine calls through.

The C engine links no LAPACK: the dense path's QR, SVD and Cholesky (and ALI3-P's
Cholesky and LU) go through an fcc_lapack table of function pointers, filled here from
SciPy's Cython bindings (scipy.linalg.cython_lapack, cython_blas) when this module is
imported. Every engine the Python build makes takes this table.
"""
from scipy.linalg.cython_blas cimport dgemm
from scipy.linalg.cython_lapack cimport (dgeqp3, dgesvd, dgetrf, dgetrs, dormqr, dpotrf,
                                         dpotrs)

import numpy as np

from fccgen import rank as _rank
from fccgen.errors import SimulationError

from ._cengine cimport (FCC_OK, fcc_dense, fcc_dense_apply, fcc_dense_factor,
                        fcc_dense_free, fcc_dense_init, fcc_dense_svd_rank)

cdef fcc_lapack _LAPACK
_LAPACK.dgeqp3 = dgeqp3
_LAPACK.dormqr = dormqr
_LAPACK.dgesvd = dgesvd
_LAPACK.dpotrf = dpotrf
_LAPACK.dpotrs = dpotrs
_LAPACK.dgetrf = dgetrf
_LAPACK.dgetrs = dgetrs
_LAPACK.dgemm = dgemm

# The rank rule's numbers (fccgen.rank holds them): a rank increase needs
# sigma_{r+1} > GROW_TOL sigma_1; rows are scaled to unit length, but no row by more
# than 1 / (ROW_FLOOR * the largest row norm of its element).
GROW_TOL = _rank.GROW_TOL
ROW_FLOOR = _rank.ROW_FLOOR


cdef const fcc_lapack *lapack_table() noexcept nogil:
    """The LAPACK table of the Python build (filled at import, never changed)."""
    return &_LAPACK


cdef int _init(fcc_dense *s, int n, int m, double rank_tol) except -1:
    """A dense solve of n coordinates and m rows with this build's LAPACK table and
    the rank rule's numbers."""
    if fcc_dense_init(s, n, m, rank_tol, GROW_TOL, ROW_FLOOR, &_LAPACK) != FCC_OK:
        raise MemoryError("cannot allocate the work arrays of the constrained solve")
    return 0


def constrained_solve(M, B, Q, b, double rank_tol=1e-10, int rank=-1):
    """Solve one problem from Python (for tests and checks): returns (x, rank).

    M: (n, n), B: (m, n), Q: (n,), b: (m,). rank >= 0: the decided rank (see "Rank"
    in engine/fcc_dense.c), else the pivot threshold alone. Raises SimulationError
    when M is singular on the null space of B.
    """
    cdef double[:, ::1] Mv = np.ascontiguousarray(M, dtype=float)
    cdef double[:, ::1] Bv = np.ascontiguousarray(B, dtype=float).reshape(-1, Mv.shape[0])
    cdef double[::1] Qv = np.ascontiguousarray(Q, dtype=float)
    cdef double[::1] bv = np.ascontiguousarray(b, dtype=float)
    cdef int n = Mv.shape[0], m = Bv.shape[0], info
    if Mv.shape[1] != n or Qv.shape[0] != n or bv.shape[0] != m:
        raise ValueError(f"inconsistent shapes: M {np.shape(M)}, B {np.shape(B)}, "
                         f"Q {np.shape(Q)}, b {np.shape(b)}")
    x = np.zeros(n)
    cdef double[::1] xv = x
    cdef fcc_dense s
    _init(&s, n, m, rank_tol)
    s.rank_fixed = rank
    try:
        with nogil:
            info = fcc_dense_factor(&s, &Mv[0, 0] if n > 0 else NULL,
                                    &Bv[0, 0] if m * n > 0 else NULL)
            if info == 0 and n > 0:
                fcc_dense_apply(&s, &Qv[0], NULL, &bv[0] if m > 0 else NULL, &xv[0])
        if info > 0:
            raise SimulationError(
                f"mass matrix singular on the constraint manifold (reduced mass matrix of "
                f"size {s.nr} not positive definite at pivot {info}; rank of B {s.r})")
        if info < 0:
            raise SimulationError(f"LAPACK error {info} in the constrained solve")
        return x, s.r
    finally:
        fcc_dense_free(&s)


def singular_values(B):
    """Singular values of B with each row scaled to unit length, largest first (the
    matrix the rank decision looks at)."""
    cdef double[:, ::1] Bv = np.ascontiguousarray(B, dtype=float)
    cdef int m = Bv.shape[0], n = Bv.shape[1] if Bv.ndim == 2 else 0, k
    cdef fcc_dense s
    _init(&s, n, m, 1e-10)
    try:
        if n * m > 0:
            with nogil:
                k = fcc_dense_svd_rank(&s, &Bv[0, 0], 0.0)
            if k < 0:
                raise SimulationError("LAPACK's SVD (dgesvd) did not converge")
        return np.array([s.sigma[i] for i in range(min(n, m))])
    finally:
        fcc_dense_free(&s)
