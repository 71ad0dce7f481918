"""Write tests/data/exudyn_modes_spatial_bars_springs.csv: the natural frequencies
Exudyn computes for tests/data/spatial_bars_springs.yaml (the test data of
tests/test_modes.py; Exudyn is needed only to rerun this script).

The same model in Exudyn: each bar an ObjectRigidBody on a Tait-Bryan-angle node
whose frame is the global frame at rest (angles 0, far from their singularity), with
the mass and the central inertia of the model file turned into that frame (R J R^T,
R = [e1 e2 e3] the model's body frame); ball joints (ObjectJointSpherical) at O and
between the bars; the four springs as ObjectConnectorSpringDamper between the fixed
points and the bars. The rest state is the equilibrium (springs at their free length,
no gravity), so ComputeODE2Eigenvalues linearizes about it: the stiffness and mass
matrices of the node coordinates, projected onto the null space of the constraint
Jacobian (by an SVD), then scipy's symmetric eigensolver. Frequencies
sqrt(|omega^2|) / (2 pi), ascending.

Exudyn's stiffness here is the derivative of the applied forces only; the derivative
of the joint forces C_q^T lambda is left out. That term vanishes at this rest state
(lambda = 0), which is why the model has no gravity: for these bars hanging under
gravity, with the joint reactions of that state in its initial state, Exudyn 1.13.6
gives every frequency 0 while fccgen gives the pendulum's.

    PYTHONPATH=. python tests/data/make_exudyn_modes.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

import exudyn as exu
from exudyn.utilities import (MarkerBodyPosition, MarkerBodyRigid, NodeRigidBodyRxyz,
                              ObjectConnectorSpringDamper, ObjectGround,
                              ObjectJointSpherical, ObjectRigidBody, RigidBodyInertia)

HERE = Path(__file__).resolve().parent
MODEL = HERE / "spatial_bars_springs.yaml"
OUT = HERE / "exudyn_modes_spatial_bars_springs.csv"


def body_frame(a, b, u):
    """Columns e1 (a to b), e2 (u), e3 = e1 x e2: the model file's body frame."""
    e1 = (b - a) / np.linalg.norm(b - a)
    e2 = u / np.linalg.norm(u)
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def build(mbs, model):
    """The bodies, joints and springs of the model file; returns nothing."""
    pts = {k: np.array(v["at"] if isinstance(v, dict) else v, float)
           for k, v in model["points"].items()}
    vecs = {k: np.array(v, float) for k, v in model["vectors"].items()}
    ground = mbs.AddObject(ObjectGround())
    previous = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=[0, 0, 0]))
    on_body = {}                     # point name -> (body, centre) of the last bar on it
    for body in model["bodies"].values():
        a, b = (pts[p] for p in body["points"])
        R = body_frame(a, b, vecs[body["vector"]])
        center = a + R @ np.array(body["center"], float)
        inertia = RigidBodyInertia(mass=body["mass"],
                                   inertiaTensor=R @ np.diag(body["inertia"]) @ R.T,
                                   com=[0, 0, 0])
        node = mbs.AddNode(NodeRigidBodyRxyz(referenceCoordinates=list(center) + [0] * 3))
        obj = mbs.AddObject(ObjectRigidBody(mass=inertia.mass,
                                            inertia=inertia.GetInertia6D(),
                                            nodeNumber=node))
        here = mbs.AddMarker(MarkerBodyRigid(bodyNumber=obj,
                                             localPosition=list(a - center)))
        mbs.AddObject(ObjectJointSpherical(markerNumbers=[previous, here]))
        previous = mbs.AddMarker(MarkerBodyRigid(bodyNumber=obj,
                                                 localPosition=list(b - center)))
        on_body[body["points"][1]] = (obj, center)
    for load in model["loads"]:
        fixed, moving = load["ends"]
        obj, center = on_body[moving]
        m0 = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground,
                                              localPosition=list(pts[fixed])))
        m1 = mbs.AddMarker(MarkerBodyPosition(bodyNumber=obj,
                                              localPosition=list(pts[moving] - center)))
        mbs.AddObject(ObjectConnectorSpringDamper(markerNumbers=[m0, m1],
                                                  referenceLength=load["length"],
                                                  stiffness=load["stiffness"], damping=0))


def frequencies(model) -> np.ndarray:
    """Exudyn's natural frequencies (Hz) about the rest state, ascending."""
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    build(mbs, model)
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.linearSolver.solverType = exu.LinearSolverType.EXUdense
    omega2, _ = mbs.ComputeODE2Eigenvalues(settings, useAbsoluteValues=True)
    return np.sqrt(np.sort(np.abs(omega2))) / (2 * np.pi)


def main():
    model = yaml.safe_load(MODEL.read_text())
    f = frequencies(model)
    with open(OUT, "w", encoding="utf-8") as out:
        out.write(f"# Exudyn {exu.__version__} ComputeODE2Eigenvalues, {MODEL.name}; "
                  f"written by {Path(__file__).name}\n")
        out.write("mode,frequency_hz\n")
        for k, value in enumerate(f, 1):
            out.write(f"{k},{value:.17g}\n")
    print(OUT.read_text())


if __name__ == "__main__":
    main()
