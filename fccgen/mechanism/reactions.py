"""Joint reactions (docs/design.md §2b): per joint, the force F and the torque T about
its point that it applies on its second body, global frame, result columns
``J.fx J.fy J.fz J.tx J.ty J.tz``.

Joints are lowered onto shared points and vectors, which have no multipliers, so the
reactions come from a Newton-Euler balance of every moving body at each recorded row
(post-processing in NumPy). With q'' from the solver (:mod:`.body_motion`):

    sum_J  s_J F_J                                  = m a_G - F_applied
    sum_J  s_J (T_J + (p_J - r_G) x F_J)            = H_G' - M_applied (about G)

s_J = +1 on the joint's second body, -1 on its first; p_J the joint point on the
second body. Each (F_J, T_J) is restricted to the joint's reaction subspace
(:func:`fccgen.mechanism.reaction_bases.bases`), F = P_f x_f, T = P_t x_t with
orthonormal columns; a joint's drivers widen it by the driven direction, so its
reaction holds the motor's torque (force) too. A coordinate driver of a point adds
one unknown, the force x e along its direction e at the point, on the one moving body
that carries the point (a point two bodies share is refused). The rows of all moving
bodies stacked give E x = b per result row (:mod:`.reaction_system`: E sparse, its
pattern fixed), solved by the pseudo-inverse, a record at a time and a chunk of records
at a time (:mod:`.reaction_solve`: a certified sparse factorisation per record, the SVD
where it cannot certify). Where E has fewer independent columns than unknowns (redundant constraints,
e.g. a planar four-bar of revolutes) the reactions are not unique and the
minimum-norm x (in N and N m together) is reported, with
``info["reactions"]["unique"]`` false.

Applied loads are attributed to bodies: gravity, forces and torques on a body (those
whose value is an expression with the values the run held at each record, from the
caller: :func:`reactions`, ``loads``), torsion springs on their two bodies, point
springs on the bodies that carry their ends, a joint's linear spring on the joint's
two bodies at its points J_a, J_b. A load that acts on a triple shared by two bodies, or on one that no body carries, and
section-2 ties that act as hidden joints (constraints not made by a joint, a point or
vector shared by bodies or a fixed one a body uses outside a joint) cannot be
attributed: reactions are refused with a :class:`~fccgen.errors.ModelError` naming the
item.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import ModelError, RunWarning, SimulationError
from ..model.types import (GROUND, Attached, BodyPoint, DriverRow, Force,
                           LinearSpring, Spring, Torque, TorsionSpring)
from .body_motion import Motion
from .driver_forces import record_chunks
from .reaction_bases import COMPONENTS
from ..expressions.named_tables import expressions_of
from .reaction_solve import solve_records
from .reaction_system import system

# The largest imbalance of the bodies' Newton-Euler balance that the reactions may
# leave, relative to its largest load or inertial term. What the least-squares solve
# leaves in a consistent balance is rounding and the recorded constraint error
# (1e-10 of it and less); a balance whose loads, accelerations and joints disagree
# (a load read on another branch than the dynamics read it) leaves O(1).
IMBALANCE = 1e-3

# Bytes of working arrays per chunk of records (body frames, the balance's blocks and
# right-hand sides): the records are solved a chunk at a time, so that the memory of
# the reactions does not grow with the length of the run.
CHUNK_BYTES = 48 * 2 ** 20


def _refuse(item_where, item: str, rule: str, value=None) -> ModelError:
    return ModelError(item_where.file, item_where.line, item,
                      "joint reactions cannot be computed: " + rule, value)


def carriers(model) -> dict[str, set[str]]:
    """Per triple name, the bodies (moving or not) that carry it."""
    out: dict[str, set[str]] = {}
    for name, b in model.bodies.items():
        for t in (b.i, b.j, b.u):
            out.setdefault(t, set()).add(name)
    for c in model.constraints:
        if isinstance(c, Attached):
            out.setdefault(c.target, set()).add(c.body)
    return out


def check_attributable(plan, loads=None) -> None:
    """ModelError for the first item whose force the body balance cannot place.
    loads: what the run held at each record (:func:`reactions`), or None."""
    model, lowering = plan.model, plan.model.mechanism
    joint_labels = {lab for labs in lowering.labels.values() for lab in labs}
    held = carriers(model)
    for k, c in enumerate(model.constraints):
        if isinstance(c, DriverRow) and c.kind == "coordinate":
            _driven_body(plan, held, c, k)
        elif getattr(c, "label", None) not in joint_labels:
            raise _refuse(c.where, f"constraints[{k}]", "its force belongs to no joint; "
                          "write it as a joint (docs/design.md §2b)", c.type)
    joint_shared = {t.name for jl in lowering.joints for t in jl.triples
                    if len(t.carriers) > 1}
    for name, bodies in held.items():
        moving = sorted(b for b in bodies if _moving(plan, b))
        if not moving or name in joint_shared:
            continue
        where = (model.points.get(name) or model.vectors.get(name)).where
        if len(bodies) > 1:
            raise _refuse(where, name, f"bodies {', '.join(sorted(bodies))} share it "
                          "without a joint", name)
        if name not in plan.index:
            raise _refuse(where, name, f"body {moving[0]} is held by this fixed "
                          "triple outside any joint", name)
    for k, ld in enumerate(model.loads):
        if isinstance(ld, Spring):
            for end in ld.ends:
                _end_body(plan, held, end, ld, k)
        elif not isinstance(ld, (Force, Torque, TorsionSpring, LinearSpring)):
            raise _refuse(ld.where, f"loads[{k}]", "no body balance is known for this "
                          "load type", ld.type)
        elif isinstance(ld, (Force, Torque)) and ld.function and loads is None:
            # its value depends on t, joint quantities or inputs: what the run held at
            # the records (inputs, turns) comes from the solver that ran it
            inputs = _element(plan, k).cls.inputs
            why = (f"it reads the input {inputs[0]}, whose values over the run"
                   if inputs else "its value is an expression, whose values at the "
                   "records (joint angles counted over turns)")
            why += (" only the run knows (simulate, statics and inverse compute these "
                    "reactions)")
            raise _refuse(ld.where, f"loads[{k}]", why,
                          expressions_of(ld.function.split("|")[-1]))


def _moving(plan, body: str) -> bool:
    return body != GROUND and any(name == body for name, _ in plan.bodies)


def _end_body(plan, held, end, load, k) -> str | None:
    """The moving body a spring end acts on (None: a fixed point)."""
    if isinstance(end, BodyPoint):
        return end.body if _moving(plan, end.body) else None
    if end not in plan.index:
        return None
    bodies = [b for b in held.get(end, ()) if _moving(plan, b)]
    if len(bodies) != 1:
        whom = ("is carried by no body" if not bodies else
                f"is shared by {' and '.join(sorted(bodies))}")
        raise _refuse(load.where, f"loads[{k}]", f"its end {end} {whom}, so its force "
                      "cannot be given to one body; attach the end to one body "
                      "(a body point) instead", end)
    return bodies[0]


def _driven_body(plan, held, row, k) -> str:
    """The moving body that carries the point of coordinate driver row ``row``."""
    point = row.triples[0]
    bodies = sorted(b for b in held.get(point, ()) if _moving(plan, b))
    if len(bodies) != 1:
        whom = ("is carried by no moving body" if not bodies else
                f"is shared by {' and '.join(bodies)}")
        raise _refuse(row.where, f"constraints[{k}]", f"the point {point} of {row.label} "
                      f"{whom}, so the driver's force cannot be given to one body; drive "
                      "a point of one body instead", point)
    return bodies[0]


def applied(plan, motion: Motion, index: dict[str, int], turns=None,
            values=None) -> np.ndarray:
    """(n, 6 n_b) applied forces and torques about each moving body's mass centre.
    turns: per torsion spring, the unwrapped angle of the record before the first of
    ``motion`` (updated in place; None: these records start the run). values: load
    index -> (n, 3) global force or torque of each load whose value is an expression
    (:func:`reactions`)."""
    model = plan.model
    out = np.zeros((motion.n, 6 * len(index)))
    centres = {b: motion.centre(b)[0] for b in index}

    def add(body, force=None, torque=None, at=None):
        if body not in index:
            return
        k = 6 * index[body]
        if force is not None:
            out[:, k:k + 3] += force
            if at is not None:
                out[:, k + 3:k + 6] += np.cross(at - centres[body], force)
        if torque is not None:
            out[:, k + 3:k + 6] += torque

    for b in index:
        add(b, force=np.tile(model.bodies[b].mass * model.gravity, (motion.n, 1)))
    held = carriers(model)
    for k, ld in enumerate(model.loads):
        if isinstance(ld, Force) and ld.body in index:
            at = (motion.centre(ld.body)[0] if ld.at is None else
                  motion.body(ld.body).point(ld.at)[0])
            add(ld.body, force=_value(ld, k, values, motion.n), at=at)
        elif isinstance(ld, Torque):
            add(ld.body, torque=_value(ld, k, values, motion.n))
        elif isinstance(ld, Spring):
            _spring(plan, motion, held, ld, k, add)
        elif isinstance(ld, TorsionSpring):
            _torsion(plan, motion, ld, k, add, {} if turns is None else turns)
        elif isinstance(ld, LinearSpring):
            _linear(plan, motion, ld, k, add)
    return out


def _value(ld, k: int, values, n: int) -> np.ndarray:
    """(n, 3) value of force or torque load k: its expression's values at the records
    (``values``), else its constant value."""
    if ld.function:
        return values[k]
    return np.tile(ld.value, (n, 1))


def _element(plan, k: int):
    return next(e for e in plan.elements if e.label == f"loads[{k}]")


def _params(plan, k: int) -> dict[str, float]:
    el = _element(plan, k)
    return dict(zip(el.cls.param_names, el.params))


def _spring(plan, motion, held, ld, k, add):
    """f on end B = -(k (L - L0) + c L') n, n = (r_B - r_A) / L; -f on end A."""
    p = _params(plan, k)
    (ra, va), (rb, vb) = (motion.reference(e) for e in ld.ends)
    d = rb - ra
    length = np.linalg.norm(d, axis=1)
    n = d / length[:, None]
    rate = np.einsum("ni,ni->n", vb - va, n)
    f = -(p["k"] * (length - p["L0"]) + p["c"] * rate)[:, None] * n
    for end, r, sign in ((ld.ends[0], ra, -1.0), (ld.ends[1], rb, 1.0)):
        body = _end_body(plan, held, end, ld, k)
        if body is not None:
            add(body, force=sign * f, at=r)


def _torsion(plan, motion, ld, k, add, turns):
    """Torque -T u on body B and +T u on body A, T = k phi + c phi' with phi as the
    element computes it (docs/elements.md), its turns counted along the records
    (unwrapped from the initial angle), and phi' = (w_B - w_A) . u."""
    p = _params(plan, k)
    u = motion.triple(ld.axis)[0]
    sides = ld.sides or tuple((plan.model.bodies[b].i, plan.model.bodies[b].j)
                              for b in ld.bodies)
    perp = []
    for (i, j), lam in zip(sides, (p["lA"], p["lB"])):
        perp.append(motion.triple(j)[0] - motion.triple(i)[0] - lam * u)
    D = np.einsum("ni,ni->n", u, np.cross(perp[0], perp[1]))
    P = np.einsum("ni,ni->n", perp[0], perp[1])
    turned = np.arctan2(p["cos0"] * D - p["sin0"] * P, p["cos0"] * P + p["sin0"] * D)
    unwrapped = np.unwrap(np.concatenate([[turns.get(k, 0.0)], turned]))[1:]
    turns[k] = float(unwrapped[-1])
    phi = unwrapped - p["free"]
    w = [motion.body(b).omega if _moving(plan, b) else 0.0 for b in ld.bodies]
    rate = np.einsum("ni,ni->n", w[1] - w[0] + np.zeros_like(u), u)
    torque = (p["k"] * phi + p["c"] * rate)[:, None] * u
    add(ld.bodies[0], torque=torque)
    add(ld.bodies[1], torque=-torque)


def _linear(plan, motion, ld, k, add):
    """A joint's linear spring (s = u.(r_b - r_a), T = k (s - L) + c s'): -T u on the
    joint's second body at r_b, +T u on its first at r_a, and the couple T d x u
    (d = r_b - r_a; zero while r_b stays on the axis line through r_a) on the first,
    which carries the axis: the element's generalized force -T ds/dq as body loads."""
    p = _params(plan, k)
    (u, du, _), (ra, va, _), (rb, vb, _) = (motion.triple(t) for t in ld.triples)
    d = rb - ra
    s = np.einsum("ni,ni->n", u, d)
    rate = np.einsum("ni,ni->n", du, d) + np.einsum("ni,ni->n", u, vb - va)
    tension = (p["k"] * (s - p["L"]) + p["c"] * rate)[:, None]
    first, second = _joint_bodies(plan, ld.triples[1])
    add(second, force=-tension * u, at=rb)
    add(first, force=tension * u, at=ra, torque=tension * np.cross(d, u))


def _joint_bodies(plan, point_a: str) -> tuple[str, str]:
    """The two bodies of the joint whose first point is ``point_a`` (J_a)."""
    joint = point_a[:-len("_a")]
    return next(jl.joint.bodies for jl in plan.model.mechanism.joints
                if jl.joint.name == joint)


def reactions(solver, result, sparse: bool | None = None, held=None,
              loads=None, references: bool = False) -> tuple[dict[str, np.ndarray], dict]:
    """(columns, info) of the joint reactions over the rows of ``result``; ModelError
    when a load or constraint cannot be attributed to a body (module docstring).

    The records are taken a chunk at a time (CHUNK_BYTES of working arrays) and each
    record's E x = b is solved on its own (fccgen.mechanism.reaction_solve; sparse:
    None picks the way by size, True/False forces the sparse or the dense way).
    held: the rows the run's events held (fccgen.runs.held_rows.HeldRows; None: no
    events): at a record where a lock holds a joint, the accelerations are those with
    its rows held and the joint's reaction gains the held direction's torque (force).
    loads: what the run held at each record (fccgen.numeric.record_loads.RecordLoads;
    None: loads whose value is an expression are refused): ``loads.chunk(t, q, v)``
    takes a chunk of records (their angles counted over turns), ``loads.hold(k, q,
    v)`` sets the solver's parameters to those of its record k (inputs, angle
    references) and returns the expression loads' values there, ``loads.restore()``
    the planned parameters again. references: the records are states outside a run
    (statics), whose torsion springs read their angles within half a turn of the
    kernels' planned references, as the kernels that found the state read them
    (docs/elements.md, "Angles over turns"); False: a run's records, whose angles are
    counted over turns from 0 at the first."""
    plan = solver.plan
    check_attributable(plan, loads)
    if loads is None:
        return _reactions(solver, result, sparse, held, None, references)
    try:
        return _reactions(solver, result, sparse, held, loads, references)
    finally:
        loads.restore()


def _planned_turns(plan) -> dict[int, float]:
    """Per torsion spring (load index), its kernel's planned angle reference th."""
    return {k: _params(plan, k)["th"] for k, ld in enumerate(plan.model.loads)
            if isinstance(ld, TorsionSpring)}


def _reactions(solver, result, sparse, held, loads, references=False):
    plan = solver.plan
    index = {name: k for k, (name, _) in enumerate(plan.bodies)}
    drivers = _coordinate_drivers(plan)
    names = [name for name, _ in plan.triples]
    n = len(result.t)
    chunk = chunk_records(plan, len(index))
    cols = {f"{jl.joint.name}.{c}": np.full(n, np.nan)
            for jl in plan.model.mechanism.joints for c in COMPONENTS}
    turns: dict[int, float] = _planned_turns(plan) if references else {}
    ranks, unknowns, dense, worst, patterns, missing = [], 0, 0, 0.0, {}, 0
    scale = 0.0                         # the largest load or inertial term balanced
    known = n if held is None else held.known     # records whose held rows are known
    for rows, keys in record_chunks(known, chunk, held):
        q = np.column_stack([result.columns[f"{t}.{c}"][rows] for t in names for c in "xyz"])
        v = np.column_stack([result.columns[f"{t}.v{c}"][rows] for t in names
                             for c in "xyz"])
        a = np.empty_like(q)
        values = {}
        if loads is not None:
            loads.chunk(result.t[rows], q, v)
        for k, t in enumerate(result.t[rows]):
            solver.set_time(float(t))          # a driven model's q'' depends on t
            if loads is not None:              # and the run's inputs, turns, loads
                for j, value in loads.hold(k, q[k], v[k]).items():
                    values.setdefault(j, np.empty((len(a), 3)))[k] = value
            a[k] = (held.accelerations(q[k], v[k], keys) if keys
                    else solver.accelerations(q[k], v[k]))
        motion = Motion(plan, q, v, a)
        at = [(body, e, motion.triple(point)[0] - motion.centre(body)[0])
              for body, e, point in drivers]
        loads_on = applied(plan, motion, index, turns, values)
        balance = system(plan, motion, index, loads_on, at, keys)
        scale = max(scale, float(np.max(np.abs(loads_on), initial=0.0)),
                    float(np.max(np.abs(balance.b), initial=0.0)))
        x, rank, solved_dense, res = solve_records(balance, sparse, patterns)
        ranks.append(rank)
        unknowns, dense, worst = (max(unknowns, balance.shape[1]), dense + solved_dense,
                                  max(worst, res))
        # a lock adds unknowns to its records: each record against its own count
        missing = max(missing, int(np.max(balance.shape[1] - rank)) if len(rank) else 0)
        _fill(cols, plan, balance.spans, x, rows)
    rank = np.concatenate(ranks) if ranks else np.zeros(0, int)
    info = dict(computed=True, unknowns=int(unknowns),
                rank=int(rank.min()) if len(rank) else 0, undetermined=missing,
                unique=missing == 0, residual=worst, balance_scale=scale,
                balanced=bool(worst <= IMBALANCE * scale),
                dense_records=int(dense), records=int(n))
    if known < n:
        info["unknown_from"] = float(result.t[known])
        info["unknown_reason"] = held.unknown_reason(result.t)
    return cols, info


def chunk_records(plan, n_bodies: int) -> int:
    """Records per chunk: CHUNK_BYTES over an estimate of one record's working arrays
    (a body's frames and derivatives ~ 200 floats, a joint's blocks ~ 200)."""
    per_record = 8 * (200 * n_bodies + 200 * len(plan.model.mechanism.joints)
                      + 4 * plan.n_q + 1)
    return int(min(1024, max(1, CHUNK_BYTES // per_record)))


def _fill(cols, plan, spans, x, rows) -> None:
    """Write the joints' F and T of the records ``rows`` into ``cols``."""
    start = 0
    for jl, (Pf, Pt) in zip(plan.model.mechanism.joints, spans):
        nf, nt = Pf.shape[2], Pt.shape[2]
        F = np.einsum("nik,nk->ni", Pf, x[:, start:start + nf])
        T = np.einsum("nik,nk->ni", Pt, x[:, start + nf:start + nf + nt])
        start += nf + nt
        for k, c in enumerate(COMPONENTS):
            cols[f"{jl.joint.name}.{c}"][rows] = (F if k < 3 else T)[:, k % 3]


def _coordinate_drivers(plan) -> list[tuple[str, np.ndarray, str]]:
    """(body, direction e, point) of each coordinate driver: one unknown, the force
    along e at its point, on the body that carries the point (:func:`_driven_body`)."""
    held, out = carriers(plan.model), []
    for k, c in enumerate(plan.model.constraints):
        if isinstance(c, DriverRow) and c.kind == "coordinate":
            out.append((_driven_body(plan, held, c, k),
                        np.array([c.scalars[x] for x in ("ex", "ey", "ez")]),
                        c.triples[0]))
    return out


def minimum_norm_note(info: dict) -> str:
    return ("the joint reactions are not unique (redundant constraints: "
            f"{info['undetermined']} of {info['unknowns']} reaction components "
            "are undetermined); the minimum-norm set is reported")


def add_reactions(solver, result, held=None, loads=None, references: bool = False):
    """Add the reaction columns to ``result`` of a mechanism-level model (in place);
    ``result.info["reactions"]`` says whether they are unique, or why they are absent.
    held: the rows the run's events held; loads: what the run held at each record;
    references: records outside a run (:func:`reactions`). Reactions that do not
    balance the bodies (info ``balanced`` false) are kept with a warning."""
    if getattr(solver.plan.model, "mechanism", None) is None or len(result.t) == 0:
        return result
    try:
        cols, info = reactions(solver, result, held=held, loads=loads,
                               references=references)
    except (ModelError, SimulationError, np.linalg.LinAlgError, MemoryError,
            RuntimeError, ValueError) as exc:
        # the run itself succeeded: keep it, and say why it has no reactions
        reason = (f"out of memory ({exc})" if isinstance(exc, MemoryError) and str(exc)
                  else "out of memory" if isinstance(exc, MemoryError) else str(exc))
        result.info["reactions"] = dict(computed=False, reason=reason)
        if not isinstance(exc, ModelError):   # a model they do not apply to: info only
            text = f"the joint reactions were not computed: {reason}; the run is kept"
            result.info.setdefault("warnings", []).append(text)
            warnings.warn(text, RunWarning, stacklevel=3)
        return result
    result.columns.update(cols)
    if not info["unique"]:
        info["note"] = minimum_norm_note(info)
    if not info["balanced"]:
        text = (f"the joint reactions leave an imbalance of {info['residual']:.3g} in "
                "the bodies' Newton-Euler balance (its largest term "
                f"{info['balance_scale']:.3g}): the applied loads, the accelerations "
                "and the joints disagree at some record, so the reactions are not to "
                "be trusted")
        result.info.setdefault("warnings", []).append(text)
        warnings.warn(text, RunWarning, stacklevel=3)
    if "unknown_reason" in info:
        text = (f"the joint reactions are NaN from t = {info['unknown_from']:.9g} s on: "
                + info["unknown_reason"])
        result.info.setdefault("warnings", []).append(text)
        warnings.warn(text, RunWarning, stacklevel=3)
    result.info["reactions"] = info
    return result
