"""The output columns of an exported model and the constants that compute them in C.

The columns are those of ``fccgen simulate`` (docs/design.md §4) that the engine's
state gives at a time: points and vectors (position, speed), bodies (centre and
angular velocity), energy, constraint_error, and the joints' angle, rate, position and
speed (the formulas of :mod:`fccgen.mechanism.outputs`, counted over turns from one
read to the next by the rule of :mod:`fccgen.mechanism.turns`), and the drivers'
forces (angle and position drivers of models without events: the multipliers of a
second engine's solve at the state read, :func:`exported_drivers`). The joints'
reactions need a least-squares solve of the bodies' balance, which a standalone
export without LAPACK leaves out with the rest of :data:`LEFT_OUT`.
The members' strain and curvature columns (fccgen.mechanism.cable_outputs) are
computed after a run too and left out; their node positions and slopes are columns.
"""
from __future__ import annotations

import math

import numpy as np

from ..mechanism.joints import ANGLE_TYPES, SLIDE_TYPES, perpendiculars
from ..mechanism.outputs import _written, joint_columns
from ..model.types import GROUND

# kind codes (the C side's enum in the api template)
Q, V, BODY, ENERGY, CERR, ANGLE, RATE, SLIDE, SLIDE_SPEED, DRIVER = range(10)
LEFT_OUT = ("joint reactions (J.fx ... J.tz), the forces of distance drivers and of "
            "the drivers of models with events, and the members' strain and curvature "
            "(m.n<k>.strain, m.n<k>.curvature)")


def exported_drivers(plan) -> dict[str, int]:
    """{result column: constraint row} of the drivers whose force the export computes:
    -lambda of the row (fccgen.mechanism.driver_forces), for angle and position
    drivers (a distance driver's slope, 2 f(t), is not in the C tables) of models
    without events (after a lock the held rows' multipliers join the solve, which the
    export's second engine does not hold)."""
    from ..mechanism.driver_forces import driver_rows
    from ..mechanism.lowering import driver_column
    lowering = getattr(plan.model, "mechanism", None)
    if lowering is None or plan.model.events:
        return {}
    rows = driver_rows(plan)
    return {driver_column(d): rows[driver_column(d)][0]
            for d in lowering.drivers or [] if d.quantity != "distance"}


class OutputTable:
    """Columns (name, kind, index) and the triple, body and joint tables of a plan."""

    def __init__(self, plan, column_names):
        self.plan = plan
        self.triples: list[tuple[int, tuple]] = []      # (q offset or -1, xyz)
        self._triple_of: dict[str, int] = {}
        self.frames: list[tuple[int, int, int, int]] = []   # (i, j, u, body row) or ground
        self._frame_of: dict[str, int] = {}
        self.angles: list[dict] = []
        self.slides: list[dict] = []
        self.drivers = exported_drivers(plan)            # column -> constraint row
        self._joint_kinds(plan)
        body_row = {name: b for b, (name, _) in enumerate(plan.bodies)}
        triple_row = {name: k for k, (name, _) in enumerate(plan.triples)}
        self.columns: list[tuple[str, int, int]] = []
        for name in column_names:
            self.columns.append((name, *self._locate(name, triple_row, body_row)))

    def _locate(self, name, triple_row, body_row):
        if name == "energy":
            return ENERGY, 0
        if name == "constraint_error":
            return CERR, 0
        if name in self.drivers:
            return DRIVER, self.drivers[name]
        stem, _, part = name.rpartition(".")
        if stem in triple_row and part in ("x", "y", "z"):
            return Q, 3 * triple_row[stem] + "xyz".index(part)
        if stem in triple_row and part in ("vx", "vy", "vz"):
            return V, 3 * triple_row[stem] + "xyz".index(part[1])
        cols = ("cx", "cy", "cz", "wx", "wy", "wz")
        if stem in body_row and part in cols:
            return BODY, 6 * body_row[stem] + cols.index(part)
        for kind, table, parts in ((ANGLE, self.angles, ("angle", "rate")),
                                   (SLIDE, self.slides, ("position", "speed"))):
            for k, j in enumerate(table):
                if j["name"] == stem and part in parts:
                    return kind + (part == parts[1]) * (RATE - ANGLE if kind == ANGLE
                                                         else SLIDE_SPEED - SLIDE), k
        raise ValueError(f"the export cannot compute the column {name!r}")

    def _triple(self, name: str) -> int:
        if name not in self._triple_of:
            plan = self.plan
            if name in plan.index:
                ref = (3 * plan.index[name], (0.0, 0.0, 0.0))
            else:
                m = plan.model
                value = m.points[name].at if name in m.points else m.vectors[name].along
                ref = (-1, tuple(float(x) for x in value))
            self._triple_of[name] = len(self.triples)
            self.triples.append(ref)
        return self._triple_of[name]

    def _frame(self, body: str) -> int:
        if body not in self._frame_of:
            if body == GROUND:
                row = (-1, -1, -1, -1)
            else:
                b = self.plan.model.bodies[body]
                rows = [k for k, (name, _) in enumerate(self.plan.bodies) if name == body]
                row = (self._triple(b.i), self._triple(b.j), self._triple(b.u),
                       rows[0] if rows else -1)
            self._frame_of[body] = len(self.frames)
            self.frames.append(row)
        return self._frame_of[body]

    def _joint_kinds(self, plan) -> None:
        lowering = getattr(plan.model, "mechanism", None)
        if lowering is None:
            return
        written = _written(plan)
        for jl in lowering.joints:
            j = jl.joint
            A, B = j.bodies
            if j.type in ANGLE_TYPES:
                RA0, RB0 = written.rotation(A)[0], written.rotation(B)[0]
                a_A = RA0.T @ np.asarray(j.axes[0], float)
                self.angles.append(dict(
                    name=j.name, frame_a=self._frame(A), frame_b=self._frame(B),
                    x=(RA0.T @ RB0).ravel(), a=a_A, n1=perpendiculars(a_A)[0], shift=0.0))
            if j.type in SLIDE_TYPES:
                self.slides.append(dict(name=j.name, a=self._triple(f"{j.name}_a"),
                                        b=self._triple(f"{j.name}_b"),
                                        axis=self._triple(f"{j.name}_axis")))

    def set_angle_shifts(self, result) -> None:
        """Each angle's whole turns at the start (``initial: joints:`` angles), read
        from a Python run: its first angle against the raw unwrapped one."""
        if not self.angles:
            return
        raw = joint_columns(self.plan, result.columns, len(result.t), near_given=False)
        for j in self.angles:
            given = result.columns[f"{j['name']}.angle"][0]
            turns = round((given - raw[f"{j['name']}.angle"][0]) / (2 * math.pi))
            j["shift"] = 2 * math.pi * turns
