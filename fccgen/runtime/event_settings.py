"""The settings of a model's compiled events (engine/fcc_events.h, fcc_event_spec):
per event its direction, action, joint rows and restitution; the angle quantities'
rows; the event kernels' constants; and where the element kernels keep copies of the
angle references (torsion springs, loads of joint angles). One source for the Python
build's EventSet (fccgen.runtime.solver) and the export's data header
(fccgen.export.c_events)."""
from __future__ import annotations

from dataclasses import dataclass

# the Zeno guard's margin: more events in one step than MAX_PER_STEP beyond those the
# model's event functions can carry without a Zeno loop (max_per_step), the contact rests
MAX_PER_STEP = 50
# rows of a run's event log; the events past them are counted (EventSet.dropped)
LOG_ROWS = 100_000


# simulate(event_location=...): rk4's two ways of locating an event function's crossing
EVENT_LOCATIONS = ("steps", "interpolant")


def check_event_location(value, sensitivities=None) -> None:
    """Refuse an ``event_location`` that is not one of EVENT_LOCATIONS, and
    "interpolant" with sensitivities (their jump terms are taken at the state of the
    re-integrated partial steps)."""
    if not isinstance(value, str) or value not in EVENT_LOCATIONS:
        raise ValueError(f"event_location must be one of {', '.join(EVENT_LOCATIONS)}, "
                         f"not {value!r}")
    if value == "interpolant" and sensitivities is not None:
        raise ValueError("event_location='interpolant' does not carry sensitivities "
                         "through an event (they are located by re-integrated partial "
                         "steps): leave event_location at 'steps'")


def max_per_step(n_events: int) -> int:
    """The Zeno guard of a model with ``n_events`` event functions: the events one step
    may carry before the next bounce rests instead (engine/fcc_rk4.c).

    Without a Zeno loop each event function acts at most twice in one step (its
    crossing, and the release of a bounce that rested; a lock and its unlock are two
    functions), so 2 n_events is what a step can legitimately carry: a mast whose
    latches, one per bay, all cross in the same step by symmetry. A Zeno loop (a bounce
    whose flights shrink geometrically) never stops firing: it still meets the guard,
    after MAX_PER_STEP events more than that, a bounded number per step."""
    return MAX_PER_STEP + 2 * n_events


@dataclass(frozen=True)
class EventSettings:
    directions: list          # per event: "rising", "falling" or "either"
    actions: list             # per event: an fccgen.runtime._events.ACTIONS name
    rows: list                # per event: its joint's first quantity row, or -1
    rows2: list               # ... second row (cylindrical), or -1
    restitution: list
    angle_rows: list          # the quantity rows that are joint angles
    constants: list           # the event kernels' numbers after the angle references
    mirror_slots: list        # element parameter index of each copied reference (th)
    mirror_angles: list       # ... its angle (index among the angle quantities)
    input_columns: tuple = () # per input the events read: its index in the model's
    input_slots: tuple = ()   # inputs, and its place in the kernels' parameters


def event_settings(plan, module) -> EventSettings:
    """The settings of ``module`` (the model's event module) for ``plan``."""
    from ..events.constants import input_positions, values
    from ..events.references import reference_slots
    events = plan.model.events
    qty = list(module.QUANTITY_NAMES)

    def row(joint, kinds):
        for kind in kinds:
            if joint is not None and f"{joint}.{kind}" in qty:
                return qty.index(f"{joint}.{kind}")
        return -1
    rows = [row(e.joint, ("angle", "position")) for e in events]
    rows2 = [row(e.joint, ("position",)) if r >= 0 and qty[r].endswith(".angle")
             else -1 for e, r in zip(events, rows)]
    angle_rows = [k for k, name in enumerate(qty) if name.endswith(".angle")]
    names = [qty[k].split(".")[0] for k in angle_rows]
    slots = reference_slots(plan)
    inputs = list(getattr(plan.model, "inputs", {}))
    where = input_positions(plan, names)
    return EventSettings([e.direction for e in events], [e.action for e in events],
                         rows, rows2, [e.restitution for e in events], angle_rows,
                         [float(x) for x in values(plan, names)],
                         [slot for slot, _ in slots], [names.index(n) for _, n in slots],
                         tuple(inputs.index(n) for n in where),
                         tuple(3 * len(angle_rows) + k for k in where.values()))
