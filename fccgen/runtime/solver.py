"""CompiledSolver: the Python face of the compiled engine for one model.

The same interface as :class:`fccgen.numeric.NumericSolver`; every array it returns is
a fresh array owned by the caller (docs/design.md §7). Python runs once per call: a
simulation is one call into the engine, which keeps the per-step loop in C.
"""
from __future__ import annotations

import functools
import importlib
import statistics
import time

import numpy as np

from ..settings import methods as registry
from .. import rank as rank_rule
from ..runs.explain import explained
from ..runs.locate import step_setting
from ..numeric.elements import element_kernels
from ..numeric import record_loads
from ..mechanism.driver_branch import check_driver_branches
from ..mechanism.driver_forces import add_driver_columns, driver_rows
from ..mechanism.outputs import settle_turns
from ..mechanism.initial_positions import assemble_at_joints
from ..mechanism.initial_speeds import initial_speeds
from ..mechanism.reactions import add_reactions
from ..settings.run import linear_solver_choice, solver_tolerances
from ..errors import SimulationError
from ..progress import run_reporter
from ..results.result import InitialState, Result, timed_run
from ..threads import single_threaded_blas
from ._assemble import FLAGS
from ._dopri5 import simulate_dopri5
from .paths import (SPARSE_MIN_COORDINATES, make_engine, pattern_samples,
                    reduced_mass_spread, small_model_path, use_sparse)
from ._rk4 import simulate_baumgarte, simulate_rk4
from ..runs import held_rows
from ..runs.energy_check import check_energy, kinetic_peak
from ..runs.guards import check_constraint_drift
from .assembler import make_assembler, time_slots
from .setup_reuse import (SetupStore, jacobian_key, kept_decision, kept_initial_state,
                          shared_decision)
from .turns import REBASING, turn_check
from .event_settings import check_event_location
from ..runs.inputs import input_run
from .work import work_tracker


def _available_methods() -> tuple[str, ...]:
    """Registry methods whose compiled loop is importable."""
    out = []
    for name in registry.names():
        module = registry.OPTIONAL_COMPILED.get(name)
        if module is not None:
            try:
                importlib.import_module(f"{__package__}.{module}")
            except ImportError:
                continue
        out.append(name)
    return tuple(out)


METHODS = _available_methods()
# How far (times the length scale) the rank is tested off the constraints for rows
# dependent only on them (CompiledSolver._manifold_redundancy), and the fixed seed.
OFF_MANIFOLD = 1e-3
OFF_MANIFOLD_SEED = 20261123


def length_scale(plan) -> float:
    """The largest body length ``l`` (or cable length) of the plan (1 if it has
    none)."""
    lengths = [el.params[el.cls.param_names.index("l")] for el in plan.elements
               if el.cls.kind == "body"]
    lengths += [c.length for c in plan.model.cables.values()]
    return float(max(lengths)) if lengths else 1.0


class CompiledSolver:
    """Assembly, constrained solve, projections and the integration methods of
    :mod:`fccgen.settings.methods` for one model, the per-step loops in compiled code.

    plan: the model's :class:`fccgen.plan.Plan`; module: its generated kernel module.
    rank_tol: QR pivot ratio at or below which a constraint row counts as lost at a
    singular position (fccgen.rank); position_tol: Newton projection tolerance on
    max_k |g_k| / ||B_k||; max_newton: its iteration limit. Each defaults to the
    model's simulate section, else fccgen.settings.run (1e-10, 1e-11 times the largest
    body length, 20). linear_solver: "dense", "sparse" or "auto" (by size;
    fccgen.runtime.paths), default the model's simulate.linear_solver, else "auto".

    progress_interval: wall-clock seconds between a run's pauses, where it reports its
    progress and sees Ctrl-C (0: after every step).
    """

    element_kernels = staticmethod(element_kernels)   # the items a failure names

    progress_interval = 0.5

    def __init__(self, plan, module, *, rank_tol=None, position_tol=None, max_newton=None,
                 linear_solver=None, events_module=None):
        self.plan = plan
        self.module = module
        self.events_module = events_module
        self.n_q = plan.n_q
        self.n_g = plan.n_g
        self.length_scale = length_scale(plan)
        self.rank_tol, self.position_tol, self.max_newton = solver_tolerances(
            plan.model.simulate, self.length_scale, rank_tol, position_tol, max_newton)
        self._asm = make_assembler(plan, module)
        self.row_groups = plan.row_groups
        self.linear_solver = linear_solver_choice(plan.model.simulate, linear_solver)
        self.setup_store = SetupStore(self)      # set-ups kept per start (setup_reuse)
        # events run on both paths (engine/fcc_events.c): auto chooses by size alone.
        # For a small model under auto this is only the size's guess until a run's rank
        # decision settles it (_choose_small_path); a run's info["path"] says which
        # path it took.
        self.sparse = use_sparse(self.linear_solver, self.n_q)
        # auto below SPARSE_MIN_COORDINATES: dense until a rank decision shows the
        # sparse solve well posed (paths.small_model_path), decided again every run
        self._auto_small = (self.linear_solver == "auto"
                            and self.n_q < SPARSE_MIN_COORDINATES)
        self._engine = self._new_engine(self.sparse)
        self._decided_at = None
        self._manifold_key = None
        self._manifold_kept = 0.0
        self._manifold_rises = True          # until _manifold_redundancy tests it
        self._dense_engine = None if self.sparse else self._engine
        self._sparse_engine = self._engine if self.sparse else None

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

    def force_jacobian_q(self, q, v) -> np.ndarray:
        """df/dq of the applied forces (the tangent's K is its negative)."""
        return self._get("force_jacobian_q", q, v)

    def force_jacobian_v(self, q, v) -> np.ndarray:
        """df/dq' of the applied forces (the tangent's C is its negative)."""
        return self._get("force_jacobian_v", q, v)

    def constraint_jacobian(self, q) -> np.ndarray:
        return self._get("constraint_jacobian", q)

    def constraint_jacobian_sparse(self, q):
        """B at q as a SciPy CSR matrix, assembled from the element blocks (no dense
        n_g x n_q array: what large models use)."""
        from .sparsity import jacobian_csr
        return jacobian_csr(self._asm, q)

    def _jacobian_for_rank(self, q):
        """B for fccgen.rank.decide: sparse for models it decides a component at a time."""
        if self.n_q > rank_rule.dense_columns_max():
            return self.constraint_jacobian_sparse(q)
        return self.constraint_jacobian(q)

    def _jacobian_for_decision(self, q):
        """B for the rank decisions (decide_rank, _manifold_redundancy): sparse above
        SPLIT_COLUMNS coordinates, where fccgen.rank decides a component at a time from
        a sparse B anyway (the same entries: no dense n_g x n_q array to fill, hash and
        convert)."""
        if self.n_q > rank_rule.SPLIT_COLUMNS:
            return self.constraint_jacobian_sparse(q)
        return self.constraint_jacobian(q)

    def constraint_bias(self, q, v) -> np.ndarray:
        return self._get("constraint_bias", q, v)

    def energy(self, q, v) -> float:
        """Total energy, kinetic plus potential."""
        kinetic, potential = self._get("energy", q, v)
        return float(kinetic + potential)

    def kinetic_energy(self, q, v) -> float:
        return float(self._get("energy", q, v)[0])

    def body_outputs(self, q, v) -> np.ndarray:
        """(n_bodies, 6): mass centre and angular velocity (global frame) per body."""
        return self._get("body_outputs", q, v)

    def constraint_rate(self, q) -> np.ndarray:
        """Partial dg/dt at the time of :meth:`set_time` (zero without drivers)."""
        return self._get("constraint_rate", q)

    def put_params(self, slots, values) -> None:
        """Write values[i] into the concatenated element parameters at slots[i]: later
        kernel calls read them (the model's inputs, angle references)."""
        self._asm.put_params(slots, values)

    def set_time(self, t) -> None:
        """Evaluate the kernels at the time t from now on (models with drivers; the
        integrators set it at every stage)."""
        self._asm.set_time(float(t))

    # -- solves -------------------------------------------------------------------------
    def accelerations(self, q, v) -> np.ndarray:
        """q'' from M q'' + B^T lambda = f - h, B q'' = -(dB/dt) v."""
        return self._engine_call(lambda e: e.accelerations(q, v))

    def project_positions(self, q):
        """(q_new, iterations): Newton projection onto g(q) = 0 with M-weighted minimal
        corrections. Raises SimulationError when it does not converge."""
        q_new, iterations, converged, residual = self._engine_call(
            lambda e: e.project_positions(q))
        if not converged:
            raise SimulationError(
                f"position projection did not converge: max |g_k|/|B_k| = {residual:.3g} "
                f"after {iterations} Newton iterations (tolerance {self.position_tol:.3g})")
        return q_new, iterations

    def project_velocities(self, q, v) -> np.ndarray:
        """The M-orthogonal projection of v onto B(q) v = 0."""
        return self._engine_call(lambda e: e.project_velocities(q, v))

    def initial_state(self) -> InitialState:
        """The model's initial positions assembled onto the constraints and its initial
        speeds projected onto B q' = 0, with the residuals before and after (kept for
        the next call from the same start: fccgen.runtime.setup_reuse)."""
        return kept_initial_state(self, self._fresh_initial_state)

    def _fresh_initial_state(self) -> InitialState:
        plan = self.plan
        self.set_time(0.0)
        q_given = np.array(plan.q0, dtype=float)
        given = _amax(self.constraints(q_given))
        try:
            q, iterations = self.project_positions(q_given)
        except SimulationError as exc:
            raise explained(SimulationError(
                f"the initial positions cannot be assembled onto the constraints: {exc}"),
                self, q_given) from None
        q = assemble_at_joints(self, q)
        self.decide_rank(q)
        try:
            v = initial_speeds(self, q, plan.v_target)
        except SimulationError as exc:
            raise explained(exc, self, q) from None
        return InitialState(q=q, v=v, position_residual_given=given,
                            position_residual=_amax(self.constraints(q)),
                            newton_iterations=iterations,
                            velocity_change=_amax(v - plan.v_target),
                            velocity_residual=_amax(self._jacobian_for_decision(q) @ v
                                                    + self.constraint_rate(q)))

    # -- simulation ---------------------------------------------------------------------
    def _pattern_tripped(self) -> bool:
        return self.sparse and getattr(self._engine, "pattern_tripped", False)

    def _new_engine(self, sparse: bool, full_pattern: bool = False):
        """An engine of this solver's tolerances (paths.make_engine); a sparse one takes
        its pattern at the model's written positions (paths.pattern_samples) unless
        full_pattern."""
        at = (pattern_samples(self.plan.q0, self.plan.v_target, self.length_scale)
              if sparse and not full_pattern else None)
        # the locked rows folded into the factorisation (engine/fcc_sparse_fold.c) on
        # models of at least SPARSE_MIN_COORDINATES coordinates, whichever way they
        # came to the sparse path; smaller ones keep the Schur complement: folded, the
        # solar array's (18 coordinates) rows cost more to fill than the solves they
        # save (its step 2.32 plain steps against 2.16), and its finite-difference
        # checks were measured with the Schur complement's rounding
        fold = sparse and self.n_q >= SPARSE_MIN_COORDINATES
        return make_engine(self._asm, self.rank_tol, self.position_tol, self.max_newton,
                           sparse, at=at,
                           switchable=self._switchable_patterns if fold else None)

    # Folded runs choose between the fold and the Schur complement after each switch,
    # by measuring a few steps of each (engine/fcc_events_fold.c, "Which is cheaper");
    # False keeps the fold (tests of the fold itself).
    _fold_trial = True

    @functools.cached_property
    def _switchable_patterns(self):
        """Per joint quantity of the model's events, the coordinates its gradient reads
        when an event switches it (paths.switchable_patterns; None: no events). The
        sparse path folds them into its factorisation's pattern."""
        if not self.plan.model.events or self.events_module is None:
            return None
        from ._events import EventSet
        from .paths import switchable_patterns
        st = self._event_settings
        probe = EventSet(self.events_module, self.n_q, st.directions, st.actions,
                         st.rows, st.rows2, st.restitution, st.angle_rows,
                         constants=st.constants)
        probe.reset(self.plan.q0)
        return switchable_patterns(probe, self.plan.q0, self.length_scale,
                                   list(st.rows) + list(st.rows2))

    def _full_pattern(self) -> None:
        """The sparse engine again, on the full pattern of A (every element block
        full), with the rank decided where the last decision was made."""
        self._engine = self._sparse_engine = self._new_engine(True, full_pattern=True)
        if self._decided_at is not None:
            self.decide_rank(self._decided_at)

    def _engine_call(self, call):
        """call(engine), redone once on the full pattern when the sparse engine's
        pattern of A, read at the written positions, no longer holds
        (paths.pattern_samples)."""
        try:
            return call(self._engine)
        except SimulationError:
            if not self._pattern_tripped():
                raise
        self._full_pattern()
        return call(self._engine)

    def simulate(self, t_end=None, dt=None, method=None, output_dt=None, project=True,
                 q0=None, v0=None, progress=None, rtol=None, atol=None,
                 reactions=True, event_tol=1e-12, rest_speed=1e-6, error=None,
                 error_on=None, inputs=None, sensitivities=None,
                 event_location="steps", **method_options) -> Result:
        """Integrate from (q0, v0), used as given, to t_end. q0 None: the consistent
        :meth:`initial_state`; only v0 None: the model's initial speeds projected at q0.

        method: a name of :mod:`fccgen.settings.methods` (default: the model's). Fixed-step
        methods take steps dt, the last one shortened to land on t_end, and record at 0,
        every output_dt (a multiple of dt) and t_end. Adaptive methods take dt as the
        first step (None: automatic), rtol and atol, and record at multiples of
        output_dt by dense output. project: after each (accepted) step, Newton position
        projection then velocity projection, for the methods that project.
        method_options: the method's options (e.g. alpha, beta for baumgarte).
        progress: called with a :class:`~fccgen.progress.ProgressEvent` (stage
        "simulate", done = t of total = t_end; its text ``"t = ... of ..."``) at most
        about every 0.5 s of wall time. It may call this solver; one that does not can
        say so (an attribute ``reads_only = True``, fccgen.progress.reads_only), and
        the run's numbers are then those of a run without it. ``result.info`` holds fccgen.settings.methods.INFO_KEYS and more.
        reactions: add the joint reaction columns of a mechanism-level model
        (fccgen.mechanism.reactions; ``result.info["reactions"]`` says whether they
        are unique, or why they are absent).
        event_tol: events are located to this time (seconds); rest_speed: a bounce
        slower than this rests on its limit (docs/events.md). event_location (rk4):
        "steps", the crossing bracketed by re-integrated partial steps; "interpolant",
        located on the step's interpolant and the state there taken from it, so that
        an event step costs two steps' evaluations and one more, whatever the
        crossing (dopri5 always locates on its continuous extension; docs/events.md
        "Location"). ``result.events``: the
        event table (fccgen.events.table), also kept in ``result.info["events"]`` so
        that every file format carries it.
        error: the largest position error accepted over the run (model length units;
        error_on: the points or columns it is measured on): the method and its setting
        are chosen by a measured pilot and the run reports ``info["error_estimate"]``
        (fccgen.target_error, docs/accuracy.md).
        inputs: the model's inputs, name -> a number, a function of t or a table
        (times, values), sampled at each output time and held until the next
        (fccgen.runs.inputs, docs/model-file.md "Inputs"); an input not given keeps
        its start value.
        sensitivities: parameter keys (``with_parameters`` keys, e.g.
        ``["bodies.arm.mass", "loads[0].stiffness"]``); their derivatives are
        integrated with the motion and read with ``result.sensitivity(column, key)``
        (fccgen.runtime.sensitivity, docs/sensitivities.md); methods rk4 and dopri5.
        With dopri5, ``sensitivity_error=True`` puts them into the error control.
        """
        if error is not None and inputs:
            raise ValueError("an error target (error=) chooses its own runs; give "
                             "inputs to a run with a method and step instead")
        check_event_location(event_location, sensitivities)
        if sensitivities is not None and error is not None:
            raise ValueError("sensitivities are integrated by one rk4 or dopri5 run: give "
                             "its dt or rtol, not an error target")
        if error is not None:
            from ..target_error import simulate_to_error
            return simulate_to_error(self, error, error_on, t_end=t_end, output_dt=output_dt,
                                     method=method, q0=q0, v0=v0, progress=progress,
                                     reactions=reactions,
                                     **({} if project else {"project": project}),
                                     event_tol=event_tol, rest_speed=rest_speed, dt=dt,
                                     rtol=rtol, atol=atol,
                                     **({} if event_location == "steps" else
                                        {"event_location": event_location}),
                                     **method_options)
        args = dict(t_end=t_end, dt=dt, method=method, output_dt=output_dt,
                    project=project, q0=q0, v0=v0, progress=progress, rtol=rtol,
                    atol=atol, reactions=reactions, event_tol=event_tol,
                    rest_speed=rest_speed, inputs=inputs,
                    sensitivities=sensitivities, event_location=event_location,
                    **method_options)
        # On the sparse path, a run whose motion leaves the pattern of A read at the
        # written positions (a model written in a plane that moves out of it) stops at
        # the first such assembly and is run again on the full pattern, once.
        return self._engine_call(lambda engine: self._simulate_once(**args))

    def _simulate_once(self, t_end, dt, method, output_dt, project, q0, v0, progress,
                       rtol, atol, reactions, event_tol, rest_speed, inputs=None,
                       sensitivities=None, event_location="steps",
                       **method_options) -> Result:
        """One run (:meth:`simulate`)."""
        d = self.plan.model.simulate
        m = registry.get(d.method if method is None else method, METHODS)
        keys = None
        sens_error = method_options.pop("sensitivity_error", None)
        if sens_error is not None and sensitivities is None:
            raise ValueError("sensitivity_error needs sensitivities=[...]")
        if sensitivities is not None:
            from .sensitivity import run as sensitivity_run
            keys = sensitivity_run.check_request(self, sensitivities, m.name,
                                                 bool(project) and m.projects, sens_error)
        opts = registry.options_for(m, rtol, atol, method_options)
        sched = registry.schedule(m, d, t_end, dt, output_dt, opts)
        held = input_run(self.plan, inputs, m.name, sched)
        if held is not None:                     # the start's values (constant: all)
            self._asm.put_params(held.slots, held.table[0, held.columns])
        try:
            return self._simulate_held(m, opts, sched, held, dt, project, q0, v0,
                                       progress, reactions, event_tol, rest_speed, keys,
                                       bool(sens_error), event_location)
        finally:
            if held is not None:                 # direct calls see the start values
                self._asm.put_params(held.slots, [self.plan.model.inputs[held.names[c]]
                                                  for c in held.columns])

    def _simulate_held(self, m, opts, sched, held, dt, project, q0, v0, progress,
                       reactions, event_tol, rest_speed, keys=None,
                       sens_error=False, event_location="steps") -> Result:
        """One run (:meth:`simulate`) with the inputs set (``held``); keys: the
        parameters of its sensitivities (checked), or None; sens_error: dopri5's error
        control includes them."""
        sens = sens_scale = sens_engine = None
        if keys is not None:
            from .sensitivity import run as sensitivity_run
        self.set_time(0.0)
        self.setup_store.start_run()
        with single_threaded_blas():      # the set-up's SVDs: as the run's solves
            q0, v0 = self._start_state(q0, v0)
            decision = self.decide_rank(q0)
        project = bool(project) and m.projects
        if keys is not None:
            from .params import module_directory
            sens_engine = sensitivity_run.engine_for(self, keys, m.name)
            sens = sensitivity_run.setup(self, keys, module_directory(self.module).parents[1],
                                         sens_engine)
            if sens_error:
                sens_scale = sensitivity_run.error_scale(self, keys)
        report = run_reporter(progress, sched.t_end)
        events = self._event_set(event_tol, rest_speed)
        self._event_inputs(events, held)
        tracker, untracked = work_tracker(self.plan, self.module, m.name,
                                          self.sparse and (sens_engine is None or
                                                           sens_engine is self._engine))
        kept = {}

        def run():
            arrays, stats = self._run(m, sched, opts, project, q0, v0, report, events,
                                      tracker, held, sens, sens_scale, sens_engine,
                                      event_location == "interpolant")
            kept["work"] = arrays.get("work") if tracker is not None else None
            return arrays, stats
        try:
            result = timed_run(self.plan, m, sched, opts, project, run,
                               settings=self.settings())
        except SimulationError as exc:
            raise explained(exc, self, q0, v0, step_setting(m, sched, opts, dt)) from None
        finally:
            if events is not None:
                log, turn, dropped = events.log(), events.largest_turn, events.dropped
                folded = (events.folded, events.fold_left, events.switch_solves,
                          events.fold_trials)
                events.restore()          # direct kernel calls: references as planned
        result.info["setup"] = self.setup_store.report()
        if report is not None:
            report.finish(result.t[-1])          # the run's end: 100%
        if events is not None and self.sparse:
            # the locked rows folded into the factorisation (engine/fcc_events_fold.c),
            # else a Schur complement; fold_left: it fell back (a row's pattern)
            result.info["event_rows_folded"] = bool(folded[0])
            result.info["event_fold_left"] = int(folded[1])
            # the switches' responses to the held rows (one per row and instant)
            result.info["event_switch_solves"] = int(folded[2])
            # the fold against the Schur complement, measured after each switch
            result.info["event_fold_trials"] = int(folded[3][0])
            result.info["event_fold_trials_folded"] = int(folded[3][1])
        if events is not None:
            turn_check(result, self.plan, self.events_module, events,
                       turn if m.name in REBASING else None)
        if events is not None and events.n_events:
            result.info["event_location"] = ("interpolant" if m.name == "dopri5"
                                             else event_location)
            from ..events.table import (energy_balance, event_rows, report_dropped_events,
                                        report_switches)
            from ._events import ACTIONS, NOTES
            result.events = event_rows(events.names, ACTIONS, log)
            result.info["events"] = result.events
            report_switches(result, log, NOTES)
            if dropped:
                report_dropped_events(result, len(log), dropped)
            (result.info["energy_drift"],
             result.info["event_energy_loss"]) = energy_balance(result.t, result["energy"],
                                                                result.events)
        # the run's own statistics: the solves after it (driver forces, held rows'
        # responses) are not the run's, and their projections are no steps
        used = self.dense_engine() if m.name == "ali3p" else (
            self._engine if sens is None else sens_engine)
        stats = used.rank_statistics()
        locks = (None if events is None or not events.n_events else
                 held_rows.of_run(self, result, self._held_quantities(events), dropped))
        loads = record_loads.of_run(self.plan, self.put_params, held, sched,
                                    m.name in REBASING, result.events or ())
        settle_turns(self.plan, result)
        add_driver_columns(self, result, locks, loads)
        check_driver_branches(self.plan, result)
        rank_rule.report_run(result, decision, stats,
                             driven=bool(driver_rows(self.plan)))
        if events is not None and events.n_events:
            from ..events.table import final_dof
            result.info["final_dof"] = final_dof(result.info, result.events)
        check_constraint_drift(self, result, project)
        check_energy(result, self.plan,
                     kinetic_peak(self, result, stats.get("kinetic_energy_peak")),
                     kept.get("work"), untracked)
        if sens is not None:
            sensitivity_run.attach(self, result, keys, sens, m.name)
            if m.name == "dopri5":
                result.info["sensitivity_error_control"] = bool(sens_error)
        if not reactions:
            return result
        return add_reactions(self, result, locks, loads)

    def dense_engine(self):
        """The dense path's engine (the solver's own unless it takes the sparse one)."""
        if self._dense_engine is None:
            self._dense_engine = self._new_engine(False)
            self._dense_engine.decide_rank(None, self._engine.decided_rank)
        return self._dense_engine

    def settings(self) -> dict:
        """The solver's tolerances, as result.info["solver"] records them."""
        return {"rank_tol": self.rank_tol, "position_tol": self.position_tol,
                "max_newton": self.max_newton, "linear_solver": self.linear_solver,
                "path": "sparse" if self.sparse else "dense"}

    def _event_set(self, tol, rest_speed):
        """The compiled events of the model, with the copies of their angle references
        in the element kernels that count turns (fccgen.events.references); None: it
        has neither (or, without events, no event module was given)."""
        model = self.plan.model
        if self.events_module is None:
            if model.events:
                raise ValueError(f"model {model.name!r} has events: give the solver its "
                                 "event module (fccgen.events.build.load_events)")
            return None
        from ._events import EventSet
        from . import event_settings as settings
        st = self._event_settings
        events = EventSet(self.events_module, self.n_q, st.directions, st.actions,
                          st.rows, st.rows2, st.restitution, st.angle_rows, tol=tol,
                          v_rest=rest_speed,
                          max_per_step=settings.max_per_step(len(st.actions)),
                          max_log=settings.LOG_ROWS, constants=st.constants)
        if st.mirror_slots:
            events.mirror(self._asm, st.mirror_slots, st.mirror_angles)
        events.fold_trial = self._fold_trial
        return events

    def _held_quantities(self, events):
        """rows(q, v, keys) of fccgen.runs.held_rows.HeldRows: the gradients and
        biases of the joint quantities ``keys`` from the event module's kernels."""
        names = list(self.events_module.QUANTITY_NAMES)

        def rows(q, v, keys):
            _, G, bias = events.quantity_kernels(q, v)
            at = [names.index(f"{joint}.{kind}") for joint, kind in keys]
            return G[at], bias[at]
        return rows

    @functools.cached_property
    def _event_settings(self):
        """The settings of the model's compiled events (fccgen.runtime.event_settings),
        made once per solver: its plan and event module do not change."""
        from .event_settings import event_settings
        return event_settings(self.plan, self.events_module)

    def _event_inputs(self, events, held) -> None:
        """Give the run's event set the inputs its event functions read (held: the
        run's inputs, fccgen.runs.inputs): their first values now, and where the run
        writes the later ones (held.event_slots, held.event_columns)."""
        if events is None or held is None:
            return
        st = self._event_settings
        if st.input_slots:
            held.event_slots = np.array(st.input_slots, np.intc)
            held.event_columns = np.array(st.input_columns, np.intc)
            events.put_inputs(held.event_slots, held.table[0, held.event_columns])

    def decide_rank(self, q) -> rank_rule.RankDecision:
        """Decide the rank of B at q by the SVD gap test (fccgen.rank) and keep it in
        the engine's factorisations (runs and direct calls) until the next decision.
        Every run decides at its start; before the first decision the factorisations
        count QR pivots above rank_tol. The same q (parameters, tolerances) takes the
        decision made before (fccgen.runtime.setup_reuse)."""
        decision = kept_decision(self, q, lambda: self._jacobian_for_decision(q),
                                 lambda B: rank_rule.decide(B, self.n_q, self.row_groups))
        self._decided_at = np.array(q, dtype=float)
        if self._auto_small:
            self._choose_small_path(q, self._jacobian_for_rank(q), decision)
        beyond = self._manifold_redundancy(q, decision) if self.sparse else 0.0
        # q None: the sparse engine keeps the rank without the rank-growth watch (and
        # without the SVD that starts it) where the rank cannot grow
        watched = q if not self.sparse or self._rank_may_grow(decision) else None
        self._engine.decide_rank(watched, decision.rank)
        if self._dense_engine is not None and self._dense_engine is not self._engine:
            self._dense_engine.decide_rank(q, decision.rank)
        if self.sparse:
            self._engine.set_beyond_rank(beyond)
        return decision

    def _rank_may_grow(self, decision) -> bool:
        """Whether the sparse path's rank-growth watch (engine/fcc_sparse_watch.c) is
        needed after the decision at q (_manifold_redundancy just made there). B is
        an analytic function of q, so a row dependency that holds at a random point
        holds identically (its minors vanish there, so everywhere, with probability
        one): when the rank off the constraints (the random point of
        _manifold_redundancy) is no higher than the decided rank, no state reaches a
        higher one and the watch has nothing to find. Kept for rows that depend on
        the time (drivers: B changes with t) and for models with events (lock rows).
        docs/reliability.md, "The rank of the constraint Jacobian"."""
        if not 0 <= decision.rank < min(self.n_q, self.n_g):
            return False                    # full rank: the watch never starts
        if len(time_slots(self.plan)) or self.plan.model.events:
            return True
        return self._manifold_rises

    def small_path_signals(self, q, B, decision) -> tuple[float, float, float]:
        """What paths.small_model_path reads at q, B (dense) and its rank decision:
        the smallest kept scaled singular value, the manifold redundancy
        (_manifold_redundancy) and the reduced mass spread (paths.reduced_mass_spread)."""
        scaled = B / rank_rule.row_scales(B, self.row_groups)[:, None] if B.size else B
        return (decision.gap[0], self._manifold_redundancy(q, decision),
                reduced_mass_spread(self.mass_matrix(q), scaled, decision.rank))

    def _choose_small_path(self, q, B, decision) -> None:
        """The path of a small model under "auto" from the decision at q
        (paths.small_model_path): the solver's engine becomes the sparse one (built
        on first use) or the dense one."""
        self.sparse = small_model_path(*self.small_path_signals(q, B, decision)) == "sparse"
        if self.sparse and self._sparse_engine is None:
            self._sparse_engine = self._new_engine(True)
        self._engine = self._sparse_engine if self.sparse else self.dense_engine()

    def _manifold_redundancy(self, q, decision) -> float:
        """For the sparse path's solves (engine/fcc_al_refine.c, "Directions beyond the decided
        rank"): sigma_r / sigma_1 of the decision when B has rows dependent only on the
        constraint manifold, 0 when its dependent rows (if any) are dependent
        everywhere. The test: the rank at q moved off the constraints by
        OFF_MANIFOLD times the length scale (fixed seed) is higher. Measured: Bricard,
        deployable, deployable_joints and the scissor mast rise (sigma_{r+1} 2e-5 ..
        2e-3 of sigma_1), A02's chain, the scissor boom and the four-bar stay at 1e-16.
        Kept per (q, rank): every run decides again at its initial state; the rank off
        the constraints is kept by its Jacobian for every solver (setup_reuse). Only
        the rank is read, so components above SPLIT_COLUMNS coordinates take the
        certified sparse decision (fccgen.rank.sparse, rank only; the SVD where it cannot
        certify the gap): 3 ms in place of 160 ms on A02's chain at 483 coordinates."""
        q = np.asarray(q, dtype=float)
        if not 0 <= decision.rank < self.n_g:
            return 0.0
        key = (decision.rank, q.tobytes())
        if self._manifold_key != key:
            start = time.process_time()
            rng = np.random.default_rng(OFF_MANIFOLD_SEED)
            off = q + OFF_MANIFOLD * self.length_scale * rng.standard_normal(q.size)
            B = self._jacobian_for_decision(off)
            moved, reused = shared_decision(
                jacobian_key("off", B, self.row_groups, self.n_q),
                lambda: rank_rule.decide(B, self.n_q, self.row_groups,
                                         dense_max=rank_rule.SPLIT_COLUMNS,
                                         rank_only=True))
            self._manifold_rises = moved.rank > decision.rank
            self._manifold_kept = decision.gap[0] if self._manifold_rises else 0.0
            self._manifold_key = key
            self.setup_store.record("off_constraint_test", time.process_time() - start,
                                    reused, moved.how)
        return self._manifold_kept

    def _start_state(self, q0, v0):
        if q0 is None:
            init = self.initial_state()
            return init.q, (init.v if v0 is None else v0)
        if v0 is None:
            v0 = self.project_velocities(q0, self.plan.v_target)
        return q0, v0

    def _run(self, m, sched, opts, project, q0, v0, report, events=None, work=None,
             held=None, sens=None, sens_scale=None, sens_engine=None,
             on_interpolant=False):
        """(arrays, stats) of one run of method m (held: inputs that change over the
        run, fccgen.runs.inputs; rk4 and baumgarte only; sens: rk4's or dopri5's
        sensitivities, carried by sens_engine; sens_scale: the parameters' sizes for
        dopri5's error control of them, None: not controlled)."""
        s, e = sched, (self._engine if sens is None else sens_engine)
        held = None if held is None or held.constant or not (
            len(held.slots) or len(held.event_slots)) else (
            held.slots, held.columns, held.table, held.event_slots, held.event_columns)
        if model_events(self.plan) and m.name not in ("rk4", "dopri5"):
            raise ValueError(f"events are located by the rk4 and dopri5 methods, not "
                             f"by {m.name}")
        if m.name == "rk4":
            return simulate_rk4(e, q0, v0, s.t_end, s.dt, s.n_steps, s.every, project,
                                report, self.progress_interval, events=events, work=work,
                                inputs=held, sens=sens, on_interpolant=on_interpolant)
        if m.name == "baumgarte":
            return simulate_baumgarte(e, q0, v0, s.t_end, s.dt, s.n_steps, s.every,
                                      opts["alpha"], opts["beta"], report,
                                      self.progress_interval, events=events, work=work,
                                      inputs=held)
        if m.name == "dopri5":
            return simulate_dopri5(e, q0, v0, s.t_end, s.output_dt, opts["rtol"],
                                   opts["atol"], s.dt or 0.0, project, report,
                                   self.progress_interval, events=events, work=work,
                                   sens=sens, sens_scale=sens_scale)
        if m.name == "ali3p":                # assembles dense M and B itself
            from ._ali3p import simulate_ali3p
            return simulate_ali3p(self.dense_engine(), q0, v0, s.t_end, s.dt, s.n_steps, s.every, opts,
                                  report, self.progress_interval,
                                  length_scale=self.length_scale)
        if m.name.startswith("scipy-"):
            from ..runs import scipy_ivp
            if events is not None:               # references from the start's angles
                events.reset(q0)
            return scipy_ivp.run(self, m.name[len("scipy-"):], s, opts, q0, v0, report,
                                 refresh=None if events is None else events.refresh,
                                 power=None if work is None else (
                                     lambda q, v, a: work.power(self._engine, q, v, a)),
                                 restart=None if events is None else (
                                     lambda: events.reset(q0)))
        raise AssertionError(f"no compiled dispatch for method {m.name!r}")

    # -- other numbers, pickling (fccgen.runtime.params) --------------------------------
    def with_parameters(self, values: dict) -> "CompiledSolver":
        """A solver of the same compiled module with other numbers, e.g.
        ``{"bodies.arm.mass": 2.0}``; see :mod:`fccgen.runtime.params`."""
        from .params import with_parameters
        return with_parameters(self, values)

    def simulate_many(self, parameters, *, threads=None, progress=None, run_progress=None,
                      **options) -> list:
        """One run per parameter set (dicts of with_parameters keys, or a pandas
        DataFrame whose columns are keys), on ``threads`` threads (None: the cores):
        a list of Results, a RunFailure where a run failed; see
        :mod:`fccgen.runtime.many`."""
        from .many import simulate_many
        return simulate_many(self, parameters, threads=threads, progress=progress,
                             run_progress=run_progress, **options)

    def __repr__(self) -> str:
        """Model, coordinates, constraint equations, DOF if decided, method, linear
        solver path and the build folder of the kernel module."""
        from pathlib import Path
        from ..results.summary import solver_repr
        file = getattr(self.module, "__file__", None)
        return solver_repr(self, self._engine.decided_rank,
                           "sparse" if self.sparse else "dense",
                           str(Path(file).parent) if file else None)

    def __reduce__(self):
        from .params import reduce_solver
        return reduce_solver(self)

    # -- timing (for fccgen bench) ---------------------------------------------------------
    def time_kernels(self, q, v, repeats=200) -> dict:
        """Seconds per global assembly of each kernel the module has (median of warm,
        batched runs in compiled loops)."""
        return {name: _median_time(lambda b, f=flag: self._asm.time_assembly(f, q, v, b),
                                   repeats)
                for name, flag in self._asm.kernel_flags().items()}

    def time_accelerations(self, q, v, repeats=200) -> float:
        """Seconds per evaluation of the accelerations (assembly, factorisation, solve)."""
        self._engine_call(lambda e: e.accelerations(q, v))    # the pattern holds at q, v
        return _median_time(lambda b: self._engine.time_accelerations(q, v, b), repeats)


def model_events(plan) -> bool:
    """The model has event functions (not only angle references to keep)."""
    return bool(plan.model.events)


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
