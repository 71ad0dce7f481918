"""The integration methods, as data: one registry for the model loader, the command
line and both solvers.

Each :class:`Method` says whether it steps with a fixed ``dt`` or adapts its step to a
tolerance, what it does, and which options it takes with their defaults and where the
defaults come from. Adding a method means adding an entry here and a branch in each
solver's dispatch; the loader and the command line follow from this table.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .run import EPS, RunSettingError, Schedule, interval, options_for, schedule


# The methods whose compiled loops locate and apply events (events: and joint limits:);
# fccgen.settings.limits says why the others cannot, the model loader refuses a model
# file that names another.
EVENT_METHODS = ("rk4", "dopri5")


@dataclass(frozen=True)
class Option:
    """A method option: its name (a keyword of ``simulate``), default and source, and
    its accepted range (low, high; open or closed ends; whole numbers only)."""
    name: str
    default: float
    help: str
    source: str
    low: float = 0.0
    high: float = 1e12
    low_open: bool = True
    high_open: bool = False
    integer: bool = False
    why: str = ""                 # the reason for the range, shown when it is broken

    def rule(self) -> str:
        positive = self.low > 0 or (self.low == 0 and self.low_open)
        what = ("a whole number" if self.integer else "a positive number" if positive
                else "a number")
        text = (f"must be {what} in "
                f"{interval(self.low, self.high, self.low_open, self.high_open)}")
        return text + (f" ({self.why})" if self.why else "")

    def accepts(self, x: float) -> bool:
        if not math.isfinite(x) or (self.integer and x != int(x)):
            return False
        above = x > self.low if self.low_open else x >= self.low
        below = x < self.high if self.high_open else x <= self.high
        return above and below


@dataclass(frozen=True)
class Method:
    name: str
    kind: str                     # "fixed" (steps of dt) or "adaptive" (rtol, atol)
    description: str
    options: tuple[Option, ...] = field(default=())
    projects: bool = True         # honours project=True (projection after each step)
    compiled_loop: bool = True    # the per-step loop runs in compiled code

    def defaults(self) -> dict[str, float]:
        return {o.name: o.default for o in self.options}


__all__ = ["EPS", "METHODS", "Method", "Option", "RunSettingError", "Schedule", "describe",
           "get", "names", "options_for", "run_info", "schedule"]


# rtol in (10 eps, 1): an error estimate below 10 eps relative is rounding (Hairer's
# DOPRI5 refuses RTOL <= 10 UROUND, "tolerances are too small"), and rtol >= 1 lets a
# step be 100% wrong.
RTOL = Option("rtol", 1e-6, "relative tolerance of the local error estimate",
              "fccgen's choice: on the examples, dopri5 at 1e-6 is within 2e-6 to 6e-6 "
              "(positions, over 1 s) of a converged solution, comparable to rk4 at "
              "dt = 1e-3 on the four-bar; SciPy's solve_ivp default 1e-3 is 1000x "
              "looser (docs/design.md §7: compare at equal accuracy)",
              low=10 * EPS, high=1.0, high_open=True,
              why="below 10 eps is rounding, 1 or more accepts any step")
ATOL = Option("atol", 1e-9, "absolute tolerance of the local error estimate",
              "fccgen's choice: three decades below rtol so that coordinates passing "
              "through zero are still controlled relative to unit-size values")
# Baumgarte, "Stabilization of constraints and integrals of motion in dynamical
# systems", Comput. Methods Appl. Mech. Eng. 1 (1972) 1-16, proposes alpha = beta
# (the constraint error then decays critically damped, e(t) ~ (1 + alpha t) exp(-alpha t)).
# The value is problem-dependent (Flores et al., "A parametric study on the Baumgarte
# stabilization method for forward dynamics of constrained multibody systems",
# J. Comput. Nonlinear Dyn. 6 (2011) 011019); MapleSim's documentation gives 1 to 10 as
# typical. 5 per time unit damps a drift to 4% within one time unit, while
# alpha * dt = 5e-3 at the default dt = 1e-3 stays far inside RK4's real stability
# interval (alpha * dt < 2.78), so the stabilisation does not stiffen the run.
# 0 is accepted (no stabilisation); the step's limit is checked with dt (rk4_stable).
BAUMGARTE_ALPHA = Option("alpha", 5.0, "Baumgarte damping alpha (1/time unit)",
                         "Baumgarte 1972 (alpha = beta, critical damping); 5 within the "
                         "typical 1-10, with alpha*dt << 2.78 at dt = 1e-3",
                         low_open=False)
BAUMGARTE_BETA = Option("beta", 5.0, "Baumgarte stiffness beta (1/time unit)",
                        "Baumgarte 1972: beta = alpha", low_open=False)

# ALI3-P (fccgen/runtime/_ali3p.pyx): Bayo & Garcia de Jalon, "Kinematic and Dynamic
# Simulation of Multibody Systems" (1994), ch. 4-5; Cuadrado, Cardenal & Bayo, Multibody
# System Dynamics 1 (1997) 259-280.
ALI3P_PENALTY = Option("penalty", 1e9, "augmented Lagrangian penalty (1/time unit^2), "
                       "scaled per constraint row by the largest mass-matrix entry / "
                       "||B_k||^2",
                       "the references' 1e7 at their dt = 1e-2 scaled to dt = 1e-3 (same "
                       "(dt^2/4) penalty, so 2-4 Newton iterations per step); passing "
                       "positions where the constraint Jacobian loses rank may need more "
                       "(A02 N-four-bar at dt = 1e-3: 1e12); reasons in "
                       "fccgen/runtime/_ali3p.pyx", high=1e30)
ALI3P_NEWTON_TOL = Option("newton_tol", 1e-10, "Newton stops when max |dq| and "
                          "max |g_k| / ||B_k|| are both <= newton_tol times the largest "
                          "body length",
                          "fccgen's choice: near the 1e-11 relative position tolerance "
                          "of the projections of rk4 and dopri5",
                          low=10 * EPS, low_open=False, high=1.0, high_open=True,
                          why="below 10 eps Newton cannot stop by tolerance")
ALI3P_MAX_NEWTON = Option("max_newton", 30, "Newton iteration limit per step",
                          "fccgen's choice: a converging step takes 2-5 iterations",
                          low=1, low_open=False, high=10_000, integer=True,
                          why="each iteration factorises the Newton matrix once")

_SCIPY = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
_SCIPY_TEXT = {
    "RK45": "SciPy solve_ivp RK45 (Dormand-Prince 5(4), explicit)",
    "DOP853": "SciPy solve_ivp DOP853 (Dormand-Prince 8(5,3), explicit)",
    "Radau": "SciPy solve_ivp Radau (implicit Runge-Kutta, order 5, stiff)",
    "BDF": "SciPy solve_ivp BDF (backward differentiation, orders 1-5, stiff)",
    "LSODA": "SciPy solve_ivp LSODA (Adams/BDF switching, ODEPACK)",
}

METHODS: dict[str, Method] = {m.name: m for m in (
    Method("rk4", "fixed",
           "classical Runge-Kutta 4 with steps dt; project=True: Newton position "
           "projection then M-orthogonal velocity projection after every step"),
    Method("dopri5", "adaptive",
           "Dormand-Prince 5(4) with FSAL and error control (Hairer: safety 0.9, "
           "factors 0.2-10), outputs by its 4th-order dense output; project=True: "
           "projection after every accepted step", (RTOL, ATOL)),
    Method("baumgarte", "fixed",
           "index-1 form with Baumgarte stabilisation, B q'' = -(dB/dt) q' - 2 alpha "
           "B q' - beta^2 g, integrated by RK4 with steps dt and no projection",
           (BAUMGARTE_ALPHA, BAUMGARTE_BETA), projects=False),
    Method("ali3p", "fixed",
           "index-3 augmented Lagrangian with mass-orthogonal projections of speeds "
           "and accelerations (ALI3-P), trapezoidal rule with steps dt, Newton on the "
           "positions; implicit, its projections are part of the method",
           (ALI3P_PENALTY, ALI3P_NEWTON_TOL, ALI3P_MAX_NEWTON), projects=False),
    *(Method(f"scipy-{s}", "adaptive",
             f"{_SCIPY_TEXT[s]} on the right-hand side y -> [v, a(q, v)]; outputs by "
             "t_eval; no projection (what a SciPy user gets)", (RTOL, ATOL),
             projects=False, compiled_loop=False) for s in _SCIPY),
)}

# Methods whose compiled loop lives in a module that may be absent (built separately).
OPTIONAL_COMPILED: dict[str, str] = {"ali3p": "_ali3p"}


def names() -> tuple[str, ...]:
    """Every method name, in registry order."""
    return tuple(METHODS)


def get(name: str, available: tuple[str, ...] | None = None) -> Method:
    """The method called ``name``; ValueError listing the available ones otherwise."""
    available = names() if available is None else available
    if name not in available:
        raise ValueError(f"unknown method {name!r}; available: {', '.join(available)}")
    return METHODS[name]


# Keys every run's ``result.info`` holds (besides method-specific ones).
INFO_KEYS = ("method", "steps", "rhs_evaluations", "rejected_steps", "newton_iterations",
             "max_constraint_error", "energy_drift", "wall_time")


def run_info(method: Method, stats: dict, energy, wall_time: float, **extra) -> dict:
    """``result.info`` of a run: INFO_KEYS from the integrator's stats, the energy
    record (energy_drift = max |E - E0| over the outputs) and the wall time, then
    ``extra`` (dt, rtol, options, ...) and any further stats."""
    e = [float(x) for x in energy]
    info = dict(method=method.name, kind=method.kind,
                steps=int(stats["steps"]), rhs_evaluations=int(stats["rhs_evaluations"]),
                rejected_steps=stats.get("rejected_steps", 0),
                newton_iterations=int(stats.get("newton_iterations", 0)),
                max_constraint_error=float(stats["max_constraint_error"]),
                energy_drift=max((abs(x - e[0]) for x in e), default=0.0),
                wall_time=float(wall_time))
    info.update(extra)
    for key, value in stats.items():
        info.setdefault(key, value)
    return info


def describe(sources: bool = False) -> str:
    """One line per method with its options and defaults; ``sources``: each option
    on its own line with its meaning and the source of its default."""
    lines = []
    for m in METHODS.values():
        line = f"{m.name} ({m.kind}): {m.description}"
        if m.options and not sources:
            line += "; options: " + ", ".join(f"{o.name}={o.default:g}" for o in m.options)
        lines.append(line)
        for o in m.options if sources else ():
            lines.append(f"    {o.name} = {o.default:g}: {o.help} [{o.source}]")
    return "\n".join(lines)
