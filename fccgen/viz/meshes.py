"""Triangle meshes of the solids the animation draws, in a solid's own axes, centred
at the origin: a box, a cylinder (axis x), a sphere. Each is ``(vertices (n, 3),
faces (m, 3) vertex indices)``; :func:`solid_mesh` scales one to a body's solid
(:class:`fccgen.model.types.Solid`).
"""
from __future__ import annotations

import numpy as np

SIDES = 16          # facets around a cylinder; rings and meridians of a sphere below
RINGS = 8


def box(a: float, b: float, c: float) -> tuple[np.ndarray, np.ndarray]:
    """The box with edges a, b, c along x, y, z."""
    v = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    v = v * np.array([a, b, c])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
             (1, 5, 7, 3)]
    faces = [f for q in quads for f in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]
    return v, np.array(faces)


def cylinder(radius: float, length: float) -> tuple[np.ndarray, np.ndarray]:
    """The cylinder of ``radius`` and ``length`` along x, both ends closed."""
    phi = 2.0 * np.pi * np.arange(SIDES) / SIDES
    ring = np.column_stack([np.zeros(SIDES), radius * np.cos(phi), radius * np.sin(phi)])
    v = np.vstack([ring - [0.5 * length, 0, 0], ring + [0.5 * length, 0, 0],
                   [[-0.5 * length, 0, 0], [0.5 * length, 0, 0]]])
    faces = []
    for k in range(SIDES):
        n = (k + 1) % SIDES
        faces += [(k, n, SIDES + n), (k, SIDES + n, SIDES + k),
                  (2 * SIDES, n, k), (2 * SIDES + 1, SIDES + k, SIDES + n)]
    return v, np.array(faces)


def sphere(radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The sphere of ``radius``: RINGS latitudes between the poles, SIDES meridians."""
    theta = np.pi * np.arange(1, RINGS) / RINGS
    phi = 2.0 * np.pi * np.arange(SIDES) / SIDES
    rings = [np.column_stack([np.full(SIDES, np.cos(t)), np.sin(t) * np.cos(phi),
                              np.sin(t) * np.sin(phi)]) for t in theta]
    v = radius * np.vstack([*rings, [[1.0, 0, 0], [-1.0, 0, 0]]])
    top, bottom = len(v) - 2, len(v) - 1
    faces = []
    for k in range(SIDES):
        n = (k + 1) % SIDES
        faces.append((top, k, n))
        last = (RINGS - 2) * SIDES
        faces.append((bottom, last + n, last + k))
        for r in range(RINGS - 2):
            a, b = r * SIDES, (r + 1) * SIDES
            faces += [(a + k, b + k, b + n), (a + k, b + n, a + n)]
    return v, np.array(faces)


def solid_mesh(solid) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of ``solid`` (kind, size) in its own axes, centred at the origin."""
    kind, size = solid.kind, solid.size
    if kind == "box":
        return box(*size)
    if kind == "sphere":
        return sphere(size[0])
    if kind in ("cylinder", "rod"):
        return cylinder(size[0], size[1])
    raise ValueError(f"no mesh for a solid of kind {kind!r}")
