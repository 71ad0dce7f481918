"""Tangent-space pieces shared by statics, linearization and modes.

Every constraint equation g_k(q) of the FCC form is linear or quadratic in q, so the
Jacobian B(q) = dg/dq is affine in q and, for fixed multipliers lambda,

    d(B(q)^T lambda)/dq = sum_k lambda_k Hess(g_k)           (a constant matrix)

A central difference ``(B(q + h e_j) - B(q - h e_j))^T lambda / (2 h)`` of an affine
function is exact for every step h: its truncation error (h^2/6 times the third
derivative) is identically zero, and only rounding remains (about eps |B| / h, so a
step of the size of the coordinates is best). The same holds for anything quadratic in
the differenced argument, such as h(q, v) and (dB/dt) v in v.
"""
from __future__ import annotations

import numpy as np

from .. import rank as rank_rule


def bases(solver, q) -> tuple[np.ndarray, np.ndarray, int]:
    """(N, Y, rank): orthonormal bases of the null space (n_q x dof) and of the row
    space (n_q x rank) of B(q). The rank is the solver's own decision (fccgen.rank:
    the SVD gap test on row-scaled B); scaling rows changes neither space."""
    B = np.asarray(solver.constraint_jacobian(q), float)
    n = solver.n_q
    if B.size == 0:
        return np.eye(n), np.zeros((n, 0)), 0
    decision = rank_rule.decide(B, n, solver.row_groups)
    scaled = B / rank_rule.row_scales(B, solver.row_groups)[:, None]
    _, _, vt = np.linalg.svd(scaled)
    r = max(decision.rank, 0)
    return vt[r:].T.copy(), vt[:r].T.copy(), r


def step_size(x: np.ndarray, scale: float) -> float:
    """Difference step for an exact (affine or quadratic) central difference: any step
    works, one of the size of the coordinates keeps rounding smallest."""
    return max(float(np.max(np.abs(x))) if x.size else 0.0, scale) * 1e-2


def cube_root_step(x: np.ndarray, scale: float) -> float:
    """Central-difference step of the cube-root rule, eps^(1/3) times the size of x:
    truncation (h^2) and rounding (eps / h) errors balance near 1e-11 relative."""
    return np.finfo(float).eps ** (1.0 / 3.0) * max(
        float(np.max(np.abs(x))) if x.size else 0.0, scale)


def central_jacobian(fun, x, h: float) -> np.ndarray:
    """d fun / d x by central differences with step h (columns per component of x)."""
    x = np.asarray(x, float)
    cols = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h
        cols.append((np.asarray(fun(x + e), float) - np.asarray(fun(x - e), float))
                    / (2.0 * h))
    f0 = np.asarray(fun(x), float)
    return np.array(cols).T.reshape(f0.size, x.size) if cols else np.zeros((f0.size, 0))


def curvature(solver, q, lam, h: float | None = None) -> np.ndarray:
    """sum_k lambda_k Hess(g_k) = d(B(q)^T lambda)/dq, exact for any step h (see the
    module docstring)."""
    lam = np.asarray(lam, float)
    if lam.size == 0:
        return np.zeros((solver.n_q, solver.n_q))
    h = step_size(q, solver.length_scale) if h is None else h
    H = central_jacobian(lambda x: solver.constraint_jacobian(x).T @ lam, q, h)
    return 0.5 * (H + H.T)      # symmetric in exact arithmetic; drop the rounding


def min_norm_multipliers(B: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The minimum-norm least-squares lambda of B^T lambda = rhs (unique reactions
    when the rows of B are independent; the minimum-norm set when they are not)."""
    if B.size == 0:
        return np.zeros(B.shape[0])
    return np.linalg.lstsq(B.T, rhs, rcond=1e-10)[0]


def amax(x) -> float:
    x = np.asarray(x, float)
    return float(np.max(np.abs(x))) if x.size else 0.0
