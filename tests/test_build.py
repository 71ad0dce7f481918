"""Building a model's module: content-hash cache, atomic installs, compiler errors.

Models are made directly from fccgen.model.types (no model file), planned with
fccgen.plan.make_plan and built with the real derivation. Every build lands in
pytest's temporary folders.
"""
from __future__ import annotations

import ctypes
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fccgen.render
from fccgen.build import BuiltModule, build_module, load_module, structure_hash
from fccgen.build.cache import MANIFEST, cache_key, read_manifest
from fccgen.build.compile import (BUILD_LOG, FLAG_POLICY, LARGE_FILE_OPS, compile_args,
                                  ext_suffix)
from fccgen.errors import BuildError
from fccgen.model.types import (Body, Initial, Model, Point, SimulateDefaults, Vector,
                                Where)
from fccgen.plan import make_plan
from fccgen.plan.kernels import KERNEL_NAMES

ROOT = Path(__file__).resolve().parent.parent


def pendulum_model(mass=2.0, length=1.0, moving_axis=False, name="pendulum") -> Model:
    """A body hinged at a fixed point; its axis vector is fixed or moving (a
    different structure: one more coordinate triple and a unit-vector class)."""
    w = Where("pendulum.yaml", None)
    points = {"O": Point("O", np.zeros(3), True, w),
              "P": Point("P", np.array([length, 0.0, 0.0]), False, w)}
    vectors = {"z": Vector("z", np.array([0.0, 0.0, 1.0]), not moving_axis, w)}
    bodies = {"arm": Body("arm", "O", "P", "z", mass, np.array([length / 2, 0.0, 0.0]),
                          np.diag([0.1, 0.2, 0.3]), w)}
    return Model(name, "pendulum.yaml", np.array([0.0, 0.0, -9.81]), points, vectors,
                 bodies, [], [], Initial(), SimulateDefaults())


def snapshot(directory: Path) -> dict[str, tuple[int, bytes]]:
    """File name -> (mtime in ns, contents) of every file in a folder."""
    return {p.name: (p.stat().st_mtime_ns, p.read_bytes())
            for p in sorted(directory.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def first_build(tmp_path_factory):
    """One fresh build of the pendulum, with the progress messages it gave."""
    out_dir = tmp_path_factory.mktemp("gen")
    messages: list[str] = []
    built = build_module(make_plan(pendulum_model()), out_dir, progress=messages.append)
    return out_dir, built, messages


@pytest.fixture
def copy_of_first(first_build, tmp_path):
    """A private copy of the first build's out_dir, for tests that change it."""
    out_dir, built, _ = first_build
    shutil.copytree(out_dir, tmp_path / "gen")
    return tmp_path / "gen"


# -- cache ---------------------------------------------------------------------------

def test_miss_then_hit(first_build):
    out_dir, built, messages = first_build
    assert not built.cache_hit
    assert set(built.timings) == {"derive", "print", "render", "compile", "total"}
    assert built.timings["compile"] > 0 and built.timings["derive"] > 0
    assert any(m.startswith("deriving") for m in messages)
    assert any(m.startswith("compiling") for m in messages)
    # the messages are structured events too (fccgen.progress): classes counted
    derive = [m for m in messages if m.stage == "derive"]
    assert derive[0].done == 0 and derive[-1].done == derive[-1].total > 0
    assert [m.stage for m in messages if m.done is None] == ["render", "compile", "compile"]
    assert built.directory == out_dir / "pendulum" / built.cache_key[:16]
    assert built.path.is_file()
    before = snapshot(built.directory)

    again = build_module(make_plan(pendulum_model()), out_dir)
    assert again.cache_hit
    assert again.path == built.path and again.cache_key == built.cache_key
    assert again.timings["compile"] == 0 and again.timings["derive"] == 0
    assert again.n_ops == built.n_ops
    assert snapshot(built.directory) == before          # nothing rewritten or recompiled


def test_changed_numbers_keep_the_structure_and_hit(first_build):
    out_dir, built, _ = first_build
    plan = make_plan(pendulum_model(mass=7.5, length=2.0))
    assert structure_hash(plan.classes) == built.structure_hash
    assert build_module(plan, out_dir).cache_hit


def test_cache_hit_does_not_import_sympy(first_build):
    out_dir, built, _ = first_build
    script = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('build_helpers', {__file__!r})\n"
        "helpers = importlib.util.module_from_spec(spec); spec.loader.exec_module(helpers)\n"
        "from fccgen.build import build_module, load_module\n"
        "from fccgen.plan import make_plan\n"
        f"built = build_module(make_plan(helpers.pendulum_model()), {str(out_dir)!r})\n"
        "load_module(built).table_capsule()\n"
        "print(built.cache_hit, 'sympy' in sys.modules)\n")
    # the fccgen this test imported (source tree or installed), never the working dir
    package_parent = str(Path(fccgen.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [package_parent, *filter(None, [os.environ.get("PYTHONPATH")])])}
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         cwd=out_dir, env=env)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["True", "False"]


def test_cache_key_covers_its_inputs(monkeypatch):
    classes = make_plan(pendulum_model()).classes
    other = make_plan(pendulum_model(moving_axis=True)).classes
    key = cache_key("pendulum", classes, FLAG_POLICY)
    assert key == cache_key("pendulum", classes, FLAG_POLICY)
    assert key != cache_key("pendulum", other, FLAG_POLICY)
    assert key != cache_key("pendulum2", classes, FLAG_POLICY)
    assert key != cache_key("pendulum", classes, {**FLAG_POLICY, "default": "-O3"})
    assert key != cache_key("pendulum", classes, FLAG_POLICY, extra="hand-made")
    texts = fccgen.render.template_texts()
    monkeypatch.setattr("fccgen.build.cache.template_texts",
                        lambda: {**texts, "kernels.c.jinja": texts["kernels.c.jinja"] + " "})
    assert key != cache_key("pendulum", classes, FLAG_POLICY)
    monkeypatch.setattr("fccgen.build.cache.runtime_header", lambda: "/* other */")
    monkeypatch.setattr("fccgen.build.cache.template_texts", lambda: texts)
    assert key != cache_key("pendulum", classes, FLAG_POLICY)


def test_changed_structure_is_a_miss_and_never_a_stale_import(first_build, copy_of_first):
    _, built, _ = first_build
    old = load_module(built)
    before = snapshot(copy_of_first / "pendulum" / built.cache_key[:16])
    rebuilt = build_module(make_plan(pendulum_model(moving_axis=True)), copy_of_first)
    assert not rebuilt.cache_hit and rebuilt.cache_key != built.cache_key
    new = load_module(rebuilt)
    assert len(old.CLASS_NAMES) == 1 and len(new.CLASS_NAMES) == 2
    assert new.STRUCTURE_HASH == rebuilt.structure_hash != old.STRUCTURE_HASH
    # One folder per structure: the new build sits beside the old one, which is
    # untouched, so neither can remove the other's module.
    assert rebuilt.directory.parent == copy_of_first / "pendulum"
    assert snapshot(copy_of_first / "pendulum" / built.cache_key[:16]) == before
    modules = [p for p in rebuilt.directory.iterdir() if p.suffix == ".so"]
    assert sorted(p.name for p in modules) == sorted([rebuilt.path.name,
                                                      f"pendulum{ext_suffix()}"])
    assert all(os.path.samefile(p, rebuilt.path) for p in modules)
    assert read_manifest(rebuilt.directory)["cache_key"] == rebuilt.cache_key
    old_copy = build_module(make_plan(pendulum_model()), copy_of_first)
    assert old_copy.cache_hit and load_module(old_copy).STRUCTURE_HASH == old.STRUCTURE_HASH


def test_load_module_from_its_folder(first_build):
    _, built, _ = first_build
    module = load_module(built.directory)
    assert module.STRUCTURE_HASH == built.structure_hash
    with pytest.raises(BuildError, match="holds no built module"):
        load_module(built.directory.parent)


# -- failed builds ---------------------------------------------------------------------

def test_compiler_error_raises_and_keeps_the_previous_build(copy_of_first, monkeypatch):
    plan = make_plan(pendulum_model(moving_axis=True))
    key16 = cache_key("pendulum", plan.classes, FLAG_POLICY)[:16]
    target = copy_of_first / "pendulum"
    old_entry = next(p for p in target.iterdir() if p.is_dir())
    before = snapshot(old_entry)
    render = fccgen.render.render_sources

    def broken(*args, **kwargs):
        sources = render(*args, **kwargs)
        sources["kernels.c"] = sources["kernels.c"].replace(
            "out[0] = ", "out[0] = undeclared_in_test + ", 1)
        return sources

    monkeypatch.setattr(fccgen.render, "render_sources", broken)
    with pytest.raises(BuildError) as info:
        build_module(plan, copy_of_first)
    message = str(info.value)
    failed = target / f"{key16}.failed-build"
    # The compiler's own error line (its quotes depend on the locale).
    assert re.search(r"kernels\.c:\d+:\d+: error: .undeclared_in_test. undeclared", message)
    assert str(failed) in message
    assert snapshot(old_entry) == before
    assert (failed / "kernels.c").is_file() and (failed / BUILD_LOG).is_file()
    # no module of the failed structure, no temporary folder left
    assert sorted(p.name for p in target.iterdir() if not p.name.endswith(".lock")) == \
        sorted([old_entry.name, failed.name])


# -- generated files -------------------------------------------------------------------

def test_generated_files_say_so(first_build):
    _, built, _ = first_build
    for name in ("kernels.c", "kernels.h", "module.pyx", "build_module.py"):
        text = (built.directory / name).read_text()
        head = "\n".join(text.splitlines()[:6])
        assert "Generated by fccgen" in head and "Do not edit" in head, name
        assert built.structure_hash in head, name
    kernels = (built.directory / "kernels.c").read_text()
    assert "M = m Dhat^T Dhat + Phi_b^T I_b Phi_b" in kernels      # equation comment
    assert "out[9]: 3 x 3, row-major" in kernels                    # shapes
    manifest = read_manifest(built.directory)
    assert manifest["class_keys"] == [c.key for c in make_plan(pendulum_model()).classes]
    assert (built.directory / MANIFEST).is_file()


def test_compiler_prints_no_warnings_for_generated_code(first_build):
    _, built, _ = first_build
    log = (built.directory / BUILD_LOG).read_text()
    kernels_cmd = [line for line in log.splitlines() if " -c kernels.c " in line]
    assert len(kernels_cmd) == 1
    assert kernels_cmd[0].split()[-3:] == ["-O2", "-Wall", "-g0"]   # ours come last
    assert not [line for line in log.splitlines() if "warning:" in line]


def test_flags_follow_the_size_of_the_file():
    assert compile_args(100)[0] == "-O2"
    assert compile_args(LARGE_FILE_OPS + 1)[0] == "-O1"
    assert "-g" not in compile_args(100) and "-Wall" in compile_args(100)
    assert "-Werror" not in compile_args(100)


# -- module interface ------------------------------------------------------------------

def test_module_exposes_table_and_names(first_build):
    _, built, _ = first_build
    plan = make_plan(pendulum_model())
    module = load_module(built)
    capsule = module.table_capsule()
    is_valid = ctypes.pythonapi.PyCapsule_IsValid
    is_valid.argtypes, is_valid.restype = [ctypes.py_object, ctypes.c_char_p], ctypes.c_int
    assert is_valid(capsule, b"fccgen.model_table") == 1

    class Table(ctypes.Structure):
        _fields_ = [("abi_version", ctypes.c_int), ("structure_hash", ctypes.c_char_p),
                    ("n_classes", ctypes.c_int), ("classes", ctypes.c_void_p)]

    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.argtypes, get.restype = [ctypes.py_object, ctypes.c_char_p], ctypes.c_void_p
    table = Table.from_address(get(capsule, b"fccgen.model_table"))
    assert table.abi_version == module.ABI_VERSION == 3
    assert table.structure_hash.decode() == module.STRUCTURE_HASH == built.structure_hash
    assert table.n_classes == len(plan.classes)
    assert module.CLASS_NAMES == tuple(c.name for c in plan.classes)
    assert module.KERNEL_NAMES == KERNEL_NAMES
    assert isinstance(built, BuiltModule) and built.module_name == "pendulum"


def test_evaluate_gives_the_body_mass_matrix(first_build):
    """Hand derivation for the pendulum body (only P moves) at its initial state:
    e1 = x, e2 = z, e3 = -y; w_b = (0, P'.y / l, P'.z / l) and v_G = a1 P', so
    M = m a1^2 E + diag(0, Iyy, Izz) / l^2 with Iyy = 0.2, Izz = 0.3."""
    _, built, _ = first_build
    plan = make_plan(pendulum_model())
    element = plan.elements[0]
    module = load_module(built)
    m = module.evaluate("mass_matrix", 0, plan.q0[element.q_index()], None, element.params)
    mass, a1, l = 2.0, 0.5, 1.0
    # Rounding only: a few operations on numbers of order one.
    np.testing.assert_allclose(m.reshape(3, 3), np.diag([mass * a1 ** 2,
                                                         mass * a1 ** 2 + 0.2 / l ** 2,
                                                         mass * a1 ** 2 + 0.3 / l ** 2]),
                               rtol=1e-14, atol=1e-15)
