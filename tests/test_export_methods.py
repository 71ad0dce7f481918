"""fccgen export of the model's other simulate: methods (docs/export.md, "What the
export runs"): baumgarte and dopri5.

Each model file is an example with its simulate: method changed, exported once per
session, built with make under -std=c99 -Wall -Wextra -pedantic -Werror, and run:

* the example's CSV equals fccgen simulate of the same file on the sparse path to
  1e-12 of each column's largest magnitude: the same C engine with the same steps,
  only the compiler's flags differ (dopri5: the same accepted steps, its records by
  the same dense output at the same times);
* the FMU, run by FMPy, equals simulate to 1e-10 (as tests/test_export_fmu.py);
* what simulate refuses with a method (events with baumgarte) the export refuses
  with the same reason, and sensitivities are refused for a method other than rk4.
"""
from __future__ import annotations

import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.errors import FccgenError
from fccgen.export import ExportError, export_c
from test_export_c import CC, MAKE, STRICT, assert_columns_equal, read_csv, run

pytestmark = pytest.mark.skipif(CC is None or MAKE is None or not sys.platform.startswith("linux"),
                                reason="needs a C compiler, make and GNU ld (Linux)")
HERE = Path(__file__).resolve().parent


def with_method(example: str, method: str, folder: Path) -> Path:
    """examples/<example>.yaml with simulate: method set to method, in folder."""
    text = (EXAMPLES / f"{example}.yaml").read_text()
    line = re.search(r"^simulate: \{(.*)\}$", text, re.M)
    settings = re.sub(r",?\s*method: \w+", "", line.group(1))
    path = folder / f"{example}_{method}.yaml"
    path.write_text(text.replace(line.group(0),
                                 f"simulate: {{{settings}, method: {method}}}"))
    return path


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    folder = tmp_path_factory.mktemp("methods")
    return lambda example, method: with_method(example, method, folder)


@pytest.fixture(scope="module")
def exported(models, build_dir, tmp_path_factory):
    """exported(example, method) -> (folder, header, rows of the example's CSV)."""
    root = tmp_path_factory.mktemp("export_methods")
    cache = {}

    def get(example, method):
        if (example, method) not in cache:
            folder = export_c(models(example, method), root / f"{example}_{method}",
                              build_dir)
            run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
            assert run([f"./{example}_selftest"], folder).strip() == "selftest passed"
            run([f"./{example}_example", "out.csv"], folder)
            cache[example, method] = (folder, *read_csv(folder / "out.csv"))
        return cache[example, method]
    return get


def simulated(models, build_dir, example, method, **kw):
    solver = fccgen.load(models(example, method), build_dir, linear_solver="sparse")
    return solver, solver.simulate(reactions=False, **kw)


@pytest.mark.parametrize("example", ["four_bar", "four_bar_driven"])
def test_baumgarte_example_equals_simulate(example, exported, models, build_dir):
    _, names, rows = exported(example, "baumgarte")
    solver, result = simulated(models, build_dir, example, "baumgarte")
    assert result.info["method"] == "baumgarte" and rows.shape[0] == len(result.t)
    assert_columns_equal(names, rows, result, 1e-12)
    # the run is not rk4's: the constraints drift (no projection), damped
    rk4 = solver.simulate(method="rk4", reactions=False)
    assert np.max(np.abs(rk4["constraint_error"])) < 1e-9
    assert np.max(np.abs(result["constraint_error"])) > 1e3 * np.max(
        np.abs(rk4["constraint_error"]))


def test_baumgarte_with_events_is_refused_as_simulate_refuses_it(models, build_dir,
                                                                 tmp_path):
    path = models("solar_array", "baumgarte")
    with pytest.raises(FccgenError) as by_simulate:
        fccgen.load(path, build_dir, linear_solver="sparse")
    with pytest.raises(FccgenError) as by_export:
        export_c(path, tmp_path / "sa", build_dir)
    assert str(by_export.value) == str(by_simulate.value)
    assert "rk4, dopri5 in a model with events" in str(by_export.value)
    assert not (tmp_path / "sa").exists()


def test_sensitivities_are_refused_for_another_method(models, build_dir, tmp_path):
    with pytest.raises(ExportError, match="method is baumgarte.*sensitivities through "
                                          "rk4 runs only"):
        export_c(models("four_bar", "baumgarte"), tmp_path / "fb", build_dir,
                 sensitivities=True)
    assert not (tmp_path / "fb").exists()


def test_no_heap_allocation_while_stepping(exported, tmp_path):
    for example, method in (("four_bar_driven", "baumgarte"),):
        folder = exported(example, method)[0]
        exe = tmp_path / f"alloc_{method}"
        run([CC, "-std=c99", "-O2", f"-I{folder}", f"-DMODEL={example}",
             f"-DHEADER={example}.h", str(HERE / "c" / "export_alloc.c"),
             str(folder / f"lib{example}.a"), "-o", str(exe),
             "-Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=free", "-lm"], tmp_path)
        lines = run([str(exe)], tmp_path).splitlines()
        assert int(lines[0].split()[1]) > 20
        words = lines[1].split()
        assert words[0] == "allocations" and int(words[1]) == 0, (method, lines)


fmpy = None
try:
    import fmpy
except ImportError:                                   # a test dependency
    pass


def fmu_rows(models, build_dir, tmp_path, example, method, **kw):
    from fccgen.export.fmu import export_fmu
    path = export_fmu(models(example, method), tmp_path / f"{example}.fmu", build_dir)
    return fmpy.simulate_fmu(str(path), **kw)


def assert_fmu_equal(rows, result, rtol):
    assert np.allclose(rows["time"], result.t, rtol=0, atol=1e-12)
    for name in rows.dtype.names[1:]:
        want = result[name]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[name] - want)) <= rtol * scale, name


@pytest.mark.skipif(fmpy is None, reason="needs FMPy")
def test_baumgarte_fmu_equals_simulate(models, build_dir, tmp_path):
    rows = fmu_rows(models, build_dir, tmp_path, "four_bar_driven", "baumgarte",
                    stop_time=1.0, output_interval=0.01)
    _, result = simulated(models, build_dir, "four_bar_driven", "baumgarte")
    assert_fmu_equal(rows, result, 1e-10)
