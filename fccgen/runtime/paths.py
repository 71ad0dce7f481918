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
# from r_ij keeps 5e-3 and 1e-3: forced onto the sparse path, at 0.1 degrees its run
# holds the dense one's answers only to 1e-8, and at 0.07 degrees (6e-4) a tenth of
# its sparse solves do not converge (tests/test_small_model_path.py).
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
                order: str = "minimum_degree", at=None, switchable=None):
    """An Engine (dense) or a SparseEngine with its structure analysed and set: the
    pattern of A with every element block full, or (at: coordinate vectors,
    pattern_samples) with the entries the blocks hold there
    (SparseBlocks.planar_pattern: a model written and moving in a plane), guarded by
    a check at every assembly. switchable: per joint quantity of the model's events the
    coordinates its gradient reads (switchable_patterns), put into the pattern of A so
    that runs fold the locked rows into the factorisation (engine/fcc_sparse_fold.c);
    None: the locked rows go through a Schur complement."""
    if not sparse:
        return Engine(asm, rank_tol, position_tol, max_newton)
    engine = SparseEngine(asm, rank_tol, position_tol, max_newton)
    masks = None
    if at is not None and np.all(np.isfinite(at)):
        engine.set_pinned(at)
        masks = engine.planar_pattern(at)
    elements = engine.solve_elements()
    rows = None
    if switchable is not None and any(len(r) for r in switchable):
        elements, masks, rows = _with_rows(elements, masks, switchable,
                                           engine.pinned_coordinates[0], asm.n_q)
    st = kept_structure(asm.n_q, elements, order, masks)
    n_el = asm.n_el
    cut = int(st.emap_ptr[n_el])
    engine.set_structure(st.perm, st.Ap, st.Ai, st.emap_ptr[:n_el + 1], st.emap[:cut])
    if rows is not None:
        engine.set_switchable(rows[0], rows[1], st.emap_ptr[n_el:] - cut, st.emap[cut:])
    return engine


def _with_rows(elements, masks, switchable, pinned, n: int):
    """The solve's elements (and planar masks) with one more element per switchable
    row, on its free coordinates (its pairs then enter the order and the pattern of
    A); and (sw_ptr, sw_idx) of those rows."""
    q_ptr, q_idx, couples = (np.asarray(a) for a in elements)
    is_pinned = np.zeros(n, dtype=bool)
    is_pinned[np.asarray(pinned, dtype=np.intp)] = True
    rows = [np.array([i for i in sorted(set(int(x) for x in r)) if not is_pinned[i]],
                     dtype=np.intc) for r in switchable]
    sizes = np.array([len(r) for r in rows], dtype=np.intp)
    sw_ptr = np.concatenate([[0], np.cumsum(sizes)]).astype(np.intc)
    sw_idx = (np.concatenate(rows) if len(rows) else np.zeros(0)).astype(np.intc)
    ext = (np.concatenate([q_ptr, q_ptr[-1] + sw_ptr[1:]]).astype(np.intc),
           np.concatenate([q_idx, sw_idx]).astype(np.intc),
           np.concatenate([couples, sizes > 0]))
    if masks is not None:
        ptr, mask = masks
        ptr = np.asarray(ptr, dtype=np.intp)
        ext_masks = (np.concatenate([ptr, ptr[-1] + np.cumsum(sizes ** 2)]),
                     np.concatenate([np.asarray(mask, dtype=bool),
                                     np.ones(int(np.sum(sizes ** 2)), dtype=bool)]))
    else:
        ext_masks = None
    return ext, ext_masks, (sw_ptr, sw_idx)


SWITCHABLE_SAMPLES = 3          # random positions the rows' patterns are read at


def switchable_patterns(events, q0, scale: float, rows) -> list:
    """Per joint quantity of the event set, the coordinates its gradient is nonzero on
    at q0 and at SWITCHABLE_SAMPLES positions about it (every coordinate moved by
    PATTERN_SPREAD * scale at random: a structurally nonzero entry is nonzero there),
    for the quantities in rows (those an event switches); empty for the others. The
    run checks these at every fill (engine/fcc_events_fold.c)."""
    q0 = np.asarray(q0, dtype=float)
    rng = np.random.default_rng(20261128)
    nz = None
    for k in range(SWITCHABLE_SAMPLES + 1):
        q = q0 if k == 0 else q0 + PATTERN_SPREAD * scale * rng.standard_normal(q0.size)
        g = events.quantity_kernels(q, np.zeros_like(q))[1]
        nz = (g != 0.0) if nz is None else nz | (g != 0.0)
    wanted = set(int(r) for r in rows if r >= 0)
    return [np.flatnonzero(nz[j]) if j in wanted else np.zeros(0, dtype=np.intp)
            for j in range(nz.shape[0])]


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
