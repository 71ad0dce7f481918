"""Body-frame numbers of a typical body (docs/design.md §1): l, alpha, beta and the
coefficients that place a body point, computed from the initial positions."""
from __future__ import annotations

import numpy as np


def body_frame_numbers(ri, rj, u) -> tuple[float, float, float]:
    """Return (l, alpha, beta): l = |r_ij|, beta = cos(gamma), alpha = sin(gamma) > 0."""
    rij = np.asarray(rj, float) - np.asarray(ri, float)
    l = float(np.linalg.norm(rij))
    e1 = rij / l
    u = np.asarray(u, float)
    beta = float(e1 @ u)
    # |e1 x u| is accurate for small angles where sqrt(1 - beta^2) is not.
    alpha = float(np.linalg.norm(np.cross(e1, u)))
    return l, alpha, beta


def point_coefficients(rho, l: float, alpha: float, beta: float) -> tuple[float, float, float]:
    """Coefficients (a1, a2, a3) of a body point with body-frame coordinates rho
    (from point i): r = r_i + a1 r_ij + a2 u + a3 (r_ij x u) / (alpha l)."""
    r1, r2, r3 = (float(x) for x in rho)
    return (r1 - r2 * beta / alpha) / l, r2 / alpha, r3


def body_rotation(ri, rj, u) -> np.ndarray:
    """R = [e1 e2 e3] (columns) of the body frame at the given positions."""
    rij = np.asarray(rj, float) - np.asarray(ri, float)
    e1 = rij / np.linalg.norm(rij)
    e3 = np.cross(e1, np.asarray(u, float))
    e3 /= np.linalg.norm(e3)
    e2 = np.cross(e3, e1)
    return np.column_stack([e1, e2, e3])
