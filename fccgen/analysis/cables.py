"""What ``fccgen check`` says about flexible members (docs/flexible.md): their nodes,
coordinates and constraint rows, and the highest frequency of their elements with what
it asks of the run's method and step.

The highest frequency is bounded by the element eigenvalue bound (Irons): the largest
natural frequency of an assembled structure with consistent mass matrices is at most
the largest frequency of its elements taken alone, omega_e^2 = max eig(K_e, M_e) at the
stress-free state (K_e = -df/dq of one free element, its rigid motions at zero). For
the cubic cable element it is the axial one, sqrt(170) sqrt(EA / rhoA) / L_e = 13.0
sqrt(EA / rhoA) / L_e, or the bending one, sqrt(8400) sqrt(EI / rhoA) / L_e^2 = 91.7
sqrt(EI / rhoA) / L_e^2, whichever is larger (computed, not taken from these); tension
and curvature of a loaded member shift it by their ratio to EA, little.

An explicit step is stable for omega dt within the method's stability interval on the
imaginary axis (RK4: 2 sqrt 2 = 2.83, with a margin, :data:`RK4_LIMIT`); dopri5 keeps
stable by shrinking its steps to about :data:`DOPRI5_LIMIT` / omega, whatever its
tolerance. The implicit ali3p (the trapezoidal rule) is stable at any step, and leaves
vibrations above about 1 / (10 dt) unresolved but undamped.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numeric import element_kernel
from ..plan.cable_kinds import CABLE_SCALARS
from ..plan.classes import ElementClass

RK4_LIMIT = 2.8           # omega dt of RK4's stability limit on the imaginary axis (2.83)
DOPRI5_LIMIT = 3.3        # the same for Dormand-Prince 5(4) (3.3 on the imaginary axis)
EXPLICIT = {"rk4": RK4_LIMIT, "baumgarte": RK4_LIMIT}
STIFF = ("ali3p", "scipy-Radau", "scipy-BDF", "scipy-LSODA")


@dataclass
class MemberFrequency:
    """The element bound of one member: omega (rad/time) and whether the highest
    element mode is axial or bending."""
    omega: float
    kind: str

    @property
    def hz(self) -> float:
        return self.omega / (2.0 * np.pi)


def member_frequency(cable) -> MemberFrequency:
    """The element eigenvalue bound of a member (module docstring)."""
    cls = ElementClass("cable", (), (False,) * 4, frozenset())
    L = cable.element_length
    values = {"L": L, "EA": cable.EA, "EI": cable.EI, "rhoA": cable.mass_per_length}
    p = np.array([values.get(n, 0.0) for n in CABLE_SCALARS])
    e = np.array([0, 0, 0, 1, 0, 0, L, 0, 0, 1, 0, 0], float)
    zero = np.zeros(12)
    K = -element_kernel(cls, "force_jacobian_q", e, zero, p).reshape(12, 12)
    M = element_kernel(cls, "mass_matrix", e, zero, p).reshape(12, 12)
    import scipy.linalg
    w2, vec = scipy.linalg.eigh(0.5 * (K + K.T), M)
    top = vec[:, -1]
    axial = np.sum(top[0::3] ** 2) >= 0.5 * np.sum(top ** 2)   # along the member (x)
    return MemberFrequency(float(np.sqrt(max(w2[-1], 0.0))), "axial" if axial else "bending")


def step_advice(omega: float, method: str, dt: float) -> str:
    """What the highest member frequency omega asks of ``method`` at step ``dt``."""
    if method in EXPLICIT:
        limit = EXPLICIT[method] / omega
        if dt <= limit:
            return (f"{method} at dt = {dt:g} is stable for the members (omega dt = "
                    f"{omega * dt:.3g} <= {EXPLICIT[method]:g})")
        return (f"{method} at dt = {dt:g} is UNSTABLE for the members (omega dt = "
                f"{omega * dt:.3g} > {EXPLICIT[method]:g}): use dt <= {limit:.3g}, or the "
                "implicit method ali3p")
    if method == "dopri5":
        return (f"dopri5 keeps stable by steps of at most about {DOPRI5_LIMIT / omega:.3g} "
                f"({omega / DOPRI5_LIMIT:.3g} steps per time unit) whatever its tolerance; "
                "the implicit method ali3p takes larger steps")
    if method in STIFF:
        resolved = 1.0 / (10.0 * dt) if method == "ali3p" else None
        text = f"{method} is implicit: stable for the members at any step"
        if resolved is not None and omega / (2 * np.pi) > resolved:
            text += (f"; at dt = {dt:g} vibrations above about {resolved:.3g} Hz are not "
                     "resolved (kept, not damped)")
        return text
    return (f"{method} is explicit: its steps shrink to about {RK4_LIMIT / omega:.3g} or "
            "less; the implicit method ali3p takes larger steps")


def cable_lines(plan) -> list[str]:
    """The lines of ``fccgen check`` about the model's members (empty without)."""
    model = plan.model
    if not model.cables:
        return []
    lines = []
    moving = set(plan.index)
    omega = 0.0
    for c in model.cables.values():
        n_q = 3 * sum(name in moving for name in (*c.nodes, *c.slopes))
        rows = sum(el.cls.n_g for el in plan.elements
                   if el.label.startswith(f"cable {c.name}:"))
        ends = [_end_text(c, k) for k in (0, 1)]
        freq = member_frequency(c)
        omega = max(omega, freq.omega)
        lines.append(f"cable {c.name}: {c.elements} elements of {c.element_length:.6g}, "
                     f"nodes {c.nodes[0]} ... {c.nodes[-1]}; {n_q} coordinates, "
                     f"{rows} constraint rows (ends: {ends[0]}; {ends[1]})")
        lines.append(f"  highest element frequency {freq.hz:.4g} Hz ({freq.kind}; "
                     "element bound)")
    sim = model.simulate
    lines.append("  " + step_advice(omega, sim.method, sim.dt))
    return lines


def _end_text(cable, k: int) -> str:
    end, node = cable.ends[k], cable.nodes[0 if k == 0 else -1]
    what = ("from", "to")[k]
    if end.kind == "point":
        return f"{what} pinned at point {node}"
    if end.kind == "free":
        return f"{what} free"
    how = "clamped" if end.clamp else "pinned"
    return f"{what} {how} on {end.body}"
