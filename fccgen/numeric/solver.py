"""NumericSolver: the NumPy version of the solver (docs/design.md §3), with the same
interface as the compiled one. It is the cross-check in tests and the baseline in
benchmarks, so it favours plain, readable NumPy over speed.

Global quantities are sums of element kernels scattered to the elements' coordinate
slots (``Element.q_index()``); constraint rows follow the elements' order.
"""
from __future__ import annotations

import numpy as np

from ..settings import methods as registry
from .. import rank as rank_rule
from ..runs.explain import explained
from ..runs.locate import step_setting
from ..mechanism.driver_branch import check_driver_branches
from ..mechanism.driver_forces import add_driver_columns, driver_rows
from ..mechanism.outputs import settle_turns
from ..mechanism.initial_positions import assemble_at_joints
from ..mechanism.initial_speeds import initial_speeds
from ..mechanism.reactions import add_reactions
from . import record_loads
from ..settings.run import linear_solver_choice, solver_tolerances
from ..errors import FccgenError, SimulationError
from ..progress import run_reporter
from ..plan import Plan
from ..results.result import InitialState, Result, timed_run
from .constrained import RankKeeper, constrained_solve, scaled_residual
from ..runs import held_rows
from ..runs.energy_check import check_energy, kinetic_peak
from ..runs.guards import check_constraint_drift, divergence_bounds
from ..runs.inputs import input_run
from ..plan.classes import input_parameter
from .dopri5 import simulate_dopri5
from .runs import RunContext, simulate_baumgarte, simulate_rk4, simulate_scipy
from .work import work_power
from .elements import element_kernels
from .references import AngleReferences
from . import sparse_projection


# kernels whose output is an n_q x n_q block of the element's coordinates
SQUARE = ("mass_matrix", "force_jacobian_q", "force_jacobian_v")

class NumericSolver:
    """Assembly, constrained solve, projections and integration in NumPy."""

    element_kernels = staticmethod(element_kernels)   # the items a failure names


    def __init__(self, plan: Plan, *, rank_tol: float | None = None,
                 position_tol: float | None = None, max_newton: int | None = None,
                 linear_solver: str | None = None):
        self.plan = plan
        self.n_q = plan.n_q
        self.n_g = plan.n_g
        self.length_scale = _length_scale(plan)
        self.rank_tol, self.position_tol, self.max_newton = solver_tolerances(
            plan.model.simulate, self.length_scale, rank_tol, position_tol, max_newton)
        # checked and kept, for the same options as the compiled solver; the NumPy
        # version has one (dense) constrained solve
        self.linear_solver = linear_solver_choice(plan.model.simulate, linear_solver)
        self._index = [el.q_index() for el in plan.elements]
        offsets = np.cumsum([0] + [el.cls.n_g for el in plan.elements])
        self._rows = [np.arange(a, b) for a, b in zip(offsets[:-1], offsets[1:])]
        self.row_groups = plan.row_groups
        self._rank = RankKeeper(groups=self.row_groups)
        # parameters per element; set_time writes t into the slots named "t"
        self._params = [np.array(el.params, float) for el in plan.elements]
        self._time_slots = [(k, el.cls.param_names.index("t"))
                            for k, el in enumerate(plan.elements)
                            if "t" in el.cls.param_names]
        self.t = 0.0
        self._held = None                 # the inputs of a run (fccgen.runs.inputs)
        self.input_values = dict(getattr(plan.model, "inputs", {}))   # held now (events)
        # turn counting of springs and loads of joint angles (numeric/references.py)
        self.references = AngleReferences(plan, self._params, self._index)

    def rebase_angles(self, q) -> None:
        """Move the elements' angle references to their angles at q (after every
        accepted step of a run; numeric/references.py)."""
        if self.references:
            self.references.rebase(q)

    def hold_inputs(self, record: int) -> None:
        """Set the inputs to their row of the record just written (a run with inputs
        that change: fccgen.runs.inputs; they hold until the next record)."""
        held = self._held
        if held is not None and not held.constant:
            self._put_inputs(held, held.table[record])

    def _put_inputs(self, held, row) -> None:
        """Write the inputs' values ``row`` (in held.names order) into the parameters
        of the elements that read them (and for the event functions)."""
        self.input_values.update(zip(held.names, (float(x) for x in row)))
        for k, el in enumerate(self.plan.elements):
            for name in el.cls.inputs:
                self._params[k][el.cls.param_names.index(input_parameter(name))] = \
                    row[held.names.index(name)]

    def put_params(self, slots, values) -> None:
        """Write values[i] into the concatenated element parameters at slots[i] (as
        the compiled assembler's put_params)."""
        starts = np.cumsum([0] + [len(p) for p in self._params])
        for slot, value in zip(np.asarray(slots, int), np.asarray(values, float)):
            e = int(np.searchsorted(starts, slot, side="right")) - 1
            self._params[e][slot - starts[e]] = value

    def set_time(self, t) -> None:
        """Evaluate the kernels at the time t from now on (models with drivers)."""
        self.t = float(t)
        for k, slot in self._time_slots:
            self._params[k][slot] = self.t

    # -- element evaluation ------------------------------------------------------------
    def _kernels(self, q, v):
        """(element, local index, row indices, kernels object) for every element."""
        q = np.asarray(q, float)
        v = None if v is None else np.asarray(v, float)
        for el, idx, rows, p in zip(self.plan.elements, self._index, self._rows,
                                    self._params):
            yield el, idx, rows, element_kernels(el.cls, q[idx],
                                                 None if v is None else v[idx], p)

    def _assemble(self, q, v, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """Global arrays of the named kernels at (q, v), in one pass over the elements."""
        out = {"mass_matrix": np.zeros((self.n_q, self.n_q)),
               "h_vector": np.zeros(self.n_q), "applied_forces": np.zeros(self.n_q),
               "constraints": np.zeros(self.n_g),
               "constraint_jacobian": np.zeros((self.n_g, self.n_q)),
               "constraint_bias": np.zeros(self.n_g),
               "constraint_rate": np.zeros(self.n_g),
               "force_jacobian_q": np.zeros((self.n_q, self.n_q)),
               "force_jacobian_v": np.zeros((self.n_q, self.n_q))}
        out = {n: out[n] for n in names}
        for el, idx, rows, k in self._kernels(q, v):
            for name in names:
                value = k.evaluate(name)
                if value is None:
                    continue
                if name in SQUARE:
                    np.add.at(out[name], (idx[:, None], idx[None, :]),
                              value.reshape(len(idx), len(idx)))
                elif name == "constraint_jacobian":
                    np.add.at(out[name], (rows[:, None], idx[None, :]),
                              value.reshape(len(rows), len(idx)))
                elif name in ("constraints", "constraint_bias", "constraint_rate"):
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

    def constraint_jacobian_sparse(self, q):
        """B at q as a SciPy CSR matrix from the element blocks (no dense n_g x n_q
        array; the compiled solver's method of the same name)."""
        return sparse_projection.sparse_jacobian(self, q)

    def _jacobian_for_rank(self, q):
        """B for fccgen.rank.decide: sparse for models it decides a component at a
        time (no dense SVD, no dense array)."""
        if self.n_q > rank_rule.dense_columns_max():
            return self.constraint_jacobian_sparse(q)
        return self.constraint_jacobian(q)

    def constraint_bias(self, q, v) -> np.ndarray:
        return self._assemble(q, v, ("constraint_bias",))["constraint_bias"]

    def constraint_rate(self, q) -> np.ndarray:
        """Partial dg/dt at the time of :meth:`set_time` (zero without drivers)."""
        return self._assemble(q, None, ("constraint_rate",))["constraint_rate"]

    def force_jacobian_q(self, q, v) -> np.ndarray:
        """df/dq of the applied forces (the tangent's K is its negative)."""
        return self._assemble(q, v, ("force_jacobian_q",))["force_jacobian_q"]

    def force_jacobian_v(self, q, v) -> np.ndarray:
        """df/dq' of the applied forces (the tangent's C is its negative)."""
        return self._assemble(q, v, ("force_jacobian_v",))["force_jacobian_v"]

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
                                 -a["constraint_bias"], self.rank_tol, self._rank)

    def project_velocities(self, q, v) -> np.ndarray:
        """The speeds nearest to v in the kinetic-energy metric with B v = -dg/dt
        (0 without drivers). A large model (more coordinates than
        fccgen.rank.dense_columns_max()) with its rank decided takes the sparse KKT
        solve (numeric/sparse_projection.py) instead of the O(n^3) dense one, and
        v = 0 with dg/dt = 0 is returned as its own projection."""
        v = np.asarray(v, float)
        if self.n_q > rank_rule.dense_columns_max():
            rate = self.constraint_rate(q)
            if not np.any(v) and not np.any(rate):
                return np.zeros(self.n_q)
            if self._rank.rank >= 0:
                done = sparse_projection.project_velocities(self, q, v, -rate,
                                                            self._rank.rank)
                if done is not None:
                    return done
        a = self._assemble(q, None, ("mass_matrix", "constraint_jacobian",
                                     "constraint_rate"))
        M = a["mass_matrix"]
        self._rank.check_growth = True          # q is on the constraints (projected)
        try:
            return constrained_solve(M, a["constraint_jacobian"], M @ np.asarray(v, float),
                                     -a["constraint_rate"], self.rank_tol, self._rank)
        finally:
            self._rank.check_growth = False

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
            q = q + constrained_solve(M, B, zero, -g, self.rank_tol, self._rank)
            g, B = self.constraints(q), self.constraint_jacobian(q)
        raise SimulationError(
            f"position projection did not converge in {self.max_newton} Newton iterations: "
            f"scaled constraint residual max |g_k|/||B_k|| = {residual:.3g} > tolerance "
            f"{self.position_tol:.3g}")

    def initial_state(self) -> InitialState:
        """plan.q0 assembled onto the constraints and plan.v_target made consistent."""
        self.set_time(0.0)
        q_given = np.array(self.plan.q0, float)
        try:
            q, iterations = self.project_positions(q_given)
        except SimulationError as exc:
            raise explained(SimulationError(
                f"the initial positions cannot be assembled onto the constraints: {exc}"),
                self, q_given) from None
        q = assemble_at_joints(self, q)
        self.decide_rank(q)
        v_given = np.array(self.plan.v_target, float)
        try:
            v = initial_speeds(self, q, v_given)
        except SimulationError as exc:
            raise explained(exc, self, q) from None
        return InitialState(
            q=q, v=v,
            position_residual_given=_amax(self.constraints(q_given)),
            position_residual=_amax(self.constraints(q)),
            newton_iterations=iterations,
            velocity_change=_amax(v - v_given),
            velocity_residual=_amax(self.constraint_jacobian(q) @ v
                                    + self.constraint_rate(q)))

    def baumgarte_accelerations(self, q, v, alpha: float, beta: float) -> np.ndarray:
        """q'' of the index-1 equations with Baumgarte stabilisation:
        B q'' = -(dB/dt) q' - 2 alpha B q' - beta^2 g."""
        a = self._assemble(q, v, ("mass_matrix", "h_vector", "applied_forces",
                                  "constraint_jacobian", "constraint_bias", "constraints",
                                  "constraint_rate"))
        B = a["constraint_jacobian"]
        g_dot = B @ np.asarray(v, float) + a["constraint_rate"]
        b = (-a["constraint_bias"] - 2.0 * alpha * g_dot
             - beta * beta * a["constraints"])
        return constrained_solve(a["mass_matrix"], B, a["applied_forces"] - a["h_vector"],
                                 b, self.rank_tol, self._rank)

    def simulate(self, t_end=None, dt=None, method=None, output_dt=None, project=True,
                 q0=None, v0=None, progress=None, rtol=None, atol=None,
                 reactions=True, event_tol=1e-12, rest_speed=1e-6, error=None,
                 error_on=None, inputs=None, event_location="steps",
                 **method_options) -> Result:
        """Integrate from (q0, v0), used as given; when q0 is None the consistent
        initial state is used, and when only v0 is None plan.v_target is projected at
        q0. The arguments mean what they mean for
        :meth:`fccgen.runtime.CompiledSolver.simulate`; defaults of t_end, dt, method
        and output_dt come from the model file; error, error_on: an error target
        (fccgen.target_error). Events (numeric/events.py) are located by rk4 and dopri5
        with projection, as in the compiled runtime. inputs: as the compiled
        runtime's (fccgen.runs.inputs): sampled at the output times, held between.
        event_location: "steps" only (the numeric version is the compiled runtime's
        check: its events are bracketed by partial steps, SciPy's brentq)."""
        if event_location != "steps":
            raise ValueError(f"the numeric version locates events by partial steps "
                             f"only (event_location='steps'), not {event_location!r}")
        if error is not None and inputs:
            raise ValueError("an error target (error=) chooses its own runs; give "
                             "inputs to a run with a method and step instead")
        if error is not None:
            from ..target_error import simulate_to_error
            return simulate_to_error(self, error, error_on, t_end=t_end, output_dt=output_dt,
                                     method=method, q0=q0, v0=v0, progress=progress,
                                     reactions=reactions,
                                     **({} if project else {"project": project}),
                                     dt=dt, rtol=rtol, atol=atol,
                                     **method_options)
        d = self.plan.model.simulate
        m = registry.get(d.method if method is None else method, tuple(INTEGRATORS))
        opts = registry.options_for(m, rtol, atol, method_options)
        sched = registry.schedule(m, d, t_end, dt, output_dt, opts)
        held = input_run(self.plan, inputs, m.name, sched)
        if held is None:
            return self._simulate_held(m, opts, sched, dt, project, q0, v0, progress,
                                       reactions, event_tol, rest_speed)
        self._held = held
        self._put_inputs(held, held.table[0])
        try:
            return self._simulate_held(m, opts, sched, dt, project, q0, v0, progress,
                                       reactions, event_tol, rest_speed)
        finally:
            self._held = None
            self._put_inputs(held, [self.plan.model.inputs[n] for n in held.names])

    def _simulate_held(self, m, opts, sched, dt, project, q0, v0, progress, reactions,
                       event_tol, rest_speed) -> Result:
        """One run (:meth:`simulate`) with the inputs set."""
        self.set_time(0.0)
        if q0 is None:
            init = self.initial_state()
            q0, v0 = init.q, (init.v if v0 is None else v0)
        elif v0 is None:
            v0 = self.project_velocities(q0, self.plan.v_target)
        project = bool(project) and m.projects
        decision = self.decide_rank(q0)
        report = run_reporter(progress, sched.t_end)
        ctx, untracked = self._context(m, sched, project, q0, v0, event_tol, rest_speed)
        kept = {}

        def run():
            arrays, stats = INTEGRATORS[m.name](self, np.array(q0, float),
                                                np.array(v0, float), sched, opts,
                                                project, report, ctx=ctx)
            kept["work"] = arrays.pop("work", None) if ctx.power is not None else None
            return arrays, stats
        self.references.start()
        try:
            result = timed_run(self.plan, m, sched, opts, project, run,
                               settings=self.settings())
        except SimulationError as exc:
            raise explained(exc, self, q0, v0, step_setting(m, sched, opts, dt)) from None
        except FccgenError:
            raise
        except (ArithmeticError, ValueError) as exc:  # a load's arithmetic in NumPy
            raise explained(SimulationError(f"the run cannot be evaluated ({exc})"), self,
                            q0, v0, step_setting(m, sched, opts, dt)) from None
        finally:
            turn = self.references.largest_turn
            self.references.restore()          # direct kernel calls: as planned
        numeric_turn_check(result, turn)
        if report is not None:
            report.finish(result.t[-1])          # the run's end: 100%
        if ctx.events is not None:
            finish_events(result, ctx.events)
        locks = None if ctx.events is None else held_rows.of_run(
            self, result, held_quantities(ctx.events))
        loads = record_loads.of_run(self.plan, self.put_params, self._held, sched,
                                    events=result.events or ())
        settle_turns(self.plan, result)
        add_driver_columns(self, result, locks, loads)
        check_driver_branches(self.plan, result)
        rank_rule.report_run(result, decision, self._rank.stats,
                             driven=bool(driver_rows(self.plan)))
        if ctx.events is not None:
            from ..events.table import final_dof
            result.info["final_dof"] = final_dof(result.info, result.events)
        check_constraint_drift(self, result, project)
        check_energy(result, self.plan, kinetic_peak(self, result, None), kept.get("work"),
                     untracked)
        if not reactions:
            return result
        return add_reactions(self, result, locks, loads)

    def _context(self, m, sched, project, q0, v0, event_tol, rest_speed):
        """(the numeric.runs.RunContext of a run of method m, why its work is not
        tracked or None)."""
        events = None
        if self.plan.model.events:
            if m.name not in ("rk4", "dopri5") or not project:
                raise ValueError(f"events are located by the rk4 and dopri5 methods with "
                                 f"projection, not by {m.name}"
                                 + ("" if project else " without projection"))
            from .events import NumericEvents
            events = NumericEvents(self, event_tol, rest_speed)
        power, untracked = work_power(self)
        q_bound, v_bound = divergence_bounds(q0, v0, sched.t_end,
                                             sched.dt if m.kind == "fixed" else None)
        return RunContext(events, power, q_bound, v_bound, self.rebase_angles), untracked

    def kinetic_energy(self, q, v) -> float:
        """The kinetic energy (the elements' energy kernels' first entry)."""
        total = 0.0
        for _, _, _, k in self._kernels(q, v):
            e = k.evaluate("energy")
            if e is not None:
                total += float(e[0])
        return total

    def settings(self) -> dict:
        """The solver's tolerances, as result.info["solver"] records them."""
        return {"rank_tol": self.rank_tol, "position_tol": self.position_tol,
                "max_newton": self.max_newton}

    def __repr__(self) -> str:
        """Model, coordinates, constraint equations, DOF if decided, method and the
        linear solver (NumPy: always the dense solve, no build)."""
        from ..results.summary import solver_repr
        return solver_repr(self, self._rank.rank, "dense (NumPy)", None)

    def decide_rank(self, q) -> rank_rule.RankDecision:
        """Decide the rank of B at q (fccgen.rank) and keep it until the next decision,
        as the compiled solver does."""
        decision = rank_rule.decide(self._jacobian_for_rank(q), self.n_q, self.row_groups)
        self._rank.decide(decision.rank)
        return decision


INTEGRATORS = {"rk4": simulate_rk4, "dopri5": simulate_dopri5,
               "baumgarte": simulate_baumgarte,
               **{f"scipy-{m}": simulate_scipy(m)
                  for m in ("RK45", "DOP853", "Radau", "BDF", "LSODA")}}


def held_quantities(events):
    """rows(q, v, keys) of fccgen.runs.held_rows.HeldRows: the gradients and biases
    of the joint quantities ``keys`` (the NumPy events' own)."""
    def rows(q, v, keys):
        out = [events.quantities[key].gradient_rate_bias(q, v) for key in keys]
        return (np.array([g for g, _, _ in out]).reshape(len(out), len(q)),
                np.array([b for _, _, b in out]))
    return rows


def finish_events(result, events) -> None:
    """The event table of a run with events (as the compiled runtime's), its switch
    warnings and the energy drift with the impacts' losses added back."""
    from ..events.table import energy_balance, event_rows, report_switches
    from .events import ACTIONS, NOTES
    log = events.table()
    result.events = event_rows(events.names, ACTIONS, log)
    result.info["events"] = result.events
    report_switches(result, log, NOTES)
    result.info["energy_drift"], result.info["event_energy_loss"] = energy_balance(
        result.t, result["energy"], result.events)


def numeric_turn_check(result, turn: tuple[float, str]) -> None:
    """Warn when an element's angle moved more than a quarter turn between two
    re-basings (the compiled runtime's turn_check, on the NumPy references)."""
    import warnings

    from ..errors import RunWarning
    if turn[0] > 0.5 * np.pi:
        text = (f"the angle of {turn[1]} turned {turn[0]:.3g} rad within one step: angles "
                f"are counted over turns from step to step and need less than half a turn "
                f"per step; rerun with a smaller dt (or tighter rtol) and compare")
        result.info.setdefault("warnings", []).append(text)
        warnings.warn(text, RunWarning, stacklevel=3)


def _amax(x) -> float:
    x = np.asarray(x, float)
    return float(np.max(np.abs(x))) if x.size else 0.0


def _length_scale(plan: Plan) -> float:
    """The largest body length l (or cable length) of the plan, 1 if it has none."""
    lengths = [el.params[el.cls.scalar_names.index("l")]
               for el in plan.elements if el.cls.kind == "body"]
    lengths += [c.length for c in plan.model.cables.values()]
    return float(max(lengths)) if lengths else 1.0
