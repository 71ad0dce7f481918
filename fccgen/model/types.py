"""The validated model: what a model file says, in plain data.

Every object keeps ``where`` (file and line of its YAML item) so that later stages
(plan, assembly) can still report errors against the user's file.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

import numpy as np


@dataclass(frozen=True)
class Where:
    file: str
    line: int | None


@dataclass
class Point:
    name: str
    at: np.ndarray            # (3,) initial position, global frame
    fixed: bool
    where: Where


@dataclass
class Vector:
    name: str
    along: np.ndarray         # (3,) unit vector (normalised exactly at load)
    fixed: bool
    where: Where


@dataclass(frozen=True)
class BodyPoint:
    """A point attached to a body: body-frame coordinates measured from point i."""
    body: str
    at: tuple[float, float, float]


PointRef = Union[str, BodyPoint]   # a point name, or a point on a body


@dataclass(frozen=True)
class Solid:
    """The solid a body is drawn as (``shape:`` of a pose-form body): ``kind`` "box"
    (size: edges a, b, c along its x, y, z), "cylinder" or "rod" (radius, length along
    its x), "sphere" (radius); ``axes``: its x, y, z (rows) in the body's frame --
    the pose frame in a PoseBody, the FCC body frame once lowered. Centred at the
    body's mass centre (fccgen.mechanism.shapes)."""
    kind: str
    size: tuple[float, ...]
    axes: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                                                    (0.0, 0.0, 1.0))


@dataclass
class Body:
    name: str
    i: str                    # point names
    j: str
    u: str                    # vector name
    mass: float
    center: np.ndarray        # (3,) body frame, from point i
    inertia: np.ndarray       # (3, 3) symmetric tensor about the mass centre, body frame
    where: Where
    shape: Solid | None = None   # what it is drawn as (pose-form bodies with shape:)


@dataclass
class PointOnLine:
    point: PointRef
    line: tuple[PointRef, PointRef]
    where: Where
    type: str = "point_on_line"


@dataclass
class Distance:
    points: tuple[PointRef, PointRef]
    length: float
    where: Where
    type: str = "distance"


@dataclass
class Attached:
    """A point or unit-vector triple rigidly tied to a body (mechanism level):
    ``rho`` is the point's body-frame position from point i, or the vector's
    body-frame components (nu1, nu2, nu3). Kind "aligned_<ab>": a vector held by its
    components on e_a and e_b only (two rows; it is a unit vector through another
    frame or fixed)."""
    target: str
    body: str
    rho: tuple[float, float, float]
    kind: str                 # "point" | "vector" | "aligned_12" | "_13" | "_23"
    where: Where
    label: str | None = None  # what made it, for reports (e.g. "joint A (revolute)")
    type: str = "attached"


@dataclass
class PointOnPlane:
    """n . (r_point - r_origin) = 0, n a unit-vector name."""
    point: str
    origin: str
    normal: str
    where: Where
    label: str | None = None
    type: str = "point_on_plane"


@dataclass
class Angle:
    """a . b = cos(angle) for two unit-vector names."""
    vectors: tuple[str, str]
    cos: float
    where: Where
    label: str | None = None
    type: str = "angle"


Constraint = Union[PointOnLine, Distance, Attached, PointOnPlane, Angle]


@dataclass
class Force:
    body: str
    value: np.ndarray         # (3,) global frame
    at: tuple[float, float, float] | None   # body frame from point i; None: mass centre
    where: Where
    type: str = "force"
    function: str = ""        # "ex;ex;ex": components as expressions of t (value unused)
    joints: tuple = ()        # set by the lowering: JointUse per joint quantity family


@dataclass
class Torque:
    body: str
    value: np.ndarray         # (3,) global frame
    where: Where
    type: str = "torque"
    function: str = ""        # "ex;ex;ex": components as expressions of t (value unused)
    joints: tuple = ()        # set by the lowering: JointUse per joint quantity family


@dataclass
class Spring:
    ends: tuple[PointRef, PointRef]
    stiffness: float
    length: float | None      # free length; None: the initial distance of the ends
    damping: float
    where: Where
    type: str = "spring"


@dataclass
class TorsionSpring:
    """A torsion spring-damper about the hinge axis ``axis`` shared by two bodies:
    torque k (theta - angle) + c theta' on ``bodies[1]`` relative to ``bodies[0]``,
    theta measured from the initial configuration (docs/elements.md)."""
    bodies: tuple[str, str]
    axis: str                 # the vector of both bodies
    stiffness: float
    angle: float              # free angle, radians from the initial configuration
    damping: float
    where: Where
    type: str = "torsion_spring"
    # points (i, j) standing for each side's body frame; None: the bodies' own i, j
    sides: tuple[tuple[str, str], tuple[str, str]] | None = None


@dataclass
class JointSpring:
    """A spring-damper on a joint's freedom (lowered by fccgen.mechanism): kind
    "torsion" (``torsion_spring`` with ``joint:``; revolute, cylindrical) with torque
    k (angle - free) + c rate, or "linear" (``linear_spring``; prismatic, cylindrical)
    with force k (position - free) + c speed, on the joint's second body."""
    kind: str
    joint: str
    stiffness: float
    free: float               # free angle (radians) or free position, from the start
    damping: float
    where: Where
    type: str = "joint_spring"


@dataclass
class LinearSpring:
    """The lowered linear spring-damper along an axis u between points ra, rb:
    s = u.(r_b - r_a), force k (s - free) + c s' (fccgen.plan.classes)."""
    triples: tuple[str, str, str]
    stiffness: float
    free: float
    damping: float
    where: Where
    type: str = "linear_spring"


Load = Union[Force, Torque, Spring, TorsionSpring, JointSpring, LinearSpring]


@dataclass
class AngularVelocity:
    value: np.ndarray         # (3,)
    frame: str                # "global" | "body"
    where: Where


@dataclass
class Initial:
    point_velocities: dict[str, np.ndarray] = field(default_factory=dict)
    body_angular_velocities: dict[str, AngularVelocity] = field(default_factory=dict)
    # joint -> (quantity "rate" | "speed", value, where): kept exactly at t = 0
    joint_speeds: dict[str, tuple[str, float, Where]] = field(default_factory=dict)
    # joint -> (quantity "angle" | "position", value, where): assembled at t = 0
    joint_positions: dict[str, tuple[str, float, Where]] = field(default_factory=dict)


# -- mechanism level (docs/design.md §2b; lowered by fccgen.mechanism) ---------------

GROUND = "ground"             # the fixed body that joints may name without declaring it


@dataclass
class PoseBody:
    """A body given by its pose: the mass centre's initial global position and the
    body axes (columns of ``frame``, global directions) in which ``inertia`` is given."""
    name: str
    mass: float
    center: np.ndarray        # (3,) global frame, initial configuration
    frame: np.ndarray         # (3, 3) rotation, columns x, y, z
    inertia: np.ndarray       # (3, 3) about the mass centre, in ``frame``
    where: Where
    shape: Solid | None = None   # given by shape: (mass terms computed from it)


@dataclass
class Joint:
    """A joint or primitive constraint between two bodies, in global initial terms:
    ``at`` a location (two for a distance), ``axes`` unit directions (axis or normal:
    one; universal and angle: one per body)."""
    name: str
    type: str
    bodies: tuple[str, str]
    at: tuple[np.ndarray, ...]
    axes: tuple[np.ndarray, ...]
    value: float | None       # distance length or angle (radians); None: initial
    where: Where
    limits: tuple[float, float] | None = None   # bounce limits of the angle or slide
    restitution: float = 0.0                    # ... and their restitution


@dataclass
class Driver:
    """A rheonomic constraint: the joint's ``quantity`` ("angle": revolute and
    cylindrical; "position": prismatic and cylindrical) follows ``function``, an
    expression of t (measured, like the joint outputs, from the initial
    configuration). Its generalized force is the result column ``name.torque``
    (angle) or ``name.force`` (position)."""
    name: str
    joint: str
    quantity: str
    function: str             # expression text, whitespace normalised (rate: and speed:
                              # give the text of their integral)
    where: Where
    point: str = ""           # quantity "coordinate": the point and the unit direction
    direction: np.ndarray | None = None


@dataclass
class DriverRow:
    """The lowered row of a driver: kind "angle" (triples u, a, b), "position"
    (triples u, ra, rb) or "distance" (ra, rb); see fccgen.plan.classes.DRIVER_KINDS."""
    kind: str
    triples: tuple[str, ...]
    function: str
    where: Where
    label: str | None = None
    type: str = "driver"
    scalars: dict = field(default_factory=dict)   # coordinate: ex, ey, ez, c0


@dataclass
class SimulateDefaults:
    t_end: float = 1.0
    dt: float = 1.0e-3
    method: str = "rk4"
    output_dt: float | None = None
    # Solver tolerances (None: the solver's defaults; fccgen.runtime.CompiledSolver).
    rank_tol: float | None = None
    position_tol: float | None = None
    max_newton: int | None = None
    linear_solver: str | None = None  # fccgen.run_settings.LINEAR_SOLVERS; None: "auto"
    # Numbers in one output row (0: unknown), set by the loader from the model's size;
    # bounds a run's record (fccgen.run_settings.schedule). Not a setting: not compared.
    values_per_output: int = field(default=0, compare=False)


@dataclass
class Model:
    name: str
    source: str                       # the model file's path as given (for messages)
    gravity: np.ndarray               # (3,)
    points: dict[str, Point]          # insertion order = file order
    vectors: dict[str, Vector]
    bodies: dict[str, Body]
    constraints: list[Constraint]
    loads: list[Load]
    initial: Initial
    simulate: SimulateDefaults
    where: dict[str, Where] = field(default_factory=dict)   # top-level keys
    pose_bodies: dict[str, PoseBody] = field(default_factory=dict)
    joints: list[Joint] = field(default_factory=list)
    drivers: list[Driver] = field(default_factory=list)
    mechanism: object = None          # fccgen.mechanism.Lowering, once lowered
    events: list = field(default_factory=list)    # fccgen.model.events.Event
    cables: dict = field(default_factory=dict)    # name -> fccgen.model.cables.Cable
    slopes: dict = field(default_factory=dict)    # name -> Slope (cable nodes, lowered)
    inputs: dict = field(default_factory=dict)    # name -> start value (docs/model-file.md)

    @property
    def moving_points(self) -> list[Point]:
        return [p for p in self.points.values() if not p.fixed]

    @property
    def moving_vectors(self) -> list[Vector]:
        return [v for v in self.vectors.values() if not v.fixed]


# -- flexible members (docs/flexible.md; fccgen.model.cables, fccgen.mechanism.cables) --

@dataclass
class Slope:
    """The slope r' = dr/dx of a cable node: a coordinate triple that is not a unit
    vector (|r'| = 1 + axial strain), so it has no u.u - 1 row."""
    name: str
    along: np.ndarray         # (3,) initial value
    fixed: bool
    where: Where


@dataclass
class SlopeNormal:
    """d . n = 0: the slope triple ``slope`` perpendicular to the unit vector
    ``normal`` (one row of a clamp, fccgen.mechanism.cables)."""
    slope: str
    normal: str
    where: Where
    label: str | None = None
    type: str = "slope_normal"


@dataclass
class PointForce:
    """A force on a point (a cable node or any moving point), global frame: constant
    ``value``, or ``function`` "ex;ex;ex", its components as expressions of t."""
    point: str
    value: np.ndarray
    where: Where
    function: str = ""
    type: str = "point_force"
