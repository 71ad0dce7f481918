"""The rank decision of :mod:`fccgen.rank` for large constraint Jacobians, without a
dense SVD of the whole of B.

The rule is fccgen.rank's: with B's rows scaled (row_scales) and sigma_1 its largest
singular value, r = the number of sigma_k > DECIDE_TOL sigma_1, and the decision is
clear when no sigma_k lies in [AMBIGUOUS_LOW, GROW_TOL] sigma_1. A dense SVD costs
O(m n^2): minutes at a few thousand coordinates. Here:

1. B splits into the connected components of its coordinate graph (coordinates coupled
   by a row); the singular values of B are the union of the components'. A component
   of at most DENSE_COMPONENT coordinates takes the dense SVD (the rule as it is).
2. A larger component C (rows scaled) is decided in the squared domain G = C^T C
   (sparse, n_c x n_c, eigenvalues sigma^2 and zeros), by three signals that must agree:

   * inertia (Sylvester): the number of eigenvalues of G below tau is the number of
     negative pivots of an LDL^T of G - tau I (SuperLU in symmetric mode, diagonal
     pivots). d_low counts sigma < ZERO_TOL sigma_1, d_high sigma < GROW_TOL sigma_1;
     d_low != d_high is a singular value inside the uncertain band;
   * Lanczos (ARPACK, shift-invert about 0): the d + 1 smallest eigenvalues; the first
     d below ZERO_TOL^2 sigma_1^2, the next at least GROW_TOL^2 sigma_1^2 (it gives the
     last kept singular value sigma_r);
   * unsquared: for the d eigenvectors X (orthonormal), ||C X||_2 bounds the d smallest
     singular values of C from above (interlacing); it must be at most
     AMBIGUOUS_LOW sigma_1, the dense rule's clear zero.

   Then the component's rank is n_c - d, the decision the dense rule would take (its d
   smallest sigma lie below AMBIGUOUS_LOW, the others above GROW_TOL), and it is clear.
   Squaring loses what lies below sqrt(eps) sigma_1 (1.5e-8), which is why the zero
   side is certified unsquared. Any disagreement, or more than MAX_NULLITY zeros, hands
   the component to the dense SVD: slow, never wrong.

   sigma_1 is bracketed (:func:`bracket`: a Ritz value below, Gershgorin above) and
   each test takes the stricter side, so the bracket can only hand a component to the
   SVD.

A decision that used step 2 is a :class:`PartialRankDecision` (``how`` "certified"):
its ``sigma`` holds only the singular values computed, and its gap is (sigma_r, the
bound ||C X||_2) relative to the bracket's lower side. The SVD after a failed
certification says so in ``how``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import ArpackError, eigsh, splu

from .rule import (AMBIGUOUS_LOW, DECIDE_TOL, GROW_TOL, RankDecision, dense_decision,
                   scales_from_norms)

DENSE_COMPONENT = 500    # coordinates: a component up to this size takes the dense SVD
ZERO_TOL = 1e-7          # sigma / sigma_1 counted as zero by the inertia (squared: 1e-14,
                         # above the rounding of G, eps ||G|| ~ 1e-15 sigma_1^2)
ROUGH_STEPS = 20         # power steps of a rank-only bracket's lower side
MAX_NULLITY = 64         # more zeros than this in one component: the dense SVD decides


@dataclass(frozen=True)
class PartialRankDecision(RankDecision):
    """A decision of which only some singular values were computed (see the module
    docstring); ``kept`` and ``dropped`` are sigma_r / sigma_1 and an upper bound of
    sigma_(r+1) / sigma_1."""
    kept: float = 1.0
    dropped: float = 0.0

    @property
    def uncertain(self) -> list[float]:
        return []          # certified: no singular value in the band

    @property
    def gap(self) -> tuple[float, float]:
        return self.kept, self.dropped


def decide_large(B, n_q: int, groups=None, dense_max: int = DENSE_COMPONENT,
                 rank_only: bool = False) -> RankDecision:
    """The rank of B (dense or SciPy sparse, rows unscaled) by fccgen.rank's rule, a
    component at a time (module docstring); dense_max: the most columns of a component
    that takes the dense SVD; rank_only: the certified components' gaps are bounds
    (:func:`certified`), for callers that read only the rank."""
    B = sp.csr_matrix(B, dtype=float)
    if not np.all(np.isfinite(B.data)):
        return RankDecision(-1, n_q, ())
    norms = np.sqrt(np.asarray(B.multiply(B).sum(axis=1)).ravel())
    C = (sp.diags(1.0 / scales_from_norms(norms, groups)) @ B).tocsr()
    parts = components(C)
    small = [(rows, cols) for rows, cols in parts if len(cols) <= dense_max]
    dense = list(zip([cols for _, cols in small], component_singular_values(C, small)))
    large = [(rows, cols) for rows, cols in parts if len(cols) > dense_max]
    grams = [gram(C[rows][:, cols]) for rows, cols in large]
    bounds = [bracket(g, rank_only) for g in grams]
    top = [s[0] for _, s in dense if s.size]
    s1 = max(top + [lo for lo, _ in bounds] + [0.0])      # sigma_1, from below
    s_hi = max(top + [hi for _, hi in bounds] + [0.0])    # ... and a bound above
    sigma = [float(x) for _, values in dense for x in values]
    if s1 <= 0.0 or not large:
        return dense_decision(np.sort(np.asarray(sigma))[::-1], n_q)
    rank = sum(int(np.sum(s > DECIDE_TOL * s1)) for _, s in dense)
    kept = [min(s[s > DECIDE_TOL * s1], default=s1) for _, s in dense if s.size]
    dropped = [max(s[s <= DECIDE_TOL * s1], default=0.0) for _, s in dense if s.size]
    if any(AMBIGUOUS_LOW * s1 <= x <= GROW_TOL * s_hi for x in sigma):
        return _all_dense(C, n_q, parts)
    for (rows, cols), g in zip(large, grams):
        found = certified(C[rows][:, cols], g, s1, s_hi, rank_only)
        if found is None:
            return _all_dense(C, n_q, parts)
        d, sigma_r, bound = found
        rank += len(cols) - d
        kept.append(sigma_r)
        dropped.append(bound)
        sigma += [sigma_r, bound] if d else [sigma_r]
    sigma = tuple(float(s) for s in sorted(sigma + [s1], reverse=True))
    return PartialRankDecision(rank, n_q, sigma, kept=float(min(kept) / s1),
                               dropped=float(max(dropped) / s1), how="certified")


def _all_dense(C, n_q: int, parts) -> RankDecision:
    """The dense rule on the scaled B, every component by its SVD (what a component
    that cannot be certified gets; the rule needs all singular values then, for the
    uncertain band)."""
    values = np.concatenate([np.zeros(0)] + component_singular_values(C, parts))
    return replace(dense_decision(np.sort(values)[::-1], n_q),
                   how="svd (the sparse test could not certify the gap)")


def component_singular_values(C, parts) -> list[np.ndarray]:
    """The singular values of each block C[rows][:, cols] of ``parts`` (the dense SVD of
    each, largest first). The blocks are filled from C's entries in one pass, and the
    blocks of one shape go through one batched LAPACK call (the same values as one
    call each): a chain's hundreds of one-coordinate components cost microseconds,
    not a SciPy slice and an SVD call each."""
    out: list = [np.zeros(0)] * len(parts)
    if not parts:
        return out
    coo = C.tocoo()
    coo.sum_duplicates()
    nonzero = coo.data != 0.0                  # stored zeros are no entries (components)
    e_row, e_col, e_val = coo.row[nonzero], coo.col[nonzero], coo.data[nonzero]
    n_r, n_c = C.shape
    part_of_col = np.full(n_c, -1)
    local_row, local_col = np.zeros(n_r, dtype=np.intp), np.zeros(n_c, dtype=np.intp)
    shape_of = {}
    group = np.zeros(len(parts), dtype=np.intp)          # the shape class of each part
    slot = np.zeros(len(parts), dtype=np.intp)           # its place in that class
    members: list[list[int]] = []
    for k, (rows, cols) in enumerate(parts):
        part_of_col[cols] = k
        local_row[rows] = np.arange(len(rows))
        local_col[cols] = np.arange(len(cols))
        shape = (len(rows), len(cols))
        if shape not in shape_of:
            shape_of[shape] = len(members)
            members.append([])
        group[k] = shape_of[shape]
        slot[k] = len(members[group[k]])
        members[group[k]].append(k)
    owner = part_of_col[e_col]
    inside = owner >= 0                        # entries of the parts asked for
    e_row, e_col, e_val, owner = e_row[inside], e_col[inside], e_val[inside], owner[inside]
    order = np.argsort(group[owner], kind="stable")
    bounds = np.searchsorted(group[owner][order], np.arange(len(members) + 1))
    for (shape, g), (lo, hi) in zip(shape_of.items(), zip(bounds[:-1], bounds[1:])):
        if not shape[0] or not shape[1]:
            continue
        e = order[lo:hi]
        stack = np.zeros((len(members[g]),) + shape)
        stack[slot[owner[e]], local_row[e_row[e]], local_col[e_col[e]]] = e_val[e]
        values = np.linalg.svd(stack, compute_uv=False)
        for j, k in enumerate(members[g]):
            out[k] = values[j]
    return out


def components(C) -> list[tuple[np.ndarray, np.ndarray]]:
    """(rows, columns) of each connected component of the coordinate graph of C (a
    coordinate without rows is a component with no rows and contributes no sigma).
    Stored zeros (planar elements write them) are no edges: they are dropped first, so
    that a row's first stored entry names its component."""
    C = C.tocsr(copy=True)
    C.eliminate_zeros()
    n = C.shape[1]
    pattern = abs(C).astype(bool).astype(float)
    if not n:
        return []
    count, label = connected_components(pattern.T @ pattern, directed=False)
    has = np.diff(C.indptr) > 0                        # rows with an entry
    first = C.indices[np.minimum(C.indptr[:-1], max(C.nnz - 1, 0))] if C.nnz else 0
    row_label = np.where(has, label[first] if C.nnz else -1, -1)
    # each component's rows and columns in ascending order, by one stable sort of the
    # labels (0 .. count - 1, each used) in place of a scan per component
    cols = _split_by_label(np.arange(n), label, count)
    rows = _split_by_label(np.flatnonzero(row_label >= 0), row_label[row_label >= 0],
                           count)
    return list(zip(rows, cols))


def _split_by_label(index: np.ndarray, label: np.ndarray, count: int) -> list:
    """index split by its labels 0 .. count - 1: the entries of each label, in the
    order of index."""
    order = np.argsort(label, kind="stable")
    ends = np.cumsum(np.bincount(label, minlength=count))[:-1]
    return np.split(index[order].astype(np.intp), ends)


def gram(C):
    """G = C^T C in compressed columns."""
    return (C.T @ C).tocsc()


def largest(G) -> float:
    """sigma_1 = sqrt(the largest eigenvalue of G) (Lanczos, a fixed start vector)."""
    if G.shape[0] <= 2:
        return float(np.sqrt(np.linalg.eigvalsh(G.toarray())[-1]))
    try:
        value = eigsh(G, k=1, which="LA", v0=np.ones(G.shape[0]), tol=1e-10,
                      return_eigenvectors=False)        # sigma_1 to ~1e-10 relative
    except ArpackError:      # the ones vector in G's null space: a fixed random start
        value = eigsh(G, k=1, which="LA", tol=1e-10, return_eigenvectors=False,
                      v0=np.random.default_rng(0).standard_normal(G.shape[0]))
    return float(np.sqrt(value[0]))


def inertia_below(G, tau: float) -> int | None:
    """The number of eigenvalues of G below tau (negative pivots of G - tau I with
    symmetric pivoting), None if the factorisation pivoted off the diagonal."""
    lu = splu((G - tau * sp.identity(G.shape[0], format="csc")).tocsc(),
              permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
              options=dict(SymmetricMode=True))
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    return int(np.sum(lu.U.diagonal() < 0.0))


def bracket(G, rough: bool = False) -> tuple[float, float]:
    """(low, high) with low <= sigma_1 <= high, sigma_1^2 the largest eigenvalue of G:
    low from Lanczos (:func:`largest`: a Ritz value never exceeds the largest
    eigenvalue), high from Gershgorin (the largest absolute row sum of G). rough: low
    is the Rayleigh quotient after ROUGH_STEPS power steps from a fixed start (never
    above sigma_1^2 either; on A02's chain at 483 coordinates 0.4 % below, in 0.2 ms
    where Lanczos takes 7-10 ms), for decisions that read only the rank."""
    if G.shape[0] <= 2:
        value = largest(G)
        return value, value
    high = float(np.sqrt(abs(G).sum(axis=1).max()))
    if rough:
        x = np.random.default_rng(0).standard_normal(G.shape[0])
        for _ in range(ROUGH_STEPS):
            x = G @ x
            x /= np.linalg.norm(x)
        low = float(np.sqrt(max(x @ (G @ x), 0.0)))
    else:
        low = largest(G)
    return low, max(high, low)


def certified(C, G, s1: float, s_hi: float | None = None, rank_only: bool = False):
    """(d, sigma_r, ||C X||_2) for a component agreeing on all three signals of the
    module docstring, else None. s1: sigma_1 or a lower bound of it, s_hi an upper
    bound (default s1): each test takes the side of the bracket that makes it
    stricter. rank_only: the null vectors X by block inverse iteration
    (:func:`smallest_right_vectors`) in place of Lanczos, and sigma_r returned as its
    lower bound GROW_TOL s_hi (what the inertia proves): the same rank, the same
    unsquared check, without the kept gap's value."""
    s_hi = s1 if s_hi is None else s_hi
    d_low = inertia_below(G, (ZERO_TOL * s1) ** 2)
    d_high = inertia_below(G, (GROW_TOL * s_hi) ** 2)
    n = G.shape[0]
    if d_low is None or d_low != d_high or d_low > MAX_NULLITY or d_low + 1 >= n:
        return None
    d = d_low
    if rank_only:
        X = _null_vectors(G, d, (ZERO_TOL * s1) ** 2) if d else None
        bound = float(np.linalg.norm(C @ X, 2)) if d else 0.0
        if bound > AMBIGUOUS_LOW * s1:
            return None
        return d, GROW_TOL * s_hi, bound
    shift = -(ZERO_TOL * s1) ** 2          # G - shift is positive definite
    values, X = eigsh(G, k=d + 1, sigma=shift, which="LM", v0=np.ones(n))
    order = np.argsort(values)
    values, X = values[order], X[:, order]
    if values[d] < (GROW_TOL * s_hi) ** 2 or (d and values[d - 1] > (ZERO_TOL * s1) ** 2):
        return None
    bound = float(np.linalg.norm(C @ X[:, :d], 2)) if d else 0.0
    if bound > AMBIGUOUS_LOW * s1:
        return None
    return d, float(np.sqrt(values[d])), bound


def _null_vectors(G, d: int, shift: float, iterations: int = 3) -> np.ndarray:
    """(n, d): orthonormal vectors of G's d smallest eigenvalues, by block inverse
    iteration on G + shift I from a fixed random block of d + 4 columns, then
    Rayleigh-Ritz (smallest_right_vectors' method, on a G at hand)."""
    n = G.shape[0]
    lu = splu((G + shift * sp.identity(n, format="csc")).tocsc())
    X = np.random.default_rng(0).standard_normal((n, min(n, d + 4)))
    for _ in range(iterations):
        X, _ = np.linalg.qr(lu.solve(X))
    _, Y = np.linalg.eigh(X.T @ (G @ X))
    return X @ Y[:, :d]


def scaled(B, groups=None):
    """B (dense or SciPy sparse) as CSR with its rows divided by row_scales."""
    B = sp.csr_matrix(B, dtype=float)
    norms = np.sqrt(np.asarray(B.multiply(B).sum(axis=1)).ravel())
    return (sp.diags(1.0 / scales_from_norms(norms, groups)) @ B).tocsr()


def smallest_right_vectors(C, k: int, iterations: int = 3) -> np.ndarray:
    """(n, k): an orthonormal basis of the right singular vectors of the sparse C that
    belong to its k smallest singular values (its null space when k is C's nullity).
    Block inverse iteration on G = C^T C: one sparse LU of G + s I (s = (ZERO_TOL
    sigma_1)^2, positive definite), X <- orth((G + s I)^-1 X) from a random block of
    k + 10 columns, then Rayleigh-Ritz. A null direction grows by 1 / s per step against
    (sigma_r^2 + s)^-1 for the smallest nonzero sigma_r, so three steps reach rounding
    whenever sigma_r > 1e-5 sigma_1 (the scaled Jacobians met so far: 1.4e-5 at 1002
    bars); a block method, unlike Lanczos, keeps a repeated zero's whole eigenspace.
    What the dense path takes from a full SVD, for models too large for one."""
    G = gram(C)
    n = G.shape[0]
    p = min(n, k + 10)
    if 2 * p >= n:                           # small: the dense SVD
        _, _, vt = np.linalg.svd(C.toarray())
        return vt[n - k:].T
    shift = (ZERO_TOL * largest(G)) ** 2
    lu = splu((G + shift * sp.identity(n, format="csc")).tocsc())
    X = np.random.default_rng(0).standard_normal((n, p))
    for _ in range(iterations):
        X, _ = np.linalg.qr(lu.solve(X))
    _, Y = np.linalg.eigh(X.T @ (G @ X))     # ascending
    return X @ Y[:, :k]
