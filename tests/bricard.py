"""Bricard's over-constrained linkage (IFToMM benchmark A04) written with the point and
vector contract of docs/design.md §2 alone, in two encodings of its hinges.

Hinges at P1..P6 = (0,0,0), (1,0,0), (1,-1,0), (1,-1,1), (0,-1,1), (0,0,1) with axes
y, z, x, y, z, x; bar k joins P_k and P_k+1 (five bars of 1 m, 1 kg, 0.1 m square
section); the sixth link (P6-P1) is the ground; gravity along -y. Counting gives
-3 degrees of freedom, the linkage has 1.

Bar k is a typical body with points (P_k, P_k+1) and vector u_k = the axis of its first
hinge, so the hinge at P_k is a shared point plus a shared vector for bar k. Bar k-1
shares the point P_k only; its rotation about u_k alone is enforced by a point K of bar
k-1 placed at P_k + a_k (a_k the axis), either
* ``line``: K on the line through P_k along u_k (``point_on_line``, 3 rows of rank 2), or
* ``distance``: K at distance sqrt(2) from two points of bar k off the axis
  (P_k+1 and P_k + e3 of bar k), which with |K - P_k| = 1 fixes K on the axis.
The hinge at P6 (axis x, on the ground) uses fixed points instead of bar k.
"""
from __future__ import annotations

import numpy as np
import yaml

P = np.array([(0, 0, 0), (1, 0, 0), (1, -1, 0), (1, -1, 1), (0, -1, 1), (0, 0, 1)], float)
AXES = np.array([(0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0)], float)
MASS, LENGTH, SIDE = 1.0, 1.0, 0.1
# Uniform bar of square section: axial m s^2/6, transverse m (s^2 + L^2)/12.
INERTIA = [MASS * SIDE ** 2 / 6, MASS * (SIDE ** 2 + LENGTH ** 2) / 12,
           MASS * (SIDE ** 2 + LENGTH ** 2) / 12]


def _frame(k: int) -> np.ndarray:
    """R = [e1 e2 e3] of bar k (0-based) at the initial configuration."""
    e1 = P[k + 1] - P[k]
    e1 /= np.linalg.norm(e1)
    e2 = AXES[k]                      # perpendicular to the bar: beta = 0, alpha = 1
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def _local(k: int, x) -> list[float]:
    """Body-frame coordinates (from point i) of the global point x in bar k."""
    return [float(c) for c in _frame(k).T @ (np.asarray(x, float) - P[k])]


def model(encoding: str = "line", t_end: float = 10.0, dt: float = 1e-3,
          name: str | None = None) -> dict:
    """The model as a dict (dump it with :func:`text`); encoding 'line' or 'distance'."""
    if encoding not in ("line", "distance"):
        raise ValueError(encoding)
    points = {"P1": {"at": P[0].tolist(), "fixed": True},
              "P6": {"at": P[5].tolist(), "fixed": True}}
    for k in range(1, 5):
        points[f"P{k + 1}"] = P[k].tolist()
    vectors = {"u1": {"along": AXES[0].tolist(), "fixed": True}}
    for k in range(1, 5):
        vectors[f"u{k + 1}"] = AXES[k].tolist()
    bodies = {f"bar{k + 1}": {"points": [f"P{k + 1}", f"P{k + 2}"], "vector": f"u{k + 1}",
                              "mass": MASS, "center": [LENGTH / 2, 0, 0],
                              "inertia": INERTIA}
              for k in range(5)}
    constraints = []
    for k in range(1, 6):                           # hinge at P_{k+1}, axis AXES[k]
        hinge = P[k]
        K = {"body": f"bar{k}", "at": _local(k - 1, hinge + AXES[k])}
        if k < 5:
            on_axis = {"body": f"bar{k + 1}", "at": [0.0, 1.0, 0.0]}
            off = [f"P{k + 2}", {"body": f"bar{k + 1}", "at": [0.0, 0.0, 1.0]}]
        else:
            points["A6"] = {"at": (hinge + AXES[k]).tolist(), "fixed": True}
            points["F6y"] = {"at": (hinge + [0, 1, 0]).tolist(), "fixed": True}
            points["F6z"] = {"at": (hinge + [0, 0, -1]).tolist(), "fixed": True}
            on_axis, off = "A6", ["F6y", "F6z"]
        if encoding == "line":
            constraints.append({"type": "point_on_line", "point": K,
                                "line": [f"P{k + 1}", on_axis]})
        else:
            constraints += [{"type": "distance", "points": [K, o],
                             "length": float(np.sqrt(2.0))} for o in off]
    return {"name": name or f"bricard_{encoding}", "gravity": [0, -9.81, 0],
            "points": points, "vectors": vectors, "bodies": bodies,
            "constraints": constraints,
            "simulate": {"t_end": t_end, "dt": dt, "method": "rk4"}}


def text(encoding: str = "line", **kw) -> str:
    return yaml.safe_dump(model(encoding, **kw), sort_keys=False)
