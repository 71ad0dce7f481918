"""Inverse dynamics along drivers: the forces that make a mechanism follow a motion its
drivers prescribe completely.

When the drivers fix every degree of freedom (rank B = n_q, decided by the SVD gap
test of :mod:`fccgen.rank` at the initial positions), the constraints alone give the
motion; no dynamics is integrated. At each output time t_k:

    g(q, t_k) = 0               Newton position projection, started from the
                                extrapolation q_{k-1} + h q'_{k-1} + h^2 q''_{k-1} / 2
    B(q) q' = -g_t              the velocity projection (unique: ker B is empty)
    B(q) q'' = -(B' q' + b)     the solver's accelerations (M q'' + B^T lambda = f - h
                                with an empty null space: q'' from the constraints
                                alone, lambda carries the forces)

Then, as after a forward run, the drivers' generalized forces from the minimum-norm
multipliers B^T lambda = f - h - M q'' (:mod:`fccgen.mechanism.driver_forces`, columns
``D.torque`` / ``D.force``) and the joint reactions from the per-body Newton-Euler
balance (:mod:`fccgen.mechanism.reactions`, columns ``J.fx ... J.tz``; a driven joint's
reaction holds its driver's torque or force too).

The positions are exact to the projection tolerance at every row, independently of
the output spacing: there is no truncation error.
"""
from __future__ import annotations

import time
import warnings

import numpy as np

from ..errors import ModelError, RunWarning

METHOD = "inverse"
REPORT_EVERY = 0.5       # seconds of wall time between progress events of a run


def check_fully_driven(solver, q) -> int:
    """The rank of B at q; ModelError when the drivers and joints leave freedoms."""
    decision = solver.decide_rank(q)
    if decision.dof > 0:
        model = solver.plan.model
        where = model.where.get("drivers")
        n_drivers = len(getattr(model.mechanism, "drivers", None) or [])
        raise ModelError(
            model.source, where.line if where else None, "drivers",
            f"inverse dynamics needs drivers that fix every degree of freedom, but with "
            f"{n_drivers} driver(s) rank B = {decision.rank} of {decision.n_q} "
            f"coordinates leaves {decision.dof} degree(s) of freedom; drive "
            f"{decision.dof} more joint quantities (docs/inverse-dynamics.md)",
            show_value=False)
    return decision.rank


def output_times(t_end: float, dt: float) -> np.ndarray:
    """0, dt, 2 dt, ... and t_end (the last interval shortened to land on it)."""
    if not (np.isfinite(t_end) and t_end > 0 and np.isfinite(dt) and dt > 0):
        raise ValueError(f"t_end and dt must be positive (got t_end={t_end}, dt={dt})")
    n = int(np.floor(t_end / dt * (1 + 1e-12)))
    t = dt * np.arange(n + 1)
    return t if t_end - t[-1] <= 1e-9 * dt else np.append(t, t_end)


def kinematics(solver, times: np.ndarray, q, v, report=None) -> tuple[dict, dict]:
    """(arrays t, q, v, body, constraint_error; stats) of the driven motion at
    ``times`` from the consistent state (q, v) at t = 0 (module docstring); ``report``:
    a :class:`~fccgen.progress.RunReporter`, called about every REPORT_EVERY s."""
    a = np.zeros_like(q)
    rows = {k: [] for k in ("q", "v", "body", "constraint_error")}
    newton = max_newton = 0
    t_prev, last = 0.0, time.perf_counter()
    for t in times:
        t, h = float(t), float(t) - t_prev
        solver.set_time(t)
        q, iterations = solver.project_positions(q + h * v + 0.5 * h * h * a)
        v = solver.project_velocities(q, v)
        a = solver.accelerations(q, v)
        newton, max_newton = newton + iterations, max(max_newton, iterations)
        for key, value in (("q", q), ("v", v), ("body", solver.body_outputs(q, v)),
                           ("constraint_error",
                            float(np.max(np.abs(solver.constraints(q)), initial=0.0)))):
            rows[key].append(np.array(value, float))
        t_prev = t
        if report is not None and time.perf_counter() - last >= REPORT_EVERY:
            report(t)
            last = time.perf_counter()
    if report is not None:
        report.finish(t_prev)
    arrays = {k: np.array(v) for k, v in rows.items()}
    arrays["t"] = np.array(times, float)
    arrays["body"] = arrays["body"].reshape(len(times), len(solver.plan.bodies), 6)
    stats = dict(newton_iterations=int(newton), max_newton_iterations=int(max_newton),
                 max_constraint_error=float(arrays["constraint_error"].max()))
    return arrays, stats


def solve_inverse(solver, t_end=None, dt=None, progress=None):
    """The :class:`~fccgen.results.result.Result` of the inverse dynamics of ``solver``'s
    model (compiled or numeric) from 0 to t_end at the output spacing dt (defaults: the
    model's simulate t_end and output_dt, else dt); ``progress`` as for
    ``simulate`` (stage "inverse")."""
    from ..mechanism.driver_forces import add_driver_columns
    from ..mechanism.outputs import add_joint_columns
    from ..mechanism.reactions import add_reactions
    from ..numeric.record_loads import RecordLoads, energies
    from ..progress import run_reporter
    from ..results.provenance import provenance
    from ..results.result import result_from_arrays
    d = solver.plan.model.simulate
    t_end = float(d.t_end if t_end is None else t_end)
    dt = float((d.output_dt or d.dt) if dt is None else dt)
    times = output_times(t_end, dt)
    solver.set_time(0.0)
    init = solver.initial_state()
    rank = check_fully_driven(solver, init.q)
    start = time.perf_counter()
    arrays, stats = kinematics(solver, times, init.q, init.v,
                               run_reporter(progress, t_end, "inverse"))
    # the turns of the springs and the expression loads' values at each row, counted
    # from the rows as after a run (the inputs at their start values)
    loads = RecordLoads(solver.plan, solver.put_params)
    # a spring's energy of its angle over turns, as a run records it (not of the
    # angle within half a turn of the planned reference)
    arrays["energy"], known, reason = energies(solver, arrays["t"], arrays["q"],
                                               arrays["v"], loads)
    info = provenance(solver.plan, solver.settings())
    energy = arrays["energy"][:known]
    info.update(method=METHOD, kind="kinematic", steps=len(times) - 1,
                rhs_evaluations=len(times), rejected_steps=0, t_end=t_end, output_dt=dt,
                energy_drift=float(np.max(np.abs(energy - energy[0]), initial=0.0)),
                rank=rank, dof=0, **stats)
    if known < len(times):
        text = f"the energy is NaN from t = {times[known]:.9g} s on: {reason}"
        info.setdefault("warnings", []).append(text)
        warnings.warn(text, RunWarning, stacklevel=2)
    result = result_from_arrays(solver.plan, arrays["t"], arrays["q"], arrays["v"],
                                arrays["body"], arrays["energy"],
                                arrays["constraint_error"], info)
    if getattr(solver.plan.model, "mechanism", None) is not None:
        add_joint_columns(solver.plan, result)
    add_driver_columns(solver, result, None, loads)
    add_reactions(solver, result, loads=loads)
    result.info["wall_time"] = time.perf_counter() - start
    return result


def summary(result, out=None) -> str:
    """The text ``fccgen inverse`` prints: the run, each driver's largest force, the
    reactions' state and where the results went."""
    info = result.info
    lines = [f"{info['model']['name']}: inverse dynamics, {len(result.t)} rows to "
             f"t = {result.t[-1]:.6g} (rank {info['rank']}, 0 degrees of freedom; max "
             f"constraint error {info['max_constraint_error']:.3g}, "
             f"{info['newton_iterations']} Newton iterations)"]
    for name in result.names:
        if name.endswith((".torque", ".force")):
            k = int(np.argmax(np.abs(result[name])))
            lines.append(f"  {name}: max |.| = {abs(result[name][k]):.6g} at "
                         f"t = {result.t[k]:.6g}")
    reaction = info.get("reactions", {})
    if reaction.get("note") or reaction.get("reason"):
        lines.append(f"note: {reaction.get('note') or reaction['reason']}")
    lines.append(f"results: {out} ({len(result.t)} rows, {len(result.names)} columns)"
                 if out else "no --out given: results not written")
    return "\n".join(lines)
