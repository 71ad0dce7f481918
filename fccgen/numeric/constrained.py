"""The constrained linear solve of the equations of motion and of the projections.

    minimise  x^T M x / 2 - Q^T x   subject to   B x = b

M alone is singular (rank 6 of 9 per body) and B may be rank-deficient (redundant
constraints: planar mechanisms made of 3-D hinges, the three rows of point_on_line).
The solve splits x over the range and the null space of B^T with a rank-revealing QR
(column pivoting), takes the particular solution on the range and minimises over the
null space, where M is positive definite whenever every body has mass and inertia.
Only QR, triangular solves and Cholesky are used, so a compiled runtime can do the same
with LAPACK (dgeqp3, dorgqr, dtrsv, dpotrf).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from .. import rank as rank_rule
from ..errors import SimulationError

# A Cholesky pivot d_k^2 below this fraction of the largest diagonal entry of the
# reduced mass matrix counts as zero: rounding leaves exactly singular matrices with
# pivots of a few ulps of their largest entry, which Cholesky alone would accept.
PIVOT_TOL = 64 * np.finfo(float).eps


def row_norms(B: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of B, with 1 for zero rows (which are not scaled)."""
    norms = np.sqrt(np.einsum("ij,ij->i", B, B))
    return np.where(norms > 0.0, norms, 1.0)


def row_scales(B: np.ndarray, groups=None) -> np.ndarray:
    """The divisors of B's rows in the solve (fccgen.rank.row_scales; runtime/_solve.pyx
    does the same); groups: the element of each row, None: each row alone."""
    return rank_rule.row_scales(B, groups)


@dataclass
class RankKeeper:
    """The decided rank of B and what the factorisations saw (fccgen.rank; the same
    rule and statistics as the compiled solve, runtime/_solve.pyx). rank < 0: count
    the QR pivots above rank_tol."""
    rank: int = -1
    grow_trigger: float = rank_rule.RANK_TOL
    t: float = 0.0                         # time of the state being solved (for the log)
    check_growth: bool = False             # the state is on the constraints (projected)
    groups: np.ndarray | None = None       # per constraint row: its element
    stats: dict = field(default_factory=dict)

    def decide(self, rank: int) -> None:
        self.rank = rank
        self.grow_trigger = rank_rule.RANK_TOL
        self.stats = dict(factorisations=0, drops=0, svd_checks=0, smallest_kept=1.0,
                          largest_dropped=0.0, increases=[])

    def choose(self, diag: np.ndarray, Bs: np.ndarray, rank_tol: float) -> int:
        """The rank of this factorisation from the QR pivots |R_kk| (diag)."""
        kmax = diag.size
        if kmax == 0 or diag[0] <= 0.0:
            return 0
        ratio = diag / diag[0]
        cap = kmax if self.rank < 0 else min(self.rank, kmax)
        r = 0
        while r < cap and ratio[r] > rank_tol:
            r += 1
        if self.rank < 0:
            return r
        st = self.stats
        st["factorisations"] += 1
        st["drops"] += r < cap
        if r > 0:
            st["smallest_kept"] = min(st["smallest_kept"], float(ratio[r - 1]))
        if cap >= kmax:
            return r
        st["largest_dropped"] = max(st["largest_dropped"], float(ratio[cap]))
        if ratio[cap] > self.grow_trigger and self.check_growth:
            st["svd_checks"] += 1
            sigma = np.linalg.svd(Bs, compute_uv=False)
            grown = int(np.sum(sigma > rank_rule.GROW_TOL * sigma[0]))
            if grown > self.rank:
                st["increases"].append((self.t, self.rank, grown))
                self.rank = grown
                while r < min(grown, kmax) and ratio[r] > rank_tol:
                    r += 1
            else:
                self.grow_trigger = 10.0 * float(ratio[cap])
        return r


def constrained_solve(M, B, Q, b, rank_tol: float = 1e-10,
                      keeper: RankKeeper | None = None) -> np.ndarray:
    """x with B x = b (least squares on the range of B) minimising x^T M x / 2 - Q^T x.

    1. rows of B and b scaled by 1/||row of B|| (zero rows left alone);
    2. QR with column pivoting of B_s^T = Q R P^T; rank r: the keeper's decided rank
       (fccgen.rank), or without one the number of |R_kk| above rank_tol |R_00|;
    3. Q1 = first r columns of Q (range of B^T), Q2 = the rest (null space of B);
    4. x_p = Q1 y with R11^T y = (P^T b_s)[:r];
    5. (Q2^T M Q2) z = Q2^T (Q - M x_p) by Cholesky, x = x_p + Q2 z.

    Raises SimulationError when Q2^T M Q2 is not positive definite.
    """
    M = np.asarray(M, float)
    B = np.asarray(B, float).reshape(-1, M.shape[0])
    Q = np.asarray(Q, float).reshape(-1)
    b = np.asarray(b, float).reshape(-1)
    n = M.shape[0]
    if B.shape[0]:
        norms = row_scales(B, keeper.groups if keeper is not None else None)
        Bs, bs = B / norms[:, None], b / norms
        Qf, R, piv = scipy.linalg.qr(Bs.T, pivoting=True)
        diag = np.abs(np.diag(R))
        r = (keeper or RankKeeper()).choose(diag, Bs, rank_tol)
        Q1, Q2 = Qf[:, :r], Qf[:, r:]
        y = scipy.linalg.solve_triangular(R[:r, :r], bs[piv][:r], trans="T", lower=False,
                                          check_finite=False)
        x_p = Q1 @ y
    else:
        Q2, x_p = np.eye(n), np.zeros(n)
    if Q2.shape[1] == 0:
        return x_p
    reduced = Q2.T @ M @ Q2
    z = _cholesky_solve(reduced, Q2.T @ (Q - M @ x_p))
    return x_p + Q2 @ z


def _cholesky_solve(A: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve A z = rhs for symmetric positive definite A, or raise SimulationError."""
    try:
        L = np.linalg.cholesky(A)
        ok = np.min(np.diag(L)) ** 2 > PIVOT_TOL * np.max(np.abs(np.diag(A)))
    except np.linalg.LinAlgError:
        ok = False
    if not ok:
        raise SimulationError(
            "the mass matrix is singular on the constraint manifold (a body or coordinate "
            "without mass or inertia, or too few constraints): Cholesky of the reduced "
            f"mass matrix failed (size {A.shape[0]})")
    w = scipy.linalg.solve_triangular(L, rhs, lower=True, check_finite=False)
    return scipy.linalg.solve_triangular(L, w, lower=True, trans="T", check_finite=False)


def scaled_residual(g: np.ndarray, B: np.ndarray) -> float:
    """max_k |g_k| / ||B_k||: the constraint residual in units of length (zero rows of
    B are not scaled)."""
    if g.size == 0:
        return 0.0
    return float(np.max(np.abs(g) / row_norms(B)))
