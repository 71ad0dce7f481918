"""The dense or the sparse path of the compiled engine, chosen by the model's size.

Dense (runtime/_engine.pyx with _solve.pyx): a pivoted QR of B and a null-space basis
per factorisation, O(n^3). Sparse (runtime/_sparse.pyx): an
LDL^T of M + B^T alpha B over a pattern fixed at load time (runtime/sparsity.py), linear
in the size for chains and trees. "auto" takes the sparse path from
SPARSE_MIN_COORDINATES moving coordinates on (docs/performance.md, "Dense and sparse
paths"): the sparse step measured faster than the dense one at every size, from 3
coordinates on, but the small models keep the dense path's longer-tested rank logic
(Bricard, 24 coordinates, has a row dependent only on the constraints: on the sparse
path a third of its solves reach it and are redone densely, docs/reliability.md), so
the threshold sits just above the largest example below it.
"""
from __future__ import annotations

import numpy as np

from ._engine import Engine
from ._sparse import SparseEngine
from .sparsity import structure

SPARSE_MIN_COORDINATES = 25
# The pattern of A is read at the written positions and at PATTERN_SAMPLES more, each
# coordinate that is nonzero there or has a nonzero initial speed moved by a random
# PATTERN_SPREAD times the length scale (fixed seed): what is zero at all of them is
# a coordinate that neither sits off zero nor moves (the out-of-plane ones of a model
# written in a plane) or an entry that is zero whatever the coordinates.
PATTERN_SAMPLES = 2
PATTERN_SPREAD = 0.1


def pattern_samples(q0, v0, scale: float) -> np.ndarray:
    """The coordinate vectors the sparse path reads the pattern of A at (above)."""
    q0 = np.asarray(q0, dtype=float)
    moving = (q0 != 0.0) | (np.asarray(v0, dtype=float) != 0.0)
    rng = np.random.default_rng(20261123)
    offsets = PATTERN_SPREAD * scale * rng.standard_normal((PATTERN_SAMPLES, q0.size))
    return np.vstack([q0, q0 + offsets * moving])


def use_sparse(linear_solver: str, n_q: int) -> bool:
    """Whether the linear solver name ("auto", "dense", "sparse") means the sparse path
    for a model of n_q coordinates."""
    if linear_solver == "auto":
        return n_q >= SPARSE_MIN_COORDINATES
    return linear_solver == "sparse"


def make_engine(asm, rank_tol, position_tol, max_newton, sparse: bool,
                order: str = "minimum_degree", at=None):
    """An Engine (dense) or a SparseEngine with its structure analysed and set: the
    pattern of A with every element block full, or (at: coordinate vectors,
    pattern_samples) with the entries the blocks hold there
    (SparseBlocks.planar_pattern: a model written and moving in a plane), guarded by
    a check at every assembly."""
    if not sparse:
        return Engine(asm, rank_tol, position_tol, max_newton)
    engine = SparseEngine(asm, rank_tol, position_tol, max_newton)
    masks = None
    if at is not None and np.all(np.isfinite(at)):
        engine.set_pinned(at)
        masks = engine.planar_pattern(at)
    st = structure(asm.n_q, *engine.solve_elements(), order=order, masks=masks)
    engine.set_structure(st.perm, st.Ap, st.Ai, st.emap_ptr, st.emap)
    return engine
