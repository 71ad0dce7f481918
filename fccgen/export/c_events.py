"""The events of an exported model (docs/export.md, "Events"): the event kernels
(the model's event module, printed by fccgen.events.build) and their settings as C
constants for the engine's fcc_event_spec and fcc_events_mirror.

Every event setting the Python build gives its EventSet (fccgen.runtime.event_settings)
is written here from the same function, with the run's defaults for the location
tolerance and the rest speed (``simulate(event_tol=..., rest_speed=...)``). A model
without events whose element kernels count turns (torsion springs, loads of joint
angles) has an event module too, with no event functions: the engine then only
re-bases the angle references after every step.
"""
from __future__ import annotations

import inspect
from pathlib import Path

from ..render.escape import c_identifier
from . import c_data

DIRECTIONS = {"rising": 1, "falling": -1, "either": 0}
# rows of the event log the exported engine keeps (NAME_event_row reads them; the
# engine counts the events past it: NAME_events_dropped)
LOG_CAP = 64


def run_defaults(solver) -> tuple[float, float]:
    """(event_tol, rest_speed) of ``solver.simulate`` when they are not given."""
    params = inspect.signature(solver.simulate).parameters
    return float(params["event_tol"].default), float(params["rest_speed"].default)


def event_header(solver) -> str:
    """The events' constants (HAS_EVENTS 0 and nothing else without an event module)."""
    module = solver.events_module
    if module is None:
        return c_data.define("HAS_EVENTS", 0)
    from ..runtime._events import ACTIONS
    from ..runtime.event_settings import event_settings, max_per_step
    st = event_settings(solver.plan, module)
    tol, rest = run_defaults(solver)
    ne = len(st.actions)
    return "".join([
        c_data.define("HAS_EVENTS", 1), c_data.define("N_EVENTS", ne),
        c_data.c_strings("EV_NAMES", list(module.EVENT_NAMES)),
        c_data.define("N_EV_ANGLES", len(st.angle_rows)),
        c_data.c_array("int", "EV_ANGLE_ROW", st.angle_rows),
        c_data.c_array("int", "EV_DIRECTION", [DIRECTIONS[d] for d in st.directions]),
        c_data.c_array("int", "EV_ACTION", [ACTIONS.index(a) for a in st.actions]),
        c_data.c_array("int", "EV_ROW", st.rows), c_data.c_array("int", "EV_ROW2", st.rows2),
        c_data.c_array("double", "EV_RESTITUTION", st.restitution),
        c_data.define("N_EV_CONSTANTS", len(st.constants)),
        c_data.c_array("double", "EV_CONSTANTS", st.constants),
        c_data.define("N_EV_INPUTS", len(st.input_slots)),
        c_data.c_array("int", "EV_INPUT_COL", st.input_columns),
        c_data.c_array("int", "EV_INPUT_SLOT", st.input_slots),
        c_data.define("N_MIRROR", len(st.mirror_slots)),
        c_data.c_array("int", "MIRROR_SLOT", st.mirror_slots),
        c_data.c_array("int", "MIRROR_ANGLE", st.mirror_angles),
        c_data.define("EVENT_TOL", tol), c_data.define("REST_SPEED", rest),
        c_data.define("EV_MAX_PER_STEP", max_per_step(ne)),
        c_data.define("EV_LOG_CAP", LOG_CAP),
    ])


def event_files(solver) -> dict[str, str]:
    """events.c and events.h of the model's event module, as fccgen.events.build
    printed them (none without an event module)."""
    module = solver.events_module
    if module is None:
        return {}
    folder = Path(module.__file__).resolve().parent
    return {name: (folder / name).read_text() for name in ("events.c", "events.h")}


def table_symbol(model_name: str) -> str:
    """The event table's C name in events.c (fccgen.events.build's template)."""
    return "fccgen_events_" + c_identifier(model_name)


def keys_keeping_constants(plan, keys, module):
    """The keys whose moves leave the event kernels' constants as they are (the C side
    keeps them fixed); a key that moves them needs a new export and is left out."""
    if module is None or not keys:
        return keys
    import numpy as np

    from ..plan import make_plan
    from ..runtime.event_settings import event_settings
    from ..runtime.params import set_parameters
    base = np.asarray(event_settings(plan, module).constants)
    kept = []
    for key, x0, slope in keys:
        for step in ((1e-3 * abs(x0) if x0 != 0 else 1.0) * s for s in (1, -1)):
            try:                       # (parameter_map kept the key at one of them)
                moved = make_plan(set_parameters(plan.model, {key: x0 + step}))
            except (ValueError, ArithmeticError):
                continue
            if np.array_equal(np.asarray(event_settings(moved, module).constants), base):
                kept.append((key, x0, slope))
            break
    return kept
