"""What ``fccgen sensitivity MODEL --params KEY,KEY [--out S.csv]`` prints about the
run of :func:`fccgen.api.sensitivity`: the run, the largest derivative for each
parameter, and where the results went."""
from __future__ import annotations

import numpy as np


def summary(result, out=None) -> str:
    """The lines the command prints for ``result`` (written to ``out`` if given)."""
    keys = result.info["sensitivities"]
    control = (" (in the error control)" if result.info.get("sensitivity_error_control")
               else "")
    lines = [f"{result.info.get('method', 'rk4')}: {result.info.get('steps')} steps to "
             f"t = {result.t[-1]:.6g} with the sensitivities to {', '.join(keys)}{control} "
             f"in {result.info.get('wall_time', 0.0):.3g} s"]
    for key in keys:
        cols = [c for c in result.names if not c.startswith("d(")
                and f"d({c})/d({key})" in result.columns]
        best = max(cols, key=lambda c: np.max(np.abs(result.sensitivity(c, key))))
        s = result.sensitivity(best, key)
        lines.append(f"  d/d({key}): largest in d({best})/d({key}) = "
                     f"{s[np.argmax(np.abs(s))]:.6g}, at t_end {s[-1]:.6g}")
    for event in getattr(result, "events", None) or []:
        lines.append(f"  event {event['name']} ({event['action']}) at t = {event['t']:.9g}: "
                     + ", ".join(f"d(time)/d({key}) = {event[f'd(time)/d({key})']:.6g}"
                                 for key in keys if f"d(time)/d({key})" in event))
    if out:
        n = sum(1 for c in result.columns if c.startswith("d(") and c not in result.hidden)
        lines.append(f"results: {out} ({len(result.t)} rows, {n} columns "
                     "d(<column>)/d(<param>))")
        if getattr(result, "events", None):
            lines.append("the events with their d(time)/d(<param>): info[\"events\"] of "
                         "the file's metadata (a CSV's <stem>.meta.json)")
    else:
        lines.append("no --out given: results not written")
    return "\n".join(lines)
