"""The command line (DESIGN section 5): each command works end to end, errors are one
clear line with a non-zero exit, and the runtime path never imports SymPy."""
from __future__ import annotations

import json
import numpy as np
import pytest

from conftest import EXAMPLES, run_python
from fccgen.cli import main
from fccgen.results import Result

PENDULUM = EXAMPLES / "a01_pendulum.yaml"


@pytest.fixture(scope="module")
def cli_build_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("cli-generated")


def run(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_generate_then_cache_hit(cli_build_dir, capsys):
    code, out, err = run([PENDULUM, "--build-dir", cli_build_dir, "--force"], capsys)
    assert code == 0, err
    assert "a01_pendulum: built" in out
    assert "import fccgen" in out and "fccgen.load(" in out
    code, out, err = run([PENDULUM, "--build-dir", cli_build_dir], capsys)
    assert code == 0 and "served from the cache" in out
    manifest = json.loads((cli_build_dir / "a01_pendulum" / "fccgen.json").read_text())
    assert manifest["model_name"] == "a01_pendulum"


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_simulate_writes_results(cli_build_dir, tmp_path, capsys, suffix):
    out_file = tmp_path / f"run{suffix}"
    code, out, err = run(["simulate", PENDULUM, "--build-dir", cli_build_dir,
                          "--t-end", "0.5", "--dt", "1e-3", "--output-dt", "0.1",
                          "--out", out_file], capsys)
    assert code == 0, err
    assert "max constraint error" in out and str(out_file) in out
    r = Result.load(out_file)
    assert np.allclose(r.t, [0, 0.1, 0.2, 0.3, 0.4, 0.5], atol=1e-12)
    assert r.names == ["t", "P.x", "P.y", "P.z", "P.vx", "P.vy", "P.vz",
                       "pendulum.cx", "pendulum.cy", "pendulum.cz",
                       "pendulum.wx", "pendulum.wy", "pendulum.wz",
                       "energy", "constraint_error"]
    # the mass falls from rest: energy conserved, length kept
    assert np.allclose(np.hypot(r["P.x"], r["P.y"]), 1.0, atol=1e-12)
    assert r["P.y"][-1] < -0.5


def test_check_reports_dof_and_redundancy(capsys):
    code, out, _ = run(["check", EXAMPLES / "four_bar.yaml"], capsys)
    assert code == 0
    assert "coordinates 6, constraint equations 6, rank 5" in out
    assert "0 counted (coordinates - equations), 1 by rank" in out
    assert "redundant constraint equations: 1" in out


def test_bench_prints_speedups(cli_build_dir, capsys):
    code, out, err = run(["bench", PENDULUM, "--build-dir", cli_build_dir,
                          "--repeats", "20"], capsys)
    assert code == 0, err
    for row in ("mass_matrix", "accelerations", "rk4 step (projected)", "cache hit"):
        assert row in out


def test_model_error_is_one_line_and_exit_code_2(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\npoints:\n  P: [0, 0, 0]\nbodies:\n  b:\n    points: [P, Q]\n"
                   "    vector: z\n    mass: 1\n    inertia: [1, 1, 1]\n")
    code, out, err = run(["check", bad], capsys)
    assert code == 2 and out == ""
    assert err.startswith(f"fccgen: error: {bad}:6: bodies.b.points")
    assert not (tmp_path / "generated").exists()


def test_nothing_generated_from_a_bad_model(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text((EXAMPLES / "double_pendulum.yaml").read_text()
                   .replace("mass: 1.0", "mass: -1.0"))
    build = tmp_path / "gen"
    code, _, err = run([bad, "--build-dir", build], capsys)
    assert code == 2 and "must be a positive number" in err
    assert not build.exists() or not any(build.iterdir())


def test_runtime_path_does_not_import_sympy(cli_build_dir, tmp_path):
    """After a build, loading the cached module and simulating imports no SymPy (it
    costs hundreds of milliseconds and is not needed at run time)."""
    assert main([str(PENDULUM), "--build-dir", str(cli_build_dir), "-q"]) == 0
    code = (
        "import sys, fccgen\n"
        f"s = fccgen.load({str(PENDULUM)!r}, {str(cli_build_dir)!r})\n"
        "r = s.simulate(t_end=0.01, output_dt=1e-3)\n"
        "assert 'sympy' not in sys.modules, 'sympy imported'\n"
        "print(len(r.t))\n")
    proc = run_python(code, tmp_path, check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "11"
