"""The event outputs of the FMU (docs/export.md, "The event log"): for a model with
events, how many happened so far in the run and the latest one's row of the event log
(the keys of ``result.events``), as discrete FMI 2.0 outputs read at each
communication point.

An event's name and action are Enumeration outputs: their types (``EventName`` with the
model's events in the order of ``NAME_event_name``, ``EventAction`` with the engine's
actions) are declared in modelDescription.xml, each with the item ``(none)`` = 0, the
value before the run's first event. The value references follow the inputs; the C side
(fmu.c.jinja) reads them in the order of EVENT_OUTPUTS.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

NONE_ITEM = "(none)"     # parentheses: never an event's name (an identifier)
EVENT_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


@dataclass(frozen=True)
class EventOutput:
    name: str            # the FMU variable
    type: str            # Real, Integer or Enumeration
    field: str           # what fmu.c.jinja reads: a NAME_event field, count, name, action
    description: str


EVENT_OUTPUTS = (
    EventOutput("events.count", "Integer", "count",
                "events so far in this run (every one, also past the C log's rows)"),
    EventOutput("events.last.time", "Real", "t", "the latest event's time"),
    EventOutput("events.last.name", "Enumeration", "name",
                "which event it was (EventName; (none) before the first)"),
    EventOutput("events.last.action", "Enumeration", "action",
                "what it did (EventAction; (none) before the first)"),
    EventOutput("events.last.impulse", "Real", "impulse",
                "the impact's multiplier (0: none)"),
    EventOutput("events.last.kinetic_energy_before", "Real", "kinetic_energy_before",
                "kinetic energy before the event"),
    EventOutput("events.last.kinetic_energy_after", "Real", "kinetic_energy_after",
                "kinetic energy after the event"),
    EventOutput("events.last.constraint_error", "Real", "constraint_error",
                "max |g| (and the locked rows) after the event"),
    EventOutput("events.last.dof", "Integer", "dof", "degrees of freedom after the event"),
    EventOutput("events.last.speed_before", "Real", "speed_before",
                "the event function's rate before the event"),
)
DECLARED = {"name": "EventName", "action": "EventAction"}


def enumeration_items(event_names, actions) -> dict:
    """{type name: [(item, value)]} of the two Enumeration types; refuses an event
    name that is not an identifier (it goes into the XML)."""
    for name in event_names:
        if not isinstance(name, str) or not EVENT_NAME.fullmatch(name):
            raise ValueError(f"{name!r} cannot be an item of the FMU's EventName type")
    return {DECLARED["name"]: [(NONE_ITEM, 0)] + [(n, k + 1) for k, n in
                                                   enumerate(event_names)],
            DECLARED["action"]: [(NONE_ITEM, 0)] + [(a, k + 1) for k, a in
                                                     enumerate(actions)]}


def clash(event_names, taken) -> str:
    """The first event output whose name is already a variable of the FMU ("": none)."""
    if not event_names:
        return ""
    taken = set(taken)
    return next((v.name for v in EVENT_OUTPUTS if v.name in taken), "")
