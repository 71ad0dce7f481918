"""Linearized equations of motion in independent coordinates (docs/linearization.md).

About a consistent state (q*, v*) (g(q*) = 0, B(q*) v* = 0) the coordinates are
z = N^T (q - q*), z' = N^T q', with N an orthonormal basis of ker B(q*) and Y one of
its row space; the dependent part Y^T (q - q*) follows from g(q) = 0 and
Y^T q' from B(q) q' = 0. In these coordinates z'' = N^T q'' exactly, and

    M_r dz'' + C_r dz' + K_r dz = 0,      A = [[0, I], [-M_r^-1 K_r, -M_r^-1 C_r]],

    M_r = N^T M N,
    K_r = N^T (R_q N + R_v V_z + M Y A_z),   C_r = N^T (R_v N + M Y A_zd),

with a* = q''(q*, v*), lambda* its (minimum-norm) multipliers and

    R_q = d(M a* + h)/dq - df/dq + sum_k lambda*_k Hess(g_k),   R_v = dh/dq' - df/dq',
    V_z = -Y (B Y)^+ d(B v*)/dq N                  (the dependent speeds' change),
    A_z = -(B Y)^+ (d(B a* + Bdot v*)/dq N + d(Bdot v)/dq' V_z),
    A_zd = -(B Y)^+ d(Bdot v)/dq' N                (the dependent accelerations' change).

About an equilibrium (v* = 0, a* = 0) everything but K_r = N^T (H - K_f) N and
C_r = -N^T (df/dq') N vanishes exactly. The curvature H, d(B v)/dq, d(B a)/dq and the
v-derivatives of h and Bdot v are central differences that are exact (the differenced
functions are affine or quadratic in their argument, see :mod:`.tangent`); only
d(M a* + h)/dq, which matters away from equilibrium, uses the cube-root step.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runs.explain import explained
from ..errors import SimulationError
from .tangent import (amax, bases, central_jacobian, cube_root_step, curvature,
                      min_norm_multipliers, step_size)


@dataclass
class Linearization:
    """The linearized motion about (q, v) in the coordinates z = N^T (q - lin.q)."""
    q: np.ndarray
    v: np.ndarray
    null_basis: np.ndarray        # N (n_q x dof): mode shapes in q are N times z-vectors
    range_basis: np.ndarray       # Y (n_q x rank)
    M_r: np.ndarray
    C_r: np.ndarray
    K_r: np.ndarray

    @property
    def dof(self) -> int:
        return self.null_basis.shape[1]

    @property
    def A(self) -> np.ndarray:
        """State matrix of x = (z, z'): x' = A x."""
        n = self.dof
        Minv = np.linalg.solve(self.M_r, np.hstack([self.K_r, self.C_r]))
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Minv[:, :n], -Minv[:, n:]]])


def linearize(solver, q, v=None) -> Linearization:
    """The linearized equations of motion about the consistent state (q, v) (v None:
    at rest). Raises SimulationError when the reduced mass matrix is singular."""
    q = np.asarray(q, float)
    v = np.zeros(solver.n_q) if v is None else np.asarray(v, float)
    N, Y, _ = bases(solver, q)
    M = solver.mass_matrix(q)
    M_r = N.T @ M @ N
    _check_inertia(solver, M_r, q)
    B = solver.constraint_jacobian(q)
    a = np.asarray(solver.accelerations(q, v), float)
    lam = min_norm_multipliers(B, solver.applied_forces(q, v) - solver.h_vector(q, v)
                               - M @ a)
    hq, hv = step_size(q, solver.length_scale), step_size(v, 1.0)
    R_q = curvature(solver, q, lam) - solver.force_jacobian_q(q, v)
    if amax(v) > 0.0 or amax(a) > 0.0:
        R_q += central_jacobian(lambda x: solver.mass_matrix(x) @ a + solver.h_vector(x, v),
                                q, cube_root_step(q, solver.length_scale))
    R_v = central_jacobian(lambda x: solver.h_vector(q, x), v, hv) - \
        solver.force_jacobian_v(q, v)
    P = np.linalg.pinv(B @ Y) if Y.shape[1] else np.zeros((0, B.shape[0]))
    bias_v = central_jacobian(lambda x: solver.constraint_bias(q, x), v, hv)
    V_z = -Y @ P @ central_jacobian(lambda x: solver.constraint_jacobian(x) @ v, q, hq) @ N
    S_q = central_jacobian(lambda x: solver.constraint_jacobian(x) @ a
                           + solver.constraint_bias(x, v), q, hq)
    A_z = -P @ (S_q @ N + bias_v @ V_z)
    A_zd = -P @ bias_v @ N
    K_r = N.T @ (R_q @ N + R_v @ V_z + M @ Y @ A_z)
    C_r = N.T @ (R_v @ N + M @ Y @ A_zd)
    return Linearization(q=q, v=v, null_basis=N, range_basis=Y, M_r=M_r, C_r=C_r, K_r=K_r)


def _check_inertia(solver, M_r, q) -> None:
    """Refuse a reduced mass matrix that is singular: its diagonal-scaled form
    D^-1/2 M_r D^-1/2 (independent of the units of each z) has an eigenvalue at or
    below 1e-12 of its largest, or a diagonal entry is not positive."""
    if not M_r.size:
        return
    d = np.diag(M_r)
    ok = bool(np.all(d > 0.0))
    if ok:
        s = 1.0 / np.sqrt(d)
        eig = np.linalg.eigvalsh(0.5 * (M_r + M_r.T) * np.outer(s, s))
        ok = eig[0] > 1e-12 * eig[-1]
    if not ok:
        raise explained(SimulationError("the reduced mass matrix N^T M N is singular: a "
                                        "motion without inertia (a massless body, or "
                                        "mass with no inertia about a free axis); modes "
                                        "are not defined"), solver, q)


def state_from_z(lin: Linearization, solver, z, zdot, tol=1e-13, max_iterations=30):
    """The consistent state (q, q') with N^T (q - q*) = z and N^T q' = z' (so that
    z = 0, z' = N^T v* gives back (q*, v*)): Newton on g(q* + N z + Y w) = 0 for w,
    to max |g_k| / ||B_k|| <= tol times the largest body length, then
    B(q) (N z' + Y s) = 0 for s (least squares)."""
    N, Y = lin.null_basis, lin.range_basis
    q = lin.q + N @ z
    for _ in range(max_iterations):
        g, B = solver.constraints(q), solver.constraint_jacobian(q)
        norms = np.linalg.norm(B, axis=1)
        if amax(g / np.where(norms > 0.0, norms, 1.0)) <= tol * solver.length_scale:
            break
        q = q + Y @ np.linalg.lstsq(B @ Y, -g, rcond=1e-10)[0]
    else:
        raise SimulationError("state_from_z: the dependent coordinates did not converge")
    B = solver.constraint_jacobian(q)
    v = N @ zdot
    v = v - Y @ np.linalg.lstsq(B @ Y, B @ v, rcond=1e-10)[0]
    return q, v
