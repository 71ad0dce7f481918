"""Which integration methods cannot run a model, and why: one place that ``check``
reports, that ``simulate`` and ``sweep`` refuse up front (before anything is built or
run), with the same sentence.

- Events (``events:`` and joint ``limits:``) are located and applied by the compiled
  rk4 and dopri5 loops only (fccgen/runtime/_events.pyx, docs/events.md). The other
  methods have no event location: ali3p's trapezoidal step would need the events
  located on its own interpolant and the lock or bounce applied with its
  augmented-Lagrangian projections, baumgarte does not project, and the SciPy methods
  run SciPy's own loop.
"""
from __future__ import annotations

from .methods import EVENT_METHODS


def reason(model, method: str) -> str:
    """Why ``method`` cannot run ``model`` ("" when it can)."""
    if model.events and method not in EVENT_METHODS:
        names = ", ".join(e.name for e in model.events)
        why = ("its trapezoidal step has no event location yet, nor the lock and bounce "
               "projections" if method == "ali3p" else "only rk4 and dopri5 locate "
               "events")
        return (f"method {method} does not take models with events (this one has "
                f"{names}): {why}; use rk4 or dopri5 (docs/events.md)")
    return ""


def refuse(model, method: str | None) -> None:
    """ValueError naming the model file when ``method`` (None: the model's own)
    cannot run ``model``."""
    from ..errors import located_text
    method = model.simulate.method if method is None else method
    why = reason(model, method)
    if why:
        first = model.events[0]
        limit = first.joint is not None and first.name in (f"{first.joint}_lower",
                                                            f"{first.joint}_upper")
        item = f"joints.{first.joint}.limits" if limit else f"events.{first.name}"
        raise ValueError(located_text(model.source, first.where.line, item, why, method))


def check_notes(model, methods) -> list[str]:
    """What ``fccgen check`` says of the methods that cannot run ``model``: one note
    for the methods of ``methods`` refused for its events."""
    refused = [m for m in methods if reason(model, m)]
    if not refused:
        return []
    names = ", ".join(e.name for e in model.events)
    return [f"methods: only {' and '.join(EVENT_METHODS)} run this model, since it has "
            f"events ({names}); refused: {', '.join(refused)} (ali3p: its trapezoidal "
            "step has no event location yet, nor the lock and bounce projections; the "
            "others do not locate events; docs/events.md)"]
