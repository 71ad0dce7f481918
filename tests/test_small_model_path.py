"""The path "auto" takes for models below SPARSE_MIN_COORDINATES (runtime/paths.py):
the sparse one where the rank decision at a run's start shows its solve well posed,
the dense one for rows dependent only on the constraint manifold, weakly kept
directions of B, and motions so light that the sparse factor would lose their pivot.
Each excluded kind is shown failing or retrying when forced onto the sparse path, so
the rule is not a guess."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import test_extremes_models as em
from conftest import EXAMPLES
from fccgen.errors import RunWarning, SimulationError
from fccgen.runtime import CompiledSolver, paths
from fccgen.runtime._sparse import SparseEngine

# (examples with events too: both paths run them, engine/fcc_events.c)
SPARSE = ["a01_pendulum", "double_pendulum", "four_bar", "four_bar_driven", "free_body",
          "rsup", "spatial_double_pendulum", "spherical_pendulum",
          "solar_array_boom_latched", "tape_spring_hinge", "panel_latch", "panel_input",
          "tape_spring_table", "pendulum_limit", "solar_array", "solar_array_input"]
# examples of SPARSE_MIN_COORDINATES coordinates or more (members' nodes and slopes)
LARGE = {"a02_n_four_bar", "scissor_boom", "cantilever", "flexible_pendulum",
         "solar_array_boom", "andrews"}
MANIFOLD = ["bricard", "deployable", "deployable_joints"]     # dense: the rows' kind


@pytest.fixture(scope="module")
def load(tmp_path_factory, build_dir):
    return em.make_loader(tmp_path_factory.mktemp("small_model_path"), build_dir)


def test_every_small_example_is_named_here():
    small = {p.stem for p in EXAMPLES.glob("*.yaml")} - LARGE
    assert small == set(SPARSE + MANIFOLD)


@pytest.mark.parametrize("name", SPARSE + MANIFOLD)
def test_auto_takes_the_sparse_path_on_the_small_examples_it_suits(compiled, name):
    shared = compiled(name)
    solver = CompiledSolver(shared.plan, shared.module, events_module=shared.events_module)
    assert solver.n_q < paths.SPARSE_MIN_COORDINATES and not solver.sparse
    solver.initial_state()                       # the first rank decision
    assert solver.sparse == (name in SPARSE)
    assert isinstance(solver._engine, SparseEngine) == (name in SPARSE)
    assert solver.settings()["path"] == ("sparse" if name in SPARSE else "dense")


def tilted(gamma):
    return em.tilted_body([math.cos(gamma), math.sin(gamma), 0.0], [0.3, 0.1, 0.05],
                          np.diag([0.02, 0.04, 0.05]), [1.0, 2.0, 3.0])


def light_second_rod(ratio=1e-10):
    p = dict(m1=1.0, c1=0.5, Ia1=2e-4, It1=0.0834333333333333, m2=0.6 * ratio, c2=0.4,
             Ia2=1.2e-4 * ratio, It2=0.03206 * ratio, g=9.81)
    return em.double_pendulum(p, [0.8, -0.6, 0], [1.6, -0.6, 0])


def test_a_weakly_kept_direction_takes_the_dense_path(load):
    """u at 0.1 degrees from r_ij: B keeps a direction at sigma_r / sigma_1 = 1e-3
    (below SMALL_KEPT_MIN, 1e-2). Forced onto the sparse path, the run holds the dense
    path's answers only to the body's own conditioning: 1e-7, ten times the 1e-8 by
    which the dense run itself differs from the NumPy version here (measured 1.2e-8
    and 9.8e-9; at 0.5 degrees both are 1e-11 and below). Solves whose corrections
    started at the rows' rounding but still moved x are not accepted
    (engine/fcc_al_refine.c, ROUNDING_ACCEPT): accepting them left this run 1.4e-4 off,
    silently."""
    solver = load(tilted(2e-3))
    solver.initial_state()
    assert not solver.sparse
    dense = solver.simulate(t_end=1.0, dt=1e-3, output_dt=0.1)
    forced = CompiledSolver(solver.plan, solver.module, linear_solver="sparse")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        sparse = forced.simulate(t_end=1.0, dt=1e-3, output_dt=0.1)
    assert sparse.info["solver"]["path"] == "sparse"
    for column in dense.columns:
        assert np.max(np.abs(sparse[column] - dense[column])) < 1e-7, column


def test_a_weaker_direction_is_redone_densely_on_the_sparse_path(load):
    """u at 0.07 degrees from r_ij (sigma_r / sigma_1 about 6e-4): forced onto the
    sparse path, a tenth of the solves along it do not converge and are redone densely,
    with a warning (measured 500 of 5,000)."""
    solver = load(tilted(1.2e-3))
    solver.initial_state()
    assert not solver.sparse
    forced = CompiledSolver(solver.plan, solver.module, linear_solver="sparse")
    with pytest.warns(RunWarning, match="did not converge"):
        forced.simulate(t_end=1.0, dt=1e-3, output_dt=0.1)


@pytest.mark.parametrize("text", [light_second_rod(), em.axisymmetric_top(
    [0.6, 0, -0.8], [0, 1, 0], 1.0, 0.5, 0.0833583333333333e-10, 0.0833583333333333,
    [0.0, 0.0, 3.0])], ids=["masses_1e10_apart", "axial_inertia_1e-10"])
def test_a_motion_far_lighter_than_the_heaviest_takes_the_dense_path(load, text):
    """The reduced mass matrix's smallest eigenvalue is 6e-11 and 2.5e-11 of M's largest
    diagonal entry (below SMALL_MASS_MIN, 1e-6). At the axis-aligned start the sparse
    factor still holds; forced onto the sparse path, both runs stop once the light
    motion has turned, naming the sparse path and what to change."""
    solver = load(text)
    solver.initial_state()
    assert not solver.sparse
    forced = CompiledSolver(solver.plan, solver.module, linear_solver="sparse")
    with pytest.raises(SimulationError, match="on the sparse path it also is when a "
                       "motion is about 1e9 or more times lighter.*--linear-solver dense"):
        forced.simulate(t_end=1.0, dt=1e-3, output_dt=0.1)


def test_the_path_is_decided_again_at_every_run(compiled, monkeypatch):
    """The rule reads each run's start: raising the mass bound past the four-bar's
    spread (0.9) sends the next run to the dense path, lowering it again back; both
    runs agree to the paths' 1e-9 (tests/test_sparse_path.py)."""
    shared = compiled("four_bar")
    solver = CompiledSolver(shared.plan, shared.module)
    sparse_run = solver.simulate(t_end=0.2, output_dt=0.05)
    assert sparse_run.info["solver"]["path"] == "sparse"
    monkeypatch.setattr(paths, "SMALL_MASS_MIN", 10.0)
    dense_run = solver.simulate(t_end=0.2, output_dt=0.05)
    assert dense_run.info["solver"]["path"] == "dense" and not solver.sparse
    for column in sparse_run.columns:
        assert np.max(np.abs(sparse_run[column] - dense_run[column])) < 1e-9, column
    monkeypatch.undo()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        assert solver.simulate(t_end=0.01).info["solver"]["path"] == "sparse"


def test_the_rule_and_the_spread_by_hand():
    assert paths.small_model_path(0.4, 0.0, 0.5) == "sparse"
    assert paths.small_model_path(0.4, 0.05, 0.5) == "dense"       # manifold rows
    assert paths.small_model_path(5e-3, 0.0, 0.5) == "dense"       # weakly kept
    assert paths.small_model_path(0.4, 0.0, 1e-8) == "dense"       # far lighter
    # a unit point mass on the x axis: the rod of length 1 from the origin leaves y, z
    # free; their masses 1 and 1e-10 against the largest diagonal entry 2
    M = np.diag([2.0, 1.0, 1e-10])
    B = np.array([[1.0, 0.0, 0.0]])
    assert paths.reduced_mass_spread(M, B, 1) == pytest.approx(5e-11)
    assert paths.reduced_mass_spread(M, np.zeros((0, 3)), 0) == pytest.approx(5e-11)
    assert paths.reduced_mass_spread(M, np.eye(3), 3) == 1.0
