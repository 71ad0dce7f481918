"""Command line (docs/design.md §5): a thin layer over :mod:`fccgen.api`.

    fccgen MODEL.yaml                 generate and compile (cached)
    fccgen simulate MODEL.yaml ...    simulate and write results
    fccgen bench MODEL.yaml           compiled vs numeric timings and differences
    fccgen check MODEL.yaml           validate and report structure
    fccgen plot RESULT --columns ...  time histories of result columns
    fccgen animate MODEL.yaml --out F.html   the motion in 3-D, one offline page
    fccgen sweep MODEL.yaml --set K=V1,V2 --out T.csv   many runs on Dask (.parquet too)
    fccgen statics MODEL.yaml         static equilibrium, reactions, stability
    fccgen modes MODEL.yaml           natural frequencies about the equilibrium
    fccgen inverse MODEL.yaml         driver forces and reactions along the drivers
    fccgen examples [DIR]             copy the example models into DIR (./examples)
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings

from .version import __version__
from .progress.terminal import ProgressDisplay as _Progress
from .progress.terminal import write_line
from .errors import (CacheRepairWarning, FccgenError, ModelError, PartialResultWarning,
                     os_reason, shown_path,
                     RunWarning)
from .settings.methods import describe as describe_methods
from .settings.methods import names as method_names
from .settings.run import LINEAR_SOLVERS

COMMANDS = ("simulate", "bench", "check", "generate", "plot", "animate", "sweep",
            "statics", "modes", "inverse", "examples", "export", "sensitivity")
EXIT_INTERRUPTED = 130      # 128 + SIGINT, as shells report it


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fccgen",
        description="Generate, compile and run solvers of the FCC form of Kane's equations.",
        epilog="With no command, 'fccgen MODEL.yaml' generates and compiles the model.")
    p.add_argument("--version", action="version", version=f"fccgen {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    def common(sp):
        sp.add_argument("model", help="model file (YAML)")
        sp.add_argument("--build-dir", default="generated",
                        help="where compiled modules go (default: ./generated)")
        sp.add_argument("-q", "--quiet", action="store_true", help="no progress messages")

    def force(sp):
        sp.add_argument("--force", action="store_true",
                        help="rebuild the compiled module even if it is cached")

    ex = sub.add_parser("examples", help="copy the example models shipped with fccgen "
                        "into a folder, so that the README's lines run anywhere")
    ex.add_argument("dir", nargs="?", default="examples",
                    help="where to copy them (default: ./examples)")
    ex.add_argument("--overwrite", action="store_true",
                    help="replace files already there (default: keep them)")

    g = sub.add_parser("generate", help="generate and compile (the default command)")
    common(g)
    force(g)

    s = sub.add_parser("simulate", help="simulate from the model's initial state",
                       epilog="methods, their options and defaults:\n" + describe_methods(),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    common(s)
    force(s)
    s.add_argument("--t-end", type=float, help="end time (default: model's simulate.t_end)")
    s.add_argument("--dt", type=float, help="time step; the first step of adaptive "
                   "methods (default: model's simulate.dt; adaptive: automatic)")
    s.add_argument("--method", help="integration method (default: model's "
                   f"simulate.method): {', '.join(method_names())}")
    s.add_argument("--rtol", type=float,
                   help="relative tolerance of adaptive methods (default 1e-6)")
    s.add_argument("--atol", type=float,
                   help="absolute tolerance of adaptive methods (default 1e-9)")
    s.add_argument("--baumgarte-alpha", type=float, metavar="ALPHA",
                   help="Baumgarte damping, 1/time (default 5)")
    s.add_argument("--baumgarte-beta", type=float, metavar="BETA",
                   help="Baumgarte stiffness, 1/time (default 5)")
    s.add_argument("--method-option", action="append", default=[], metavar="NAME=VALUE",
                   help="any option of the method (repeatable), e.g. penalty=1e8")
    s.add_argument("--error", type=float, metavar="E",
                   help="the largest position error accepted over the run, in the "
                        "model's length unit: fccgen chooses the method (--method "
                        "restricts it) and its step or tolerance from a short pilot and "
                        "reports the run's estimated error (docs/accuracy.md)")
    s.add_argument("--error-on", metavar="COLUMNS",
                   help="with --error: the points, vectors or columns the error is "
                        "measured on, comma-separated (default: every moving point)")
    s.add_argument("--output-dt", type=float,
                   help="output interval, a multiple of dt (default: every step)")
    s.add_argument("--event-location", choices=("steps", "interpolant"),
                   help="rk4: locate an event's crossing by re-integrated partial steps "
                        "(steps, the default) or on the step's interpolant, with the "
                        "state there from it (interpolant: each event step costs two "
                        "steps' evaluations and one more; docs/events.md)")
    s.add_argument("--no-reactions", action="store_true",
                   help="skip the joint reaction columns of a mechanism-level model "
                        "(J.fx ... J.tz; computed after the run)")
    s.add_argument("--out", help="write results to FILE.csv, .npz or .h5 with how they "
                   "were made (CSV: in FILE.meta.json); checked before the run, "
                   "written atomically")
    s.add_argument("--all-columns", action="store_true",
                   help="also write the columns of the points and vectors fccgen made "
                        "for joints and pose-form bodies (A_axis.x, rod_center.vy, ...; "
                        "default: only what the model names; .npz and .h5 keep them "
                        "apart for fccgen animate)")
    s.add_argument("--keep-partial", action="store_true",
                   help="if the run stops early (Ctrl-C, a failure), write the rows "
                        "recorded so far to FILE.partial.csv|.npz|.h5, marked as partial")
    s.add_argument("--rank-tol", type=float, metavar="TOL",
                   help="QR pivot ratio at or below which a constraint row counts as "
                        "lost at a singular position (default: model's simulate.rank_tol, "
                        "else 1e-10; see docs/reliability.md)")
    s.add_argument("--position-tol", type=float, metavar="TOL",
                   help="Newton position projection tolerance on max |g_k| / ||B_k|| "
                        "(default: model's simulate.position_tol, else 1e-11 x the "
                        "largest body length)")
    s.add_argument("--linear-solver", choices=LINEAR_SOLVERS,
                   help="the compiled runtime's constrained solve: dense (pivoted QR), "
                        "sparse (LDL^T over a pattern fixed at load, linear in the size) "
                        "or auto (sparse from 25 coordinates, below where each run's "
                        "rank decision shows it well posed; default: model's "
                        "simulate.linear_solver, else auto; see docs/performance.md)")
    s.add_argument("--max-newton", type=int, metavar="N",
                   help="Newton iteration limit of the position projection (default: "
                        "model's simulate.max_newton, else 20)")
    s.add_argument("--no-project", action="store_true",
                   help="do not project positions and velocities onto the constraints")
    s.add_argument("--numeric", action="store_true",
                   help="use the NumPy version instead of the compiled one (slow)")

    b = sub.add_parser("bench", help="time compiled vs numeric versions")
    common(b)
    force(b)
    b.add_argument("--repeats", type=int, default=200,
                   help="timed repetitions per measurement (median reported)")
    b.add_argument("--accuracy", action="store_true",
                   help="work-precision measurement instead: every method over a ladder "
                        "of steps or tolerances, error against a reference, CPU time; "
                        "writes a CSV table, an SVG plot (and a PNG one with "
                        "matplotlib) and a text summary")
    b.add_argument("--out-dir", default="accuracy",
                   help="where --accuracy writes its files (default: ./accuracy)")
    b.add_argument("--t-end", type=float,
                   help="--accuracy: end time (default: model's simulate.t_end)")
    b.add_argument("--output-dt", type=float,
                   help="--accuracy: interval of the compared outputs (default: model's "
                        "simulate.output_dt, else 10 dt)")
    b.add_argument("--methods", help="--accuracy: comma-separated methods (default: all)")
    b.add_argument("--numeric-rungs", type=int, default=1,
                   help="--accuracy: coarsest rungs also run by the numeric version "
                        "(default 1; 0: none)")
    b.add_argument("--reference",
                   help="--accuracy: published reference, a text table (time first); "
                        "default: a converged run of the compiled rk4")
    b.add_argument("--reference-point",
                   help="--accuracy: the point the reference gives, e.g. B0 (its x, y "
                        "[, z] follow time in the table)")

    c = sub.add_parser("check", help="validate and report coordinates, constraints, DOF")
    common(c)
    c.add_argument("--no-generate", action="store_true",
                   help="do not derive, print and render the kernels (faster; the "
                        "report then says that simulate may still refuse the model)")
    _viz_sweep_parsers(sub, common)

    st = sub.add_parser("statics", help="static equilibrium from the initial configuration")
    common(st)
    st.add_argument("--out", help="write the equilibrium as one result row at t = 0 "
                    "(.csv, .npz or .h5): section 4's columns, the reactions by joint "
                    "and component, the drivers' forces, how it was made")
    mo = sub.add_parser("modes", help="natural frequencies (Hz) and damping ratios")
    common(mo)
    mo.add_argument("--about", choices=("equilibrium", "initial"), default="equilibrium",
                    help="linearize about the static equilibrium (default) or the "
                         "model's initial state")
    mo.add_argument("--out", help="write the rows mode, frequency_hz, damping_ratio, "
                                  "rigid to FILE.csv")
    _mode_shape_options(mo)
    iv = sub.add_parser("inverse", help="inverse dynamics: the driver forces and joint "
                        "reactions along a motion the drivers fix completely")
    common(iv)
    iv.add_argument("--t-end", type=float, help="end time (default: the model's)")
    iv.add_argument("--dt", type=float, help="output spacing (default: the model's "
                    "output_dt, else dt)")
    iv.add_argument("--out", help="write the results (.npz, .csv, .h5)")
    iv.add_argument("--numeric", action="store_true", help="use the NumPy version")
    return p


def _mode_shape_options(mo) -> None:
    """fccgen modes --shapes: the mode shapes as results the animation plays."""
    mo.add_argument("--shapes", metavar="FILE", help="write each mode shape as a result "
                    "(one period of small motion, projected onto the constraints) to "
                    "FILE.mode1.npz, FILE.mode2.npz, ... (.npz, .csv or .h5); play one "
                    "with fccgen animate MODEL --result FILE --mode K")
    mo.add_argument("--amplitude", type=float, metavar="A", help="--shapes: the largest "
                    "coordinate's excursion, in the model's length unit (default: 0.1 x "
                    "the largest body length)")


def _viz_sweep_parsers(sub, common) -> None:
    """plot, animate (fccgen.viz) and sweep (fccgen.sweep): one call of the API each."""
    pl = sub.add_parser("plot", help="plot time histories of result columns")
    pl.add_argument("result", help="a result file written by simulate (.csv, .npz or .h5)")
    pl.add_argument("--columns", help="comma-separated column names, e.g. P.x,P.y,energy "
                    "(default: the first moving point's position)")
    pl.add_argument("--out", help="figure file, .png, .svg or .pdf (default: the "
                    "result's name with .png)")
    pl.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    an = sub.add_parser("animate", help="write an offline web page playing the motion "
                        "in 3-D (bodies as their shapes or inertia boxes, joints, ground; "
                        "play button, time slider)")
    an.add_argument("model", help="model file (YAML)")
    an.add_argument("--out", required=True, help="the page to write (.html)")
    an.add_argument("--result", help="a result of this model (.csv, .npz or .h5; default: "
                    "run the model's own simulate settings first)")
    an.add_argument("--mode", type=int, metavar="K", help="with --result FILE: play "
                    "mode K of the shapes written by fccgen modes --shapes FILE")
    an.add_argument("--t-end", type=float, help="without --result: end time of the run")
    an.add_argument("--frames", type=int, metavar="N", help="at most N frames, rows "
                    "spread evenly (default 300)")
    an.add_argument("--build-dir", default="generated",
                    help="where compiled modules go (default: ./generated)")
    an.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    xp = sub.add_parser("export", help="write the model as a standalone C project "
                        "(--c DIR) or an FMI 2.0 co-simulation FMU (--fmu FILE.fmu)")
    common(xp)
    xp.add_argument("--c", metavar="DIR", dest="c_dir",
                    help="write the C project (Makefile, CMakeLists.txt, API) into DIR")
    xp.add_argument("--fmu", metavar="FILE", help="write an FMU (.fmu) for linux64")
    xp.add_argument("--event-location", choices=("steps", "interpolant"),
                    help="how the exported engine locates events by default (the C "
                         "API's NAME_set_event_location changes it): by re-integrated "
                         "partial steps (steps, as fccgen simulate) or on the step's "
                         "interpolant (a step with an event then costs two steps' "
                         "evaluations and one more; docs/export.md \"Step time\")")
    xp.add_argument("--sensitivities", nargs="?", const=True, default=False,
                    metavar="KEY,KEY",
                    help="rk4 sensitivities with respect to the parameter keys (derives "
                         "the d/dp kernels; docs/export.md): the C project carries every "
                         "key's (chosen at run time); the FMU outputs d(COLUMN)/d(KEY) "
                         "for the keys named (all that have one without a list)")

    se = sub.add_parser("sensitivity", help="one rk4 (or dopri5) run with the derivatives "
                        "of every column with respect to parameter keys "
                        "(docs/sensitivities.md)")
    common(se)
    se.add_argument("--force", action="store_true", help="rebuild even if cached")
    se.add_argument("--params", required=True, metavar="KEY,KEY",
                    help="parameter keys, comma-separated, e.g. "
                         "bodies.arm.mass,loads[0].stiffness")
    se.add_argument("--t-end", type=float, help="end time (default: model's)")
    se.add_argument("--dt", type=float, help="time step (default: model's)")
    se.add_argument("--output-dt", type=float, help="output interval, a multiple of dt")
    se.add_argument("--method", choices=("rk4", "dopri5"), default="rk4",
                    help="the integrator (default: rk4)")
    se.add_argument("--rtol", type=float, help="dopri5: relative tolerance")
    se.add_argument("--atol", type=float, help="dopri5: absolute tolerance")
    se.add_argument("--sensitivity-error", action="store_true", default=None,
                    help="dopri5: the sensitivities in the step's error control")
    se.add_argument("--out", help="write t and the columns d(<column>)/d(<param>) to "
                    "FILE.csv, .npz or .h5")

    sw = sub.add_parser("sweep", help="many runs of one compiled model with different "
                        "numbers, on Dask; one row of summary figures per run",
                        epilog="KEY is an item path of the model file: gravity[k], "
                        "points.P.at[k], vectors.u.along[k], bodies.B.mass, "
                        "bodies.B.center[k], bodies.B.inertia[k], constraints[K].length, "
                        "loads[K].value[k], loads[K].at[k], loads[K].stiffness, "
                        "loads[K].length, loads[K].damping, initial.points.P[k], "
                        "simulate.t_end, simulate.dt, simulate.output_dt")
    common(sw)
    sw.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2,...",
                    required=True, help="numbers to try (repeatable: every combination "
                    "runs), e.g. bodies.arm.mass=1,2 or simulate.dt=1e-3,5e-4")
    sw.add_argument("--out", required=True,
                    help="the table to write (.csv, or .parquet with pyarrow)")
    sw.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, "
                    "e.g. tcp://host:8786 (default: a local cluster)")
    sw.add_argument("--method", help="integration method (default: the model's)")
    sw.add_argument("--workers", type=int, help="threads of the local cluster")
    sw.add_argument("--outputs", metavar="NAME:STAT,...", help="more table columns: a "
                    "result column's final, initial, max, min, absmax, tmax or tmin, an "
                    "event's time, last or count, a run statistic run:NAME, e.g. "
                    "motor.torque:max,latch:time,run:steps (docs/sweeps.md)")
    sw.add_argument("--run-timeout", type=float, metavar="SECONDS", help="stop a run "
                    "after this much wall time; its row gets status timeout (default: "
                    "no limit)")
    sw.add_argument("--resume", action="store_true", help="keep the rows of the partial "
                    "file a stopped sweep left beside --out and run only the others (runs "
                    "stopped by --run-timeout run again)")


def _method_options(items: list[str]) -> dict[str, float]:
    """NAME=VALUE strings of --method-option as a dict of numbers."""
    options = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError(item)
            options[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--method-option {item!r}: expected NAME=NUMBER") from None
    return options


def _solver_options(args) -> dict:
    """The solver tolerances given on the command line, checked."""
    out = {}
    for name in ("rank_tol", "position_tol"):
        value = getattr(args, name)
        if value is not None:
            if not (0.0 < value < 1.0):
                raise ValueError(f"--{name.replace('_', '-')} must be a number in (0, 1) "
                                 f"(got {value!r})")
            out[name] = value
    if args.max_newton is not None:
        if not 1 <= args.max_newton <= 1000:
            raise ValueError(f"--max-newton must be a whole number in [1, 1000] "
                             f"(got {args.max_newton!r})")
        out["max_newton"] = args.max_newton
    if getattr(args, "linear_solver", None) is not None:
        out["linear_solver"] = args.linear_solver
    return out


def _error_options(args) -> dict:
    """error=, error_on= of --error and --error-on, checked."""
    if args.error is None:
        if args.error_on:
            raise ValueError("--error-on measures the error of --error: give --error E")
        return {}
    chosen = [f"--{k}" for k in ("dt", "rtol", "atol") if getattr(args, k) is not None]
    if chosen or args.no_project:
        raise ValueError(f"--error chooses the step or tolerance itself: leave out "
                         f"{', '.join(chosen + (['--no-project'] if args.no_project else []))}")
    on = [c.strip() for c in (args.error_on or "").split(",") if c.strip()]
    return dict(error=args.error, error_on=on or None)


def _error_summary(info) -> str:
    """The choice of an error target and the error the run reached."""
    acc = info["accuracy"]
    cost = acc["cost"]
    repeat = (f", first run and its estimate {cost['repeat']:.3g}" if cost.get("repeat")
              else "")
    return (f"error target {info['error_target']:g}: chose {acc['choice']}\n"
            f"estimated error {info['error_estimate']:.3g} (largest at t = "
            f"{info['error_estimate_time']:.6g}; {acc['estimate']}); cost in evaluations: "
            f"pilot {cost['pilot']:.3g}, run {cost['run']:.3g}, estimate "
            f"{cost['estimate']:.3g}{repeat}; whole {cost.get('whole', 0):.3g}")


def _run_summary(result) -> str:
    """One paragraph of a run's statistics (result.info)."""
    info = result.info
    e = result["energy"]
    rejected = info.get("rejected_steps")
    return (f"{info.get('method')}: {info.get('steps')} steps to t = {result.t[-1]:.6g} "
            f"in {info.get('wall_time', float('nan')):.3g} s "
            f"({info.get('rhs_evaluations')} right-hand-side evaluations, "
            f"{'unknown' if rejected is None else rejected} rejected steps, "
            f"{info.get('newton_iterations', 0)} Newton iterations); "
            f"max constraint error {info.get('max_constraint_error', float('nan')):.3g}; "
            f"energy drift {info.get('energy_drift', float('nan')):.3g} "
            + (f"(max |E - E0|, E0 = {e[0]:.6g})" if "event_energy_loss" not in info else
               f"(max |E + event losses - E0|, E0 = {e[0]:.6g}; events took "
               f"{info['event_energy_loss']:.6g})") + _dof_summary(info)
            + _work_summary(info))


def _work_summary(info) -> str:
    """The energy balance with the work added back (runtime/energy_check.py), for a
    model whose energy changes on purpose."""
    check = info.get("energy_check") or {}
    if check.get("work") is None:
        return ""
    return (f"; energy balance {check.get('balance_drift', float('nan')):.3g} "
            f"(max |E - W + event losses - E0|, W = {check['work']:.6g}: the work of "
            f"dampers, drivers and loads without potential)")


def _internal_note(result, args) -> str:
    """What became of the internal columns (result.internal) in the file written."""
    hidden = len(result.internal)
    if not hidden:
        return ""
    if args.all_columns:
        return f" and {hidden} internal columns"
    if args.out.lower().endswith(".csv"):
        return f"; {hidden} internal columns left out, --all-columns writes them"
    return f"; {hidden} internal columns kept apart"


def _dof_summary(info) -> str:
    """The run's degrees of freedom by rank and what the rank decisions saw."""
    if "dof" not in info:
        return ""
    text = f"; degrees of freedom {info['dof']} by rank"
    if info.get("final_dof", info["dof"]) != info["dof"]:
        text += f", {info['final_dof']} at the end"
    drops = info.get("singular_position_factorisations", 0)
    if drops:
        text += f" ({drops} factorisations near a singular position)"
    bad = info.get("sparse_unconverged_solves", 0)
    if bad:
        beyond = info.get("sparse_beyond_rank_solves", 0)
        text += (f"; {bad} of {info.get('sparse_solves')} sparse solves did not converge"
                 f" ({info.get('sparse_dense_fallbacks', 0)} redone by the dense solve"
                 + (f", {beyond} at a row dependent only on the constraints"
                    if beyond else "") + ")")
    return text


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] not in COMMANDS and not argv[0].startswith("-"):
        argv.insert(0, "generate")
    args = _parser().parse_args(argv)
    if args.command is None:
        _parser().print_help()
        return 2
    progress = _Progress(getattr(args, "quiet", False))
    with warnings.catch_warnings():
        warnings.simplefilter("always", CacheRepairWarning)
        warnings.simplefilter("always", PartialResultWarning)
        warnings.simplefilter("always", RunWarning)
        warnings.showwarning = _show_warning
        try:
            return _guarded(args, progress)
        finally:
            progress.close()


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """fccgen's warnings as one line on stderr (no source location)."""
    write_line(f"fccgen: warning: {message}")


def _error(progress, text: str, code: int) -> int:
    progress.close()
    print(f"fccgen: {text}", file=sys.stderr)
    return code


def _partial_note(exc, args) -> str:
    path = getattr(exc, "partial_path", None)
    if path is not None:
        return f"; partial result written to {path}"
    if getattr(args, "keep_partial", False) and getattr(args, "out", None):
        return ("; --keep-partial: the integrator handed back no recorded rows, so no "
                "partial result was written")
    return "; no results written" if getattr(args, "out", None) else ""


def _guarded(args, progress) -> int:
    """Run a command; every expected failure ends as one 'fccgen: error:' paragraph
    and Ctrl-C as one line with exit status 130, never a traceback."""
    try:
        return _run(args, progress)
    except KeyboardInterrupt as exc:
        return _error(progress, f"interrupted{_partial_note(exc, args)}", EXIT_INTERRUPTED)
    except ModelError as exc:
        return _error(progress, f"error: {exc}", 2)
    except (FccgenError, ValueError) as exc:
        return _error(progress, f"error: {exc}{_partial_note(exc, args)}", 1)
    except OSError as exc:      # anything the library did not word itself
        where = f" {shown_path(exc.filename)}" if exc.filename else ""
        return _error(progress, f"error: cannot use{where}: {os_reason(exc)}", 1)


def _run(args, progress) -> int:
    from . import api
    if args.command == "examples":
        from .example_models import copy_examples, example_names
        written = copy_examples(args.dir, overwrite=args.overwrite)
        print(f"examples: {len(written)} files written to {args.dir}"
              + ("" if written else " (all were there; --overwrite replaces them)")
              + f"\nmodels: {', '.join(example_names())}"
              f"\ntry: fccgen simulate {args.dir}/double_pendulum.yaml --out "
              "double_pendulum.csv")
        return 0
    if args.command == "generate":
        t0 = time.perf_counter()
        plan, built = api.generate(args.model, args.build_dir, force=args.force,
                                   progress=progress)
        how = "served from the cache" if built.cache_hit else "built"
        print(f"{plan.model.name}: {how} in {time.perf_counter() - t0:.2f} s "
              f"({plan.n_q} coordinates, {plan.n_g} constraint equations, "
              f"{len(plan.classes)} element classes)")
        print(f"module: {built.path}")
        print("use it from Python:\n"
              "    import fccgen\n"
              f"    solver = fccgen.load({str(args.model)!r}"
              + ("" if args.build_dir == "generated" else f", build_dir={args.build_dir!r}")
              + ")\n"
              "    result = solver.simulate()        # result['t'], result.names\n"
              "or import the kernel module itself:\n"
              f"    import sys; sys.path.insert(0, {str(built.directory)!r})\n"
              f"    import {built.module_name}")
        return 0
    if args.command == "sensitivity":
        from .runtime.sensitivity.summary import summary
        result = api.sensitivity(args.model, args.params, t_end=args.t_end, dt=args.dt,
                                 output_dt=args.output_dt, out=args.out,
                                 build_dir=args.build_dir, force=args.force,
                                 progress=progress, method=args.method, rtol=args.rtol,
                                 atol=args.atol,
                                 sensitivity_error=args.sensitivity_error)
        print(summary(result, args.out))
        return 0
    if args.command == "export":
        from .export.cli import run_export
        return run_export(args, progress)
    if args.command == "simulate":
        options = _method_options(args.method_option)
        options.update({k: v for k, v in (("alpha", args.baumgarte_alpha),
                                          ("beta", args.baumgarte_beta)) if v is not None})
        if args.no_reactions:
            options["reactions"] = False
        if args.event_location is not None:
            options["event_location"] = args.event_location
        options.update(_error_options(args))
        result, init = api.simulate(
            args.model, t_end=args.t_end, dt=args.dt, method=args.method,
            output_dt=args.output_dt, project=not args.no_project, numeric=args.numeric,
            out=args.out, build_dir=args.build_dir, force=args.force,
            keep_partial=args.keep_partial, progress=progress, all_columns=args.all_columns,
            rtol=args.rtol, atol=args.atol, solver_options=_solver_options(args), **options)
        print(init.report())
        print(_run_summary(result))
        if "error_target" in result.info:
            print(_error_summary(result.info))
        reaction = result.info.get("reactions", {})
        said = " ".join(result.info.get("warnings", []))     # already printed as warnings
        text = reaction.get("note") or reaction.get("reason")
        if text and text not in said:
            print(f"fccgen: warning: {text}", file=sys.stderr)
        if "events" in result.info:                  # the model has events
            from .events.table import summary
            print(summary(result.events))
        if args.out:
            print(f"results: {args.out} ({len(result.t)} rows, {len(result.names)} "
                  f"columns{_internal_note(result, args)})")
        else:
            print("no --out given: results not written")
        return 0
    if args.command == "bench" and args.force:
        api.generate(args.model, args.build_dir, force=True, progress=progress)
    if args.command == "bench" and args.accuracy:
        return _accuracy(args, progress)
    if args.command == "bench":
        from .bench.speed import bench_model
        report = bench_model(args.model, args.build_dir, repeats=args.repeats,
                             progress=progress)
        print(report.text())
        return 0
    if args.command == "plot":
        print(f"figure: {api.plot(args.result, args.columns, args.out)}")
        return 0
    if args.command == "animate":
        page, n_frames, result = api.animate(
            args.model, args.out, result=args.result, mode=args.mode, t_end=args.t_end,
            max_frames=args.frames, build_dir=args.build_dir, progress=progress)
        print(f"animation: {page} ({n_frames} frames of {len(result.t)} rows)")
        return 0
    if args.command == "sweep":
        from .sweep import SweepInterrupted, quiet_dask
        try:
            quiet_dask()                       # its logged tracebacks: one paragraph
            table = api.sweep(args.model, args.set, args.out, scheduler=args.scheduler,
                              method=args.method, workers=args.workers,
                              outputs=args.outputs, run_timeout=args.run_timeout,
                              resume=args.resume, build_dir=args.build_dir,
                              progress=progress)
        except SweepInterrupted as exc:              # rows saved: say how many, where
            return _error(progress, str(exc), EXIT_INTERRUPTED)
        except ModelError:
            raise
        except (FccgenError, ValueError) as exc:     # the message says what was saved
            return _error(progress, f"error: {exc}", 1)
        late = f", {table.timed_out} of them timed out" if table.timed_out else ""
        print(f"sweep: {len(table.rows)} runs ({table.failed} failed{late}) on {table.where} "
              f"in {table.wall_time:.3g} s\ntable: {args.out}")
        return 0
    if args.command == "check":
        from .diagnostics.check import check_model
        print(check_model(args.model, progress=progress,
                          generate=not args.no_generate).text())
        return 0
    if args.command in ("statics", "modes", "inverse"):
        return _analysis(args, progress, api)
    raise AssertionError(args.command)


def _analysis(args, progress, api) -> int:
    """``fccgen statics`` and ``fccgen modes``: one call of the API each."""
    if args.command == "statics":
        from .analysis.statics_result import reaction_lines
        eq, result = api.equilibrium(args.model, out=args.out, build_dir=args.build_dir,
                                     progress=progress)
        print("\n".join([eq.text(multipliers=False), *reaction_lines(result)]))
        if args.out:
            print(f"equilibrium: {args.out} (one row at t = 0, {len(result.names)} "
                  "columns; how it was made in its metadata)")
        return 0
    if args.command == "inverse":
        from .analysis.inverse import summary
        from .api import inverse_dynamics
        result = inverse_dynamics(args.model, t_end=args.t_end, dt=args.dt, out=args.out,
                                  numeric=args.numeric, build_dir=args.build_dir,
                                  progress=progress)
        print(summary(result, args.out))
        return 0
    result, equilibrium = api.modes(args.model, about=args.about, out=args.out,
                                    shapes=args.shapes, amplitude=args.amplitude,
                                    build_dir=args.build_dir, progress=progress)
    if equilibrium is not None:
        print(equilibrium.summary())
    print(result.text())
    if args.out:
        print(f"modes: {args.out}")
    _print_shape_files(args, len(result.frequency_hz))
    return 0


def _print_shape_files(args, n_modes: int) -> None:
    """Where fccgen modes --shapes wrote the shapes, and how to play one."""
    if not args.shapes or not n_modes:
        return
    from .results.files import mode_shape_path
    names = [str(mode_shape_path(args.shapes, k)) for k in range(1, n_modes + 1)]
    print(f"mode shapes: {', '.join(names)}\nplay one: fccgen animate {args.model} "
          f"--result {args.shapes} --mode 1 --out mode1.html")


def _accuracy(args, progress) -> int:
    """``fccgen bench MODEL --accuracy``: one call of
    :func:`fccgen.bench.accuracy.bench_accuracy`."""
    from .bench.accuracy import reference_from_table
    from .bench.accuracy_report import bench_accuracy
    from .results.result import check_output
    check_output(f"{args.out_dir}/summary.csv", "--out-dir")    # writable, before the run
    reference = None
    if args.reference:
        if not args.reference_point:
            raise ValueError("--reference needs --reference-point (the point it gives)")
        reference = reference_from_table(args.reference, args.reference_point)
    methods = [m.strip() for m in args.methods.split(",")] if args.methods else None
    report = bench_accuracy(args.model, args.build_dir, args.out_dir, t_end=args.t_end,
                            output_dt=args.output_dt, methods=methods,
                            numeric_rungs=args.numeric_rungs, reference=reference,
                            progress=progress)
    print(report.summary())
    for note in report.notes:
        print(f"note: {note}")
    for kind, path in report.files.items():
        print(f"{kind}: {path}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
