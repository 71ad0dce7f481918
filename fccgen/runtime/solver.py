"""CompiledSolver: the Python face of the compiled engine for one model.

The same interface as :class:`fccgen.numeric.NumericSolver`; every array it returns is
a fresh array owned by the caller (DESIGN section 7). Python runs once per call: a
simulation is one call into the engine, which keeps the per-step loop in C.
"""
from __future__ import annotations

import math
import statistics
import time

import numpy as np

from ..errors import BuildError, SimulationError
from ..results import InitialState, Result, result_from_arrays
from ._assemble import FLAGS, Assembler
from ._engine import Engine
from ._rk4 import simulate_rk4

METHODS = ("rk4",)


def length_scale(plan) -> float:
    """The largest body length ``l`` of the plan (1 if it has no body)."""
    lengths = [el.params[el.cls.param_names.index("l")] for el in plan.elements
               if el.cls.kind == "body"]
    return float(max(lengths)) if lengths else 1.0


def make_assembler(plan, module) -> Assembler:
    """Bind a generated module's kernels to the plan's instance data (checked)."""
    try:
        capsule = module.table_capsule()
        structure_hash = module.STRUCTURE_HASH
    except AttributeError as exc:
        raise BuildError(f"{getattr(module, '__name__', module)!r} is not a generated "
                         f"kernel module ({exc})") from None
    els = plan.elements
    q_idx = [el.q_index() for el in els]
    q_ptr = np.concatenate([[0], np.cumsum([len(i) for i in q_idx])])
    p_ptr = np.concatenate([[0], np.cumsum([len(el.params) for el in els])])
    return Assembler(
        capsule, [c.name for c in plan.classes],
        np.array([(c.n_q, c.n_p, c.n_g) for c in plan.classes], dtype=np.intc).reshape(-1, 3),
        np.asarray(plan.class_of, dtype=np.intc), q_ptr,
        np.concatenate(q_idx) if q_idx else np.zeros(0, np.intc), p_ptr,
        np.concatenate([el.params for el in els]) if els else np.zeros(0),
        plan.n_q, np.array([e for _, e in plan.bodies], dtype=np.intc),
        structure_hash=structure_hash, owner=module)


class CompiledSolver:
    """Assembly, constrained solve, projections and RK4 of one model, in compiled code.

    plan: the model's :class:`fccgen.plan.Plan`; module: its generated kernel module.
    rank_tol: relative rank threshold of the constraint Jacobian (redundant rows below
    it are dropped); position_tol: Newton projection tolerance on max_k |g_k| / ||B_k||
    (default 1e-11 times the largest body length); max_newton: iteration limit.
    """

    def __init__(self, plan, module, *, rank_tol=1e-10, position_tol=None, max_newton=20):
        self.plan = plan
        self.module = module
        self.n_q = plan.n_q
        self.n_g = plan.n_g
        self.rank_tol = float(rank_tol)
        self.length_scale = length_scale(plan)
        self.position_tol = (1e-11 * self.length_scale if position_tol is None
                             else float(position_tol))
        self.max_newton = int(max_newton)
        self._asm = make_assembler(plan, module)
        self._engine = Engine(self._asm, self.rank_tol, self.position_tol, self.max_newton)

    # -- global quantities ------------------------------------------------------------
    def _get(self, name, q, v=None):
        return self._asm.quantity(FLAGS[name], q, v)

    def mass_matrix(self, q) -> np.ndarray:
        return self._get("mass_matrix", q)

    def h_vector(self, q, v) -> np.ndarray:
        return self._get("h_vector", q, v)

    def applied_forces(self, q, v) -> np.ndarray:
        return self._get("applied_forces", q, v)

    def constraints(self, q) -> np.ndarray:
        return self._get("constraints", q)

    def constraint_jacobian(self, q) -> np.ndarray:
        return self._get("constraint_jacobian", q)

    def constraint_bias(self, q, v) -> np.ndarray:
        return self._get("constraint_bias", q, v)

    def energy(self, q, v) -> float:
        """Total energy, kinetic plus potential."""
        kinetic, potential = self._get("energy", q, v)
        return float(kinetic + potential)

    def body_outputs(self, q, v) -> np.ndarray:
        """(n_bodies, 6): mass centre and angular velocity (global frame) per body."""
        return self._get("body_outputs", q, v)

    # -- solves -------------------------------------------------------------------------
    def accelerations(self, q, v) -> np.ndarray:
        """q'' from M q'' + B^T lambda = f - h, B q'' = -(dB/dt) v."""
        return self._engine.accelerations(q, v)

    def project_positions(self, q):
        """(q_new, iterations): Newton projection onto g(q) = 0 with M-weighted minimal
        corrections. Raises SimulationError when it does not converge."""
        q_new, iterations, converged, residual = self._engine.project_positions(q)
        if not converged:
            raise SimulationError(
                f"position projection did not converge: max |g_k|/|B_k| = {residual:.3g} "
                f"after {iterations} Newton iterations (tolerance {self.position_tol:.3g})")
        return q_new, iterations

    def project_velocities(self, q, v) -> np.ndarray:
        """The M-orthogonal projection of v onto B(q) v = 0."""
        return self._engine.project_velocities(q, v)

    def initial_state(self) -> InitialState:
        """The model's initial positions assembled onto the constraints and its initial
        speeds projected onto B q' = 0, with the residuals before and after."""
        plan = self.plan
        q_given = np.array(plan.q0, dtype=float)
        given = _amax(self.constraints(q_given))
        try:
            q, iterations = self.project_positions(q_given)
        except SimulationError as exc:
            raise SimulationError(f"{plan.model.source}: the initial positions cannot be "
                                  f"assembled onto the constraints: {exc}") from None
        v = self.project_velocities(q, plan.v_target)
        return InitialState(q=q, v=v, position_residual_given=given,
                            position_residual=_amax(self.constraints(q)),
                            newton_iterations=iterations,
                            velocity_change=_amax(v - plan.v_target),
                            velocity_residual=_amax(self.constraint_jacobian(q) @ v))

    # -- simulation ---------------------------------------------------------------------
    def simulate(self, t_end=None, dt=None, method=None, output_dt=None, project=True,
                 q0=None, v0=None, progress=None) -> Result:
        """Integrate from (q0, v0), used as given, to t_end with steps dt, the last one
        shortened to land on t_end. q0 None: the consistent :meth:`initial_state`;
        only v0 None: the model's initial speeds projected at q0.

        Results at t = 0, every output_dt (a multiple of dt) and t_end. project: after
        each step, Newton position projection then velocity projection. progress: called
        with a one-line message (``"t = ..."``) at most about every 0.5 s of wall time.
        """
        t_end, dt, method, every, n_steps = self._schedule(t_end, dt, method, output_dt)
        if q0 is None:
            init = self.initial_state()
            q0, v0 = init.q, (init.v if v0 is None else v0)
        elif v0 is None:
            v0 = self.project_velocities(q0, self.plan.v_target)
        report = None
        if progress is not None:
            def report(t):
                progress(f"t = {t:.6g} of {t_end:.6g} ({100.0 * t / t_end:.0f}%)")
        start = time.perf_counter()
        arrays, stats = simulate_rk4(self._engine, q0, v0, t_end, dt, n_steps, every,
                                     bool(project), report)
        info = dict(method=method, dt=dt, steps=stats["steps"],
                    rhs_evaluations=stats["rhs_evaluations"],
                    max_newton_iterations=stats["max_newton_iterations"],
                    projection_failures=stats["projection_failures"],
                    wall_time=time.perf_counter() - start,
                    max_constraint_error=stats["max_constraint_error"],
                    project=bool(project))
        return result_from_arrays(self.plan, arrays["t"], arrays["q"], arrays["v"],
                                  arrays["body"], arrays["energy"],
                                  arrays["constraint_error"], info)

    def _schedule(self, t_end, dt, method, output_dt):
        """Defaults from the model's ``simulate`` section, checked; returns
        (t_end, dt, method, output_every, n_steps)."""
        d = self.plan.model.simulate
        t_end = float(d.t_end if t_end is None else t_end)
        dt = float(d.dt if dt is None else dt)
        method = d.method if method is None else method
        if method not in METHODS:
            raise ValueError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
        for name, value in (("t_end", t_end), ("dt", dt)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number (got {value!r})")
        if output_dt is None:
            output_dt = d.output_dt if d.output_dt is not None else dt
        output_dt = float(output_dt)
        ratio = output_dt / dt
        every = round(ratio) if math.isfinite(ratio) else 0
        if every < 1 or abs(ratio - every) > 1e-9 * ratio:
            raise ValueError(f"output_dt must be a positive multiple of dt = {dt!r} "
                             f"(got {output_dt!r})")
        n_steps = max(1, math.ceil(t_end / dt - 1e-9))
        return t_end, dt, method, every, n_steps

    # -- timing (for fccgen bench) ---------------------------------------------------------
    def time_kernels(self, q, v, repeats=200) -> dict:
        """Seconds per global assembly of each kernel the module has (median of warm,
        batched runs in compiled loops)."""
        return {name: _median_time(lambda b, f=flag: self._asm.time_assembly(f, q, v, b),
                                   repeats)
                for name, flag in self._asm.kernel_flags().items()}

    def time_accelerations(self, q, v, repeats=200) -> float:
        """Seconds per evaluation of the accelerations (assembly, factorisation, solve)."""
        return _median_time(lambda b: self._engine.time_accelerations(q, v, b), repeats)


def _amax(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.max(np.abs(x))) if x.size else 0.0


def _median_time(run_batch, repeats: int, min_batch_seconds: float = 2e-4) -> float:
    """Median seconds per call; ``run_batch(b)`` returns the seconds of b calls."""
    run_batch(1)
    batch = 1
    while run_batch(batch) < min_batch_seconds and batch < 1 << 20:
        batch *= 2
    samples = [run_batch(batch) / batch for _ in range(max(repeats // 10, 5))]
    return statistics.median(samples)
