"""Every method has the same guards (docs/reliability.md): the divergence bounds, the
energy check (with the work added back) and, without projection, the check of the
constraint drift. Before, the SciPy methods and ``--no-project`` runs had neither the
blow-up stop nor the energy check: DOPRI5 at rtol 0.9 without projection ended with a
constraint error of 1e117 on a 1 m pendulum, and exit status 0."""
from __future__ import annotations

import warnings

import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.errors import RunWarning, SimulationError

LOOSE = dict(rtol=0.9, atol=0.9, t_end=10.0, output_dt=0.1)

# A 1 kg bob on a stiff spring (1e6 N/m) from a fixed point, released horizontally at
# its free length under gravity: an elastic pendulum whose spring is 1e4 times
# stiffer than its swing.
ELASTIC = """
name: elastic_pendulum
gravity: [0, 0, -9.81]
points:
  O: {at: [0, 0, 0], fixed: true}
bodies:
  bob: {mass: 1.0, center: [1.0, 0, 0], inertia: [1.0e-3, 1.0e-3, 1.0e-3]}
loads:
  - {type: spring, ends: [O, {body: bob, at: [0, 0, 0]}], stiffness: 1.0e6, length: 1.0}
simulate: {t_end: 2.0, dt: 1.0e-3, method: rk4}
"""


@pytest.mark.parametrize("method, project", [("dopri5", False), ("scipy-RK45", True)])
def test_a_loose_run_that_blows_up_stops(compiled, method, project):
    """A01 at rtol = atol = 0.9: the pendulum's state passes 1e6 times its reach at
    t = 1.92 s and the run stops with an error that says so."""
    with pytest.raises(SimulationError, match=r"stopped at t = 1\.92.*the run diverged: "
                                              r"max \|q\| reached"):
        compiled("a01_pendulum").simulate(method=method, project=project, **LOOSE)


def test_numeric_stops_too(numeric):
    with pytest.raises(SimulationError, match=r"the run diverged: max \|q\| reached"):
        numeric("a01_pendulum").simulate(method="dopri5", project=False, **LOOSE)


def test_the_command_line_exits_with_an_error(build_dir, tmp_path):
    out = tmp_path / "r.csv"
    code = main(["simulate", str(EXAMPLES / "a01_pendulum.yaml"), "--method", "dopri5",
                 "--rtol", "0.9", "--atol", "0.9", "--no-project", "--t-end", "10",
                 "--output-dt", "0.1", "--out", str(out), "--build-dir", str(build_dir),
                 "-q"])
    assert code == 1 and not out.exists()


def test_an_unprojected_run_that_leaves_the_constraints_says_so(compiled):
    """DOPRI5 at rtol 1e-3 without projection keeps A01 finite, but its rod ends
    stretched by its own length: both the constraint drift (0.998 of the model's
    size) and the energy (170 % of the peak kinetic energy) are reported."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", RunWarning)
        result = compiled("a01_pendulum").simulate(method="dopri5", rtol=1e-3,
                                                   atol=1e-3, project=False, t_end=10.0,
                                                   output_dt=0.1)
    said = " ".join(str(w.message) for w in seen)
    assert "without projection the run left the constraints" in said
    assert "the energy changed by" in said
    assert result.info["constraint_drift"]["scaled_residual"] > 0.5


def test_lsoda_on_a_stiff_spring_is_checked(build_dir, tmp_path):
    """LSODA at rtol 1e-3 on the elastic pendulum changes its energy by 3 % of the peak
    kinetic energy: warned; at rtol 1e-8 it keeps it to 1e-6 and says nothing."""
    path = tmp_path / "elastic.yaml"
    path.write_text(ELASTIC)
    solver = fccgen.load(path, build_dir)
    with pytest.warns(RunWarning, match="the energy changed by"):
        solver.simulate(method="scipy-LSODA", rtol=1e-3, atol=1e-3, output_dt=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        good = solver.simulate(method="scipy-LSODA", rtol=1e-8, atol=1e-8, output_dt=0.1)
    assert good.info["energy_check"]["drift_fraction"] < 1e-5
