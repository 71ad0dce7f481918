"""Parameter derivatives of an element class's kernels: d/dp_j of M, h, f, g, B and
the velocity-product term (the constraint bias), by SymPy from the same expressions
the kernels are printed from.

Layout: parameter-major, ``out[j * size + k] = d K_k / d p_j`` where ``K`` is the
kernel's row-major output (``KernelSpec.size(cls)`` numbers) and ``p_j`` is
``cls.param_names[j]``; the column of one parameter is contiguous. A kernel whose
derivative is identically zero for every parameter is None.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from .derived import DerivedClass

# The kernels of the equations of motion M q'' + B^T lambda = f - h, B q'' = -(bias),
# g(q) = 0 that depend on the parameters (in fcc_dp_class order, fcc_dp.h).
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


@dataclass(frozen=True)
class TangentInputs:
    """The extra inputs of the tangent kernel: accelerations a and multipliers lam of
    the element (its coordinates, its constraint rows) and the direction (dq, dv, dp)."""
    a: tuple[sympy.Symbol, ...]
    lam: tuple[sympy.Symbol, ...]
    dq: tuple[sympy.Symbol, ...]
    dv: tuple[sympy.Symbol, ...]
    dp: tuple[sympy.Symbol, ...]


def _matrix(derived: DerivedClass, name: str, rows: int, cols: int) -> sympy.Matrix:
    k = derived.kernels[name]
    return sympy.zeros(rows, cols) if k is None else sympy.Matrix(rows, cols, list(k))


def tangent_jacobian(derived: DerivedClass) -> tuple[TangentInputs, sympy.Matrix]:
    """The directional derivatives the forward sensitivities need, as one matrix.

    With R1 = f - h - M a - B^T lam (n_q) and R2 = -bias - B a (n_g), the residuals of
    M a + B^T lam = f - h, B a = -bias, and Phi = B v + dg/dt (n_g) the velocity
    constraint, the tangent kernel's outputs for the direction (dq, dv, dp) are

        [ dR1[dq, dv, dp] (n_q);  dR2[dq, dv, dp] (n_g);
          (dg/dp) dp (n_g);       dPhi[dq, dp] (n_g) ]  =  J [dq; dv; dp]

    with J of n_q + 3 n_g rows and 2 n_q + n_p columns:

        J = [ dR/dq     dR/dv   dR/dp ]      R = [R1; R2]
            [ 0         0       dg/dp ]
            [ dPhi/dq   0       dPhi/dp ]

    The sensitivity s of a run then has M s_a + B^T s_lam = dR1, B s_a = dR2 (the
    accelerations' derivative) and the linearised projections B s_q = -(dg/dp) dp,
    B s_v = -dPhi[s_q, dp]. The outputs are linear in the direction, and J depends
    only on (q, v, p, a, lam): evaluated once, it serves every direction at one state.
    """
    cls = derived.cls
    n, ng, npar = cls.n_q, cls.n_g, cls.n_p
    sym = lambda stem, k: tuple(sympy.symbols(f"{stem}0:{k}", real=True)) if k else ()  # noqa: E731
    inp = TangentInputs(sym("a_", n), sym("lam_", ng), sym("dq_", n), sym("dv_", n),
                        sym("dp_", npar))
    a, lam = sympy.Matrix(n, 1, list(inp.a)), sympy.Matrix(ng, 1, list(inp.lam))
    M = _matrix(derived, "mass_matrix", n, n)
    h = _matrix(derived, "h_vector", n, 1)
    f = _matrix(derived, "applied_forces", n, 1)
    g = _matrix(derived, "constraints", ng, 1)
    B = _matrix(derived, "constraint_jacobian", ng, n)
    bias = _matrix(derived, "constraint_bias", ng, 1)
    rate = _matrix(derived, "constraint_rate", ng, 1)
    v = sympy.Matrix(n, 1, list(derived.v))
    R = (f - h - M * a - B.T * lam).col_join(-bias - B * a) if ng else f - h - M * a
    phi = B * v + rate
    q, vv, p = (sympy.Matrix(len(x), 1, list(x)) for x in (derived.q, derived.v, derived.p))

    def jac(expr: sympy.Matrix, x: sympy.Matrix) -> sympy.Matrix:
        return expr.jacobian(x) if x.rows else sympy.zeros(expr.rows, 0)

    J = jac(R, q).row_join(jac(R, vv)).row_join(jac(R, p))
    if ng:
        J = J.col_join(sympy.zeros(ng, 2 * n).row_join(jac(g, p)))
        J = J.col_join(jac(phi, q).row_join(sympy.zeros(ng, n)).row_join(jac(phi, p)))
    return inp, J
