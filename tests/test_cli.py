"""The command line (docs/design.md §5): each command works end to end, errors are one
clear line with a non-zero exit, and the runtime path never imports SymPy."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import EXAMPLES, run_python
from fccgen.cli import main
from fccgen.results.result import Result

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
    [manifest_file] = (cli_build_dir / "a01_pendulum").glob("*/fccgen.json")
    manifest = json.loads(manifest_file.read_text())
    assert manifest["model_name"] == "a01_pendulum"


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".h5"])
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
    # how it was made comes back from every format
    assert r.info["method"] == "rk4" and r.info["dt"] == 1e-3 and r.info["t_end"] == 0.5
    assert r.info["model"]["name"] == "a01_pendulum" and r.info["steps"] == 500


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


# -- faults: checked before the run, partial results, Ctrl-C, environment ------------------

def test_unwritable_out_is_refused_before_anything_runs(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    build = tmp_path / "gen"
    for out, says in ((tmp_path / "file" / "r.csv", "in the way"),
                      (tmp_path / "r.txt", "results are written as .csv, .npz or .h5")):
        code, _, err = run(["simulate", PENDULUM, "--build-dir", build, "--out", out],
                           capsys)
        assert code == 1 and err.startswith("fccgen: error: ") and says in err
        assert "Traceback" not in err and err.count("\n") == 1
    assert not build.exists()                       # refused before generating anything


def _stop_after_three_rows(monkeypatch, exc_type):
    """Make the compiled solver's run stop like an interrupted integrator: it raises
    with the rows it recorded attached (``exc.partial``)."""
    from fccgen.errors import SimulationError
    from fccgen.runtime.solver import CompiledSolver
    real = CompiledSolver._run

    def stopping(self, *args):
        arrays, stats = real(self, *args)
        exc = (SimulationError("simulation stopped at t = 0.2: singular mass matrix (test)")
               if exc_type is SimulationError else KeyboardInterrupt())
        exc.partial = ({k: v[:3] for k, v in arrays.items()}, stats)
        raise exc
    monkeypatch.setattr(CompiledSolver, "_run", stopping)


@pytest.mark.parametrize("stop", ["error", "ctrl-c"])
@pytest.mark.parametrize("keep", [True, False])
def test_partial_result_only_when_asked(stop, keep, cli_build_dir, tmp_path, capsys,
                                        monkeypatch):
    from fccgen.errors import PartialResultWarning, SimulationError
    _stop_after_three_rows(monkeypatch, SimulationError if stop == "error"
                           else KeyboardInterrupt)
    out = tmp_path / "run.csv"
    code, _, err = run(["simulate", PENDULUM, "--build-dir", cli_build_dir, "-q",
                        "--t-end", "0.5", "--output-dt", "0.1", "--out", out,
                        *(["--keep-partial"] if keep else [])], capsys)
    assert code == (1 if stop == "error" else 130) and "Traceback" not in err
    assert not out.exists()
    partial = tmp_path / "run.partial.csv"
    if not keep:
        assert list(tmp_path.iterdir()) == []
        assert err.endswith("(test) (got 0.001); no results written\n" if stop == "error" else
                            "fccgen: interrupted; no results written\n")
        return
    assert err.endswith(f"partial result written to {partial}\n")
    with pytest.warns(PartialResultWarning, match="t = 0.2"):
        r = Result.load(partial)
    assert r.partial and np.allclose(r.t, [0.0, 0.1, 0.2], atol=1e-12)
    assert ("Ctrl-C" if stop == "ctrl-c" else "singular") in r.info["stopped_by"]


def test_keep_partial_says_when_there_is_nothing_to_keep(cli_build_dir, tmp_path, capsys,
                                                        monkeypatch):
    from fccgen.runtime.solver import CompiledSolver

    def interrupted(self, *args):
        raise KeyboardInterrupt       # no rows attached
    monkeypatch.setattr(CompiledSolver, "_run", interrupted)
    code, _, err = run(["simulate", PENDULUM, "--build-dir", cli_build_dir, "-q",
                        "--t-end", "0.1", "--out", tmp_path / "r.npz", "--keep-partial"],
                       capsys)
    assert code == 130 and list(tmp_path.iterdir()) == []
    assert err == ("fccgen: interrupted; --keep-partial: the integrator handed back no "
                   "recorded rows, so no partial result was written\n")


def test_ctrl_c_during_a_build_is_one_line_and_leaves_nothing(tmp_path, capsys,
                                                              monkeypatch):
    from fccgen.cli import _Progress

    def interrupt(self, message):
        if message.startswith("compiling"):
            raise KeyboardInterrupt
    monkeypatch.setattr(_Progress, "__call__", interrupt)
    build = tmp_path / "gen"
    code, out, err = run([PENDULUM, "--build-dir", build], capsys)
    assert (code, out, err) == (130, "", "fccgen: interrupted\n")
    leftovers = [p.name for p in (build / "a01_pendulum").iterdir()
                 if not p.name.endswith(".lock")]
    assert leftovers == []


def test_sigint_ends_a_run_with_status_130(cli_build_dir, tmp_path):
    """A real Ctrl-C (SIGINT) in the middle of a run, without a race: the run cannot
    end first (DOPRI5 on a pendulum to t = 1e12 s, some 1e13 steps, accepted by the
    run's limits), and the signal is sent only once the run has reported progress at
    a time t > 0 from inside its loop.

    The child starts with SIGINT at its default disposition. A process started in the
    background by a non-interactive shell (``cmd &``, nohup) inherits SIGINT ignored,
    and Python then installs no KeyboardInterrupt handler, as a Unix program should:
    the run rightly ignores the signal. Without the reset this test would depend on
    how the test runner itself was started."""
    import os
    import signal
    import subprocess
    import sys

    import fccgen
    assert main([str(PENDULUM), "--build-dir", str(cli_build_dir), "-q"]) == 0
    package_parent = str(Path(fccgen.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": package_parent}
    with subprocess.Popen(
            [sys.executable, "-m", "fccgen.cli", "simulate", str(PENDULUM), "--build-dir",
             str(cli_build_dir), "--method", "dopri5", "--t-end", "1e12",
             "--output-dt", "1e6", "--out", str(tmp_path / "r.npz")],
            cwd=tmp_path, env=env, stderr=subprocess.PIPE, stdout=subprocess.PIPE,
            text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)) as proc:
        seen = []
        for line in proc.stderr:             # plain progress lines: stderr is a pipe
            seen.append(line)
            match = re.match(r"fccgen: t = (\S+) of ", line)
            if match and float(match.group(1)) > 0:
                break
        else:
            raise AssertionError(f"the run ended without reporting progress: {seen}")
        proc.send_signal(signal.SIGINT)
        try:
            _, rest = proc.communicate(timeout=300)  # a guard against a hang, not a timing
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            raise AssertionError(f"the run ignored SIGINT: {seen}") from None
    assert proc.returncode == 130, rest
    assert rest.splitlines()[-1] == "fccgen: interrupted; no results written"
    assert "Traceback" not in rest and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", [[], ["simulate", "--t-end", "0.01"],
                                     ["bench", "--repeats", "1"]])
def test_force_rebuilds_in_every_command_that_builds(command, cli_build_dir, capsys,
                                                     monkeypatch):
    import fccgen.api
    forced = []
    generate = fccgen.api.generate

    def recording(path, build_dir="generated", *, force=False, progress=None):
        forced.append(force)
        return generate(path, build_dir, force=False, progress=progress)
    monkeypatch.setattr(fccgen.api, "generate", recording)
    args = [*command[:1], PENDULUM, *command[1:], "--build-dir", cli_build_dir, "-q"]
    code, _, err = run([*args, "--force"], capsys)
    assert code == 0, err
    assert forced and forced[0] is True


def test_missing_compiler_is_one_paragraph(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    code, out, err = run([PENDULUM, "--build-dir", tmp_path / "gen"], capsys)
    assert code == 1 and out == ""
    lines = err.splitlines()
    assert lines[-1].startswith("fccgen: error: no C compiler") and "set CC" in lines[-1]
    assert all(line.startswith("fccgen: ") for line in lines)


def test_repaired_cache_is_one_warning_line(cli_build_dir, tmp_path, capsys, monkeypatch):
    import shutil

    import fccgen.build
    from fccgen.errors import BuildError
    assert main([str(PENDULUM), "--build-dir", str(cli_build_dir), "-q"]) == 0
    shutil.copytree(cli_build_dir / "a01_pendulum", tmp_path / "gen" / "a01_pendulum")
    [manifest] = (tmp_path / "gen" / "a01_pendulum").glob("*/fccgen.json")
    manifest.write_text("{}")

    def no_compile(*args):
        raise BuildError("not compiled in this test")
    monkeypatch.setattr(fccgen.build, "_compile_and_install", no_compile)
    code, _, err = run([PENDULUM, "--build-dir", tmp_path / "gen", "-q"], capsys)
    assert code == 1
    assert err.splitlines() == [
        f"fccgen: warning: the cached module in {manifest.parent} is damaged or "
        "incomplete (its fccgen.json lacks cache_key, extension, files, flags, "
        "model_name, n_ops, structure_hash, timings); rebuilding it",
        "fccgen: error: not compiled in this test"]


def test_python_dash_m_fccgen_is_the_command(tmp_path):
    """python -m fccgen runs the command line (from a folder that does not shadow the
    installed package)."""
    from conftest import run_python
    out = run_python("import runpy, sys; sys.argv = ['fccgen', '--version']; "
                     "runpy.run_module('fccgen', run_name='__main__')", tmp_path,
                     check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("fccgen ")
