"""Kernel expressions of flexible members (fccgen.plan.cable_kinds, docs/flexible.md),
registered in :data:`fccgen.derive.elements.BUILDERS` when the package is imported.

A cable element's coordinates e = (r1, d1, r2, d2) give r(x) = sum_j S_j(xi) e_j with
the cubic Hermite functions of xi = x / L:

    S1 = 1 - 3 xi^2 + 2 xi^3,   S2 = L (xi - 2 xi^2 + xi^3),
    S3 = 3 xi^2 - 2 xi^3,       S4 = L (xi^3 - xi^2).

Mass matrix M = rhoA int S^T S dx and the loads (rhoA g + q) int S dx are integrated
exactly here (SymPy integrates the polynomials in xi). The strain energy per length,

    u(a, b) = EA/2 (|a| - 1)^2 + EI/2 |a x b|^2 / |a|^6,     a = r', b = r''

(axial strain |r'| - 1 and the curvature |r' x r''| / |r'|^3 of the cable form without
torsion), and the dissipation per length of the damping c,

    D = c/2 (EA (a . a')^2 + EI |a' x b + a x b'|^2),

the rates of the Green strain (a.a - 1)/2 and of the vector a x b (|a| times the
curvature vector): at the stress-free state its damping matrix is exactly c times the
stiffness matrix (stiffness-proportional), and it vanishes for a rigid motion of the
member but for one of a bent member about an axis across its plane of bending
(docs/flexible.md),

are differentiated by SymPy in the six variables (a, b) (and their rates) once; the
element sums them at the Gauss points of :data:`GAUSS_POINTS`, where a and b are
linear in e: f = -L sum_g w_g G_g^T (du/dx + dD/dx'), df/dq = -L sum_g w_g G_g^T
(d2u/dx2 + d2D/dx dx') G_g, df/dq' = -L sum_g w_g G_g^T d2D/dx'2 G_g, with
G_g = d(a, b)/de at the point.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy

from ..plan.cable_kinds import CABLE_TRIPLES, GAUSS_POINTS
from .elements import BUILDERS, Outputs
from .kinematics import cross, dot
from .mechanism import _functions_of_time
from .symbols import ClassSymbols

XI = sympy.Symbol("xi", real=True)


def shape_functions(L) -> list[sympy.Expr]:
    """S1..S4 of xi (module docstring)."""
    return [1 - 3 * XI ** 2 + 2 * XI ** 3, L * (XI - 2 * XI ** 2 + XI ** 3),
            3 * XI ** 2 - 2 * XI ** 3, L * (XI ** 3 - XI ** 2)]


def gauss_rule(n: int) -> list[tuple[sympy.Float, sympy.Float]]:
    """(xi, weight) of the n-point Gauss-Legendre rule on [0, 1] (weights sum to 1)."""
    t, w = np.polynomial.legendre.leggauss(n)
    return [(sympy.Float(0.5 * (1.0 + x), 17), sympy.Float(0.5 * y, 17))
            for x, y in zip(t, w)]


@lru_cache(maxsize=None)
def _density(damped: bool):
    """(X, XD, (EA, EI, c), u, grad, hess, rate) of the energy and dissipation
    densities in the six variables X = (a, b) and their rates XD: u, grad = du/dX +
    dD/dXD (6), hess = d2u/dX2 + d(dD/dXD)/dX (6 x 6), rate = d2D/dXD2 (6 x 6, None
    undamped); the symbols EA, EI, c stand for the class's parameters."""
    X = sympy.symbols("a0:3 b0:3", real=True)
    XD = sympy.symbols("ad0:3 bd0:3", real=True)
    EA, EI, c = sympy.symbols("EA EI c", real=True)
    a, b = sympy.Matrix(X[:3]), sympy.Matrix(X[3:])
    s2 = dot(a, a)
    eps = sympy.sqrt(s2) - 1
    ab = cross(a, b)
    u = EA / 2 * eps ** 2 + EI / 2 * dot(ab, ab) / s2 ** 3
    grad = [sympy.diff(u, x) for x in X]
    hess = [[None] * 6 for _ in range(6)]
    for i in range(6):
        for j in range(i, 6):
            hess[i][j] = hess[j][i] = sympy.diff(grad[i], X[j])
    rate = None
    if damped:
        # rates of the Green strain (a.a - 1)/2 and of the curvature vector a x b
        ad, bd = sympy.Matrix(XD[:3]), sympy.Matrix(XD[3:])
        c_dot = cross(ad, b) + cross(a, bd)
        D = c / 2 * (EA * dot(a, ad) ** 2 + EI * dot(c_dot, c_dot))
        g_d = [sympy.diff(D, xd) for xd in XD]
        grad = [x + y for x, y in zip(grad, g_d)]
        hess = [[hess[i][j] + sympy.diff(g_d[i], X[j]) for j in range(6)]
                for i in range(6)]
        rate = [[sympy.diff(g_d[i], XD[j]) for j in range(6)] for i in range(6)]
    return X, XD, (EA, EI, c), u, grad, hess, rate


def _mass_and_load(L):
    """(Mhat, s): int_0^1 S S^T dxi (4 x 4) and int_0^1 S dxi (4), exact."""
    S = shape_functions(L)
    m = [[sympy.integrate(S[i] * S[j], (XI, 0, 1)) for j in range(4)] for i in range(4)]
    return m, [sympy.integrate(x, (XI, 0, 1)) for x in S]


def cable(s: ClassSymbols) -> Outputs:
    """Mass matrix, elastic, damping, gravity and distributed-load forces, their
    Jacobians and the energy of one element (module docstring)."""
    L, rhoA = s.scalar("L"), s.scalar("rhoA")
    triples = [s.triple(n) for n in CABLE_TRIPLES]
    e = [x for t in triples for x in t.pos]                       # 12, fixed ones params
    ev = [x for t in triples for x in t.vel]
    moving = [3 * j + k for j, t in enumerate(triples) if t.moving for k in range(3)]
    load = [rhoA * s.scalar(f"g{c}") + s.scalar(f"q{c}") for c in "xyz"]
    m_hat, s_int = _mass_and_load(L)

    mass = [rhoA * L * (m_hat[i // 3][j // 3] if i % 3 == j % 3 else 0)
            for i in moving for j in moving]
    f_ext = [L * s_int[i // 3] * load[i % 3] for i in range(12)]
    kinetic = sum((mass[a * len(moving) + b] * ev[i] * ev[j] / 2
                   for a, i in enumerate(moving) for b, j in enumerate(moving)
                   if mass[a * len(moving) + b] != 0), sympy.S.Zero)
    potential = -sum((f_ext[i] * e[i] for i in range(12)), sympy.S.Zero)

    damped = s.scalar("c") != 0
    X, XD, (EA_s, EI_s, c_s), u_density, grad, hess, rate = _density(damped)
    params = {EA_s: s.scalar("EA"), EI_s: s.scalar("EI"), c_s: s.scalar("c")}
    S = shape_functions(L)
    dS = [sympy.diff(x, XI) / L for x in S]
    ddS = [sympy.diff(x, XI, 2) / L ** 2 for x in S]
    f = [sympy.S.Zero] * 12
    K = [[sympy.S.Zero] * 12 for _ in range(12)]
    C = [[sympy.S.Zero] * 12 for _ in range(12)]
    strain = sympy.S.Zero
    for xi, w in gauss_rule(GAUSS_POINTS):
        d1 = [x.subs(XI, xi) for x in dS]
        d2 = [x.subs(XI, xi) for x in ddS]
        # G: column i of d(a, b)/de is (d1[slot] at row comp, d2[slot] at row 3 + comp)
        values = {}
        for k in range(3):
            values[X[k]] = sum((d1[j] * e[3 * j + k] for j in range(4)), sympy.S.Zero)
            values[X[3 + k]] = sum((d2[j] * e[3 * j + k] for j in range(4)), sympy.S.Zero)
            values[XD[k]] = sum((d1[j] * ev[3 * j + k] for j in range(4)), sympy.S.Zero)
            values[XD[3 + k]] = sum((d2[j] * ev[3 * j + k] for j in range(4)), sympy.S.Zero)
        values.update(params)
        wl = w * L

        def at(expr):
            return expr.xreplace(values)

        gx = [at(x) for x in grad]
        hx = [[at(x) for x in row] for row in hess]
        rx = [[at(x) for x in row] for row in rate] if rate is not None else None
        strain += wl * at(u_density)

        def G(i):
            """(row of a, coefficient), (row of b, coefficient) of column i."""
            slot, comp = divmod(i, 3)
            return ((comp, d1[slot]), (3 + comp, d2[slot]))

        for i in moving:
            f[i] -= wl * sum((cf * gx[r] for r, cf in G(i)), sympy.S.Zero)
            for j in moving:
                pairs = [(r, cr, q, cq) for r, cr in G(i) for q, cq in G(j)]
                K[i][j] -= wl * sum((cr * cq * hx[r][q] for r, cr, q, cq in pairs),
                                    sympy.S.Zero)
                if rx is not None:
                    C[i][j] -= wl * sum((cr * cq * rx[r][q] for r, cr, q, cq in pairs),
                                        sympy.S.Zero)
    out = {"mass_matrix": mass,
           "applied_forces": [f[i] + f_ext[i] for i in moving],
           "energy": [kinetic, strain + potential],
           "force_jacobian_q": [K[i][j] for i in moving for j in moving]}
    if damped:
        out["force_jacobian_v"] = [C[i][j] for i in moving for j in moving]
    return out


def slope_normal(s: ClassSymbols) -> Outputs:
    """g = d . n (a clamp row): B = [n^T on d, d^T on n], bias 2 d' . n'."""
    d, n = s.triple("d"), s.triple("n")
    row = [sympy.S.Zero] * s.cls.n_q
    for t, other in ((d, n), (n, d)):
        if t.moving:
            k = s.offsets[t.name]
            for c in range(3):
                row[k + c] = other.pos[c]
    return {"constraints": [dot(d.pos, n.pos)],
            "constraint_jacobian": row,
            "constraint_bias": [2 * dot(d.vel, n.vel)]}


def point_force(s: ClassSymbols) -> Outputs:
    """f = F on the point r; potential -F . r."""
    F = sympy.Matrix([s.scalar(n) for n in ("Fx", "Fy", "Fz")])
    return {"applied_forces": list(F), "energy": [sympy.S.Zero, -dot(F, s.triple("r").pos)]}


def point_force_t(s: ClassSymbols) -> Outputs:
    """f = F(t) on the point r (no potential)."""
    return {"applied_forces": list(_functions_of_time(s))}


BUILDERS.update({"cable": cable, "slope_normal": slope_normal,
                 "point_force": point_force, "point_force_t": point_force_t})
