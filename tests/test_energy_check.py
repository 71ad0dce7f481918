"""The energy as an independent check of a run (fccgen/runs/energy_check.py): a
model that conserves its energy warns when a run's drift exceeds 1 % of the largest
kinetic energy; models that exchange energy on purpose are named and not checked."""
from __future__ import annotations

import warnings

import pytest

from fccgen.errors import RunWarning
from fccgen.runs.energy_check import DRIFT_FRACTION, energy_exchange


def test_a_step_too_coarse_for_a_conservative_pendulum_is_reported(compiled):
    """A01 (1 DOF, gravity only) by RK4 for 10 s: at dt = 0.1 s (about 20 steps per
    swing) the energy drifts by 1.5 % of the peak kinetic energy while the constraints
    hold to the projection's tolerance: warned, with the figure in info. At dt = 0.01
    s it drifts by 1.7e-7 of it: no warning."""
    solver = compiled("a01_pendulum")
    with pytest.warns(RunWarning, match=r"energy changed by .* conserves it"):
        coarse = solver.simulate(t_end=10.0, dt=0.1, method="rk4")
    check = coarse.info["energy_check"]
    assert check["conservative"] and check["drift_fraction"] > DRIFT_FRACTION
    assert coarse.info["max_constraint_error"] < 1e-9       # it looks right otherwise
    assert any("energy changed" in w for w in coarse.info["warnings"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        fine = solver.simulate(t_end=10.0, dt=0.01, method="rk4")
    assert fine.info["energy_check"]["drift_fraction"] < 1e-6


@pytest.mark.parametrize("name, reason", [
    ("deployable", "constant torque does work"),
    ("four_bar_driven", "driver does work"),
    ("a02_n_four_bar", None),
    ("solar_array", None),            # impacts' losses are added back (events)
])
def test_which_models_must_keep_their_energy(compiled, name, reason):
    """Dampers, drivers, torques and loads of time exchange energy: the first such
    element is named; gravity, constant forces and undamped springs do not."""
    got = energy_exchange(compiled(name).plan)
    assert (got is None) if reason is None else (reason in got)
