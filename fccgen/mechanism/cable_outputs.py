"""Axial strain and curvature at the nodes of flexible members as result columns
(docs/flexible.md), computed after a run from the recorded
positions and slopes, vectorised over the output samples.

At node k the slope is r' itself, so the strain is |d_k| - 1 exactly. The curvature
|r' x r''| / |r'|^3 needs r'', which the cubic elements give on either side of a node
(r'' is continuous only within an element): the column is the mean of the two
elements' values at the node (one element at the ends). Columns
``<member>.n<k>.strain``, ``<member>.n<k>.curvature`` (and ``<member>.tip.*``) are
named after the member even where a node is a named point.
"""
from __future__ import annotations

import numpy as np

from ..model.cables import node_names

def _track(plan, columns, name: str, n: int, value) -> np.ndarray:
    """(n, 3) positions of a triple over the samples (fixed: its value repeated)."""
    if name in plan.index:
        return np.column_stack([columns[f"{name}.{k}"] for k in "xyz"])
    return np.tile(np.asarray(value, float), (n, 1))


def _second_derivative(r1, d1, r2, d2, L: float, xi: float) -> np.ndarray:
    """r'' at xi of an element (rows: samples)."""
    return ((12 * xi - 6) / L ** 2 * r1 + (6 * xi - 4) / L * d1
            + (6 - 12 * xi) / L ** 2 * r2 + (6 * xi - 2) / L * d2)


def cable_values(plan, columns: dict, n: int) -> dict[str, np.ndarray]:
    """Name -> (n,) values of the strain and curvature columns."""
    model, out = plan.model, {}
    for c in model.cables.values():
        r = [_track(plan, columns, p, n, model.points[p].at) for p in c.nodes]
        d = [_track(plan, columns, s, n, model.slopes[s].along) for s in c.slopes]
        L = c.element_length
        curv = [np.zeros(n) for _ in c.nodes]
        count = [0] * len(c.nodes)
        for k in range(c.elements):
            for node, xi in ((k, 0.0), (k + 1, 1.0)):
                b = _second_derivative(r[k], d[k], r[k + 1], d[k + 1], L, xi)
                a = d[node]
                curv[node] += (np.linalg.norm(np.cross(a, b), axis=1)
                               / np.linalg.norm(a, axis=1) ** 3)
                count[node] += 1
        for k, name in enumerate(node_names(c.name, c.elements)):
            out[f"{name}.strain"] = np.linalg.norm(d[k], axis=1) - 1.0
            out[f"{name}.curvature"] = curv[k] / count[k]
    return out


def add_cable_columns(plan, result) -> None:
    """Add the strain and curvature columns to a run's result (in place)."""
    result.columns.update(cable_values(plan, result.columns, len(result.t)))
