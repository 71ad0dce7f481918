"""Write the model file of a triangular scissor mast of N bays deployed by torsion springs.

    python3 examples/make_scissor_mast.py 167           # 1002 bars: scissor_mast_167.yaml
    python3 examples/make_scissor_mast.py 3 three.yaml  # N = 3 -> three.yaml

A deployable mast of triangular cross-section, as built for booms and antenna masts:
three longerons' worth of corner hubs (columns A, B, C), joined on each of the three
faces by a scissor (pantograph) chain. Bay k of face XY (XY = AB, BC, CA) has two bars
of LENGTH crossing at their middles: a from hub X_k to hub Y_(k+1), b from Y_k to
X_(k+1). Every hub joins four bars (two per face, two at the ends of the mast); each
face's bars turn about the face's normal, so the hubs are hinges about the two normals
of their faces (shared points, the bars' fixed vector the face normal: the hubs
translate without turning, as they do in the mast's deployment). The crossing pivots
are spherical joints between the two bars of a bay, hinges about the normal since both
bars stay in their face. At the base the three hubs A_0, B_0, C_0 slide in radial
guides (point_on_line joints to ground along their column's radial direction in z = 0),
which holds the mast centred on the z axis.

Deploying, each bar turns from FOLDED deg to the mast axis z towards FREE: the bays
grow (height LENGTH cos(phi)) while the section shrinks (side LENGTH sin(phi)). A
torsion spring at every pivot, relaxed at FREE deg, drives it; without damping it swings
between FOLDED and 2 FREE - FOLDED deg, away from the flat position (90 deg).

Degrees of freedom: 1. The face planes keep their normals, so the hubs of each column
stay on one vertical line; equal bays on the three faces then need one angle phi for
all bars. Free in space the mast would add its 3 translations, which the guides remove
(6 equations, 3 of them redundant). N bays give 6 N bars.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from fccgen.example_models import size_arguments

LENGTH = 1.0          # m, every bar
MASS = 0.5            # kg, every bar, uniformly distributed
AXIAL = 1.0e-5        # kg m^2, a small axial inertia
FOLDED = 80.0         # deg, the bars' initial angle to the mast axis z
FREE = 50.0           # deg, the angle at which the springs are relaxed
STIFFNESS = 20.0      # N m/rad, each crossing pivot's torsion spring
T_END = 2.0           # s
COLUMNS = "ABC"
FACES = (("A", "B"), ("B", "C"), ("C", "A"))

HEADER = """\
# A triangular scissor mast of {n} bays ({bars} bars) deployed by torsion springs, in
# space (no gravity). Units: kg, m, s. Written by examples/make_scissor_mast.py (do not
# edit by hand: run the script, whose docstring describes the structure).
#
# Hubs A_k, B_k, C_k (k = 0..{n}) at the corners of the section; each face XY has per
# bay two bars of {length:g} m and {mass:g} kg crossing at a spherical pivot, hinged at
# the hubs about the face normal n_XY (the bars' fixed vector); the base hubs slide in
# radial guides. The bars start at {folded:g} deg to the mast axis (section side
# {side:.4g} m, height {height:.4g} m); a torsion spring of {k:g} N m/rad at every pivot,
# relaxed at {free:g} deg, deploys the mast.
# Degrees of freedom: 1
"""


def model_name(n: int) -> str:
    return f"scissor_mast_{n}"


def _vec(v) -> str:
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def geometry(n: int, phi_deg: float = FOLDED):
    """(hubs, normals, pivots, radial) at bar angle phi_deg to z: hub name -> position,
    face name -> unit normal (z x the face's edge direction), (face, k) -> pivot
    position, column -> its radial direction (x, y)."""
    phi = math.radians(phi_deg)
    side, height = LENGTH * math.sin(phi), LENGTH * math.cos(phi)
    radius = side / math.sqrt(3.0)
    angles = {c: math.radians(90 + 120 * i) for i, c in enumerate(COLUMNS)}
    radial = {c: (math.cos(a), math.sin(a)) for c, a in angles.items()}
    hubs = {f"{c}{k}": (radius * radial[c][0], radius * radial[c][1], k * height)
            for c in COLUMNS for k in range(n + 1)}
    normals, pivots = {}, {}
    for x, y in FACES:
        ex, ey = radial[y][0] - radial[x][0], radial[y][1] - radial[x][1]
        norm = math.hypot(ex, ey)
        normals[x + y] = (-ey / norm, ex / norm, 0.0)          # z x (edge direction)
        for k in range(n):
            mid = [(hubs[f"{x}0"][i] + hubs[f"{y}0"][i]) / 2 for i in range(2)]
            pivots[(x + y, k)] = (mid[0], mid[1], (k + 0.5) * height)
    return hubs, normals, pivots, radial


def model_text(n: int) -> str:
    """The YAML text of the scissor mast of ``n`` bays (6 n bars)."""
    if n < 1:
        raise ValueError(f"N must be at least 1 (got {n})")
    hubs, normals, pivots, radial = geometry(n)
    it = MASS * LENGTH ** 2 / 12.0
    free = 2.0 * math.radians(FOLDED - FREE)      # b turns by +2 delta relative to a
    phi = math.radians(FOLDED)
    out = [HEADER.format(n=n, bars=6 * n, length=LENGTH, mass=MASS, folded=FOLDED,
                         side=LENGTH * math.sin(phi), height=n * LENGTH * math.cos(phi),
                         k=STIFFNESS, free=FREE)]
    out += [f"name: {model_name(n)}", "gravity: [0, 0, 0]", "points:"]
    out += [f"  {name}: {_vec(at)}" for name, at in hubs.items()]
    out.append("vectors:")
    out += [f"  n{face}: {{along: {_vec(v)}, fixed: true}}" for face, v in normals.items()]
    out.append("bodies:")
    body = (f"mass: {MASS:g}, center: [{LENGTH / 2:g}, 0, 0], "
            f"inertia: [{AXIAL:g}, {it!r}, {it!r}]")
    for x, y in FACES:
        for k in range(n):
            out.append(f"  {x}{y}a{k}: {{points: [{x}{k}, {y}{k + 1}], vector: n{x}{y}, "
                       f"{body}}}")
            out.append(f"  {x}{y}b{k}: {{points: [{y}{k}, {x}{k + 1}], vector: n{x}{y}, "
                       f"{body}}}")
    out.append("joints:")
    for x, y in FACES:
        out += [f"  - {{name: X{x}{y}{k}, type: spherical, "
                f"bodies: [{x}{y}a{k}, {x}{y}b{k}], at: {_vec(pivots[(x + y, k)])}}}"
                for k in range(n)]
    for x, y in FACES:                                 # hub x_0 starts bar a_0 of face xy
        out.append(f"  - {{name: base_{x}, type: point_on_line, "
                   f"bodies: [ground, {x}{y}a0], at: {_vec(hubs[f'{x}0'])}, "
                   f"axis: {_vec((*radial[x], 0.0))}}}")
    out.append("loads:")
    for x, y in FACES:
        out += [f"  - {{type: torsion_spring, bodies: [{x}{y}a{k}, {x}{y}b{k}], "
                f"axis: n{x}{y}, stiffness: {STIFFNESS:g}, angle: {free!r}}}"
                for k in range(n)]
    out.append(f"simulate: {{t_end: {T_END:g}, dt: 1.0e-3, output_dt: 0.01}}")
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    args = size_arguments(argv[1:], __doc__, 4, "N, the number of bays")
    n = args.n
    path = args.path if args.path is not None else Path(f"{model_name(n)}.yaml")
    path.write_text(model_text(n))
    print(f"wrote {path} ({n} bays, {6 * n} bars)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
