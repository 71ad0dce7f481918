"""Reference solutions in minimal coordinates, independent of fccgen.

Each function integrates equations of motion derived by hand (Lagrange's equations in
joint angles or Euler angles; the derivations are in the docstrings) with SciPy's
DOP853 at rtol = atol = 1e-12. Parameters are plain numbers, so a test can feed the
values of an example model file and compare the two formulations.

Conventions: planar pendulums swing in the x-y plane with gravity along -y; angles are
measured from the downward vertical (-y), positive counter-clockwise about +z. The top
(spherical pendulum) has gravity along -z and z-x-z Euler angles.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

RTOL = ATOL = 1e-12


def integrate(rhs, y0, t):
    """Integrate y' = rhs(t, y) from t[0] and return the states at the times t
    (shape (len(t), len(y0))); raises if the integrator fails."""
    t = np.asarray(t, float)
    sol = solve_ivp(rhs, (t[0], t[-1]), np.asarray(y0, float), method="DOP853",
                    t_eval=t, rtol=RTOL, atol=ATOL)
    if sol.status != 0:
        raise RuntimeError(f"integration failed: {sol.message}")
    return sol.y.T


# -- simple pendulum -------------------------------------------------------------------

def simple_pendulum(L, g, theta0, omega0, t):
    """Point mass on a massless rod of length L about a fixed pivot at the origin.

    theta'' = -(g / L) sin(theta); x = L sin(theta), y = -L cos(theta).
    Returns (x, y), arrays over t.
    """
    theta = simple_pendulum_states(L, g, theta0, omega0, t)[:, 0]
    return L * np.sin(theta), -L * np.cos(theta)


def simple_pendulum_states(L, g, theta0, omega0, t):
    """The angle and angular rate of :func:`simple_pendulum`, shape (len(t), 2)."""
    return integrate(lambda _t, s: [s[1], -g / L * np.sin(s[0])], [theta0, omega0], t)


# -- double pendulum (compound, two rods) --------------------------------------------------

def _double_pendulum_matrices(p, th, w):
    """Mass matrix and right-hand side of the double pendulum's Lagrange equations.

    Rod k has length Lk, mass mk, mass centre at distance ck from its upper joint on
    the rod's axis, inertia Ik about its mass centre (about z). With absolute angles
    th1, th2 and d = th1 - th2:
        T = (m1 c1^2 + I1 + m2 L1^2) th1'^2 / 2 + (m2 c2^2 + I2) th2'^2 / 2
            + m2 L1 c2 cos(d) th1' th2'
        V = -(m1 c1 + m2 L1) g cos(th1) - m2 c2 g cos(th2)
    which gives M th'' = rhs below.
    """
    m1, m2, c1, c2 = p["m1"], p["m2"], p["c1"], p["c2"]
    L1, g = p["L1"], p["g"]
    d = th[0] - th[1]
    k = m2 * L1 * c2
    M = np.array([[m1 * c1**2 + p["I1"] + m2 * L1**2, k * np.cos(d)],
                  [k * np.cos(d), m2 * c2**2 + p["I2"]]])
    rhs = np.array([-k * np.sin(d) * w[1]**2 - (m1 * c1 + m2 * L1) * g * np.sin(th[0]),
                    k * np.sin(d) * w[0]**2 - m2 * c2 * g * np.sin(th[1])])
    return M, rhs


def double_pendulum_states(params, theta0, omega0, t):
    """Angles and rates [th1, th2, w1, w2] over t (see :func:`double_pendulum`)."""
    def rhs(_t, s):
        M, f = _double_pendulum_matrices(params, s[:2], s[2:])
        return np.concatenate([s[2:], np.linalg.solve(M, f)])
    return integrate(rhs, [*theta0, *omega0], t)


def double_pendulum(params, theta0, omega0, t):
    """Compound double pendulum: rod 1 from a fixed pivot at the origin to joint P1,
    rod 2 from P1 to its tip P2, both hinged about z, gravity g along -y.

    params: dict with L1, m1, c1, I1, L2, m2, c2, I2, g (L2 places the tip; ck is the
    distance of rod k's mass centre from its upper joint; Ik its inertia about the
    mass centre). theta0, omega0: absolute angles from the downward vertical and their
    rates. Returns (p1, p2), the positions of P1 and P2, each of shape (len(t), 2).
    """
    s = double_pendulum_states(params, theta0, omega0, t)
    th1, th2 = s[:, 0], s[:, 1]
    p1 = params["L1"] * np.column_stack([np.sin(th1), -np.cos(th1)])
    p2 = p1 + params["L2"] * np.column_stack([np.sin(th2), -np.cos(th2)])
    return p1, p2


def double_pendulum_energy(params, states):
    """Total energy T + V along rows of states [th1, th2, w1, w2] (zero potential at
    the pivot's height)."""
    s = np.atleast_2d(states)
    out = np.empty(len(s))
    for n, row in enumerate(s):
        M, _ = _double_pendulum_matrices(params, row[:2], row[2:])
        T = 0.5 * row[2:] @ M @ row[2:]
        V = -(params["m1"] * params["c1"] + params["m2"] * params["L1"]) * params["g"] \
            * np.cos(row[0]) - params["m2"] * params["c2"] * params["g"] * np.cos(row[1])
        out[n] = T + V
    return out


# -- heavy symmetric top with a fixed point (Lagrange top) --------------------------------

def _top_constants(p):
    """(A, C, m g d): transverse inertia about the fixed point, axial inertia, and the
    gravity moment coefficient."""
    return p["It"] + p["m"] * p["d"] ** 2, p["Ia"], p["m"] * p["g"] * p["d"]


def _top_rhs(p):
    """Lagrange's equations of the top in z-x-z Euler angles (theta, phi, psi).

    The symmetry axis is e = (sin th sin ph, -sin th cos ph, cos th); the mass centre is
    at distance d along e from the fixed point O, gravity g along -z. With
    A = It + m d^2, C = Ia and the spin w3 = psi' + phi' cos th:
        L = A (th'^2 + phi'^2 sin^2 th) / 2 + C w3^2 / 2 - m g d cos th.
    theta:  A th'' = sin th (A phi'^2 cos th - C w3 phi' + m g d)
    phi:    p_phi = A phi' sin^2 th + C w3 cos th is constant, so
            phi'' = th' (C w3 - 2 A phi' cos th) / (A sin th)
    psi:    w3 is constant, so psi'' = -(phi'' cos th - phi' th' sin th).
    Singular only where sin th = 0 (axis vertical), which the tests avoid.
    """
    A, C, mgd = _top_constants(p)

    def rhs(_t, s):
        th, _ph, _ps, dth, dph, dps = s
        w3 = dps + dph * np.cos(th)
        ddth = np.sin(th) * (A * dph**2 * np.cos(th) - C * w3 * dph + mgd) / A
        ddph = dth * (C * w3 - 2 * A * dph * np.cos(th)) / (A * np.sin(th))
        ddps = -(ddph * np.cos(th) - dph * dth * np.sin(th))
        return [dth, dph, dps, ddth, ddph, ddps]
    return rhs


def top_axis_and_omega(states):
    """Symmetry axis e and angular velocity w (global frame) for rows of Euler states
    [th, ph, ps, th', ph', ps']: w = ph' z + th' n + ps' e, n = (cos ph, sin ph, 0)."""
    s = np.atleast_2d(states)
    th, ph, dth, dph, dps = s[:, 0], s[:, 1], s[:, 3], s[:, 4], s[:, 5]
    e = np.column_stack([np.sin(th) * np.sin(ph), -np.sin(th) * np.cos(ph), np.cos(th)])
    n = np.column_stack([np.cos(ph), np.sin(ph), np.zeros_like(ph)])
    w = dth[:, None] * n + dps[:, None] * e
    w[:, 2] += dph
    return e, w


def top_state(axis, omega):
    """Euler state [th, ph, ps, th', ph', ps'] (ps = 0) of a top whose symmetry axis is
    the unit vector ``axis`` and whose angular velocity is ``omega`` (global frame)."""
    e = np.asarray(axis, float) / np.linalg.norm(axis)
    th = np.arccos(np.clip(e[2], -1.0, 1.0))
    ph = np.arctan2(e[0], -e[1])
    n = np.array([np.cos(ph), np.sin(ph), 0.0])
    rates = np.linalg.solve(np.column_stack([[0.0, 0.0, 1.0], n, e]), np.asarray(omega, float))
    return np.array([th, ph, 0.0, rates[1], rates[0], rates[2]])


def spherical_top(params, state0, t):
    """Heavy axisymmetric body pivoting about a fixed point O at the origin.

    params: dict with m, d (mass centre on the axis, distance from O), L (distance of
    the tip P from O on the axis), It (central transverse inertia), Ia (axial inertia),
    g (gravity along -z). state0: Euler state (see :func:`top_state`).
    Returns (tip, omega, states): tip positions and angular velocities (global frame),
    each (len(t), 3), and the Euler states (len(t), 6).
    """
    states = integrate(_top_rhs(params), state0, t)
    e, w = top_axis_and_omega(states)
    return params["L"] * e, w, states


def top_invariants(params, axis, omega):
    """Energy, angular momentum about O along z, and spin w . e for rows of axis e and
    angular velocity w, computed from the vectors (not from Euler angles)."""
    A, C, mgd = _top_constants(params)
    e, w = np.atleast_2d(axis), np.atleast_2d(omega)
    spin = np.sum(w * e, axis=1)
    H = A * (w - spin[:, None] * e) + C * spin[:, None] * e
    energy = 0.5 * np.sum(w * H, axis=1) + mgd * e[:, 2]
    return energy, H[:, 2], spin
