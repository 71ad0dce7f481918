"""Locked rows folded into the sparse factorisation (engine/fcc_sparse_fold.c,
fcc_events_fold.c) against the Schur complement of the same rows (fcc_events.c).

The set-up puts each switchable joint row into the pattern of A; a run folds the used
rows into every factorisation, and result.info["event_rows_folded"] says so. A solver
whose pattern has no such rows (CompiledSolver._switchable_patterns None) takes the
Schur complement. After each switch a run measures a few steps each way and keeps the
cheaper (CompiledSolver._fold_trial, fcc_events_fold.c "Which is cheaper"); the tests
of the fold itself keep it. Both solve the same constrained systems, and differ by the
refinement's rounding (it stops at 1e-15 of |x|), amplified by the motion: hence the
tolerances of tests/test_sparse_events.py, 1e-9 of each column's largest value (or
of 1) and 1e-10 s on the event times (measured 8e-14 on the boom of 3 units over
2 s).
"""
from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest

import fccgen.api as api
from conftest import example_module
from fccgen.errors import RunWarning
from fccgen.runtime import CompiledSolver
from test_sparse_events import assert_same

ROOT = Path(__file__).resolve().parent.parent


def latched_mast_text(n: int) -> str:
    """benchmarks/sparse_events.py's scissor mast of n bays with a latch per bay, its
    latches locked from its first step (the benchmark's "locked" variant: in the
    natural run the first latch takes the mast's one DOF and the others never
    cross)."""
    spec = importlib.util.spec_from_file_location(
        "sparse_events_bench", ROOT / "benchmarks" / "sparse_events.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.variants(module.latched_mast(n))[0]


def run(solver, t_end, schur=False, patterns=None, monkeypatch=None, trial=False,
        engine=None):
    """A sparse RK4 run of a fresh solver of solver's model: folded (the set-up's
    patterns, or patterns), or with the Schur complement (no rows in the pattern);
    trial: choosing between them after each switch (the default of simulate).
    engine: a dict that receives the fresh solver's engine statistics."""
    if schur or patterns is not None:
        monkeypatch.setattr(CompiledSolver, "_switchable_patterns",
                            None if schur else patterns)
    fresh = CompiledSolver(solver.plan, solver.module, linear_solver="sparse",
                           events_module=solver.events_module)
    fresh._fold_trial = trial
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        result = fresh.simulate(t_end=t_end, dt=1e-3, method="rk4", reactions=False)
    if engine is not None:
        engine.update(fresh._engine.rank_statistics())
    return result


@pytest.fixture(scope="module")
def mast3(build_dir, tmp_path_factory):
    """The mast of 3 bays whose three latches lock in its first step."""
    path = tmp_path_factory.mktemp("mast") / "mast3.yaml"
    path.write_text(latched_mast_text(3))
    return api.load(path, build_dir, linear_solver="sparse")


@pytest.fixture(scope="module")
def mast12(build_dir, tmp_path_factory):
    """The mast of 12 bays whose twelve latches lock in its first step."""
    path = tmp_path_factory.mktemp("mast") / "mast12.yaml"
    path.write_text(latched_mast_text(12))
    return api.load(path, build_dir, linear_solver="sparse")


@pytest.mark.parametrize("bays", [3, 12])
def test_each_switch_keeps_the_cheaper_way(bays, request, monkeypatch):
    """After the latches lock (in the first step), a run takes 4 steps folded and 4
    with the Schur complement, keeps the one whose solves cost less, and measures
    again 1000 steps later: two choices in 1.2 s. Which is cheaper depends on the
    model, not its size: whole runs forced each way, the independent signal, take the
    same factorisations and fewer refinement steps folded on the mast of 3 bays
    (measured over 1.2 s: 13,253 against 24,048), fewer through the Schur complement
    on the mast of 12 (24,149 against 43,348: its folded row makes every solve slow,
    while the Schur complement's converge in two steps at 0 DOF). The run that
    chooses keeps the cheaper of the two every time (13,339 and 24,309 steps: the
    trials' 8 steps twice cost under 5 % more), and equals both forced runs to
    test_sparse_events.py's tolerances."""
    solver = request.getfixturevalue(f"mast{bays}")
    chosen = run(solver, 1.2, trial=True)
    folded = run(solver, 1.2)
    schur = run(solver, 1.2, schur=True, monkeypatch=monkeypatch)
    fold_cheaper = folded.info["sparse_iterations"] < schur.info["sparse_iterations"]
    assert fold_cheaper is (bays == 3)
    assert chosen.info["event_fold_trials"] == 2
    assert chosen.info["event_fold_trials_folded"] == (2 if fold_cheaper else 0)
    assert chosen.info["event_rows_folded"] is fold_cheaper
    cheaper = folded if fold_cheaper else schur
    assert chosen.info["sparse_iterations"] < 1.05 * cheaper.info["sparse_iterations"]
    names = [f"latch{k}" for k in range(bays)]
    assert_same(folded, chosen, names)
    assert_same(schur, chosen, names)


def test_latched_mast_folded_as_schur(mast3, monkeypatch):
    """The mast of 3 bays to 0.3 s, its three latches locking in one step (1 -> 0
    DOF, two of the rows redundant): folded, the same run as with the Schur
    complement, in fewer solves (one refinement per stage instead of one more per
    used row)."""
    folded = run(mast3, 0.3)
    schur = run(mast3, 0.3, schur=True, monkeypatch=monkeypatch)
    assert folded.info["event_rows_folded"] and folded.info["event_fold_left"] == 0
    assert not schur.info["event_rows_folded"]
    assert_same(schur, folded, [f"latch{k}" for k in range(3)])
    assert [e["dof"] for e in folded.events][-1] == 0
    assert folded.info["sparse_solves"] < schur.info["sparse_solves"]


def test_a_row_outside_its_pattern_leaves_the_fold(build_dir, tmp_path, monkeypatch):
    """The boom of 3 units whose latch row is given a pattern without one of the
    coordinates its gradient reads: the first fill after the latch finds it, the run
    leaves the fold for the Schur complement (counted) and equals the folded run."""
    path = tmp_path / "boom3.yaml"
    path.write_text(example_module("make_scissor_boom").model_text(3))
    solver = api.load(path, build_dir)
    folded = run(solver, 1.0)
    rows = solver._switchable_patterns
    pinned = set(int(i) for i in solver._engine.pinned_coordinates[0])
    free = [[i for i in r if int(i) not in pinned] for r in rows]
    cut = [np.array(f[:-1], dtype=np.intp) for f in free]     # one coordinate less
    assert any(len(f) for f in free)
    broken = run(solver, 1.0, patterns=cut, monkeypatch=monkeypatch)
    assert folded.info["event_rows_folded"] and folded.info["event_fold_left"] == 0
    assert not broken.info["event_rows_folded"] and broken.info["event_fold_left"] == 1
    assert_same(broken, folded, ["latch"])


def test_a_tie_of_locks_solves_each_rows_response_once(mast3):
    """The mast's three latches lock at one instant, one after the other: each switch
    decides the used rows among all held ones, whose responses at that instant are
    solved once (engine/fcc_event_actions.c, response_at): 3 solves, not 1 + 2 + 3
    (and as many again for the impacts). The run is the dense path's, whose
    decisions take the SVD, to test_sparse_events.py's tolerances; the first lock
    takes the mast's one DOF and the other two are redundant."""
    sparse = run(mast3, 0.01)
    dense = CompiledSolver(mast3.plan, mast3.module, linear_solver="dense",
                           events_module=mast3.events_module)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        rd = dense.simulate(t_end=0.01, dt=1e-3, method="rk4", reactions=False)
    names = [e["name"] for e in sparse.events]
    assert sorted(names) == [f"latch{k}" for k in range(3)]
    assert len({e["t"] for e in sparse.events}) == 1
    assert_same(rd, sparse, names)
    assert [e["dof"] for e in sparse.events] == [0, 0, 0]
    assert sparse.info["event_switch_solves"] == 3


def test_a_tie_of_locks_factors_once(mast3, build_dir, tmp_path):
    """The next lock of a tie acts at the q of the one before, with no factorisation
    in between: it starts from that lock's factor and from the v its impact left,
    which B v = 0 holds already (engine/fcc_event_actions.c, fcc_ev_apply), instead
    of assembling and factoring the same matrix again and projecting v once more. So
    the first step of the mast whose three latches lock at one instant takes as many
    factorisations as the same mast with one latch (measured 20 and 20; 24 latches
    took 43 against 20 before: one more per lock and the slow solves' boosted
    factors), and one more solve per extra lock, its row's response (two before,
    with the velocity projection); the states are those of the dense path
    (test_a_tie_of_locks_solves_each_rows_response_once)."""
    head, events = latched_mast_text(3).split("events:\n")
    kept = [line for line in events.splitlines()[1:] if not line.startswith("  - ")]
    path = tmp_path / "mast3_one_latch.yaml"
    path.write_text(head + "events:\n" + events.splitlines()[0] + "\n"
                    + "\n".join(kept) + "\n")
    one = api.load(path, build_dir, linear_solver="sparse")
    counts = {}
    for name, solver in (("three", mast3), ("one", one)):
        stats = {}
        result = run(solver, 1e-3, engine=stats)
        counts[name] = (len(result.events), stats["factorisations"],
                        result.info["sparse_solves"])
    assert counts["three"][0] == 3 and counts["one"][0] == 1
    assert counts["three"][1] == counts["one"][1], counts
    assert counts["three"][2] == counts["one"][2] + 2, counts


def test_held_rows_folded_do_not_start_an_svd_of_b(mast3, monkeypatch):
    """The rank-growth watch (engine/fcc_sparse_watch.c) tracks the null space of B
    through the factor; with the locked rows folded into it, that factor takes the
    direction the latches hold (B's null space is unchanged), which started an SVD
    check of B in the first step (a dense SVD: 22.6 s for the 5025 x 3024 B of a mast
    of 167 bays, docs/performance.md). The watch keeps its basis while rows are
    held: no check, on the folded
    run as on the Schur complement's, and the rank is B's as before."""
    folded = run(mast3, 0.05)
    schur = run(mast3, 0.05, schur=True, monkeypatch=monkeypatch)
    assert folded.info["event_rows_folded"] and not schur.info["event_rows_folded"]
    assert folded.info["rank_svd_checks"] == schur.info["rank_svd_checks"] == 0
    assert folded.info["dof_changes"] == schur.info["dof_changes"] == []
