"""What the NumPy version's events read (docs/events.md), written independently of
the compiled event kernels (fccgen.events.symbolic): joint angles and slides with
their gradient and bias, point coordinates and speeds, and the event functions.

Joint angle (revolute, cylindrical J between A and B, axis triple J_axis = u): each
side's direction perpendicular to the axis, p = r_j - r_i - lam u from two points of
its body (lam = r_ij . u at the written configuration; ground: a fixed perpendicular
of the axis), D = u . (p_A x p_B), P = p_A . p_B; the angle from the written
configuration, counted over turns, is

    theta = theta_r + atan2(S, C),  (S, C) = (D, P) turned back by psi_0 + theta_r,

psi_0 = atan2(D, P) at the written configuration, theta_r the reference the events
move to the angle after every accepted step. With x = (p_A, p_B, u) linear in q:
dtheta/dx = (P dD - D dP) / N (N = D^2 + P^2); the bias (d/dt dtheta/dq) v, the
second derivative along v at q'' = 0, is ((P D'' - D P'') N - (P D' - D P') N') / N^2
with D'' = 2 (u'.(p_A' x p_B) + u'.(p_A x p_B') + u.(p_A' x p_B')), P'' = 2 p_A'.p_B'.

Joint slide (prismatic, cylindrical): s = (r_b - r_a) . u of the triples J_a, J_b,
J_axis (0 where J_a and J_b coincide), bias 2 (r_b' - r_a') . u'.

Event functions are read from the model file's text (``when``) by Python's ast and
evaluated with forward derivatives over (q, v) (fccgen.numeric.joint_loads._dual):
a condition ``lhs OP rhs`` is lhs - rhs. Rates, speeds and point velocities enter
with their values only (their gradients are never needed: a bounce, which needs
ds/dq, reads positions and time only).
"""
from __future__ import annotations

import ast
import math
from functools import lru_cache

import numpy as np

from ..mechanism.joints import ANGLE_TYPES, perpendiculars
from ..model.types import GROUND
from .joint_loads import _dual
from .kinematics import cross

POINT_QUANTITIES = {"x": 0, "y": 1, "z": 2}


@lru_cache(maxsize=None)
def event_tree(text: str) -> ast.AST:
    """The expression s of an event's ``when`` text (lhs - rhs of a condition)."""
    node = ast.parse(text.strip(), mode="eval").body
    if isinstance(node, ast.Compare):
        return ast.BinOp(left=node.left, op=ast.Sub(), right=node.comparators[0])
    return node


class Triples:
    """Positions and speeds of the plan's triples (moving: from q, v; fixed: the
    model's values) and their coordinate slots."""

    def __init__(self, plan):
        self.plan = plan
        model = plan.model
        self.fixed = {**{n: np.asarray(p.at, float) for n, p in model.points.items()},
                      **{n: np.asarray(v.along, float) for n, v in model.vectors.items()}}
        self.q0 = np.asarray(plan.q0, float)

    def get(self, name: str, q, v=None):
        """(position, speed, slot or None)."""
        k = self.plan.index.get(name)
        if k is None:
            return self.fixed[name], np.zeros(3), None
        sl = slice(3 * k, 3 * k + 3)
        return q[sl], (np.zeros(3) if v is None else v[sl]), k

    def written(self, name: str) -> np.ndarray:
        k = self.plan.index.get(name)
        return self.fixed[name] if k is None else self.q0[3 * k:3 * k + 3]


class JointAngle:
    """theta, dtheta/dq and the bias of a joint angle (module docstring)."""

    def __init__(self, triples: Triples, joint):
        self.t, self.joint = triples, joint
        model = triples.plan.model
        self.axis = f"{joint.name}_axis"
        u0 = triples.written(self.axis)
        self.sides = []
        for body in joint.bodies:
            if body == GROUND:
                self.sides.append((None, None, perpendiculars(u0)[0], 0.0))
            else:
                b = model.bodies[body]
                r = triples.written(b.j) - triples.written(b.i)
                self.sides.append((b.i, b.j, None, float(r @ u0)))
        d, p = self._dp(self._x(self.t.q0, None)[0])
        self.psi0 = math.atan2(d, p)

    def _x(self, q, v):
        """(p_A, p_B, u), their speeds, and per part the (slot, coefficient) pairs of
        its triples (p = r_j - r_i - lam u)."""
        u, du, ku = self.t.get(self.axis, q, v)
        parts, rates, slots = [], [], []
        for i, j, const, lam in self.sides:
            if const is not None:
                parts.append(const)
                rates.append(np.zeros(3))
                slots.append([])
                continue
            (ri, vi, ki), (rj, vj, kj) = self.t.get(i, q, v), self.t.get(j, q, v)
            parts.append(rj - ri - lam * u)
            rates.append(vj - vi - lam * du)
            slots.append([(k, c) for k, c in ((ki, -1.0), (kj, 1.0)) if k is not None])
        return (parts[0], parts[1], u), (rates[0], rates[1], du), (slots, ku)

    @staticmethod
    def _dp(x):
        pa, pb, u = x
        return float(u @ cross(pa, pb)), float(pa @ pb)

    def value(self, q, theta_r: float) -> float:
        d, p = self._dp(self._x(q, None)[0])
        c, s = math.cos(self.psi0 + theta_r), math.sin(self.psi0 + theta_r)
        return theta_r + math.atan2(c * d - s * p, c * p + s * d)

    def gradient_rate_bias(self, q, v):
        """(dtheta/dq, theta' = dtheta/dq . v, bias)."""
        (pa, pb, u), (dpa, dpb, du), (slots, ku) = self._x(q, v)
        d, p = self._dp((pa, pb, u))
        gd = (cross(pb, u), cross(u, pa), cross(pa, pb))      # dD / (p_A, p_B, u)
        gp = (pb, pa, np.zeros(3))
        n2 = d * d + p * p
        gx = [(p * a - d * b) / n2 for a, b in zip(gd, gp)]   # dtheta / (p_A, p_B, u)
        grad = np.zeros(self.t.plan.n_q)
        for part, side in zip(gx[:2], slots):
            for k, c in side:
                grad[3 * k:3 * k + 3] += c * part
        if ku is not None:                   # u directly, and through p = ... - lam u
            grad[3 * ku:3 * ku + 3] += gx[2] - sum(
                lam * part for part, (_, _, const, lam) in zip(gx[:2], self.sides)
                if const is None)
        d1 = du @ cross(pa, pb) + u @ cross(dpa, pb) + u @ cross(pa, dpb)
        p1 = dpa @ pb + pa @ dpb
        d2 = 2.0 * (du @ cross(dpa, pb) + du @ cross(pa, dpb) + u @ cross(dpa, dpb))
        p2 = 2.0 * (dpa @ dpb)
        rate = (p * d1 - d * p1) / n2
        bias = ((p * d2 - d * p2) * n2 - (p * d1 - d * p1) * 2.0 * (d * d1 + p * p1)) / n2**2
        return grad, float(rate), float(bias)


class JointSlide:
    """s = (r_b - r_a) . u of a joint's triples, its gradient, speed and bias."""

    def __init__(self, triples: Triples, joint):
        self.t = triples
        self.names = (f"{joint.name}_a", f"{joint.name}_b", f"{joint.name}_axis")

    def value(self, q, theta_r: float = 0.0) -> float:
        (ra, _, _), (rb, _, _), (u, _, _) = (self.t.get(n, q) for n in self.names)
        return float((rb - ra) @ u)

    def gradient_rate_bias(self, q, v):
        (ra, va, ka), (rb, vb, kb), (u, du, ku) = (self.t.get(n, q, v) for n in self.names)
        grad = np.zeros(self.t.plan.n_q)
        for k, g in ((ka, -u), (kb, u), (ku, rb - ra)):
            if k is not None:
                grad[3 * k:3 * k + 3] += g
        return grad, float((vb - va) @ u + (rb - ra) @ du), float(2.0 * (vb - va) @ du)


def joint_quantity(triples: Triples, joint, kind: str):
    """The angle or slide of ``joint``."""
    return JointAngle(triples, joint) if kind == "angle" else JointSlide(triples, joint)


def quantity_kind(joint, name: str) -> str:
    """"angle" for J.angle and J.rate of an angle joint, else "position"."""
    return "angle" if name in ("angle", "rate") and joint.type in ANGLE_TYPES else "position"


def event_value(tree, env: dict) -> tuple[float, np.ndarray]:
    """(s, ds/d(q, v)) of an event tree over env {name: (value, gradient)}."""
    return _dual(tree, env)
