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


Constraint = Union[PointOnLine, Distance]


@dataclass
class Force:
    body: str
    value: np.ndarray         # (3,) global frame
    at: tuple[float, float, float] | None   # body frame from point i; None: mass centre
    where: Where
    type: str = "force"


@dataclass
class Torque:
    body: str
    value: np.ndarray         # (3,) global frame
    where: Where
    type: str = "torque"


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


Load = Union[Force, Torque, Spring, TorsionSpring]


@dataclass
class AngularVelocity:
    value: np.ndarray         # (3,)
    frame: str                # "global" | "body"
    where: Where


@dataclass
class Initial:
    point_velocities: dict[str, np.ndarray] = field(default_factory=dict)
    body_angular_velocities: dict[str, AngularVelocity] = field(default_factory=dict)


@dataclass
class SimulateDefaults:
    t_end: float = 1.0
    dt: float = 1.0e-3
    method: str = "rk4"
    output_dt: float | None = None


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

    @property
    def moving_points(self) -> list[Point]:
        return [p for p in self.points.values() if not p.fixed]

    @property
    def moving_vectors(self) -> list[Vector]:
        return [v for v in self.vectors.values() if not v.fixed]
