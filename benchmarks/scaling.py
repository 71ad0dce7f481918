"""Cost per RK4 step of the dense and the sparse path on the A02 chain, against its size.

    python benchmarks/scaling.py [--n 5 10 20 40 80 160 320] [--dense-max 160] [--cpu-time]

For each N the A02 N-four-bar model (examples/make_n_four_bar.py) is generated and
compiled into a scratch directory, loaded once with ``linear_solver="dense"`` and once
with ``"sparse"``; from the consistent initial state, RK4 with projection at
dt = 1e-3 is timed: runs of K and of 2K steps (K doubled until the K extra steps take
about 0.2 s), the difference of the fastest of 5 runs of each length over K reported
(the run's set-up excluded; on a loaded machine the fastest run is the one least
disturbed). Prints the table and, for each path, the exponent p of time ~ N^p fitted by least squares of log time on log N.
The dense path above --dense-max is skipped (one step costs a second at N = 320).
With --cpu-time the process's CPU time is measured instead of wall time: on a machine
shared with other work it counts only this process's own work.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import fccgen  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DT = 1e-3


def model_text(n: int) -> str:
    spec = importlib.util.spec_from_file_location(
        "make_n_four_bar", ROOT / "examples" / "make_n_four_bar.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.model_text(n)


CLOCK = time.perf_counter


def step_time(solver, q0, v0, target: float = 0.2, repeats: int = 5) -> float:
    """Seconds per RK4 step (with projection) of warm runs: runs of K and 2K steps,
    K doubled until the K extra steps take about ``target`` seconds, the difference of
    the fastest run of each length over K (so the run's set-up, the dense SVD of the
    initial rank decision and the first projections, is not counted; the fastest runs,
    as the machine's other work only ever adds time)."""
    def run(k):
        t0 = CLOCK()
        solver.simulate(t_end=k * DT, dt=DT, method="rk4", q0=q0, v0=v0,
                        output_dt=k * DT)
        return CLOCK() - t0
    k = 4
    while run(2 * k) - run(k) < target and k < 1 << 16:
        k *= 2
    shorter = min(run(k) for _ in range(repeats))
    longer = min(run(2 * k) for _ in range(repeats))
    return (longer - shorter) / k


def exponent(ns, times) -> float:
    """p of time ~ N^p, least squares in log-log."""
    return float(np.polyfit(np.log(ns), np.log(times), 1)[0])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[5, 10, 20, 40, 80, 160, 320])
    parser.add_argument("--dense-max", type=int, default=160)
    parser.add_argument("--cpu-time", action="store_true",
                        help="time the process's CPU time, not wall time")
    args = parser.parse_args(argv)
    global CLOCK
    CLOCK = time.process_time if args.cpu_time else time.perf_counter
    warnings.simplefilter("ignore")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.n:
            path = Path(tmp) / f"a02_{n}.yaml"
            path.write_text(model_text(n))
            build = Path(tmp) / "generated"
            sparse = fccgen.load(path, build, linear_solver="sparse")
            init = sparse.initial_state()
            t_sparse = step_time(sparse, init.q, init.v)
            t_dense = None
            if n <= args.dense_max:
                dense = fccgen.load(path, build, linear_solver="dense")
                t_dense = step_time(dense, init.q, init.v)
            rows.append((n, sparse.n_q, t_dense, t_sparse))
            dense_text = f"{1e3 * t_dense:10.4f}" if t_dense else f"{'-':>10}"
            print(f"N {n:4d}  n_q {sparse.n_q:5d}  dense {dense_text} ms  "
                  f"sparse {1e3 * t_sparse:8.4f} ms", flush=True)
    print("\n| N | n_q | dense (ms/step) | sparse (ms/step) |\n| --- | --- | --- | --- |")
    for n, nq, td, ts in rows:
        print(f"| {n} | {nq} | {f'{1e3 * td:.4f}' if td else '-'} | {1e3 * ts:.4f} |")
    dense_rows = [(n, td) for n, _, td, _ in rows if td]
    if len(dense_rows) > 1:
        print(f"\ndense exponent: {exponent(*zip(*dense_rows)):.2f}")
    if len(rows) > 1:
        print(f"sparse exponent: {exponent([r[0] for r in rows], [r[3] for r in rows]):.2f}")


if __name__ == "__main__":
    main()
