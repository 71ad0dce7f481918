"""Write tests/data/exudyn_flexible_pendulum.csv: the tip of the flexible pendulum of
examples/flexible_pendulum.yaml computed by Exudyn (the test data of
tests/test_cables_dynamics.py; Exudyn is needed only to rerun this script).

The same member in Exudyn: ELEMENTS ObjectANCFCable2D elements (Exudyn's planar ANCF
cable, axial strain |r'| - 1 and its own curvature measure) on NodePoint2DSlope1
nodes laid along the x axis, the first node's position held by two
CoordinateConstraints (the pin at O), gravity as a LoadMassProportional on every
element. Integrated by Exudyn's implicit generalized-alpha solver with spectral
radius 1 (no numerical damping) and steps of STEP over T_END; the tip position is
written every OUTPUT. The mesh is finer than the example's so that the data are
converged to well below the tolerance of the test (measured: 64 and 128 elements
differ by the figure printed at the end).

    PYTHONPATH=. python tests/data/make_exudyn_flexible_pendulum.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

import exudyn as exu
from exudyn.itemInterface import (CoordinateConstraint, LoadMassProportional,
                                  MarkerBodyMass, MarkerNodeCoordinate, NodePoint2DSlope1,
                                  NodePointGround, ObjectANCFCable2D, ObjectGround)

HERE = Path(__file__).resolve().parent
MODEL = HERE.parent.parent / "examples" / "flexible_pendulum.yaml"
OUT = HERE / "exudyn_flexible_pendulum.csv"
ELEMENTS = 128
STEP = 1e-5
T_END = 1.0
OUTPUT = 0.01


def tip_track(member: dict, gravity, elements: int, step: float):
    """(t, tip x, tip y) of the pendulum in Exudyn with ``elements`` elements."""
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    length = float(member["to"][0])
    h = length / elements
    mbs.AddObject(ObjectGround())
    ground = mbs.AddNode(NodePointGround(referenceCoordinates=[0, 0, 0]))
    nodes = [mbs.AddNode(NodePoint2DSlope1(referenceCoordinates=[k * h, 0, 1, 0]))
             for k in range(elements + 1)]
    for k in range(elements):
        cable = mbs.AddObject(ObjectANCFCable2D(
            length=h, massPerLength=float(member["mass_per_length"]),
            bendingStiffness=float(member["EI"]), axialStiffness=float(member["EA"]),
            nodeNumbers=[nodes[k], nodes[k + 1]]))
        mass = mbs.AddMarker(MarkerBodyMass(bodyNumber=cable))
        mbs.AddLoad(LoadMassProportional(markerNumber=mass,
                                         loadVector=[float(g) for g in gravity]))
    m_ground = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=ground, coordinate=0))
    for c in (0, 1):
        m = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes[0], coordinate=c))
        mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground, m]))
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.timeIntegration.numberOfSteps = int(round(T_END / step))
    settings.timeIntegration.endTime = T_END
    settings.timeIntegration.generalizedAlpha.spectralRadius = 1.0
    settings.timeIntegration.verboseMode = 0
    settings.solutionSettings.writeSolutionToFile = False
    settings.timeIntegration.newton.relativeTolerance = 1e-10
    settings.timeIntegration.newton.absoluteTolerance = 1e-12
    samples = []
    every = int(round(OUTPUT / step))

    def record(mbs_, t):
        k = int(round(t / step))
        if k % every == 0:
            x, y = mbs_.GetNodeOutput(nodes[-1], exu.OutputVariableType.Position)[:2]
            samples.append((t, x, y))
        return True
    mbs.SetPreStepUserFunction(record)
    mbs.SolveDynamic(settings)
    x, y = mbs.GetNodeOutput(nodes[-1], exu.OutputVariableType.Position)[:2]
    samples.append((T_END, x, y))
    out = {}
    for t, x, y in samples:                   # one row per output time
        out[round(t / OUTPUT)] = (round(t / OUTPUT) * OUTPUT, x, y)
    return np.array([out[k] for k in sorted(out)])


def main():
    model = yaml.safe_load(MODEL.read_text())
    member = model["cables"]["rod"]
    track = tip_track(member, model["gravity"], ELEMENTS, STEP)
    coarse = tip_track(member, model["gravity"], ELEMENTS // 2, STEP)
    change = float(np.max(np.abs(track[:, 1:] - coarse[:, 1:])))
    with open(OUT, "w", encoding="utf-8") as out:
        out.write(f"# Exudyn {exu.__version__} ObjectANCFCable2D x {ELEMENTS}, "
                  f"generalized-alpha rho = 1, step {STEP:g}; {MODEL.name}; written by "
                  f"{Path(__file__).name}; {ELEMENTS // 2} elements differ by at most "
                  f"{change:.3g} m\n")
        out.write("t,tip_x,tip_y\n")
        for t, x, y in track:
            out.write(f"{t:.6g},{x:.17g},{y:.17g}\n")
    print(f"{len(track)} rows; {ELEMENTS // 2} vs {ELEMENTS} elements: {change:.3g} m")


if __name__ == "__main__":
    main()
