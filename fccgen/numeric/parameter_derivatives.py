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
