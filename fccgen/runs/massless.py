"""The motion of a model that carries no mass or inertia.

A singular reduced mass matrix (M not positive definite on the null space of B) is a
property of the model, not of the numbers the integrator happened to meet: some
motion allowed by the constraints carries no mass or inertia. The eigenvector of the
smallest eigenvalue of N^T M N (N a basis of the null space of B) is that motion; its
largest coordinates name the points and vectors that move without inertia, and the
bodies and constraints that use them are the items to look at.
"""
from __future__ import annotations

import numpy as np


def massless_users(plan, M: np.ndarray, B: np.ndarray, top: int = 4):
    """(coordinate names, labels of the model items using them) of the motion with the
    least kinetic energy, or None when M is positive definite on the null space of B."""
    import scipy.linalg                  # only on this (rare) path
    N = scipy.linalg.null_space(B) if B.size else np.eye(M.shape[0])
    if N.shape[1] == 0:
        return None
    w, z = np.linalg.eigh(N.T @ M @ N)
    scale = max(float(np.max(np.abs(np.diag(M)))), 1e-300)
    if w[0] > 1e-12 * scale:
        return None
    x = N @ z[:, 0]
    order = np.argsort(-np.abs(x))
    coords = [int(i) for i in order[:top] if abs(x[i]) > 0.1 * abs(x[order[0]])]
    names = [f"{plan.triples[i // 3][0]}.{'xyz'[i % 3]}" for i in coords]
    slots = {i // 3 for i in coords}
    users = sorted({el.label for el in plan.elements if slots & set(el.slots)})
    return names, users


def massless_motion(plan, M: np.ndarray, B: np.ndarray, top: int = 4) -> str:
    """A sentence naming the coordinates (and the model items that use them) of the
    motion with the least kinetic energy, or '' when M is positive definite on the
    null space of B."""
    found = massless_users(plan, M, B, top)
    if found is None:
        return ""
    names, users = found
    text = (f"the motion with no mass or inertia moves {', '.join(names)}")
    if users:
        text += f" (used by {', '.join(users[:6])}{', ...' if len(users) > 6 else ''})"
    return text + ("; give those bodies mass and inertia, or constrain that motion")
