"""What the analyses write: ``fccgen statics --out`` is one result row at t = 0 with
the reactions named by joint and component (units said), which equal those of the
dynamics at rest; ``modes.csv`` carries how it was made in its sidecar."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.results.result import Result


def test_statics_out_is_one_row_with_named_reactions(build_dir, tmp_path, capsys):
    model = EXAMPLES / "four_bar_driven.yaml"
    out = tmp_path / "eq.csv"
    assert main(["statics", str(model), "--build-dir", str(build_dir), "-q",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "reactions (force fx fy fz and torque tx ty tz" in text
    assert "units: the model's force and force x length" in text
    assert "driver motor.torque" in text and "(force x length)" in text
    assert "A_axis" not in text and "[0]" not in text       # no bare, unnamed rows
    eq = Result.load(out)
    assert list(eq.t) == [0.0] and eq.info["kind"] == "static equilibrium"
    assert eq.info["model"]["name"] == "four_bar_driven" and "fccgen_version" in eq.info
    for j in "OABC":
        assert all(f"{j}.{c}" in eq.names for c in ("fx", "fy", "fz", "tx", "ty", "tz"))
    # a structure held by its motor against gravity: the joints carry the weight
    weight = 9.81 * (0.2 + 0.7 + 0.6)
    assert eq["O.fy"][0] + eq["C.fy"][0] == pytest.approx(weight, rel=1e-9)
    # the motor's static torque is the crank's and the coupler's moment about O
    assert eq["motor.torque"][0] == pytest.approx(0.157864, rel=1e-5)


def test_statics_of_a_model_given_by_points_names_forces_per_point(build_dir, capsys):
    model = EXAMPLES / "double_pendulum.yaml"
    assert main(["statics", str(model), "--build-dir", str(build_dir), "-q"]) == 0
    text = capsys.readouterr().out
    line = next(x for x in text.splitlines() if x.strip().startswith("P2 "))
    # at rest under gravity the constraints hold P2 up against rod2's weight share
    gy = float(line.split("gy")[1].split()[0])
    assert gy == pytest.approx(0.6 * 9.81 * 0.5, rel=1e-9)


def test_modes_csv_says_how_it_was_made(build_dir, tmp_path):
    out = tmp_path / "modes.csv"
    assert main(["modes", str(EXAMPLES / "double_pendulum.yaml"), "--build-dir",
                 str(build_dir), "-q", "--out", str(out)]) == 0
    meta = json.loads((tmp_path / "modes.meta.json").read_text())
    info = meta["info"]
    assert info["model"]["name"] == "double_pendulum" and info["about"] == "equilibrium"
    assert info["fccgen_version"] and info["method"] == "eigh"
    import hashlib
    assert meta["sha256"] == hashlib.sha256(out.read_bytes()).hexdigest()
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert rows.shape == (2, 4) and meta["columns"][1] == "frequency_hz"
