"""The NumPy version of the parameter derivatives of the element kernels: five-point
differences of the hand-written NumPy kernels (fccgen.numeric.elements) in each
parameter, written independently of the symbolic path (fccgen.derive.parameters).

Same layout as the compiled ones: an (n_p, size) array, a row per parameter. The
stencil is exact for parameters that enter a kernel as polynomials of degree <= 4
(masses, inertias, stiffnesses, dampings, gravity and most geometry); for the others
(a length or sin(gamma) in a denominator) its error is h^4 |K^(5)| / 30. With the
default step h = 2e-4 max(1, |p_j|) rounding (eps |K| / h, ~1e-12 relative) dominates.
"""
from __future__ import annotations

import numpy as np

from .elements import element_kernel


def kernel_dp(cls, name: str, q, v, p, rel_step: float = 2e-4) -> np.ndarray:
    """d/dp_j of kernel ``name`` of class ``cls`` at (q, v, p), one row per p_j."""
    p = np.asarray(p, dtype=float)

    def at(x):
        out = element_kernel(cls, name, q, v, x)
        return None if out is None else np.asarray(out, dtype=float)

    base = at(p)
    if base is None:
        return np.zeros((p.size, 0))
    rows = []
    for j in range(p.size):
        h = rel_step * max(1.0, abs(p[j]))
        e = np.zeros(p.size)
        e[j] = h
        rows.append((-at(p + 2 * e) + 8 * at(p + e) - 8 * at(p - e) + at(p - 2 * e))
                    / (12 * h))
    return np.array(rows).reshape(p.size, base.size)


def _residuals(cls, q, v, p, a, lam) -> np.ndarray:
    """[f - h - M a - B^T lam; -bias - B a; g; B v + dg/dt] of the NumPy kernels."""
    n, ng = cls.n_q, cls.n_g

    def get(name, shape):
        out = element_kernel(cls, name, q, v, p)
        return np.zeros(shape) if out is None else np.asarray(out, float).reshape(shape)

    M, h, f = get("mass_matrix", (n, n)), get("h_vector", n), get("applied_forces", n)
    g, B = get("constraints", ng), get("constraint_jacobian", (ng, n))
    bias, rate = get("constraint_bias", ng), get("constraint_rate", ng)
    return np.concatenate([f - h - M @ a - B.T @ lam, -bias - B @ a, g, B @ v + rate])


def tangent(cls, q, v, p, a, lam, dq, dv, dp, step: float = 2e-4) -> np.ndarray:
    """The tangent kernel (fccgen.derive.parameters.tangent_jacobian) of the NumPy
    kernels: five-point differences along the direction, the velocity constraint's
    and g's rows along (dq, dp) and dp alone as that kernel defines them."""
    q, v, p = (np.asarray(x, float) for x in (q, v, p))
    dq, dv, dp = (np.asarray(x, float) for x in (dq, dv, dp))
    n, ng = cls.n_q, cls.n_g

    def d(direction):
        eq, ev, ep = direction

        def at(s):
            return _residuals(cls, q + s * eq, v + s * ev, p + s * ep, a, lam)
        return (-at(2 * step) + 8 * at(step) - 8 * at(-step) + at(-2 * step)) / (12 * step)

    full = d((dq, dv, dp))
    out = full[:n + ng]
    if ng:
        zero_q, zero_v = np.zeros(n), np.zeros(n)
        out = np.concatenate([out, d((zero_q, zero_v, dp))[n + ng:n + 2 * ng],
                              d((dq, zero_v, dp))[n + 2 * ng:]])
    return out
