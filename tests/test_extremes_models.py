"""Model texts and loading helpers shared by the extreme-case tests
(tests/test_extremes_*.py; this module holds no tests). Models are written as YAML so
that every case goes through the loader, the plan, the generated kernels and the
compiled runtime exactly as a user's model file does.

Several models reuse the structure (element classes) and the name of an example
(spherical_pendulum, double_pendulum, four_bar): the build cache then serves them from
the example's build in the same test run instead of compiling again.
"""
from __future__ import annotations

import hashlib

import numpy as np

import fccgen

EPS = float(np.finfo(float).eps)


def make_loader(model_dir, build_dir):
    """load(text) -> CompiledSolver of a model text, written to model_dir under a name
    taken from its hash and built into build_dir (shared with the examples, so a model
    with an example's name and structure is served from that build)."""
    solvers = {}

    def load(text: str):
        key = hashlib.sha256(text.encode()).hexdigest()[:16]
        if key not in solvers:
            path = model_dir / f"model_{key}.yaml"
            path.write_text(text)
            solvers[key] = fccgen.load(path, build_dir)
        return solvers[key]
    return load


def vec(x) -> str:
    """A YAML flow sequence of floats written with all 17 digits."""
    return "[" + ", ".join(repr(float(v)) for v in np.ravel(x)) + "]"


def tilted_body(u, center, inertia, omega, name="tilted_body") -> str:
    """A rigid body about a fixed point O (ball joint), tip P at (1, 0, 0), moving unit
    vector u, full centre and inertia tensor [Ixx Iyy Izz Ixy Ixz Iyz] in its body
    frame, turning at omega (global frame), gravity along -z."""
    I = np.asarray(inertia, float)
    six = [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]
    return f"""name: {name}
gravity: [0, 0, -9.81]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  P: [1.0, 0, 0]
vectors:
  u: {vec(u)}
bodies:
  b:
    points: [O, P]
    vector: u
    mass: 2.0
    center: {vec(center)}
    inertia: {vec(six)}
initial:
  bodies: {{b: {{angular_velocity: {vec(omega)}, frame: global}}}}
"""


def axisymmetric_top(P, u, mass, d, axial, transverse, omega, g=9.81) -> str:
    """A rod-like axisymmetric body on a ball joint at O (the spherical_pendulum
    example's structure): tip P, vector u perpendicular to OP, mass centre at distance
    d on the axis, central inertia [axial, transverse, transverse], angular velocity
    omega (global), gravity g along -z."""
    return f"""name: spherical_pendulum
gravity: [0, 0, {-float(g)!r}]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  P: {vec(P)}
vectors:
  u: {vec(u)}
bodies:
  rod:
    points: [O, P]
    vector: u
    mass: {float(mass)!r}
    center: [{float(d)!r}, 0, 0]
    inertia: {vec([axial, transverse, transverse])}
initial:
  bodies: {{rod: {{angular_velocity: {vec(omega)}, frame: global}}}}
"""


def double_pendulum(p, P1, P2) -> str:
    """Two rods hinged about the fixed z (the double_pendulum example's structure):
    p holds m1, c1, Ia1, It1, m2, c2, Ia2, It2, g (gravity along -y)."""
    return f"""name: double_pendulum
gravity: [0, {-p['g']!r}, 0]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  P1: {vec(P1)}
  P2: {vec(P2)}
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  rod1:
    points: [O, P1]
    vector: z
    mass: {p['m1']!r}
    center: [{p['c1']!r}, 0, 0]
    inertia: {vec([p['Ia1'], p['It1'], p['It1']])}
  rod2:
    points: [P1, P2]
    vector: z
    mass: {p['m2']!r}
    center: [{p['c2']!r}, 0, 0]
    inertia: {vec([p['Ia2'], p['It2'], p['It2']])}
"""


def spring_pendulum(k, v0=0.01) -> str:
    """The A01 pendulum (1 kg at P on a 1 m rod about z, gravity -y) hanging down, with
    a spring of stiffness k from the fixed point C = (1, -1, 0) to P, unstretched at
    the start; P starts at v0 m/s along x, i.e. along the spring."""
    return f"""name: spring_pendulum
gravity: [0, -9.81, 0]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  C: {{at: [1, -1, 0], fixed: true}}
  P: [0, -1, 0]
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  pendulum:
    points: [O, P]
    vector: z
    mass: 1.0
    center: [1, 0, 0]
    inertia: [0, 0, 0]
loads:
  - {{type: spring, ends: [C, P], stiffness: {float(k)!r}, length: 1.0}}
initial:
  points: {{P: [{float(v0)!r}, 0, 0]}}
"""


def parallelogram(theta0, omega0, r=0.1, L=0.4) -> str:
    """A parallelogram four-bar (the four_bar example's structure, all hinges about the
    fixed z): ground O-C of length L, crank O-A and rocker C-B of length r, coupler A-B
    of length L; crank at theta0 turning at omega0; gravity -y."""
    A = r * np.array([np.cos(theta0), np.sin(theta0), 0.0])
    B = A + [L, 0.0, 0.0]
    vA = r * omega0 * np.array([-np.sin(theta0), np.cos(theta0), 0.0])
    return f"""name: four_bar
gravity: [0, -9.81, 0]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  C: {{at: [{float(L)!r}, 0, 0], fixed: true}}
  A: {vec(A)}
  B: {vec(B)}
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  crank:
    points: [O, A]
    vector: z
    mass: 0.2
    center: [{r / 2!r}, 0, 0]
    inertia: [1.0e-5, 2.0e-4, 2.0e-4]
  coupler:
    points: [A, B]
    vector: z
    mass: 0.7
    center: [{L / 2!r}, 0, 0]
    inertia: [3.5e-5, 0.009, 0.009]
  rocker:
    points: [C, B]
    vector: z
    mass: 0.2
    center: [{r / 2!r}, 0, 0]
    inertia: [1.0e-5, 2.0e-4, 2.0e-4]
initial:
  points: {{A: {vec(vA)}, B: {vec(vA)}}}
"""
