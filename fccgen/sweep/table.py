"""The table of a sweep and its files (docs/sweeps.md).

Rows are written as they finish: each finished run is appended (flushed to the disk)
to the *partial file* beside the table, ``<stem>.partial.csv`` (sweep.csv ->
sweep.partial.csv, sweep.parquet -> sweep.partial.csv), in the order the runs end,
with the column ``run`` giving each row its place in the sweep. When every run has
ended, the table is written in the sweep's order into a temporary file of the same
folder and renamed over ``--out`` (with its metadata), and then the partial file is
removed. A sweep that stops early (Ctrl-C, a lost scheduler, a killed process) leaves
the partial file: a complete CSV of the rows that finished, readable as it is, which
``--resume`` (:func:`read_partial`) takes up again.

Provenance: a CSV table has a JSON sidecar ``<stem>.meta.json`` (as result files do,
:mod:`fccgen.results.files`) holding :attr:`SweepTable.info`: the fccgen version, when
the sweep ended, the model (name, file, hash of its written numbers, structure hash),
the method and its settings, the solver's tolerances, the swept values, the outputs
asked for, the run time limit and where it ran; a Parquet table holds the same JSON in
its schema metadata (key ``fccgen_info``). Each row carries ``model_hash``, the hash
of the numbers that run used (:func:`fccgen.results.provenance.model_hash`).
"""
from __future__ import annotations

import csv
import errno
import io
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import HostError
from ..results.files import atomic_write, info_json, sidecar_path, temp_name

SUFFIXES = (".csv", ".parquet")


def partial_path(path) -> Path:
    """Where the rows of a sweep meant for ``path`` go while it runs."""
    path = Path(path)
    return path.with_name(f"{path.stem}.partial.csv")


def check_table_path(path, option: str = "--out", resume: bool = False) -> Path:
    """Check, before anything is built or run, that the table can be written at
    ``path``: a .csv or .parquet name (pyarrow installed for .parquet), not a folder,
    in a folder that exists (created if missing) and takes new files, and, unless
    ``resume``, no partial file of an earlier sweep that stopped (its rows would be
    lost). ValueError for a bad name, HostError for a place that cannot be written."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ValueError(f"{path}: a sweep table is written as .csv or .parquet (got "
                         f"{path.suffix or 'no suffix'!r})")
    if path.suffix.lower() == ".parquet":
        _pyarrow()                        # missing: say so before any run
    if path.is_dir():
        raise ValueError(f"{path} is a folder; give a file name, e.g. {path / 'sweep.csv'}")
    partial = partial_path(path)
    if partial.exists() and not resume:
        raise HostError(f"{partial} holds the rows of an earlier sweep that stopped before "
                        f"its end. To fix it, run the same sweep with --resume (its rows "
                        f"are kept and only the other runs run), or move the file "
                        f"elsewhere or delete it", errno=errno.EEXIST)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        probe = temp_name(path)
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        probe.unlink()
    except OSError as exc:
        raise HostError.from_os_error(exc, "write the sweep table in", path.parent, option,
                                      name_file=False) from None
    return path


@dataclass
class SweepTable:
    """The rows of a sweep, in the order of :func:`fccgen.sweep.combinations`;
    ``info``: its provenance (module docstring)."""
    keys: list[str]
    rows: list[dict]
    wall_time: float
    where: str                              # the cluster that ran it
    columns: list[str] = field(default_factory=list)
    info: dict = field(default_factory=dict)

    @property
    def failed(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)

    @property
    def timed_out(self) -> int:
        """Rows of runs stopped by the time limit (counted in :attr:`failed` too)."""
        return sum(r["status"] == "timeout" for r in self.rows)

    def save(self, path) -> Path:
        """Write the table as CSV (header first, numbers in their shortest exact form,
        the metadata in ``<stem>.meta.json``) or Parquet (``.parquet``: one typed column
        per name, through pyarrow, the optional extra ``parquet``; the metadata in the
        schema), atomically."""
        path = Path(path)
        if path.suffix.lower() not in SUFFIXES:
            raise ValueError(f"{path}: a sweep table is written as .csv or .parquet")
        path.parent.mkdir(parents=True, exist_ok=True)
        info = dict(self.info, rows=len(self.rows), failed=self.failed,
                    wall_time=self.wall_time, where=self.where)
        if path.suffix.lower() == ".parquet":
            atomic_write(path, lambda tmp: _write_parquet(tmp, self.columns, self.rows,
                                                          info))
            return path

        def write_table(tmp):
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh)
                w.writerow(self.columns)
                for row in self.rows:
                    w.writerow([_cell(row.get(c)) for c in self.columns])

        def write_sidecar(tmp_csv):
            meta = {"fccgen_sweep": 1, "file": path.name, "columns": self.columns,
                    "info": json.loads(info_json(info))}
            text = json.dumps(meta, indent=1, sort_keys=True) + "\n"
            atomic_write(sidecar_path(path), lambda tmp: tmp.write_text(text, "utf-8"))
        atomic_write(path, write_table, write_sidecar)
        return path


TEXT_COLUMNS = ("status", "error", "model_hash")


def read_partial(path: Path, columns: list[str]) -> dict[int, dict]:
    """The rows of a partial file written by a sweep with these ``columns``, by their
    run number (the last row of a run counts); ValueError when its columns differ. A
    last line cut by a killed process (no line end) is removed from the file: its run
    runs again."""
    data = Path(path).read_bytes()
    whole = data[:data.rfind(b"\n") + 1]
    if len(whole) != len(data):
        with open(path, "r+b") as fh:
            fh.truncate(len(whole))
    reader = csv.reader(io.StringIO(whole.decode("utf-8"), newline=""))
    header = next(reader, [])
    if header != columns:
        raise ValueError(f"{path} was written by a sweep with other columns "
                         f"({', '.join(header)}), not this one's ({', '.join(columns)}): "
                         f"move it elsewhere or delete it")
    rows = {}
    for cells in reader:
        row = {c: _parse(c, x) for c, x in zip(columns, cells) if x != ""}
        rows[int(row["run"])] = row
    return rows


def _parse(column: str, text: str):
    if column in TEXT_COLUMNS:
        return text
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


class PartialWriter:
    """Appends each finished row to the partial file (module docstring), flushed and
    synced, so that a sweep that stops keeps every row that finished; ``append``:
    go on with the file of a stopped sweep (its header is there)."""

    def __init__(self, path: Path, columns: list[str], append: bool = False):
        self.path = Path(path)
        self.columns = columns
        self.count = 0
        self._fh = open(self.path, "a" if append else "x", newline="", encoding="utf-8")
        self._csv = csv.writer(self._fh)
        if not append:
            self._write(columns)

    def _write(self, cells) -> None:
        self._csv.writerow(cells)
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def add(self, row: dict) -> None:
        self._write([_cell(row.get(c)) for c in self.columns])
        self.count += 1

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()

    def remove(self) -> None:
        self.close()
        self.path.unlink(missing_ok=True)


def _pyarrow():
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise ValueError("a .parquet sweep table needs pyarrow: pip install "
                         "'fccgen[parquet]' (or write .csv)") from None
    return pyarrow


def _write_parquet(path: Path, columns: list[str], rows: list[dict], info: dict) -> None:
    pa = _pyarrow()
    data = {}
    for c in columns:
        values = [row.get(c) for row in rows]
        if any(isinstance(x, float) for x in values) and all(
                x is None or isinstance(x, (int, float)) for x in values):
            values = [None if x is None else float(x) for x in values]   # one type
        data[c] = values
    table = pa.Table.from_pydict(data)
    table = table.replace_schema_metadata({b"fccgen_info": info_json(info).encode("utf-8")})
    pa.parquet.write_table(table, str(path))


def _cell(value) -> str:
    if value is None:
        return ""
    return repr(value) if isinstance(value, float) else str(value)   # floats round-trip
