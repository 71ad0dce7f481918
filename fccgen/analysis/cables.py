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

With the stiffness-proportional damping c every element mode w has the poles
s^2 + c w^2 s + w^2 = 0: undamped, s = +-i w; heavily damped high modes (c w > 2) have
a real pole near -c w^2, which limits an explicit step far more than w does. An
explicit step dt is stable when R(s dt) lies in the unit circle for every pole, R the
method's stability polynomial (:data:`STABILITY`; RK4 on the imaginary axis: w dt <=
2.83); dopri5 keeps stable by shrinking its steps to that limit, whatever its
tolerance. The implicit ali3p (the trapezoidal rule) is stable at any step, and leaves
vibrations above about 1 / (10 dt) unresolved but undamped.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numeric import element_kernel
from ..plan.cable_kinds import CABLE_SCALARS
from ..plan.classes import ElementClass

# Stability polynomials R(z) of the explicit methods (y' = s y: y_n+1 = R(s dt) y_n):
# classical RK4, and the 5th-order solution of Dormand-Prince 5(4) (Hairer, Norsett &
# Wanner, "Solving ODEs I", II.10; the z^6 / 600 term is DOPRI5's).
STABILITY = {
    "rk4": (1.0, 1.0, 1 / 2, 1 / 6, 1 / 24),
    "baumgarte": (1.0, 1.0, 1 / 2, 1 / 6, 1 / 24),
    "dopri5": (1.0, 1.0, 1 / 2, 1 / 6, 1 / 24, 1 / 120, 1 / 600),
}
STIFF = ("ali3p", "scipy-Radau", "scipy-BDF", "scipy-LSODA")


@dataclass
class MemberFrequency:
    """The element bound of one member: omega (rad/time) of its highest mode, whether
    that mode is axial or bending, and the poles s of every element mode with the
    member's damping (s^2 + c w^2 s + w^2 = 0 per mode w; c = 0: s = +-i w)."""
    omega: float
    kind: str
    poles: np.ndarray

    @property
    def hz(self) -> float:
        return self.omega / (2.0 * np.pi)


def member_frequency(cable) -> MemberFrequency:
    """The element eigenvalue bound of a member (module docstring)."""
    import scipy.linalg
    cls = ElementClass("cable", (), (False,) * 4, frozenset())
    L = cable.element_length
    values = {"L": L, "EA": cable.EA, "EI": cable.EI, "rhoA": cable.mass_per_length}
    p = np.array([values.get(n, 0.0) for n in CABLE_SCALARS])
    e = np.array([0, 0, 0, 1, 0, 0, L, 0, 0, 1, 0, 0], float)
    zero = np.zeros(12)
    K = -element_kernel(cls, "force_jacobian_q", e, zero, p).reshape(12, 12)
    M = element_kernel(cls, "mass_matrix", e, zero, p).reshape(12, 12)
    w2, vec = scipy.linalg.eigh(0.5 * (K + K.T), M)
    w2 = np.maximum(w2, 0.0)
    top = vec[:, -1]
    axial = np.sum(top[0::3] ** 2) >= 0.5 * np.sum(top ** 2)   # along the member (x)
    c = float(getattr(cable, "damping", 0.0))
    poles = np.concatenate([np.roots([1.0, c * x, x]) for x in w2 if x > 0.0])
    return MemberFrequency(float(np.sqrt(w2[-1])), "axial" if axial else "bending",
                           poles.astype(complex))


def stable_step(poles, method: str) -> float:
    """The largest dt with R(s dt) inside the unit circle for every pole s, for an
    explicit method of STABILITY (along each ray from 0 the stable set is an interval
    [0, d], found by bisection)."""
    coef = STABILITY[method][::-1]
    limit = np.inf
    for s in np.asarray(poles, complex):
        if abs(s) == 0.0:
            continue
        lo, hi = 0.0, 8.0 / abs(s)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if abs(np.polyval(coef, s * mid)) <= 1.0 + 1e-12 else (lo, mid)
        limit = min(limit, lo)
    return float(limit)


def step_advice(freq: MemberFrequency, method: str, dt: float) -> str:
    """What the members' poles (:func:`member_frequency`) ask of ``method`` at ``dt``."""
    if method in ("rk4", "baumgarte"):
        limit = stable_step(freq.poles, method)
        if dt <= limit:
            return (f"{method} at dt = {dt:g} is stable for the members (limit "
                    f"{limit:.3g})")
        return (f"{method} at dt = {dt:g} is UNSTABLE for the members: use dt <= "
                f"{limit:.3g}, or the implicit method ali3p")
    if method == "dopri5":
        limit = stable_step(freq.poles, method)
        return (f"dopri5 keeps stable by steps of at most about {limit:.3g} "
                f"({1.0 / limit:.3g} steps per time unit) whatever its tolerance; the "
                "implicit method ali3p takes larger steps")
    if method in STIFF:
        text = f"{method} is implicit: stable for the members at any step"
        if method == "ali3p" and freq.hz > 1.0 / (10.0 * dt):
            text += (f"; at dt = {dt:g} vibrations above about {1.0 / (10.0 * dt):.3g} "
                     "Hz are not resolved (kept, not damped)")
        return text
    limit = stable_step(freq.poles, "dopri5")
    return (f"{method} is explicit: its steps shrink to about {limit:.3g} or less; the "
            "implicit method ali3p takes larger steps")


def cable_lines(plan) -> list[str]:
    """The lines of ``fccgen check`` about the model's members (empty without)."""
    model = plan.model
    if not model.cables:
        return []
    lines = []
    moving = set(plan.index)
    worst = None
    for c in model.cables.values():
        n_q = 3 * sum(name in moving for name in (*c.nodes, *c.slopes))
        rows = sum(el.cls.n_g for el in plan.elements
                   if el.label.startswith(f"cable {c.name}:"))
        ends = [_end_text(c, k) for k in (0, 1)]
        freq = member_frequency(c)
        worst = freq if worst is None else MemberFrequency(
            max(worst.omega, freq.omega), worst.kind,
            np.concatenate([worst.poles, freq.poles]))
        lines.append(f"cable {c.name}: {c.elements} elements of {c.element_length:.6g}, "
                     f"nodes {c.nodes[0]} ... {c.nodes[-1]}; {n_q} coordinates, "
                     f"{rows} constraint rows (ends: {ends[0]}; {ends[1]})")
        damped = (f", damping {c.damping:g}: fastest decay rate "
                  f"{float(np.max(-freq.poles.real)):.3g} per time unit"
                  if c.damping else "")
        lines.append(f"  highest element frequency {freq.hz:.4g} Hz ({freq.kind}; "
                     f"element bound){damped}")
    sim = model.simulate
    lines.append("  " + step_advice(worst, sim.method, sim.dt))
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
