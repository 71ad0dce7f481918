"""Writing and reading result files safely: atomic writes with the umask's
permissions, temporary and cut files refused, partial results marked and flagged."""
from __future__ import annotations

import json
import os
import stat
import subprocess
import sys

import numpy as np
import pytest

import fccgen.results.result
from fccgen.errors import HostError, PartialResultWarning
from fccgen.results.result import Result, check_output, partial_path


def small_result(n=4, **info) -> Result:
    t = np.linspace(0.0, 0.3, n)
    return Result(t, {"P.x": np.cos(t), "energy": np.full(n, 1.5)}, dict(info))


@pytest.fixture
def umask():
    """Set the process umask for a test and restore it."""
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".h5"])
@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_save_uses_the_umask_and_leaves_no_temporary(umask, tmp_path, suffix, mask):
    umask(mask)
    path = small_result(method="rk4").save(tmp_path / f"r{suffix}")
    written = sorted(tmp_path.iterdir())
    assert [p.name for p in written] == sorted(
        [path.name, *(["r.meta.json"] if suffix == ".csv" else [])])
    for p in written:                       # the CSV's sidecar too
        assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~mask
    back = Result.load(path)
    assert back.names == ["t", "P.x", "energy"] and not back.partial
    np.testing.assert_array_equal(back["P.x"], small_result()["P.x"])   # %.17g: exact
    assert back.info == {"method": "rk4"}


def test_a_failed_save_keeps_the_previous_file(tmp_path, monkeypatch):
    path = small_result(n=4).save(tmp_path / "r.csv")
    before = path.read_bytes()

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(fccgen.results.result.np, "savetxt", fail)
    with pytest.raises(HostError, match="no space left.*free some space.*--out"):
        small_result(n=9).save(path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.meta.json"]


def test_temporary_and_cut_files_are_refused(tmp_path):
    path = small_result().save(tmp_path / "r.csv")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    leftover = tmp_path / f".r.csv.{dead}.0123456789ab.tmp"    # a killed save's file
    leftover.write_bytes(path.read_bytes()[:-20])
    with pytest.raises(ValueError, match="temporary file of a save that did not end"):
        Result.load(leftover)
    cut = tmp_path / "cut.csv"
    cut.write_bytes(path.read_bytes()[:-3])
    with pytest.raises(ValueError, match="incomplete result file"):
        Result.load(cut)
    small_result().save(path)                    # the next save removes the leftover
    assert not leftover.exists()


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".h5"])
def test_partial_results_are_marked_and_flagged(tmp_path, suffix):
    result = small_result(stopped_by="interrupted (Ctrl-C)")
    path = result.save(partial_path(tmp_path / f"run{suffix}"), partial=True)
    assert path.name == f"run.partial{suffix}"
    with pytest.warns(PartialResultWarning, match="partial result.*t = 0.3.*Ctrl-C"):
        back = Result.load(path)
    assert back.partial and len(back.t) == 4
    renamed = path.rename(tmp_path / f"renamed{suffix}")     # the mark is inside too
    with pytest.warns(PartialResultWarning):
        assert Result.load(renamed).partial


def test_check_output_before_a_run(tmp_path):
    with pytest.raises(ValueError, match=r"\.csv, \.npz or \.h5 \(got '\.txt'\)"):
        check_output(tmp_path / "r.txt")
    (tmp_path / "file").write_text("")
    with pytest.raises(HostError, match="in the way.*--out"):
        check_output(tmp_path / "file" / "r.csv")
    (tmp_path / "dir.csv").mkdir()
    with pytest.raises(HostError, match="it is a folder"):
        check_output(tmp_path / "dir.csv")
    assert check_output(tmp_path / "new" / "r.npz") == tmp_path / "new" / "r.npz"
    assert list((tmp_path / "new").iterdir()) == []           # the probe is gone


def test_check_output_permission_denied(tmp_path, monkeypatch):
    """A folder that takes no new file (chmod where it restricts, i.e. not as root;
    a refused open otherwise)."""
    folder = tmp_path / "ro"
    folder.mkdir()
    if os.geteuid() != 0:
        folder.chmod(0o555)
    else:
        real_open = os.open

        def refuse(path, *args, **kwargs):
            if str(path).startswith(str(folder)):
                raise PermissionError(13, "Permission denied", str(path))
            return real_open(path, *args, **kwargs)
        monkeypatch.setattr(fccgen.results.result.os, "open", refuse)
    try:
        with pytest.raises(HostError, match="Permission denied.*make it writable") as info:
            check_output(folder / "r.csv")
        # the folder is named, not the probe file (an internal name)
        assert f"in {folder}: " in str(info.value) and ".tmp" not in str(info.value)
    finally:
        folder.chmod(0o755)


def test_npz_info_is_json(tmp_path):
    path = small_result(steps=np.int64(3), error=np.float64(1e-9)).save(tmp_path / "r.npz")
    with np.load(path) as data:
        info = json.loads(str(data["__fccgen_info__"]))
    assert info == {"steps": 3, "error": 1e-9}
