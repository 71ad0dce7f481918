"""What a sweep table carries beyond its summary figures: ``--outputs`` (docs/sweeps.md).

The grammar is a comma-separated list of ``NAME:STATISTIC`` items; the statistic says
what NAME is::

    COLUMN:final    the column's last value          COLUMN:initial  its first value
    COLUMN:max      its largest value                COLUMN:min      its smallest value
    COLUMN:absmax   its largest magnitude            COLUMN:tmax     the time of its max
    COLUMN:tmin     the time of its min
    EVENT:time      when the event first happened    EVENT:count     how often it did
    EVENT:last      when it last happened
    run:STAT        a number of the run's statistics (result.info): steps,
                    rhs_evaluations, newton_iterations, energy_drift, wall_time, ...

e.g. ``--outputs motor.torque:max,latch:time,P.x:final,run:newton_iterations``. COLUMN
is a result column of the model (``fccgen simulate`` lists them in its result), EVENT
the name of one of its events. Each item becomes a table column of the same name
(``motor.torque:max``). The statistics are over the recorded rows (every output_dt and
the end), as the result file holds them; an event that never happens gives an empty
time and a count of 0; a failed run gives empty cells.

:func:`parse_outputs` checks the form before anything is built; :func:`check_outputs`
checks the names against the columns, events and statistics of a short run of the
model before the sweep's runs; :func:`evaluate` gives one run's values.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

COLUMN_STATS = ("final", "initial", "max", "min", "absmax", "tmax", "tmin")
EVENT_STATS = ("time", "count", "last")
RUN = "run"
FORM = ("NAME:STATISTIC, e.g. motor.torque:max, latch:time, P.x:final or "
        "run:newton_iterations")


@dataclass(frozen=True)
class Output:
    """One item of ``--outputs``: ``kind`` is "column", "event" or "run"."""
    name: str
    stat: str
    kind: str

    @property
    def label(self) -> str:
        """The table column it fills."""
        return f"{self.name}:{self.stat}"


def _bad(item: str, why: str) -> ValueError:
    return ValueError(f"--outputs item {item!r}: {why}")


def parse_outputs(text) -> list[Output]:
    """``"motor.torque:max,latch:time"`` (or a list of such items) -> [Output, ...];
    ValueError naming the item and the rule it breaks."""
    if text is None:
        return []
    items = text.split(",") if isinstance(text, str) else list(text)
    outputs: list[Output] = []
    for raw in items:
        item = str(raw).strip()
        name, sep, stat = item.rpartition(":")
        name, stat = name.strip(), stat.strip()
        if not sep or not name or not stat:
            raise _bad(item, f"expected {FORM}")
        if name == RUN:
            kind = "run"
        elif stat in COLUMN_STATS:
            kind = "column"
        elif stat in EVENT_STATS:
            kind = "event"
        else:
            raise _bad(item, f"unknown statistic {stat!r}; a column takes "
                       f"{', '.join(COLUMN_STATS)}; an event takes {', '.join(EVENT_STATS)};"
                       " a run statistic is written run:NAME (e.g. run:steps)")
        out = Output(name, stat, kind)
        if out in outputs:
            raise _bad(item, "is given twice")
        outputs.append(out)
    if isinstance(text, str) and not outputs:
        raise ValueError(f"--outputs is empty; expected {FORM}")
    return outputs


def run_statistics(info: dict) -> list[str]:
    """The names of ``result.info``'s numbers, what ``run:NAME`` may ask for."""
    return [k for k, v in info.items()
            if isinstance(v, (int, float, np.number)) and not isinstance(v, bool)]


def _near(name: str, choices) -> str:
    import difflib
    close = difflib.get_close_matches(name, list(choices), n=3)
    return f" (did you mean {', '.join(close)}?)" if close else ""


def check_outputs(outputs: list[Output], columns, events, info: dict, source) -> None:
    """ValueError naming the model file, the item and the names it may use, for an
    item whose column, event or statistic the model does not have. ``columns``: the
    result's column names; ``events``: the model's event names; ``info``: a run's
    result.info."""
    columns = list(columns)
    stats = run_statistics(info)
    for out in outputs:
        if out.kind == "column" and out.name not in columns:
            raise ValueError(f"{source}: --outputs item {out.label!r}: the model has no "
                             f"result column {out.name!r}{_near(out.name, columns)}; its "
                             f"columns: {', '.join(columns)}")
        if out.kind == "event" and out.name not in events:
            raise ValueError(f"{source}: --outputs item {out.label!r}: the model has no "
                             f"event {out.name!r}{_near(out.name, events)}; its events: "
                             f"{', '.join(events) or 'none'}")
        if out.kind == "run" and out.stat not in stats:
            raise ValueError(f"{source}: --outputs item {out.label!r}: a run has no "
                             f"statistic {out.stat!r}{_near(out.stat, stats)}; its "
                             f"statistics: {', '.join(stats)}")


def evaluate(outputs: list[Output], result) -> dict:
    """{label: value} of one finished run (a :class:`~fccgen.results.result.Result`)."""
    values = {}
    for out in outputs:
        if out.kind == "run":
            value = result.info.get(out.stat)
            values[out.label] = None if value is None else _number(value)
        elif out.kind == "event":
            times = [float(e["t"]) for e in result.events if e["name"] == out.name]
            if out.stat == "count":
                values[out.label] = len(times)
            else:
                values[out.label] = (times[0] if out.stat == "time" else times[-1]) \
                    if times else None
        else:
            values[out.label] = _column_stat(result.t, result[out.name], out.stat)
    return values


def _column_stat(t, x, stat: str):
    x = np.asarray(x, dtype=float)
    if stat == "final":
        return float(x[-1])
    if stat == "initial":
        return float(x[0])
    if stat == "max":
        return float(np.max(x))
    if stat == "min":
        return float(np.min(x))
    if stat == "absmax":
        return float(np.max(np.abs(x)))
    if np.isnan(x).any():     # a value the run could not give: when is unknown too
        return float("nan")   # (argmax would name the first NaN's time)
    k = int(np.argmax(x) if stat == "tmax" else np.argmin(x))
    return float(t[k])


def _number(value):
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    return float(value)
