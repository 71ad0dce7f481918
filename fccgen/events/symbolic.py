"""Event functions and joint quantities as SymPy expressions of the model's global
coordinates q, speeds v, time t and the runtime parameters p.

Joint angles are written relative to a reference angle theta_r that the runtime keeps
at the angle of the last accepted state (turn counting), so that the angle stays
smooth through +-pi and is unwrapped over turns:

    angle = theta_r + atan2(a . (m x x), m . x),

with a = R_A a_A the joint axis, x = R_B w the rotated reference direction of body B
(w = C_0^T n1, C_0 = R_A0^T R_B0, n1 perpendicular to a_A) and m = R_A (cos theta_r n1
+ sin theta_r (a_A x n1)) the reference direction turned by theta_r. At theta_r = 0
this is fccgen.mechanism.outputs's angle. Parameters: p[3k:3k+3] = (theta_r, cos
theta_r, sin theta_r) of the k-th angle quantity. Slides: position = (r_b - r_a) . a
of the joint's carried points and axis. Rates and speeds are d/dt = grad_q . v.

Numbers of the initial configuration (body constants, fixed points and vectors, the
directions a_A, n1, w of each angle) are runtime parameters too, after the angle
references, in the order of fccgen.events.constants.layout: one module serves every
initial configuration of a model. So are the model's inputs that event functions
read (the last of them): the runtime writes each input's held value there.

Switchable rows (lock and unlock) are the joint quantities r(q) held at a value; their
Jacobian grad_q r and bias (d/dt grad_q r) . v = v^T (d^2 r / dq^2) v are kernels too.

After the events' quantities come the angles that only element kernels read (torsion
springs, loads of joint angles; fccgen.events.references): the runtime re-bases their
references like the others and copies them into those kernels' parameters. They are
never locked, so their gradient and bias rows are left zero.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..model.types import GROUND
from .constants import SIZES, layout
from .references import HINGE_TRIPLES, angle_sources, event_quantities


@dataclass
class Quantity:
    """A joint angle or slide that events use or lock: ``kind`` angle | position."""
    joint: str
    kind: str
    expr: sympy.Expr                 # of q (and p for angles)
    param: int | None                # angles: index k of (theta_r, cos, sin) in p
    parts: tuple | None = None       # angles: (y, x, (y', x'), (y'', x'')) of
                                     # expr = theta_r + atan2(y, x), along v
    lockable: bool = True            # False: only element kernels read its reference
                                     # (fccgen.events.references); no gradient, bias

    @property
    def name(self) -> str:
        return f"{self.joint}.{self.kind}"


@dataclass
class EventSystem:
    """Symbols and expressions of a model's event kernels."""
    q: list
    v: list
    t: sympy.Symbol
    p: list
    quantities: list[Quantity]
    functions: list[sympy.Expr]      # s_k(q, v, t, p), one per model event
    uses_v: list[bool]               # s_k reads speeds (rates, velocities)

    def gradient(self, e: sympy.Expr) -> list:
        """d e / dq, dense over q."""
        free = e.free_symbols
        return [sympy.diff(e, s) if s in free else sympy.S.Zero for s in self.q]

    def quantity_bias(self, qty: Quantity) -> sympy.Expr:
        """(d/dt grad_q r) . v of a quantity; for an angle theta_r + atan2(y, x), by
        the chain rule from the polynomials x, y: with x' = grad x . v and x'' its
        bias, r'' = ((x y'' - y x'')(x^2 + y^2) - 2 (x y' - y x')(x x' + y y'))
        / (x^2 + y^2)^2."""
        if qty.parts is None:
            return self.bias(qty.expr)
        y, x, (yd, xd), (yb, xb) = qty.parts
        n2 = x * x + y * y
        return ((x * yb - y * xb) * n2 - 2 * (x * yd - y * xd) * (x * xd + y * yd)) / n2**2

    def rate(self, e: sympy.Expr) -> sympy.Expr:
        """grad_q e . v."""
        return sum((g * vk for g, vk in zip(self.gradient(e), self.v)), sympy.S.Zero)

    def bias(self, e: sympy.Expr) -> sympy.Expr:
        """(d/dt grad_q e) . v = sum_ij (d^2 e / dq_i dq_j) v_i v_j for e = e(q) (the
        quantities' polynomials: term-wise derivatives of the expanded form)."""
        index = {s: k for k, s in enumerate(self.q)}
        out = []
        for si in sorted(e.free_symbols & set(index), key=index.get):
            di = sympy.diff(e, si)
            for sj in sorted(di.free_symbols & set(index), key=index.get):
                out.append(sympy.diff(di, sj) * self.v[index[si]] * self.v[index[sj]])
        return sympy.Add(*out)

    def time_derivative(self, e: sympy.Expr) -> sympy.Expr:
        return sum((g * vk for g, vk in zip(self.gradient(e), self.v)),
                   sympy.diff(e, self.t))


class _Frames:
    """Triples and body rotations in terms of q and the constants' symbols."""

    def __init__(self, plan, q, v, consts: dict):
        self.plan, self.q, self.v = plan, q, v
        self.consts = consts             # (kind, name) -> its parameter symbols

    def jet(self, name: str) -> tuple:
        """(r, r', r'') of a triple along v: (q slots, v slots, 0); fixed: constants."""
        r = self.triple(name)
        if name in self.plan.index:
            k = 3 * self.plan.index[name]
            return r, sympy.Matrix(self.v[k:k + 3]), sympy.zeros(3, 1)
        return r, sympy.zeros(3, 1), sympy.zeros(3, 1)

    def rotation_jet(self, body: str) -> tuple:
        """(R, R', R'') along v of :meth:`rotation` (R'' without the q'' terms: the
        bias). e1, e2 are linear in q, e3 = r_ij x u / (alpha l) bilinear, so
        e3'' = 2 r_ij' x u' / (alpha l)."""
        if body == GROUND:
            return sympy.eye(3), sympy.zeros(3, 3), sympy.zeros(3, 3)
        b = self.plan.model.bodies[body]
        (ri, vi, _), (rj, vj, _), (u, vu, _) = (self.jet(x) for x in (b.i, b.j, b.u))
        l, alpha, beta = self.consts[("body", body)]
        r, rd = rj - ri, vj - vi

        def frame(e1, u_, e3):
            return sympy.Matrix.hstack(e1, (u_ - beta * e1) / alpha, e3 / (alpha * l))
        zero = sympy.zeros(3, 1)
        return (frame(r / l, u, r.cross(u)), frame(rd / l, vu, rd.cross(u) + r.cross(vu)),
                frame(zero, zero, 2 * rd.cross(vu)))

    def triple(self, name: str) -> sympy.Matrix:
        if name in self.plan.index:
            k = 3 * self.plan.index[name]
            return sympy.Matrix(self.q[k:k + 3])
        return sympy.Matrix(self.consts[("triple", name)])

    def rotation(self, body: str) -> sympy.Matrix:
        """R = [e1 e2 e3] of a body from its i, j, u (ground: the identity), with the
        body constants l = |r_ij|, beta = cos(r_ij, u), alpha = sin(r_ij, u) (docs/design.md
        section 1): e1 = r_ij / l, e2 = (u - beta e1) / alpha, e3 = r_ij x u / (alpha
        l). Polynomial in q (exact on the constraint manifold, which the runs keep to
        their position tolerance), so that derivatives stay small."""
        return self.rotation_jet(body)[0]


def _angle(f: _Frames, joint, p) -> tuple:
    """(theta_r, y, x, (y', x'), (y'', x'')) of the joint's angle theta_r + atan2(y, x),
    rates and biases along v by the product rule on the frames' jets; the directions
    a_A, n1, a_A x n1, w are the joint's constants (fccgen.events.constants)."""
    A, B = joint.bodies
    c12 = f.consts[("angle", joint.name)]
    a_A, n1, an1, w = (sympy.Matrix(c12[k:k + 3]) for k in (0, 3, 6, 9))
    JA, JB = f.rotation_jet(A), f.rotation_jet(B)
    theta, c, s = p
    m_A = c * n1 + s * an1
    a = [R * a_A for R in JA]
    m = [R * m_A for R in JA]
    x = [R * w for R in JB]
    y0 = a[0].dot(m[0].cross(x[0]))
    y1 = a[1].dot(m[0].cross(x[0])) + a[0].dot(m[1].cross(x[0])) + a[0].dot(m[0].cross(x[1]))
    y2 = (a[2].dot(m[0].cross(x[0])) + a[0].dot(m[2].cross(x[0]))
          + a[0].dot(m[0].cross(x[2])) + 2 * (a[1].dot(m[1].cross(x[0]))
                                              + a[1].dot(m[0].cross(x[1]))
                                              + a[0].dot(m[1].cross(x[1]))))
    x0 = m[0].dot(x[0])
    x1 = m[1].dot(x[0]) + m[0].dot(x[1])
    x2 = m[2].dot(x[0]) + m[0].dot(x[2]) + 2 * m[1].dot(x[1])
    return theta, y0, x0, (y1, x1), (y2, x2)


def _hinge(f: _Frames, plan, source, p) -> sympy.Expr:
    """theta_r + atan2(S, C) of an angle that only element kernels read, measured as
    its first reader measures it (fccgen.events.references, docs/elements.md): with
    p = r_j - r_i - lam u on each side, D = u.(p_A x p_B), P = p_A.p_B and (S, C) =
    (D, P) turned back by the initial angle and theta_r. Cheaper than the frames'
    measure, and the reader's atan2 then starts each step at 0 exactly."""
    el = plan.elements[source.element]
    c = f.consts[("hinge", source.name)]
    la, lb, c0, s0 = c[:4]
    moving = dict(zip(el.cls.moving_triples, el.slots))
    tri = {}
    for k, t in enumerate(HINGE_TRIPLES):
        name = source.prefix + t
        if name in moving:
            tri[t] = sympy.Matrix(f.q[3 * moving[name]:3 * moving[name] + 3])
        else:
            tri[t] = sympy.Matrix(c[4 + 3 * k:7 + 3 * k])
    u = tri["u"]
    pa = tri["A.rj"] - tri["A.ri"] - la * u
    pb = tri["B.rj"] - tri["B.ri"] - lb * u
    big_d, big_p = u.dot(pa.cross(pb)), pa.dot(pb)
    theta, cr, sr = p
    cos_, sin_ = c0 * cr - s0 * sr, s0 * cr + c0 * sr
    # unevaluated: SymPy's atan2 asks the signs of its arguments, seconds per angle
    return theta + sympy.atan2(cos_ * big_d - sin_ * big_p, cos_ * big_p + sin_ * big_d,
                               evaluate=False)


def _position(f: _Frames, joint) -> sympy.Expr:
    ra, rb = f.triple(f"{joint.name}_a"), f.triple(f"{joint.name}_b")
    return (rb - ra).dot(f.triple(f"{joint.name}_axis"))


def event_system(plan) -> EventSystem:
    """The event functions of ``plan.model.events`` and the joint quantities they use
    or lock, as expressions of (q, v, t, p)."""
    model = plan.model
    n = 3 * len(plan.triples)
    q = list(sympy.symbols(f"q0:{n}", real=True))
    v = list(sympy.symbols(f"v0:{n}", real=True))
    t = sympy.Symbol("t", real=True)
    lowering = getattr(model, "mechanism", None)
    joints = {jl.joint.name: jl.joint for jl in lowering.joints} if lowering else {}
    wanted = event_quantities(model.events, joints)
    # angles that only element kernels read (springs, loads of joint angles): after
    # the events' own, for their references (fccgen.events.references)
    referenced = {src.name: src for src in angle_sources(plan)
                  if (src.name, "angle") not in wanted}
    wanted += [(name, "angle") for name in referenced]
    lockable = len(wanted) - len(referenced)
    angles = [jname for jname, kind in wanted if kind == "angle"]
    p = []
    for k in range(len(angles)):
        p += list(sympy.symbols(f"theta{k} cos{k} sin{k}", real=True))
    consts = {}
    for kind, name in layout(plan, angles):
        k = len(p)
        consts[(kind, name)] = list(sympy.symbols(f"c{k}:{k + SIZES[kind]}", real=True))
        p += consts[(kind, name)]
    frames = _Frames(plan, q, v, consts)
    quantities = []
    for row, (jname, kind) in enumerate(wanted):
        if kind == "angle" and jname in referenced:
            k = len([x for x in quantities if x.kind == "angle"])
            quantities.append(Quantity(jname, kind, _hinge(frames, plan, referenced[jname],
                                                           p[3 * k:3 * k + 3]),
                                       k, None, False))
        elif kind == "angle":
            k = len([x for x in quantities if x.kind == "angle"])
            theta, y, x, rates, biases = _angle(frames, joints[jname], p[3 * k:3 * k + 3])
            quantities.append(Quantity(jname, kind, theta + sympy.atan2(y, x), k,
                                       (y, x, rates, biases), row < lockable))
        else:
            quantities.append(Quantity(jname, kind, _position(frames, joints[jname]), None))
    system = EventSystem(q, v, t, p, quantities, [], [])
    subs = _substitutions(model, frames, system)
    for ev in model.events:
        s = ev.function.xreplace(subs)
        system.functions.append(s)
        system.uses_v.append(bool(s.free_symbols & set(v)))
    return system


def _substitutions(model, frames: _Frames, system: EventSystem) -> dict:
    """Quantity symbol (as the model file's events name them) -> expression."""
    subs = {sympy.Symbol("t", real=True): system.t}
    for name in model.points:
        r = frames.triple(name)
        if name in frames.plan.index:
            k = 3 * frames.plan.index[name]
            vel = system.v[k:k + 3]
        else:
            vel = [0, 0, 0]
        for c, (x, vx) in enumerate(zip(r, vel)):
            subs[sympy.Symbol(f"{name}.{'xyz'[c]}", real=True)] = x
            subs[sympy.Symbol(f"{name}.v{'xyz'[c]}", real=True)] = vx
    for (kind, name), symbols in frames.consts.items():   # the inputs events read
        if kind == "input":
            subs[sympy.Symbol(name, real=True)] = symbols[0]
    used = set().union(*(ev.function.free_symbols for ev in model.events))
    for qty in system.quantities:
        rate = sympy.Symbol(f"{qty.joint}.{'rate' if qty.kind == 'angle' else 'speed'}",
                            real=True)
        subs[sympy.Symbol(qty.name, real=True)] = qty.expr
        if rate in used:
            subs[rate] = system.time_derivative(qty.expr)
    return subs
