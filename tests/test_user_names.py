"""Names a user wrote: a model with joints shows its bodies, joints, drivers and
loads; the points and vectors the lowering made (``O_drive_b.x``, ``A_axis.x``) are
kept in ``result.internal`` and written only on request, and the files that keep them
apart bring them back, so that a saved result still animates. A model given by points
keeps every column of docs/design.md §4."""
from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.results.result import Result

MADE = re.compile(r"^[A-Za-z0-9]+_(axis\d?|drive_[ab]|a|b|n\d|nb|center|end|[xyz]|"
                  r"normal|spring\d)\.")


@pytest.fixture(scope="module")
def driven(compiled):
    return compiled("four_bar_driven").simulate(t_end=0.05)


def test_columns_are_the_users_and_internals_are_apart(driven):
    names = driven.names
    assert "motor.torque" in names and "crank.cx" in names and "O.angle" in names
    assert "A.x" in names                       # a joint's own point: the joint's place
    assert not [n for n in names if MADE.match(n)], names
    internal = driven.internal
    assert "O_drive_b.x" in internal and "A_axis.x" in internal
    assert all(MADE.match(n) for n in internal), sorted(internal)
    assert driven["O_drive_b.x"] is internal["O_drive_b.x"]       # still by name
    assert list(driven.to_pandas().columns) == names[1:]
    assert "A_axis.x" in driven.to_pandas(all_columns=True).columns
    assert "O_drive_b.x" not in repr(driven)


def test_a_model_given_by_points_keeps_every_column(compiled):
    result = compiled("double_pendulum").simulate(t_end=0.01)
    assert result.internal == {}
    assert result.names[:7] == ["t", "P1.x", "P1.y", "P1.z", "P1.vx", "P1.vy", "P1.vz"]


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".h5"])
def test_files_hold_the_users_columns_and_keep_internals_where_they_can(
        driven, tmp_path, suffix):
    path = driven.save(tmp_path / f"r{suffix}")
    back = Result.load(path)
    assert back.names == driven.names
    if suffix == ".csv":                        # for other tools: only on request
        assert back.internal == {}
        assert "A_axis.x" not in path.read_text().splitlines()[0]
    else:                                       # apart, and back as result.internal
        assert set(back.internal) == set(driven.internal)
        assert np.array_equal(back["A_axis.x"], driven["A_axis.x"])
    full = Result.load(driven.save(tmp_path / f"all{suffix}", all_columns=True))
    assert set(full.internal) == set(driven.internal) and full.names == driven.names


def test_h5_root_holds_only_the_users_columns(driven, tmp_path):
    import h5py
    path = driven.save(tmp_path / "r.h5")
    with h5py.File(path, "r") as f:
        root = [n for n, v in f.items() if isinstance(v, h5py.Dataset)]
        assert root == driven.names and "A_axis.x" in f["internal"]


def test_cli_writes_internals_on_request_and_animates_from_npz(build_dir, tmp_path,
                                                               capsys):
    model = EXAMPLES / "four_bar_driven.yaml"
    args = ["simulate", str(model), "--t-end", "0.05", "--build-dir", str(build_dir), "-q"]
    assert main([*args, "--out", str(tmp_path / "r.csv")]) == 0
    out = capsys.readouterr().out
    assert "internal columns left out, --all-columns writes them" in out
    assert main([*args, "--out", str(tmp_path / "all.csv"), "--all-columns"]) == 0
    assert "A_axis.x" in (tmp_path / "all.csv").read_text().splitlines()[0]
    assert main([*args, "--out", str(tmp_path / "r.npz")]) == 0
    capsys.readouterr()
    page = tmp_path / "r.html"
    assert main(["animate", str(model), "--result", str(tmp_path / "r.npz"), "--out",
                 str(page), "--build-dir", str(build_dir), "-q"]) == 0
    assert page.stat().st_size > 1_000_000
    code = main(["animate", str(model), "--result", str(tmp_path / "r.csv"), "--out",
                 str(tmp_path / "csv.html"), "--build-dir", str(build_dir), "-q"])
    err = capsys.readouterr().err
    assert code == 1 and "--all-columns" in err and not (tmp_path / "csv.html").exists()
