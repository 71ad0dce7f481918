"""NumPy kernels of forces and torques whose components read joint quantities (kinds
force_q, torque_q; docs/elements.md "Loads of joint quantities"), registered in
:data:`fccgen.numeric.elements.KIND_KERNELS` when the package is imported. Written
independently of the symbolic path: no SymPy.

f = G^T F(t, z) with G^T the load's map (Dhat^T of its point, or Phi_b^T R^T) and
z the joint quantities. Then

    df/dq  = [d(G^T)/dq] F  +  G^T (dF/dz) (dz/dq),      df/dq' = G^T (dF/dz) (dz/dq'),

the first term being the constant-load Jacobian at the current F. dF/dz comes from
first-order forward differentiation of the expression's syntax tree; the gradients
of z are written out by hand:

* angle = th + atan2(S, C) (see fccgen.derive.joint_loads; th the solver's turn
  reference); with the vectors u, p_A, p_B,
  dD = (p_A x p_B, p_B x u, u x p_A) and dP = (0, p_B, p_A) on (u, p_A, p_B), and
  p = r_j - r_i - lam u chained to the triples. rate = (C S' - S C') / N with
  d rate/dq' = d angle/dq and d rate/dq from the gradients of S', C':
  dD' = (p_A' x p_B + p_A x p_B', p_B x u' + p_B' x u, u' x p_A + u x p_A'),
  dP' = (0, p_B', p_A');
* a named table name(z) (fccgen.expressions.named_tables): SciPy's clamped spline of
  its rows and the spline's derivative, constant outside the rows;
* position = u.d - s0 (d = r_b - r_a): gradient (d, -u, u) on (u, r_a, r_b);
  speed = u'.d + u.d': on q (d', -u', u'), on q' the position gradient.
"""
from __future__ import annotations

import ast
import math
from functools import cached_property, lru_cache

import numpy as np

from ..expressions.named_tables import expressions_of, numeric_splines
from .elements import KIND_KERNELS, ForceKernels, TorqueKernels, turned
from .kinematics import cross
from .mechanism_kernels import input_values

# -- first-order forward differentiation over several variables -----------------------

_UNARY = {"sin": (math.sin, math.cos), "cos": (math.cos, lambda x: -math.sin(x)),
          "tan": (math.tan, lambda x: 1.0 + math.tan(x) ** 2),
          "exp": (math.exp, math.exp), "log": (math.log, lambda x: 1.0 / x),
          "sqrt": (math.sqrt, lambda x: 0.5 / math.sqrt(x)),
          "abs": (abs, lambda x: math.copysign(1.0, x))}


def _dual(node: ast.AST, env: dict, tables=None) -> tuple[float, np.ndarray]:
    """(value, gradient over env's variables) of a checked expression tree; env maps
    names to (value, gradient); ``tables``: name -> x -> (value, slope) of the named
    tables the tree calls (fccgen.expressions.named_tables.numeric_splines)."""
    tables = tables or {}
    zero = np.zeros_like(next(iter(env.values()))[1])
    if isinstance(node, ast.Constant):
        return float(node.value), zero
    if isinstance(node, ast.Name):
        return env[node.id] if node.id != "pi" else (math.pi, zero)
    if isinstance(node, ast.Attribute):
        return env[f"{node.value.id}.{node.attr}"]
    if isinstance(node, ast.UnaryOp):
        a, da = _dual(node.operand, env, tables)
        return (-a, -da) if isinstance(node.op, ast.USub) else (a, da)
    if isinstance(node, ast.BinOp):
        (a, da), (b, db) = _dual(node.left, env, tables), _dual(node.right, env, tables)
        op = type(node.op)
        if op is ast.Add:
            return a + b, da + db
        if op is ast.Sub:
            return a - b, da - db
        if op is ast.Mult:
            return a * b, da * b + a * db
        if op is ast.Div:
            return a / b, (da * b - a * db) / (b * b)
        if op is ast.Pow and not db.any():                   # a ** constant
            return a ** b, (b * a ** (b - 1.0) if b != 0.0 else 0.0) * da
        if op is ast.Pow:
            value = a ** b
            return value, value * (db * math.log(a) + b * da / a)
    if isinstance(node, ast.Call):
        args = [_dual(x, env, tables) for x in node.args]
        name = node.func.id
        if name in tables:                                   # a named table
            (a, da), = args
            value, slope = tables[name](a)
            return value, slope * da
        if name in _UNARY:
            f, d = _UNARY[name]
            (a, da), = args
            return f(a), d(a) * da
        if name == "atan2":
            (y, dy), (x, dx) = args
            return math.atan2(y, x), (x * dy - y * dx) / (x * x + y * y)
        pick = min if name == "min" else max
        return pick(args, key=lambda z: z[0])
    raise ValueError(f"{ast.unparse(node)!r} is not in the restricted grammar "
                     "(docs/expressions.md)")


@lru_cache(maxsize=None)
def _trees(text: str) -> tuple[ast.AST, ...]:
    return tuple(ast.parse(x.strip(), mode="eval").body for x in text.split(";"))


# -- joint quantities with their gradients --------------------------------------------

def _dot(a, b):
    """a . b of 3-vectors, or of stacks of them with the components first (3, n)."""
    return (a * b).sum(axis=0)


def _hinge(x, prefix: str):
    """The hinge measure's parts: (u, u', p_A, p_B, p_A', p_B', D, P, D', P'); the
    vectors may be stacks (3, n) of records, components first."""
    pos = {n: x.pos[prefix + n] for n in ("A.ri", "A.rj", "B.ri", "B.rj", "u")}
    vel = {n: x.vel[prefix + n] for n in pos}
    la, lb = x.s[prefix + "lA"], x.s[prefix + "lB"]
    u, du = pos["u"], vel["u"]
    pa, pb = pos["A.rj"] - pos["A.ri"] - la * u, pos["B.rj"] - pos["B.ri"] - lb * u
    va, vb = vel["A.rj"] - vel["A.ri"] - la * du, vel["B.rj"] - vel["B.ri"] - lb * du
    D, P = _dot(u, cross(pa, pb)), _dot(pa, pb)
    Dd = _dot(du, cross(pa, pb)) + _dot(u, cross(va, pb)) + _dot(u, cross(pa, vb))
    Pd = _dot(va, pb) + _dot(pa, vb)
    return u, du, pa, pb, va, vb, D, P, Dd, Pd


def angle_rate(x, prefix: str):
    """(angle, rate) of the hinge ``prefix`` without their gradients (as :func:`_angle`
    gives them: th + atan2(S, C) and (C S' - S C') / N); arrays over the records when
    x's vectors are stacks (3, n)."""
    s = x.s
    c0, s0 = turned(s, prefix)
    *_, D, P, Dd, Pd = _hinge(x, prefix)
    S, C = c0 * D - s0 * P, c0 * P + s0 * D
    Sd, Cd = c0 * Dd - s0 * Pd, c0 * Pd + s0 * Dd
    return s[prefix + "th"] + np.arctan2(S, C), (C * Sd - S * Cd) / (S * S + C * C)


def _angle(x, prefix: str):
    """(angle, rate, d angle/dq, d rate/dq) over the element's q."""
    s = x.s
    la, lb = s[prefix + "lA"], s[prefix + "lB"]
    c0, s0 = turned(s, prefix)
    u, du, pa, pb, va, vb, D, P, Dd, Pd = _hinge(x, prefix)
    zero = np.zeros(3)
    # gradients on (u, p_A, p_B)
    gD, gP = (cross(pa, pb), cross(pb, u), cross(u, pa)), (zero, pb, pa)
    gDd = (cross(va, pb) + cross(pa, vb), cross(pb, du) + cross(vb, u),
           cross(du, pa) + cross(u, va))
    gPd = (zero, vb, va)

    def to_q(g):                      # chain p = r_j - r_i - lam u to the triples
        gu, ga, gb = g
        return x.columns({prefix + "u": gu - la * ga - lb * gb, prefix + "A.rj": ga,
                          prefix + "A.ri": -ga, prefix + "B.rj": gb, prefix + "B.ri": -gb},
                         1)[0]
    S, C = c0 * D - s0 * P, c0 * P + s0 * D
    Sd, Cd = c0 * Dd - s0 * Pd, c0 * Pd + s0 * Dd
    dS, dC = to_q(gD) * c0 - to_q(gP) * s0, to_q(gP) * c0 + to_q(gD) * s0
    dSd, dCd = to_q(gDd) * c0 - to_q(gPd) * s0, to_q(gPd) * c0 + to_q(gDd) * s0
    N = S * S + C * C
    rate = (C * Sd - S * Cd) / N
    g_angle = (C * dS - S * dC) / N
    g_rate = ((dC * Sd + C * dSd - dS * Cd - S * dCd) / N
              - rate * 2.0 * (S * dS + C * dC) / N)
    return s[prefix + "th"] + math.atan2(S, C), rate, g_angle, g_rate


def _position(x, prefix: str):
    """(position, speed, d position/dq, d speed/dq)."""
    u, ra, rb = (x.pos[prefix + n] for n in ("u", "ra", "rb"))
    du, va, vb = (x.vel[prefix + n] for n in ("u", "ra", "rb"))
    d, dd = rb - ra, vb - va
    g = x.columns({prefix + "u": d, prefix + "ra": -u, prefix + "rb": u}, 1)[0]
    g_speed = x.columns({prefix + "u": dd, prefix + "ra": -du, prefix + "rb": du}, 1)[0]
    return u @ d - x.s[prefix + "s0"], du @ d + u @ dd, g, g_speed


class _JointLoad:
    """Mixin over the constant-load kernels: F(t, z) written into the components
    ``names`` at construction, and its gradients kept for the Jacobians."""
    names: tuple[str, str, str]

    def __init__(self, cls, q, v, p):
        super().__init__(cls, q, v, p)
        x, n = self.x, cls.n_q
        env = {"t": (x.s["t"], np.zeros(2 * n))}       # gradient over (q, q')
        for name, value in input_values(cls, x.s).items():   # constant over a step
            env[name] = (value, np.zeros(2 * n))
        for joint, family in cls.joint_families:
            prefix = f"{joint}.{family}."
            if family == "angle":
                a, r, ga, gr = _angle(x, prefix)
                pairs = (("angle", a, ga, 0 * ga), ("rate", r, gr, ga))
            else:
                a, r, ga, gr = _position(x, prefix)
                pairs = (("position", a, ga, 0 * ga), ("speed", r, gr, ga))
            for name, value, gq, gv in pairs:
                env[f"{joint}.{name}"] = (value, np.concatenate([gq, gv]))
        text = cls.function.split("|", 1)[1]
        tables = numeric_splines(text)
        text = expressions_of(text)
        try:
            rows = [_dual(tree, env, tables) for tree in _trees(text)]
        except ValueError as exc:         # the user's text, never a syntax tree
            raise ValueError(f"the load {text.replace(';', ', ')!r}: {exc}") from None
        for name, (value, _) in zip(self.names, rows):
            x.s[name] = value
        self.dF = np.array([g for _, g in rows])         # 3 x 2 n_q

    @cached_property
    def map_t(self) -> np.ndarray:
        """G^T: n_q x 3, f = G^T F."""
        raise NotImplementedError

    def applied_forces(self):
        return self.map_t @ self.force_value

    def force_jacobian_q(self):
        n = self.cls.n_q
        return super().force_jacobian_q() + self.map_t @ self.dF[:, :n]

    def force_jacobian_v(self):
        return self.map_t @ self.dF[:, self.cls.n_q:]


class ForceQKernels(_JointLoad, ForceKernels):
    """f = Dhat^T F(t, z)."""
    names = ("Fx", "Fy", "Fz")

    @cached_property
    def map_t(self):
        return self.x.columns(self.P.dhat, 3).T

    @property
    def force_value(self):
        return self.force


class TorqueQKernels(_JointLoad, TorqueKernels):
    """f = Phi_b^T R^T T(t, z)."""
    names = ("Tx", "Ty", "Tz")

    @cached_property
    def map_t(self):
        from .kinematics import body_frame
        s = self.x.s
        F = body_frame(*self.x.body_triples(), s["l"], s["alpha"], s["beta"])
        return self.x.columns(F.phi_b, 3).T @ F.R.T

    @property
    def force_value(self):
        return np.array([self.x.s[n] for n in self.names])


KIND_KERNELS.update({"force_q": ForceQKernels, "torque_q": TorqueQKernels})
