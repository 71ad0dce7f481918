"""Worst over median step time of the exported C engine, on the thread's CPU clock
(docs/export.md, "Step time"; docs/performance.md).

    python benchmarks/step_time_spread.py [--repeats 5] [--models a02_n_four_bar,solar_array]
        [--event-location steps,interpolant]

Per model: fccgen export --c (rk4 with projection, the sparse path, the model's dt),
built with -O2, linked with the timing harness benchmarks/c/step_spread.c, which runs
the model's whole simulate: run REPEATS times warm, one step_to of one dt at a time,
and times each step with clock_gettime(CLOCK_THREAD_CPUTIME_ID) and, for comparison,
CLOCK_MONOTONIC. On a shared machine the wall clock of a step also holds the time the
thread waited for a core (a preemption costs a whole scheduler slice, milliseconds),
which the per-thread CPU clock leaves out: it measures the engine.

Steps are split by what happened in them: a step in which an event was located and
acted on (its event log grew: the Illinois iterations of re-integrated partial steps,
the impact, the rest of the step) is an "event step"; the others are plain steps
(after a lock the plain steps carry the locked rows, so they cost more than before
it; they are still plain steps). Printed per model and clock, each statistic the
median over the repeats: the median step, the 99.9th percentile and the worst step of
the plain steps, worst / median (the issue's bound: 1.5), p99.9 / median; "least
w/m", the worst over the median of each step's least time over the repeats (the
machine's interruptions land on other steps in each repeat, the engine's own work on
the same ones: this is the engine's spread); and the worst event step over the
median plain step. Then where the time goes: the sparse solves' refinement
iterations per plain step (the step's cost follows them) and the acceleration
evaluations of plain and event steps. Run with single-threaded BLAS; no Python runs
in the timed loop.

--event-location: the exports' ways of locating events (fccgen export
--event-location), each model exported and timed once per way, in turn: "steps"
(re-integrated partial steps, the default) and "interpolant" (the step's
interpolant: an event step takes one evaluation more than a step and the rest of the
step). Models without events are timed once.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from fccgen.api import plan_model  # noqa: E402
from fccgen.export import export_c  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
HARNESS = Path(__file__).resolve().parent / "c" / "step_spread.c"


def step_times(name: str, folder: Path, repeats: int) -> np.ndarray:
    """(repeats, n_steps, 5): per step CPU ns, wall ns, events in it, the sparse
    solves' refinement iterations and the acceleration evaluations."""
    cc = shutil.which("cc") or shutil.which("gcc")
    subprocess.run(["make", "-s", f"CC={cc}", "CFLAGS=-std=c99 -O2", f"lib{name}.a"],
                   cwd=folder, check=True)
    exe = folder / "spread"
    subprocess.run([cc, "-std=c99", "-O2", f"-I{folder}", f"-DMODEL={name}",
                    f"-DAPI_SOURCE={name}_api.c", str(HARNESS),
                    str(folder / f"lib{name}.a"), "-o", str(exe), "-lm"],
                   cwd=folder, check=True)
    out = subprocess.run([str(exe), str(repeats)], cwd=folder, check=True,
                         capture_output=True, text=True).stdout
    return np.array([[[float(x) for x in line.split()] for line in block.splitlines()[1:]]
                     for block in out.split("run ")[1:]])


def spread(times: np.ndarray, plain: np.ndarray) -> dict:
    """Statistics of one repeat's step times (seconds) on one clock: of the plain
    steps, and the worst event step over the plain median."""
    med = float(np.median(times[plain]))
    return dict(median=med, p999=float(np.quantile(times[plain], 0.999)),
                worst=float(np.max(times[plain])),
                event=float(np.max(times[~plain])) / med if np.any(~plain) else np.nan)


def model_dt(folder: Path, name: str) -> float:
    """The exported run's step (DT of NAME_data.h, a hexadecimal literal)."""
    for line in (folder / f"{name}_data.h").read_text().splitlines():
        if line.startswith("#define DT "):
            return float.fromhex(line.split()[2])
    raise ValueError(f"{name}_data.h has no DT")


def report(name: str, runs: np.ndarray, dt: float) -> None:
    plain = runs[0, :, 2] == 0
    for col, clock in ((0, "cpu"), (1, "wall")):
        stats = [spread(r[:, col] * 1e-9, plain) for r in runs]
        m = {k: float(np.median([s[k] for s in stats])) for k in stats[0]}
        least = runs[:, :, col].min(axis=0)        # per step, the least over repeats
        engine = float(np.max(least[plain]) / np.median(least[plain]))
        print(f"{name:15s} {clock:5s} {plain.size:6d} {m['median'] * 1e6:7.2f}us "
              f"{m['p999'] * 1e6:8.2f}us {m['worst'] * 1e6:9.2f}us "
              f"{m['worst'] / m['median']:9.2f} {m['p999'] / m['median']:9.2f} "
              f"{engine:10.2f} {int(np.sum(~plain)):6d} {m['event']:9.2f}")
    least = runs[:, :, 0].min(axis=0)
    slow = int(np.flatnonzero(plain)[np.argmax(least[plain])])
    it, rhs = runs[0, :, 3], runs[0, :, 4]
    print(f"{'':15s} refinement iterations per plain step: median {np.median(it[plain]):.0f}, "
          f"max {it[plain].max():.0f}, at the slowest plain step (ending at t = "
          f"{(slow + 1) * dt:g} s) {it[slow]:.0f}; acceleration evaluations: "
          f"plain {np.median(rhs[plain]):.0f}"
          + (f", event steps {', '.join(f'{x:.0f}' for x in rhs[~plain])}"
             if np.any(~plain) else ""))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--models", default="a02_n_four_bar,solar_array")
    p.add_argument("--event-location", default="steps",
                   help="comma-separated: steps, interpolant (default steps)")
    args = p.parse_args()
    ways = args.event_location.split(",")
    with tempfile.TemporaryDirectory() as tmp:
        build = Path(tmp) / "generated"
        print(f"{'model':15s} {'clock':5s} {'steps':>6s} {'median':>9s} {'p99.9':>10s} "
              f"{'worst':>11s} {'worst/med':>9s} {'p99.9/med':>9s} {'least w/m':>10s} "
              f"{'events':>6s} {'event/med':>9s}")
        for name in args.models.split(","):
            model = ROOT / "examples" / f"{name}.yaml"
            for way in (ways if plan_model(model).model.events else ways[:1]):
                folder = export_c(model, Path(tmp) / f"{name}_{way}", build,
                                  event_location=way)
                label = name if len(ways) == 1 else f"{name}/{way[:6]}"
                report(label, step_times(name, folder, args.repeats),
                       model_dt(folder, name))


if __name__ == "__main__":
    main()
