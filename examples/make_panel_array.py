"""Write the model file of an accordion solar array of N hinged panels on a bus.

    python3 examples/make_panel_array.py 300                  # panel_array_300.yaml
    python3 examples/make_panel_array.py 3 three.yaml         # N = 3 -> three.yaml

The array of examples/solar_array.yaml carried on to N panels: stowed, the panels stand
folded against each other (each 0.05 m further out along x), joined by revolute hinges
at alternating top and bottom edges (z = +0.5 and -0.5 m, axes -y and +y). A torsion
spring at every hinge, relaxed at SPRING_ANGLE rad, unfolds the array; the bus is free
in space (no gravity) and takes the reaction of the deployment. Every hinge is a joint,
so every hinge's reaction force and torque is a column of the results: the model sizes
the reactions' cost (docs/performance.md).
"""
from __future__ import annotations

import sys
from pathlib import Path

from fccgen.example_models import size_arguments

PANEL_MASS = 10.0          # kg
PANEL_INERTIA = (1.667, 0.834, 0.834)   # kg m^2 about the centre, body frame
BUS_MASS = 200.0           # kg
BUS_INERTIA = 33.3         # kg m^2
STIFFNESS = 4.0            # N m / rad, every hinge
SPRING_ANGLE = 2.0         # rad, where each hinge's spring is relaxed
PITCH = 0.05               # m along x between stowed panels
T_END = 3.0                # s


def model_name(n: int) -> str:
    return f"panel_array_{n}"


def model_text(n: int) -> str:
    if n < 1:
        raise ValueError(f"the array needs at least one panel, got {n}")
    out = [f"# An accordion solar array of {n} panels on a free bus, unfolded by a "
           "torsion spring at every", "# hinge. Units: kg, m, s. Written by "
           "examples/make_panel_array.py (do not edit by hand: run the script).",
           f"name: {model_name(n)}", "bodies:",
           f"  bus: {{mass: {BUS_MASS:g}, center: [0, 0, 0], "
           f"inertia: [{BUS_INERTIA:g}, {BUS_INERTIA:g}, {BUS_INERTIA:g}]}}"]
    inertia = ", ".join(f"{x:g}" for x in PANEL_INERTIA)
    for k in range(1, n + 1):
        out.append(f"  panel{k}: {{mass: {PANEL_MASS:g}, center: [{_x(k):.4f}, 0, 0], "
                   f"inertia: [{inertia}]}}")
    out.append("joints:")
    for k in range(1, n + 1):
        first = "bus" if k == 1 else f"panel{k - 1}"
        z, axis = (0.5, -1) if k % 2 else (-0.5, 1)
        out.append(f"  - {{name: H{k}, type: revolute, bodies: [{first}, panel{k}], "
                   f"at: [{_x(k):.4f}, 0, {z:g}], axis: [0, {axis}, 0]}}")
    out.append("loads:")
    out += [f"  - {{type: torsion_spring, joint: H{k}, stiffness: {STIFFNESS:g}, "
            f"angle: {SPRING_ANGLE:g}, damping: 0.0}}" for k in range(1, n + 1)]
    out.append(f"simulate: {{t_end: {T_END:g}, dt: 1.0e-3, method: rk4}}")
    return "\n".join(out) + "\n"


def _x(k: int) -> float:
    """x of panel k's centre (and of its hinge to the body before it)."""
    return 0.55 + PITCH * (k - 1)


def main(argv: list[str]) -> int:
    args = size_arguments(argv[1:], __doc__, 10, "N, the number of panels")
    n = args.n
    path = args.path if args.path is not None else Path(f"{model_name(n)}.yaml")
    path.write_text(model_text(n), encoding="utf-8")
    print(f"wrote {path} ({n} panels, {n} hinges)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
