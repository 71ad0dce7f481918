"""Parameter derivatives of an element class's kernels: d/dp_j of M, h, f, g, B and
the velocity-product term (the constraint bias), by SymPy from the same expressions
the kernels are printed from.

Layout: parameter-major, ``out[j * size + k] = d K_k / d p_j`` where ``K`` is the
kernel's row-major output (``KernelSpec.size(cls)`` numbers) and ``p_j`` is
``cls.param_names[j]``; the column of one parameter is contiguous. A kernel whose
derivative is identically zero for every parameter is None.
"""
from __future__ import annotations

import sympy

from .derived import DerivedClass

# The kernels of the equations of motion M q'' + B^T lambda = f - h, B q'' = -(bias),
# g(q) = 0 that depend on the parameters (in fcc_dp_class order, fccgen_dp.h).
PARAMETER_KERNELS = ("mass_matrix", "h_vector", "applied_forces", "constraints",
                     "constraint_jacobian", "constraint_bias")


def dp_name(kernel: str) -> str:
    """Name of the parameter derivative of ``kernel``: ``mass_matrix_dp``."""
    return f"{kernel}_dp"


def parameter_derivatives(derived: DerivedClass) -> dict[str, sympy.Matrix | None]:
    """``{dp_name(k): column Matrix or None}`` for every k of PARAMETER_KERNELS."""
    out: dict[str, sympy.Matrix | None] = {}
    p = sympy.Matrix(derived.p)
    for name in PARAMETER_KERNELS:
        kernel = derived.kernels[name]
        if kernel is None or not derived.p:
            out[dp_name(name)] = None
            continue
        jac = kernel.jacobian(p)                    # size x n_p
        entries = [jac[k, j] for j in range(jac.cols) for k in range(jac.rows)]
        out[dp_name(name)] = (None if all(e == 0 for e in entries)
                              else sympy.Matrix(entries))
    return out
