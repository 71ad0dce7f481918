"""The rank decisions made without a dense SVD of a component (fccgen.rank.sparse, the
off-constraint test of CompiledSolver._manifold_redundancy) equal the SVD's on the
examples with redundant rows, at the start and a little off the constraints; where
the sparse test cannot certify the gap it says so and the SVD decides."""
from __future__ import annotations

import numpy as np
import pytest

import bricard
import fccgen
from conftest import example_module
from fccgen import rank as rank_rule
from fccgen.rank import sparse as rank_sparse
from fccgen.runtime import setup_reuse
from fccgen.runtime.solver import OFF_MANIFOLD, OFF_MANIFOLD_SEED

EXAMPLES = ["bricard", "deployable", "deployable_joints", "four_bar", "a02_n_four_bar"]


def _points(solver):
    """The start (assembled) and the off-constraint point of _manifold_redundancy."""
    q = np.asarray(solver.initial_state().q, float)
    rng = np.random.default_rng(OFF_MANIFOLD_SEED)
    return q, q + OFF_MANIFOLD * solver.length_scale * rng.standard_normal(q.size)


def _agree(solver) -> list[str]:
    """Every component above one coordinate through the sparse test (dense_max 1):
    the rank equals the SVD's at both points; returns how each was decided."""
    how = []
    for q in _points(solver):
        B = solver.constraint_jacobian_sparse(q)
        svd = rank_sparse.decide_large(B, solver.n_q, solver.row_groups,
                                       dense_max=10 ** 9)
        new = rank_rule.decide(B, solver.n_q, solver.row_groups, dense_max=1)
        assert svd.how == "svd"
        assert new.rank == svd.rank, (new.how, new.rank, svd.rank)
        assert new.how == "certified" or new.how.startswith("svd (")
        if new.how == "certified":
            # its gap is the SVD's: sigma_r / sigma_1 (Lanczos) to 2e-3, and the
            # first dropped one (a bound) below the rule's clear zero, as the SVD's
            assert new.gap[0] == pytest.approx(svd.gap[0], rel=2e-3)
            assert max(new.gap[1], svd.gap[1]) <= rank_rule.AMBIGUOUS_LOW
        how.append(new.how)
        # what the off-constraint test takes: the rank alone, by inverse iteration
        only = rank_rule.decide(B, solver.n_q, solver.row_groups, dense_max=1,
                                rank_only=True)
        assert only.rank == svd.rank, (only.how, only.rank, svd.rank)
        assert only.how == "certified" or only.how.startswith("svd (")
    return how


@pytest.mark.parametrize("name", EXAMPLES)
def test_the_sparse_decision_equals_the_svd_on_the_examples(compiled, name):
    _agree(compiled(name))


def test_bricard_flat_four_bar_and_mast_agree(tmp_path, build_dir):
    """Bricard in its distance encoding, the A02 chain of 30 (planar: 60 redundant
    rows) and a 4-bay scissor mast: the chain's and the mast's components are
    certified without an SVD."""
    texts = {"bricard_distance": bricard.text("distance"),
             "chain": example_module("make_n_four_bar").model_text(30),
             "mast": example_module("make_scissor_mast").model_text(4)}
    hows = {}
    for name, text in texts.items():
        path = tmp_path / f"{name}.yaml"
        path.write_text(text, encoding="utf-8")
        hows[name] = _agree(fccgen.load(path, build_dir))
    assert hows["chain"] == ["certified", "certified"]
    assert "certified" in hows["mast"]


def test_an_uncertifiable_component_falls_back_to_the_svd_and_says_so():
    """A component whose nullity exceeds MAX_NULLITY cannot be certified: the SVD
    decides and ``how`` names the fallback."""
    n = rank_sparse.MAX_NULLITY + 12
    B = np.zeros((n - 1, n))
    for k in range(n - 1):
        B[k, k], B[k, k + 1] = 1.0, -1.0          # a path: nullity 1, certified
    decision = rank_rule.decide(B, n, None, dense_max=1)
    assert decision.rank == n - 1 and decision.how == "certified"
    wide = np.hstack([B, np.tile(B[:, -1:], (1, rank_sparse.MAX_NULLITY + 1))])
    decision = rank_rule.decide(wide, wide.shape[1], None, dense_max=1)
    assert decision.rank == n - 1
    assert decision.how.startswith("svd (the sparse test could not certify")


def test_info_says_how_the_setup_decided_and_reuse_follows_the_jacobian(compiled):
    """info["setup"] names each decision's method; a solver of other masses takes the
    decisions kept for the same Jacobian (masses do not enter B), one of other
    geometry (a point moved) decides afresh, and each gives its own run."""
    setup_reuse.forget()
    solver = compiled("a02_n_four_bar").with_parameters({})
    first = solver.simulate(t_end=0.01, dt=1e-3, reactions=False)
    setup = first.info["setup"]
    assert setup["rank_decision"]["reused"] is False
    assert setup["rank_decision"]["method"] == "svd"
    assert setup["off_constraint_test"]["method"] in ("svd", "certified")
    heavier = solver.with_parameters({"bodies.rocker0.mass": 3.0})
    run = heavier.simulate(t_end=0.01, dt=1e-3, reactions=False)
    assert run.info["setup"]["rank_decision"]["reused"] is True
    assert run.info["setup"]["off_constraint_test"]["reused"] is True
    setup_reuse.forget()
    fresh = solver.with_parameters({"bodies.rocker0.mass": 3.0}).simulate(
        t_end=0.01, dt=1e-3, reactions=False)
    assert fresh.info["setup"]["rank_decision"]["reused"] is False
    for name, column in run.columns.items():
        np.testing.assert_array_equal(column, fresh.columns[name], err_msg=name)
    moved = solver.with_parameters({"points.B0.at": [0.0, 1.01, 0.0]})
    assert moved.simulate(t_end=0.01, dt=1e-3, reactions=False).info[
        "setup"]["rank_decision"]["reused"] is False


def test_components_are_the_connected_parts_of_the_coordinate_graph():
    """components() against the definition, on random sparse B with empty rows, empty
    columns and stored zeros: each coordinate in exactly one part, every entry of a
    row inside its part's columns, rows and columns ascending, no part splittable (a
    part's columns are reached from its first one through its rows)."""
    import scipy.sparse as sp
    rng = np.random.default_rng(3)
    for trial in range(60):
        m, n = (int(x) for x in rng.integers(1, 30, 2))
        B = sp.random(m, n, density=float(rng.uniform(0.02, 0.25)), random_state=trial,
                      format="csr")
        if B.nnz:
            B.data[0] = 0.0                      # a stored zero is no edge
        parts = rank_sparse.components(B)
        dense = B.toarray() != 0.0
        cols = np.concatenate([c for _, c in parts])
        assert np.array_equal(np.sort(cols), np.arange(n))
        rows = np.concatenate([r for r, _ in parts])
        assert np.array_equal(np.sort(rows), np.flatnonzero(dense.any(axis=1)))
        for r, c in parts:
            assert np.all(np.diff(r) > 0) and np.all(np.diff(c) > 0)
            outside = np.setdiff1d(np.arange(n), c)
            assert not dense[np.ix_(r, outside)].any()
            reached, frontier = {int(c[0])}, [int(c[0])]
            while frontier:
                j = frontier.pop()
                for i in np.flatnonzero(dense[:, j]):
                    for k in np.flatnonzero(dense[i]):
                        if int(k) not in reached:
                            reached.add(int(k))
                            frontier.append(int(k))
            assert reached == set(int(x) for x in c)


@pytest.mark.parametrize("name", EXAMPLES)
def test_the_decisions_from_the_dense_and_the_sparse_jacobian_are_equal(compiled, name):
    """A run's decisions read B sparse above SPLIT_COLUMNS coordinates
    (CompiledSolver._jacobian_for_decision): the same entries, so the same decision,
    bit for bit, as from the dense B, at the start and off the constraints, both
    ways of deciding (all singular values; the rank only, component-wise above
    SPLIT_COLUMNS)."""
    solver = compiled(name)
    for q in _points(solver):
        dense, sparse = solver.constraint_jacobian(q), solver.constraint_jacobian_sparse(q)
        assert np.array_equal(sparse.toarray(), dense)
        # what fccgen.rank.decide takes above SPLIT_COLUMNS: the start decision
        # (components up to DENSE_COMPONENT by their SVD), the off-constraint test
        # (rank only, above SPLIT_COLUMNS certified), every component certified
        for dense_max, rank_only in ((rank_sparse.DENSE_COMPONENT, False),
                                     (rank_rule.SPLIT_COLUMNS, True), (1, False)):
            a = rank_sparse.decide_large(dense, solver.n_q, solver.row_groups,
                                         dense_max, rank_only)
            b = rank_sparse.decide_large(sparse, solver.n_q, solver.row_groups,
                                         dense_max, rank_only)
            assert (a.rank, a.sigma, a.gap, a.how) == (b.rank, b.sigma, b.gap, b.how)
