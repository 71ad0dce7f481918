"""The sparse path's pattern of A read from the element blocks (paths.pattern_samples,
SparseBlocks.planar_pattern): a model written and moving in a plane leaves out its
out-of-plane entries (about half of L's fill on the chains), a guard at every assembly
checks that they stay (near) zero, and a model that leaves the plane is run again on
the full pattern."""
from __future__ import annotations

import numpy as np

import fccgen
from conftest import example_module
from fccgen.runtime import CompiledSolver


def _full(solver):
    """A solver like solver on the full pattern (every element block full)."""
    other = CompiledSolver(solver.plan, solver.module, linear_solver="sparse")
    other._full_pattern()
    return other


def test_a_chain_moving_in_its_plane_keeps_the_smaller_pattern(tmp_path, build_dir):
    """The pendulum on a cart with 10 links (36 coordinates): L has 64 nonzeros
    instead of 135, no assembly over 1 s trips the guard, and the run equals the one
    on the full pattern to 1e-12 of each column's size (the factor only preconditions
    the refinement, whose residuals use the full blocks)."""
    path = tmp_path / "cart_10.yaml"
    path.write_text(example_module("make_pendulum_on_cart").model_text(10))
    solver = fccgen.load(path, build_dir, linear_solver="sparse")
    full = _full(solver)
    assert solver._engine.nonzeros[1] < 0.6 * full._engine.nonzeros[1]
    r = solver.simulate(t_end=1.0, dt=1e-3, output_dt=0.01, reactions=False)
    rf = full.simulate(t_end=1.0, dt=1e-3, output_dt=0.01, reactions=False)
    assert not solver._engine.pattern_tripped
    assert solver._engine.nonzeros[1] < 0.6 * full._engine.nonzeros[1]   # kept
    for c in rf.columns:
        assert np.max(np.abs(r[c] - rf[c])) <= 1e-12 * max(1.0, np.max(np.abs(rf[c]))), c


PENDULUM = """\
name: horizontal_pendulum
gravity: [0, 0, -9.81]
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [1.0, 0, 0]
  Q: [2.0, 0, 0]
vectors:
  u: [0, 1, 0]
  w: [0, 1, 0]
bodies:
  rod1: {points: [O, P], vector: u, mass: 1.0, center: [0.5, 0, 0],
         inertia: [5.0e-5, 0.0834, 0.0834]}
  rod2: {points: [P, Q], vector: w, mass: 0.5, center: [0.5, 0, 0],
         inertia: [2.5e-5, 0.0417, 0.0417]}
simulate: {t_end: 1.0, dt: 1.0e-3, output_dt: 0.01}
"""


def test_a_model_leaving_its_written_plane_is_run_again_on_the_full_pattern(
        tmp_path, build_dir):
    """A double pendulum written horizontal in the x-y plane at rest, gravity along -z:
    its z coordinates are zero and still where the pattern is read, so it leaves them
    out; the first stage that moves them trips the guard, and the run is redone on the
    full pattern: it equals the dense path's run to 1e-9 of each column's size."""
    path = tmp_path / "horizontal_pendulum.yaml"
    path.write_text(PENDULUM)
    sparse = fccgen.load(path, build_dir, linear_solver="sparse")
    dense = fccgen.load(path, build_dir, linear_solver="dense")
    smaller = sparse._engine.nonzeros[1]
    r = sparse.simulate(reactions=False)
    rd = dense.simulate(reactions=False)
    assert sparse._engine.nonzeros[1] > smaller          # now on the full pattern
    assert np.ptp(r["Q.z"]) > 0.5                         # it fell out of the plane
    for c in rd.columns:
        if c == "constraint_error":
            continue
        assert np.max(np.abs(r[c] - rd[c])) <= 1e-9 * max(1.0, np.max(np.abs(rd[c]))), c


def test_a_single_call_off_the_plane_is_answered_on_the_full_pattern(tmp_path, build_dir):
    """accelerations() at a state out of the written plane (the dense run's at
    t = 0.5 s): the guard trips inside the call, which is redone on the full pattern
    and gives the dense path's answer to 1e-10."""
    path = tmp_path / "horizontal_pendulum.yaml"
    path.write_text(PENDULUM)
    sparse = fccgen.load(path, build_dir, linear_solver="sparse")
    dense = fccgen.load(path, build_dir, linear_solver="dense")
    smaller = sparse._engine.nonzeros[1]
    r = dense.simulate(t_end=0.5, output_dt=0.5, reactions=False)
    q = np.array([r[f"{n}.{c}"][-1] for n, _ in dense.plan.triples for c in "xyz"])
    v = np.array([r[f"{n}.v{c}"][-1] for n, _ in dense.plan.triples for c in "xyz"])
    assert abs(r["Q.z"][-1]) > 0.1
    a = sparse.accelerations(q, v)
    assert sparse._engine.nonzeros[1] > smaller
    assert np.max(np.abs(a - dense.accelerations(q, v))) <= 1e-10 * np.max(np.abs(a))


def _masks_by_definition(el, samples):
    """planar_masks' definition, element by element: an entry (a, b) of a coupling
    element's block is in the pattern when M_ab != 0 or B_ra B_rb != 0 for some row
    r at some sample (NaN counts as nonzero); an M or B entry zero at every sample is
    guarded by GUARD_TOL times its block's largest finite-or-infinite |entry|."""
    from fccgen.runtime.sparse_setup import GUARD_TOL
    n = len(el.nq)
    masks, zero_m, zero_b = [], np.ones(el.mptr[-1], bool), np.ones(el.bptr[-1], bool)
    scale_m, scale_b = np.zeros(n), np.zeros(n)
    for e in range(n):
        nq, ng = el.nq[e], el.ng[e]
        if not (el.has_m[e] or ng > 0):
            masks.append(np.zeros(0, bool))       # couples nothing: no block
            continue
        block = np.zeros((nq, nq), bool)
        for mblk, bblk in samples:
            m = mblk[el.mptr[e]:el.mptr[e + 1]]
            if m.size:
                block |= (m != 0).reshape(nq, nq)
                zero_m[el.mptr[e]:el.mptr[e + 1]] &= m == 0
                scale_m[e] = max([scale_m[e], *(abs(x) for x in m if x != 0 and x == x)])
            b = bblk[el.bptr[e]:el.bptr[e + 1]].reshape(ng, nq)
            for r in range(ng):
                block |= np.outer(b[r] != 0, b[r] != 0)
            zero_b[el.bptr[e]:el.bptr[e + 1]] &= (b == 0).ravel()
            scale_b[e] = max([scale_b[e], *(abs(x) for x in b.ravel() if x != 0 and x == x)])
        masks.append(block.ravel())
    ptr = np.concatenate([[0], np.cumsum([m.size for m in masks])])
    tol_m = GUARD_TOL * np.repeat(scale_m, np.diff(el.mptr))
    tol_b = GUARD_TOL * np.repeat(scale_b, np.diff(el.bptr))
    return (ptr, np.concatenate(masks), np.flatnonzero(zero_m),
            tol_m[np.flatnonzero(zero_m)], np.flatnonzero(zero_b), tol_b[np.flatnonzero(zero_b)])


def test_the_masks_are_those_of_their_definition_on_mixed_elements():
    """planar_masks takes the elements of one block shape together; on 60 random
    elements of five shapes (with and without mass blocks, rows or both, one coupling
    nothing), blocks with zeros, NaN and infinities, at three samples, it returns
    exactly the masks and guards of the element-by-element definition."""
    from types import SimpleNamespace

    from fccgen.runtime.sparse_setup import planar_masks
    rng = np.random.default_rng(7)
    kinds = [(3, 1, True), (6, 0, True), (2, 2, False), (6, 3, True), (4, 0, False)]
    picks = rng.integers(0, len(kinds), 60)
    nq = np.array([kinds[k][0] for k in picks])
    ng = np.array([kinds[k][1] for k in picks])
    has_m = np.array([kinds[k][2] for k in picks])
    mptr = np.concatenate([[0], np.cumsum(nq ** 2 * has_m)])
    bptr = np.concatenate([[0], np.cumsum(nq * ng)])
    el = SimpleNamespace(nq=nq, ng=ng, has_m=has_m, mptr=mptr, bptr=bptr)

    def block(size):
        x = rng.normal(size=size) * (rng.random(size) < 0.5)
        x[rng.random(size) < 0.03] = np.nan
        x[rng.random(size) < 0.02] = np.inf
        return x
    samples = [(block(mptr[-1]), block(bptr[-1])) for _ in range(3)]
    got = planar_masks(el, samples)
    want = _masks_by_definition(el, samples)
    for name, g, w in zip(("ptr", "mask", "zero_m", "tol_m", "zero_b", "tol_b"), got, want):
        assert np.array_equal(g, w), name
    assert 0 < len(got[2]) < mptr[-1] and 0 < len(got[4]) < bptr[-1]
