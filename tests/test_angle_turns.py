"""Joint angles counted over turns along records (fccgen/mechanism/turns.py,
docs/elements.md "Angles over turns"): records far apart keep a steady rotor's turns,
a rate that changes too much between records leaves the angle NaN with a warning,
an event between records takes the nearest branch; the exported C engine counts its
reads the same way."""
from __future__ import annotations

import math
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest

import fccgen
from fccgen.errors import RunWarning
from fccgen.mechanism.turns import count_turns

SPUN = """\
name: spun_arm
bodies:
  arm: {mass: 1.0, center: [0.5, 0, 0], inertia: [0.001, 0.1, 0.1]}
joints:
  - {name: H, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 0, 1]}
loads:
  - {type: torsion_spring, joint: H, stiffness: 0.5, angle: -0.3, damping: 0.0}
initial:
  joints: {H: {rate: 6.0}}
simulate: {t_end: 1.8, dt: 1.0e-3, output_dt: 0.6}
"""


def write(tmp_path, text, name="spun_arm"):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def test_a_steady_rotor_keeps_its_turns_between_far_records():
    """5 rad between records at a constant 5 rad/s: every record counted (the
    nearest branch would have gone back 1.28 rad each time)."""
    t = np.arange(6.0)
    true = 5.0 * t
    raw = np.angle(np.exp(1j * true))
    angles, known, _ = count_turns(raw[None], np.full((1, 6), 5.0), t)
    assert known[0] == 6 and np.abs(angles[0] - true).max() < 1e-12


def test_a_rate_that_changes_too_much_loses_the_turns_from_there():
    """theta = t^3 read once a second: from 1 to 2 s the earlier rate advances 3 rad,
    the trapezoid 7.5; no branch of the 7 rad increment is within a quarter turn of
    the trapezoid and the advance's at once: the records from 2 s are not counted."""
    t = np.arange(4.0)
    raw = np.angle(np.exp(1j * t ** 3))
    _, known, _ = count_turns(raw[None], (3 * t ** 2)[None], t)
    assert known[0] == 2


def test_an_event_between_records_takes_the_nearest_branch():
    """A bounce at 0.5 s reverses the rate (4 rad/s to -4): the rates say nothing of
    the interval across it, so the nearest branch (2 rad on) is taken, unchecked;
    without the event time the same records are refused (the trapezoid says 0)."""
    t = np.array([0.0, 1.0])
    raw = np.array([[0.0, 2.0]])
    rate = np.array([[4.0, -4.0]])
    angles, known, _ = count_turns(raw, rate, t, impacts=[0.5])
    assert known[0] == 2 and angles[0, 1] == pytest.approx(2.0)
    assert count_turns(raw, rate, t)[1][0] == 1


@pytest.mark.parametrize("numeric", [False, True])
def test_records_far_apart_keep_the_joint_angle(numeric, tmp_path, build_dir):
    """The arm spun at 6 rad/s against a weak spring, recorded every 0.6 s (3.2 to
    3.6 rad between records): its H.angle equals the same run's recorded every step
    (the same steps: 1e-12 rad). Before, the angle columns took the nearest branch
    between records and read -3.06 rad at 0.6 s instead of 3.23."""
    path = write(tmp_path, SPUN)
    solver = (fccgen.load_numeric(path) if numeric else
              fccgen.load(path, build_dir=build_dir))
    t_end = 1.2 if numeric else 1.8
    coarse = solver.simulate(t_end=t_end, reactions=False)
    fine = solver.simulate(t_end=t_end, output_dt=1e-3, reactions=False)
    at = np.searchsorted(fine.t, coarse.t - 1e-9)
    assert np.abs(fine.t[at] - coarse.t).max() < 1e-12
    assert coarse["H.angle"][1] > 3.0
    assert np.abs(coarse["H.angle"] - fine["H.angle"][at]).max() < 1e-12
    assert "angle_turns_lost" not in coarse.info


CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")


@pytest.mark.skipif(CC is None or MAKE is None or not sys.platform.startswith("linux"),
                    reason="needs a C compiler and make")
@pytest.mark.parametrize("text, lost", [
    (SPUN, False),
    (SPUN.replace("  - {type: torsion_spring, joint: H, stiffness: 0.5, angle: -0.3, "
                  "damping: 0.0}",
                  '  - {type: torque, body: arm, value: [0, 0, "200*(8.0 - H.angle)"]}')
     .replace("output_dt: 0.6", "output_dt: 0.1"), True),
], ids=["steady", "lost"])
def test_the_export_counts_its_reads_as_simulate_counts_its_records(
        text, lost, tmp_path, build_dir):
    """The exported example reads the state at the output times: its H.angle equals
    fccgen simulate's to 1e-12 of the column's largest value where both count it, and
    is NaN where simulate's is (a stiff torque of the angle swings the arm through
    16 rad every 0.3 s: read every 0.1 s its turns are lost). The selftest replays
    the golden rows, NaN where the run's are."""
    from fccgen.export import export_c
    path = write(tmp_path, text)
    solver = fccgen.load(path, build_dir=build_dir, linear_solver="sparse")
    with warnings.catch_warnings():      # the export's golden run says it too
        warnings.simplefilter("ignore", RunWarning)
        folder = export_c(path, tmp_path / "c", build_dir)
    for cmd in ([MAKE, "-s", f"CC={CC}", "CFLAGS=-std=c99 -Wall -Wextra -pedantic "
                 "-Werror -O2"], ["./spun_arm_example", "out.csv"],
                ["./spun_arm_selftest"]):
        done = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
        assert done.returncode == 0, done.stdout + done.stderr
    names = (folder / "out.csv").read_text().splitlines()[0].split(",")
    rows = np.genfromtxt(folder / "out.csv", delimiter=",", skip_header=1, ndmin=2)
    column = rows[:, names.index("H.angle")]
    if lost:
        with pytest.warns(RunWarning):
            r = solver.simulate(reactions=False)
        assert "H.angle" in r.info["angle_turns_lost"]
    else:
        r = solver.simulate(reactions=False)
        assert column[-1] > math.pi
    want = r["H.angle"]
    assert np.array_equal(np.isnan(column), np.isnan(want))
    ok = ~np.isnan(want)
    assert np.abs(column[ok] - want[ok]).max() <= 1e-12 * np.abs(want[ok]).max()
