"""The comparison's systems in Exudyn (its Python API), integrated as Exudyn usually is.

Every rod is a planar rigid body (``NodeRigidBody2D`` + ``ObjectRigidBody2D``: x, y and
the angle phi, 3 coordinates), every hinge a ``RevoluteJoint2D`` (2 algebraic equations
in index-3 form), the cart a ``MassPoint2D`` held on the x axis by a coordinate
constraint. Exudyn integrates the index-3 DAE with its implicit generalized-alpha
method (spectral radius 0.9, its default), solving each step's Newton system with its
sparse LU (``EigenSparse``, its pattern analysed once; relative Newton tolerance
1e-8, its default).

A02: rockers 0..N hinged to ground at A_i = (i, 0), couplers i hinged to the rockers at
B_i and B_(i+1): 2N + 1 bodies and 3N + 1 hinges (6N + 2 equations on 6N + 3
coordinates: 1 degree of freedom, no redundant equation in the plane). At the flat
position the Jacobian loses rank; Exudyn's sparse LU is told to go on through it
(``ignoreSingularJacobian``), as the chain passes it 20 times in the benchmark.
"""
from __future__ import annotations

import math

import exudyn as exu
import numpy as np
from exudyn.itemInterface import (CoordinateConstraint, MarkerBodyPosition,
                                  MarkerNodeCoordinate, MassPoint2D, NodePoint2D,
                                  NodePointGround, NodeRigidBody2D, ObjectGround, RevoluteJoint2D,
                                  RigidBody2D, SensorBody)

from systems import CART, FOUR_BAR


class ExudynModel:
    """One system in Exudyn: ``advance(n_steps)`` from the initial state each time (the
    solver restarts from the nodes' initial values), ``point()`` the tracked point's
    (x, y) at the end of the last run, ``history`` its sensor rows (t, x, y)."""

    def __init__(self, builder, n: int, dt: float, *, sensor_period: float | None = None,
                 spectral_radius: float = 0.9):
        self.sc = exu.SystemContainer()
        self.mbs = self.sc.AddSystem()
        self.dt = dt
        body, local = builder(self.mbs, n)
        self.sensor = self.mbs.AddSensor(SensorBody(
            bodyNumber=body, localPosition=local, storeInternal=True, writeToFile=False,
            outputVariableType=exu.OutputVariableType.Position))
        self.mbs.Assemble()
        ss = exu.SimulationSettings()
        ss.timeIntegration.generalizedAlpha.spectralRadius = spectral_radius
        ss.timeIntegration.verboseMode = 0
        ss.linearSolver.solverType = exu.LinearSolverType.EigenSparse
        ss.linearSolver.ignoreSingularJacobian = True
        ss.linearSolver.reuseAnalyzedPattern = True
        ss.solution.file.write = False
        ss.solution.sensors.writePeriod = sensor_period or 1e9
        ss.show.computationTime = False
        ss.show.statistics = False
        self.settings = ss

    def advance(self, n_steps: int) -> None:
        ti = self.settings.timeIntegration
        ti.numberOfSteps = n_steps
        ti.endTime = n_steps * self.dt
        if not exu.SolveDynamic(self.mbs, self.settings, showHints=False):
            raise RuntimeError("Exudyn: SolveDynamic did not converge")

    def point(self) -> np.ndarray:
        return np.asarray(self.history[-1, 1:3])

    @property
    def history(self) -> np.ndarray:
        return np.asarray(self.mbs.GetSensorStoredData(self.sensor))


def _rod(mbs, center, phi, velocity, omega, mass=1.0, length=1.0):
    """A uniform rod as a planar rigid body, its axis along the body's x, at angle phi."""
    node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[center[0], center[1], phi],
                                       initialVelocities=[velocity[0], velocity[1], omega]))
    return mbs.AddObject(RigidBody2D(mass=mass, inertia=mass * length ** 2 / 12.0,
                                     nodeNumber=node))


def _hinge(mbs, body1, local1, body2, local2):
    m1 = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body1, localPosition=local1))
    m2 = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body2, localPosition=local2))
    mbs.AddObject(RevoluteJoint2D(markerNumbers=[m1, m2]))


def build_a02(mbs, n: int):
    """The A02 chain of n loops; returns (body, local position) of B0."""
    L, h, v = FOUR_BAR.LENGTH, FOUR_BAR.LENGTH / 2, FOUR_BAR.SPEED
    ground = mbs.AddObject(ObjectGround())
    rockers, couplers = [], []
    for i in range(n + 1):
        # Rocker i turns about A_i at -v/L (B_i moves at +v along x); its centre at +v/2.
        body = _rod(mbs, (i, h), math.pi / 2, (v / 2, 0.0), -v / L, FOUR_BAR.MASS, L)
        _hinge(mbs, ground, [float(i), 0.0, 0.0], body, [-h, 0.0, 0.0])
        rockers.append(body)
    for i in range(n):
        body = _rod(mbs, (i + h, L), 0.0, (v, 0.0), 0.0, FOUR_BAR.MASS, L)
        _hinge(mbs, rockers[i], [h, 0.0, 0.0], body, [-h, 0.0, 0.0])
        _hinge(mbs, body, [h, 0.0, 0.0], rockers[i + 1], [h, 0.0, 0.0])
        couplers.append(body)
    _gravity(mbs, rockers + couplers, FOUR_BAR.MASS, FOUR_BAR.GRAVITY)
    return rockers[0], [h, 0.0, 0.0]


def build_cart(mbs, n: int):
    """The n-link pendulum on a cart; returns (body, local position) of the tip P_n."""
    L, h, v = CART.LENGTH, CART.LENGTH / 2, CART.SPEED
    s, c = math.sin(CART.TILT), math.cos(CART.TILT)
    ground = mbs.AddObject(ObjectGround())
    cart_node = mbs.AddNode(NodePoint2D(referenceCoordinates=[0.0, 0.0],
                                        initialVelocities=[v, 0.0]))
    cart = mbs.AddObject(MassPoint2D(mass=CART.CART_MASS, nodeNumber=cart_node))
    ground_node = mbs.AddNode(NodePointGround(referenceCoordinates=[0] * 3))
    mg = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))
    my = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=cart_node, coordinate=1))
    mbs.AddObject(CoordinateConstraint(markerNumbers=[mg, my]))
    phi = -math.pi / 2 + CART.TILT        # rod axis (body x) along (sin tilt, -cos tilt)
    prev, prev_local, rods = cart, [0.0, 0.0, 0.0], []
    for k in range(1, n + 1):
        center = ((k - 0.5) * L * s, -(k - 0.5) * L * c)
        body = _rod(mbs, center, phi, (v, 0.0), 0.0, CART.MASS, L)
        _hinge(mbs, prev, prev_local, body, [-h, 0.0, 0.0])
        prev, prev_local = body, [h, 0.0, 0.0]
        rods.append(body)
    _gravity(mbs, rods, CART.MASS, CART.GRAVITY)
    # The cart's weight is carried by the constraint y = 0; it does no work.
    return rods[-1], [h, 0.0, 0.0]


def _gravity(mbs, bodies, mass, g):
    from exudyn.itemInterface import Force
    for body in bodies:
        marker = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[0, 0, 0]))
        mbs.AddLoad(Force(markerNumber=marker, loadVector=[0.0, -mass * g, 0.0]))


BUILDERS = {"a02": build_a02, "cart": build_cart}


def make(system: str, n: int, dt: float, **options) -> ExudynModel:
    return ExudynModel(BUILDERS[system], n, dt, **options)
