"""NumericSolver: the NumPy version of the solver (DESIGN section 3), with the same
interface as the compiled one. It is the cross-check in tests and the baseline in
benchmarks, so it favours plain, readable NumPy over speed.

Global quantities are sums of element kernels scattered to the elements' coordinate
slots (``Element.q_index()``); constraint rows follow the elements' order.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..errors import SimulationError
from ..plan import Plan
from ..results import InitialState, Result, result_from_arrays
from .constrained import constrained_solve, scaled_residual
from .elements import element_kernels


class NumericSolver:
    """Assembly, constrained solve, projections and integration in NumPy."""

    def __init__(self, plan: Plan, *, rank_tol: float = 1e-10,
                 position_tol: float | None = None, max_newton: int = 20):
        self.plan = plan
        self.n_q = plan.n_q
        self.n_g = plan.n_g
        self.rank_tol = float(rank_tol)
        self.max_newton = int(max_newton)
        self.length_scale = _length_scale(plan)
        self.position_tol = (1e-11 * self.length_scale if position_tol is None
                             else float(position_tol))
        self._index = [el.q_index() for el in plan.elements]
        offsets = np.cumsum([0] + [el.cls.n_g for el in plan.elements])
        self._rows = [np.arange(a, b) for a, b in zip(offsets[:-1], offsets[1:])]

    # -- element evaluation ------------------------------------------------------------
    def _kernels(self, q, v):
        """(element, local index, row indices, kernels object) for every element."""
        q = np.asarray(q, float)
        v = None if v is None else np.asarray(v, float)
        for el, idx, rows in zip(self.plan.elements, self._index, self._rows):
            yield el, idx, rows, element_kernels(el.cls, q[idx],
                                                 None if v is None else v[idx], el.params)

    def _assemble(self, q, v, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """Global arrays of the named kernels at (q, v), in one pass over the elements."""
        out = {"mass_matrix": np.zeros((self.n_q, self.n_q)),
               "h_vector": np.zeros(self.n_q), "applied_forces": np.zeros(self.n_q),
               "constraints": np.zeros(self.n_g),
               "constraint_jacobian": np.zeros((self.n_g, self.n_q)),
               "constraint_bias": np.zeros(self.n_g)}
        out = {n: out[n] for n in names}
        for el, idx, rows, k in self._kernels(q, v):
            for name in names:
                value = k.evaluate(name)
                if value is None:
                    continue
                if name == "mass_matrix":
                    np.add.at(out[name], (idx[:, None], idx[None, :]),
                              value.reshape(len(idx), len(idx)))
                elif name == "constraint_jacobian":
                    np.add.at(out[name], (rows[:, None], idx[None, :]),
                              value.reshape(len(rows), len(idx)))
                elif name in ("constraints", "constraint_bias"):
                    out[name][rows] = value
                else:
                    np.add.at(out[name], idx, value)
        return out

    # -- global quantities ---------------------------------------------------------------
    def mass_matrix(self, q) -> np.ndarray:
        return self._assemble(q, None, ("mass_matrix",))["mass_matrix"]

    def h_vector(self, q, v) -> np.ndarray:
        return self._assemble(q, v, ("h_vector",))["h_vector"]

    def applied_forces(self, q, v) -> np.ndarray:
        return self._assemble(q, v, ("applied_forces",))["applied_forces"]

    def constraints(self, q) -> np.ndarray:
        return self._assemble(q, None, ("constraints",))["constraints"]

    def constraint_jacobian(self, q) -> np.ndarray:
        return self._assemble(q, None, ("constraint_jacobian",))["constraint_jacobian"]

    def constraint_bias(self, q, v) -> np.ndarray:
        return self._assemble(q, v, ("constraint_bias",))["constraint_bias"]

    def energy(self, q, v) -> float:
        """Kinetic plus potential energy of all elements."""
        total = 0.0
        for _, _, _, k in self._kernels(q, v):
            e = k.evaluate("energy")
            if e is not None:
                total += float(e[0] + e[1])
        return total

    def body_outputs(self, q, v) -> np.ndarray:
        """(n_bodies, 6): mass centre and angular velocity (global) in plan.bodies order."""
        out = np.zeros((len(self.plan.bodies), 6))
        for b, (_, e) in enumerate(self.plan.bodies):
            el, idx = self.plan.elements[e], self._index[e]
            out[b] = element_kernels(el.cls, np.asarray(q, float)[idx],
                                     np.asarray(v, float)[idx], el.params).evaluate(
                                         "body_outputs")
        return out

    # -- solves ----------------------------------------------------------------------------
    def accelerations(self, q, v) -> np.ndarray:
        """q'' from M q'' + B^T lambda = f - h, B q'' = -(dB/dt) q'."""
        a = self._assemble(q, v, ("mass_matrix", "h_vector", "applied_forces",
                                  "constraint_jacobian", "constraint_bias"))
        return constrained_solve(a["mass_matrix"], a["constraint_jacobian"],
                                 a["applied_forces"] - a["h_vector"],
                                 -a["constraint_bias"], self.rank_tol)

    def project_velocities(self, q, v) -> np.ndarray:
        """The speeds nearest to v in the kinetic-energy metric with B v = 0."""
        a = self._assemble(q, None, ("mass_matrix", "constraint_jacobian"))
        M = a["mass_matrix"]
        return constrained_solve(M, a["constraint_jacobian"], M @ np.asarray(v, float),
                                 np.zeros(self.n_g), self.rank_tol)

    def project_positions(self, q) -> tuple[np.ndarray, int]:
        """Newton iterations dq = argmin dq^T M dq / 2 subject to B dq = -g until
        max_k |g_k| / ||B_k|| <= position_tol.

        Full Newton in the constraints (g and B are evaluated at every iterate); the
        metric M is the mass matrix at the starting point. Returns (q, iterations).
        """
        q = np.array(q, float)
        a = self._assemble(q, None, ("mass_matrix", "constraints", "constraint_jacobian"))
        M = a["mass_matrix"]
        g, B = a["constraints"], a["constraint_jacobian"]
        zero = np.zeros(self.n_q)
        for it in range(self.max_newton + 1):
            residual = scaled_residual(g, B)
            if not np.isfinite(residual):
                raise SimulationError(f"position projection: constraint residual is not "
                                      f"finite (got {residual})")
            if residual <= self.position_tol:
                return q, it
            if it == self.max_newton:
                break
            q = q + constrained_solve(M, B, zero, -g, self.rank_tol)
            g, B = self.constraints(q), self.constraint_jacobian(q)
        raise SimulationError(
            f"position projection did not converge in {self.max_newton} Newton iterations: "
            f"scaled constraint residual max |g_k|/||B_k|| = {residual:.3g} > tolerance "
            f"{self.position_tol:.3g}")

    def initial_state(self) -> InitialState:
        """plan.q0 assembled onto the constraints and plan.v_target made consistent."""
        q_given = np.array(self.plan.q0, float)
        q, iterations = self.project_positions(q_given)
        v_given = np.array(self.plan.v_target, float)
        v = self.project_velocities(q, v_given)
        return InitialState(
            q=q, v=v,
            position_residual_given=_amax(self.constraints(q_given)),
            position_residual=_amax(self.constraints(q)),
            newton_iterations=iterations,
            velocity_change=_amax(v - v_given),
            velocity_residual=_amax(self.constraint_jacobian(q) @ v))

    def simulate(self, t_end=None, dt=None, method=None, output_dt=None, project=True,
                 q0=None, v0=None) -> Result:
        """Integrate from (q0, v0), used as given; when q0 is None the consistent
        initial state is used, and when only v0 is None plan.v_target is projected at
        q0. Defaults of t_end, dt, method and output_dt come from the model file."""
        defaults = self.plan.model.simulate
        method = defaults.method if method is None else method
        if method not in INTEGRATORS:
            raise ValueError(f"unknown integration method {method!r}; available: "
                             + ", ".join(INTEGRATORS))
        if q0 is None:
            init = self.initial_state()
            q0, v0 = init.q, (init.v if v0 is None else v0)
        elif v0 is None:
            v0 = self.project_velocities(q0, self.plan.v_target)
        t_end = defaults.t_end if t_end is None else t_end
        dt = defaults.dt if dt is None else dt
        if output_dt is None:
            output_dt = dt if defaults.output_dt is None else defaults.output_dt
        return INTEGRATORS[method](self, np.array(q0, float), np.array(v0, float),
                                   float(t_end), float(dt), float(output_dt), bool(project))


def _output_steps(t_end: float, dt: float, output_dt: float) -> tuple[int, int]:
    """(number of steps, output every so many steps), checking the arguments."""
    if not (t_end > 0.0 and dt > 0.0 and output_dt > 0.0):
        raise ValueError(f"t_end, dt and output_dt must be positive "
                         f"(got {t_end!r}, {dt!r}, {output_dt!r})")
    ratio = output_dt / dt
    every = round(ratio)
    if every < 1 or abs(ratio - every) > 1e-9 * ratio:
        raise ValueError(f"output_dt must be a whole multiple of dt "
                         f"(got output_dt {output_dt!r}, dt {dt!r})")
    return math.ceil(t_end / dt - 1e-9), every


def _rk4_step(solver: NumericSolver, q, v, h):
    """One classical Runge-Kutta step of q' = v, v' = accelerations(q, v)."""
    a1 = solver.accelerations(q, v)
    v2 = v + 0.5 * h * a1
    a2 = solver.accelerations(q + 0.5 * h * v, v2)
    v3 = v + 0.5 * h * a2
    a3 = solver.accelerations(q + 0.5 * h * v2, v3)
    v4 = v + h * a3
    a4 = solver.accelerations(q + h * v3, v4)
    return (q + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4))


def simulate_rk4(solver: NumericSolver, q, v, t_end, dt, output_dt, project) -> Result:
    """Fixed-step RK4, the last step shortened to land on t_end; after each step the
    positions and then the speeds are projected onto the constraints (if ``project``)."""
    n_steps, every = _output_steps(t_end, dt, output_dt)
    start = time.perf_counter()
    out: dict[str, list] = {k: [] for k in ("t", "q", "v", "body", "energy", "cerr")}

    def record(t, q, v):
        out["t"].append(t)
        out["q"].append(q.copy())
        out["v"].append(v.copy())
        out["body"].append(solver.body_outputs(q, v))
        out["energy"].append(solver.energy(q, v))
        out["cerr"].append(_amax(solver.constraints(q)))

    record(0.0, q, v)
    max_newton = 0
    for k in range(1, n_steps + 1):
        t = k * dt if k < n_steps else t_end
        try:
            q, v = _rk4_step(solver, q, v, dt if k < n_steps else t_end - (k - 1) * dt)
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
                raise SimulationError("the state is not finite")
            if project:
                q, iterations = solver.project_positions(q)
                v = solver.project_velocities(q, v)
                max_newton = max(max_newton, iterations)
        except SimulationError as exc:
            raise SimulationError(f"at t = {t:.6g} (step {k}): {exc}") from None
        if k % every == 0 or k == n_steps:
            record(t, q, v)
    info = dict(method="rk4", steps=n_steps, rhs_evaluations=4 * n_steps,
                max_newton_iterations=max_newton, wall_time=time.perf_counter() - start,
                max_constraint_error=float(max(out["cerr"])))
    shape = (len(out["t"]), len(solver.plan.bodies), 6)
    return result_from_arrays(solver.plan, np.array(out["t"]), np.array(out["q"]),
                              np.array(out["v"]), np.array(out["body"]).reshape(shape),
                              np.array(out["energy"]), np.array(out["cerr"]), info)


INTEGRATORS = {"rk4": simulate_rk4}


def _amax(x) -> float:
    x = np.asarray(x, float)
    return float(np.max(np.abs(x))) if x.size else 0.0


def _length_scale(plan: Plan) -> float:
    """The largest body length l of the plan, 1 if it has no body."""
    lengths = [el.params[el.cls.scalar_names.index("l")]
               for el in plan.elements if el.cls.kind == "body"]
    return float(max(lengths)) if lengths else 1.0
