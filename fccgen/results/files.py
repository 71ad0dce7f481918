"""The file formats of a result (docs/design.md §4), each keeping ``result.info``, the
metadata of :mod:`fccgen.results.provenance`:

The internal columns of a model with joints (the points and vectors fccgen made,
``result.internal``) go into a CSV only when asked (``all_columns``); the HDF5 file
keeps them in its group ``internal`` (at the root when asked).

- ``.csv``: the header is the column names, ``t`` first, then one row per output
  time (numbers in their exact shortest form, ``%.17g``): pandas.read_csv and
  numpy.loadtxt(skiprows=1) read it as it is. The metadata go to a JSON *sidecar*
  next to it, ``<stem>.meta.json`` (run.csv -> run.meta.json) holding ``info``, the
  column names, the row count and the sha256 of the CSV it describes; a sidecar that
  does not match its CSV (a CSV rewritten by another program) is ignored with a
  :class:`~fccgen.errors.ResultMetadataWarning`.
- ``.npz``: one array per column name, the internal ones included (their names as
  JSON in the entry ``__fccgen_internal__``), and ``info`` as JSON in the entry
  ``__fccgen_info__``.
- ``.h5`` / ``.hdf5`` (h5py): one dataset per column name at the root, in order,
  ``t`` a dimension scale that every other column is attached to (the netCDF-4
  layout, so ``xarray.open_dataset(path, engine="h5netcdf")`` reads it as one
  Dataset over ``t``); root attributes ``fccgen_columns`` (the names, JSON) and
  ``fccgen_info`` (``info``, JSON); when the run has events, a group ``events`` with
  one dataset per field of the events table, for other tools.

Every file is written into a temporary file of the same folder and renamed over the
target (:func:`atomic_write`), with the permissions the user's umask gives.
"""
from __future__ import annotations

import glob
import hashlib
import json
import os
import uuid
import warnings
from pathlib import Path

import numpy as np

from ..errors import HostError, ResultMetadataWarning

SUFFIXES = (".csv", ".npz", ".h5", ".hdf5")
HDF5 = (".h5", ".hdf5")
INFO_ENTRY = "__fccgen_info__"          # NPZ entry holding result.info as JSON
INTERNAL_ENTRY = "__fccgen_internal__"  # NPZ entry naming the internal columns (JSON)
INTERNAL_GROUP = "internal"             # HDF5 group of the internal columns
PARTIAL_LINE = "# fccgen: partial result"
SIDECAR = ".meta.json"


def check_suffix(path: Path) -> str:
    """The lower-case suffix of a result file name; ValueError when unsupported, and
    HostError for .h5 without h5py."""
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{path}: results are written as .csv, .npz or .h5 (got "
                         f"{suffix or 'no suffix'!r})")
    if suffix in HDF5:
        require_h5py()
    return suffix


def require_h5py():
    """The h5py module, or a HostError saying how to install it."""
    try:
        import h5py
    except ImportError:
        raise HostError("HDF5 results (.h5) need h5py, which is not installed. To fix "
                        "it, pip install 'fccgen[hdf5]' (or write .npz or .csv)") from None
    return h5py


def sidecar_path(path) -> Path:
    """Where the metadata of a CSV result go: run.csv -> run.meta.json."""
    path = Path(path)
    return path.with_name(f"{path.stem}{SIDECAR}")


# -- writing ---------------------------------------------------------------------------

def temp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:12]}.tmp")


def clean_stale_temps(path: Path) -> None:
    """Remove temporary files of earlier saves to ``path`` whose process is gone."""
    for tmp in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):
        pid = tmp.name[len(path.name) + 2:].partition(".")[0]
        if pid.isdigit() and int(pid) != os.getpid():
            try:
                os.kill(int(pid), 0)
            except ProcessLookupError:
                tmp.unlink(missing_ok=True)
            except (PermissionError, OverflowError):
                pass


def atomic_write(path: Path, write_to, before_replace=None) -> None:
    """``write_to(tmp)`` fills a new temporary file of ``path``'s folder (created with
    mode 0o666 less the umask), which is then synced and renamed over ``path``;
    ``before_replace(tmp)`` runs just before the rename. Nothing is left on failure."""
    clean_stale_temps(path)
    tmp = temp_name(path)
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))   # umask applies
    try:
        write_to(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        if before_replace is not None:
            before_replace(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def json_value(value):
    """A JSON-able form of an info value (NumPy numbers and arrays included)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def info_json(info: dict) -> str:
    return json.dumps(info, default=json_value, sort_keys=True)


def write(result, path: Path, suffix: str, all_columns: bool = False) -> None:
    """Write ``result`` to ``path`` in the format of ``suffix`` (atomically); the
    internal columns as :meth:`fccgen.results.result.Result.save` says."""
    if suffix == ".csv":
        _write_csv(result, path, all_columns)
    elif suffix == ".npz":
        atomic_write(path, lambda tmp: _write_npz(result, tmp))
    else:
        atomic_write(path, lambda tmp: _write_h5(result, tmp, all_columns))


def _write_csv(result, path: Path, all_columns: bool) -> None:
    """The CSV, then its sidecar (renamed in place just before the CSV is)."""
    names = result.all_names() if all_columns else result.names

    def write_table(tmp):
        with open(tmp, "wb") as f:
            np.savetxt(f, result.table(all_columns), delimiter=",",
                       header=",".join(names), comments="", fmt="%.17g")
            if result.partial:
                f.write(f"{PARTIAL_LINE}: {result.info.get('stopped_by', 'unfinished')}\n"
                        .encode("utf-8"))

    meta = {"fccgen_result": 1, "rows": len(result.t), "columns": names}
    if all_columns and result.internal:
        meta["internal_columns"] = list(result.internal)
    write_csv_with_sidecar(path, write_table, meta, result.info)


def write_csv_with_sidecar(path: Path, write_table, meta: dict, info: dict) -> None:
    """``write_table(tmp)`` writes a CSV, then its sidecar ``<stem>.meta.json`` holds
    ``meta``, the file's name and sha256, and ``info`` (how it was made); both written
    atomically, the sidecar renamed in place just before the CSV is."""
    def write_sidecar(tmp_csv):
        full = {**meta, "file": path.name, "sha256": _sha256(tmp_csv),
                "info": json.loads(info_json(info))}
        text = json.dumps(full, indent=1, sort_keys=True) + "\n"
        atomic_write(sidecar_path(path), lambda tmp: tmp.write_text(text, "utf-8"))
    atomic_write(path, write_table, write_sidecar)


def _write_npz(result, tmp: Path) -> None:
    internal = {INTERNAL_ENTRY: np.array(json.dumps(list(result.internal)))} \
        if result.internal else {}
    with open(tmp, "wb") as f:
        np.savez(f, **{n: result[n] for n in result.all_names()},
                 **{INFO_ENTRY: np.array(info_json(result.info))}, **internal)


def _write_h5(result, tmp: Path, all_columns: bool) -> None:
    h5py = require_h5py()
    names = result.all_names() if all_columns else result.names
    with h5py.File(tmp, "w", track_order=True) as f:
        f.attrs["fccgen_columns"] = json.dumps(names)
        f.attrs["fccgen_info"] = info_json(result.info)
        if result.internal:
            f.attrs["fccgen_internal"] = json.dumps(list(result.internal))
        for name in names:
            f.create_dataset(name, data=np.asarray(result[name]))
        f["t"].make_scale("t")          # every column is a function of t (netCDF-4 form)
        for name in names[1:]:
            f[name].dims[0].attach_scale(f["t"])
        if result.internal and not all_columns:
            group = f.create_group(INTERNAL_GROUP, track_order=True)
            for name, values in result.internal.items():
                group.create_dataset(name, data=np.asarray(values))
                group[name].dims[0].attach_scale(f["t"])
        events = result.info.get("events")
        if isinstance(events, list) and events and all(isinstance(e, dict) for e in events):
            group = f.create_group("events", track_order=True)
            for key in dict.fromkeys(k for e in events for k in e):
                values = [e.get(key) for e in events]
                if all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       for v in values):
                    group.create_dataset(key, data=np.array(values, dtype=float))
                else:
                    group.create_dataset(key, data=[str(v) for v in values],
                                         dtype=h5py.string_dtype())


def _sha256(path: Path) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


# -- reading ---------------------------------------------------------------------------

def read(path: Path, suffix: str) -> tuple[dict, dict, list]:
    """(arrays by name, ``t`` and the internal columns included; info; the names of
    the internal columns) of a result file."""
    if suffix == ".npz":
        with np.load(path) as data:
            arrays = {n: data[n] for n in data.files}
        info = json.loads(str(arrays.pop(INFO_ENTRY))) if INFO_ENTRY in arrays else {}
        hidden = (json.loads(str(arrays.pop(INTERNAL_ENTRY))) if INTERNAL_ENTRY in arrays
                  else [])
        return arrays, info, hidden
    if suffix == ".csv":
        return _read_csv(path)
    return _read_h5(path)


def _read_csv(path: Path) -> tuple[dict, dict, list]:
    """(arrays by name, info) of a CSV result and its sidecar; refuses a file whose
    last line is cut."""
    with open(path, "rb") as fh:
        data = fh.read()
    if data and not data.endswith(b"\n"):
        raise ValueError(f"{path}: incomplete result file (its last line is cut)")
    lines = data.decode("utf-8").splitlines()
    info, hidden = _read_sidecar(path, hashlib.sha256(data).hexdigest())
    if lines and lines[-1].startswith(PARTIAL_LINE):
        info.update(partial=True,
                    stopped_by=lines[-1][len(PARTIAL_LINE):].lstrip(": ").strip())
    names = lines[0].strip().split(",") if lines else []
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, comments="#")
    if table.shape[1] != len(names):
        raise ValueError(f"{path}: {len(names)} column names but {table.shape[1]} columns")
    return {n: table[:, k] for k, n in enumerate(names)}, info, hidden


def _read_sidecar(path: Path, sha256: str) -> tuple[dict, list]:
    """The info of a CSV's sidecar and the names of its internal columns; ({}, [])
    when there is none or it describes another file."""
    meta_path = sidecar_path(path)
    try:
        meta = json.loads(meta_path.read_text("utf-8"))
    except FileNotFoundError:
        return {}, []
    except (OSError, ValueError) as exc:
        warnings.warn(ResultMetadataWarning(
            f"{meta_path}: unreadable metadata of {path.name} ({exc}); loaded without "
            "them"), stacklevel=4)
        return {}, []
    if not isinstance(meta, dict) or meta.get("sha256") != sha256:
        warnings.warn(ResultMetadataWarning(
            f"{meta_path} describes another version of {path.name} (the CSV was changed "
            "after it was written); loaded without its metadata"), stacklevel=4)
        return {}, []
    return dict(meta.get("info") or {}), list(meta.get("internal_columns") or [])


def _read_h5(path: Path) -> tuple[dict, dict, list]:
    h5py = require_h5py()
    with h5py.File(path, "r") as f:
        if "fccgen_columns" not in f.attrs:
            raise ValueError(f"{path}: not a result file written by fccgen (its root has "
                             "no fccgen_columns attribute)")
        names = json.loads(f.attrs["fccgen_columns"])
        arrays = {n: np.asarray(f[n][()]) for n in names}
        hidden = json.loads(f.attrs.get("fccgen_internal", "[]"))
        group = f.get(INTERNAL_GROUP)
        if isinstance(group, h5py.Group):
            arrays.update({n: np.asarray(group[n][()]) for n in hidden if n in group})
        info = json.loads(f.attrs.get("fccgen_info", "{}"))
    return arrays, info, hidden


def mode_shape_path(path, k: int) -> Path:
    """The file of mode k (1-based) among the shapes written for ``path``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.mode{int(k)}{path.suffix}")


def mode_file(result, mode: int) -> Path:
    """The file of mode ``mode`` among the shapes that ``fccgen modes --shapes
    RESULT`` wrote (RESULT.mode<k><suffix>); ValueError naming the ones there are."""
    if result is None or not isinstance(result, (str, Path)):
        raise ValueError("--mode needs --result NAME, the name given to fccgen modes "
                         "--shapes (e.g. --result modes.npz --mode 1)")
    if int(mode) < 1:
        raise ValueError(f"--mode counts from 1 (got {mode})")
    path = mode_shape_path(result, mode)
    if path.exists():
        return path
    base = Path(result)
    found = sorted(base.parent.glob(f"{base.stem}.mode*{base.suffix}"),
                   key=lambda p: (len(p.name), p.name))
    if not found:
        raise ValueError(f"no mode shapes named {base.stem}.mode<k>{base.suffix} in "
                         f"{base.parent}: write them first with fccgen modes MODEL "
                         f"--shapes {base}")
    raise ValueError(f"{path} does not exist; the shapes written as {base} are "
                     + ", ".join(p.name for p in found))
