"""The comparison's systems in MuJoCo (MJCF written here), integrated with its RK4.

MuJoCo works in joint coordinates: a kinematic tree of hinges (and a slide for the
cart), one coordinate per joint. The pendulum on a cart is a tree (n + 1 coordinates,
no constraint). The A02 chain is the tree "rocker i hinged to ground at A_i, coupler i
hinged to rocker i at B_i" (2N + 1 hinges) whose N loops are closed by ``connect``
equality constraints (coupler i's far end to rocker i+1's top, 3 rows each). MuJoCo
enforces equality constraints softly: a spring-damper of time constant ``solref[0]``
(and damping ratio ``solref[1]``) pulls each violation back to zero, solved with the
constraint forces by its Newton solver at every evaluation; ``solimp`` (default
0.9 0.95 0.001) sets how much of the constraint force it applies (its impedance).
``SOLREF`` = (3e-3, 1) with the default impedance is used for the timing; the accuracy
comparison (``accuracy_a02.py``) tightens both. The time constant must stay above
about two steps for stability.
No geometry, no contacts: the bodies carry explicit inertias.
"""
from __future__ import annotations

import math

import mujoco
import numpy as np

from systems import CART, FOUR_BAR

SOLREF = (3e-3, 1.0)


def _inertial(mass, length, axis):
    """A uniform rod along the body's local axis ``axis`` ("x" or "y") from its origin:
    mass centre at length/2, transverse inertia m L^2 / 12, tiny axial inertia."""
    it, ax = mass * length ** 2 / 12.0, 1e-6
    pos = f"{length / 2!r} 0 0" if axis == "x" else f"0 {length / 2!r} 0"
    diag = f"{ax} {it!r} {it!r}" if axis == "x" else f"{it!r} {ax} {it!r}"
    return f'<inertial pos="{pos}" mass="{mass!r}" diaginertia="{diag}"/>'


def _header(name, g, dt):
    return [f'<mujoco model="{name}">',
            f'  <option timestep="{dt!r}" integrator="RK4" gravity="0 {-g!r} 0">',
            '    <flag contact="disable"/>', '  </option>', '  <worldbody>']


def a02_mjcf(n: int, dt: float, solref=SOLREF, solimp=None) -> str:
    """MJCF of the A02 chain of n loops (rocker hinges ``a<i>``, coupler hinges ``b<i>``)."""
    L, m = FOUR_BAR.LENGTH, FOUR_BAR.MASS
    out = _header(f"a02_{n}", FOUR_BAR.GRAVITY, dt)
    for i in range(n + 1):
        out.append(f'    <body name="rocker{i}" pos="{i} 0 0">')
        out.append(f'      <joint name="a{i}" type="hinge" axis="0 0 1"/>')
        out.append(f'      {_inertial(m, L, "y")}')
        if i < n:
            out.append(f'      <body name="coupler{i}" pos="0 {L!r} 0">')
            out.append(f'        <joint name="b{i}" type="hinge" axis="0 0 1"/>')
            out.append(f'        {_inertial(m, L, "x")}')
            out.append('      </body>')
        out.append('    </body>')
    out += ['  </worldbody>', '  <equality>']
    soft = f'solref="{solref[0]!r} {solref[1]!r}"'
    if solimp is not None:
        soft += ' solimp="' + " ".join(repr(float(x)) for x in solimp) + '"'
    out += [f'    <connect body1="coupler{i}" body2="rocker{i + 1}" anchor="{L!r} 0 0" '
            f'{soft}/>' for i in range(n)]
    out += ['  </equality>', '</mujoco>']
    return "\n".join(out)


def cart_mjcf(n: int, dt: float) -> str:
    """MJCF of the n-link pendulum on a cart (slide ``cart``, hinges ``h1``..``h<n>``)."""
    L, m = CART.LENGTH, CART.MASS
    out = _header(f"cart_{n}", CART.GRAVITY, dt)
    ci = CART.CART_INERTIA
    out.append('    <body name="cart">')
    out.append('      <joint name="cart" type="slide" axis="1 0 0"/>')
    out.append(f'      <inertial pos="0 0 0" mass="{CART.CART_MASS!r}" '
               f'diaginertia="{ci} {ci} {ci}"/>')
    # Each rod's body frame: origin at its hinge, local x along the rod. The first is
    # turned by -90 + tilt degrees about z; the others follow it straight.
    angle = math.degrees(-math.pi / 2 + CART.TILT)
    for k in range(1, n + 1):
        pos = "0 0 0" if k == 1 else f"{L!r} 0 0"
        euler = f' euler="0 0 {angle!r}"' if k == 1 else ""
        out.append(f'{"  " * (k + 2)}<body name="rod{k}" pos="{pos}"{euler}>')
        out.append(f'{"  " * (k + 3)}<joint name="h{k}" type="hinge" axis="0 0 1"/>')
        out.append(f'{"  " * (k + 3)}{_inertial(m, L, "x")}')
    out.append(f'{"  " * (n + 3)}<site name="tip" pos="{L!r} 0 0"/>')
    out += [f'{"  " * (k + 2)}</body>' for k in range(n, 0, -1)]
    out += ['    </body>', '  </worldbody>', '</mujoco>']
    return "\n".join(out)


class MujocoModel:
    """One system in MuJoCo: ``advance(n_steps)`` from the initial state each time,
    ``point()`` the tracked point's (x, y) now."""

    def __init__(self, system: str, n: int, dt: float, solref=SOLREF, solimp=None):
        self.system, self.n = system, n
        xml = a02_mjcf(n, dt, solref, solimp) if system == "a02" else cart_mjcf(n, dt)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        self.qvel0 = self._initial_speeds()

    def _initial_speeds(self) -> np.ndarray:
        v = np.zeros(self.model.nv)
        if self.system == "a02":
            w = FOUR_BAR.SPEED / FOUR_BAR.LENGTH
            # Rockers turn at -w (B_i moves at +v along x); couplers stay level, so
            # each coupler hinge turns at +w relative to its rocker.
            for i in range(self.n + 1):
                v[self.model.joint(f"a{i}").dofadr[0]] = -w
            for i in range(self.n):
                v[self.model.joint(f"b{i}").dofadr[0]] = w
        else:
            v[self.model.joint("cart").dofadr[0]] = CART.SPEED
        return v

    def reset(self) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self.data.qvel[:] = self.qvel0
        mujoco.mj_forward(self.model, self.data)

    def advance(self, n_steps: int) -> None:
        self.reset()
        self.step(n_steps)

    def step(self, n_steps: int) -> None:
        """n_steps more steps from the current state."""
        mujoco.mj_step(self.model, self.data, nstep=n_steps)

    def point(self) -> np.ndarray:
        """(x, y) of B0 (the origin of coupler0's frame) or of the tip, at the current
        state (mj_step leaves the positions of the state before its last step)."""
        mujoco.mj_kinematics(self.model, self.data)
        if self.system == "a02":
            return np.array(self.data.body("coupler0").xpos[:2])
        return np.array(self.data.site("tip").xpos[:2])


def make(system: str, n: int, dt: float, **options) -> MujocoModel:
    return MujocoModel(system, n, dt, **options)
