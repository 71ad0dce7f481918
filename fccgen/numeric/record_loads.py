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
follow the records instead, by the rule of the joint angle columns
(:mod:`fccgen.mechanism.turns`). Each record's angle is taken on the branch nearest to
the previous angle advanced by its rate (a rotor turning fast between records keeps its
turns), and checked against the trapezoid of the two rates: a record where they differ
by more than a quarter turn cannot be placed on a turn (:class:`UncountedTurns`), and
the reactions are refused, the driver forces and the energy NaN from there (record
more often). The angles of a chunk of records are measured at once
(:func:`fccgen.numeric.joint_loads.angle_rate` on stacks of records). A method that
does not re-base (ali3p) measures its angles within half a turn of the planned
references: they are left as planned.
"""
from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np

from ..events.references import element_angles
from ..plan.classes import REFERENCE_SCALARS, input_parameter
from ..runs.inputs import input_slots, record_times
from .elements import element_kernels
from .joint_loads import angle_rate
from ..mechanism.driver_forces import record_chunks
from ..mechanism.turns import count_turns

EXPRESSION_KINDS = ("force_t", "torque_t", "force_q", "torque_q")


class UncountedTurns(ValueError):
    """The records are too far apart to count an angle's turns; ``record``: the
    chunk's first record that cannot be placed on a turn (those before it are)."""

    def __init__(self, message: str, record: int):
        super().__init__(message)
        self.record = record


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
        self.reference_slots = np.array(
            [self.starts[e] + plan.elements[e].cls.param_names.index(
                prefix + REFERENCE_SCALARS[0]) + i
             for e, prefix in self.sources for i in range(3)], np.intc)
        self.previous = None           # (t, angles, rates) of the last record
        self.impacts = np.zeros(0)     # the run's event times (of_run)
        self.lost = None               # (record, why) where placed() stopped
        self.t, self.angles = np.zeros(0), np.zeros((len(self.sources), 0))
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

    def _stack(self, e: int, q, v):
        """Element e's inputs over the records (q, v: n x n_q of the plan), with
        its references 0: scalars, and the triples as stacks (3, n)."""
        el = self.plan.elements[e]
        cls, p = el.cls, np.array(el.params, float)
        s = dict(zip(cls.scalar_names, p[:len(cls.scalar_names)].tolist()))
        idx = el.q_index()
        ql, vl = q[:, idx].T, v[:, idx].T
        pos, vel, k_q, k_p = {}, {}, 0, len(cls.scalar_names)
        for name, fixed in zip(cls.triple_names, cls.fixed):
            if fixed:
                pos[name], vel[name] = p[k_p:k_p + 3, None], np.zeros((3, 1))
                k_p += 3
            else:
                pos[name], vel[name] = ql[k_q:k_q + 3], vl[k_q:k_q + 3]
                k_q += 3
        return SimpleNamespace(s=s, pos=pos, vel=vel)

    def chunk(self, t, q, v) -> None:
        """Take the records (t, q, v: one row each, in order of time, following the
        previous chunk's) whose :meth:`hold` comes next: their angles counted over
        turns (module docstring)."""
        self.t = np.asarray(t, float)
        n = len(self.t)
        raw, rate = np.empty((len(self.sources), n)), np.empty((len(self.sources), n))
        for j, (e, prefix) in enumerate(self.sources):
            x = self._stack(e, np.asarray(q, float), np.asarray(v, float))
            for name in REFERENCE_SCALARS:
                x.s[prefix + name] = 0.0 if name != "cr" else 1.0
            raw[j], rate[j] = angle_rate(x, prefix)
        angles, known, step = count_turns(raw, rate, self.t, self.impacts, self.previous)
        if n and self.sources and known.min() < n:   # the first record, then its angle
            j = int(np.argmin(known))
            k = int(known[j])
            ts = np.concatenate([self.t[:1] if self.previous is None else
                                 self.previous[0], self.t])
            e, prefix = self.sources[j]
            name = prefix.split(".")[0] or self.plan.elements[e].label
            self.angles = angles           # the records before it are placed
            raise UncountedTurns(
                f"the angle of {name} moved {abs(step[j, k]):.3g} rad between the "
                f"records at t = {ts[k]:.9g} and {ts[k + 1]:.9g} s, too far to count "
                "its turns from the records; record more often (output_dt)", k)
        if n:
            self.previous = (self.t[-1:], angles[:, -1:], rate[:, -1:])
        self.angles = angles

    def hold(self, k: int, q, v, values: bool = True) -> dict[int, np.ndarray]:
        """The values (global force or torque) of the expression loads at record k of
        the chunk (q, v its coordinates and speeds); the solver's parameters set to the
        record's (inputs, references). values False: the parameters only (an empty
        dict; the driver forces and the energy read the solver, not the loads)."""
        t = float(self.t[k])
        q, v = np.asarray(q, float), np.asarray(v, float)
        angles = self.angles[:, k]
        values = [np.column_stack([angles, np.cos(angles), np.sin(angles)]).ravel()]
        row = self._input_row(t)
        slots = [self.reference_slots]
        for name, found in self.input_slots.items():
            if name in row:
                slots.append(np.asarray(found, np.intc))
                values.append(np.full(len(found), row[name]))
        slots = np.concatenate(slots).astype(np.intc)
        if len(slots):
            self.put(slots, np.concatenate(values))
            self.touched.update(slots.tolist())
        out = {}
        for j, e in self.loads.items() if values else ():
            el = self.plan.elements[e]
            names = el.cls.param_names
            p = np.array(el.params, float)
            p[names.index("t")] = t
            for name in el.cls.inputs:          # not given: the planned start value
                if name in row:
                    p[names.index(input_parameter(name))] = row[name]
            for source, (own, prefix) in enumerate(self.sources):
                if own == e:
                    i = names.index(prefix + REFERENCE_SCALARS[0])
                    p[i:i + 3] = values[0][3 * source:3 * source + 3]
            idx = el.q_index()
            kernels = element_kernels(el.cls, q[idx], v[idx], p)
            out[j] = np.array([kernels.x.s[n] for n in kernels.names])
        return out

    def placed(self, t, q, v, parts):
        """The records of ``parts`` ((slice of records, tag) in order of time, from the
        run's start) that can be placed on a turn, as (record, tag), each yielded with
        the solver's parameters held at the record's (:meth:`hold`, without the loads'
        values). At a record that cannot be placed (:class:`UncountedTurns`) it
        stops, with ``lost`` (that record, why); else ``lost`` is None."""
        self.lost = None
        for part, tag in parts:
            stop = part.stop
            try:
                self.chunk(t[part], q[part], v[part])
            except UncountedTurns as exc:          # the records before it are placed
                stop = part.start + exc.record
                self.lost = (stop, str(exc))
            for k in range(part.start, stop):
                self.hold(k - part.start, q[k], v[k], values=False)
                yield k, tag
            if self.lost is not None:
                return

    def restore(self) -> None:
        """The planned values again in every parameter :meth:`hold` wrote."""
        if self.touched:
            plan_params = np.concatenate([np.asarray(el.params, float)
                                          for el in self.plan.elements])
            slots = np.array(sorted(self.touched), np.intc)
            self.put(slots, plan_params[slots])
        self.touched = set()
        self.previous = None


def energies(solver, t, q, v, loads: RecordLoads, chunk: int = 1024):
    """(energy at each record, records known, why not the rest) of the records (t, q,
    v: one row each, in order of time, from the run's start), each with the angle
    references and inputs the run held there (``loads``, which is restored after),
    so that a torsion spring wound past half a turn stores k phi^2 / 2 of its angle
    over turns, not of the angle within half a turn of its planned reference. Where
    the records are too far apart to count the turns (:meth:`RecordLoads.placed`),
    the energy is NaN from there on and the reason is returned."""
    n = len(t)
    out = np.full(n, np.nan)
    try:
        for k, _ in loads.placed(t, q, v, record_chunks(n, chunk, None)):
            solver.set_time(float(t[k]))
            out[k] = solver.energy(q[k], v[k])
    finally:
        loads.restore()
    known, reason = loads.lost or (n, "")
    return out, known, reason


def of_run(plan, put, inputs, sched, turns: bool = True, events=()) -> RecordLoads:
    """The RecordLoads of a run with the schedule ``sched`` and the inputs ``inputs``
    (fccgen.runs.inputs.input_run; None: the model has none); events: its event
    table (fccgen.events.table.event_rows)."""
    times = None if inputs is None or inputs.constant else record_times(sched)
    loads = RecordLoads(plan, put, inputs, times, turns)
    loads.impacts = np.array(sorted(e["t"] for e in events), float)
    return loads
