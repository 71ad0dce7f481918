"""Faults around the build cache: damaged, incomplete or foreign cache entries are
detected before import and rebuilt; processes building in one folder do not disturb
each other; abandoned temporary folders are removed; the machine's problems (no
compiler, a folder that cannot be written, a full disk) end in a HostError that says
what to do.

Damage is done to copies of the session's builds (conftest ``build_dir``), never to
the builds themselves.
"""
from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import fccgen
import fccgen.build
from conftest import EXAMPLES
from fccgen.build import build_module, load_module
from fccgen.build.cache import MANIFEST, check_entry, read_manifest
from fccgen.build.compile import BUILD_LOG
from fccgen.build.store import TEMP_PREFIX, _host, clean_stale
from fccgen.errors import BuildError, CacheRepairWarning, HostError

PENDULUM = EXAMPLES / "a01_pendulum.yaml"
# Compiled and numeric versions of one model over a short run: rounding only, the two
# evaluate the same equations in a different order (docs/design.md §6: ~1e-12).
AGREE = 1e-10


@pytest.fixture
def pendulum_copy(compiled, build_dir, tmp_path):
    """(out_dir, entry): a private copy of the session's a01_pendulum build."""
    compiled("a01_pendulum")
    shutil.copytree(build_dir / "a01_pendulum", tmp_path / "gen" / "a01_pendulum",
                    ignore=shutil.ignore_patterns("*.lock"))
    out = tmp_path / "gen"
    entry = next(p for p in (out / "a01_pendulum").iterdir() if p.is_dir()
                 and not p.name.endswith(".failed-build"))
    return out, entry


def _key(entry: Path) -> str:
    return read_manifest(entry)["cache_key"]


def _truncate(entry: Path) -> None:
    so = entry / read_manifest(entry)["extension"]
    data = so.read_bytes()
    so.write_bytes(data[: len(data) // 3])           # the plain name is the same file


def _random_bytes(entry: Path) -> None:
    so = entry / read_manifest(entry)["extension"]
    so.write_bytes(np.random.default_rng(1).bytes(so.stat().st_size))


def _missing_keys(entry: Path) -> None:
    manifest = read_manifest(entry)
    del manifest["files"], manifest["structure_hash"]
    (entry / MANIFEST).write_text(json.dumps(manifest))


def _foreign(entry: Path, other: Path) -> None:
    """Another model's whole entry copied in place of this one."""
    shutil.rmtree(entry)
    shutil.copytree(other, entry)


DAMAGE = {"truncated": (_truncate, "sha256 mismatch"),
          "random bytes": (_random_bytes, "sha256 mismatch"),
          "missing keys": (_missing_keys, "lacks files, structure_hash"),
          "foreign": (None, "another model or structure")}


def _damage(kind, entry, compiled, build_dir):
    if kind == "foreign":
        compiled("double_pendulum")
        other = next(p for p in (build_dir / "double_pendulum").iterdir() if p.is_dir()
                     and not p.name.endswith(".failed-build"))
        _foreign(entry, other)
    else:
        DAMAGE[kind][0](entry)


@pytest.mark.parametrize("kind", list(DAMAGE))
def test_damage_is_detected_and_never_imported(kind, pendulum_copy, compiled, build_dir,
                                               monkeypatch):
    out, entry = pendulum_copy
    key = _key(entry)
    built = build_module(fccgen.api.plan_model(PENDULUM), out)     # sound: a hit
    assert built.cache_hit
    _damage(kind, entry, compiled, build_dir)
    manifest, problem = check_entry(entry, key, "a01_pendulum")
    assert manifest is None and DAMAGE[kind][1] in problem
    with pytest.raises(BuildError, match="cannot be imported"):
        load_module(built)                    # never dlopen'ed: it could crash us
    calls = []

    def no_compile(*args):
        calls.append(args)
        raise BuildError("stop here")          # the decision to rebuild is what is tested
    monkeypatch.setattr(fccgen.build, "_compile_and_install", no_compile)
    with pytest.warns(CacheRepairWarning, match=DAMAGE[kind][1]):
        with pytest.raises(BuildError, match="stop here"):
            build_module(fccgen.api.plan_model(PENDULUM), out)
    assert len(calls) == 1


def test_damaged_entry_is_rebuilt_and_right(pendulum_copy, numeric):
    """A truncated module (it gave SIGBUS on import) is rebuilt for real, and the new
    one agrees with the numeric version. (Every kind of damage leads to the same
    rebuild: see the test above; one real compile is enough.)"""
    out, entry = pendulum_copy
    _truncate(entry)
    with pytest.warns(CacheRepairWarning, match=f"{entry}.*rebuilding it"):
        solver = fccgen.load(PENDULUM, out)
    assert check_entry(entry, _key(entry), "a01_pendulum")[1] is None
    dt = 1e-3
    rc = solver.simulate(t_end=20 * dt, dt=dt)
    rn = numeric("a01_pendulum").simulate(t_end=20 * dt, dt=dt)
    assert np.max(np.abs(rc["P.x"] - rn["P.x"])) < AGREE
    assert np.max(np.abs(rc["P.vy"] - rn["P.vy"])) < AGREE


CONCURRENT = """
import importlib.util, json, sys
import numpy as np
spec = importlib.util.spec_from_file_location('helpers', {helpers!r})
helpers = importlib.util.module_from_spec(spec); spec.loader.exec_module(helpers)
from fccgen.build import build_module, load_module
from fccgen.numeric import NumericSolver
from fccgen.plan import make_plan
from fccgen.runtime import CompiledSolver
plan = make_plan(helpers.pendulum_model(moving_axis=sys.argv[1] == 'moving'))
built = build_module(plan, {out!r})
rc = CompiledSolver(plan, load_module(built)).simulate(t_end=0.01, dt=1e-3)
rn = NumericSolver(plan).simulate(t_end=0.01, dt=1e-3)
print(json.dumps([built.cache_hit, built.cache_key,
                  float(np.max(np.abs(rc.table() - rn.table())))]))
"""


def test_eight_processes_build_two_structures_of_one_name(tmp_path):
    """Four processes build each of two structures named 'pendulum' into one folder
    at once: each structure is compiled once, the others wait and use it, and every
    process gets a module that agrees with the numeric version."""
    helpers = str(Path(__file__).with_name("test_build.py"))
    script = CONCURRENT.format(helpers=helpers, out=str(tmp_path / "gen"))
    package_parent = str(Path(fccgen.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [package_parent, *filter(None, [os.environ.get("PYTHONPATH")])])}
    kinds = ["fixed", "moving"] * 4
    procs = [subprocess.Popen([sys.executable, "-c", script, kind], cwd=tmp_path, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for kind in kinds]
    outputs = [p.communicate() for p in procs]
    assert all(p.returncode == 0 for p in procs), [err for _, err in outputs]
    rows = [json.loads(out.strip().splitlines()[-1]) for out, _ in outputs]
    keys = {kind: {r[1] for r, k in zip(rows, kinds) if k == kind} for kind in set(kinds)}
    assert all(len(v) == 1 for v in keys.values()) and keys["fixed"] != keys["moving"]
    assert sum(not hit for hit, _, _ in rows) == 2          # one compile per structure
    assert max(diff for _, _, diff in rows) < AGREE
    model = tmp_path / "gen" / "pendulum"
    entries = sorted(p.name for p in model.iterdir() if p.is_dir())
    assert entries == sorted(k[:16] for v in keys.values() for k in v)   # no temp left


def test_abandoned_temporary_folders_are_removed(pendulum_copy):
    out, entry = pendulum_copy
    model = entry.parent
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    killed = model / f"{TEMP_PREFIX}{_host()}-{dead}-0123456789ab"
    alive = model / f"{TEMP_PREFIX}{_host()}-{os.getpid()}-0123456789ab"
    old = model / f"{TEMP_PREFIX}otherhost-1-0123456789ab"
    recent_elsewhere = model / f"{TEMP_PREFIX}otherhost-2-0123456789ab"
    for folder in (killed, alive, old, recent_elsewhere):
        folder.mkdir()
        (folder / "kernels.c").write_text("/* partial */")
    legacy = out / ".a01_pendulum.build-abc123"      # earlier versions: no owner recorded
    legacy.mkdir()
    two_days_ago = time.time() - 2 * 86400
    for folder in (old, legacy):
        os.utime(folder, (two_days_ago, two_days_ago))
    assert build_module(fccgen.api.plan_model(PENDULUM), out).cache_hit
    assert not killed.exists() and not old.exists() and not legacy.exists()
    assert alive.exists() and recent_elsewhere.exists()     # their owners may be running
    assert clean_stale(model) == []


# -- the machine's problems -----------------------------------------------------------------

@pytest.mark.parametrize("how", ["CC", "PATH"])
def test_missing_compiler_is_reported_before_deriving(how, tmp_path, monkeypatch):
    if how == "CC":
        monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    else:
        monkeypatch.delenv("CC", raising=False)
        monkeypatch.setenv("PATH", str(tmp_path))        # an empty folder
    said = []
    with pytest.raises(HostError, match="no C compiler") as info:
        build_module(fccgen.api.plan_model(PENDULUM), tmp_path / "gen", progress=said.append)
    assert "set CC" in str(info.value) and info.value.errno == errno.ENOENT
    assert not any(m.startswith("deriving") for m in said)


def test_unwritable_build_folder(tmp_path, monkeypatch):
    """Permission denied on the build folder (chmod where it restricts, i.e. not as
    root; a refused mkdir otherwise) and a folder path under a regular file."""
    plan = fccgen.api.plan_model(PENDULUM)
    locked = tmp_path / "locked"
    locked.mkdir()
    if os.geteuid() != 0:
        locked.chmod(0o555)
    else:
        real_mkdir = Path.mkdir

        def refuse(self, *args, **kwargs):
            if locked in self.parents:
                raise PermissionError(errno.EACCES, "Permission denied", str(self))
            return real_mkdir(self, *args, **kwargs)
        monkeypatch.setattr(Path, "mkdir", refuse)
    try:
        with pytest.raises(HostError, match="Permission denied.*make it writable.*"
                                            "--build-dir") as info:
            build_module(plan, locked / "gen")
        assert info.value.errno == errno.EACCES
    finally:
        locked.chmod(0o755)
    monkeypatch.undo()
    (tmp_path / "file").write_text("")
    with pytest.raises(HostError, match="in the way"):
        build_module(plan, tmp_path / "file" / "gen")


def test_read_only_cache_still_serves_a_sound_entry(pendulum_copy, monkeypatch):
    out, _ = pendulum_copy

    def no_lock(entry):
        raise AssertionError("a cache hit must not need to write")
    monkeypatch.setattr(fccgen.build, "build_lock", no_lock)
    assert build_module(fccgen.api.plan_model(PENDULUM), out).cache_hit


class _FullDisk:
    """subprocess.run of a compiler that ran out of space, and a log that cannot be
    written either."""

    def __init__(self, log_fails: bool):
        self.log_fails = log_fails

    def run(self, *args, **kwargs):
        return subprocess.CompletedProcess(
            args, 1, "", "kernels.c: fatal error: error writing to ccX.s: "
                         "No space left on device\ncompilation terminated.\n")

    def write_text(self, real):
        def write(path, text, *args, **kwargs):
            if self.log_fails and path.name == BUILD_LOG:
                raise OSError(errno.ENOSPC, "No space left on device", str(path))
            return real(path, text, *args, **kwargs)
        return write


@pytest.mark.parametrize("log_fails", [False, True])
def test_full_disk_keeps_or_quotes_the_compiler_log(log_fails, tmp_path, monkeypatch):
    disk = _FullDisk(log_fails)
    monkeypatch.setattr(fccgen.build.compile.subprocess, "run", disk.run)
    monkeypatch.setattr(Path, "write_text", disk.write_text(Path.write_text))
    with pytest.raises(HostError) as info:
        build_module(fccgen.api.plan_model(PENDULUM), tmp_path / "gen")
    message = str(info.value)
    assert info.value.errno == errno.ENOSPC and "free some space" in message
    assert "error writing to ccX.s" in message            # the compiler's own line
    if log_fails:
        assert "log could not be written" in message
    else:
        log = next((tmp_path / "gen" / "a01_pendulum").glob(f"*.failed-build/{BUILD_LOG}"))
        assert str(log) in message and "No space left" in log.read_text()


def test_full_disk_while_writing_sources(tmp_path, monkeypatch):
    def full(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))
    monkeypatch.setattr(Path, "write_text", full)
    with pytest.raises(HostError, match="no space left.*free some space") as info:
        build_module(fccgen.api.plan_model(PENDULUM), tmp_path / "gen")
    assert info.value.errno == errno.ENOSPC
    model = tmp_path / "gen" / "a01_pendulum"
    assert f"in {model}: " in str(info.value) and TEMP_PREFIX not in str(info.value)
    assert not [p for p in model.iterdir() if p.name.startswith(TEMP_PREFIX)]
