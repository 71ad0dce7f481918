"""The rigid motion of every moving body over the rows of a result, from the recorded
coordinates q, speeds q' and the accelerations q'' (NumPy, vectorised over rows).

A typical body's frame (docs/design.md §1) is e1 = r_ij / l, e3 = w / |w| with
w = r_ij x u, e2 = e3 x e1. On the constraint manifold l and |w| are constant, so

    e1'' = a_ij / l,   w'' = a_ij x u + 2 v_ij x u' + r_ij x u'',   e3'' = w'' / |w|,
    e2'' = e3'' x e1 + 2 e3' x e1' + e3 x e1''

and, for any orthonormal frame moving rigidly (e_k' = omega x e_k),

    omega = 1/2 sum_k e_k x e_k',   alpha = omega' = 1/2 sum_k e_k x e_k''.

A body point rho (body frame, from point i) is at r = r_i + R rho, with
r'' = a_i + sum_k rho_k e_k''; the mass centre's acceleration a_G follows with
rho = rho_G. The rate of angular momentum about G is H_G' = I alpha + omega x I omega,
I = R J R^T (J: the inertia about G in the body frame).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.types import BodyPoint


def _unit(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x / |x|, |x|) row-wise for (n, 3) arrays."""
    n = np.linalg.norm(x, axis=1)
    return x / n[:, None], n


@dataclass
class BodyMotion:
    """(n, 3) or (n, 3, 3) arrays of one body over the rows."""
    r_i: np.ndarray
    v_i: np.ndarray
    a_i: np.ndarray
    R: np.ndarray            # (n, 3, 3), columns e1 e2 e3
    R_dot: np.ndarray
    R_ddot: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray

    def point(self, rho) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration of the body point ``rho`` (body frame)."""
        rho = np.asarray(rho, float)
        return (self.r_i + self.R @ rho, self.v_i + self.R_dot @ rho,
                self.a_i + self.R_ddot @ rho)


class Motion:
    """Positions, speeds and accelerations of a plan's triples and bodies over rows.

    q, v, a: (n, n_q). Fixed triples are constant and at rest."""

    def __init__(self, plan, q: np.ndarray, v: np.ndarray, a: np.ndarray):
        self.plan, self.q, self.v, self.a = plan, q, v, a
        self.n = len(q)
        self._bodies: dict[str, BodyMotion] = {}

    def triple(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(n, 3) position, speed and acceleration of a point or vector."""
        if name in self.plan.index:
            s = slice(3 * self.plan.index[name], 3 * self.plan.index[name] + 3)
            return self.q[:, s], self.v[:, s], self.a[:, s]
        m = self.plan.model
        value = m.points[name].at if name in m.points else m.vectors[name].along
        zero = np.zeros((self.n, 3))
        return np.tile(np.asarray(value, float), (self.n, 1)), zero, zero

    def body(self, name: str) -> BodyMotion:
        """The frame of body ``name`` and its first and second derivatives."""
        if name not in self._bodies:
            self._bodies[name] = self._frame(self.plan.model.bodies[name])
        return self._bodies[name]

    def _frame(self, b) -> BodyMotion:
        (ri, vi, ai), (rj, vj, aj), (u, ud, udd) = (self.triple(x) for x in (b.i, b.j, b.u))
        rij, vij, aij = rj - ri, vj - vi, aj - ai
        e1, l = _unit(rij)
        e1d, e1dd = vij / l[:, None], aij / l[:, None]
        w = np.cross(rij, u)
        e3, wn = _unit(w)
        e3d = (np.cross(vij, u) + np.cross(rij, ud)) / wn[:, None]
        e3dd = (np.cross(aij, u) + 2.0 * np.cross(vij, ud) + np.cross(rij, udd)) / wn[:, None]
        e2 = np.cross(e3, e1)
        e2d = np.cross(e3d, e1) + np.cross(e3, e1d)
        e2dd = np.cross(e3dd, e1) + 2.0 * np.cross(e3d, e1d) + np.cross(e3, e1dd)
        frame = [(e1, e1d, e1dd), (e2, e2d, e2dd), (e3, e3d, e3dd)]
        omega = 0.5 * sum(np.cross(e, ed) for e, ed, _ in frame)
        alpha = 0.5 * sum(np.cross(e, edd) for e, _, edd in frame)
        stack = [np.stack([f[k] for f in frame], axis=2) for k in range(3)]
        return BodyMotion(ri, vi, ai, *stack, omega, alpha)

    def centre(self, name: str):
        """Position and acceleration of body ``name``'s mass centre."""
        r, _, a = self.body(name).point(self.plan.model.bodies[name].center)
        return r, a

    def momentum_rate(self, name: str) -> np.ndarray:
        """(n, 3) H_G' = I alpha + omega x I omega, I = R J R^T."""
        bm, J = self.body(name), self.plan.model.bodies[name].inertia
        inertia = bm.R @ J @ np.swapaxes(bm.R, 1, 2)
        Iw = np.einsum("nij,nj->ni", inertia, bm.omega)
        return np.einsum("nij,nj->ni", inertia, bm.alpha) + np.cross(bm.omega, Iw)

    def reference(self, ref) -> tuple[np.ndarray, np.ndarray]:
        """Position and speed of a point reference (a point name or a body point)."""
        if isinstance(ref, BodyPoint):
            r, v, _ = self.body(ref.body).point(ref.at)
            return r, v
        r, v, _ = self.triple(ref)
        return r, v
