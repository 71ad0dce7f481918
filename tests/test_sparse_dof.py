"""Changes of the degrees of freedom on the sparse path (runtime/_sparse.pyx): the same
reports as the dense path (fccgen.rank), from a bound on sigma_{r+1} that the sparse
solves keep at every velocity projection, confirmed by the dense path's SVD rule."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen import rank as rank_rule
from fccgen.diagnostics.check import check_model
from fccgen.errors import RunWarning
from fccgen.runtime import CompiledSolver
from fccgen.runtime._sparse import SparseEngine
from test_rank_decision import FLAT_FOUR_BAR, near_flat_four_bar


def paths(solver):
    """(dense, sparse) solvers of one compiled module."""
    return (CompiledSolver(solver.plan, solver.module, linear_solver="dense"),
            CompiledSolver(solver.plan, solver.module, linear_solver="sparse"))


def run(solver, **kw):
    """(result, warning texts) of a run."""
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        result = solver.simulate(**kw)
    return result, [str(w.message) for w in record if w.category is RunWarning]


@pytest.fixture(scope="module")
def flat_four_bar(tmp_path_factory, build_dir):
    path = tmp_path_factory.mktemp("flat") / "flat_four_bar.yaml"
    path.write_text(FLAT_FOUR_BAR)
    return fccgen.load(path, build_dir)


def test_leaving_a_singular_start_is_reported_alike_on_both_paths(flat_four_bar):
    """The four-bar released from its flat position (2 DOF there, 1 once it moves):
    the sparse path reports the change at the same time with the same text, and
    follows the same branch P.y = sin(t) (test_rank_decision)."""
    dense, sparse = paths(flat_four_bar)
    assert isinstance(sparse._engine, SparseEngine)
    rd, wd = run(dense, t_end=1.0, output_dt=0.1)
    rs, ws = run(sparse, t_end=1.0, output_dt=0.1)
    assert rs.info["dof_changes"] == rd.info["dof_changes"] == [
        dict(t=0.001, dof_before=2, dof_after=1)]
    assert (rs.info["dof"], rs.info["final_dof"]) == (2, 1)
    assert ws == wd and any("changed from 2 to 1 at t = 0.001" in w for w in ws)
    assert rs.info["warnings"] == rd.info["warnings"]
    # 1e-9: the branch's closed form; both paths measured 6e-15 from it
    assert np.allclose(rs["P.y"], np.sin(rs.t), atol=1e-9)
    # one SVD confirms the change: the bound passed the trigger at the first step only
    assert rs.info["rank_svd_checks"] == 1


def test_the_bound_that_starts_the_check_is_not_below_the_singular_value(flat_four_bar):
    """The watch's bound ||B_s N||_F at the first projected state is at least
    sigma_{r+1} / sigma_1 there (Courant-Fischer): checked against numpy's SVD of the
    row-scaled B at that state."""
    _, sparse = paths(flat_four_bar)
    result, _ = run(sparse, t_end=0.001, dt=0.001, output_dt=0.001)
    q = np.array([result[f"{p}.{x}"][-1] for p in "PQ" for x in "xyz"])
    assert np.allclose(q[[0, 3]], sparse.plan.q0[[0, 3]])   # the order of q: P, Q
    B = sparse.constraint_jacobian(q)
    sigma = rank_rule.scaled_singular_values(B, sparse.row_groups)
    relative = sigma[4] / sigma[0]                  # the start's rank is 4
    assert relative > rank_rule.GROW_TOL            # it grew: the check had to start
    assert result.info["largest_dropped_pivot"] >= relative * (1 - 1e-12)


def test_a_slow_departure_is_reported_soon_after_the_crossing(tmp_path, build_dir):
    """Released from the flat position at 1e-4 m/s: sigma_5 / sigma_1 passes GROW_TOL
    only after ~20 steps. Both paths confirm by the SVD at the state, so neither
    reports early; the sparse path's next check comes when its bound has grown as
    much as sigma_5 must (at least 2x), so it reports within twice the crossing
    time (measured 0.031 s for a crossing at 0.020 s; the dense path's decade rule
    reports at 0.101 s)."""
    path = tmp_path / "slow_four_bar.yaml"
    path.write_text(FLAT_FOUR_BAR.replace("name: flat_four_bar", "name: slow_four_bar")
                    .replace("{P: [0, 1, 0], Q: [0, 1, 0]}",
                             "{P: [0, 1.0e-4, 0], Q: [0, 1.0e-4, 0]}"))
    dense, sparse = paths(fccgen.load(path, build_dir))
    rs, _ = run(sparse, t_end=0.1, output_dt=0.001)
    rd, _ = run(dense, t_end=0.12, output_dt=0.12)
    t_cross = None
    for i, t in enumerate(rs.t):
        q = np.array([rs[f"{p}.{x}"][i] for p in "PQ" for x in "xyz"])
        sigma = rank_rule.scaled_singular_values(sparse.constraint_jacobian(q),
                                                 sparse.row_groups)
        if sigma[4] > rank_rule.GROW_TOL * sigma[0]:
            t_cross = t
            break
    assert t_cross is not None and 0.01 < t_cross < 0.05
    [change] = rs.info["dof_changes"]
    assert (change["dof_before"], change["dof_after"]) == (2, 1)
    assert t_cross <= change["t"] <= 2 * t_cross + 1e-12
    [change_dense] = rd.info["dof_changes"]
    assert change_dense["t"] >= t_cross


def test_an_uncertain_start_is_said_alike_on_both_paths(tmp_path, build_dir):
    """The parallelogram 1e-8 rad from flat (test_rank_decision): both paths warn that
    the start is close to a singular position and report the same change."""
    path = tmp_path / "near_flat.yaml"
    path.write_text(near_flat_four_bar(1e-8))
    dense, sparse = paths(fccgen.load(path, build_dir))
    rd, wd = run(dense, t_end=0.01)
    rs, ws = run(sparse, t_end=0.01)
    assert ws == wd and any("close to a singular position" in w for w in ws)
    assert rs.info["dof_changes"] == rd.info["dof_changes"]


@pytest.mark.parametrize("name", ["a02_n_four_bar", "bricard", "deployable_joints"])
def test_no_false_alarm_on_redundant_mechanisms(compiled, name):
    """A02 (40 redundant rows, through its flat position at t = 0.75 s), Bricard and
    the deployable with joints on the sparse path for 1 s: no change, no SVD, as on
    the dense path. A02's redundant rows are dependent off the constraints too, so its
    rank cannot grow and the watch stays off (bound 0); Bricard's and the
    deployable's are dependent only on the constraints, so the watch runs and its
    bound stays far below the trigger GROW_TOL = 1e-6 (measured 8.6e-10 and 6.5e-8;
    2.5e-9 on A02 while it ran there), so no SVD was needed."""
    solver = compiled(name)
    sparse = CompiledSolver(solver.plan, solver.module, linear_solver="sparse")
    result, texts = run(sparse, t_end=1.0, dt=1e-3, method="rk4", reactions=False)
    assert texts == []
    assert result.info["dof_changes"] == [] and result.info["rank_svd_checks"] == 0
    assert result.info["dof"] == result.info["final_dof"] == 1
    if name == "a02_n_four_bar":
        assert sparse._engine.watched_directions == 0
        assert result.info["largest_dropped_pivot"] == 0.0
    else:
        assert sparse._engine.watched_directions == 1
        assert 0.0 < result.info["largest_dropped_pivot"] < rank_rule.GROW_TOL


def test_check_reports_the_rank_of_a_model_on_the_sparse_path(compiled):
    """fccgen check on A02 (the sparse path by default): the rank and degrees of
    freedom that a sparse run starts from."""
    solver = compiled("a02_n_four_bar")
    assert solver.sparse
    report = check_model(EXAMPLES / "a02_n_four_bar.yaml")
    assert (report.n_q, report.rank, report.dof) == (123, 122, 1)
    decision = solver.decide_rank(solver.initial_state().q)
    assert (decision.rank, decision.dof) == (report.rank, report.dof)


def test_the_command_line_says_the_change_on_the_sparse_path(flat_four_bar, tmp_path,
                                                             build_dir, capsys):
    from fccgen.cli import main
    path = tmp_path / "flat_four_bar.yaml"
    path.write_text(FLAT_FOUR_BAR)
    assert main(["simulate", str(path), "--build-dir", str(build_dir), "-q",
                 "--t-end", "0.1", "--linear-solver", "sparse"]) == 0
    out, err = capsys.readouterr()
    assert "degrees of freedom 2 by rank, 1 at the end" in out
    assert "fccgen: warning: the degrees of freedom changed from 2 to 1 at t = 0.001" in err


def test_the_watch_runs_only_where_the_rank_can_grow(compiled, flat_four_bar):
    """The watch is left off where the rows dependent at the start are dependent off
    the constraints too (the four-bar's "perpendicular to z" row: its rank cannot
    grow anywhere), and stays on where they are dependent only at the start (the
    flat four-bar), where the growth is still caught."""
    four_bar = compiled("four_bar")
    sparse = CompiledSolver(four_bar.plan, four_bar.module, linear_solver="sparse")
    result, warned = run(sparse, t_end=0.05)
    assert (result.info["dof"], result.info["final_dof"]) == (1, 1)
    assert sparse._engine.watched_directions == 0
    assert result.info["rank_svd_checks"] == 0 and not warned
    _, flat = paths(flat_four_bar)
    rs, ws = run(flat, t_end=0.01, output_dt=0.01)
    assert flat._engine.watched_directions == 1        # 1 DOF after the change
    assert rs.info["dof_changes"] == [dict(t=0.001, dof_before=2, dof_after=1)]
    assert any("changed from 2 to 1" in w for w in ws)
