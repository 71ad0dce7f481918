"""The minimum-norm least-squares solution x = E^+ b of the reaction balance
(:mod:`fccgen.mechanism.reactions`), record by record.

The rule is the dense one: the singular values of E at or below RANK_RTOL times the
largest are dropped (redundant constraints leave reaction components undetermined;
the minimum-norm x is reported then). Two ways reach it:

* dense (:func:`solve_dense`): the SVD of every record's E, vectorised over records.
  What small systems take (at most DENSE_UNKNOWNS unknowns), and every record that
  the sparse way cannot certify;
* sparse (:func:`solve_sparse`), for one record: E is sparse (6 n_b x unknowns, a
  few entries per column) and G = E^T E is its small sparse Gram matrix. One LDL^T of
  G - tau I (SuperLU in symmetric mode with diagonal pivots; tau = (ZERO_TOL s)^2,
  s^2 = ||G||_1 >= sigma_1^2) gives both the certificate and the solve:

  - the number of its negative pivots is the number of eigenvalues of G below tau
    (Sylvester's law of inertia). None means every sigma_k of E exceeds
    ZERO_TOL sigma_1 > RANK_RTOL sigma_1: E has full column rank, the dense rule keeps
    every direction and x is the unique least-squares solution;
  - x comes from the corrected semi-normal equations: x = F^-1 E^T b, then up to
    REFINE corrections dx = F^-1 E^T (b - E x) with the residual taken on E itself
    (F = G - tau I; each correction removes the shift and the rounding of the squared
    system), until a correction is at most CONVERGED ||x||.

  A record with an eigenvalue below tau (redundant reactions, or a near-singular
  balance), an off-diagonal pivot, or a refinement that does not settle is solved
  densely instead, so the answer is the dense rule's wherever the sparse way is not
  certified. Its cost is a sparse factorisation of the unknowns' size per record, and
  it never holds more than one record's E.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.sparse.csgraph import reverse_cuthill_mckee
from scipy.sparse.linalg import splu

# Relative singular value of E (its largest = 1) below which a direction counts as
# lost: redundant constraints give singular values at the level of the recorded
# constraint error (~1e-11 of a length), real ones are O(1) in N and N m per metre.
RANK_RTOL = 1e-8
# The sparse certificate: no singular value below this fraction of the largest (the
# shift tau = ZERO_TOL^2 s^2 sits above the rounding of G, eps ||G|| ~ 1e-16 s^2).
ZERO_TOL = 1e-7
REFINE = 3               # corrections of the semi-normal solution, at most
CONVERGED = 1e-10        # the last correction, relative to ||x||, to accept a record
DENSE_UNKNOWNS = 48      # systems this small take the dense SVD (vectorised)
BAND_FILL = 64           # banded Cholesky while (width + 1)^2 <= this times the unknowns
RETRY_AFTER = 16         # records between sparse attempts after one that failed


def solve_dense(E: np.ndarray, b: np.ndarray):
    """(x, rank per record): minimum-norm least-squares x of E x = b, E (n, rows,
    unknowns) dense, by the SVD of each record."""
    if E.shape[2] == 0:
        return np.zeros((len(b), 0)), np.zeros(len(b), int)
    U, s, Vt = np.linalg.svd(E, full_matrices=False)
    keep = s > RANK_RTOL * s[:, :1]
    inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    y = np.einsum("nki,nk->ni", U, b) * inv
    return np.einsum("nij,ni->nj", Vt, y), keep.sum(axis=1)


class Pattern:
    """What the fixed pattern of E gives once for all records: the rows of its entries,
    the pattern of G = E^T E in a reverse Cuthill-McKee order of the unknowns, and G's
    bandwidth there. Structures built as chains (booms, masts, arrays) have G banded in
    that order, so a record's G - tau I is factorised by a banded Cholesky (LAPACK
    pbtrf: O(m w^2), no ordering per record); a wider band takes SuperLU."""

    def __init__(self, system):
        self.m = m = system.shape[1]
        indptr, self.cols = system.indptr, system.indices.astype(np.intp)
        self.row_of = np.repeat(np.arange(system.shape[0]), np.diff(indptr))
        self.starts = indptr[:-1][np.diff(indptr) > 0]
        self.filled = np.flatnonzero(np.diff(indptr) > 0)
        self.n_rows = system.shape[0]
        # every pair (p, q) of entries in one row adds E_p E_q to G[col p, col q]
        count = np.diff(indptr).astype(np.intp)
        size = np.repeat(count, count ** 2)
        local = np.arange(size.size) - np.repeat(np.cumsum(count ** 2) - count ** 2,
                                                 count ** 2)
        start = np.repeat(indptr[:-1].astype(np.intp), count ** 2)
        p, q = start + local // np.maximum(size, 1), start + local % np.maximum(size, 1)
        pattern = sp.csr_matrix((np.ones(len(p)), (self.cols[p], self.cols[q])),
                                shape=(m, m))
        self.perm = (reverse_cuthill_mckee(pattern, symmetric_mode=True).astype(np.intp)
                     if m else np.zeros(0, np.intp))
        where = np.empty(m, np.intp)
        where[self.perm] = np.arange(m)
        i, j = where[self.cols[p]], where[self.cols[q]]
        lower = i >= j                          # G is symmetric: its lower band
        self.p, self.q = p[lower], q[lower]
        self.width = int(np.max(i[lower] - j[lower])) if lower.any() else 0
        self.band_at = (i[lower] - j[lower]) * m + j[lower]
        self.banded = (self.width + 1) * (self.width + 1) <= BAND_FILL * max(m, 1)

    def times(self, values, x):
        """E x of one record (values: its entries)."""
        out = np.zeros(self.n_rows)
        if self.starts.size:
            out[self.filled] = np.add.reduceat(values * x[self.cols], self.starts)
        return out

    def transposed(self, values, r):
        """E^T r of one record."""
        return np.bincount(self.cols, weights=values * r[self.row_of], minlength=self.m)

    def gram_band(self, values) -> np.ndarray:
        """(width + 1, m): the lower band of G = E^T E in the permuted order (LAPACK's
        lower banded storage: row d holds G[j + d, j])."""
        band = np.bincount(self.band_at, weights=values[self.p] * values[self.q],
                           minlength=(self.width + 1) * self.m)
        return band.reshape(self.width + 1, self.m)


def _one_norm(band: np.ndarray) -> float:
    """||G||_1 of the symmetric G from its lower band (an upper bound of sigma_1^2)."""
    a = np.abs(band)
    sums = a.sum(axis=0)
    for d in range(1, a.shape[0]):
        sums[d:] += a[d, :-d]
    return float(sums.max()) if sums.size else 0.0


def solve_sparse(pattern: Pattern, values: np.ndarray, b: np.ndarray,
                 E: sp.csr_matrix | None = None) -> np.ndarray | None:
    """x of one record by the certified sparse way (module docstring), None when it
    cannot certify the record (the caller solves it densely). values: the record's
    entries of E; E: the record's E as CSR (needed when the band is too wide)."""
    m = pattern.m
    if pattern.banded:
        band = pattern.gram_band(values)
        scale = _one_norm(band)
        if not scale > 0.0 or not np.isfinite(scale):
            return None
        band[0] -= ZERO_TOL ** 2 * scale
        try:                                   # succeeds iff G - tau I is definite
            factor = cholesky_banded(band, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            return None
        perm = pattern.perm

        def solve(rhs):
            out = np.empty(m)
            out[perm] = cho_solve_banded((factor, True), rhs[perm], check_finite=False)
            return out
    else:
        G = (E.T @ E).tocsc()
        scale = float(abs(G).sum(axis=0).max()) if G.nnz else 0.0
        if not scale > 0.0 or not np.isfinite(scale):
            return None
        try:
            lu = splu((G - ZERO_TOL ** 2 * scale * sp.identity(m, format="csc")).tocsc(),
                      permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                      options=dict(SymmetricMode=True))
        except RuntimeError:                   # exactly singular
            return None
        if not np.array_equal(lu.perm_r, lu.perm_c) or np.any(lu.U.diagonal() <= 0.0):
            return None
        solve = lu.solve
    x = solve(pattern.transposed(values, b))
    for _ in range(REFINE):
        dx = solve(pattern.transposed(values, b - pattern.times(values, x)))
        x += dx
        if not np.all(np.isfinite(x)):
            return None
        if np.linalg.norm(dx) <= CONVERGED * max(np.linalg.norm(x), 1e-300):
            return x
    return None


def solve_records(system, sparse: bool | None = None, patterns: dict | None = None):
    """(x (n, unknowns), rank per record, records solved densely, max |E x - b|) of a
    :class:`~fccgen.mechanism.reaction_system.System`. sparse None: the sparse way
    for systems of more than DENSE_UNKNOWNS unknowns; True/False forces it. After a
    record the sparse way could not certify, the next RETRY_AFTER - 1 records go
    straight to the dense SVD (a model with redundant reactions fails it everywhere).
    patterns: a dict kept across calls, so that chunks of one run share their
    :class:`Pattern`."""
    n, m = system.n, system.shape[1]
    if sparse is None:
        sparse = m > DENSE_UNKNOWNS
    if not sparse or m == 0:
        E = system.dense()
        x, rank = solve_dense(E, system.b)
        r = np.einsum("nij,nj->ni", E, x) - system.b
        return x, rank, n, float(np.max(np.abs(r))) if r.size else 0.0
    x = np.zeros((n, m))
    rank = np.full(n, m)
    key = (system.shape, system.indptr.tobytes(), system.indices.tobytes())
    patterns = {} if patterns is None else patterns
    if key not in patterns:
        patterns[key] = Pattern(system)
    pattern = patterns[key]
    dense, worst, skip = 0, 0.0, 0
    for k in range(n):
        values, found = system.values[k], None
        if skip:
            skip -= 1
        else:
            found = solve_sparse(pattern, values, system.b[k],
                                 None if pattern.banded else system.matrix(k))
            skip = 0 if found is not None else RETRY_AFTER - 1
        if found is None:
            xk, rk = solve_dense(system.dense(slice(k, k + 1)), system.b[k:k + 1])
            found, rank[k] = xk[0], rk[0]
            dense += 1
        x[k] = found
        r = pattern.times(values, found) - system.b[k]
        if r.size:
            worst = max(worst, float(np.max(np.abs(r))))
    return x, rank, dense, worst
