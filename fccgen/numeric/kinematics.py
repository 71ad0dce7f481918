"""Kinematics of body points and body frames in NumPy, written from docs/elements.md.

Everything is plain vector algebra on 3-vectors. Partial derivatives are kept per
*triple* (a dict from the element's triple name to a 3x3 block, or a row block), so that
fixed triples simply drop out when :meth:`Local.columns` lays the blocks out over the
element's local coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..plan.classes import KIND_ENDS, ElementClass

EYE = np.eye(3)
ZERO3 = np.zeros(3)


def cross(a, b) -> np.ndarray:
    """a x b of two 3-vectors (np.cross is general and an order of magnitude slower)."""
    return np.array([a[1] * b[2] - a[2] * b[1],
                     a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def skew(a) -> np.ndarray:
    """The cross-product matrix ~a, so that skew(a) @ b = a x b."""
    return np.array([[0.0, -a[2], a[1]],
                     [a[2], 0.0, -a[0]],
                     [-a[1], a[0], 0.0]])


class Local:
    """An element's inputs by name: scalars from p, triple positions and speeds from
    q and v (moving triples) or from p (fixed triples, at rest)."""

    def __init__(self, cls: ElementClass, q, v, p):
        q = np.asarray(q, float).reshape(-1)
        v = np.zeros(cls.n_q) if v is None else np.asarray(v, float).reshape(-1)
        p = np.asarray(p, float).reshape(-1)
        if q.size != cls.n_q or v.size != cls.n_q or p.size != cls.n_p:
            raise ValueError(f"{cls.name}: expected q, v of size {cls.n_q} and p of size "
                             f"{cls.n_p} (got {q.size}, {v.size}, {p.size})")
        self.cls = cls
        n_s = len(cls.scalar_names)
        self.s = dict(zip(cls.scalar_names, p[:n_s].tolist()))
        self.pos: dict[str, np.ndarray] = {}
        self.vel: dict[str, np.ndarray] = {}
        k_q, k_p = 0, n_s
        for name, fixed in zip(cls.triple_names, cls.fixed):
            if fixed:
                self.pos[name], self.vel[name] = p[k_p:k_p + 3], ZERO3
                k_p += 3
            else:
                self.pos[name], self.vel[name] = q[k_q:k_q + 3], v[k_q:k_q + 3]
                k_q += 3

    def columns(self, blocks: dict[str, np.ndarray], rows: int) -> np.ndarray:
        """A (rows x n_q) matrix from per-triple blocks (rows x 3 each, or a 3-vector for
        one row); blocks of fixed triples are dropped, missing ones are zero."""
        out = np.zeros((rows, self.cls.n_q))
        for k, name in enumerate(self.cls.moving_triples):
            if name in blocks:
                out[:, 3 * k:3 * k + 3] += np.reshape(blocks[name], (rows, 3))
        return out

    def body_triples(self, prefix: str = ""):
        """(names, positions, speeds) of the triples ri, rj, u (with an end prefix)."""
        names = tuple(f"{prefix}{t}" for t in ("ri", "rj", "u"))
        return (names, tuple(self.pos[n] for n in names), tuple(self.vel[n] for n in names))


@dataclass
class PointKinematics:
    """Position, velocity, bias acceleration (the acceleration at q'' = 0) and partial
    velocities Dhat (per triple, 3x3) of a point."""
    r: np.ndarray
    v: np.ndarray
    bias: np.ndarray
    dhat: dict[str, np.ndarray]


@dataclass
class FrameKinematics:
    """Body frame R = [e1 e2 e3], body-frame angular velocity w_b, its partials Phi_b
    (per triple, 3x3) and the bias c_w of its time derivative."""
    R: np.ndarray
    w_b: np.ndarray
    phi_b: dict[str, np.ndarray]
    c_w: np.ndarray

    @property
    def w(self) -> np.ndarray:
        """Angular velocity in the global frame."""
        return self.R @ self.w_b


def body_point(names, pos, vel, l, alpha, b1, b2, b3) -> PointKinematics:
    """r = ri + b1 r_ij + b2 u + c (r_ij x u), c = b3 / (alpha l)."""
    ri, rj, u = pos
    dri, drj, du = vel
    rij, drij = rj - ri, drj - dri
    c = b3 / (alpha * l)
    r = ri + b1 * rij + b2 * u + c * cross(rij, u)
    v = dri + b1 * drij + b2 * du + c * (cross(drij, u) + cross(rij, du))
    su = skew(u)
    dhat = {names[0]: (1.0 - b1) * EYE + c * su,
            names[1]: b1 * EYE - c * su,
            names[2]: b2 * EYE + c * skew(rij)}
    return PointKinematics(r, v, 2.0 * c * cross(drij, du), dhat)


def plain_point(name, r, v) -> PointKinematics:
    """A named point: its own triple, Dhat = E, no bias."""
    return PointKinematics(r, v, ZERO3, {name: EYE})


def end_point(x: Local, end: str) -> PointKinematics:
    """Kinematics of the end ``end`` ("A", "B", "K") of a joint or spring element."""
    kind = x.cls.ends[KIND_ENDS[x.cls.kind].index(end)]
    if kind == "point":
        name = f"{end}.r"
        return plain_point(name, x.pos[name], x.vel[name])
    s = x.s
    names, pos, vel = x.body_triples(f"{end}.")
    return body_point(names, pos, vel, s[f"{end}.l"], s[f"{end}.alpha"],
                      s[f"{end}.b1"], s[f"{end}.b2"], s[f"{end}.b3"])


def body_frame(names, pos, vel, l, alpha, beta) -> FrameKinematics:
    """Frame and angular velocity of a typical body (docs/elements.md, seed eq. 13).

    w_b = [e2'.e3, e3'.e1, e1'.e2]. In the second row (r_ij x u').e1 = 0 because
    e1 = r_ij / l, so w_b2 = (r_ij' x u).e1 / (alpha l) = -r_ij'.e3 / l exactly.

    Its time derivative is Phi_b q'' + c_w with c_w = (d Phi_b / dt) q'. Rows 1 and 3
    have coefficients linear in q and give e2'.e3' and e1'.e2'. Row 2 does not: the
    derivative of -r_ij'.e3 / l at q'' = 0 is -r_ij'.e3' / l = e1.(r_ij' x u') / (alpha l),
    which is e3'.e1' + 2 e1.(r_ij' x u') / (alpha l), not e3'.e1' alone. Terms that
    vanish identically (a.(a x b)) are left out so that quantities that are zero for a
    class (h of a hinge about a fixed axis) come out exactly zero, not as rounding.
    """
    ri, rj, u = pos
    dri, drj, du = vel
    rij, drij = rj - ri, drj - dri
    k = 1.0 / (alpha * l)
    e1 = rij / l
    e2 = (u - beta * e1) / alpha
    e3 = k * cross(rij, u)
    de1 = drij / l
    de2 = (du - beta * de1) / alpha
    de3 = k * (cross(drij, u) + cross(rij, du))
    w_b = np.array([de2 @ e3, -(drij @ e3) / l, de1 @ e2])
    # rows of w_b's partials with respect to r_ij' (ri: minus, rj: plus) and u'
    d_rij = np.array([-beta / (alpha * l) * e3, -e3 / l, e2 / l])
    d_u = np.array([e3 / alpha, ZERO3, ZERO3])
    phi_b = {names[0]: -d_rij, names[1]: d_rij, names[2]: d_u}
    # e2'.e3' without its identically zero terms u'.(r_ij x u') and r_ij'.(r_ij' x u)
    c_w1 = (du @ cross(drij, u) - beta / l * (drij @ cross(rij, du))) / (alpha ** 2 * l)
    c_w = np.array([c_w1, k * (e1 @ cross(drij, du)), de1 @ de2])
    return FrameKinematics(np.column_stack([e1, e2, e3]), w_b, phi_b, c_w)


def inertia_tensor(s: dict) -> np.ndarray:
    """I_b from the six tensor components of a body's scalars."""
    return np.array([[s["Ixx"], s["Ixy"], s["Ixz"]],
                     [s["Ixy"], s["Iyy"], s["Iyz"]],
                     [s["Ixz"], s["Iyz"], s["Izz"]]])
