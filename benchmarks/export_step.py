"""The exported C step against the Python-wrapped engine's step, and the spread of
the exported step's time (docs/export.md).

    python benchmarks/export_step.py [--repeats 7] [--models a02_n_four_bar,rsup,solar_array]

Per model: fccgen export --c (sparse path), built with -O2 (the Python build's flag);
then, in this one run, the model's whole simulate: run (rk4, projection, dt, t_end)
REPEATS times warm in each:

* exported: the C program benchmarks/c/export_steps.c, through the API, one
  step_to per step (the run pauses after every step);
* wrapped: fccgen.runtime._rk4.simulate_rk4 on the sparse engine of the Python build
  (the C loop, records every output_dt), from the same initial state, with the
  model's events (the solar array's two latches) as simulate runs them.

Printed: the median run time of each, their ratio (exported / wrapped), and from the
exported run the median, 99.9th percentile and worst single-step time and worst /
median (a loaded machine's preemptions land in the worst step: run it alone). The
solar array's worst steps are those that locate and apply a latch. Run with
single-threaded BLAS.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import fccgen  # noqa: E402
from fccgen.settings import methods as registry
from fccgen.export import export_c  # noqa: E402
from fccgen.runtime.solver import METHODS  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PROGRAM = Path(__file__).resolve().parent / "c" / "export_steps.c"


def exported_times(name: str, folder: Path, repeats: int) -> tuple[list, np.ndarray]:
    cc = shutil.which("cc") or shutil.which("gcc")
    subprocess.run(["make", "-s", f"CC={cc}", "CFLAGS=-std=c99 -O2", f"lib{name}.a"],
                   cwd=folder, check=True)
    exe = folder / "steps"
    subprocess.run([cc, "-std=c99", "-O2", f"-I{folder}", f"-DMODEL={name}",
                    f"-DHEADER={name}.h", str(PROGRAM), str(folder / f"lib{name}.a"),
                    "-o", str(exe), "-lm"], cwd=folder, check=True)
    out = subprocess.run([str(exe), str(repeats)], cwd=folder, check=True,
                         capture_output=True, text=True).stdout.splitlines()
    runs = [float(line.split()[1]) for line in out if line.startswith("run")]
    steps = np.array([float(x) for x in out[-1].split()[1:]]) * 1e-9
    return runs, steps


def wrapped_times(solver, repeats: int) -> list:
    from fccgen.runtime._rk4 import simulate_rk4
    d = solver.plan.model.simulate
    s = registry.schedule(registry.get("rk4", METHODS), d)
    solver.simulate(reactions=False)     # takes the full pattern if the run needs it
    init = solver.initial_state()
    solver.decide_rank(init.q)
    from fccgen.export.c_events import run_defaults
    events = solver._event_set(*run_defaults(solver))    # None: no events, no turns
    runs = []
    try:
        for r in range(repeats + 1):
            t0 = time.perf_counter()
            simulate_rk4(solver._engine, init.q, init.v, s.t_end, s.dt, s.n_steps,
                         s.every, True, events=events)
            if r:
                runs.append(time.perf_counter() - t0)
    finally:
        if events is not None:
            events.restore()
    return runs


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--models", default="a02_n_four_bar,rsup,solar_array")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        build = Path(tmp) / "generated"
        print(f"{'model':16s} {'exported s':>11s} {'wrapped s':>10s} {'ratio':>6s} "
              f"{'step median':>12s} {'p99.9':>10s} {'step worst':>11s} {'worst/med':>9s}")
        for name in args.models.split(","):
            path = ROOT / "examples" / f"{name}.yaml"
            folder = export_c(path, Path(tmp) / name, build)
            runs, steps = exported_times(name, folder, args.repeats)
            solver = fccgen.load(path, build, linear_solver="sparse")
            wrapped = wrapped_times(solver, args.repeats)
            e, w = statistics.median(runs), statistics.median(wrapped)
            med, worst = float(np.median(steps)), float(np.max(steps))
            p999 = float(np.quantile(steps, 0.999))
            print(f"{name:16s} {e:11.4f} {w:10.4f} {e / w:6.3f} {med * 1e6:10.2f}us "
                  f"{p999 * 1e6:8.2f}us {worst * 1e6:9.2f}us {worst / med:9.2f}")


if __name__ == "__main__":
    main()
