"""Other numbers for a compiled model, and compiled solvers that cross processes.

A compiled module serves every model with the same *structure* (docs/design.md §3):
masses, lengths, inertias, loads and initial positions are runtime parameters of the
element classes. :func:`with_parameters` sets such numbers in a copy of the in-memory
model, checks them with the model file's own rules, lays out the plan again and binds
it to the same module. The new plan must have exactly the old element classes: a value
that would fold a term to a structural zero (or unfold one), e.g. a mass-centre
coordinate set to exactly 0 that was not, needs a new build and is refused.

Keys are item paths as in the model file and its error messages, a component with
``[k]``::

    gravity[1]   points.P.at   vectors.u.along   bodies.arm.mass   bodies.arm.center[0]
    bodies.arm.inertia[2]   constraints[0].length   loads[1].stiffness   loads[0].value[2]
    initial.points.P[0]   simulate.t_end   simulate.dt   simulate.output_dt
    cables.boom.EA   cables.boom.EI   cables.boom.mass_per_length   cables.boom.damping
    cables.boom.distributed_load[1]

Pickling (:func:`reduce_solver`): a solver travels as its plan, the folder of its
built module and its tolerances; the receiving process loads the module from that
folder (checked against its manifest), so both must see the same file system.
"""
from __future__ import annotations

import copy
import math
import re
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..model import checks

SETTABLE = ("gravity", "points.NAME.at", "vectors.NAME.along", "bodies.NAME.mass",
            "bodies.NAME.center", "bodies.NAME.inertia", "constraints[K].length",
            "loads[K].value", "loads[K].at", "loads[K].stiffness", "loads[K].length",
            "loads[K].damping", "initial.points.NAME", "simulate.t_end", "simulate.dt",
            "simulate.output_dt", "cables.NAME.EA", "cables.NAME.EI",
            "cables.NAME.mass_per_length", "cables.NAME.damping",
            "cables.NAME.distributed_load")
# The rule of each scalar field: 'positive', 'nonnegative' or 'number'.
SCALAR_RULES = {"mass": "positive", "length": "positive", "stiffness": "nonnegative",
                "damping": "nonnegative", "t_end": "positive", "dt": "positive",
                "output_dt": "positive", "EA": "positive", "EI": "positive",
                "mass_per_length": "positive"}
_TOKEN = re.compile(r"\.?([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]")


def split_key(key: str) -> list:
    """``'bodies.arm.center[0]'`` -> ``['bodies', 'arm', 'center', 0]``."""
    tokens, pos = [], 0
    while pos < len(key):
        m = _TOKEN.match(key, pos)
        if m is None or (pos == 0 and key.startswith(".")):
            raise _unknown(key, "<parameters>")
        tokens.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if not tokens:
        raise _unknown(key, "<parameters>")
    return tokens


def _unknown(key, source, why="is not a number fccgen can set") -> ModelError:
    return ModelError(source, None, key, f"{why}; settable numbers: {', '.join(SETTABLE)} "
                      "(a component as NAME[k])", show_value=False)


def set_parameters(model, values: dict):
    """A copy of ``model`` with the given numbers set and checked (ModelError when a
    key names nothing settable or a value breaks a rule of the model file). A body's
    inertia is checked once all its components are set, so that several components
    moved together are judged as the tensor they make.

    The copy shares every part that no key sets with ``model`` (_Writable): each
    setter replaces values, never writes into them, and the parts of a model refer to
    one another by name only, so a shallow copy of each part a key sets is enough."""
    writable = _Writable(model)
    model = writable.model
    inertias = {}
    for key, value in values.items():
        writable.own(str(key))
        touched = _set_one(model, str(key), value)
        if touched is not None:
            inertias.setdefault(id(touched[0]), (touched[0], []))[1].append(touched[1:])
    for body, keys in inertias.values():
        problem = checks.inertia_problem(body.inertia)
        if problem:
            raise ModelError(model.source, keys[-1][1], ", ".join(k for k, _ in keys),
                             problem, show_value=False)
    if any(str(key).startswith(("points.", "vectors.")) for key in values):
        for body in model.bodies.values():       # only a point or a vector moves them
            _check_body_geometry(model, body)
    return model


class _Writable:
    """A shallow copy of a model whose parts become its own (shallow copies, with the
    table that holds them) as keys are about to set them: copy on write."""
    TABLES = ("points", "vectors", "bodies", "cables", "constraints", "loads")

    def __init__(self, model):
        self.model = copy.copy(model)
        self._owned: set[int] = set()

    def own(self, key: str) -> None:
        """Make the part ``key`` sets the copy's own (unknown keys: _set_one says)."""
        tokens = split_key(key)
        if len(tokens) > 1 and isinstance(tokens[-1], int):
            tokens.pop()
        try:
            obj, _, _ = _target(self.model, tokens, key)
        except ModelError:
            return
        m = self.model
        if obj is m or id(obj) in self._owned:
            return
        if obj is m.simulate:
            m.simulate = self._mine(copy.copy(obj))
            return
        if obj is m.initial.point_velocities:
            m.initial = copy.copy(m.initial)
            m.initial.point_velocities = self._mine(dict(obj))
            return
        for name in self.TABLES:
            table = getattr(m, name, None) or ()
            where = (table.items() if isinstance(table, dict) else enumerate(table))
            at = next((k for k, item in where if item is obj), None)
            if at is not None:
                if id(table) not in self._owned:
                    table = self._mine(dict(table) if isinstance(table, dict)
                                       else list(table))
                    setattr(m, name, table)
                table[at] = self._mine(copy.copy(obj))
                return
        raise AssertionError(f"{key}: set_parameters found no owner of the part it sets")

    def _mine(self, obj):
        self._owned.add(id(obj))
        return obj


def _named(table: dict, name, what: str, key: str, source: str):
    if name not in table:
        plural = "bodies" if what == "body" else f"{what}s"
        raise ModelError(source, None, key, f"no {what} named {name!r}; "
                         f"{plural}: {', '.join(table) or 'none'}", show_value=False)
    return table[name]


def _indexed(items: list, k, what: str, key: str, source: str):
    if not isinstance(k, int) or k >= len(items):
        have = (f"{len(items)} {what}s (indices 0 to {len(items) - 1})" if items
                else f"no {what}s")
        raise ModelError(source, None, key, f"the model has {have}", show_value=False)
    return items[k]


def _target(model, tokens: list, key: str):
    """(object, attribute name, line of the item) that ``tokens`` address."""
    src = model.source
    head, rest = tokens[0], tokens[1:]
    if head == "gravity" and not rest:
        return model, "gravity", model.where.get("gravity", None)
    if head in ("points", "vectors", "bodies") and len(rest) == 2 and isinstance(rest[0], str):
        table = getattr(model, head)
        item = _named(table, rest[0], {"points": "point", "vectors": "vector",
                                       "bodies": "body"}[head], key, src)
        fields = {"points": ("at",), "vectors": ("along",),
                  "bodies": ("mass", "center", "inertia")}[head]
        if rest[1] in fields:
            return item, rest[1], item.where
    if head in ("constraints", "loads") and len(rest) == 2 and isinstance(rest[1], str):
        item = _indexed(getattr(model, head), rest[0], head[:-1], key, src)
        if rest[1] in ("length", "value", "at", "stiffness", "damping") and \
                hasattr(item, rest[1]) and getattr(item, rest[1]) is not None:
            return item, rest[1], item.where
        if rest[1] == "length" and hasattr(item, "length"):
            return item, "length", item.where       # a spring's default free length
    if head == "cables" and len(rest) == 2 and isinstance(rest[0], str):
        member = _named(getattr(model, "cables", {}), rest[0], "cable", key, src)
        if rest[1] in ("EA", "EI", "mass_per_length", "damping", "distributed_load"):
            return member, rest[1], member.where
    if head == "initial" and len(rest) == 2 and rest[0] == "points":
        _named(model.points, rest[1], "point", key, src)
        return model.initial.point_velocities, rest[1], None
    if head == "simulate" and len(rest) == 1 and rest[0] in ("t_end", "dt", "output_dt"):
        return model.simulate, rest[0], model.where.get("simulate", None)
    raise _unknown(key, src)


def _get(obj, name):
    if isinstance(obj, dict):
        return obj.get(name, np.zeros(3))
    return getattr(obj, name)


def _put(obj, name, value) -> None:
    if isinstance(obj, dict):
        obj[name] = value
    else:
        setattr(obj, name, value)


def _number(value, key, source, line) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise ModelError(source, line, key, "must be a number", value)
    x = float(value)
    if not math.isfinite(x):
        raise ModelError(source, line, key, "must be a finite number", value)
    return x


def check_key(model, key: str) -> None:
    """ModelError when ``key`` names no settable number of ``model`` (its value's rules
    are checked when it is set)."""
    tokens = split_key(str(key))
    if len(tokens) > 1 and isinstance(tokens[-1], int):
        tokens.pop()
    _target(model, tokens, str(key))


def _pose(model, tokens: list):
    """(r_i, R, F) of a body the file gave by its pose (``bodies.NAME`` with ``center``
    and ``frame``), else None: its inertia and centre are stored in the FCC body frame,
    and its keys address them in the file's terms (docs/model-file.md)."""
    if tokens[0] != "bodies" or len(tokens) < 2:
        return None
    poses = getattr(getattr(model, "mechanism", None), "poses", None) or {}
    return poses.get(tokens[1])


def _six(I: np.ndarray) -> np.ndarray:
    return np.array([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])


def _file_terms(pose, name: str, value):
    """A body's stored inertia or centre as the model file gives it."""
    ri, R, F = pose
    if name == "inertia":
        FR = F.T @ R
        return FR @ np.asarray(value, float) @ FR.T
    return ri + R @ np.asarray(value, float)


def _stored_terms(pose, name: str, value):
    """The inverse of :func:`_file_terms`."""
    ri, R, F = pose
    if name == "inertia":
        FR = F.T @ R
        I = FR.T @ np.asarray(value, float) @ FR
        return 0.5 * (I + I.T)
    return R.T @ (np.asarray(value, float) - ri)


def value_of(model, key: str):
    """The number (or list) at ``key``, in the model file's terms; an inertia as its
    six components [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] in the body's ``frame``."""
    tokens = split_key(str(key))
    component = tokens.pop() if len(tokens) > 1 and isinstance(tokens[-1], int) else None
    obj, name, _ = _target(model, tokens, str(key))
    value = _get(obj, name)
    pose = _pose(model, tokens)
    if pose is not None and name in ("inertia", "center"):
        value = _file_terms(pose, name, value)
    if name == "inertia":
        value = _six(np.asarray(value, float))
    if component is None:
        return value if np.ndim(value) == 0 else np.asarray(value, float)
    return float(np.asarray(value, float)[component]) \
        if component < np.size(value) else float("nan")


def _set_one(model, key: str, value):
    """Set one number; for an inertia, (body, key, line) for the check that waits until
    every key is set (set_parameters), else None."""
    tokens = split_key(key)
    component = tokens.pop() if len(tokens) > 1 and isinstance(tokens[-1], int) else None
    obj, name, where = _target(model, tokens, key)
    line = getattr(where, "line", None)
    src = model.source
    pose = _pose(model, tokens) if name in ("inertia", "center") else None
    if name == "inertia":
        _set_inertia(obj, value, component, key, src, line, pose)
        return obj, key, line
    old = _get(obj, name)
    if pose is not None:
        old = _file_terms(pose, name, old)
    if np.ndim(old) == 0:
        if component is not None:
            raise ModelError(src, line, key, f"{name} is one number, not a list",
                             show_value=False)
        x = _number(value, key, src, line)
        _check_rule(SCALAR_RULES.get(name, "number"), x, key, src, line)
        _put(obj, name, x)
        return
    new = np.array(old, dtype=float).copy()
    if component is not None:
        if component > 2:
            raise ModelError(src, line, key, "a component index is 0, 1 or 2",
                             show_value=False)
        new[component] = _number(value, key, src, line)
    else:
        seq = np.ravel(np.asarray(value, dtype=object))
        if seq.shape != (3,):
            raise ModelError(src, line, key, "must be a list of 3 numbers", value)
        new = np.array([_number(v, key, src, line) for v in seq])
    if name == "along":
        problem = checks.unit_vector_problem(new)
        if problem:
            raise ModelError(src, line, key, problem, show_value=False)
    if pose is not None:
        new = _stored_terms(pose, name, new)
    _put(obj, name, tuple(new) if isinstance(old, tuple) else new)


def _check_rule(rule: str, x: float, key, source, line) -> None:
    if rule == "positive" and not x > 0:
        raise ModelError(source, line, key, "must be a positive number", x)
    if rule == "nonnegative" and not x >= 0:
        raise ModelError(source, line, key, "must be a number >= 0", x)


def _set_inertia(body, value, component, key, source, line, pose=None) -> None:
    """Inertia as [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (or 3 principal values); a component
    indexes that list of six. A pose-form body's are in its ``frame``, as in the file."""
    I = body.inertia if pose is None else _file_terms(pose, "inertia", body.inertia)
    six = _six(I)
    if component is not None:
        if component > 5:
            raise ModelError(source, line, key, "an inertia component is 0 to 5 "
                             "(Ixx, Iyy, Izz, Ixy, Ixz, Iyz)", show_value=False)
        six[component] = _number(value, key, source, line)
    else:
        seq = np.ravel(np.asarray(value, dtype=object))
        if seq.shape not in ((3,), (6,)):
            raise ModelError(source, line, key, "must be a list of 3 or 6 numbers", value)
        six = np.array([_number(v, key, source, line) for v in seq])
    tensor = checks.inertia_tensor(six)       # its rules: set_parameters, once all are set
    body.inertia = tensor if pose is None else _stored_terms(pose, "inertia", tensor)


def _check_body_geometry(model, body) -> None:
    ri, rj = model.points[body.i].at, model.points[body.j].at
    u = model.vectors[body.u].along
    line = body.where.line
    if checks.coincide(np.asarray(ri), np.asarray(rj)):
        raise ModelError(model.source, line, f"bodies.{body.name}.points",
                         f"points {body.i} and {body.j} coincide", show_value=False)
    angle = checks.parallel_angle(np.asarray(ri), np.asarray(rj), np.asarray(u))
    if angle is not None:
        raise ModelError(model.source, line, f"bodies.{body.name}.vector",
                         f"{body.u} is parallel to {body.i}->{body.j} "
                         f"(angle {angle:.3g} deg)", show_value=False)


def same_structure(old_plan, new_plan, values: dict) -> None:
    """Refuse a plan whose element classes differ from the compiled ones."""
    src = old_plan.model.source
    keys = ", ".join(map(str, values))
    if new_plan.triples != old_plan.triples or len(new_plan.elements) != len(old_plan.elements):
        raise ModelError(src, None, keys, "these values change the model's coordinates or "
                         "elements; edit the model file and build it again",
                         show_value=False)
    for old, new in zip(old_plan.elements, new_plan.elements):
        if old.cls == new.cls:
            continue
        folded = sorted(new.cls.zeros - old.cls.zeros)
        unfolded = sorted(old.cls.zeros - new.cls.zeros)
        what = []
        if folded:
            what.append(f"make {', '.join(folded)} of {new.label} exactly 0, a term the "
                        "compiled module keeps")
        if unfolded:
            what.append(f"make {', '.join(unfolded)} of {new.label} nonzero, a term the "
                        "compiled module folded away as a structural zero")
        raise ModelError(src, new.where.line, keys,
                         f"these values {' and '.join(what) or 'change its structure'}; "
                         "that needs a new build (edit the model file and run fccgen "
                         "again), or use a value close to but not exactly 0",
                         show_value=False)


def solver_options(solver) -> dict:
    """rank_tol, position_tol (None when it is the default for the plan's lengths) and
    max_newton of a solver."""
    default = 1e-11 * solver.length_scale
    return {"rank_tol": solver.rank_tol, "max_newton": solver.max_newton,
            "linear_solver": solver.linear_solver,
            "position_tol": None if solver.position_tol == default else solver.position_tol}


def with_parameters(solver, values: dict):
    """A new solver of the same compiled module (and event module: its numbers of the
    initial configuration are runtime parameters too) with the numbers in ``values``
    set (keys: see the module docstring), the other numbers and tolerances kept."""
    from ..plan import make_plan
    new_plan = make_plan(set_parameters(solver.plan.model, dict(values)))
    same_structure(solver.plan, new_plan, values)
    return type(solver)(new_plan, solver.module, **solver_options(solver),
                        events_module=getattr(solver, "events_module", None))


def module_directory(module) -> Path:
    """The folder of a built module (its manifest is there)."""
    return Path(module.__file__).resolve().parent


def rebuild_solver(cls, plan, directory, options, events_directory=None):
    """Unpickle a solver: load the module (and the event module, if any) from its
    folder (checked) and bind the plan."""
    from ..build import load_module
    if events_directory is not None:
        options = {**options, "events_module": load_module(events_directory)}
    return cls(plan, load_module(directory), **options)


def reduce_solver(solver):
    """``__reduce__`` of a compiled solver: its plan, module folder and tolerances."""
    options = {"rank_tol": solver.rank_tol, "position_tol": solver.position_tol,
               "max_newton": solver.max_newton, "linear_solver": solver.linear_solver}
    events = getattr(solver, "events_module", None)
    return (rebuild_solver, (type(solver), solver.plan,
                             str(module_directory(solver.module)), options,
                             None if events is None else str(module_directory(events))))
