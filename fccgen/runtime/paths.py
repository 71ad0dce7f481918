"""The dense or the sparse path of the compiled engine, chosen by the model's size and,
for small models, by how well the sparse solve is posed where each run starts.

Dense (runtime/engine/fcc_engine.c with fcc_dense.c): a pivoted QR of B and a
null-space basis per factorisation, O(n^3). Sparse (runtime/engine/fcc_sparse_*.c): an
LDL^T of M + B^T alpha B over a pattern fixed at load time (runtime/sparsity.py), linear
in the size for chains and trees. "auto" takes the sparse path from
SPARSE_MIN_COORDINATES coordinates on (docs/performance.md, "Dense and sparse paths").
Below, where the dense path costs little more, it takes the sparse path (measured
1.4-4.3 times faster on every example, benchmarks/small_paths.py) only when the rank
decision at the run's start shows it well posed (small_model_path): no row dependent
only on the constraint manifold (Bricard's kind: a third of its sparse solves would be
redone densely, docs/reliability.md), every kept direction of B resolved by the
augmented-Lagrangian steps at a rate of 1e-3 or better, and no motion so much lighter
than the heaviest coordinate that a pivot of M + B^T alpha B nears the factorisation's
limit (masses 1e10 apart). Otherwise the dense path, whose rank logic handles all
three.
"""
from __future__ import annotations

import hashlib
import threading

import numpy as np

from ._engine import Engine
from ._sparse import SparseEngine
from .setup_reuse import jacobian_key, shared_decision
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


# Small models under "auto" (small_model_path). KEPT_MIN: the smallest scaled singular
# value sigma_r / sigma_1 the rank decision keeps; an augmented-Lagrangian step shrinks
# that direction's error by 1 / (1 + RHO sigma^2) (RHO 1e7, engine/fcc_sparse.h), 1e-3 at
# 1e-2. Measured: 4e-2 .. 1 on the examples; the body whose u is 0.6 and 0.1 degrees
# from r_ij keeps 5e-3 and 1e-3, and a tenth of its sparse solves did not converge.
# MASS_MIN: the smallest eigenvalue of the reduced mass matrix N^T M N (N the null
# space of the row-scaled B at the decided rank, orthonormal) over the largest diagonal
# entry of M. A's pivot along that direction is about this over RHO of its diagonal,
# and the factorisation stops below 64 eps = 1.4e-14 of it: the double pendulum with
# masses 1e10 apart (6e-11) and the pendulum whose axial inertia is 1e-10 of its
# transverse one (2.5e-11) did, once they had turned from their axis-aligned start.
# Measured 1.5e-4 (the spherical pendulum) .. 1.2 on the examples.
SMALL_KEPT_MIN = 1e-2
SMALL_MASS_MIN = 1e-6


def use_sparse(linear_solver: str, n_q: int) -> bool:
    """Whether the linear solver name ("auto", "dense", "sparse") means the sparse path
    for a model of n_q coordinates from the start (auto below SPARSE_MIN_COORDINATES:
    the dense path until the first rank decision, small_model_path)."""
    if linear_solver == "auto":
        return n_q >= SPARSE_MIN_COORDINATES
    return linear_solver == "sparse"


def small_model_path(kept_sigma: float, manifold_sigma: float, mass_spread: float) -> str:
    """"sparse" or "dense" for a model below SPARSE_MIN_COORDINATES under "auto", from
    its rank decision at a run's start: kept_sigma the smallest scaled singular value
    kept, manifold_sigma nonzero when B has rows dependent only on the constraint
    manifold (CompiledSolver._manifold_redundancy), mass_spread the reduced mass
    matrix's smallest eigenvalue over M's largest diagonal entry (module constants)."""
    if manifold_sigma > 0.0:
        return "dense"
    if kept_sigma >= SMALL_KEPT_MIN and mass_spread >= SMALL_MASS_MIN:
        return "sparse"
    return "dense"


def reduced_mass_spread(M: np.ndarray, B_scaled: np.ndarray, rank: int) -> float:
    """The smallest eigenvalue of N^T M N over max diag(M), N the right singular vectors
    of the row-scaled B beyond the first rank (1 when there is none)."""
    scale = float(np.max(np.diag(M))) if M.size else 0.0
    if rank >= M.shape[0] or not scale > 0.0:
        return 1.0
    if B_scaled.size:
        # a function of B alone, kept per process by its bytes like the rank decisions
        # (setup_reuse.shared_decision): a solver of other masses at the same start
        # (with_parameters, simulate_many, a sensitivity's shifted models) reuses it
        null, _ = shared_decision(
            jacobian_key("null", B_scaled, None, rank),
            lambda: np.linalg.svd(B_scaled, full_matrices=True)[2][rank:].T)
    else:
        null = np.eye(M.shape[0])
    return float(np.linalg.eigvalsh(null.T @ M @ null)[0]) / scale


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
    st = kept_structure(asm.n_q, engine.solve_elements(), order, masks)
    engine.set_structure(st.perm, st.Ap, st.Ai, st.emap_ptr, st.emap)
    return engine


_STRUCTURES: dict = {}          # sparsity.structure's answers, by its inputs' bytes
_STRUCTURES_KEPT = 16
_structures_lock = threading.Lock()


def kept_structure(n: int, elements, order: str, masks):
    """sparsity.structure(n, *elements, order=order, masks=masks), kept for the
    process by the bytes of its inputs: the solvers of one structure with other
    numbers (with_parameters, simulate_many) whose pattern of A is the same take the
    same ordering and maps (a deterministic function of those inputs) without the
    analysis (1.4 ms of a 17 ms run of A02's chain of 10)."""
    h = hashlib.sha256(repr((n, order, masks is None)).encode())
    for a in list(elements) + (list(masks) if masks is not None else []):
        h.update(repr(np.shape(a)).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    key = h.hexdigest()
    with _structures_lock:
        found = _STRUCTURES.get(key)
    if found is None:
        found = structure(n, *elements, order=order, masks=masks)
        with _structures_lock:
            _STRUCTURES[key] = found
            while len(_STRUCTURES) > _STRUCTURES_KEPT:
                _STRUCTURES.pop(next(iter(_STRUCTURES)))
    return found
