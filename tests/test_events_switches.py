"""Switches of the compiled events (fccgen/runtime/_events.pyx): the degrees of freedom
after a lock or unlock decided by rank, resting contacts that release when their
contact force would pull, and event modules shared by models that differ only in
numbers (with_parameters, initial angles)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import fccgen.api as api
from fccgen.errors import RunWarning

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _four_bar(events: str) -> str:
    """examples/four_bar_driven.yaml without its driver (1 DOF) and with ``events``."""
    text = (EXAMPLES / "four_bar_driven.yaml").read_text()
    text = text.replace("name: four_bar_driven", "name: four_bar_locks")
    text = text.replace('drivers:\n  - {name: motor, joint: O, angle: "10*t"}\n', "")
    assert "drivers" not in text
    return text.replace("t_end: 1.0", "t_end: 0.6") + "events:\n" + events


TWICE = """\
  - {name: lock_O, when: "t >= 0.1", do: lock, joint: O}
  - {name: lock_C, when: "t >= 0.2", do: lock, joint: C}
  - {name: free_O, when: "t >= 0.3", do: unlock, joint: O}
  - {name: free_C, when: "t >= 0.4", do: unlock, joint: C}
"""
ONCE = """\
  - {name: lock_O, when: "t >= 0.1", do: lock, joint: O}
  - {name: free_O, when: "t >= 0.4", do: unlock, joint: O}
"""


@pytest.fixture(scope="module")
def four_bars(build_dir, tmp_path_factory):
    folder = tmp_path_factory.mktemp("switches")
    out = {}
    for name, events in (("twice", TWICE), ("once", ONCE)):
        path = folder / f"four_bar_{name}.yaml"
        path.write_text(_four_bar(events))
        out[name] = api.load(path, build_dir)
    return out


def test_a_second_latch_on_a_one_dof_mechanism_is_redundant(four_bars):
    """The four-bar (1 DOF) locked at its crank hinge O, then at its rocker hinge C:
    the first lock leaves 0 DOF, the second adds no constraint (its row follows from
    the loop and O's row): DOF 1 -> 0 -> 0 with a RunWarning naming it. Unlocking O
    leaves C holding (its row is used now: still 0 DOF, no singular solve); unlocking
    C frees the crank again (1 DOF). While locked nothing moves; after the release
    the motion equals that of a run locked once (O from 0.1 to 0.4 s): both start
    from rest at the same configuration, held to the projection's 1e-12 by different
    rows, so they agree to 1e-10 rad over the remaining 0.2 s (measured: equal, and
    7e-34 rad/s in the rates)."""
    with pytest.warns(RunWarning, match="'lock_C'.*adds no constraint.*stay 0"):
        twice = four_bars["twice"].simulate(method="rk4", dt=1e-3)
    assert [(r["name"], r["dof"]) for r in twice.events] == [
        ("lock_O", 0), ("lock_C", 0), ("free_O", 0), ("free_C", 1)]
    assert twice.info["dof"] == 1
    assert sum("adds no constraint" in w for w in twice.info["warnings"]) == 1
    assert twice.events[0]["kinetic_energy_after"] <= 1e-20
    held = (twice.t > 0.1) & (twice.t <= 0.4)
    for j in "OC":
        assert np.max(np.abs(twice[f"{j}.rate"][held])) <= 1e-12
        assert np.ptp(twice[f"{j}.angle"][held]) <= 1e-12
    once = four_bars["once"].simulate(method="rk4", dt=1e-3)
    assert [(r["name"], r["dof"]) for r in once.events] == [("lock_O", 0), ("free_O", 1)]
    np.testing.assert_array_equal(twice.t, once.t)
    for name in ("O.angle", "C.angle", "A.angle"):
        assert np.max(np.abs(twice[name] - once[name])) <= 1e-10, name
        assert np.max(np.abs(twice[name.replace("angle", "rate")]
                             - once[name.replace("angle", "rate")])) <= 1e-9, name
    assert abs(twice["O.angle"][-1] - twice["O.angle"][held][0]) > 1e-3   # moves again
