"""The sparse path of the compiled runtime (runtime/_sparse.pyx: LDL^T of
M + B^T alpha B over a load-time pattern, augmented-Lagrangian refinement) against the
dense one (pivoted QR of B): accelerations, projections and 1 s runs of every example,
the choice of path (auto by size, forced by option, CLI and model file), and the chain
of more than 100 bodies where the sparse path is the default."""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from conftest import EXAMPLES, example_module
from fccgen.errors import ModelError, RunWarning
from fccgen.runtime import CompiledSolver
from fccgen.runtime._engine import Engine
from fccgen.runtime._sparse import SparseEngine
from fccgen.runtime.paths import SPARSE_MIN_COORDINATES

EXAMPLE_NAMES = sorted(p.stem for p in EXAMPLES.glob("*.yaml"))


def both(solver):
    """(dense, sparse) solvers of the same compiled module (events included: both paths
    run them, engine/fcc_events.c)."""
    return (CompiledSolver(solver.plan, solver.module, linear_solver="dense",
                           events_module=solver.events_module),
            CompiledSolver(solver.plan, solver.module, linear_solver="sparse",
                           events_module=solver.events_module))


def rel(a, b) -> float:
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(a)), 1e-300))


@pytest.mark.parametrize("name", EXAMPLE_NAMES)
def test_accelerations_and_projections_agree_with_the_dense_path(compiled, name):
    # 1e-10: the dense solve is exact to ~1e-15 relative; the sparse refinement stops at
    # 1e-15 of |x| (measured 1e-15 .. 2e-15 on every example), so 1e-10 leaves room for
    # the conditioning of the reduced mass matrix without hiding a wrong solve
    # (a missed constraint row changes the accelerations by O(1)).
    dense, sparse = both(compiled(name))
    assert isinstance(sparse._engine, SparseEngine) and type(dense._engine) is Engine
    init = dense.initial_state()
    rng = np.random.default_rng(7)
    v_other = dense.project_velocities(init.q, init.v + rng.standard_normal(dense.n_q))
    for v in (init.v, v_other):
        assert rel(dense.accelerations(init.q, v), sparse.accelerations(init.q, v)) < 1e-10
    v_off = init.v + rng.standard_normal(dense.n_q)
    assert rel(dense.project_velocities(init.q, v_off),
               sparse.project_velocities(init.q, v_off)) < 1e-10
    # a position 1e-9 off the constraints (a step leaves them by its local error, far
    # less): both Newton projections land on the same point (measured 1e-16 apart; at
    # 1e-7 off, Bricard's redundant rows, linearised inconsistently, part them by 3e-6)
    q_off = init.q + 1e-9 * rng.standard_normal(dense.n_q)
    qd, _ = dense.project_positions(q_off)
    qs, _ = sparse.project_positions(q_off)
    assert np.max(np.abs(qd - qs)) < 1e-10 * max(1.0, np.max(np.abs(qd)))


@pytest.mark.parametrize("name", EXAMPLE_NAMES)
def test_one_second_runs_agree_with_the_dense_path(compiled, name):
    # 1e-9 of each column's largest value (or of 1): both runs take the same RK4 steps
    # and projections; they differ by the solves' rounding, amplified by the motion
    # (measured up to 7e-12, A02's energy through the flat position at t = 0.75 s).
    dense, sparse = both(compiled(name))
    # one second at 1 ms; the examples with flexible members state a smaller step,
    # within RK4's stable step for them (fccgen check says which); andrews, whose
    # motion needs 10 us steps (below 1e-4), runs its own 0.03 s
    d = dense.plan.model.simulate
    run = (dict(t_end=d.t_end, dt=d.dt) if d.dt < 1e-4 and d.t_end < 1.0
           else dict(t_end=1.0, dt=min(1e-3, d.dt)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        # reactions off: they are post-processing of the recorded states by the same
        # code on both paths, and a reaction component that is zero in truth carries
        # the rounding of the model's largest forces (1e6 N in deployable_joints)
        rd = dense.simulate(**run, method="rk4", reactions=False)
        rs = sparse.simulate(**run, method="rk4", reactions=False)
    for column in rd.columns:
        a, b = rd[column], rs[column]
        if column == "constraint_error":      # a residual: rounding of the state's size
            scale = max(np.max(np.abs(rd[c])) for c in rd.columns if c != column)
            assert np.max(b) <= 1e-9 * max(1.0, scale)
            continue
        assert np.max(np.abs(a - b)) <= 1e-9 * max(1.0, np.max(np.abs(a))), column
    # events (both paths run them): the same ones, at times 1e-10 s apart (located
    # to event_tol 1e-12 s on functions that differ by the solves' rounding)
    ed, es = rd.events or [], rs.events or []
    assert [e["name"] for e in ed] == [e["name"] for e in es]
    assert all(abs(x["t"] - y["t"]) <= 1e-10 for x, y in zip(ed, es))


def test_a_projection_removing_kinetic_energy_is_flagged_on_the_sparse_path(compiled):
    """Speeds that break the constraints (used as given): the first velocity
    projection removes most of the kinetic energy, and the sparse path reports it as
    the dense one does (fccgen.rank.KE_CUT_WARN)."""
    _, sparse = both(compiled("four_bar"))
    init = sparse.initial_state()
    v0 = np.random.default_rng(3).standard_normal(sparse.n_q)
    with pytest.warns(RunWarning) as caught:
        result = sparse.simulate(t_end=0.01, q0=init.q, v0=v0)
    texts = [str(w.message) for w in caught]
    assert any(re.search("removed .* of the kinetic energy at t = 0.001", t) for t in texts)
    # the energy check sees the same loss from the energy column (E0 has the given speeds)
    assert any("energy changed" in t for t in texts)
    assert result.info["projection_energy_cut"] > 0.1


@pytest.mark.parametrize("name", ["four_bar", "four_bar_driven"])
def test_the_energy_a_projection_removes_is_the_same_on_both_paths(compiled, name):
    """The sparse path's watch takes the removed energy (v - w)^T M (v - w) from the one
    product M v when B w = 0 (runtime/_sparse.pyx, watch_kinetic_energy), and from a
    second product when a driver makes B w = -dg/dt: both equal the dense path's two
    products to 1e-9 of the cut (rounding of a cut of about half the energy)."""
    dense, sparse = both(compiled(name))
    init = dense.initial_state()
    v = init.v + np.random.default_rng(5).standard_normal(dense.n_q)
    cuts = []
    for s in (dense, sparse):
        s.decide_rank(init.q)
        s.set_time(0.37)
        s.project_velocities(init.q, v)
        cuts.append(s._engine.rank_statistics()["kinetic_energy_cut"])
    assert 0.05 < cuts[0] < 1.0
    assert cuts[1] == pytest.approx(cuts[0], rel=1e-9)


def test_the_path_is_chosen_by_size_unless_forced(compiled):
    small = compiled("four_bar")
    assert small.n_q < SPARSE_MIN_COORDINATES
    fresh = CompiledSolver(small.plan, small.module)    # before any rank decision: dense
    assert fresh.linear_solver == "auto" and not fresh.sparse
    assert not isinstance(fresh._engine, SparseEngine)
    fresh.initial_state()                               # decided: well posed, sparse
    assert fresh.sparse and isinstance(fresh._engine, SparseEngine)
    a02 = compiled("a02_n_four_bar")
    assert a02.n_q >= SPARSE_MIN_COORDINATES and a02.sparse
    assert isinstance(a02._engine, SparseEngine)
    forced = CompiledSolver(small.plan, small.module, linear_solver="dense")
    forced.initial_state()
    assert not forced.sparse and not isinstance(forced._engine, SparseEngine)
    forced = CompiledSolver(small.plan, small.module, linear_solver="sparse")
    assert forced.sparse and isinstance(forced._engine, SparseEngine)
    with pytest.raises(ValueError, match="linear_solver must be one of auto, dense, sparse"):
        CompiledSolver(small.plan, small.module, linear_solver="qr")


def test_the_model_file_and_the_command_line_choose_the_path(tmp_path, build_dir, capsys):
    import fccgen
    from fccgen.cli import main
    text = (EXAMPLES / "four_bar.yaml").read_text()
    path = tmp_path / "four_bar_sparse.yaml"
    assert "\nsimulate: {" in text
    path.write_text(text.replace("\nsimulate: {", "\nsimulate: {linear_solver: sparse, ", 1))
    solver = fccgen.load(path, build_dir)
    assert solver.linear_solver == "sparse" and solver.sparse
    assert not fccgen.load(path, build_dir, linear_solver="dense").sparse
    bad = tmp_path / "four_bar_bad.yaml"
    bad.write_text(text.replace("\nsimulate: {", "\nsimulate: {linear_solver: lu, ", 1))
    with pytest.raises(ModelError, match="simulate.linear_solver"):
        fccgen.load(bad, build_dir)
    common = ["simulate", str(EXAMPLES / "four_bar.yaml"), "--build-dir", str(build_dir),
              "-q", "--t-end", "0.01"]
    assert main([*common, "--linear-solver", "sparse"]) == 0
    with pytest.raises(SystemExit):
        main([*common, "--linear-solver", "lu"])
    capsys.readouterr()


def _chain_text(n: int) -> str:
    return example_module("make_n_four_bar").model_text(n)


def test_a_chain_of_over_100_bodies_runs_on_the_sparse_path(tmp_path, build_dir):
    """A02 with N = 50 loops (101 bars, 153 coordinates, 50 redundant rows): the sparse
    path is the default; its run agrees with the dense one and keeps the energy."""
    import fccgen
    path = tmp_path / "a02_50.yaml"
    path.write_text(_chain_text(50))
    solver = fccgen.load(path, build_dir)
    assert len(solver.plan.bodies) > 100 and isinstance(solver._engine, SparseEngine)
    # pattern: a chain stays banded: L has at most a few times the nonzeros of A
    nnz_a, nnz_l = solver._engine.nonzeros
    assert nnz_l < 4 * nnz_a
    dense = CompiledSolver(solver.plan, solver.module, linear_solver="dense")
    rs = solver.simulate(t_end=0.2, dt=1e-3)
    rd = dense.simulate(t_end=0.2, dt=1e-3)
    for column in rd.columns:        # tolerance: see test_one_second_runs_agree...
        assert np.max(np.abs(rd[column] - rs[column])) <= 1e-9 * max(
            1.0, np.max(np.abs(rd[column]))), column
    energy = rs["energy"]            # RK4 at dt 1e-3 with projection: drift ~1e-10
    assert np.max(np.abs(energy - energy[0])) < 1e-7 * abs(energy[0])


def _with_params(plan, element: int, **values):
    import dataclasses
    els = list(plan.elements)
    params = els[element].params.copy()
    for name, value in values.items():
        params[els[element].cls.param_names.index(name)] = value
    els[element] = dataclasses.replace(els[element], params=params)
    return dataclasses.replace(plan, elements=els)


def test_the_sparse_path_reports_a_singular_mass_matrix_and_non_finite_forces(compiled):
    from fccgen.errors import SimulationError
    pendulum = compiled("a01_pendulum")
    plan, module = pendulum.plan, pendulum.module
    body = next(e for _, e in plan.bodies)
    massless = CompiledSolver(_with_params(plan, body, m=0.0, Ixx=0.0, Iyy=0.0, Izz=0.0),
                              module, linear_solver="sparse")
    q, v = plan.q0, np.zeros(plan.n_q)
    with pytest.raises(SimulationError, match="singular on the constraint manifold"):
        massless.accelerations(q, v)
    with pytest.raises(SimulationError, match=r"stopped at t = 0: mass matrix singular.*"
                                              r"RK4 stage 1"):
        massless.simulate(t_end=0.01, q0=q, v0=v)
    infinite = CompiledSolver(_with_params(plan, body, gy=np.inf), module,
                              linear_solver="sparse")
    with pytest.raises(SimulationError, match="non-finite applied forces f in RK4 stage 1"):
        infinite.simulate(t_end=0.01, q0=q, v0=v)


def test_time_dependent_constraints_take_the_same_targets_on_both_paths(compiled):
    """A driver's rows move with t: the velocity projection targets B w = -dg/dt and
    Baumgarte's g' is B v + dg/dt. At t = 0.37 (f' = 10 rad/s, so dg/dt is not zero) both
    paths must give the same projected speeds and Baumgarte accelerations; 1e-10 as in
    the agreement test above (leaving out dg/dt changes them by O(1))."""
    dense, sparse = both(compiled("four_bar_driven"))
    init = dense.initial_state()
    rng = np.random.default_rng(3)
    v = init.v + rng.standard_normal(dense.n_q)
    for s in (dense, sparse):
        s.set_time(0.37)
    gt = dense._asm.quantity(1024, init.q, None)          # ASM_T: dg/dt at t = 0.37
    assert np.max(np.abs(gt)) > 1.0
    wd, ws = dense.project_velocities(init.q, v), sparse.project_velocities(init.q, v)
    assert rel(wd, ws) < 1e-10
    B = dense.constraint_jacobian(init.q)
    assert np.max(np.abs(B @ ws + gt)) < 1e-10 * max(1.0, np.max(np.abs(ws)))
    # Baumgarte at speeds on the moving tangent space (the four-bar's redundant row
    # makes the right-hand side inconsistent for arbitrary speeds, where the two paths
    # resolve it differently; the driver row's g = sin(theta - f) is far from 0 here)
    ad = dense._engine.baumgarte_accelerations(init.q, wd, 5.0, 5.0)
    as_ = sparse._engine.baumgarte_accelerations(init.q, wd, 5.0, 5.0)
    assert rel(ad, as_) < 1e-10
