"""Kernel expressions of every element kind (docs/elements.md).

Each builder takes the class symbols and returns ``{kernel name: outputs}`` for the
kernels of its kind, outputs as flat row-major lists; :func:`fccgen.derive.derive_class`
turns them into the :class:`~fccgen.derive.derived.DerivedClass`. Constraint Jacobians
and biases are written in closed form (B = dg/dq, (dB/dt) q'); the tests check them
against finite differences.
"""
from __future__ import annotations

from typing import Callable

import sympy

from ..plan.classes import ALIGNED_ROWS, KIND_ENDS
from .kinematics import (E3, BodyFrame, PointKin, body_frame, cross, dot, end_point,
                         lin_combine, lin_row, skew)
from .symbols import ClassSymbols, Lin

Outputs = dict[str, list[sympy.Expr]]


def _flat(m: sympy.Matrix) -> list[sympy.Expr]:
    """Row-major entries of a matrix."""
    return list(m)


def _gram(a: sympy.Matrix, w: sympy.Matrix | None = None) -> sympy.Matrix:
    """a^T w a (w symmetric, default E), built on the upper triangle and mirrored so
    the result is exactly symmetric; zero products are left out."""
    k = a if w is None else w * a
    n = a.cols
    out = sympy.zeros(n, n)
    for i in range(n):
        for j in range(i, n):
            out[i, j] = out[j, i] = sympy.Add(*[a[r, i] * k[r, j] for r in range(a.rows)
                                                 if a[r, i] != 0 and k[r, j] != 0])
    return out


def _generalized(s: ClassSymbols, lin: Lin, x: sympy.Matrix) -> list[sympy.Expr]:
    """L^T x in local coordinates (n_q outputs)."""
    return _flat(s.local(lin_row(x, lin), 1))


def _jacobian_rows(s: ClassSymbols, rows: list[Lin]) -> list[sympy.Expr]:
    """Row-major n_g x n_q Jacobian from one per-triple map (1 x 3 blocks) per row."""
    return [e for row in rows for e in _flat(s.local(row, 1))]


def _points(s: ClassSymbols) -> list[PointKin]:
    return [end_point(s, end, kind) for end, kind in zip(KIND_ENDS[s.cls.kind], s.cls.ends)]


def _vec(s: ClassSymbols, *names: str) -> sympy.Matrix:
    return sympy.Matrix([s.scalar(n) for n in names])


# -- body -------------------------------------------------------------------------

def _inertia(s: ClassSymbols) -> sympy.Matrix:
    xx, yy, zz, xy, xz, yz = (s.scalar(n) for n in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"))
    return sympy.Matrix([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def _body_constraints(s: ClassSymbols, f: BodyFrame) -> Outputs:
    """Rows "length" r_ij.r_ij - l^2 and "angle" r_ij.u - l beta (as the class lists)."""
    rij, rd, u = f.rij, f.rij_dot, f.u
    rows = {"length": (dot(rij, rij) - f.l ** 2, f.rij_blocks(2 * rij.T), 2 * dot(rd, rd)),
            "angle": (dot(rij, u.pos) - f.l * f.beta,
                      {**f.rij_blocks(u.pos.T), **({u.name: rij.T} if u.moving else {})},
                      2 * dot(rd, u.vel))}
    chosen = [rows[name] for name in s.cls.constraint_rows]
    return {"constraints": [g for g, _, _ in chosen],
            "constraint_jacobian": _jacobian_rows(s, [b for _, b, _ in chosen]),
            "constraint_bias": [c for _, _, c in chosen]}


def body(s: ClassSymbols) -> Outputs:
    """Mass matrix, inertia terms, gravity, rigid-body constraints, energy and outputs;
    the mass centre is the body point (a1, a2, a3)."""
    f = body_frame(s)
    m, ib = s.scalar("m"), _inertia(s)
    g = _vec(s, "gx", "gy", "gz")
    cg = f.point(s.scalar("a1"), s.scalar("a2"), s.scalar("a3"))
    dhat, phi = s.local(cg.dhat, 3), s.local(f.phi_b, 3)
    mass = m * _gram(dhat) + _gram(phi, ib)
    i_w = ib * f.w_b
    rot = ib * f.c_w + cross(f.w_b, i_w)
    h = [m * x + y for x, y in zip(_generalized(s, cg.dhat, cg.bias),
                                   _generalized(s, f.phi_b, rot))]
    return {"mass_matrix": _flat(mass),
            "h_vector": h,
            "applied_forces": [m * e for e in _generalized(s, cg.dhat, g)],
            **_body_constraints(s, f),
            "energy": [m * dot(cg.vel, cg.vel) / 2 + dot(f.w_b, i_w) / 2,
                       -m * dot(g, cg.pos)],
            "body_outputs": _flat(cg.pos) + _flat(f.w)}


# -- constraints ------------------------------------------------------------------

def unit_vector(s: ClassSymbols) -> Outputs:
    """g = u.u - 1, B = 2 u^T, bias 2 u'.u'."""
    u = s.triple("u")
    return {"constraints": [dot(u.pos, u.pos) - 1],
            "constraint_jacobian": _jacobian_rows(s, [{u.name: 2 * u.pos.T}] if u.moving
                                                  else [{}]),
            "constraint_bias": [2 * dot(u.vel, u.vel)]}


def distance(s: ClassSymbols) -> Outputs:
    """g = d.d - L^2 (d = r_B - r_A), B = 2 d^T (Dhat_B - Dhat_A),
    bias 2 d'.d' + 2 d.(bias_B - bias_A)."""
    a, b = _points(s)
    d, dd = b.pos - a.pos, b.vel - a.vel
    delta = lin_combine((1, b.dhat), (-1, a.dhat))
    return {"constraints": [dot(d, d) - s.scalar("L") ** 2],
            "constraint_jacobian": _jacobian_rows(s, [lin_combine((2 * d.T, delta))]),
            "constraint_bias": [2 * dot(dd, dd) + 2 * dot(d, b.bias - a.bias)]}


def point_on_line(s: ClassSymbols) -> Outputs:
    """g = a x b, a = r_K - r_A, b = r_B - r_A; B = -~b Da + ~a Db;
    bias = a'' x b + 2 a' x b' + a x b'' at q'' = 0."""
    k, pa, pb = _points(s)
    a, b = k.pos - pa.pos, pb.pos - pa.pos
    ad, bd = k.vel - pa.vel, pb.vel - pa.vel
    da = lin_combine((1, k.dhat), (-1, pa.dhat))
    db = lin_combine((1, pb.dhat), (-1, pa.dhat))
    jac = s.local(lin_combine((-skew(b), da), (skew(a), db)), 3)
    bias = (cross(k.bias - pa.bias, b) + 2 * cross(ad, bd) + cross(a, pb.bias - pa.bias))
    return {"constraints": _flat(cross(a, b)),
            "constraint_jacobian": _flat(jac),
            "constraint_bias": _flat(bias)}


# -- loads ------------------------------------------------------------------------

def force(s: ClassSymbols, F: sympy.Matrix | None = None) -> Outputs:
    """f = Dhat^T F at the body point (b1, b2, b3); potential -F.r (a constant F;
    F given: a force of time, kind force_t, without potential)."""
    f = body_frame(s)
    pt = f.point(s.scalar("b1"), s.scalar("b2"), s.scalar("b3"))
    if F is not None:
        return {"applied_forces": _generalized(s, pt.dhat, F)}
    F = _vec(s, "Fx", "Fy", "Fz")
    return {"applied_forces": _generalized(s, pt.dhat, F),
            "energy": [sympy.S.Zero, -dot(F, pt.pos)]}


def torque(s: ClassSymbols, T: sympy.Matrix | None = None) -> Outputs:
    """f = Phi_b^T (R^T T); a constant torque has no potential (energy [0, 0]);
    T given: a torque of time (kind torque_t)."""
    f = body_frame(s)
    T = _vec(s, "Tx", "Ty", "Tz") if T is None else T
    t_body = sympy.Matrix([dot(f.e1, T), dot(f.e2, T), dot(f.e3, T)])
    return {"applied_forces": _generalized(s, f.phi_b, t_body),
            "energy": [sympy.S.Zero, sympy.S.Zero]}


def spring(s: ClassSymbols) -> Outputs:
    """f = -T (Dhat_B - Dhat_A)^T n with T = k (L - L0) + c L', n = d / L; the scalar
    -T / L multiplies (Dhat_B - Dhat_A)^T d once per output."""
    a, b = _points(s)
    k, l0, c = s.scalar("k"), s.scalar("L0"), s.scalar("c")
    d, dd = b.pos - a.pos, b.vel - a.vel
    length = sympy.sqrt(dot(d, d))
    tension = k * (length - l0) + c * dot(d, dd) / length
    delta = lin_combine((1, b.dhat), (-1, a.dhat))
    scale = -tension / length
    w = _generalized(s, delta, d)
    # product rule on f_i = scale w_i keeps scale, w_i and their derivatives as shared
    # subtrees (differentiating the expanded f is much slower and gives larger trees)
    d_scale_q = [sympy.diff(scale, x) for x in s.q]
    d_scale_v = [sympy.diff(scale, x) for x in s.v]
    return {"applied_forces": [scale * e for e in w],
            "energy": [sympy.S.Zero, k * (length - l0) ** 2 / 2],
            "force_jacobian_q": [scale * sympy.diff(wi, x) + wi * ds
                                 for wi in w for x, ds in zip(s.q, d_scale_q)],
            "force_jacobian_v": [wi * ds for wi in w for ds in d_scale_v]}


def reference_rotation(s: ClassSymbols, prefix: str) -> tuple[sympy.Expr, sympy.Expr]:
    """cos and sin of theta_init + th: the initial angle (prefix cos0, sin0) turned on
    by the runtime's angle reference (prefix th, cr, sr)."""
    c0, s0 = s.scalar(prefix + "cos0"), s.scalar(prefix + "sin0")
    cr, sr = s.scalar(prefix + "cr"), s.scalar(prefix + "sr")
    return c0 * cr - s0 * sr, s0 * cr + c0 * sr


def torsion_spring(s: ClassSymbols) -> Outputs:
    """Torsion spring-damper about the shared unit vector u of bodies A and B.

    p_A = r_ij,A - lA u and p_B = r_ij,B - lB u (lA = l_A beta_A: perpendicular to u on
    the constraint manifold); D = u.(p_A x p_B) and P = p_A.p_B, so that the angle from
    p_A to p_B is atan2(D, P). Turned back by the initial angle (cos0, sin0) and the
    reference th (cr, sr; the runtime keeps th at the joint angle of the last accepted
    state, fccgen.events.references): with c = cos0 cr - sin0 sr, s = sin0 cr + cos0 sr,
    S = c D - s P, C = c P + s D and phi = th - free + atan2(S, C), the deflection
    from the free angle counted over turns (atan2 stays near 0 within a step).
    V = k phi^2 / 2 and f = -(k phi + c phi') g, with N = S^2 + C^2 and

        g = dphi/dq = (C/N) dS - (S/N) dC,    phi' = (C S' - S C')/N,
        H = d2phi/dq2 = (C/N) d2S - (S/N) d2C + b1 (dS dC^T + dC dS^T)
                        - b2 (dS dS^T - dC dC^T),  b1 = (S^2 - C^2)/N^2, b2 = 2 S C/N^2,
        df/dq = -g (k g + c H q')^T - (k phi + c phi') H,   df/dq' = -c g g^T,

    where H q' takes dS' = d2S q' in place of d2S (and likewise for C). S' and C' are
    written by the product rule on the vectors, which keeps every output a few
    scalars of S, C and small polynomials."""
    ai, aj, bi, bj, u = (s.triple(n) for n in ("A.ri", "A.rj", "B.ri", "B.rj", "u"))
    k, c, n = s.scalar("k"), s.scalar("c"), len(s.q)
    cos0, sin0 = reference_rotation(s, "")
    pa = aj.pos - ai.pos - s.scalar("lA") * u.pos
    pb = bj.pos - bi.pos - s.scalar("lB") * u.pos
    pa_dot = aj.vel - ai.vel - s.scalar("lA") * u.vel
    pb_dot = bj.vel - bi.vel - s.scalar("lB") * u.vel
    big_d, big_p = dot(u.pos, cross(pa, pb)), dot(pa, pb)
    d_dot = (dot(u.vel, cross(pa, pb)) + dot(u.pos, cross(pa_dot, pb))
             + dot(u.pos, cross(pa, pb_dot)))
    p_dot = dot(pa_dot, pb) + dot(pa, pb_dot)
    big_s, big_c = cos0 * big_d - sin0 * big_p, cos0 * big_p + sin0 * big_d
    s_dot, c_dot = cos0 * d_dot - sin0 * p_dot, cos0 * p_dot + sin0 * d_dot
    d_s = [sympy.diff(big_s, x) for x in s.q]
    d_c = [sympy.diff(big_c, x) for x in s.q]
    h_s = [[sympy.diff(d_s[i], s.q[j]) for j in range(n)] for i in range(n)]
    h_c = [[sympy.diff(d_c[i], s.q[j]) for j in range(n)] for i in range(n)]
    d_s_dot = [sympy.diff(s_dot, x) for x in s.q]       # = d2S q'
    d_c_dot = [sympy.diff(c_dot, x) for x in s.q]
    norm = big_s ** 2 + big_c ** 2
    w_s, w_c = big_c / norm, -big_s / norm
    b1, b2 = (big_s ** 2 - big_c ** 2) / norm ** 2, 2 * big_s * big_c / norm ** 2
    phi = s.scalar("th") - s.scalar("free") + sympy.atan2(big_s, big_c)
    g = [w_s * x + w_c * y for x, y in zip(d_s, d_c)]
    torque = k * phi + c * (w_s * s_dot + w_c * c_dot)

    def hess(i, j):
        return (w_s * h_s[i][j] + w_c * h_c[i][j] + b1 * (d_s[i] * d_c[j] + d_c[i] * d_s[j])
                - b2 * (d_s[i] * d_s[j] - d_c[i] * d_c[j]))

    h_v = [w_s * d_s_dot[j] + w_c * d_c_dot[j] + b1 * (d_s[j] * c_dot + d_c[j] * s_dot)
           - b2 * (d_s[j] * s_dot - d_c[j] * c_dot) for j in range(n)]
    return {"applied_forces": [-torque * gi for gi in g],
            "energy": [sympy.S.Zero, k * phi ** 2 / 2],
            "force_jacobian_q": [-g[i] * (k * g[j] + c * h_v[j]) - torque * hess(i, j)
                                 for i in range(n) for j in range(n)],
            "force_jacobian_v": [-c * gi * gj for gi in g for gj in g]}


# -- force Jacobians ------------------------------------------------------------------

def _jacobian(exprs: list[sympy.Expr], wrt: tuple[sympy.Symbol, ...]) -> list[sympy.Expr]:
    """Row-major d(exprs)/d(wrt), square when len(exprs) == len(wrt)."""
    return [sympy.diff(e, x) for e in exprs for x in wrt]


def with_force_jacobians(builder: Callable[[ClassSymbols], Outputs]
                         ) -> Callable[[ClassSymbols], Outputs]:
    """The builder plus ``force_jacobian_q`` = df/dq and ``force_jacobian_v`` = df/dq'
    of its applied forces f, by differentiating the expressions of f (the checks
    compare them with finite differences and with the NumPy version)."""
    def build(s: ClassSymbols) -> Outputs:
        out = builder(s)
        f = out.get("applied_forces")
        if f is not None and s.q and "force_jacobian_q" not in out:
            out["force_jacobian_q"] = _jacobian(f, s.q)
            out["force_jacobian_v"] = _jacobian(f, s.v)
        return out
    build.__doc__ = builder.__doc__
    return build


# -- mechanism level: attached triples, point on a plane, dot product ---------------

def _attached(s: ClassSymbols, target: str, offset_ri: bool) -> Outputs:
    """g = r_k - P (a point) or w - (P - r_i) (a vector), P the body point
    r_i + b1 r_ij + b2 u + c (r_ij x u), c = b3/(alpha l): B = [E on the target,
    -Dhat_P (minus E on r_i for a vector)], bias -2c r_ij' x u'."""
    f = body_frame(s)
    pt = f.point(s.scalar("b1"), s.scalar("b2"), s.scalar("b3"))
    k = s.triple(target)
    dhat = dict(pt.dhat)
    pos = pt.pos
    if not offset_ri:                      # a direction: P - r_i, no r_i term
        pos = pt.pos - f.ri.pos
        if f.ri.moving:
            dhat[f.ri.name] = dhat[f.ri.name] - E3
    jac = lin_combine((-1, dhat), (1, {k.name: E3} if k.moving else {}))
    return {"constraints": _flat(k.pos - pos),
            "constraint_jacobian": _flat(s.local(jac, 3)),
            "constraint_bias": _flat(-pt.bias)}


def attached_point(s: ClassSymbols) -> Outputs:
    """r_k - [r_i + b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l)] = 0 (three rows)."""
    return _attached(s, "k", True)


def attached_vector(s: ClassSymbols) -> Outputs:
    """w - (nu1 e1 + nu2 e2 + nu3 e3) = w - [b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l)]
    = 0 with b = point_coefficients(nu) (three rows; |w| = 1 follows)."""
    return _attached(s, "w", False)


def point_on_plane(s: ClassSymbols) -> Outputs:
    """g = n.(r_K - r_A); B = (r_K - r_A)^T on n, n^T (Dhat_K - Dhat_A) on the ends;
    bias 2 n'.(r_K' - r_A') + n.(bias_K - bias_A)."""
    n = s.triple("n")
    k, a = _points(s)
    d, dd = k.pos - a.pos, k.vel - a.vel
    row = lin_combine((n.pos.T, k.dhat), (-n.pos.T, a.dhat),
                      (1, {n.name: d.T} if n.moving else {}))
    return {"constraints": [dot(n.pos, d)],
            "constraint_jacobian": _jacobian_rows(s, [row]),
            "constraint_bias": [2 * dot(n.vel, dd) + dot(n.pos, k.bias - a.bias)]}


def dot_product(s: ClassSymbols) -> Outputs:
    """g = a.b - c (c = cos of the angle between unit vectors a, b); B = [b^T, a^T];
    bias 2 a'.b'."""
    a, b = s.triple("a"), s.triple("b")
    row = lin_combine((1, {a.name: b.pos.T} if a.moving else {}),
                      (1, {b.name: a.pos.T} if b.moving else {}))
    return {"constraints": [dot(a.pos, b.pos) - s.scalar("c")],
            "constraint_jacobian": _jacobian_rows(s, [row]),
            "constraint_bias": [2 * dot(a.vel, b.vel)]}


def aligned_vector(s: ClassSymbols) -> Outputs:
    """Rows of cls.constraint_rows among "e1" w.r_ij - c1, "e2" w.u - c2 and
    "e3" w.(r_ij x u) - c3: a unit vector held by two body-frame components.
    B: e1 [-w^T on ri, w^T on rj, r_ij^T on w]; e2 [w^T on u, u^T on w];
    e3 [(u x w)^T on r_ij, (w x r_ij)^T on u, (r_ij x u)^T on w].
    Bias: 2 w'.r_ij', 2 w'.u', 2 [w'.(r_ij' x u) + w'.(r_ij x u') + w.(r_ij' x u')]."""
    ri, rj, u, w = (s.triple(t) for t in ("ri", "rj", "u", "w"))
    rij, rd = rj.pos - ri.pos, rj.vel - ri.vel

    def on(triple, block):
        return {triple.name: block} if triple.moving else {}

    def on_rij(block):
        return lin_combine((-1, on(ri, block)), (1, on(rj, block)))

    rows = {
        "e1": (dot(w.pos, rij) - s.scalar("c1") if "c1" in s.cls.scalar_names else None,
               lin_combine((1, on_rij(w.pos.T)), (1, on(w, rij.T))),
               2 * dot(w.vel, rd)),
        "e2": (dot(w.pos, u.pos) - s.scalar("c2") if "c2" in s.cls.scalar_names else None,
               lin_combine((1, on(u, w.pos.T)), (1, on(w, u.pos.T))),
               2 * dot(w.vel, u.vel)),
        "e3": (dot(w.pos, cross(rij, u.pos)) - s.scalar("c3")
               if "c3" in s.cls.scalar_names else None,
               lin_combine((1, on_rij(cross(u.pos, w.pos).T)), (1, on(u, cross(w.pos, rij).T)),
                           (1, on(w, cross(rij, u.pos).T))),
               2 * (dot(w.vel, cross(rd, u.pos)) + dot(w.vel, cross(rij, u.vel))
                    + dot(w.pos, cross(rd, u.vel)))),
    }
    chosen = [rows[r] for r in s.cls.constraint_rows]
    return {"constraints": [g for g, _, _ in chosen],
            "constraint_jacobian": _jacobian_rows(s, [b for _, b, _ in chosen]),
            "constraint_bias": [c for _, _, c in chosen]}


MECHANISM_BUILDERS: dict[str, Callable[[ClassSymbols], Outputs]] = {
    "attached_point": attached_point, "attached_vector": attached_vector,
    "point_on_plane": point_on_plane, "dot": dot_product,
    **{kind: aligned_vector for kind in ALIGNED_ROWS},
}


BUILDERS: dict[str, Callable[[ClassSymbols], Outputs]] = {
    "body": with_force_jacobians(body), "unit_vector": unit_vector, "distance": distance,
    "point_on_line": point_on_line, "force": with_force_jacobians(force),
    "torque": with_force_jacobians(torque), "spring": with_force_jacobians(spring),
    "torsion_spring": torsion_spring,
}
BUILDERS.update(MECHANISM_BUILDERS)

