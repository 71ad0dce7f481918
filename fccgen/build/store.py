"""Where cached builds live, and how processes share them safely.

Layout of a build folder (``--build-dir``, default ``generated/``)::

    <out_dir>/<name>/<key16>/            one finished build: sources, build.log,
                                         <name>-<id><EXT_SUFFIX>, <name><EXT_SUFFIX>,
                                         fccgen.json (the manifest, with file hashes)
    <out_dir>/<name>/<key16>.lock        lock file of builds of that key
    <out_dir>/<name>/<key16>.failed-build/   sources and log of the last failed build
    <out_dir>/<name>/.fccgen-tmp-<host>-<pid>-<random>/   a build in progress

``key16`` is the start of the cache key, which covers the structure (element-class
keys), the tools and the flags: two structures of the same model name never share a
folder, so neither can remove the other's module.

Concurrency: a build of one key holds an exclusive ``fcntl.flock`` on its lock file
from the second cache check to the end of the install; other processes wanting the same
key wait, then find the finished build. A finished build is put in place by renaming
its temporary folder: a reader sees the whole entry or none. Temporary folders left by
killed processes (their pid is dead on this host, or they are older than a day) are
removed by the next build of that model.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import socket
import time
import uuid
from pathlib import Path

try:
    import fcntl
except ImportError:     # pragma: no cover - not POSIX: builds are not locked
    fcntl = None

from ..errors import HostError

TEMP_PREFIX = ".fccgen-tmp-"
STALE_SECONDS = 24 * 3600       # any temporary folder this old is abandoned
KEY_CHARS = 16


def model_dir(out_dir: Path, model_name: str) -> Path:
    """``<out_dir>/<model_name>``; the name must be an ASCII identifier (the model
    loader refuses any other), so that it can name nothing but one folder in out_dir."""
    from ..render.escape import c_identifier
    return Path(out_dir) / c_identifier(model_name)


def entry_dir(out_dir: Path, model_name: str, key: str) -> Path:
    """The folder of the build of (model_name, key)."""
    return model_dir(out_dir, model_name) / key[:KEY_CHARS]


def failed_dir(entry: Path) -> Path:
    return entry.with_name(f"{entry.name}.failed-build")


def _host() -> str:
    return socket.gethostname().replace("-", "_") or "host"


def make_dirs(path: Path, option: str = "--build-dir") -> None:
    """``mkdir -p`` that ends in a HostError saying what to do."""
    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise HostError.from_os_error(exc, "create the build folder", path, option) from None


@contextlib.contextmanager
def build_lock(entry: Path):
    """Hold the exclusive lock of one key's builds (blocks while another process
    builds it)."""
    lock = entry.with_name(f"{entry.name}.lock")
    make_dirs(lock.parent)
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        raise HostError.from_os_error(exc, "write in the build folder", lock.parent,
                                      "--build-dir", name_file=False) from None
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)            # closing releases the lock


def new_temp_dir(parent: Path) -> Path:
    """A fresh temporary folder in ``parent``, named so that a later build can tell
    whether its owner is still alive."""
    path = Path(parent) / f"{TEMP_PREFIX}{_host()}-{os.getpid()}-{uuid.uuid4().hex[:12]}"
    try:
        path.mkdir()
    except OSError as exc:
        raise HostError.from_os_error(exc, "write in the build folder", parent,
                                      "--build-dir", name_file=False) from None
    return path


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def is_stale(path: Path, now: float | None = None) -> bool:
    """Whether a temporary folder was abandoned: its owner (pid on this host) is gone,
    or it is older than STALE_SECONDS (owners on other hosts cannot be asked)."""
    name = path.name
    if not name.startswith(TEMP_PREFIX):
        return False
    host, _, rest = name[len(TEMP_PREFIX):].partition("-")
    pid_text = rest.partition("-")[0]
    try:
        age = (time.time() if now is None else now) - path.stat().st_mtime
    except OSError:
        return False
    if age > STALE_SECONDS:
        return True
    return host == _host() and pid_text.isdigit() and not _pid_alive(int(pid_text))


def clean_stale(parent: Path) -> list[Path]:
    """Remove abandoned temporary folders in ``parent`` (best effort); returns them."""
    removed = []
    try:
        candidates = [p for p in Path(parent).iterdir() if p.name.startswith(TEMP_PREFIX)]
    except OSError:
        return removed
    for path in candidates:
        if is_stale(path):
            shutil.rmtree(path, ignore_errors=True)
            if not path.exists():
                removed.append(path)
    return removed


def clean_legacy(out_dir: Path, model_name: str, now: float | None = None) -> None:
    """Remove temporary build folders of earlier fccgen versions
    (``<out_dir>/.<name>.build-<random>``, no owner recorded) once a day old."""
    now = time.time() if now is None else now
    try:
        for path in Path(out_dir).glob(f".{model_name}.build-*"):
            if now - path.stat().st_mtime > STALE_SECONDS:
                shutil.rmtree(path, ignore_errors=True)
    except OSError:
        pass


def put_in_place(tmp: Path, entry: Path) -> None:
    """Rename a finished build folder ``tmp`` to ``entry``, replacing what is there
    (moved aside first, then removed). Call with the key's lock held."""
    trash = None
    if entry.exists() or entry.is_symlink():
        trash = new_temp_dir(entry.parent)
        os.replace(entry, trash / "old")
    os.replace(tmp, entry)
    if trash is not None:
        shutil.rmtree(trash, ignore_errors=True)
