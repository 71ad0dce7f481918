"""Write the model file of a planar scissor boom of N units deployed by torsion springs.

    python3 examples/make_scissor_boom.py               # N = 12 -> examples/scissor_boom.yaml
    python3 examples/make_scissor_boom.py 3             # N = 3  -> ./scissor_boom_3.yaml
    python3 examples/make_scissor_boom.py 3 three.yaml  # N = 3  -> three.yaml

The committed ``scissor_boom.yaml`` is this script's output for N = 12: running the
first command again must leave it unchanged. ``model_text(n, latch=False)`` gives the
boom without its latch (spherical pivots, no event): it swings between FOLDED and
2 FREE - FOLDED for ever.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from fccgen.example_models import size_arguments

LENGTH = 1.0          # m, every bar
MASS = 0.5            # kg, every bar, uniformly distributed
AXIAL = 1.0e-5        # kg m^2, a small axial inertia (no effect: bars turn about z)
FOLDED = 80.0         # deg, the bars' initial angle to the boom axis x
FREE = 50.0           # deg, the angle at which the springs are relaxed
LATCH = 30.0          # deg, full deployment: the bar angle at which pivot X0 latches
STIFFNESS = 20.0      # N m/rad, each crossing pivot's torsion spring
T_END = 4.0           # s

HEADER = """\
# A planar scissor boom of {n} units (lazy tongs) deployed by torsion springs, in space
# (no gravity). Units: kg, m, s. Written by examples/make_scissor_boom.py (do not edit by
# hand: run the script).
#
# Unit k has two bars of {length:g} m and {mass:g} kg crossing at their middles: a_k from
# the bottom node B_k to the top node T_(k+1), b_k from T_k to B_(k+1). The end nodes
# are shared points (hinges about z: every bar uses the fixed vector z); the crossing
# pivots X_k are spherical joints between a_k and b_k, hinges about z too since both
# bars stay in the plane. At the base, point_on_line joints to ground let T_0 and B_0
# slide on the line x = 0 and the first pivot X_0 on the line y = 0, which holds the
# boom symmetric about the x axis.
# The bars start at {folded:g} deg to x (folded: {width:.4g} m long) and a torsion spring
# of {k:g} N m/rad at every pivot, relaxed at {free:g} deg, deploys the boom; without
# damping it swings between {folded:g} and {swing:g} deg (2 x {free:g} - {folded:g}), away
# from the flat position (0 deg) where the mechanism is singular.
#
# Coordinates {nq}, constraint equations {ng}, rank {rank}: the nodes T, B, the pivots
# X and the base joints' points; 2 equations per bar, 3 per bar at its pivot, 5 per
# base joint, of which {redundant} are redundant
# (the z rows repeat what the bodies' fixed vector z already holds). Checked in
# tests/test_example_mechanisms.py: one degree of freedom by rank, energy conserved,
# the motion symmetric about x and the units equal.
# Degrees of freedom: 1
"""

LATCHED_HEADER = """\
# A planar scissor boom of {n} units (lazy tongs) deployed by torsion springs and
# latched at full length, in space (no gravity). Units: kg, m, s. Written by
# examples/make_scissor_boom.py (do not edit by hand: run the script).
#
# Unit k has two bars of {length:g} m and {mass:g} kg crossing at their middles: a_k from
# the bottom node B_k to the top node T_(k+1), b_k from T_k to B_(k+1). The end nodes
# are shared points (hinges about z: every bar uses the fixed vector z); the crossing
# pivots X_k are spherical joints between a_k and b_k, hinges about z too since both
# bars stay in the plane, except X0: a revolute about z, whose angle X0.angle the latch
# reads and locks. At the base, point_on_line joints to ground let T_0 and B_0 slide on
# the line x = 0 and the first pivot X_0 on the line y = 0, which holds the boom
# symmetric about the x axis.
# The bars start at {folded:g} deg to x (folded: {width:.4g} m long) and a torsion spring
# of {k:g} N m/rad at every pivot, relaxed at {free:g} deg, deploys the boom; unlatched and
# without damping it would swing between {folded:g} and {swing:g} deg (2 x {free:g} - {folded:g}).
#
# Full deployment is a bar angle of {latch:g} deg, X0.angle = 2 x ({folded:g} - {latch:g}) deg: the
# boom is then {full:.4g} m long, {ratio:.3g} times its folded length; it gets there on its
# first outward swing (which ends at {swing:g} deg) with {ke:.4g} J of its {e0:.4g} J still kinetic,
# so the latch takes a real shock; and it stays {latch:g} deg away from the flat position
# (0 deg) where the mechanism is singular. The lock event `latch` welds X0 there: a
# plastic impact (docs/events.md) that takes the boom from 1 to 0 DOF and all of its
# kinetic energy; the springs, pulling back towards {free:g} deg, keep the latch loaded.
# One lock latches every unit, since the boom has one degree of freedom; a lock on
# every pivot would add rows that repeat it.
#
# Coordinates {nq}, constraint equations {ng}, rank {rank}: the nodes T, B, the pivots
# X, the base joints' points and X0's axis vector; 2 equations per bar, 3 per bar at
# its pivot, 5 per base joint and 3 per bar at X0's axis, of which {redundant} are
# redundant (the z rows repeat what the bodies' fixed vector z already holds, and the
# axis on b0 what it is on a0). Checked in tests/test_example_mechanisms.py and
# tests/test_scissor_boom_latch.py: one degree of freedom by rank, energy conserved,
# the motion symmetric about x and the units equal before the latch; the latch's time
# and energy loss against the energy equation, 0 DOF after it, and the boom held at
# full length to the end.
# Degrees of freedom: 1
"""


def model_name(n: int) -> str:
    return "scissor_boom" if n == 12 else f"scissor_boom_{n}"


def _xy(x: float, y: float) -> str:
    return f"[{x!r}, {y!r}, 0]"


def spring_energy(n: int, angle: float) -> float:
    """The springs' energy (J) at the bar angle ``angle`` (deg): each pivot turns by
    2 (FOLDED - angle) from the start, so n k (2 (angle - FREE))^2 / 2 in radians."""
    return 2.0 * n * STIFFNESS * math.radians(angle - FREE) ** 2


def latch_angle() -> float:
    """X0.angle (rad) at full deployment: b turns by 2 (FOLDED - LATCH) relative to a."""
    return 2.0 * math.radians(FOLDED - LATCH)


def header(n: int, latch: bool) -> str:
    """The comment block that opens the model file of ``n`` units."""
    width = n * LENGTH * math.cos(math.radians(FOLDED))
    if not latch:
        return HEADER.format(n=n, length=LENGTH, mass=MASS, folded=FOLDED, free=FREE,
                             width=width, k=STIFFNESS, swing=2 * FREE - FOLDED,
                             nq=9 * n + 15, ng=10 * n + 15, rank=9 * n + 14,
                             redundant=n + 1)
    full = n * LENGTH * math.cos(math.radians(LATCH))
    return LATCHED_HEADER.format(
        n=n, length=LENGTH, mass=MASS, folded=FOLDED, free=FREE, width=width,
        k=STIFFNESS, swing=2 * FREE - FOLDED, latch=LATCH, full=full,
        ratio=full / width, ke=spring_energy(n, FOLDED) - spring_energy(n, LATCH),
        e0=spring_energy(n, FOLDED), nq=9 * n + 18, ng=10 * n + 21, rank=9 * n + 17,
        redundant=n + 4)


def model_text(n: int, *, latch: bool = True) -> str:
    """The YAML text of the scissor boom of ``n`` units, latched at full deployment
    (LATCH) by a lock event on the revolute pivot X0 unless ``latch`` is false."""
    if n < 1:
        raise ValueError(f"N must be at least 1 (got {n})")
    beta = math.radians(FOLDED)
    w, h = LENGTH * math.cos(beta), 0.5 * LENGTH * math.sin(beta)
    it = MASS * LENGTH ** 2 / 12.0
    free = 2.0 * math.radians(FOLDED - FREE)      # b turns by +2 delta relative to a
    out = [header(n, latch)]
    out += [f"name: {model_name(n)}", "gravity: [0, 0, 0]", "points:"]
    for k in range(n + 1):
        out.append(f"  T{k}: {_xy(k * w, h)}")
        out.append(f"  B{k}: {_xy(k * w, -h)}")
    out += ["vectors:", "  z: {along: [0, 0, 1], fixed: true}", "bodies:"]
    body = (f"vector: z, mass: {MASS:g}, center: [{LENGTH / 2:g}, 0, 0], "
            f"inertia: [{AXIAL:g}, {it!r}, {it!r}]")
    for k in range(n):
        out.append(f"  a{k}: {{points: [B{k}, T{k + 1}], {body}}}")
        out.append(f"  b{k}: {{points: [T{k}, B{k + 1}], {body}}}")
    out.append("joints:")
    for k in range(n):
        kind = "revolute" if latch and k == 0 else "spherical"
        axis = ", axis: [0, 0, 1]" if kind == "revolute" else ""
        out.append(f"  - {{name: X{k}, type: {kind}, bodies: [a{k}, b{k}], "
                   f"at: {_xy((k + 0.5) * w, 0.0)}{axis}}}")
    out += [f"  - {{name: base_top, type: point_on_line, bodies: [ground, b0], "
            f"at: {_xy(0.0, h)}, axis: [0, 1, 0]}}",
            f"  - {{name: base_bottom, type: point_on_line, bodies: [ground, a0], "
            f"at: {_xy(0.0, -h)}, axis: [0, 1, 0]}}",
            f"  - {{name: base_pivot, type: point_on_line, bodies: [ground, a0], "
            f"at: {_xy(0.5 * w, 0.0)}, axis: [1, 0, 0]}}", "loads:"]
    out += [f"  - {{type: torsion_spring, bodies: [a{k}, b{k}], axis: z, "
            f"stiffness: {STIFFNESS:g}, angle: {free!r}}}" for k in range(n)]
    if latch:
        out += ["events:", f"  - {{name: latch, when: \"X0.angle >= "
                f"{2 * (FOLDED - LATCH):g}*pi/180\", do: lock, joint: X0}}"]
    out.append(f"simulate: {{t_end: {T_END:g}, dt: 1.0e-3, output_dt: 0.01}}")
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    args = size_arguments(argv[1:], __doc__, 12, "N, the number of scissor units")
    n = args.n
    default = (Path(__file__).resolve().parent / "scissor_boom.yaml" if n == 12
               else Path(f"{model_name(n)}.yaml"))
    path = args.path if args.path is not None else default
    path.write_text(model_text(n))
    print(f"wrote {path} ({n} units)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
