"""fccgen export --c DIR (docs/export.md): the standalone C project of a model.

Each model is exported once per session, built with make under
-std=c99 -Wall -Wextra -pedantic -Werror, and run. Shown here:

* the example's CSV has the columns of fccgen simulate but the joint reactions (which
  need a least-squares solve of the bodies' balance after the run), and equals
  fccgen simulate on the sparse path to 1e-12 of each column's largest magnitude: it
  is the same C engine with the same steps, only the compiler's flags differ (the
  driver forces, from a second solve at each read, to 1e-10);
* the selftest replays the golden values stored at export time (and under
  -fsanitize=address,undefined);
* a parameter set by its with_parameters key equals with_parameters;
* no heap allocation from a run's start to its end (malloc and friends wrapped at
  link time), while the set-up's allocations are counted;
* two exported models link into one program (every external symbol carries the
  model's prefix, checked with nm) and run interleaved;
* models the export cannot take (method ali3p) are refused with the reason; nothing of the model
  file or the folder's path reaches the generated files unchecked.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import EXAMPLES

from fccgen.export import ExportError, export_c

CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")
STRICT = "-std=c99 -Wall -Wextra -pedantic -Werror -O2"
HERE = Path(__file__).resolve().parent
MODELS = ["four_bar", "four_bar_driven", "deployable_joints", "rsup", "a02_n_four_bar"]

pytestmark = pytest.mark.skipif(CC is None or MAKE is None or not sys.platform.startswith("linux"),
                                reason="needs a C compiler, make and GNU ld (Linux)")


def run(cmd, cwd, **kw):
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, **kw)
    assert done.returncode == 0, f"{cmd}: {done.stdout}\n{done.stderr}"
    return done.stdout


def read_csv(path):
    names = path.read_text().splitlines()[0].split(",")
    return names, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


@pytest.fixture(scope="session")
def exported(build_dir, tmp_path_factory):
    """exported(name) -> (folder, header, rows of the example's CSV), built once."""
    root = tmp_path_factory.mktemp("export_c")
    cache = {}

    def get(name):
        if name not in cache:
            folder = export_c(EXAMPLES / f"{name}.yaml", root / name, build_dir)
            run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
            run([f"./{name}_example", "out.csv"], folder)
            cache[name] = (folder, *read_csv(folder / "out.csv"))
        return cache[name]
    return get


def assert_columns_equal(names, rows, result, rtol):
    for k, name in enumerate(names):
        want = result.t if name == "t" else result[name]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[:, k] - want)) <= rtol * scale, name


@pytest.mark.parametrize("name", MODELS)
def test_the_example_writes_simulates_csv(name, exported, compiled_sparse):
    """Same columns (but reactions), same rows, equal to 1e-12 of each column's
    largest magnitude; and the selftest passes. The driver forces (four_bar_driven's
    motor.torque) come from a second solve at each read, the engine's
    augmented-Lagrangian multipliers corrected once, where simulate takes a
    least-squares solve: 1e-10 of the column's largest (measured 3.8e-13)."""
    folder, names, rows = exported(name)
    result = compiled_sparse(name).simulate(reactions=False)
    drivers = _driver_columns(compiled_sparse(name))
    expected = [n for n in result.names
                if not n.endswith((".fx", ".fy", ".fz", ".tx", ".ty", ".tz"))]
    assert names == expected
    assert rows.shape == (len(result.t), len(names))
    plain = [k for k, n in enumerate(names) if n not in drivers]
    assert_columns_equal([names[k] for k in plain], rows[:, plain], result, 1e-12)
    forces = [k for k, n in enumerate(names) if n in drivers]
    assert_columns_equal([names[k] for k in forces], rows[:, forces], result, 1e-10)
    assert bool(forces) == (name == "four_bar_driven")
    assert run([f"./{name}_selftest"], folder).strip() == "selftest passed"


def _driver_columns(solver):
    from fccgen.mechanism.driver_forces import driver_rows
    return set(driver_rows(solver.plan))


def test_the_auto_path_agrees_with_the_sparse_export(exported, compiled):
    """fccgen simulate's default path (auto: dense here) and the export's sparse path
    are two solves of the same equations: equal to 1e-9 of each column (the two
    factorisations round differently)."""
    names, rows = exported("four_bar")[1:]
    result = compiled("four_bar").simulate(reactions=False)
    assert_columns_equal(names[:-1], rows[:, :-1], result, 1e-9)   # not constraint_error


def test_a_parameter_set_by_key_equals_with_parameters(exported, compiled_sparse):
    folder = exported("four_bar_driven")[0]
    run(["./four_bar_driven_example", "heavy.csv", "bodies.coupler.mass=1.3",
         "bodies.rocker.inertia[0]=4e-5"], folder)
    names, rows = read_csv(folder / "heavy.csv")
    solver = compiled_sparse("four_bar_driven").with_parameters(
        {"bodies.coupler.mass": 1.3, "bodies.rocker.inertia[0]": 4e-5})
    assert_columns_equal(names, rows, solver.simulate(reactions=False), 1e-12)


def test_a_bad_parameter_is_refused_by_the_api(exported):
    folder = exported("four_bar_driven")[0]
    for arg, why in (("bodies.coupler.mass=-1", "must be a positive number"),
                     ("bodies.nothing.mass=1", "no parameter of this name"),
                     ("bodies.coupler.mass=abc", "not a number")):
        done = subprocess.run(["./four_bar_driven_example", "bad.csv", arg], cwd=folder,
                              capture_output=True, text=True)
        assert done.returncode == 2 and why in done.stderr, done.stderr


def test_no_heap_allocation_while_stepping(exported, tmp_path):
    """Through the API: start, every step, every output read; the set-up's
    allocations are seen by the same counter."""
    folder = exported("four_bar_driven")[0]
    exe = tmp_path / "alloc"
    run([CC, "-std=c99", "-O2", f"-I{folder}", "-DMODEL=four_bar_driven",
         "-DHEADER=four_bar_driven.h", str(HERE / "c" / "export_alloc.c"),
         str(folder / "libfour_bar_driven.a"), "-o", str(exe),
         "-Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=free", "-lm"], tmp_path)
    lines = run([str(exe)], tmp_path).splitlines()
    assert int(lines[0].split()[1]) > 20
    words = lines[1].split()
    assert words[0] == "allocations" and int(words[1]) == 0 and int(words[3]) == 1000


def test_the_selftest_passes_under_the_sanitizers(exported, tmp_path):
    """The whole project again with -fsanitize=address,undefined (the model with
    joints and a driver: every output kind but slides)."""
    src = exported("four_bar_driven")[0]
    folder = tmp_path / "asan"
    shutil.copytree(src, folder, ignore=shutil.ignore_patterns("*.o", "*.a", "*_example",
                                                               "*_selftest", "*.csv"))
    flags = "-std=c99 -O1 -g -fsanitize=address,undefined -fno-sanitize-recover=all"
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={flags}", f"LDFLAGS={flags}",
         "four_bar_driven_selftest"], folder)
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1"}
    assert run(["./four_bar_driven_selftest"], folder, env=env).strip() == "selftest passed"


def test_two_models_link_into_one_program(exported, tmp_path):
    """four_bar and rsup: both libraries hold a whole engine, under their prefixes
    (nm: every defined external symbol starts with the model's name)."""
    fb, rs = exported("four_bar")[0], exported("rsup")[0]
    nm = shutil.which("nm")
    for folder, name in ((fb, "four_bar"), (rs, "rsup")):
        if nm:
            listed = run([nm, "-g", "--defined-only", f"lib{name}.a"], folder)
            symbols = [ln.split()[2] for ln in listed.splitlines() if len(ln.split()) == 3]
            assert symbols and all(s.startswith(name + "_") for s in symbols), \
                [s for s in symbols if not s.startswith(name + "_")]
    exe = tmp_path / "two"
    run([CC, "-std=c99", "-O2", "-Wall", "-Werror", f"-I{fb}", f"-I{rs}",
         str(HERE / "c" / "export_two_models.c"), str(fb / "libfour_bar.a"),
         str(rs / "librsup.a"), "-o", str(exe), "-lm"], tmp_path)
    lines = run([str(exe)], tmp_path).splitlines()
    for line, name in zip(lines, ("four_bar", "rsup")):
        words = line.split()
        assert words[0] == name
        _, names, rows = exported(name)
        row = rows[np.argmin(np.abs(rows[:, 0] - 0.1))]
        got = np.array([float(w) for w in words[1:]])
        assert row[0] == pytest.approx(0.1, abs=1e-12) and got.shape == row.shape
        scale = np.maximum(np.max(np.abs(rows), axis=0), 1e-300)
        assert np.all(np.abs(got - row) <= 1e-12 * scale)


def test_a_model_the_export_cannot_run_is_refused_with_the_reason(build_dir, tmp_path):
    with pytest.raises(ExportError, match="method is ali3p.*rk4"):
        export_c(EXAMPLES / "cantilever.yaml", tmp_path / "cl", build_dir)
    assert not (tmp_path / "cl").exists()


def test_the_command_line_says_what_is_missing_or_refused(capsys, tmp_path):
    from fccgen.cli import main
    model = str(EXAMPLES / "four_bar.yaml")
    assert main(["export", model, "--build-dir", str(tmp_path)]) == 1
    assert "--c DIR" in capsys.readouterr().err
    assert main(["export", str(EXAMPLES / "cantilever.yaml"), "--c", str(tmp_path / "cl"),
                 "--build-dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "cannot export cantilever" in err and "rk4" in err
    assert not (tmp_path / "cl").exists()


@pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")
def test_cmake_builds_the_same_project(exported, tmp_path):
    folder = exported("four_bar")[0]
    build = tmp_path / "build"
    run(["cmake", "-S", str(folder), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release"], tmp_path)
    run(["cmake", "--build", str(build), "--target", "four_bar_selftest"], tmp_path)
    assert run([str(build / "four_bar_selftest")], tmp_path).strip() == "selftest passed"
