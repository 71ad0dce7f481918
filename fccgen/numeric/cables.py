"""NumPy kernels of flexible members (fccgen.plan.cable_kinds, docs/flexible.md),
registered in :data:`fccgen.numeric.elements.KIND_KERNELS` when the package is
imported. Written from the formulation, independently of the symbolic path: every
integral over an element (mass and loads too) by Gauss quadrature of the shape
functions, and the derivatives of the strain energy and the dissipation worked out by
hand in vector form:

    a = r', b = r'', s = |a|, n = a / s, eps = s - 1,  c = a x b, phi = s^-3, k = phi c

    d eps/da = n,             d2 eps/da2 = (E - n n^T) / s,     eps' = n . a'
    dk/da = -phi ~b + c (dphi/da)^T,  dk/db = phi ~a,  dphi/da = -3 s^-5 a,
    d2 k_i/da2 = dc_i (dphi)^T + dphi dc_i^T + c_i (-3 s^-5 E + 15 s^-7 a a^T),
    d2 k_i/da_j db_l = phi eps_ijl + (dphi/da_j) (dc_i/db_l),   d2 k_i/db2 = 0

(dc_i the gradient of c_i in a, i.e. row i of -~b). Energy per length
EA eps^2 / 2 + EI k.k / 2; dissipation c (EA (a.a')^2 + EI |c'|^2) / 2 with
c' = a' x b + a x b' = Jc x', Jc = [-~b, ~a] = d(a x b)/d(a, b).
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from ..plan.cable_kinds import CABLE_TRIPLES, GAUSS_POINTS
from .elements import KIND_KERNELS, ElementKernels
from .kinematics import EYE, cross, skew
from .mechanism_kernels import _TimedLoad

# Levi-Civita symbol eps_ijk
LEVI = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    LEVI[_i, _j, _k], LEVI[_i, _k, _j] = 1.0, -1.0
MASS_POINTS = 4                  # exact for the degree-6 products S_i S_j


def gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights of the n-point Gauss-Legendre rule on [0, 1]."""
    t, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (1.0 + t), 0.5 * w


def hermite(xi: float, L: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(S, dS/dx, d2S/dx2) of the four cubic Hermite functions at xi = x / L."""
    S = np.array([1 - 3 * xi ** 2 + 2 * xi ** 3, L * (xi - 2 * xi ** 2 + xi ** 3),
                  3 * xi ** 2 - 2 * xi ** 3, L * (xi ** 3 - xi ** 2)])
    dS = np.array([6 * (xi ** 2 - xi) / L, 1 - 4 * xi + 3 * xi ** 2,
                   6 * (xi - xi ** 2) / L, 3 * xi ** 2 - 2 * xi])
    ddS = np.array([(12 * xi - 6) / L ** 2, (6 * xi - 4) / L,
                    (6 - 12 * xi) / L ** 2, (6 * xi - 2) / L])
    return S, dS, ddS


def density(a, b, ad, bd, EA, EI, c):
    """(u, g, H, C) at one point: energy density u, the force density g = du/dx +
    dD/dx' (6), H = dg/dx (6 x 6) and C = dg/dx' (6 x 6), x = (a, b)."""
    s = float(np.sqrt(a @ a))
    n, eps = a / s, s - 1.0
    P = (EYE - np.outer(n, n)) / s                       # d2 eps / da2
    cv, phi = cross(a, b), s ** -3
    dphi = -3.0 * s ** -5 * a
    d2phi = -3.0 * s ** -5 * EYE + 15.0 * s ** -7 * np.outer(a, a)
    k = phi * cv
    dc_a = -skew(b)                                      # rows: gradients of c_i in a
    J = np.hstack([phi * dc_a + np.outer(cv, dphi), phi * skew(a)])
    Hk = np.zeros((3, 6, 6))                             # d2 k_i / dx2
    for i in range(3):
        Hk[i, :3, :3] = (np.outer(dc_a[i], dphi) + np.outer(dphi, dc_a[i])
                         + cv[i] * d2phi)
        Hk[i, :3, 3:] = phi * LEVI[i] + np.outer(dphi, skew(a)[i])
        Hk[i, 3:, :3] = Hk[i, :3, 3:].T
    u = 0.5 * EA * eps ** 2 + 0.5 * EI * k @ k
    g = np.concatenate([EA * eps * n, np.zeros(3)]) + EI * J.T @ k
    H = EI * (J.T @ J + np.einsum("i,imn->mn", k, Hk))
    H[:3, :3] += EA * (np.outer(n, n) + eps * P)
    C = np.zeros((6, 6))
    if c != 0.0:
        # e' = a.a' (Green strain rate), c' = Jc x' with Jc = d(a x b)/d(a, b)
        Jc = np.hstack([-skew(b), skew(a)])
        e_dot, c_dot = a @ ad, Jc @ np.concatenate([ad, bd])
        g[:3] += c * EA * e_dot * a
        g += c * EI * Jc.T @ c_dot
        H[:3, :3] += c * EA * (np.outer(a, ad) + e_dot * EYE)
        # d(Jc^T c')/dx = sum_i c'_i d2c_i/dx2 + Jc^T dc'/dx; d2c_i/da_j db_k = eps_ijk
        E = np.einsum("i,ijk->jk", c_dot, LEVI)
        H += c * EI * (np.block([[np.zeros((3, 3)), E], [E.T, np.zeros((3, 3))]])
                       + Jc.T @ np.hstack([-skew(bd), skew(ad)]))
        C[:3, :3] = c * EA * np.outer(a, a)
        C += c * EI * Jc.T @ Jc
    return u, g, H, C


class CableKernels(ElementKernels):
    """One ANCF cable element (module docstring); the 12 element coordinates are
    (r1, d1, r2, d2), of which the moving ones are the local coordinates."""

    @cached_property
    def _e(self):
        x = self.x
        e = np.concatenate([x.pos[n] for n in CABLE_TRIPLES])
        ev = np.concatenate([x.vel[n] for n in CABLE_TRIPLES])
        moving = [3 * j + k for j, n in enumerate(CABLE_TRIPLES)
                  if n in x.cls.moving_triples for k in range(3)]
        return e, ev, np.array(moving, dtype=np.intp)

    def _load(self) -> np.ndarray:
        s = self.x.s
        return np.array([s["rhoA"] * s[f"g{c}"] + s[f"q{c}"] for c in "xyz"])

    @cached_property
    def _mass_full(self) -> np.ndarray:
        s = self.x.s
        M = np.zeros((12, 12))
        for xi, w in zip(*gauss(MASS_POINTS)):
            N = np.kron(hermite(xi, s["L"])[0], EYE)          # 3 x 12
            M += w * N.T @ N
        return s["rhoA"] * s["L"] * M

    @cached_property
    def _external(self) -> np.ndarray:
        """int S^T (rhoA g + q) dx (12)."""
        s = self.x.s
        f = np.zeros(12)
        for xi, w in zip(*gauss(MASS_POINTS)):
            f += w * np.kron(hermite(xi, s["L"])[0], EYE).T @ self._load()
        return s["L"] * f

    @cached_property
    def _internal(self):
        """(strain energy, f, df/dq, df/dq') of the elastic and damping forces (12)."""
        s = self.x.s
        e, ev, _ = self._e
        U, f, K, C = 0.0, np.zeros(12), np.zeros((12, 12)), np.zeros((12, 12))
        for xi, w in zip(*gauss(GAUSS_POINTS)):
            _, dS, ddS = hermite(xi, s["L"])
            G = np.vstack([np.kron(dS, EYE), np.kron(ddS, EYE)])   # d(a, b)/de, 6 x 12
            x, xd = G @ e, G @ ev
            u, g, H, Cx = density(x[:3], x[3:], xd[:3], xd[3:], s["EA"], s["EI"], s["c"])
            wl = w * s["L"]
            U += wl * u
            f -= wl * G.T @ g
            K -= wl * G.T @ H @ G
            C -= wl * G.T @ Cx @ G
        return U, f, K, C

    def mass_matrix(self):
        m = self._e[2]
        return self._mass_full[np.ix_(m, m)]

    def applied_forces(self):
        return (self._internal[1] + self._external)[self._e[2]]

    def force_jacobian_q(self):
        m = self._e[2]
        return self._internal[2][np.ix_(m, m)]

    def force_jacobian_v(self):
        m = self._e[2]
        return self._internal[3][np.ix_(m, m)]

    def energy(self):
        e, ev, _ = self._e
        return [0.5 * ev @ self._mass_full @ ev, self._internal[0] - self._external @ e]


class SlopeNormalKernels(ElementKernels):
    """d . n = 0 for a slope d and a unit vector n (a clamp row)."""

    def _rows(self):
        d, n = self.x.pos["d"], self.x.pos["n"]
        dd, dn = self.x.vel["d"], self.x.vel["n"]
        return [(d @ n, {"d": n, "n": d}, 2.0 * dd @ dn)]


class PointForceKernels(ElementKernels):
    """A constant force F on a point r: f = F, potential -F . r."""

    @property
    def force(self) -> np.ndarray:
        s = self.x.s
        return np.array([s["Fx"], s["Fy"], s["Fz"]])

    def applied_forces(self):
        return self.x.columns({"r": EYE}, 3).T @ self.force

    def energy(self):
        return [0.0, -self.force @ self.x.pos["r"]]

    def force_jacobian_q(self):
        return np.zeros((self.cls.n_q, self.cls.n_q))


class PointForceTKernels(_TimedLoad, PointForceKernels):
    """f = F(t) on the point (no potential)."""
    names = ("Fx", "Fy", "Fz")


KIND_KERNELS.update({"cable": CableKernels, "slope_normal": SlopeNormalKernels,
                     "point_force": PointForceKernels, "point_force_t": PointForceTKernels})
