"""The event table of a run: one row per event that happened, as plain dicts (JSON-able,
so that every result file format carries it), and its text summary for the CLI."""
from __future__ import annotations

import numpy as np

# Columns of result.events (DESIGN section 4): time, event name, action, impulse (the
# multiplier of the impact: along ds/dq for a bounce, the norm over the locked rows for
# a lock), kinetic energy before and after, max |g| (and locked rows) after, the
# degrees of freedom after, and the event function's rate just before (bounces).
COLUMNS = ("t", "name", "action", "impulse", "kinetic_energy_before",
           "kinetic_energy_after", "constraint_error", "dof", "speed_before")


def event_rows(names, actions, log: np.ndarray) -> list[dict]:
    """Rows of the event table from the runtime's log ((n, 9): t, event index, action
    code, impulse, ke before, ke after, constraint error, dof, speed before)."""
    rows = []
    for rec in log:
        rows.append({"t": float(rec[0]), "name": names[int(rec[1])],
                     "action": actions[int(rec[2])], "impulse": float(rec[3]),
                     "kinetic_energy_before": float(rec[4]),
                     "kinetic_energy_after": float(rec[5]),
                     "constraint_error": float(rec[6]), "dof": int(rec[7]),
                     "speed_before": float(rec[8])})
    return rows


def energy_balance(t, energy, rows: list[dict]) -> tuple[float, float]:
    """(energy drift, event energy loss) of a run with events. An impact changes the
    kinetic energy only (the positions do not jump), by ke_after - ke_before; adding
    the losses of the events up to each output time back to E(t) leaves the
    integration's own drift: max_i |E(t_i) + sum_{t_e <= t_i} (ke_before - ke_after)
    - E(t_0)|. Without this, a latch's energy loss would read as drift."""
    t = np.asarray(t, float)
    e = np.asarray(energy, float)
    lost = np.zeros_like(e)
    for r in rows:
        lost[t >= r["t"]] += r["kinetic_energy_before"] - r["kinetic_energy_after"]
    drift = float(np.max(np.abs(e + lost - e[0]))) if e.size else 0.0
    return drift, float(lost[-1]) if e.size else 0.0


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
