"""fccgen export --c of a model with flexible members (docs/export.md,
docs/flexible.md): the flexible pendulum is exported, built under -std=c99 -Wall -Wextra -pedantic -Werror and run. The
example's CSV has simulate's columns but the members' strain and curvature (computed
after a run, like the reactions) and equals fccgen simulate on the sparse path to
1e-12 of each column's largest magnitude (the same C engine and steps); the selftest
replays the golden values."""
from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.export import export_c

CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")
STRICT = "-std=c99 -Wall -Wextra -pedantic -Werror -O2"

pytestmark = pytest.mark.skipif(CC is None or MAKE is None or not sys.platform.startswith("linux"),
                                reason="needs a C compiler and make (Linux)")


def run(cmd, cwd):
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    assert done.returncode == 0, f"{cmd}: {done.stdout}\n{done.stderr}"
    return done.stdout


def test_export_of_members_runs_as_simulate(build_dir, tmp_path):
    name = "flexible_pendulum"
    folder = export_c(EXAMPLES / f"{name}.yaml", tmp_path / name, build_dir)
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
    run([f"./{name}_example", "out.csv"], folder)
    assert run([f"./{name}_selftest"], folder).strip() == "selftest passed"
    names = (folder / "out.csv").read_text().splitlines()[0].split(",")
    rows = np.loadtxt(folder / "out.csv", delimiter=",", skiprows=1, ndmin=2)
    result = fccgen.load(EXAMPLES / f"{name}.yaml", build_dir,
                         linear_solver="sparse").simulate(reactions=False)
    expected = [n for n in result.names if not n.endswith((".strain", ".curvature"))]
    assert names == expected
    assert rows.shape == (len(result.t), len(names))
    for k, column in enumerate(names):
        want = result.t if column == "t" else result[column]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[:, k] - want)) <= 1e-12 * scale, column
