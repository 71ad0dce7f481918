"""IFToMM benchmark A02, the N-four-bar mechanism (N = 40): the model file, its structure
(1 degree of freedom, 40 redundant equations), and the benchmark's high-precision level
(B0 position error <= 1e-3 m over 20 s) met by the method that meets it cheapest."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import EXAMPLES, REFERENCE, example_module
from fccgen.bench.accuracy import reference_from_table

MODEL = EXAMPLES / "a02_n_four_bar.yaml"
DATA = REFERENCE / "mbsbenchmark_A02_solution_data_B0.csv"

# The cheapest run that meets the high-precision level in the work-precision measurement
# (docs/accuracy.md, benchmarks/accuracy_a01_a02.py): dopri5 with projection at
# rtol = 1e-8, atol = 1e-11 (measured error 6.9e-5 m, 1049 steps; rk4 with projection at
# dt = 0.01 costs as much for 4.5e-4 m). Projection keeps the chain on the constraints
# through the 20 passages of the singular horizontal position: every method without it
# leaves the benchmark's branch of motion or stops there.
METHOD = dict(method="dopri5", rtol=1e-8, atol=1e-11, project=True)


def _generator():
    return example_module("make_n_four_bar")


def test_the_model_file_is_the_generator_output_for_n_40():
    assert MODEL.read_text() == _generator().model_text(40)


def test_the_generator_scales_the_chain_with_n():
    import yaml
    model = yaml.safe_load(_generator().model_text(3))
    assert len(model["bodies"]) == 2 * 3 + 1
    assert sum(1 for p in model["points"].values() if isinstance(p, list)) == 3 + 1


def test_check_finds_one_degree_of_freedom_and_40_redundant_equations():
    from fccgen.diagnostics.check import check_model
    report = check_model(MODEL)
    assert (report.n_q, report.n_g, report.rank) == (123, 162, 122)
    assert report.dof == 1
    # The couplers' "perpendicular to z" rows follow from the rockers' at their ends.
    assert report.redundant == [f"bodies.coupler{i} (angle)" for i in range(40)]


def test_the_initial_state_is_the_benchmarks(numeric):
    solver = numeric("a02_n_four_bar")
    init = solver.initial_state()
    q, v = init.q.reshape(-1, 3), init.v.reshape(-1, 3)
    # B_i at (i, 1, 0), all moving at 1 m/s along +x: consistent as given (exact data).
    assert np.array_equal(q, np.column_stack([np.arange(41), np.ones(41), np.zeros(41)]))
    assert np.allclose(v, [1.0, 0.0, 0.0], rtol=0, atol=1e-14)
    assert init.position_residual_given == 0.0 and init.velocity_change < 1e-14


@pytest.fixture(scope="module")
def a02_run(compiled):
    """The benchmark run (the runtime holds BLAS to one thread during it: its dense
    solves at n_q = 123 were many times slower with threads competing for the cores)."""
    result = compiled("a02_n_four_bar").simulate(t_end=20.0, output_dt=0.05, **METHOD)
    return result, result.info


def test_a02_meets_the_high_precision_level_over_20_s(a02_run):
    result, info = a02_run
    error, when = reference_from_table(DATA, "B0").error(result)
    # The benchmark's high-precision level: B0 position error <= 1e-3 m at its 401
    # output times (0.05 s apart) over 20 s.
    assert error <= 1e-3, f"{METHOD}: B0 error {error:.3g} m at t = {when:g} s"
    assert info["method"] == "dopri5" and info["steps"] > 0


def test_a02_passes_the_singular_position_and_stays_on_the_constraints(a02_run):
    result, info = a02_run
    y = result["B0.y"]
    ref = np.loadtxt(DATA, delimiter=",", skiprows=6)
    # The chain turns over and over: B0.y changes sign 20 times in the reference, each
    # a passage through the horizontal (singular) position; the run does the same.
    crossings = np.sum(np.diff(np.sign(ref[:, 2])) != 0)
    assert crossings == 20 and np.sum(np.diff(np.sign(y)) != 0) == crossings
    # Projection after every step keeps g(q) = 0 to its Newton tolerance (1e-11 m).
    assert info["max_constraint_error"] < 1e-10
    # A conservative system: the energy of the run drifts by far less than it holds
    # (about 620 J: 590 J of potential energy at the start, 27 J of kinetic).
    e = result["energy"]
    assert np.max(np.abs(e - e[0])) < 1e-3 * np.max(np.abs(e))
