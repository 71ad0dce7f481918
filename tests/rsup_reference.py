"""A minimal-coordinate reference for the spatial slider-crank examples/rsup.yaml:
one degree of freedom, the crank angle theta, by the energy equation

    M(theta) theta'^2 / 2 + V(theta) = E0,   so   theta' = sqrt(2 (E0 - V) / M)

while the crank turns one way (it does: theta' > 5.4 rad/s throughout the first 2 s),
with T = M theta'^2 / 2 and V written out by hand with SymPy (independent of fccgen's
FCC equations):

* crank pin B = O + Lc (0, -sin theta, cos theta) (theta about +x, 0 as written);
* slider joint C = (s, 0, 0), s = sqrt(Lr^2 - B_y^2 - B_z^2) (the written branch s > 0);
* rod direction d = (C - B) / Lr; the rod's body vector a1 (the universal joint's rod
  axis, (0, 0, 1) as written) keeps a1.d = c0 = -2/3 and stays perpendicular to the
  slider's axis y: a1 = (cos psi, 0, sin psi), psi = beta + acos(c0 / rho) with
  (d_x, d_z) = rho (cos beta, sin beta); the rod frame R = [d, n, d x n],
  n = (a1 - c0 d) / |a1 - c0 d|, and omega = vee(R' R^T) theta';
* the rod's inertia is axisymmetric about d: omega.I omega = I_t |omega|^2 -
  (I_t - I_a) (omega.d)^2.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

O = (0.0, 0.1, 0.12)
LC, LR = 0.08, 0.3
M_CRANK, M_ROD, M_SLIDER = 0.12, 0.5, 2.0
I_CRANK_AXIS = 1.0e-5                 # about the crank's body z = the hinge axis
CRANK_CENTRE = 0.04                   # from the hinge along the crank
I_ROD_AXIAL, I_ROD = 5.0e-5, 3.75e-3
G = 9.81


def energy_terms():
    """(M, V) as functions of theta (floats)."""
    th = sp.symbols("theta")
    B = sp.Matrix([O[0], O[1] - LC * sp.sin(th), O[2] + LC * sp.cos(th)])
    s = sp.sqrt(LR ** 2 - B[1] ** 2 - B[2] ** 2)
    C = sp.Matrix([s, 0, 0])
    d = (C - B) / LR
    c0 = sp.Rational(-2, 3)
    rho = sp.sqrt(d[0] ** 2 + d[2] ** 2)
    psi = sp.atan2(d[2], d[0]) + sp.acos(c0 / rho)
    a1 = sp.Matrix([sp.cos(psi), 0, sp.sin(psi)])
    n = a1 - c0 * d
    n = n / sp.sqrt(n.dot(n))
    R = sp.Matrix.hstack(d, n, d.cross(n))
    W = R.diff(th) * R.T                              # omega per unit theta' (skew)
    w = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
    v_rod = ((B + C) / 2).diff(th)
    M = (I_CRANK_AXIS + M_CRANK * CRANK_CENTRE ** 2 + M_ROD * v_rod.dot(v_rod)
         + I_ROD * w.dot(w) - (I_ROD - I_ROD_AXIAL) * w.dot(d) ** 2
         + M_SLIDER * s.diff(th) ** 2)
    V = G * (M_CRANK * (O[2] + CRANK_CENTRE * sp.cos(th)) + M_ROD * (B[2] + C[2]) / 2)
    return sp.lambdify(th, M, "math", cse=True), sp.lambdify(th, V, "math", cse=True)


def crank_angle(rate0: float, t_eval: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta, theta') at t_eval from theta = 0, theta' = rate0: the energy equation
    integrated by DOP853 at rtol = atol = 1e-13."""
    from scipy.integrate import solve_ivp
    M, V = energy_terms()
    energy = 0.5 * M(0.0) * rate0 ** 2 + V(0.0)

    def rate(_, y):
        return [np.sqrt(2.0 * (energy - V(y[0])) / M(y[0]))]
    sol = solve_ivp(rate, (0.0, float(t_eval[-1])), [0.0], method="DOP853", rtol=1e-13,
                    atol=1e-13, t_eval=t_eval)
    theta = sol.y[0]
    return theta, np.array([rate(0.0, [x])[0] for x in theta])
