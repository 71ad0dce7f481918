"""A pose-form body as a typical body (docs/design.md sections 1 and 2b): the choice of its
points i, j and vector u among the triples its joints give it, and its mass terms in
the FCC body frame that choice defines.

* i, j: the first carried point and the carried point farthest from it; with a single
  point (or all at one place), the mass centre; if that coincides too, or the body
  carries no point, a point offset from i along the body axis x by the body's radius
  of gyration (1 if it has no inertia).
* u: a carried vector at least :data:`GOOD_SIN` away from parallel to r_ij, preferring
  a fixed one, then one that no body chosen earlier uses as u (a vector that is some
  body's u needs no attachment rows to that body); else the body axis (x, y, z) most
  nearly perpendicular to r_ij.
* inertia: I_fcc = R^T F I F^T R with F the pose frame and R = [e1 e2 e3] at the
  initial configuration; the centre: rho_G = R^T (c - r_i); a shape's axes (rows,
  pose frame) a_fcc = R^T F a.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..model import checks
from ..model.types import Body, PoseBody
from ..model.geometry import body_rotation

# sin(angle between u and r_ij) below which a carried vector is not taken as u: the
# mass matrix's condition grows like 1/sin^2 (fccgen.model.checks.PARALLEL_SIN).
GOOD_SIN = 0.1


@dataclass
class Choice:
    """Names chosen for a body's i, j, u and the new triples the choice needs:
    (name, kind, initial value)."""
    i: str
    j: str
    u: str
    new: list[tuple[str, str, np.ndarray]]


def _sin(rij: np.ndarray, v: np.ndarray) -> float:
    return float(np.linalg.norm(np.cross(rij / np.linalg.norm(rij), v)))


def gyration_length(body: PoseBody) -> float:
    """sqrt(trace(I) / (2 m)): the radius of gyration, 1 for a point mass."""
    r = float(np.sqrt(np.trace(body.inertia) / (2.0 * body.mass)))
    return r if r > 0 else 1.0


def choose_frame(body: PoseBody, points: list[tuple[str, np.ndarray]],
                 vectors: list[tuple[str, np.ndarray, bool]], used_u: set[str]) -> Choice:
    """i, j, u for ``body`` from its carried ``points`` (name, position) and
    ``vectors`` (name, direction, fixed); ``used_u``: vectors already some body's u."""
    new: list[tuple[str, str, np.ndarray]] = []
    if points:
        i, ri = points[0]
    else:
        i, ri = f"{body.name}_center", body.center
        new.append((i, "point", body.center))
    far = [(float(np.linalg.norm(r - ri)), n, r) for n, r in points[1:]
           if not checks.coincide(ri, r)]
    if far:
        _, j, rj = max(far, key=lambda x: x[0])
    elif not checks.coincide(ri, body.center) and points:
        j, rj = f"{body.name}_center", body.center
        new.append((j, "point", rj))
    else:
        j, rj = f"{body.name}_end", ri + gyration_length(body) * body.frame[:, 0]
        new.append((j, "point", rj))
    rij = rj - ri
    ranked = sorted(((_sin(rij, v), fixed, name not in used_u, -k, name)
                     for k, (name, v, fixed) in enumerate(vectors)), reverse=True,
                    key=lambda s: (s[0] >= GOOD_SIN, s[1], s[2], s[0], s[3]))
    if ranked and ranked[0][0] >= GOOD_SIN:
        u = ranked[0][4]
    else:
        sins = [_sin(rij, body.frame[:, k]) for k in range(3)]
        k = int(np.argmax(sins))
        u = f"{body.name}_{'xyz'[k]}"
        new.append((u, "vector", body.frame[:, k]))
    return Choice(i, j, u, new)


def typical_body(body: PoseBody, ri, rj, u, choice: Choice) -> tuple[Body, np.ndarray]:
    """The section-2 body of a pose-form body with its chosen i, j, u (initial values
    ri, rj, u) and the rotation R of its FCC frame."""
    R = body_rotation(ri, rj, u)
    center = R.T @ (body.center - ri)
    FR = body.frame.T @ R
    inertia = FR.T @ body.inertia @ FR
    inertia = 0.5 * (inertia + inertia.T)
    shape = body.shape
    if shape is not None:          # its axes from the pose frame to the FCC frame
        axes = np.asarray(shape.axes, float) @ FR
        shape = replace(shape, axes=tuple(tuple(float(x) for x in row) for row in axes))
    return Body(body.name, choice.i, choice.j, choice.u, body.mass, center, inertia,
                body.where, shape), R
