"""Which joints take part in the redundant constraint equations (``fccgen check``).

Which row of a dependent set a rank-revealing factorization calls redundant is a
matter of pivoting; what is not is the set of rows that take part in some dependency:
the rows k whose unit vector e_k has a component in the left null space of B (rows
scaled to unit norm), ||N^T e_k|| > DEPENDENT_TOL with N an orthonormal basis of it.
"""
from __future__ import annotations

import re

import numpy as np

# A row takes part in a dependency when its weight in the left null space is above
# this: null vectors are unit vectors, so rounding leaves weights of ~1e-15 on rows
# that take no part, and a row of a dependency among n rows weighs ~1/sqrt(n).
DEPENDENT_TOL = 1e-6
_JOINT = re.compile(r"^joint (\w+) ")


def dependent_rows(B: np.ndarray, rank: int) -> np.ndarray:
    """Indices of the rows of B that take part in a dependency (B has ``rank``)."""
    if B.shape[0] == 0 or rank >= B.shape[0]:
        return np.zeros(0, dtype=int)
    norms = np.linalg.norm(B, axis=1)
    scaled = B / np.where(norms > 0, norms, 1.0)[:, None]
    U = np.linalg.svd(scaled)[0]
    weight = np.linalg.norm(U[:, rank:], axis=1)
    return np.nonzero(weight > DEPENDENT_TOL)[0]


def dependency_text(B: np.ndarray, rank: int, labels: list[str]) -> str:
    """'joints J1, J2; other rows bodies.bar1 (length), ...' for the dependent rows, or
    '' when there are none."""
    return rows_text(dependent_rows(B, rank), labels)


def rows_text(rows, labels: list[str]) -> str:
    """'joints J1, J2; other rows bodies.bar1 (length), ...' for the row indices
    ``rows``, or '' when there are none."""
    joints: list[str] = []
    others: list[str] = []
    for k in rows:
        m = _JOINT.match(labels[k])
        if m:
            if m.group(1) not in joints:
                joints.append(m.group(1))
        else:
            others.append(labels[k])
    parts = []
    if joints:
        parts.append("joints " + ", ".join(joints))
    if others:
        parts.append("other rows " + ", ".join(others))
    return "; ".join(parts)
