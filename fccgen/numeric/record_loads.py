"""What a run held at each of its records, for the joint reactions
(fccgen.mechanism.reactions): the values of its loads whose value is an expression
(of t, of joint quantities, of named tables, of the model's inputs), the inputs, and
the angle references of the kernels that count turns.

The loads are evaluated by the NumPy kernels (:mod:`.mechanism_kernels`,
:mod:`.joint_loads`) with the element's parameters as the run had them at the record:
t, the inputs it held there (fccgen.runs.inputs: sampled at each output time and held
until the next, so at a record's time the value sampled there), and each angle's turn
reference. The same parameters are written into the solver (``put``), so that the
accelerations of the balance are the run's too.

Angles over turns: a run re-bases every reference after each accepted step
(docs/elements.md, "Angles over turns"), from 0 at its start; here the references
follow the records instead. Each record's angle is taken on the branch nearest to the
previous angle advanced by its rate (a rotor turning fast between records keeps its
turns), and checked against the trapezoid of the two rates: a record where they differ
by more than a quarter turn cannot be placed on a turn, and the reactions are refused
(record more often). A method that does not re-base (ali3p) measures its angles
within half a turn of the planned references: they are left as planned.
"""
from __future__ import annotations

import math
import re

import numpy as np

from ..events.references import element_angles
from ..plan.classes import REFERENCE_SCALARS, input_parameter
from ..runs.inputs import input_slots, record_times
from .elements import element_kernels
from .joint_loads import angle_rate
from .kinematics import Local

EXPRESSION_KINDS = ("force_t", "torque_t", "force_q", "torque_q")
TURN = 2.0 * math.pi


class RecordLoads:
    """Per record (in order), the values of the expression loads and the parameters
    the run held. plan: the solver's plan; put(slots, values): writes values into
    the solver's concatenated element parameters; inputs: the run's
    fccgen.runs.inputs.InputRun (None: the model has none); times: the output times
    its table's rows were sampled at (None: a constant table); turns: the run
    re-based its angle references (methods other than ali3p)."""

    def __init__(self, plan, put, inputs=None, times=None, turns: bool = True):
        self.plan, self.put = plan, put
        self.starts = np.concatenate([[0], np.cumsum([len(el.params)
                                                      for el in plan.elements])])
        self.loads = {int(m.group(1)): e for e, el in enumerate(plan.elements)
                      if el.cls.kind in EXPRESSION_KINDS
                      and (m := re.fullmatch(r"loads\[(\d+)\]", el.label))}
        self.sources = ([(s.element, s.prefix) for s in element_angles(plan)]
                        if turns else [])
        self.inputs, self.times = inputs, times
        self.input_slots = input_slots(plan)
        self.previous = None           # (t, angles, rates) of the last record
        self.touched: set[int] = set()

    def _input_row(self, t: float) -> dict[str, float]:
        held = self.inputs
        if held is None:
            return {}
        if held.constant or self.times is None:
            row = held.table[0]
        else:       # held from its output time to the next: the last time <= t
            tol = 1e-9 * max(1.0, abs(float(self.times[-1])))
            row = held.table[max(0, int(np.searchsorted(self.times, t + tol,
                                                        side="right")) - 1)]
        return dict(zip(held.names, (float(x) for x in row)))

    def _measure(self, e: int, prefix: str, q, v) -> tuple[float, float]:
        """(angle within half a turn of 0, rate) of (element e, prefix) at q, v."""
        el = self.plan.elements[e]
        p = np.array(el.params, float)
        k = el.cls.param_names.index(prefix + REFERENCE_SCALARS[0])
        p[k:k + 3] = 0.0, 1.0, 0.0
        idx = el.q_index()
        return angle_rate(Local(el.cls, q[idx], v[idx], p), prefix)

    def _angles(self, t: float, q, v) -> list[float]:
        """The references of this record: each angle counted over turns."""
        measured = [self._measure(e, prefix, q, v) for e, prefix in self.sources]
        if self.previous is None:                # the run's start: references 0
            angles = [a for a, _ in measured]
        else:
            t0, before, rates = self.previous
            dt = t - t0
            angles = []
            for (raw, rate), a0, r0, (e, prefix) in zip(measured, before, rates,
                                                        self.sources):
                guess = a0 + r0 * dt
                angle = raw + TURN * round((guess - raw) / TURN)
                if abs(angle - (a0 + 0.5 * (r0 + rate) * dt)) > 0.5 * math.pi:
                    name = prefix.split(".")[0] or self.plan.elements[e].label
                    raise ValueError(
                        f"the angle of {name} moved {abs(angle - a0):.3g} rad between "
                        f"the records at t = {t0:.9g} and {t:.9g} s, too far to count "
                        "its turns from the records; record more often (output_dt)")
                angles.append(angle)
        self.previous = (t, angles, [r for _, r in measured])
        return angles

    def hold(self, t: float, q, v) -> dict[int, np.ndarray]:
        """The values (global force or torque) of the expression loads at the record
        (t, q, v); the solver's parameters set to the record's (inputs, references).
        Records must come in order of time."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        slots, values = [], []
        refs = {}
        for (e, prefix), angle in zip(self.sources, self._angles(t, q, v)):
            refs[(e, prefix)] = angle
            el = self.plan.elements[e]
            k = el.cls.param_names.index(prefix + REFERENCE_SCALARS[0])
            slots += range(self.starts[e] + k, self.starts[e] + k + 3)
            values += [angle, math.cos(angle), math.sin(angle)]
        row = self._input_row(t)
        for name, found in self.input_slots.items():
            if name in row:
                slots += found
                values += [row[name]] * len(found)
        if slots:
            self.put(np.array(slots, np.intc), np.array(values, float))
            self.touched.update(slots)
        out = {}
        for k, e in self.loads.items():
            el = self.plan.elements[e]
            names = el.cls.param_names
            p = np.array(el.params, float)
            p[names.index("t")] = t
            for name in el.cls.inputs:          # not given: the planned start value
                if name in row:
                    p[names.index(input_parameter(name))] = row[name]
            for (source, prefix), angle in refs.items():
                if source == e:
                    j = names.index(prefix + REFERENCE_SCALARS[0])
                    p[j:j + 3] = angle, math.cos(angle), math.sin(angle)
            idx = el.q_index()
            kernels = element_kernels(el.cls, q[idx], v[idx], p)
            out[k] = np.array([kernels.x.s[n] for n in kernels.names])
        return out

    def restore(self) -> None:
        """The planned values again in every parameter :meth:`hold` wrote."""
        if self.touched:
            plan_params = np.concatenate([np.asarray(el.params, float)
                                          for el in self.plan.elements])
            slots = np.array(sorted(self.touched), np.intc)
            self.put(slots, plan_params[slots])
        self.touched = set()
        self.previous = None


def of_run(plan, put, inputs, sched, turns: bool = True) -> RecordLoads:
    """The RecordLoads of a run with the schedule ``sched`` and the inputs ``inputs``
    (fccgen.runs.inputs.input_run; None: the model has none)."""
    times = None if inputs is None or inputs.constant else record_times(sched)
    return RecordLoads(plan, put, inputs, times, turns)
