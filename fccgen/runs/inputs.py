"""The model's inputs in a run (docs/model-file.md, "Inputs").

An input is a parameter of the element classes that read it ("input:NAME",
fccgen.plan.classes): the kernels take it as they take a mass, so a new value needs
no rebuild. ``simulate(inputs=...)`` gives each input as

* a number: held over the whole run;
* a function of t: sampled at each output time;
* a table ``(times, values)``: interpolated linearly at each output time (held at
  its first and last values outside it);

and holds each sample until the next output time (zero-order hold), as an FMU master
sets inputs at its communication points. An input not given keeps its start value.
Inputs that change over the run need a method that stops at every output time: the
fixed-step methods rk4 and baumgarte (adaptive methods step across output times).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..plan.classes import input_parameter

HOLDING_METHODS = ("rk4", "baumgarte")


def input_slots(plan) -> dict[str, list[int]]:
    """name -> the indices into the concatenated element parameters of every copy of
    the input (one per element class instance that reads it); the model's order."""
    slots: dict[str, list[int]] = {name: [] for name in plan.model.inputs}
    start = 0
    for el in plan.elements:
        for name in el.cls.inputs:
            slots[name].append(start + el.cls.param_names.index(input_parameter(name)))
        start += len(el.params)
    return slots


@dataclass
class InputRun:
    """The inputs of one run: slots and columns (one entry per parameter slot), and
    a table with one row per record (or one row: constant)."""
    names: list
    slots: np.ndarray
    columns: np.ndarray
    table: np.ndarray
    # the same for the event kernels' parameters (set by the compiled solver when the
    # model's event functions read inputs; fccgen.runtime.event_settings)
    event_slots: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intc))
    event_columns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intc))

    @property
    def constant(self) -> bool:
        return self.table.shape[0] == 1


def _sampler(name: str, given):
    """times -> values of one input as the caller gave it."""
    if isinstance(given, (bool, np.bool_)):
        raise ValueError(f"input {name!r}: give a number, a function of t or a table "
                         "(times, values), not a bool")
    if isinstance(given, (int, float, np.integer, np.floating)):
        return lambda times: np.full(len(times), float(given))
    if callable(given):
        return lambda times: np.array([float(given(float(t))) for t in times])
    try:
        times, values = (np.asarray(x, float) for x in given)
    except (TypeError, ValueError):
        raise ValueError(f"input {name!r}: give a number, a function of t or a table "
                         "(times, values) of two equally long arrays") from None
    if times.ndim != 1 or times.shape != values.shape or times.size < 1 \
            or np.any(np.diff(times) <= 0) or not np.all(np.isfinite(times)):
        raise ValueError(f"input {name!r}: a table is (times, values), two 1-D arrays "
                         "of the same length with finite times strictly increasing")
    return lambda sample: np.interp(sample, times, values)


def input_run(plan, inputs, method: str, sched) -> InputRun | None:
    """The inputs of a run of ``method`` with the schedule ``sched`` (None: the model
    has none). Unknown names, non-finite values, and inputs that change over a run of a
    method that does not stop at every output time raise ValueError."""
    model_inputs = plan.model.inputs
    inputs = dict(inputs or {})
    unknown = sorted(set(inputs) - set(model_inputs))
    if unknown:
        known = ", ".join(model_inputs) or "none"
        raise ValueError(f"model {plan.model.name!r} has no input {unknown[0]!r} "
                         f"(its inputs: {known})")
    if not model_inputs:
        return None
    names = list(model_inputs)
    varying = [n for n in inputs
               if not isinstance(inputs[n], (int, float, np.integer, np.floating))]
    if varying and method not in HOLDING_METHODS:
        raise ValueError(f"input {varying[0]!r} changes over the run: inputs are held "
                         f"between output times, which only the fixed-step methods "
                         f"({', '.join(HOLDING_METHODS)}) stop at, and {method} steps "
                         "across them. Use method='rk4', or give the inputs as numbers")
    times = record_times(sched) if varying else np.zeros(1)
    rows = len(times)
    table = np.empty((rows, len(names)))
    for k, name in enumerate(names):
        if name in inputs:
            table[:, k] = _sampler(name, inputs[name])(times[:rows])
        else:
            table[:, k] = model_inputs[name]
        bad = np.flatnonzero(~np.isfinite(table[:, k]))
        if bad.size:
            raise ValueError(f"input {name!r} is not a finite number at t = "
                             f"{times[bad[0]]:g} ({table[bad[0], k]})")
    slots, columns = [], []
    for k, (name, found) in enumerate(input_slots(plan).items()):
        slots += found
        columns += [k] * len(found)
    return InputRun(names, np.array(slots, np.intc), np.array(columns, np.intc), table)


def record_times(sched) -> np.ndarray:
    """The output times of a fixed-step schedule: 0, every ``every`` steps, t_end."""
    n = sched.n_steps // sched.every + (1 if sched.n_steps % sched.every else 0)
    times = np.arange(n + 1) * sched.every * sched.dt
    times[-1] = sched.t_end
    return times
