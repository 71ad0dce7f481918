"""Time per step of fccgen, MuJoCo and Exudyn on the same systems, against size.

    python benchmarks/peers/run.py [--system a02|cart|boom] [--sizes N ...] [--reps R]
                                   [--fccgen-solver auto|dense|sparse] [--dt 1e-3]
                                   [--fccgen-no-projection] [--name STEM] [--steps K]

Needs the ``peers`` extra (``pip install -e .[peers]``: mujoco, exudyn). Systems: the
A02 N-four-bar chain (N loops), the n-link pendulum on a cart and the scissor boom of
n units (``systems.py``); the same geometry, masses, loads and initial state in every
tool, the same step dt. fccgen: RK4 with projection (its default); MuJoCo: its RK4,
loops closed by soft ``connect`` constraints; Exudyn: generalized-alpha with its
sparse solver. MuJoCo has no model of the boom: its column says so. Time per
step as in ``timing.py`` (CPU, warm, medians of interleaved repetitions; the same k
for every tool where ``systems.TIMED_STEPS`` sets one, the boom, or ``--steps``
gives one, within the system's ``TIMED_SPAN``). Prints the table of times and ratios
and the exponent p of time ~ N^p (least squares of log time on log N over the sizes
>= --fit-from); writes ``STEM.csv`` and ``STEM.png`` (log-log;
STEM is --name, default ``peers_scaling``) into --out-dir. ``--fccgen-no-projection`` runs
fccgen's RK4 without the projection after each step (``project=False``: what that
projection costs; its constraint drift is then the integrator's). Run with
single-threaded BLAS (set here before NumPy loads), as the other benchmarks.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from systems import (PEERS, ROOT, SYSTEMS, TIMED_SPAN, TIMED_STEPS, TITLES,  # noqa: E402
                     n_coordinates)

TOOLS = ("fccgen", "mujoco", "exudyn")
DEFAULT_SIZES = {"a02": (5, 10, 20, 40, 80, 160, 320), "cart": (1, 2, 5, 10, 20, 50, 100, 200),
                 "boom": (10, 20, 50, 100, 250, 500)}


def make_models(system, n, dt, fccgen_solver, project=True):
    """{tool: model} of fccgen and of the peers that have a model of the system (a peer
    without one is neither imported nor timed)."""
    import importlib

    import fccgen_models
    models = {"fccgen": fccgen_models.make(system, n, dt, linear_solver=fccgen_solver,
                                           project=project)}
    for tool in PEERS[system]:
        models[tool] = importlib.import_module(f"{tool}_models").make(system, n, dt)
    return models


def measure(system, sizes, dt, reps, fccgen_solver, log, project=True, steps=None):
    from timing import MAX_STEPS, time_interleaved
    steps = steps or TIMED_STEPS[system]
    span = TIMED_SPAN[system]
    max_steps = MAX_STEPS if span is None else max(1, min(MAX_STEPS, int(span / (2 * dt))))
    if steps and span is not None:
        steps = min(steps, max_steps)      # a given k stays within the span too
    rows = []
    for n in sizes:
        timings = time_interleaved(make_models(system, n, dt, fccgen_solver, project),
                                   reps, max_steps, steps)
        for t in timings.values():
            rows.append(dict(system=system, n=n, n_q=n_coordinates(system, n), tool=t.tool,
                             seconds_per_step=t.per_step, steps=t.steps, setup=t.setup,
                             spread=t.spread))
        log(f"{system} n={n}: " + ", ".join(
            f"{t.tool} {t.per_step * 1e3:.4g} ms" for t in timings.values()))
    return rows


def exponent(rows, system, tool, fit_from):
    pts = [(r["n"], r["seconds_per_step"]) for r in rows
           if r["system"] == system and r["tool"] == tool and r["n"] >= fit_from]
    if len(pts) < 2:
        return float("nan")
    n, t = np.log(np.array(pts, dtype=float)).T
    return float(np.polyfit(n, t, 1)[0])


def table(rows, system, fit_from) -> str:
    """Markdown table: times per step, ratios, and the fitted exponents; a peer without
    a model of the system has "no model" in its columns."""
    by = {(r["n"], r["tool"]): r["seconds_per_step"] for r in rows if r["system"] == system}
    sizes = sorted({n for n, _ in by})
    head = ("| n | fccgen n_q | fccgen | MuJoCo | Exudyn | fccgen/MuJoCo | fccgen/Exudyn |\n"
            "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    lines = [head]
    for n in sizes:
        f, m, e = (by.get((n, tool)) for tool in TOOLS)
        lines.append(f"| {n} | {n_coordinates(system, n)} | {_ms(f)} | {_ms(m)} | {_ms(e)} "
                     f"| {_ratio(f, m)} | {_ratio(f, e)} |")
    p = {tool: (f"{exponent(rows, system, tool, fit_from):.2f}"
                if tool == "fccgen" or tool in PEERS[system] else "no model") for tool in TOOLS}
    lines.append(f"| exponent (n >= {fit_from}) | | {p['fccgen']} | {p['mujoco']} "
                 f"| {p['exudyn']} | | |")
    return "\n".join(lines)


def _ms(seconds: float | None) -> str:
    return "no model" if seconds is None else f"{seconds * 1e3:.3g} ms"


def _ratio(a: float, b: float | None) -> str:
    return "" if b is None else f"{a / b:.3g}"


def write_csv(rows, path: Path) -> None:
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def plot(rows, systems, path: Path, note: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(systems), figsize=(5.5 * len(systems), 4.2),
                             squeeze=False)
    for ax, system in zip(axes[0], systems):
        for tool, marker in zip(TOOLS, "os^"):
            pts = sorted((r["n"], r["seconds_per_step"]) for r in rows
                         if r["system"] == system and r["tool"] == tool)
            if pts:
                n, t = zip(*pts)
                ax.loglog(n, np.array(t) * 1e3, marker=marker, label=tool)
        ax.set_title(TITLES[system])
        ax.set_xlabel("n")
        ax.set_ylabel("CPU time per step (ms)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle(note, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--system", choices=SYSTEMS, action="append",
                    help="a system to measure (repeatable; default a02 and cart, the "
                         "boom only when named)")
    ap.add_argument("--sizes", type=int, nargs="+",
                    help="sizes N (default: a02 5..320, cart 1..200, boom 10..500)")
    ap.add_argument("--reps", type=int, default=5, help="repetitions (medians of these)")
    ap.add_argument("--dt", type=float, default=1e-3, help="step of every tool (s)")
    ap.add_argument("--fccgen-solver", default="auto", choices=("auto", "dense", "sparse"),
                    help="fccgen's linear_solver option (passed only when not auto)")
    ap.add_argument("--fccgen-no-projection", action="store_true",
                    help="fccgen's RK4 without the projection after each step")
    ap.add_argument("--fit-from", type=int, default=10,
                    help="smallest size in the fit of the exponents")
    ap.add_argument("--out-dir", type=Path, default=ROOT / "docs" / "performance")
    ap.add_argument("--steps", type=int,
                    help="k of every tool's timed runs (k and 2k steps from the start), "
                         "instead of each tool's calibrated k or the system's TIMED_STEPS")
    ap.add_argument("--name", default="peers_scaling",
                    help="stem of the written .csv and .png (default peers_scaling)")
    args = ap.parse_args(argv)
    systems = args.system or ["a02", "cart"]
    start = time.perf_counter()

    def log(message):
        print(f"[{time.perf_counter() - start:7.1f} s] {message}", flush=True)
    rows = []
    for system in systems:
        rows += measure(system, args.sizes or DEFAULT_SIZES[system], args.dt, args.reps,
                        args.fccgen_solver, log, not args.fccgen_no_projection, args.steps)
    note = (f"dt {args.dt:g} s, fccgen linear_solver {args.fccgen_solver}"
            f"{f', k = {args.steps} steps' if args.steps else ''}"
            f"{', no projection' if args.fccgen_no_projection else ''}, "
            f"{args.reps} reps; {platform.machine()} {platform.system()}, "
            f"{os.cpu_count()} CPUs, Python {platform.python_version()}, "
            f"{time.strftime('%Y-%m-%d')}")
    for system in systems:
        print(f"\n== {TITLES[system]}: CPU time per step ==\n{table(rows, system, args.fit_from)}")
    print(note)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = (args.out_dir / f"{args.name}{ext}" for ext in (".csv", ".png"))
    write_csv(rows, csv_path)
    plot(rows, systems, png_path, note)
    print(f"written: {csv_path}, {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
