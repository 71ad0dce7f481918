"""rk4 sensitivities on the sparse path (engine/fcc_sens_sparse.c): equal to the dense
path's, and to central differences, through lock events too; what needs the dense path
(dopri5, geometry keys) takes it under linear_solver="auto", with a note.

Why 1e-9 between the paths: both integrate the same stage equations and linearised
projections, and differ only in how each linear system is solved (pivoted QR and
Cholesky against the augmented-Lagrangian refinement to rounding): the motions agree
to 2e-14 (measured), the sensitivities to 2.4e-11 of each column's largest value
(with a floor of 1e-3 of the key's largest derivative of any column, for columns
whose derivative is nearly zero; measured on both models). The bound is 1e-9: room
for rounding, yet it fails the stage multipliers taken straight from the refinement
(accurate to RHO eps ~ 2e-9 of themselves only; they gave 7e-9 on the boom's energy),
which fcc_sens_sparse.c corrects once.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import example_module

from test_sensitivity_runs import check_against_differences, state_columns

RUN = dict(t_end=0.3, dt=1e-3, method="rk4")
BOOM_KEYS = ["loads[0].stiffness", "loads[1].damping", "bodies.a1.mass"]
A02_KEYS = ["bodies.rocker1.mass", "bodies.coupler2.mass"]


def boom_text(latch=False, units=2):
    """The scissor boom of 2 units (units) with damped torsion springs."""
    text = example_module("make_scissor_boom").model_text(units, latch=latch)
    return text.replace("angle:", "damping: 0.05, angle:")


@pytest.fixture(scope="session")
def paths(build_dir):
    """paths(name) -> (solver on the sparse path, on the dense path)."""
    import fccgen
    texts = {"boom": boom_text(), "a02": example_module("make_n_four_bar").model_text(3)}
    cache = {}

    def get(name):
        if name not in cache:
            path = build_dir / f"sens_sparse_{name}.yaml"
            path.write_text(texts[name])
            cache[name] = tuple(fccgen.load(path, build_dir, linear_solver=ls)
                                for ls in ("sparse", "dense"))
        return cache[name]
    return get


@pytest.fixture(scope="session")
def runs(paths):
    cache = {}

    def get(name, keys):
        if name not in cache:
            cache[name] = tuple(s.simulate(**RUN, reactions=False, sensitivities=keys) for s in paths(name))
        return cache[name]
    return get


@pytest.mark.parametrize("name, keys", [("boom", BOOM_KEYS), ("a02", A02_KEYS)])
def test_sparse_equals_dense(runs, name, keys):
    sparse, dense = runs(name, keys)
    assert sparse.info["sensitivity_path"] == "sparse"
    assert dense.info["sensitivity_path"] == "dense"
    assert_paths_agree(sparse, dense, keys, name)


def assert_paths_agree(sparse, dense, keys, name):
    """Each state column's derivative to 1e-9 of its largest value (floor: 1e-3 of
    the key's largest derivative)."""
    for key in keys:
        cols = state_columns(dense, key)
        big = max(np.max(np.abs(dense.sensitivity(c, key))) for c in cols)
        assert big > 0, key
        for c in cols:
            want = dense.sensitivity(c, key)
            scale = max(np.max(np.abs(want)), 1e-3 * big)
            error = np.max(np.abs(sparse.sensitivity(c, key) - want))
            assert error <= 1e-9 * scale, (name, key, c, error / scale)


def test_sparse_matches_central_differences(paths, runs):
    """The module test_sensitivity_runs's comparison (1e-7, Richardson-checked steps),
    with the differences' runs on the sparse path too."""
    solver = paths("boom")[0]
    result = runs("boom", BOOM_KEYS)[0]
    columns = state_columns(result, BOOM_KEYS[0])
    for key in BOOM_KEYS:
        assert check_against_differences(result, solver, key, columns, RUN,
                                         label="boom sparse", normwise=True) >= 1, key


def test_latched_boom_auto_takes_the_sparse_path(build_dir):
    """The latched boom under linear_solver="auto": its own path is the sparse one, and
    its run with sensitivities takes it through the latches, equal to the dense path's
    (1e-9, as above; the latch times' derivatives too)."""
    import fccgen
    path = build_dir / "sens_sparse_boom_latched.yaml"
    path.write_text(boom_text(latch=True))
    auto = fccgen.load(path, build_dir)
    dense = fccgen.load(path, build_dir, linear_solver="dense")
    assert auto.sparse
    run = dict(RUN, t_end=0.6, reactions=False, sensitivities=["bodies.a1.mass"])
    sparse_run, dense_run = auto.simulate(**run), dense.simulate(**run)
    assert sparse_run.info["sensitivity_path"] == "sparse"
    assert "lock" in [e["action"] for e in dense_run.events]
    key = "bodies.a1.mass"
    assert_paths_agree(sparse_run, dense_run, [key], "latched boom")
    for a, b in zip(sparse_run.events, dense_run.events):
        t_key = f"d(time)/d({key})"
        assert abs(a[t_key] - b[t_key]) <= 1e-9 * max(abs(b[t_key]), 1e-12)


def test_auto_takes_the_dense_path_where_it_must(paths, build_dir):
    """dopri5 under linear_solver="auto" on a model whose own path is the sparse one:
    the dense path, and info says why."""
    import fccgen
    path = build_dir / "sens_sparse_boom_auto.yaml"
    path.write_text(boom_text())
    auto = fccgen.load(path, build_dir)
    assert auto.sparse
    r = auto.simulate(t_end=0.05, method="dopri5", rtol=1e-6, atol=1e-9,
                      reactions=False, sensitivities=["bodies.a1.mass"])
    assert r.info["sensitivity_path"] == "dense"
    assert "dopri5" in r.info["sensitivity_path_note"]


def test_linear_directions_are_found_once_per_solver(paths, monkeypatch):
    """A second call's linear keys come from the solver's own record, equal to the
    first; another solver (with_parameters) finds its own."""
    from fccgen.runtime.sensitivity import parameters
    solver = paths("boom")[0]
    first = parameters.directions(solver, BOOM_KEYS)

    def refused(*args):
        raise AssertionError("the directions were found again")
    monkeypatch.setattr(parameters, "_shifted", refused)
    again = parameters.directions(solver, BOOM_KEYS[::-1])
    assert np.array_equal(again[0], first[0][::-1])
    assert np.array_equal(again[1], first[1][::-1])
    other = solver.with_parameters({"bodies.a1.mass": 2.0})
    with pytest.raises(AssertionError, match="found again"):
        parameters.directions(other, BOOM_KEYS[:1])


def test_stage_solves_start_near_their_answer(build_dir, tmp_path):
    """The sensitivities' solves on the sparse path (6 per step and key: 4 stages, 2
    projections) take about 2 solves with the factor each, the refinement's least
    (a first pass and the one that shows it converged): the stages half a step after
    the one before (2 and 4) start from multipliers extrapolated in time
    (engine/fcc_sens.c, rk4_warm). Measured on the damped boom of 3 units: 2.001 per
    solve (1 and 3 keys), against 2.31 and 2.25 when those stages started from the
    previous stage's multipliers (about 3 solves each for stages 2 and 4; 5 on the
    boom of 7 units). Counts, not times: the bound 2.1 holds them to rounding's
    changes in when a refinement stops."""
    import fccgen
    path = tmp_path / "sens_sparse_boom3.yaml"
    path.write_text(boom_text(units=3))
    solver = fccgen.load(path, build_dir, linear_solver="sparse")
    solver.simulate(**RUN, reactions=False)
    plain = solver._engine.rank_statistics()
    for keys in (BOOM_KEYS[:1], BOOM_KEYS):
        result = solver.simulate(**RUN, reactions=False, sensitivities=keys)
        stats = solver._engine.rank_statistics()
        assert result.info["sensitivity_path"] == "sparse"
        solves = stats["sparse_solves"] - plain["sparse_solves"]
        assert solves == 6 * result.info["steps"] * len(keys)
        assert stats["sparse_unconverged"] == plain["sparse_unconverged"] == 0
        with_factor = stats["sparse_iterations"] - plain["sparse_iterations"]
        assert 2.0 <= with_factor / solves <= 2.1, (keys, with_factor / solves)
