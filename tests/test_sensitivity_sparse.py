"""rk4 sensitivities on the sparse path (engine/fcc_sens_sparse.c): equal to the dense
path's, and to central differences; models with lock events keep the dense path.

Why 1e-9 between the paths: both integrate the same stage equations and linearised
projections, and differ only in how each linear system is solved (pivoted QR and
Cholesky against the augmented-Lagrangian refinement to rounding): the motions agree
to 2e-14 (measured), the sensitivities to 1.5e-11 of each column's largest value
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


def boom_text(latch=False):
    """The scissor boom of 2 units with damped torsion springs."""
    text = example_module("make_scissor_boom").model_text(2, latch=latch)
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


def test_lock_events_keep_the_dense_path(build_dir):
    """A lock event's rows are carried with dense M and B: linear_solver='sparse' is
    refused with the reason, before anything runs."""
    import fccgen
    path = build_dir / "sens_sparse_boom_latched.yaml"
    path.write_text(boom_text(latch=True))
    solver = fccgen.load(path, build_dir, linear_solver="sparse")
    with pytest.raises(ValueError, match="lock events carry their sensitivities"):
        solver.simulate(**RUN, sensitivities=["bodies.a1.mass"])
