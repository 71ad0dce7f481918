"""Coordinates held still by linear constraints with constant rows, left out of the
sparse solve (SparseBlocks.set_pinned): a planar chain's out-of-plane coordinates and
the cart's rail coordinates, with the rows that hold them. The solve then works on the
other coordinates and rows alone; its answers must equal the full solve's and the
dense path's, and a state where a fixed row no longer holds must be answered on the
full pattern."""
from __future__ import annotations

import numpy as np

import fccgen
from conftest import example_module
from fccgen.runtime import CompiledSolver
from fccgen.runtime.sparsity import isolated_last


def _cart(tmp_path, build_dir, n=10):
    path = tmp_path / f"cart_{n}.yaml"
    path.write_text(example_module("make_pendulum_on_cart").model_text(n))
    sparse = fccgen.load(path, build_dir, linear_solver="sparse")
    dense = CompiledSolver(sparse.plan, sparse.module, linear_solver="dense")
    full = CompiledSolver(sparse.plan, sparse.module, linear_solver="sparse")
    full._full_pattern()                      # no pattern read: nothing pinned
    return sparse, dense, full


def _names(solver, indices):
    names = [f"{p}.{c}" for p, _ in solver.plan.triples for c in "xyz"]
    return sorted(names[i] for i in indices)


def test_the_cart_pins_its_rail_and_out_of_plane_coordinates(tmp_path, build_dir):
    """n = 10: C and D on the rail (y = z = 0 for C, y = 0 and "perpendicular to z"
    for D) and every tip's z (each rod's "perpendicular to z" row, down the chain):
    n + 4 coordinates and as many rows; the full-pattern engine pins none."""
    sparse, _, full = _cart(tmp_path, build_dir)
    pinned, fixed = sparse._engine.pinned_coordinates
    assert _names(sparse, pinned) == sorted(
        ["C.y", "C.z", "D.y", "D.z"] + [f"P{k}.z" for k in range(1, 11)])
    assert len(fixed) == 14
    assert len(full._engine.pinned_coordinates[0]) == 0


def test_the_factorisation_leaves_out_the_pinned_coordinates(tmp_path, build_dir):
    """The order puts the pinned coordinates (coupled to nothing) last, and the
    LDL^T and its solves stop before them: 36 - 14 columns for n = 10; the
    full-pattern engine factors all 36. Every pinned coordinate comes after every
    free one in the order (sparsity.isolated_last)."""
    sparse, _, full = _cart(tmp_path, build_dir)
    assert sparse._engine.factored_columns == 36 - 14
    assert full._engine.factored_columns == 36


def test_isolated_coordinates_go_last_in_their_order():
    """isolated_last keeps the coupled coordinates' order and appends the others in
    theirs."""
    perm = np.array([4, 0, 5, 2, 1, 3], dtype=np.intc)
    groups = [np.array([0, 2]), np.array([2, 4])]
    assert isolated_last(perm, groups).tolist() == [4, 0, 2, 5, 1, 3]


def test_pinned_solves_equal_the_full_and_the_dense_solves(tmp_path, build_dir):
    """Accelerations and projections at the initial state and at other speeds: to
    1e-12 relative of the full sparse solve and of the dense one (both stop at about
    1e-15 of |x|: the same system, the pinned rows and coordinates merely left out),
    and exactly zero on the pinned coordinates."""
    sparse, dense, full = _cart(tmp_path, build_dir)
    pinned = sparse._engine.pinned_coordinates[0]
    init = dense.initial_state()
    rng = np.random.default_rng(3)
    for v in (init.v, dense.project_velocities(init.q, init.v + rng.standard_normal(36))):
        a = sparse.accelerations(init.q, v)
        for other in (full, dense):
            b = other.accelerations(init.q, v)
            assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b))
        assert np.all(a[pinned] == 0.0)
    v_off = init.v + 0.1 * rng.standard_normal(36)
    w = sparse.project_velocities(init.q, v_off)
    assert np.max(np.abs(w - dense.project_velocities(init.q, v_off))) <= 1e-12 * np.max(
        np.abs(w))
    assert np.all(w[pinned] == 0.0)


def test_a_run_with_pinned_coordinates_equals_the_full_and_the_dense_runs(
        tmp_path, build_dir):
    """1 s of RK4 at dt 1 ms: every column to 1e-12 (full pattern) and 1e-9 (dense
    path, the suite's bound for the two paths) of its size; no guard trips, and the
    pinned coordinates keep their values exactly."""
    sparse, dense, full = _cart(tmp_path, build_dir)
    runs = [s.simulate(t_end=1.0, dt=1e-3, output_dt=0.01, reactions=False)
            for s in (sparse, full, dense)]
    assert not sparse._engine.pattern_tripped
    assert len(sparse._engine.pinned_coordinates[0]) == 14
    r, rf, rd = runs
    for c in rd.columns:
        if c == "constraint_error":
            continue
        size = max(1.0, np.max(np.abs(rd[c])))
        assert np.max(np.abs(r[c] - rf[c])) <= 1e-12 * size, c
        assert np.max(np.abs(r[c] - rd[c])) <= 1e-9 * size, c
    for name in _names(sparse, sparse._engine.pinned_coordinates[0]):
        assert np.ptp(r[name]) == 0.0, name


def test_a_start_off_a_fixed_row_is_run_on_the_full_pattern(tmp_path, build_dir):
    """A run handed a q0 with the chain 1e-3 m off its plane (z = 1e-3 everywhere:
    the cart's "C on z = 0" no longer holds, the pinned coordinates would have to
    move): the first position projection trips the guard and the run is redone on the
    full pattern, which takes the chain back to the plane as the dense path does; the
    two runs agree to 1e-9 of each column's size."""
    sparse, dense, _ = _cart(tmp_path, build_dir, n=3)
    init = dense.initial_state()
    q0 = init.q.copy()
    q0[2::3] += 1e-3
    r = sparse.simulate(t_end=0.2, dt=1e-3, output_dt=0.01, q0=q0, v0=init.v,
                        reactions=False)
    rd = dense.simulate(t_end=0.2, dt=1e-3, output_dt=0.01, q0=q0, v0=init.v,
                        reactions=False)
    assert len(sparse._engine.pinned_coordinates[0]) == 0      # now the full pattern
    assert abs(r["P3.z"][-1]) < 1e-9
    for c in rd.columns:
        if c == "constraint_error":
            continue
        assert np.max(np.abs(r[c] - rd[c])) <= 1e-9 * max(1.0, np.max(np.abs(rd[c]))), c


def test_a_spatial_model_pins_nothing(compiled):
    """The spatial double pendulum has no constant rows that hold a coordinate: the
    solve keeps every coordinate and row."""
    s = compiled("spatial_double_pendulum")
    solver = CompiledSolver(s.plan, s.module, linear_solver="sparse")
    pinned, fixed = solver._engine.pinned_coordinates
    assert len(pinned) == 0 and len(fixed) == 0
