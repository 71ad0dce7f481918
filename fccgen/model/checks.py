"""Physical and geometric rules of a model, as pure functions on numbers.

Each check returns ``None`` when the rule holds and the rule's wording otherwise, so the
loader can raise it against the right item and line.
"""
from __future__ import annotations

import math

import numpy as np

from .fields import MIN_POSITIVE

# |v| of a unit vector must be 1 within this (docs/design.md §2).
UNIT_TOLERANCE = 1e-9
# Points i, j of a body coincide when |r_ij| <= this * max(1, |r_i|, |r_j|): a few
# thousand roundings of the positions, far below any real body's size.
COINCIDE_RELATIVE = 1e-12
# u is too nearly parallel to r_ij when sin(angle) is below this. The spin about r_ij
# reaches u's motion scaled by sin(gamma), so the mass matrix in FCC coordinates has a
# condition number ~1/sin^2(gamma) and rounding grows like 50 eps / sin^2(gamma)
# (measured, independent of the step: 1.5e-9 m at 1e-3, 1e-6 m at 1e-4, 1e-3 m at 1e-6;
# docs/extremes.md). 1e-3 keeps that below the 1e-9 level the tests hold solvers to.
PARALLEL_SIN = 1e-3
# The triangle inequality of principal moments holds within this relative tolerance
# (a planar lamina sits exactly on the boundary, I3 = I1 + I2).
TRIANGLE_RELATIVE = 1e-9
# A principal moment counts as zero when below this times the largest one: eigvalsh
# rounds at ~1e-16 relative, so this separates rounding from a real moment.
DEFINITE_RELATIVE = 1e-12


def _fmt(values) -> str:
    return ", ".join(f"{float(x):.10g}" for x in values)


def unit_vector_problem(v: np.ndarray) -> str | None:
    """Rule broken by a vector that should have length 1, or None."""
    norm = float(np.linalg.norm(v))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        return f"must be a unit vector (|v| = 1 within {UNIT_TOLERANCE:g}); |v| = {norm:.17g}"
    return None


def inertia_tensor(values: np.ndarray) -> np.ndarray:
    """Symmetric 3x3 tensor from 3 principal values or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]."""
    values = np.asarray(values, dtype=float)
    if values.shape == (3,):
        return np.diag(values)
    if values.shape == (6,):
        ixx, iyy, izz, ixy, ixz, iyz = values
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    raise ValueError(f"inertia needs 3 or 6 numbers, got {values.shape}")


def inertia_problem(tensor: np.ndarray) -> str | None:
    """Rule broken by an inertia tensor, or None.

    The all-zero tensor is a point mass and is accepted; otherwise the tensor must be
    positive definite and its principal moments must satisfy the triangle inequality
    (each at most the sum of the other two), as every rigid body's do.
    """
    if not np.any(tensor):
        return None
    moments = np.linalg.eigvalsh(tensor)
    if 0 < moments[-1] < MIN_POSITIVE:
        return (f"must have a principal moment of at least {MIN_POSITIVE:g} unless all "
                f"zero (fccgen's limit on a positive quantity); they are {_fmt(moments)}")
    if moments[0] <= DEFINITE_RELATIVE * abs(moments[-1]):
        return ("must be positive definite (or all zero for a point mass); "
                f"its principal moments are {_fmt(moments)}")
    total = float(moments.sum())
    for k in range(3):
        if moments[k] - (total - moments[k]) > TRIANGLE_RELATIVE * total:
            return (f"principal moments {_fmt(moments)} break the triangle inequality "
                    "(each must be at most the sum of the other two)")
    return None


def coincide(ri: np.ndarray, rj: np.ndarray) -> bool:
    """True when a body's points i and j are at the same place."""
    scale = max(1.0, float(np.linalg.norm(ri)), float(np.linalg.norm(rj)))
    return float(np.linalg.norm(rj - ri)) <= COINCIDE_RELATIVE * scale


def parallel_angle(ri: np.ndarray, rj: np.ndarray, u: np.ndarray) -> float | None:
    """Angle in degrees between r_ij and u when they are (nearly) parallel, else None."""
    rij = rj - ri
    e1 = rij / np.linalg.norm(rij)
    sin = float(np.linalg.norm(np.cross(e1, u)))
    if sin < PARALLEL_SIN:
        return math.degrees(math.atan2(sin, float(e1 @ u)))
    return None
