"""Sensitivities to geometry keys (fccgen.runtime.sensitivity.geometry): points'
positions, a load's point, a distance constraint's length.

Reference: Richardson central differences of the same fixed-step runs at p +- d
(tests/test_sensitivity_runs.py check_against_differences: 1e-7 of each column's
largest derivative where the differences are in their asymptotic range), with
d = 1e-5 m for a coordinate that is 0 (its own 1e-4 |p| would be rounding). The
cases cover each way a key reaches the run:
- the double pendulum: a moving point (P2, P1: the bodies' lengths, angles and mass
  centres in their bases change, the start moves with the point), a fixed point (O:
  the fixed point's parameters), and, with initial speeds, the speeds' projection;
- the four-bar with a distance constraint (tests/data/four_bar_distance.yaml): its
  length and the fixed pivot C are not in the written positions' constraints, so the
  assembled start moves by the linearised projection; the force's body point enters
  the kernels only;
- the four-bar of examples/four_bar.yaml: a redundant row (rank 5 of 6). Moving B
  at dt = 1 ms leaves 2.8e-7 relative (the run's linearised projections' drift-sized
  terms, docs/sensitivities.md; the start's derivative is exact to 1e-13 there) and
  4e-10 at 0.5 ms, so it runs at 0.5 ms over 0.15 s.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from test_sensitivity_runs import check_against_differences, state_columns

from fccgen.errors import ModelError
from fccgen.runtime.sensitivity import geometry
from fccgen.runtime.sensitivity.parameters import current_value

RUN = dict(t_end=0.3, dt=1e-3, method="rk4")
CASES = {
    "double_pendulum": (["points.P2.at[0]", "points.P1.at[1]", "points.O.at[1]"], {}),
    "double_pendulum_moving": (["points.P2.at[0]", "points.P1.at[1]"], {}),
    "four_bar_distance": (["constraints[0].length", "points.C.at[0]", "points.A.at[1]",
                           "loads[0].at[0]"], {}),
    "four_bar": (["points.C.at[0]", "points.B.at[1]"], dict(dt=5e-4, t_end=0.15)),
}


@pytest.fixture(scope="session")
def geometry_solver(compiled, build_dir):
    import fccgen
    cache = {}

    def get(name):
        if name not in cache:
            if name == "four_bar_distance":
                cache[name] = fccgen.load(ROOT / "tests" / "data" / f"{name}.yaml",
                                          build_dir)
            elif name == "double_pendulum_moving":     # initial speeds to project
                cache[name] = compiled("double_pendulum").with_parameters(
                    {"initial.points.P2[0]": 0.5, "initial.points.P2[1]": 0.3})
            else:
                cache[name] = compiled(name)
        return cache[name]
    return get


@pytest.mark.parametrize("name", list(CASES))
def test_geometry_keys_match_central_differences(geometry_solver, name):
    solver = geometry_solver(name)
    keys, step = CASES[name]
    run = {**RUN, **step}
    result = solver.simulate(**run, reactions=False, sensitivities=keys)
    columns = state_columns(result, keys[0])
    for key in keys:
        x = abs(current_value(solver.plan.model, key))
        rel = 1e-4 if x > 0.05 else 1e-5 / max(x, 1e-3)
        strict = check_against_differences(result, solver, key, columns, run, rel=rel,
                                           label=name)
        assert strict >= 1, (name, key, "no column's step in its asymptotic range")


def test_moving_start_against_the_assembly(geometry_solver):
    """The distance's length and the pivot C move the assembled start (B turns about
    C): dq0/dp from the linearised projection against central differences of the
    starts Newton assembles at p +- d and p +- d/2, d = 1e-4, combined by Richardson.
    Measured: the plain differences differ from dq0/dp by 2e-7 at d = 1e-4 and 2e-9 at
    1e-5 relative (O(d^2): the linearised projection is the assembly's derivative);
    Richardson's value leaves Newton's own stopping error divided by d (position_tol
    1e-11 of the model's length): 1e-8 of the largest |dq0/dp|. The start's derivative
    is no small correction (its largest entry is order 1 m/m)."""
    from fccgen.runtime.sensitivity.parameters import directions
    solver = geometry_solver("four_bar_distance")
    n, d = solver.plan.n_q, 1e-4
    for key in ("constraints[0].length", "points.C.at[0]"):
        _, S0 = directions(solver, [key])
        x = current_value(solver.plan.model, key)
        start = {s: np.asarray(solver.with_parameters({key: x + s}).initial_state().q)
                 for s in (d, -d, d / 2, -d / 2)}
        d1 = (start[d] - start[-d]) / (2 * d)
        d2 = (start[d / 2] - start[-d / 2]) / d
        want = (4 * d2 - d1) / 3
        assert np.max(np.abs(want)) > 0.1, key
        assert np.max(np.abs(S0[0, :n] - want)) <= 1e-8 * np.max(np.abs(want)), key
        assert not np.any(S0[0, n:]), key            # released from rest, no drivers


@pytest.mark.parametrize("key, words", [
    ("vectors.z.along[0]", "unit vector"),
    ("points.P1.at[2]", "structural zero"),
])
def test_refused_geometry_keys(compiled, key, words):
    with pytest.raises(ModelError) as info:
        compiled("double_pendulum").simulate(**RUN, sensitivities=[key])
    assert words in str(info.value) and key in str(info.value)


def test_start_assembled_away_is_refused(geometry_solver):
    """A distance length off the written positions: Newton moves the start, along a
    path whose derivative is not taken."""
    off = geometry_solver("four_bar_distance").with_parameters({"constraints[0].length": 0.31})
    with pytest.raises(ModelError, match="assembled away from the written positions"):
        off.simulate(**RUN, sensitivities=["points.A.at[1]"])


class _Rows:
    """A stand-in for a solver's M and B at the start (two coordinates, two rows)."""
    def __init__(self, B):
        self.B = np.array(B, float)

    def mass_matrix(self, q):
        return np.diag([2.0, 1.0])

    def constraint_jacobian(self, q):
        return self.B


def test_linearised_projection_and_broken_redundancy():
    """Two copies of one row: consistent changes give the M-orthogonal projection;
    changes that disagree (the key breaks the redundancy) give None, never a
    least-squares compromise."""
    q0, dqw = np.zeros(2), np.array([0.3, 0.7])
    rows = _Rows([[1.0, 0.0], [1.0, 0.0]])
    y = geometry._linearised_projection(rows, q0, dqw, np.array([0.5, 0.5]))
    assert np.allclose(y, [-0.5, 0.7], rtol=0, atol=1e-14)
    assert geometry._linearised_projection(rows, q0, dqw, np.array([0.5, 0.6])) is None


def test_richardson_refuses_a_kink():
    """A smooth function's derivative to 1e-12 with a small disagreement; a kink at
    the value (max(s, 0)^2) disagrees by its own size."""
    h = 1e-2
    steps = (h, -h, h / 2, -h / 2, h / 4, -h / 4)
    smooth, worst = geometry.richardson({s: [np.array([np.sin(1 + s)])] for s in steps},
                                        h, (1.0,))
    assert abs(smooth[0][0] - np.cos(1)) < 1e-12 and worst < geometry.AGREE
    _, worst = geometry.richardson({s: [np.array([max(s, 0.0) ** 2])] for s in steps},
                                   h, (1.0,))
    assert worst > 0.5


def test_geometry_keys_on_the_sparse_path_are_refused_before_the_run():
    """The sparse path holds a planar model's out-of-plane coordinates fixed, and a
    geometry key can move them: its solves would leave that change out. A solver
    loaded on the sparse path is told so, and what works, before anything runs."""
    import fccgen
    solver = fccgen.load(ROOT / "examples" / "double_pendulum.yaml", linear_solver="sparse")
    with pytest.raises(ValueError, match="dense path only"):
        solver.simulate(t_end=0.01, dt=1e-3, method="rk4",
                        sensitivities=["points.P2.at[0]"])
