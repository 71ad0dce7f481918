"""The event table of a run: one row per event that happened, as plain dicts (JSON-able,
so that every result file format carries it), and its text summary for the CLI."""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import RunWarning
from ..rank import AMBIGUOUS_LOW, GROW_TOL

# Columns of result.events (docs/design.md §4): time, event name, action, impulse (the
# multiplier of the impact: along ds/dq for a bounce, the norm over the locked rows for
# a lock), kinetic energy before and after, max |g| (and locked rows) after, the
# degrees of freedom after, and the event function's rate just before (bounces).
COLUMNS = ("t", "name", "action", "impulse", "kinetic_energy_before",
           "kinetic_energy_after", "constraint_error", "dof", "speed_before")


def event_rows(names, actions, log: np.ndarray) -> list[dict]:
    """Rows of the event table from the runtime's log ((n, 9) or more: t, event index,
    action code, impulse, ke before, ke after, constraint error, dof, speed before)."""
    rows = []
    for rec in log:
        rows.append({"t": float(rec[0]), "name": names[int(rec[1])],
                     "action": actions[int(rec[2])], "impulse": float(rec[3]),
                     "kinetic_energy_before": float(rec[4]),
                     "kinetic_energy_after": float(rec[5]),
                     "constraint_error": float(rec[6]), "dof": int(rec[7]),
                     "speed_before": float(rec[8])})
    return rows


def energy_losses(t, rows: list[dict]) -> np.ndarray:
    """Per output time t_i, the kinetic energy the events up to it took:
    sum_{t_e <= t_i} (ke_before - ke_after). An impact changes the kinetic energy only
    (the positions do not jump), so E(t_i) plus this is what the integration alone
    would have kept."""
    t = np.asarray(t, float)
    lost = np.zeros_like(t)
    for r in rows:
        lost[t >= r["t"]] += r["kinetic_energy_before"] - r["kinetic_energy_after"]
    return lost


def energy_balance(t, energy, rows: list[dict]) -> tuple[float, float]:
    """(energy drift, event energy loss) of a run with events: the drift is
    max_i |E(t_i) + energy_losses(t_i) - E(t_0)|, the integration's own; without
    adding the losses back, a latch's energy loss would read as drift."""
    e = np.asarray(energy, float)
    if not e.size:
        return 0.0, 0.0
    lost = energy_losses(t, rows)
    return float(np.max(np.abs(e + lost - e[0]))), float(lost[-1])


def switch_warnings(rows: list[dict], log: np.ndarray, notes: dict) -> list[str]:
    """Texts of the runtime's notes on switches (log columns 9, 10: NOTE_ bits and
    the smallest relative singular value in the uncertain band): a lock whose rows
    add no constraint on the motion, a rank after a switch that is uncertain."""
    texts = []
    for row, rec in zip(rows, log):
        bits = int(rec[9]) if len(rec) > 9 else 0
        where = f"event {row['name']!r} ({row['action']}) at t = {row['t']:.12g}"
        if bits & notes["redundant"]:
            texts.append(
                f"{where}: the locked joint's rows follow from the constraints and the "
                f"rows already locked (it was rigid already): the lock adds no "
                f"constraint, the degrees of freedom stay {row['dof']}")
        if bits & notes["uncertain"]:
            texts.append(
                f"{where}: the degrees of freedom after the switch are uncertain: a "
                f"relative singular value {float(rec[10]):.2g} of the constraint Jacobian "
                f"with the locked rows lies between {AMBIGUOUS_LOW:g} and {GROW_TOL:g} "
                f"(near a singular position); the run counts {row['dof']}")
    return texts


def report_switches(result, log: np.ndarray, notes: dict) -> None:
    """Add :func:`switch_warnings` to ``result.info["warnings"]`` and issue each as a
    :class:`~fccgen.errors.RunWarning`."""
    texts = switch_warnings(result.events, log, notes)
    result.info.setdefault("warnings", []).extend(texts)
    for text in texts:
        warnings.warn(text, RunWarning, stacklevel=3)


def report_dropped_events(result, kept: int, dropped: int) -> None:
    """Say that the event log kept only its first ``kept`` rows (the run itself went on
    through every event): ``result.info["events_dropped"]`` and a RunWarning."""
    result.info["events_dropped"] = int(dropped)
    last = result.events[-1]["t"] if result.events else 0.0
    text = (f"{dropped} events after the first {kept} are not in result.events (the "
            f"log keeps {kept} rows); the run went through all {kept + dropped}: its "
            f"columns are complete, but events after t = {last:.9g} s are not listed, "
            f"and the energy check covers the run up to then")
    result.info.setdefault("warnings", []).append(text)
    warnings.warn(text, RunWarning, stacklevel=3)


def final_dof(info: dict, rows: list[dict]) -> int:
    """The degrees of freedom at the end of a run with events. The rank findings
    (info["final_dof"], info["dof_changes"]) count the constraint Jacobian's rank only;
    the last switch's row counts the locked rows too (docs/events.md). Its DOF, moved
    by the rank changes found after it, is the DOF at the end."""
    if not rows:
        return info["final_dof"]
    last = rows[-1]
    base = info["dof"]
    for change in info.get("dof_changes", ()):
        if change["t"] <= last["t"]:
            base = change["dof_after"]
    return last["dof"] + info["final_dof"] - base


def summary(rows: list[dict], limit: int = 20) -> str:
    """A few lines for the CLI: how many events, then the first ``limit`` of them."""
    if not rows:
        return "events: none happened"
    lines = [f"events: {len(rows)} (t, name, action, impulse, kinetic energy before -> "
             "after, constraint error, dof)"]
    for r in rows[:limit]:
        lines.append(f"  t = {r['t']:.12g}  {r['name']}  {r['action']}  "
                     f"impulse {r['impulse']:.6g}  KE {r['kinetic_energy_before']:.6g} -> "
                     f"{r['kinetic_energy_after']:.6g}  |g| {r['constraint_error']:.3g}  "
                     f"dof {r['dof']}")
    if len(rows) > limit:
        lines.append(f"  ... and {len(rows) - limit} more (result.events)")
    return "\n".join(lines)
