"""What the animation draws, as positions over the result's rows, from the *lowered*
model (joints and pose-form bodies already turned into points, vectors and typical
bodies, :mod:`fccgen.mechanism`):

- each body's frame at every row, R = [e1 e2 e3] from its r_i, r_j, u (the FCC body
  frame, docs/design.md §1), so any body-fixed point is r_i + R rho;
- each body's solid: its ``shape:`` when it has one, else its *inertia box* -- the
  uniform box of the same mass and principal moments, edges
  a_k = sqrt(6 (I_1 + I_2 + I_3 - 2 I_k) / m) along the principal axes (a body
  without inertia has none);
- each body's skeleton: the segment from i to j and from the mass centre to every
  other point the body carries (its joints' points);
- the joints at their points, the ground's points (fixed points and the joints'
  points on ground).

Labels are the names a user wrote: bodies, joints, and the points of a model given
by points; points the lowering made (``A_axis``, ``rod_center``) are drawn as part
of their body, never named.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.types import Attached
from .meshes import solid_mesh

# An inertia box's edge is drawn at least this share of its longest edge (a slender
# rod's box is otherwise a line that no face shows).
MIN_EDGE_SHARE = 0.02


@dataclass
class Solid:
    """A body's solid at every row: vertices (n_rows, n_vertices, 3), faces."""
    body: str
    kind: str                  # "shape" | "inertia box"
    vertices: np.ndarray
    faces: np.ndarray


def triple_tracks(model, result) -> dict[str, np.ndarray]:
    """(n_rows, 3) values of every point and vector of the lowered ``model``: moving
    ones from the result, fixed ones repeated. A moving one missing from the result is
    a ValueError that names the result's model."""
    n = len(result.t)
    tracks = {}
    for items in (model.points.values(), model.vectors.values()):
        for p in items:
            value = p.at if hasattr(p, "at") else p.along
            if p.fixed:
                tracks[p.name] = np.tile(np.asarray(value, float), (n, 1))
                continue
            names = [f"{p.name}.{c}" for c in "xyz"]
            try:
                tracks[p.name] = np.column_stack([result[c] for c in names])
            except KeyError:
                missing = next(c for c in names if not _has(result, c))
                raise ValueError(
                    f"the result has no column {missing}: it is not a result of the "
                    f"model {model.name} ({model.source}), or it was saved without the "
                    "columns of the points and vectors fccgen made for the joints "
                    "(save it with all columns: --all-columns)") from None
    return tracks


def _has(result, name: str) -> bool:
    try:
        result[name]
    except KeyError:
        return False
    return True


def body_frames(model, tracks) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per body (r_i (n, 3), R (n, 3, 3)) at every row."""
    out = {}
    for b in model.bodies.values():
        ri, rj, u = tracks[b.i], tracks[b.j], tracks[b.u]
        e1 = rj - ri
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e3 = np.cross(e1, u)
        e3 /= np.linalg.norm(e3, axis=1, keepdims=True)
        e2 = np.cross(e3, e1)
        out[b.name] = (ri, np.stack([e1, e2, e3], axis=2))
    return out


def inertia_box(mass: float, inertia) -> tuple[tuple, np.ndarray] | None:
    """Edges (a, b, c) and axes (rows, body frame) of the uniform box with the body's
    mass and principal moments; None for a body without inertia."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, float))
    total = float(moments.sum())
    if not total > 0.0 or not mass > 0.0:
        return None
    edges = np.sqrt(np.maximum(6.0 * (total - 2.0 * moments) / mass, 0.0))
    edges = np.maximum(edges, MIN_EDGE_SHARE * edges.max())
    return tuple(float(e) for e in edges), axes.T


def body_solids(model, frames) -> list[Solid]:
    """Every body's solid (its shape, or its inertia box) at every row."""
    from types import SimpleNamespace
    out = []
    for b in model.bodies.values():
        if b.shape is not None:
            solid, kind = b.shape, "shape"
        else:
            box = inertia_box(b.mass, b.inertia)
            if box is None:
                continue
            solid = SimpleNamespace(kind="box", size=box[0], axes=box[1])
            kind = "inertia box"
        local, faces = solid_mesh(solid)
        rho = np.asarray(b.center, float) + local @ np.asarray(solid.axes, float)
        ri, R = frames[b.name]
        out.append(Solid(b.name, kind, ri[:, None, :] + np.einsum("nij,vj->nvi", R, rho),
                         faces))
    return out


def carried_points(model) -> dict[str, list[str]]:
    """Per body the points it carries besides i and j (attached by the lowering)."""
    out: dict[str, list[str]] = {b: [] for b in model.bodies}
    for c in model.constraints:
        if isinstance(c, Attached) and c.kind == "point" and c.body in out:
            out[c.body].append(c.target)
    return out


def skeletons(model, frames, tracks) -> dict[str, list[np.ndarray]]:
    """Per body its segments, each (n_rows, 2, 3): i to j, then the mass centre to
    every other point it carries."""
    extra = carried_points(model)
    out = {}
    for b in model.bodies.values():
        ri, R = frames[b.name]
        centre = ri + R @ np.asarray(b.center, float)
        segments = [np.stack([tracks[b.i], tracks[b.j]], axis=1)]
        segments += [np.stack([centre, tracks[p]], axis=1) for p in extra[b.name]]
        out[b.name] = segments
    return out


def joint_points(model) -> list[tuple[str, str]]:
    """(joint name, the point that marks it): the joint's shared point, else its point
    on the second body."""
    mech = getattr(model, "mechanism", None)
    if mech is None:
        return []
    marks = []
    for jl in mech.joints:
        points = [t for t in jl.triples if t.kind == "point"]
        if not points:
            continue
        second = jl.joint.bodies[1]
        shared = [t for t in points if len(t.carriers) > 1]
        on_second = [t for t in points if second in t.carriers]
        marks.append((jl.joint.name, (shared or on_second or points)[0].name))
    return marks


def user_points(model, user_model) -> list[str]:
    """The points of the lowered model that the user named (a model given by points),
    in file order."""
    return [p for p in user_model.points if p in model.points]
