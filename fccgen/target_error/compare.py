"""What an error target measures: the compared columns of a run, and the distance
between two runs of the same model on the output times they share.

The error of a run is the largest Euclidean distance, over the output times, of a
compared point from where it should be (docs/accuracy.md). By default every moving
point of the model is compared (its ``.x .y .z`` columns); a model without moving
points compares its moving vectors, scaled by the model's length scale so that the
error stays a length. ``error_on`` names what to compare instead: a point or vector
(all three of its coordinates) or single columns; columns of one point or vector are
taken together as one distance.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TIME_MATCH = 1e-9      # output times of two runs must agree to this (relative to t_end)


@dataclass(frozen=True)
class Compared:
    """The groups of columns whose distance is the error, and the factor that makes a
    group's distance a length (1 for points, the length scale for unit vectors)."""
    groups: tuple[tuple[str, tuple[str, ...], float], ...]   # (label, columns, scale)

    @property
    def columns(self) -> list[str]:
        return [c for _, cols, _ in self.groups for c in cols]


def compared(plan, length_scale: float, error_on=None) -> Compared:
    """The compared groups of a model's plan: every moving point (by default), or what
    ``error_on`` names (point and vector names, or column names such as ``B0.x``)."""
    triples = dict(plan.triples)            # name -> "point" | "vector"
    if not error_on:
        kind = "point" if "point" in triples.values() else "vector"
        scale = 1.0 if kind == "point" else float(length_scale)
        return Compared(tuple((n, tuple(f"{n}.{c}" for c in "xyz"), scale)
                              for n, k in triples.items() if k == kind))
    if isinstance(error_on, str):
        error_on = [error_on]
    groups: dict[str, list[str]] = {}
    for item in error_on:
        name = str(item).strip()
        if name in triples:
            groups.setdefault(name, []).extend(f"{name}.{c}" for c in "xyz")
            continue
        owner = name.rsplit(".", 1)[0] if "." in name else name
        groups.setdefault(owner, []).append(name)
    return Compared(tuple((label, tuple(dict.fromkeys(cols)),
                           float(length_scale) if triples.get(label) == "vector"
                           and all(c.rsplit(".", 1)[-1] in "xyz" for c in cols) else 1.0)
                          for label, cols in groups.items()))


def check_columns(what: Compared, result) -> None:
    """ValueError naming each compared column a result does not have."""
    missing = [c for c in what.columns if c not in result.columns]
    if missing:
        raise ValueError(
            f"error_on: no column {', '.join(repr(c) for c in missing)} in the results of "
            f"this model; give point or vector names, or columns among: "
            f"{', '.join(result.names[1:])}")


def shared_times(a, b, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices (ia, ib) of the output times that runs a and b both recorded."""
    ta, tb = np.asarray(a.t), np.asarray(b.t)
    tol = TIME_MATCH * max(abs(t_end), 1.0)
    ib = np.clip(np.searchsorted(tb, ta - tol), 0, len(tb) - 1)
    hit = np.abs(tb[ib] - ta) <= tol
    return np.flatnonzero(hit), ib[hit]


def distance(a, b, what: Compared, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """(times, largest distance of any compared group) between runs a and b at the
    output times both recorded; a non-finite value counts as infinitely far."""
    ia, ib = shared_times(a, b, t_end)
    d = np.zeros(len(ia))
    for _, cols, scale in what.groups:
        sq = sum((np.asarray(a[c])[ia] - np.asarray(b[c])[ib]) ** 2 for c in cols)
        d = np.maximum(d, scale * np.sqrt(sq))
    return np.asarray(a.t)[ia], np.where(np.isfinite(d), d, np.inf)


def speeds(result, what: Compared) -> np.ndarray:
    """The largest speed of any compared group at each output time (0 where a group
    has no speed columns): turns an error in time into an error in position."""
    v = np.zeros(len(result.t))
    for _, cols, scale in what.groups:
        rates = [c.rsplit(".", 1)[0] + ".v" + c.rsplit(".", 1)[1] for c in cols]
        if all(r in result.columns for r in rates):
            v = np.maximum(v, scale * np.sqrt(sum(np.asarray(result[r]) ** 2
                                                  for r in rates)))
    return v


def event_times(result) -> list[tuple[str, float]]:
    """(name, time) of each event of a run, in order (empty: no events)."""
    return [(str(row["name"]), float(row["t"]))
            for row in (result.events or [])]
