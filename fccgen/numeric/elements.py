"""The kernels of every element kind in NumPy (docs/elements.md), with the layouts
of fccgen/plan/kernels.py: local coordinates and speeds of the moving triples, row-major
matrices, ``energy = [kinetic, potential]``, ``body_outputs = [r_G, w]``.

One :class:`ElementKernels` object holds one element at one state; its kinematics are
computed once, when a kernel first needs them, so that a solver asking several kernels
of the same element pays for them once.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from ..plan.classes import ALIGNED_ROWS, KIND_ENDS, ElementClass
from ..plan.kernels import KERNELS
from .kinematics import (EYE, Local, body_frame, body_point, cross, end_point,
                         inertia_tensor, skew)

_SPECS = {k.name: k for k in KERNELS}


class ElementKernels:
    """Kernels of one element at (q, v); subclasses implement the ones of their kind.

    Constraint elements implement ``_rows()``: per constraint row, its value g, its
    partials (per triple) and its bias q'^T (d2g/dq2) q'.
    """

    def __init__(self, cls: ElementClass, q, v, p):
        self.cls = cls
        self.x = Local(cls, q, v, p)

    def evaluate(self, name: str) -> np.ndarray | None:
        """Flattened row-major output of kernel ``name``, or None if it does not apply."""
        spec = _SPECS[name]
        if not spec.applies(self.cls):
            return None
        out = np.array(getattr(self, name)(), float).reshape(-1)
        if out.size != spec.size(self.cls):  # pragma: no cover - a layout bug
            raise AssertionError(f"{self.cls.name}.{name}: {out.size} outputs, "
                                 f"expected {spec.size(self.cls)}")
        return out

    # -- constraints, from _rows() -------------------------------------------------
    def _rows(self) -> list[tuple[float, dict, float]]:
        return []

    @cached_property
    def _row_data(self):
        return self._rows()

    def constraints(self) -> np.ndarray:
        return np.array([g for g, _, _ in self._row_data])

    def constraint_jacobian(self) -> np.ndarray:
        rows = [self.x.columns(blocks, 1) for _, blocks, _ in self._row_data]
        return np.vstack(rows) if rows else np.zeros((0, self.cls.n_q))

    def constraint_bias(self) -> np.ndarray:
        return np.array([b for _, _, b in self._row_data])


class BodyKernels(ElementKernels):
    """A rigid body: mass centre r_G (a body point with a1..a3), frame, constraints."""

    @cached_property
    def G(self):
        s = self.x.s
        return body_point(*self.x.body_triples(), s["l"], s["alpha"], s["a1"], s["a2"],
                          s["a3"])

    @cached_property
    def frame(self):
        s = self.x.s
        return body_frame(*self.x.body_triples(), s["l"], s["alpha"], s["beta"])

    @cached_property
    def dhat(self) -> np.ndarray:
        return self.x.columns(self.G.dhat, 3)

    @cached_property
    def phi_b(self) -> np.ndarray:
        return self.x.columns(self.frame.phi_b, 3)

    @cached_property
    def inertia(self) -> np.ndarray:
        return inertia_tensor(self.x.s)

    @property
    def gravity(self) -> np.ndarray:
        s = self.x.s
        return np.array([s["gx"], s["gy"], s["gz"]])

    def mass_matrix(self):
        """M = m Dhat^T Dhat + Phi_b^T I_b Phi_b."""
        D, P = self.dhat, self.phi_b
        return self.x.s["m"] * D.T @ D + P.T @ self.inertia @ P

    def h_vector(self):
        """h = m Dhat^T a_bias + Phi_b^T (I_b c_w + w_b x I_b w_b)."""
        F, I = self.frame, self.inertia
        moment = I @ F.c_w + cross(F.w_b, I @ F.w_b)
        return self.x.s["m"] * self.dhat.T @ self.G.bias + self.phi_b.T @ moment

    def applied_forces(self):
        """f = Dhat^T (m g)."""
        return self.dhat.T @ (self.x.s["m"] * self.gravity)

    def _rows(self):
        x, s = self.x, self.x.s
        names, (ri, rj, u), (dri, drj, du) = x.body_triples()
        rij, drij = rj - ri, drj - dri
        rows = []
        for row in self.cls.constraint_rows:
            if row == "length":
                rows.append((rij @ rij - s["l"] ** 2,
                             {names[0]: -2.0 * rij, names[1]: 2.0 * rij},
                             2.0 * drij @ drij))
            else:  # "angle"
                rows.append((rij @ u - s["l"] * s["beta"],
                             {names[0]: -u, names[1]: u, names[2]: rij},
                             2.0 * drij @ du))
        return rows

    def energy(self):
        """[m v_G.v_G / 2 + w_b.I_b w_b / 2, -m g.r_G]."""
        m, G, w_b = self.x.s["m"], self.G, self.frame.w_b
        return [0.5 * m * G.v @ G.v + 0.5 * w_b @ self.inertia @ w_b,
                -m * self.gravity @ G.r]

    def body_outputs(self):
        """[r_G, R w_b]."""
        return np.concatenate([self.G.r, self.frame.w])

    def force_jacobian_q(self):
        """d(Dhat^T m g)/dq: Dhat depends on q through its c ~u and c ~r_ij blocks."""
        s = self.x.s
        c = s["a3"] / (s["alpha"] * s["l"])
        return _square(self.x, _dhat_t_jacobian(("ri", "rj", "u"), c,
                                                s["m"] * self.gravity))


class UnitVectorKernels(ElementKernels):
    """u . u - 1 = 0 for a moving unit vector."""

    def _rows(self):
        u, du = self.x.pos["u"], self.x.vel["u"]
        return [(u @ u - 1.0, {"u": 2.0 * u}, 2.0 * du @ du)]


class DistanceKernels(ElementKernels):
    """d . d - L^2 = 0, d = r_B - r_A."""

    def _rows(self):
        A, B = end_point(self.x, "A"), end_point(self.x, "B")
        d, dd = B.r - A.r, B.v - A.v
        blocks = _combine((2.0 * d, B.dhat), (-2.0 * d, A.dhat))
        bias = 2.0 * dd @ dd + 2.0 * d @ (B.bias - A.bias)
        return [(d @ d - self.x.s["L"] ** 2, blocks, bias)]


class PointOnLineKernels(ElementKernels):
    """(r_K - r_A) x (r_B - r_A) = 0 (three rows, rank two)."""

    def _rows(self):
        K, A, B = (end_point(self.x, e) for e in ("K", "A", "B"))
        a, b = K.r - A.r, B.r - A.r
        da, db = K.v - A.v, B.v - A.v
        g = cross(a, b)
        # dg = a' x b + a x b' = -~b a' + ~a b'
        blocks = _combine((-skew(b), K.dhat), (skew(b) - skew(a), A.dhat), (skew(a), B.dhat))
        bias = (cross(K.bias - A.bias, b) + 2.0 * cross(da, db)
                + cross(a, B.bias - A.bias))
        return [(g[k], {n: blk[k] for n, blk in blocks.items()}, bias[k]) for k in range(3)]


class ForceKernels(ElementKernels):
    """A constant global force F at a body point: f = Dhat^T F, energy [0, -F . r]."""

    @cached_property
    def P(self):
        s = self.x.s
        return body_point(*self.x.body_triples(), s["l"], s["alpha"], s["b1"], s["b2"],
                          s["b3"])

    @property
    def force(self) -> np.ndarray:
        s = self.x.s
        return np.array([s["Fx"], s["Fy"], s["Fz"]])

    def applied_forces(self):
        return self.x.columns(self.P.dhat, 3).T @ self.force

    def energy(self):
        return [0.0, -self.force @ self.P.r]

    def force_jacobian_q(self):
        """d(Dhat^T F)/dq for the constant F at the point (b1, b2, b3)."""
        s = self.x.s
        c = s["b3"] / (s["alpha"] * s["l"])
        return _square(self.x, _dhat_t_jacobian(("ri", "rj", "u"), c, self.force))


class TorqueKernels(ElementKernels):
    """A constant global torque T: f = Phi_b^T (R^T T) (not conservative: no energy)."""

    def applied_forces(self):
        s = self.x.s
        F = body_frame(*self.x.body_triples(), s["l"], s["alpha"], s["beta"])
        T = np.array([s["Tx"], s["Ty"], s["Tz"]])
        return self.x.columns(F.phi_b, 3).T @ (F.R.T @ T)

    def force_jacobian_q(self):
        """df/dq with f written out per triple: with s_k = T . e_k,
        f_u = s1 e3 / alpha and f_rij = -beta s1 e3 / (alpha l) - s2 e3 / l + s3 e2 / l
        (f_ri = -f_rij, f_rj = f_rij); each product s_k e_j differentiates to
        e_j (T^T de_k) + s_k de_j with the derivatives of e1, e2, e3 below."""
        s = self.x.s
        l, alpha, beta = s["l"], s["alpha"], s["beta"]
        T = np.array([s["Tx"], s["Ty"], s["Tz"]])
        _, (ri, rj, u), _ = self.x.body_triples()
        rij = rj - ri
        e = [rij / l, (u - beta * rij / l) / alpha, cross(rij, u) / (alpha * l)]
        de = {"rij": [EYE / l, -beta / (alpha * l) * EYE, -skew(u) / (alpha * l)],
              "u": [np.zeros((3, 3)), EYE / alpha, skew(rij) / (alpha * l)]}
        blocks = {}
        for var, d in de.items():
            def prod(k, j):          # d(s_k e_j)/d var
                return np.outer(e[j], T @ d[k]) + (T @ e[k]) * d[j]
            f_u = prod(0, 2) / alpha
            f_rij = (-beta / (alpha * l) * prod(0, 2) - prod(1, 2) / l + prod(2, 1) / l)
            cols = {"ri": -1.0, "rj": 1.0} if var == "rij" else {"u": 1.0}
            for col, sign in cols.items():
                blocks[("u", col)] = sign * f_u
                blocks[("ri", col)] = -sign * f_rij
                blocks[("rj", col)] = sign * f_rij
        return _square(self.x, blocks)


class SpringKernels(ElementKernels):
    """A linear spring-damper between ends A and B: tension k (L - L0) + c L'."""

    @cached_property
    def geometry(self):
        A, B = end_point(self.x, "A"), end_point(self.x, "B")
        d = B.r - A.r
        L = float(np.sqrt(d @ d))
        return A, B, L, d / L, (B.v - A.v)

    def applied_forces(self):
        """f = -T (Dhat_B - Dhat_A)^T n."""
        s = self.x.s
        A, B, L, n, dd = self.geometry
        tension = s["k"] * (L - s["L0"]) + s["c"] * (n @ dd)
        blocks = _combine((-tension * n, B.dhat), (tension * n, A.dhat))
        return self.x.columns(blocks, 1).reshape(-1)

    def energy(self):
        s = self.x.s
        L = self.geometry[2]
        return [0.0, 0.5 * s["k"] * (L - s["L0"]) ** 2]

    @cached_property
    def _delta(self) -> np.ndarray:
        """Delta = Dhat_B - Dhat_A (3 x n_q): d' = Delta q'."""
        A, B = self.geometry[:2]
        return self.x.columns(_combine((EYE, B.dhat), (-EYE, A.dhat)), 3)

    def force_jacobian_q(self):
        """With f = -T Delta^T n, n = d / L, P = E - n n^T:
        df/dq = -(Delta^T n) dT/dq - T (Delta^T P Delta / L + H), where
        dT/dq = k n^T Delta + c (d'^T P Delta / L + n^T V); H = d(Delta^T w)/dq and
        V = d(Delta q')/dq hold the q-dependence of the ends' Dhat (body points)."""
        s, x = self.x.s, self.x
        A, B, L, n, dd = self.geometry
        D = self._delta
        P = EYE - np.outer(n, n)
        tension = s["k"] * (L - s["L0"]) + s["c"] * (n @ dd)
        H = (_end_square(x, "B", lambda names, c: _dhat_t_jacobian(names, c, n))
             - _end_square(x, "A", lambda names, c: _dhat_t_jacobian(names, c, n)))
        V = _end_velocity_jacobian(x, "B") - _end_velocity_jacobian(x, "A")
        dT = s["k"] * n @ D + s["c"] * (dd @ P @ D / L + n @ V)
        return -np.outer(D.T @ n, dT) - tension * (D.T @ P @ D / L + H)

    def force_jacobian_v(self):
        """df/dq' = -c (Delta^T n)(n^T Delta): only the damper term reads speeds."""
        Dn = self._delta.T @ self.geometry[3]
        return -self.x.s["c"] * np.outer(Dn, Dn)


def turned(s: dict, prefix: str) -> tuple[float, float]:
    """cos and sin of the initial angle (prefix cos0, sin0) plus the angle reference
    th (prefix cr, sr, its cosine and sine)."""
    c0, s0, cr, sr = (s[prefix + n] for n in ("cos0", "sin0", "cr", "sr"))
    return c0 * cr - s0 * sr, s0 * cr + c0 * sr


class TorsionSpringKernels(ElementKernels):
    """A torsion spring-damper about the shared unit vector u of bodies A and B
    (docs/elements.md), in the variables x = (p_A, p_B, u), which are linear in q:
    p_A = r_ij,A - lA u, p_B = r_ij,B - lB u, so dx/dq = L is constant.

    D = u.(p_A x p_B) (a triple product) and P = p_A.p_B (a dot product) have simple
    gradients and Hessians in x; (C, S) = (P, D) turned back by the initial angle and
    the angle reference th (:func:`turned`), C = c P + s D, S = c D - s P, and the
    deflection phi = th - free + atan2(S, C), counted over turns while the solver
    keeps th at the joint angle of the last accepted state (NumericSolver)."""

    @cached_property
    def x_map(self) -> np.ndarray:
        """L = dx/dq (9 x n_q)."""
        s = self.x.s
        blocks = [{"A.ri": -EYE, "A.rj": EYE, "u": -s["lA"] * EYE},
                  {"B.ri": -EYE, "B.rj": EYE, "u": -s["lB"] * EYE}, {"u": EYE}]
        return np.vstack([self.x.columns(b, 3) for b in blocks])

    @cached_property
    def angle(self):
        """(phi, dphi/dx (9), d2phi/dx2 (9 x 9), x' (9))."""
        s, pos, vel = self.x.s, self.x.pos, self.x.vel
        u = pos["u"]
        pa = pos["A.rj"] - pos["A.ri"] - s["lA"] * u
        pb = pos["B.rj"] - pos["B.ri"] - s["lB"] * u
        x_dot = np.concatenate([vel["A.rj"] - vel["A.ri"] - s["lA"] * vel["u"],
                                vel["B.rj"] - vel["B.ri"] - s["lB"] * vel["u"], vel["u"]])
        Z = np.zeros((3, 3))
        # gradients and Hessians in x = (p_A, p_B, u), blocks in that order
        D = u @ cross(pa, pb)
        dD = np.concatenate([cross(pb, u), cross(u, pa), cross(pa, pb)])
        hD = np.block([[Z, -skew(u), skew(pb)], [skew(u), Z, -skew(pa)],
                       [-skew(pb), skew(pa), Z]])
        P = pa @ pb
        dP = np.concatenate([pb, pa, np.zeros(3)])
        hP = np.block([[Z, EYE, Z], [EYE, Z, Z], [Z, Z, Z]])
        c0, s0 = turned(s, "")
        S, dS, hS = c0 * D - s0 * P, c0 * dD - s0 * dP, c0 * hD - s0 * hP
        C, dC, hC = c0 * P + s0 * D, c0 * dP + s0 * dD, c0 * hP + s0 * hD
        N = S * S + C * C
        g = (C * dS - S * dC) / N
        H = ((np.outer(dS, dC) - np.outer(dC, dS) + C * hS - S * hC) / N
             - np.outer(g, 2.0 * (S * dS + C * dC)) / N)
        return float(s["th"] - s["free"] + np.arctan2(S, C)), g, H, x_dot

    @cached_property
    def _torque(self):
        """(k phi + c phi', dphi/dq)."""
        phi, g, _, x_dot = self.angle
        s = self.x.s
        return s["k"] * phi + s["c"] * (g @ x_dot), self.x_map.T @ g

    def applied_forces(self):
        """f = -(k phi + c phi') dphi/dq."""
        torque, gq = self._torque
        return -torque * gq

    def energy(self):
        return [0.0, 0.5 * self.x.s["k"] * self.angle[0] ** 2]

    def force_jacobian_q(self):
        """df/dq = -L^T g (k g + c H x')^T L - (k phi + c phi') L^T H L."""
        _, g, H, x_dot = self.angle
        s, L = self.x.s, self.x_map
        torque, gq = self._torque
        return -np.outer(gq, L.T @ (s["k"] * g + s["c"] * H @ x_dot)) - torque * L.T @ H @ L

    def force_jacobian_v(self):
        """df/dq' = -c (dphi/dq)(dphi/dq)^T."""
        gq = self._torque[1]
        return -self.x.s["c"] * np.outer(gq, gq)


def _dhat_t_jacobian(names, c: float, w) -> dict[tuple[str, str], np.ndarray]:
    """d(Dhat^T w)/dq at fixed w for the body point with c = b3 / (alpha l) of the
    triples names = (ri, rj, u): Dhat^T w is (1 - b1) w + c w x u on ri,
    b1 w - c w x u on rj and b2 w + c w x r_ij on u, so only c ~w blocks remain.
    Blocks are keyed (row triple, column triple)."""
    ri, rj, u = names
    sw = c * skew(w)
    return {(ri, u): sw, (rj, u): -sw, (u, rj): sw, (u, ri): -sw}


def _velocity_jacobian(names, c: float, vel) -> dict[str, np.ndarray]:
    """d(Dhat q')/dq at fixed q' for a body point: its velocity holds
    c (r_ij' x u + r_ij x u'), whose q-derivatives are c ~r_ij' (on u) and
    -c ~u' (on r_ij)."""
    ri, rj, u = names
    dri, drj, du = vel
    return {u: c * skew(drj - dri), rj: -c * skew(du), ri: c * skew(du)}


def _end_data(x, end: str):
    """(triple names, c, speeds) of a body-point end, or None for a named point."""
    kind = x.cls.ends[KIND_ENDS[x.cls.kind].index(end)]
    if kind == "point":
        return None
    s = x.s
    names, _, vel = x.body_triples(f"{end}.")
    return names, s[f"{end}.b3"] / (s[f"{end}.alpha"] * s[f"{end}.l"]), vel


def _end_square(x, end: str, blocks_of) -> np.ndarray:
    data = _end_data(x, end)
    if data is None:
        return np.zeros((x.cls.n_q, x.cls.n_q))
    return _square(x, blocks_of(data[0], data[1]))


def _end_velocity_jacobian(x, end: str) -> np.ndarray:
    data = _end_data(x, end)
    if data is None:
        return np.zeros((3, x.cls.n_q))
    return x.columns(_velocity_jacobian(*data), 3)


def _square(x, blocks: dict[tuple[str, str], np.ndarray]) -> np.ndarray:
    """An n_q x n_q matrix from 3x3 blocks keyed (row triple, column triple); blocks
    touching a fixed triple are dropped."""
    at = {name: 3 * k for k, name in enumerate(x.cls.moving_triples)}
    out = np.zeros((x.cls.n_q, x.cls.n_q))
    for (r, c), block in blocks.items():
        if r in at and c in at:
            out[at[r]:at[r] + 3, at[c]:at[c] + 3] += block
    return out


def _combine(*terms) -> dict[str, np.ndarray]:
    """Per triple, sum of ``left @ dhat[triple]`` over the (left, dhat) terms."""
    out: dict[str, np.ndarray] = {}
    for left, dhat in terms:
        for name, block in dhat.items():
            out[name] = out.get(name, 0.0) + left @ block
    return out


# -- mechanism level: attached triples, point on a plane, dot product ---------------

class AttachedKernels(ElementKernels):
    """A triple tied to a body: g = r_k - P for a point, g = w - (P - r_i) for a unit
    vector (nu1 e1 + nu2 e2 + nu3 e3 = P - r_i with b = point_coefficients(nu)), where
    P = r_i + b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l) is a body point."""
    target = "k"

    def _rows(self):
        x, s = self.x, self.x.s
        names, pos, vel = x.body_triples()
        P = body_point(names, pos, vel, s["l"], s["alpha"], s["b1"], s["b2"], s["b3"])
        r, dhat = P.r, dict(P.dhat)
        if self.target == "w":
            r = r - pos[0]
            dhat[names[0]] = dhat[names[0]] - EYE
        blocks = {n: -b for n, b in dhat.items()}
        blocks[self.target] = EYE
        g = x.pos[self.target] - r
        return [(g[k], {n: b[k] for n, b in blocks.items()}, -P.bias[k]) for k in range(3)]


class AttachedVectorKernels(AttachedKernels):
    target = "w"


class PointOnPlaneKernels(ElementKernels):
    """n . (r_K - r_A) = 0 for a unit normal triple n."""

    def _rows(self):
        K, A = end_point(self.x, "K"), end_point(self.x, "A")
        n, dn = self.x.pos["n"], self.x.vel["n"]
        d = K.r - A.r
        blocks = _combine((n, K.dhat), (-n, A.dhat))
        blocks["n"] = blocks.get("n", 0.0) + d
        bias = 2.0 * dn @ (K.v - A.v) + n @ (K.bias - A.bias)
        return [(n @ d, blocks, bias)]


class DotKernels(ElementKernels):
    """a . b - c = 0 for unit vector triples a, b (c = cos of their angle)."""

    def _rows(self):
        a, b = self.x.pos["a"], self.x.pos["b"]
        da, db = self.x.vel["a"], self.x.vel["b"]
        return [(a @ b - self.x.s["c"], {"a": b, "b": a}, 2.0 * da @ db)]


class AlignedVectorKernels(ElementKernels):
    """Two of "e1" w.r_ij - c1, "e2" w.u - c2, "e3" w.(r_ij x u) - c3 (the class's
    rows): a unit vector w held along a body vector by two body-frame components
    (c1 = l nu1, c2 = beta nu1 + alpha nu2, c3 = alpha l nu3)."""

    def _rows(self):
        x, s = self.x, self.x.s
        (ni, nj, nu), (ri, rj, u), (dri, drj, du) = x.body_triples()
        w, dw = x.pos["w"], x.vel["w"]
        rij, drij = rj - ri, drj - dri
        rows = {}
        if "c1" in s:
            rows["e1"] = (w @ rij - s["c1"], {ni: -w, nj: w, "w": rij}, 2.0 * dw @ drij)
        if "c2" in s:
            rows["e2"] = (w @ u - s["c2"], {nu: w, "w": u}, 2.0 * dw @ du)
        if "c3" in s:
            n = cross(rij, u)
            uw = cross(u, w)
            rows["e3"] = (w @ n - s["c3"], {ni: -uw, nj: uw, nu: cross(w, rij), "w": n},
                          2.0 * (dw @ cross(drij, u) + dw @ cross(rij, du)
                                 + w @ cross(drij, du)))
        return [rows[r] for r in self.cls.constraint_rows]


MECHANISM_KERNELS: dict[str, type[ElementKernels]] = {
    "attached_point": AttachedKernels, "attached_vector": AttachedVectorKernels,
    "point_on_plane": PointOnPlaneKernels, "dot": DotKernels,
    **{kind: AlignedVectorKernels for kind in ALIGNED_ROWS},
}


KIND_KERNELS: dict[str, type[ElementKernels]] = {
    "body": BodyKernels, "unit_vector": UnitVectorKernels, "distance": DistanceKernels,
    "point_on_line": PointOnLineKernels, "force": ForceKernels, "torque": TorqueKernels,
    "spring": SpringKernels,
    "torsion_spring": TorsionSpringKernels,
}
KIND_KERNELS.update(MECHANISM_KERNELS)


def element_kernels(cls: ElementClass, q, v, p) -> ElementKernels:
    """The kernels object of an element of class ``cls`` at state (q, v)."""
    return KIND_KERNELS[cls.kind](cls, q, v, p)


def element_kernel(cls: ElementClass, name: str, q, v, p) -> np.ndarray | None:
    """Flattened row-major output of kernel ``name`` (same length as
    ``KernelSpec.size(cls)``), or None if the kernel does not apply to the class."""
    return element_kernels(cls, q, v, p).evaluate(name)

