"""Short text (and HTML) summaries of solvers and results, for ``repr`` in a terminal
or a notebook.

A solver reads ``<CompiledSolver four_bar: 6 coordinates, 6 constraint equations,
DOF 1 (decided), method rk4, linear solver dense, build generated/four_bar/...>``;
DOF = n_q - rank(B) once a run (or :meth:`decide_rank`) has decided the rank, else
"undecided". A result reads ``<Result: 501 rows, t 0 .. 5, 32 columns (x_1, ...),
method rk4, 2 events>`` (and ``partial`` when the run stopped early).
"""
from __future__ import annotations

import html

SHOWN_COLUMNS = 4          # column names a result's repr lists before "..."


def solver_repr(solver, rank: int, path: str, build: str | None) -> str:
    """One line naming what the solver holds; rank < 0: not decided yet."""
    plan = solver.plan
    dof = (f"DOF {plan.n_q - rank} (decided)" if rank >= 0 else "DOF undecided")
    parts = [f"{plan.n_q} coordinates", f"{plan.n_g} constraint equations", dof,
             f"method {plan.model.simulate.method}",
             f"linear solver {solver.linear_solver} -> {path}"]
    if build is not None:
        parts.append(f"build {build}")
    return f"<{type(solver).__name__} {plan.model.name}: " + ", ".join(parts) + ">"


def result_fields(result) -> list[tuple[str, str]]:
    """(label, value) pairs of a result's summary, in display order."""
    t = result.t
    names = result.names[1:]          # the user's columns, not result.internal
    shown = ", ".join(names[:SHOWN_COLUMNS]) + (", ..." if len(names) > SHOWN_COLUMNS
                                                 else "")
    fields = [("rows", str(len(t))),
              ("t", f"{t[0]:g} .. {t[-1]:g}" if len(t) else "empty"),
              ("columns", f"{len(names)} ({shown})" if names else "0"),
              ("method", str(result.info.get("method", "?"))),
              ("events", str(len(result.events)))]
    if result.partial:
        fields.append(("partial", "yes: the run stopped before its end"))
    return fields


def result_repr(result) -> str:
    f = dict(result_fields(result))
    count, _, shown = f["columns"].partition(" ")
    text = (f"<Result: {f['rows']} rows, t {f['t']}, {count} columns"
            + (f" {shown}" if shown else "")
            + f", method {f['method']}, {f['events']} events")
    return text + (", partial>" if result.partial else ">")


def result_html(result) -> str:
    """The summary as a small two-column HTML table (escaped)."""
    rows = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                   f"<td style='text-align:left'>{html.escape(v)}</td></tr>"
                   for k, v in result_fields(result))
    return f"<table><caption>fccgen Result</caption>{rows}</table>"
