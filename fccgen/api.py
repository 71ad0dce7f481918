"""The Python API: every command-line action is one call of a function here.

Nothing here imports SymPy: generation (which does) is imported lazily by
``fccgen.build`` only on a cache miss.

``progress``: a callback called with :class:`fccgen.progress.ProgressEvent` objects
(stage, done, total, t, elapsed), each also the one-line message as a ``str``, so a
callback written for text keeps working.
"""
from __future__ import annotations

from .mechanism import lower
from .model import load_model
from .plan import make_plan
from .progress import Progress

DEFAULT_BUILD_DIR = "generated"


def plan_model(path):
    """Load, validate, lower (joints, pose-form bodies) and lay out a model file."""
    return make_plan(lower(load_model(path)))


def generate(path, build_dir=DEFAULT_BUILD_DIR, *, force=False, progress: Progress = None):
    """Generate and compile a model's kernels (served from the cache when unchanged).

    Returns ``(plan, built)`` with ``built`` a :class:`fccgen.build.BuiltModule`.
    """
    from .build import build_module
    plan = plan_model(path)
    built = build_module(plan, build_dir, force=force, progress=progress)
    return plan, built


def load(path, build_dir=DEFAULT_BUILD_DIR, *, force=False, progress: Progress = None,
         **solver_options):
    """A compiled solver of the model (generated and compiled first if needed; always
    rebuilt with ``force``).

    ``solver_options`` go to :class:`fccgen.runtime.CompiledSolver` (rank_tol,
    position_tol, max_newton, linear_solver: "auto", "dense" or "sparse").
    """
    from .build import load_module
    from .runtime import CompiledSolver
    plan, built = generate(path, build_dir, force=force, progress=progress)
    from .events.references import angle_sources
    events = None
    if plan.model.events or angle_sources(plan):  # events, or angles counted over turns
        from .events.build import load_events
        events = load_events(plan, build_dir, force=force)
    return CompiledSolver(plan, load_module(built), events_module=events, **solver_options)


def load_numeric(path, **solver_options):
    """The NumPy version of the same solver (slow; the cross-check and baseline)."""
    from .numeric import NumericSolver
    return NumericSolver(plan_model(path), **solver_options)


def simulate(path, *, t_end=None, dt=None, method=None, output_dt=None, project=True,
             numeric=False, out=None, build_dir=DEFAULT_BUILD_DIR, force=False,
             keep_partial=False, progress: Progress = None, rtol=None, atol=None,
             solver_options: dict | None = None, all_columns=False, error=None,
             error_on=None, **method_options):
    """Simulate a model from its consistent initial state; write ``out`` if given.

    rtol, atol: tolerances of adaptive methods; solver_options: rank_tol,
    position_tol, max_newton (see :func:`load`); method_options: the method's options
    (e.g. alpha, beta for baumgarte; see :mod:`fccgen.settings.methods`). ``out`` is checked
    before anything runs (suffix, writable folder). When the run stops early (Ctrl-C,
    SimulationError) nothing is written, unless ``keep_partial``: then the rows
    recorded so far, if the integrator hands them back, go to ``<stem>.partial<suffix>``
    and the exception's ``partial_path`` says where. ``all_columns``: write the internal
    columns too (:meth:`fccgen.results.result.Result.save`). error, error_on: an error target
    (the method and its setting chosen by a pilot; docs/accuracy.md). Returns
    ``(result, initial_state)``.
    """
    from .settings.limits import refuse
    if error is not None:
        method_options.update(error=error, error_on=error_on)
    from .results.result import check_output, partial_path
    out = None if out is None else check_output(out)
    refuse(lower(load_model(path)), method)          # before anything is built
    solver_options = solver_options or {}
    solver = (load_numeric(path, **solver_options) if numeric else
              load(path, build_dir, force=force, progress=progress, **solver_options))
    init = solver.initial_state()
    try:
        result = solver.simulate(t_end=t_end, dt=dt, method=method, output_dt=output_dt,
                                 project=project, q0=init.q, v0=init.v, progress=progress,
                                 rtol=rtol, atol=atol, **method_options)
    except BaseException as exc:
        partial = getattr(exc, "partial_result", None)
        if keep_partial and out is not None and partial is not None:
            exc.partial_path = partial.save(partial_path(out), partial=True,
                                            all_columns=all_columns)
        raise
    if out is not None:
        result.save(out, all_columns=all_columns)
    return result, init


def plot(result, columns=None, out=None, *, title=None):
    """Plot result columns (a Result or a .csv/.npz/.h5 file) against time and write the
    figure to ``out`` (.png, .svg, .pdf; default: the result file's name with .png).
    Returns the figure's path."""
    from pathlib import Path

    from .results.result import Result
    from .viz.plot import check_figure_path, save_plot
    if out is None:
        if isinstance(result, Result):
            raise ValueError("plot: give out=FIG.png for a result held in memory")
        out = Path(result).with_suffix(".png")
    out = check_figure_path(out)
    if not isinstance(result, Result):
        title = title or Path(result).name
        result = Result.load(result)
    return save_plot(result, columns, out, title=title)


def animate(path, out, *, result=None, mode=None, t_end=None, max_frames=None,
            build_dir=DEFAULT_BUILD_DIR, progress: Progress = None):
    """Write a self-contained page (``out``, .html, plotly.js inlined) that plays the
    model's motion in 3-D: ``result`` (a Result or a .csv/.npz/.h5 file of this model), or
    else a run of the model's default simulation (its simulate settings; ``t_end``
    overrides the end time). ``mode``: play mode k of the shapes written by
    :func:`modes` with ``shapes=result``. At most ``max_frames`` frames (default 300),
    rows spread evenly. Returns ``(page path, number of frames, the result shown)``."""
    from .model import load_model
    from .results.result import Result
    from .viz.animate import DEFAULT_MAX_FRAMES, check_page_path, write_animation
    out = check_page_path(out)
    if mode is not None:
        from .results.files import mode_file
        result = mode_file(result, mode)
    model = load_model(path)
    if result is None:
        result, _ = simulate(path, t_end=t_end, build_dir=build_dir, progress=progress)
    elif not isinstance(result, Result):
        result = Result.load(result)
    page, n_frames = write_animation(model, result, out, max_frames or DEFAULT_MAX_FRAMES)
    return page, n_frames, result


def sweep(path, sets, out=None, *, scheduler=None, method=None, workers=None,
          outputs=None, run_timeout=None, resume=False, build_dir=DEFAULT_BUILD_DIR,
          progress: Progress = None):
    """Run the model once per combination of ``sets`` ({key: [values]}, or
    ``["KEY=V1,V2", ...]``) on Dask, compiled once; write the table to ``out`` (.csv
    or .parquet) if given, each row to ``<stem>.partial.csv`` beside it as its run
    finishes. ``outputs``: what the table carries besides its figures, e.g.
    ``"motor.torque:max,latch:time"``; ``run_timeout``: seconds of wall time a run may
    take; ``resume``: keep the rows of the partial file a stopped sweep left and run
    only the others. Dask, ``out``, ``sets`` and ``outputs`` are checked before
    anything is built.
    Keys: :mod:`fccgen.runtime.params`; figures: :mod:`fccgen.sweep`; docs/sweeps.md.
    Returns a :class:`fccgen.sweep.SweepTable`."""
    from .sweep import check_table_path, parse_sets, require_dask
    from .sweep import sweep as run_sweep
    from .sweep.outputs import parse_outputs
    require_dask()
    out = None if out is None else check_table_path(out, resume=resume)
    if not isinstance(sets, dict):
        sets = parse_sets(sets)
    outputs = parse_outputs(outputs)
    if run_timeout is not None and not run_timeout > 0:
        raise ValueError(f"--run-timeout must be a positive number of seconds "
                         f"(got {run_timeout!r})")
    solver = load(path, build_dir, progress=progress)
    return run_sweep(solver, sets, scheduler=scheduler, method=method, workers=workers,
                     progress=progress, outputs=outputs, run_timeout=run_timeout, out=out,
                     resume=resume)


def statics(path, *, numeric=False, build_dir=DEFAULT_BUILD_DIR, progress: Progress = None):
    """The static equilibrium of a model from its initial configuration
    (:func:`fccgen.analysis.statics`); returns an :class:`~fccgen.analysis.Equilibrium`."""
    return equilibrium(path, numeric=numeric, build_dir=build_dir, progress=progress)[0]


def equilibrium(path, *, out=None, numeric=False, build_dir=DEFAULT_BUILD_DIR,
                progress: Progress = None):
    """The static equilibrium and its one-row result (section 4's columns at t = 0,
    the reactions named by joint and component, the drivers' forces, provenance and
    the equilibrium's figures in ``info``: :mod:`fccgen.analysis.statics_result`),
    written to ``out`` (.csv, .npz, .h5; checked before anything runs) if given.
    Returns ``(equilibrium, result)``."""
    from .analysis import statics as solve_statics
    from .analysis.statics_result import equilibrium_result
    from .results.result import check_output
    out = None if out is None else check_output(out)
    solver = load_numeric(path) if numeric else load(path, build_dir, progress=progress)
    eq = solve_statics(solver)
    result = equilibrium_result(solver, eq)
    if out is not None:
        result.save(out)
    return eq, result


def inverse_dynamics(path, *, t_end=None, dt=None, out=None, numeric=False,
                     build_dir=DEFAULT_BUILD_DIR, progress: Progress = None):
    """Inverse dynamics of the model file ``path`` (:mod:`fccgen.analysis.inverse`):
    the driver forces and joint reactions along a motion the drivers fix completely,
    as a Result with the positions, speeds, joint outputs, the drivers' forces and the
    joint reactions at 0, dt, ..., t_end; written to ``out`` if given (any result
    format)."""
    from .analysis.inverse import solve_inverse
    from .results import check_output
    if out is not None:
        out = check_output(out)
    solver = load_numeric(path) if numeric else load(path, build_dir, progress=progress)
    result = solve_inverse(solver, t_end=t_end, dt=dt, progress=progress)
    if out is not None:
        result.save(out)
    return result


def modes(path, *, about="equilibrium", out=None, shapes=None, amplitude=None,
          numeric=False, build_dir=DEFAULT_BUILD_DIR, progress: Progress = None):
    """Natural frequencies and mode shapes about the static equilibrium
    (``about="equilibrium"``) or the model's initial state (``about="initial"``);
    writes the rows ``mode, frequency_hz, damping_ratio, rigid`` to ``out`` (CSV) if
    given, and each mode shape as a result the animation plays to
    ``<stem>.mode<k><suffix>`` of ``shapes`` (e.g. modes.npz -> modes.mode1.npz; see
    :mod:`fccgen.analysis.mode_shapes`; ``amplitude`` in length units). Both names are
    checked before anything runs. Returns ``(modes, equilibrium or None)``."""
    from .analysis import linearize
    from .analysis import modes as solve_modes
    from .analysis import statics as solve_statics
    from .results.result import check_output
    if about not in ("equilibrium", "initial"):
        raise ValueError(f"about must be 'equilibrium' or 'initial' (got {about!r})")
    if out is not None:
        if not str(out).endswith(".csv"):
            raise ValueError(f"modes are written as CSV: give --out a .csv name (got {out})")
        out = check_output(out)
    if shapes is not None:
        shapes = check_output(shapes, "--shapes")
    solver = load_numeric(path) if numeric else load(path, build_dir, progress=progress)
    if about == "equilibrium":
        equilibrium = solve_statics(solver)
        lin = linearize(solver, equilibrium.q)
    else:
        equilibrium, init = None, solver.initial_state()
        lin = linearize(solver, init.q, init.v)
    result = solve_modes(lin)
    if out is not None:
        from .results.provenance import provenance
        info = provenance(solver.plan, getattr(solver, "settings", dict)())
        info.update(kind="modes", about=about, dof=int(lin.null_basis.shape[1]))
        if equilibrium is not None:
            info.update(equilibrium_force_residual=equilibrium.force_residual,
                        equilibrium_stability=equilibrium.stability)
        result.write_csv(out, info)
    if shapes is not None:
        from .analysis.mode_shapes import mode_shapes, write_mode_shapes
        write_mode_shapes(mode_shapes(solver, lin, result, amplitude=amplitude,
                                      about=about), shapes)
    return result, equilibrium


def sensitivity(path, params, *, t_end=None, dt=None, output_dt=None, out=None,
                build_dir=DEFAULT_BUILD_DIR, force=False, progress: Progress = None,
                solver_options: dict | None = None, method="rk4", rtol=None, atol=None,
                sensitivity_error=None):
    """One rk4 (or dopri5: method, rtol, atol, sensitivity_error) run of the model with
    the sensitivities to ``params`` (parameter keys, a list or one comma-separated
    string; docs/sensitivities.md). ``out``: write ``t`` and the columns
    ``d(<column>)/d(<param>)`` (CSV, NPZ or HDF5, with how they were made). Returns the
    full result (its columns and the sensitivities')."""
    from .results import Result, check_output
    from .runtime.sensitivity.run import split_keys
    out = None if out is None else check_output(out)
    keys = split_keys(params)
    solver = load(path, build_dir, force=force, progress=progress, **(solver_options or {}))
    extra = {} if sensitivity_error is None else {"sensitivity_error": sensitivity_error}
    result = solver.simulate(t_end=t_end, dt=dt, method=method, output_dt=output_dt,
                             rtol=rtol, atol=atol, progress=progress, reactions=False,
                             sensitivities=keys, **extra)
    if out is not None:
        names = [n for n in result.columns if n.startswith("d(")]
        table = Result(result.t, {n: result.columns[n] for n in names}, dict(result.info),
                       hidden={n for n in names if n in result.hidden})
        table.save(out)
    return result
