"""Element classes: the structure that one generated kernel serves.

An *element* is a body, a unit-vector constraint, a joint constraint or a load. Its
kinematics depend on *triples*: the three coordinates of a point or of a unit vector.
A triple is either moving (its coordinates are generalized coordinates) or fixed (its
values are parameters). Two elements share a class, and so one kernel, when they have
the same kind, the same kinds of ends, the same fixed pattern and the same structural
zeros; their numbers are runtime parameters.

Layout conventions every stage follows (derive, numeric, runtime):

* local coordinates ``q``: the moving triples in ``triple_names`` order, 3 numbers each;
  local speeds ``v`` likewise;
* parameters ``p``: ``scalar_names`` in order, then ``x, y, z`` of every *fixed* triple
  in ``triple_names`` order (see :attr:`ElementClass.param_names`);
* matrices are row-major: mass matrix ``n_q x n_q``, constraint Jacobian ``n_g x n_q``;
* ``energy`` is ``[kinetic, potential]``; ``body_outputs`` is ``[cx, cy, cz, wx, wy, wz]``
  (mass centre and angular velocity, global frame).
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from functools import cached_property, lru_cache

from .cable_kinds import CABLE_KINDS, TIMED_POINT_KINDS

# Scalars of a point end that sits on a body ("body point"): the body's frame numbers
# and the point's coefficients b1..b3 (r = r_i + b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l)).
BODY_POINT_SCALARS = ("l", "alpha", "beta", "b1", "b2", "b3")
BODY_TRIPLES = ("ri", "rj", "u")

# A torsion spring between bodies A and B about their shared unit vector u
# (docs/elements.md): the points i, j of both bodies and u. Scalars: stiffness k,
# damping c, lA = l_A beta_A and lB = l_B beta_B (the reference directions
# p = r_ij - (l beta) u, perpendicular to u), cos/sin of the initial angle from p_A to
# p_B (cos0, sin0), the free angle measured from the initial configuration (free), and
# the turn-counting reference the runtime writes (REFERENCE_SCALARS).
TORSION_SPRING_TRIPLES = ("A.ri", "A.rj", "B.ri", "B.rj", "u")
# The angle reference theta_r and its cosine and sine: the joint angle (from the
# initial configuration) at the last accepted state, written by the runtime as it
# re-bases the event kernels' angle references (fccgen.events.references), so that an
# angle theta_r + atan2(...) counts turns. Outside a run: a torsion spring's free
# angle, a load's 0 (the start). Never folded.
REFERENCE_SCALARS = ("th", "cr", "sr")
TORSION_SPRING_SCALARS = ("k", "c", "lA", "lB", "cos0", "sin0", "free", *REFERENCE_SCALARS)

# Per kind: own scalars, names of point ends, own triples.
KIND_SCALARS = {
    "body": ("l", "alpha", "beta", "a1", "a2", "a3", "m",
             "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz", "gx", "gy", "gz"),
    "unit_vector": (),
    "distance": ("L",),
    "point_on_line": (),
    "force": ("l", "alpha", "beta", "b1", "b2", "b3", "Fx", "Fy", "Fz"),
    "torque": ("l", "alpha", "beta", "Tx", "Ty", "Tz"),
    "spring": ("k", "L0", "c"),
    "torsion_spring": TORSION_SPRING_SCALARS,
}
KIND_ENDS = {
    "body": (), "unit_vector": (), "force": (), "torque": (),
    "distance": ("A", "B"),
    "point_on_line": ("K", "A", "B"),
    "spring": ("A", "B"),
    "torsion_spring": (),
}
KIND_TRIPLES = {
    "body": BODY_TRIPLES, "force": BODY_TRIPLES, "torque": BODY_TRIPLES,
    "unit_vector": ("u",), "distance": (), "point_on_line": (), "spring": (),
    "torsion_spring": TORSION_SPRING_TRIPLES,
}
# Scalars that may be folded to zero when they are exactly zero (structural zeros).
FOLDABLE = {
    "body": {"beta", "a1", "a2", "a3", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz",
             "gx", "gy", "gz"},
    "unit_vector": set(),
    "distance": set(),
    "point_on_line": set(),
    "force": {"beta", "b1", "b2", "b3", "Fx", "Fy", "Fz"},
    "torque": {"beta", "Tx", "Ty", "Tz"},
    "spring": {"L0", "c"},
    "torsion_spring": {"c", "lA", "lB", "cos0", "sin0", "free"},
}
END_FOLDABLE = {"beta", "b1", "b2", "b3"}

# -- mechanism level (docs/joints.md): attached points and vectors, point on a plane,
# constant dot product. Attached triples carry the coefficients b1..b3 of their
# body-frame coordinates (fccgen.model.geometry.point_coefficients); all rows are linear
# or quadratic in q.
MECHANISM_KINDS = {
    # kind: (scalars, ends, triples, foldable, constraint rows)
    "attached_point": (BODY_POINT_SCALARS, (), (*BODY_TRIPLES, "k"),
                       {"beta", "b1", "b2", "b3"}, ("x", "y", "z")),
    "attached_vector": (BODY_POINT_SCALARS, (), (*BODY_TRIPLES, "w"),
                        {"beta", "b1", "b2", "b3"}, ("x", "y", "z")),
    "point_on_plane": ((), ("K", "A"), ("n",), set(), ("plane",)),
    "dot": (("c",), (), ("a", "b"), {"c"}, ("dot",)),
}
# Two rows that tie a unit vector w, already a unit vector through another frame, to a
# body by two of its body-frame components: "e1" w.r_ij - c1, "e2" w.u - c2,
# "e3" w.(r_ij x u) - c3 (c1 = l nu1, c2 = beta nu1 + alpha nu2, c3 = alpha l nu3; the
# e3 row is quadratic only for a fixed w). Kind aligned_vector_<ab> keeps rows a, b.
ALIGNED_ROWS = {"aligned_vector_12": ("e1", "e2"), "aligned_vector_13": ("e1", "e3"),
                "aligned_vector_23": ("e2", "e3")}
for _kind, _rows in ALIGNED_ROWS.items():
    _c = tuple(f"c{r[1]}" for r in _rows)
    MECHANISM_KINDS[_kind] = (_c, (), (*BODY_TRIPLES, "w"), set(_c), _rows)
# Drivers (docs/joints.md, "Drivers"): rheonomic rows g(q) - f(t) with f an expression
# of the time t (the class's ``function``, part of its key), t a parameter the runtime
# writes. driver_angle: b.(-sin f a + cos f (u x a)) with a, b unit vectors of the
# joint's two bodies perpendicular to the axis u; driver_position: u.(r_b - r_a) - f;
# driver_distance: (r_b - r_a).(r_b - r_a) - f^2; driver_coordinate: e.r - c0 - f (e a
# unit direction, c0 = e.r at the start).
DRIVER_KINDS = {
    "driver_angle": (("t",), (), ("u", "a", "b"), set(), ("driver",)),
    "driver_position": (("t",), (), ("u", "ra", "rb"), set(), ("driver",)),
    "driver_distance": (("t",), (), ("ra", "rb"), set(), ("driver",)),
    "driver_coordinate": (("t", "ex", "ey", "ez", "c0"), (), ("r",), {"ex", "ey", "ez"},
                          ("driver",)),
}
MECHANISM_KINDS.update(DRIVER_KINDS)
# Loads given as expressions of t (docs/elements.md): three components, ``function``
# "Fx;Fy;Fz" (or "Tx;Ty;Tz"), the time t a parameter the runtime writes.
TIMED_LOAD_KINDS = {
    "force_t": (("l", "alpha", "beta", "b1", "b2", "b3", "t"), (), BODY_TRIPLES,
                {"beta", "b1", "b2", "b3"}, ()),
    "torque_t": (("l", "alpha", "beta", "t"), (), BODY_TRIPLES, {"beta"}, ()),
}
MECHANISM_KINDS.update(TIMED_LOAD_KINDS)
# A linear spring-damper along a prismatic or cylindrical joint: s = u.(r_b - r_a) with
# u the joint axis, force k (s - L) + c s' (docs/elements.md).
MECHANISM_KINDS["linear_spring"] = (("k", "L", "c"), (), ("u", "ra", "rb"), {"L", "c"}, ())
# Loads whose expressions also use joint quantities (docs/elements.md, "Loads of joint
# quantities"): the timed loads' scalars and triples plus, per joint quantity family the
# expression names, the triples and scalars of :data:`JOINT_FAMILIES` under the prefix
# "J.family." (J the joint). ``function`` is "J:family,...|ex;ex;ex".
JOINT_LOAD_KINDS = {"force_q": "force_t", "torque_q": "torque_t"}
for _kind, _base in JOINT_LOAD_KINDS.items():
    MECHANISM_KINDS[_kind] = MECHANISM_KINDS[_base]
# angle: the two sides' points i, j and the axis u, with lA, lB, cos0, sin0 and the
# reference th, cr, sr as the torsion spring's; position: u.(r_b - r_a) - s0.
JOINT_FAMILIES = {
    "angle": (("lA", "lB", "cos0", "sin0", *REFERENCE_SCALARS),
              ("A.ri", "A.rj", "B.ri", "B.rj", "u")),
    "position": (("s0",), ("u", "ra", "rb")),
}
# Flexible members (fccgen/plan/cable_kinds.py): cable elements, clamp rows, point forces.
TIMED_LOAD_KINDS.update(TIMED_POINT_KINDS)
MECHANISM_KINDS.update(CABLE_KINDS)
MECHANISM_KINDS.update(TIMED_POINT_KINDS)
FUNCTION_KINDS = (*DRIVER_KINDS, *TIMED_LOAD_KINDS, *JOINT_LOAD_KINDS)
# Loads whose expressions may read the model's inputs (docs/model-file.md, "Inputs"):
# each input a class reads is one more scalar, "input:NAME", that the runtime writes
# between steps (as it writes "t" at every stage).
INPUT_KINDS = ("force_t", "torque_t", *JOINT_LOAD_KINDS)


def input_parameter(name: str) -> str:
    """The scalar name of the input ``name`` in the classes that read it."""
    return f"input:{name}"
for _kind, (_scalars, _ends, _triples, _foldable, _rows) in MECHANISM_KINDS.items():
    KIND_SCALARS[_kind] = _scalars
    KIND_ENDS[_kind] = _ends
    KIND_TRIPLES[_kind] = _triples
    FOLDABLE[_kind] = _foldable
KINDS = tuple(KIND_SCALARS)
END_KINDS = ("point", "body_point")


@dataclass(frozen=True)
class ElementClass:
    """The structure of an element; see the module docstring for layouts."""
    kind: str
    ends: tuple[str, ...]          # per end of KIND_ENDS[kind]: "point" | "body_point"
    fixed: tuple[bool, ...]        # per triple of triple_names
    zeros: frozenset[str]          # scalar names folded to zero
    function: str = ""             # drivers: f(t); timed loads: "ex;ex;ex" (grammar of
                                   # fccgen.expressions.grammar, in t)
    inputs: tuple[str, ...] = ()   # the model's inputs the function reads (sorted): each
                                   # a parameter "input:NAME" the runtime writes

    def __post_init__(self):
        if self.kind not in KIND_SCALARS:
            raise ValueError(f"unknown element kind {self.kind!r}")
        if len(self.ends) != len(KIND_ENDS[self.kind]):
            raise ValueError(f"{self.kind}: expected {len(KIND_ENDS[self.kind])} ends")
        if len(self.fixed) != len(self.triple_names):
            raise ValueError(f"{self.kind}: fixed mask has the wrong length")
        unknown = set(self.zeros) - set(self.scalar_names)
        if unknown:
            raise ValueError(f"{self.kind}: zeros name unknown scalars {sorted(unknown)}")
        if bool(self.function) != (self.kind in FUNCTION_KINDS):
            raise ValueError(f"{self.kind}: a function of time belongs to driver and "
                             "timed-load classes only, and every one of them has one")
        if self.inputs and self.kind not in INPUT_KINDS:
            raise ValueError(f"{self.kind}: only loads of time read inputs")

    @cached_property
    def joint_families(self) -> tuple[tuple[str, str], ...]:
        """(joint, family) pairs of a joint-quantity load, from its ``function``."""
        if self.kind not in JOINT_LOAD_KINDS:
            return ()
        header = self.function.split("|", 1)[0]
        return tuple(tuple(e.split(":")) for e in header.split(","))

    def _family_names(self, which: int) -> list[str]:
        return [f"{j}.{fam}.{n}" for j, fam in self.joint_families
                for n in JOINT_FAMILIES[fam][which]]

    @cached_property
    def scalar_names(self) -> tuple[str, ...]:
        names = list(KIND_SCALARS[self.kind]) + self._family_names(0)
        for end, end_kind in zip(KIND_ENDS[self.kind], self.ends):
            if end_kind == "body_point":
                names += [f"{end}.{s}" for s in BODY_POINT_SCALARS]
        return tuple(names) + tuple(input_parameter(n) for n in self.inputs)

    @cached_property
    def triple_names(self) -> tuple[str, ...]:
        names = list(KIND_TRIPLES[self.kind]) + self._family_names(1)
        for end, end_kind in zip(KIND_ENDS[self.kind], self.ends):
            if end_kind == "body_point":
                names += [f"{end}.{t}" for t in BODY_TRIPLES]
            else:
                names.append(f"{end}.r")
        return tuple(names)

    @cached_property
    def moving_triples(self) -> tuple[str, ...]:
        return tuple(t for t, f in zip(self.triple_names, self.fixed) if not f)

    @cached_property
    def param_names(self) -> tuple[str, ...]:
        names = list(self.scalar_names)
        for t, f in zip(self.triple_names, self.fixed):
            if f:
                names += [f"{t}.x", f"{t}.y", f"{t}.z"]
        return tuple(names)

    @property
    def n_q(self) -> int:
        return 3 * len(self.moving_triples)

    @property
    def n_p(self) -> int:
        return len(self.param_names)

    @cached_property
    def constraint_rows(self) -> tuple[str, ...]:
        """Names of the constraint equations this element contributes, in order."""
        if self.kind == "body":
            fi, fj, fu = self.fixed
            rows = []
            if not (fi and fj):
                rows.append("length")      # r_ij . r_ij - l^2
            if not (fi and fj and fu):
                rows.append("angle")       # r_ij . u - l beta
            return tuple(rows)
        if self.kind == "unit_vector":
            return ("unit",)               # u . u - 1
        if self.kind == "distance":
            return ("distance",)           # d . d - L^2, d = r_B - r_A
        if self.kind == "point_on_line":
            return ("cross.x", "cross.y", "cross.z")   # (r_K - r_A) x (r_B - r_A)
        if self.kind in MECHANISM_KINDS:
            return MECHANISM_KINDS[self.kind][4]
        return ()

    @property
    def n_g(self) -> int:
        return len(self.constraint_rows)

    @cached_property
    def key(self) -> str:
        """Canonical text of the structure (stable across runs and machines)."""
        key = {"kind": self.kind, "ends": list(self.ends),
               "fixed": [int(f) for f in self.fixed], "zeros": sorted(self.zeros)}
        if self.function:
            key["function"] = self.function
        if self.inputs:
            key["inputs"] = list(self.inputs)
        return json.dumps(key, sort_keys=True, separators=(",", ":"))

    @cached_property
    def name(self) -> str:
        """C identifier of the class: kind and a short hash of the key."""
        digest = hashlib.sha256(self.key.encode()).hexdigest()[:8]
        return f"{self.kind}_{digest}"

    def describe(self) -> str:
        """One line for generated headers and reports."""
        fixed = [t for t, f in zip(self.triple_names, self.fixed) if f]
        parts = [self.kind]
        if self.ends:
            parts.append("ends " + "/".join(self.ends))
        parts.append("fixed " + (",".join(fixed) if fixed else "none"))
        parts.append("zeros " + (",".join(sorted(self.zeros)) if self.zeros else "none"))
        if self.function:
            text = self.function
            if text.startswith("table:"):         # a table: its hash (the rows are long)
                text = ":".join(text.split(":")[:2])
            from ..expressions.named_tables import short_text
            text = short_text(text)                # a load's named tables: the same
            parts.append(f"f(t) = {text}")
        return "; ".join(parts)


@lru_cache(maxsize=4096)
def element_class(kind: str, ends: tuple, fixed: tuple, zeros: frozenset,
                  function: str = "", inputs: tuple = ()) -> ElementClass:
    """The ElementClass of these fields, one instance per distinct class in a process.
    It is immutable, so a plan's elements can share it: its checks and derived names
    (scalar_names, triple_names, key, ...) are worked out once, not per element and
    per with_parameters call."""
    return ElementClass(kind, ends, fixed, zeros, function, inputs)

