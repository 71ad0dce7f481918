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

Scissor boom of n units: bars a_k and b_k are planar rigid bodies (uniform bars, 2n
bodies, 6n coordinates); every end node shared by two bars a ``RevoluteJoint2D``,
every crossing pivot X_k a ``RevoluteJoint2D`` between the bars' middles; at the base
T_0 and B_0 slide on the line x = 0 and X_0 on y = 0, each a ``PrismaticJoint2D`` to
ground that leaves the rotation free (one equation: the point's distance from the
line). 6n - 1 equations on 6n coordinates, no redundant one (fccgen's model has n + 1
redundant z rows, which the plane leaves out). The torsion spring of pivot X_k is a
``CoordinateSpringDamper`` on the two bars' angle coordinates (see ``build_boom``).
"""
from __future__ import annotations

import math

import exudyn as exu
import numpy as np
from exudyn.itemInterface import (CoordinateConstraint, CoordinateSpringDamper,
                                  MarkerBodyPosition, MarkerBodyRigid, MarkerNodeCoordinate,
                                  MassPoint2D, NodePoint2D, NodePointGround, NodeRigidBody2D,
                                  ObjectGround, PrismaticJoint2D, RevoluteJoint2D, RigidBody2D,
                                  SensorBody)

from systems import BOOM, CART, FOUR_BAR


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


def _on_line(mbs, ground, point, body, local, normal):
    """The body's point ``local`` kept on the line through ``point`` (on ground) whose
    unit normal is ``normal`` (global): (p_ground - p_body) . normal = 0, the rotation
    left free."""
    m_body = mbs.AddMarker(MarkerBodyRigid(bodyNumber=body, localPosition=local))
    m_ground = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=point))
    # Exudyn's normal is in the second marker's frame: ground's, so it stays global.
    mbs.AddObject(PrismaticJoint2D(markerNumbers=[m_body, m_ground], normalMarker1=normal,
                                   constrainRotation=False))


def build_boom(mbs, n: int):
    """The unlatched scissor boom of n units, at rest at its folded angle, no gravity;
    returns (body, local position) of the tip node T_n (the far end of bar a_(n-1)).

    Bar a_k runs from B_k to T_(k+1) at the angle +beta to x, b_k from T_k to B_(k+1)
    at -beta (beta = FOLDED), both centred on the pivot X_k = ((k + 1/2) w, 0), each
    along its body's x axis. fccgen's torsion spring at X_k turns b_k relative to a_k:
    theta = (phi_b - phi_a) - (phi_b - phi_a)(0), torque k (theta - free) with
    free = 2 (FOLDED - FREE): the potential k/2 (theta - free)^2. Exudyn's coordinate
    spring is k/2 (q_1 - q_0 - offset)^2 on node coordinates, which are displacements
    from the reference (the initial angles here): q_0 = phi_a - phi_a(0),
    q_1 = phi_b - phi_b(0), so q_1 - q_0 = theta and offset = free."""
    L, h, m = BOOM.LENGTH, BOOM.LENGTH / 2, BOOM.MASS
    beta = math.radians(BOOM.FOLDED)
    w = L * math.cos(beta)
    free = 2.0 * math.radians(BOOM.FOLDED - BOOM.FREE)
    ground = mbs.AddObject(ObjectGround())
    a, b = [], []
    for k in range(n):
        center = ((k + 0.5) * w, 0.0)
        a.append(_rod(mbs, center, beta, (0.0, 0.0), 0.0, m, L))
        b.append(_rod(mbs, center, -beta, (0.0, 0.0), 0.0, m, L))
        _hinge(mbs, a[k], [0.0, 0.0, 0.0], b[k], [0.0, 0.0, 0.0])          # X_k
        angle_a = mbs.AddMarker(MarkerNodeCoordinate(
            nodeNumber=mbs.GetObject(a[k])["nodeNumber"], coordinate=2))
        angle_b = mbs.AddMarker(MarkerNodeCoordinate(
            nodeNumber=mbs.GetObject(b[k])["nodeNumber"], coordinate=2))
        mbs.AddObject(CoordinateSpringDamper(markerNumbers=[angle_a, angle_b],
                                             stiffness=BOOM.STIFFNESS, damping=0.0,
                                             offset=free))
    for k in range(1, n):
        _hinge(mbs, a[k - 1], [h, 0.0, 0.0], b[k], [-h, 0.0, 0.0])        # T_k
        _hinge(mbs, b[k - 1], [h, 0.0, 0.0], a[k], [-h, 0.0, 0.0])        # B_k
    _on_line(mbs, ground, [0.0, 0.0, 0.0], b[0], [-h, 0.0, 0.0], [1.0, 0.0, 0.0])  # T_0
    _on_line(mbs, ground, [0.0, 0.0, 0.0], a[0], [-h, 0.0, 0.0], [1.0, 0.0, 0.0])  # B_0
    _on_line(mbs, ground, [0.0, 0.0, 0.0], a[0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])  # X_0
    return a[-1], [h, 0.0, 0.0]


def _gravity(mbs, bodies, mass, g):
    from exudyn.itemInterface import Force
    for body in bodies:
        marker = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[0, 0, 0]))
        mbs.AddLoad(Force(markerNumber=marker, loadVector=[0.0, -mass * g, 0.0]))


BUILDERS = {"a02": build_a02, "cart": build_cart, "boom": build_boom}


def make(system: str, n: int, dt: float, **options) -> ExudynModel:
    return ExudynModel(BUILDERS[system], n, dt, **options)
