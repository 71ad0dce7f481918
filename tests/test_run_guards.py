"""Runs that blow up end with an error (never exit 0 with 1e251 in the results), and
the rows recorded before the stop are kept only when asked, marked partial."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.errors import PartialResultWarning, SimulationError
from fccgen.results.result import Result


def test_diverging_fixed_step_run_is_an_error(compiled):
    """Baumgarte at dt = 0.5 on the double pendulum used to finish with values of
    1e251; the run now stops once max |v| passes 1e6 (|v0| + max|q0| / dt)."""
    solver = compiled("double_pendulum")
    with pytest.raises(SimulationError, match=r"diverged: max \|v\|") as info:
        solver.simulate(t_end=20.0, dt=0.5, output_dt=0.5, method="baumgarte")
    rows = info.value.partial_result
    assert rows.partial and 0 < rows.t[-1] < 20.0
    assert np.all(np.isfinite(rows.table()))


@pytest.mark.parametrize("method", ["rk4", "baumgarte"])
def test_bounds_leave_accurate_runs_alone(compiled, method):
    """The same model at a sound step runs to its end under both fixed-step methods."""
    result = compiled("double_pendulum").simulate(t_end=2.0, dt=1e-3, output_dt=0.1,
                                                  method=method)
    assert result.t[-1] == 2.0


def test_keep_partial_writes_a_marked_file_only_when_asked(tmp_path, build_dir):
    out = tmp_path / "run.csv"
    args = [str(EXAMPLES / "double_pendulum.yaml"), "--method", "baumgarte", "--dt",
            "0.5", "--output-dt", "0.5", "--out", str(out), "--build-dir", str(build_dir),
            "-q"]
    assert main(["simulate", *args]) == 1
    assert not out.exists() and not (tmp_path / "run.partial.csv").exists()
    assert main(["simulate", *args, "--keep-partial"]) == 1
    assert not out.exists()
    with pytest.warns(PartialResultWarning, match="partial result"):
        partial = Result.load(tmp_path / "run.partial.csv")
    assert partial.partial and partial.t[-1] < 5.0 and len(partial.t) >= 2


MASSLESS_TIP = """
name: massless_tip
gravity: [0, -9.81, 0]
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [1, 0, 0]
  Q: [2, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  rod: {points: [O, P], vector: z, mass: 1.0, center: [0.5, 0, 0],
        inertia: [1.0e-4, 0.08, 0.08]}
  tip: {points: [P, Q], vector: z, mass: 1.0, center: [0, 0, 0], inertia: [0, 0, 0]}
"""


@pytest.mark.parametrize("numeric", [False, True])
def test_singular_mass_matrix_names_the_file_and_the_massless_motion(
        tmp_path, build_dir, numeric):
    """The tip body's mass sits at its hinge P and it has no inertia: its swing about P
    (Q moving across the rod, Q.y) carries no kinetic energy."""
    import fccgen
    path = tmp_path / "massless_tip.yaml"
    path.write_text(MASSLESS_TIP)
    solver = fccgen.load_numeric(path) if numeric else fccgen.load(path, build_dir)
    with pytest.raises(SimulationError, match=r"massless_tip\.yaml:13: bodies\.tip: "
                                              r".*singular.*moves "
                                              r"Q\.y \(used by bodies\.tip\)"):
        solver.initial_state()
