"""Write the model file of an n-link pendulum on a cart, for any n.

    python3 examples/make_pendulum_on_cart.py              # n = 2 -> ./pendulum_on_cart_2.yaml
    python3 examples/make_pendulum_on_cart.py 50           # n = 50 -> ./pendulum_on_cart_50.yaml
    python3 examples/make_pendulum_on_cart.py 50 p50.yaml  # n = 50 -> p50.yaml

A cart of 1 kg slides without friction along the x axis; a chain of n uniform rods
(1 m, 1 kg each) hangs from it, hinged about z at the cart and at every joint between
rods. Gravity 9.81 N/kg along -y. The chain starts straight, tilted by 30 degrees from
the downward vertical, and everything (cart and chain) moves at 1 m/s along +x. The
same system is modelled in MuJoCo and Exudyn by ``benchmarks/peers/`` for the
comparison of time per step with n.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from fccgen.example_models import size_arguments

LENGTH = 1.0          # m, every rod
MASS = 1.0            # kg, every rod, uniformly distributed
CART_MASS = 1.0       # kg
CART_LENGTH = 1.0     # m, distance C-D of the cart's two points (both on the x axis)
GRAVITY = 9.81        # N/kg, along -y
TILT = math.radians(30.0)   # initial angle of the straight chain from the downward vertical
SPEED = 1.0           # m/s, initial x-velocity of the cart and of every rod (a translation)
AXIAL = 1.0e-6        # kg m^2, a tiny axial inertia: no effect (every rod turns about z)
CART_INERTIA = 1.0e-3  # kg m^2, central inertia of the cart: no effect (it cannot turn)

HEADER = """\
# {n}-link pendulum on a cart: a cart of {cart:g} kg sliding without friction along x,
# and a chain of {n} uniform rods of {length:g} m and {mass:g} kg hinged about z, gravity
# {gravity} N/kg along -y. Units: kg, m, s.
# Written by examples/make_pendulum_on_cart.py (do not edit by hand: run the script).
#
# Points: C (the cart's hinge, on the x axis) and D (a second cart point {cl:g} m further
# along x), P1..P{n} (the rods' far ends, P0 = C). The chain starts straight at {tilt:g}
# degrees from the downward vertical; cart and chain move at {speed:g} m/s along +x.
# The cart stays on the x axis and cannot turn: C on the planes y = 0 and z = 0, D on the
# plane y = 0 (its z follows from the cart's "perpendicular to z" equation).
# Each rod is a slender uniform rod: central inertia m L^2 / 12 = {it:.6g} about its
# transverse axes and a tiny axial inertia ({axial:g}) that has no effect.
#
# FCC model: every body uses the fixed vector z. Coordinates {nq} (C, D, P1..P{n}),
# constraint equations {ng} (cart: length, "perpendicular to z", 3 plane equations; each
# rod: length, "perpendicular to z"), none redundant.
# Degrees of freedom: {dof}
"""


def model_name(n: int) -> str:
    return f"pendulum_on_cart_{n}"


def tip_positions(n: int) -> list[tuple[float, float]]:
    """Initial (x, y) of P0 = C, P1, ..., Pn: the straight chain tilted by TILT."""
    s, c = math.sin(TILT), math.cos(TILT)
    return [(k * LENGTH * s, -k * LENGTH * c) for k in range(n + 1)]


def model_text(n: int) -> str:
    """The YAML text of the n-link pendulum on a cart."""
    if n < 1:
        raise ValueError(f"n must be at least 1 (got {n})")
    it = MASS * LENGTH ** 2 / 12.0
    out = [HEADER.format(n=n, cart=CART_MASS, length=LENGTH, mass=MASS, gravity=GRAVITY,
                         cl=CART_LENGTH, tilt=math.degrees(TILT), speed=SPEED, it=it,
                         axial=AXIAL, nq=3 * (n + 2), ng=5 + 2 * n, dof=n + 1)]
    out.append(f"name: {model_name(n)}")
    out.append(f"gravity: [0, {-GRAVITY}, 0]")
    out.append("points:")
    out.append("  O: {at: [0, 0, 0], fixed: true}")
    out.append("  C: [0, 0, 0]")
    out.append(f"  D: [{CART_LENGTH:g}, 0, 0]")
    out += [f"  P{k}: [{x!r}, {y!r}, 0]" for k, (x, y) in enumerate(tip_positions(n))
            if k > 0]
    out.append("vectors:")
    out.append("  y: {along: [0, 1, 0], fixed: true}")
    out.append("  z: {along: [0, 0, 1], fixed: true}")
    out.append("bodies:")
    ci = f"{CART_INERTIA:g}"
    out.append(f"  cart: {{points: [C, D], vector: z, mass: {CART_MASS:g}, "
               f"center: [0, 0, 0], inertia: [{ci}, {ci}, {ci}]}}")
    inertia = f"[{AXIAL:g}, {it!r}, {it!r}]"
    for k in range(1, n + 1):
        a = "C" if k == 1 else f"P{k - 1}"
        out.append(f"  rod{k}: {{points: [{a}, P{k}], vector: z, mass: {MASS:g}, "
                   f"center: [{LENGTH / 2:g}, 0, 0], inertia: {inertia}}}")
    out.append("constraints:")
    out.append("  - {type: point_on_plane, point: C, origin: O, normal: y}")
    out.append("  - {type: point_on_plane, point: C, origin: O, normal: z}")
    out.append("  - {type: point_on_plane, point: D, origin: O, normal: y}")
    out.append("initial:")
    out.append("  points:")
    out += [f"    {p}: [{SPEED:g}, 0, 0]" for p in ["C", "D"] +
            [f"P{k}" for k in range(1, n + 1)]]
    out.append("simulate: {t_end: 5.0, dt: 1.0e-3, output_dt: 0.01}")
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    args = size_arguments(argv, __doc__, 2, "n, the number of rods")
    n = args.n
    path = args.path if args.path is not None else Path(f"{model_name(n)}.yaml")
    path.write_text(model_text(n))
    print(f"{path}: n = {n}, {n + 1} bodies, {3 * (n + 2)} coordinates")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
