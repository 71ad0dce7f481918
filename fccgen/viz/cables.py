"""Flexible members drawn as curves (docs/flexible.md): the cubic Hermite line of
every element through its nodes' positions and slopes, as the elements themselves
interpolate it, sampled at :data:`SAMPLES` points per element.

:func:`cable_trace` gives the plotly trace of a model's members at one row of a
result, for the animation (fccgen.viz.animate) to add to its moving traces.
"""
from __future__ import annotations

import numpy as np

SAMPLES = 8                      # points per element along the curve (ends included)


def _track(model, result, name: str, initial) -> np.ndarray:
    """(n_rows, 3) values of a node's point or slope: from the result's columns, or
    its initial value repeated (a fixed point)."""
    cols = [f"{name}.{c}" for c in "xyz"]
    if all(c in result.columns for c in cols):
        return np.column_stack([result.columns[c] for c in cols])
    return np.tile(np.asarray(initial, float), (len(result.t), 1))


def cable_lines(model, result, k: int) -> tuple[list, list, list]:
    """x, y, z lists of every member's curve at row k, None between members."""
    xyz = ([], [], [])
    xi = np.linspace(0.0, 1.0, SAMPLES)
    shape = np.array([1 - 3 * xi ** 2 + 2 * xi ** 3, xi - 2 * xi ** 2 + xi ** 3,
                      3 * xi ** 2 - 2 * xi ** 3, xi ** 3 - xi ** 2]).T    # (SAMPLES, 4)
    for cable in model.cables.values():
        L = cable.element_length
        slope0 = cable.chord / cable.length
        r = [_track(model, result, p, model.points[p].at)[k] for p in cable.nodes]
        d = [_track(model, result, s, slope0)[k] for s in cable.slopes]
        for e in range(cable.elements):
            stack = np.array([r[e], L * d[e], r[e + 1], L * d[e + 1]])    # (4, 3)
            points = shape @ stack
            start = 0 if e == 0 else 1
            for c in range(3):
                xyz[c].extend(float(x) for x in points[start:, c])
        for c in range(3):
            xyz[c].append(None)
    return xyz


def cable_trace(model, result, k: int, go):
    """The plotly Scatter3d of the members at row k (None for a model without)."""
    if not getattr(model, "cables", None):
        return None
    x, y, z = cable_lines(model, result, k)
    return go.Scatter3d(x=x, y=y, z=z, mode="lines", name="cables",
                        hoverinfo="skip", line=dict(width=4, color="#2ca02c"))
