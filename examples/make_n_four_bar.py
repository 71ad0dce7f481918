"""Write the model file of the IFToMM benchmark A02, "N four-bar mechanism", for any N.

    python3 examples/make_n_four_bar.py              # N = 40 -> examples/a02_n_four_bar.yaml
    python3 examples/make_n_four_bar.py 3            # N = 3  -> ./n_four_bar_3.yaml
    python3 examples/make_n_four_bar.py 3 three.yaml # N = 3  -> three.yaml

The committed ``a02_n_four_bar.yaml`` is this script's output for N = 40, so the file is
reproducible: running the first command again must leave it unchanged.
"""
from __future__ import annotations

import sys
from pathlib import Path

from fccgen.example_models import size_arguments

LENGTH = 1.0          # m, every bar
MASS = 1.0            # kg, every bar, uniformly distributed
GRAVITY = 9.81        # N/kg, along -y
SPEED = 1.0           # m/s, initial x-velocity of B0 (and of every B_i: a parallelogram)
AXIAL = 1.0e-6        # kg m^2, a tiny axial inertia: no effect (every bar turns about z)

HEADER = """\
# IFToMM multibody benchmark problem A02, "N four-bar mechanism", N = {n}: {n} four-bar
# loops in a row, {bars} bars of {length:g} m and {mass:g} kg (uniformly distributed mass),
# gravity {gravity} N/kg along -y, 20 s. Units: kg, m, s.
# Written by examples/make_n_four_bar.py (do not edit by hand: run the script).
# Reference solution: tests/reference/mbsbenchmark_A02_solution_data_B0.csv (position of
# B0 every 0.05 s for 20 s; see tests/reference/SOURCES.md).
#
# Ground points A0..A{n} at x = 0, 1, ..., {n}, y = 0 (fixed); moving points B0..B{n}
# start at (i, 1). Bars: {rockers} vertical "rockers" A_i-B_i and {n} horizontal
# "couplers" B_i-B_(i+1). Each bar is a slender uniform rod: central inertia m L^2 / 12
# = {it:.6g} about its transverse axes, and a tiny axial inertia ({axial:g}) that
# has no effect, since every bar turns about z only.
# Initial state: every B_i moves at {speed:g} m/s along +x (the chain moves as a
# parallelogram; the reference data start at B0 = (0, 1) with dx/dt = 1 m/s).
#
# FCC model: every bar uses the fixed vector z, so every joint is a planar hinge about z.
# Coordinates {nq} (B0..B{n}), constraint equations {ng} ({bars} lengths, {bars}
# "perpendicular to z"), rank {rank}: the {n} couplers' "perpendicular to z" equations are
# redundant (each follows from the rockers' at its two ends).
# When the bars are all horizontal (collinear, on y = 0) the Jacobian loses {n} more
# ranks: the mechanism passes through that singular position twice per turn.
# Degrees of freedom: 1
"""


def model_name(n: int) -> str:
    """``a02_n_four_bar`` for the benchmark's N = 40, ``n_four_bar_<N>`` otherwise."""
    return "a02_n_four_bar" if n == 40 else f"n_four_bar_{n}"


def model_text(n: int) -> str:
    """The YAML text of the N-four-bar model."""
    if n < 1:
        raise ValueError(f"N must be at least 1 (got {n})")
    it = MASS * LENGTH ** 2 / 12.0
    out = [HEADER.format(n=n, bars=2 * n + 1, rockers=n + 1, length=LENGTH, mass=MASS,
                         gravity=GRAVITY, it=it, axial=AXIAL, speed=SPEED,
                         nq=3 * (n + 1), ng=2 * (2 * n + 1), rank=3 * (n + 1) - 1)]
    out.append(f"name: {model_name(n)}")
    out.append(f"gravity: [0, {-GRAVITY}, 0]")
    out.append("points:")
    out += [f"  A{i}: {{at: [{i}, 0, 0], fixed: true}}" for i in range(n + 1)]
    out += [f"  B{i}: [{i}, {LENGTH:g}, 0]" for i in range(n + 1)]
    out.append("vectors:")
    out.append("  z: {along: [0, 0, 1], fixed: true}")
    out.append("bodies:")
    inertia = f"[{AXIAL:g}, {it!r}, {it!r}]"
    center = f"[{LENGTH / 2:g}, 0, 0]"
    for i in range(n + 1):
        out.append(f"  rocker{i}: {{points: [A{i}, B{i}], vector: z, mass: {MASS:g}, "
                   f"center: {center}, inertia: {inertia}}}")
    for i in range(n):
        out.append(f"  coupler{i}: {{points: [B{i}, B{i + 1}], vector: z, mass: {MASS:g}, "
                   f"center: {center}, inertia: {inertia}}}")
    out.append("initial:")
    out.append("  points:")
    out += [f"    B{i}: [{SPEED:g}, 0, 0]" for i in range(n + 1)]
    out.append("simulate: {t_end: 20.0, dt: 1.0e-3, output_dt: 0.05}")
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    args = size_arguments(argv, __doc__, 40, "N, the number of four-bar loops")
    n = args.n
    if args.path is not None:
        path = args.path
    elif n == 40:
        path = Path(__file__).resolve().parent / "a02_n_four_bar.yaml"
    else:
        path = Path(f"{model_name(n)}.yaml")
    path.write_text(model_text(n))
    print(f"{path}: N = {n}, {2 * n + 1} bars, {3 * (n + 1)} coordinates")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
