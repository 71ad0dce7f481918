"""Cost per RK4 step of the dense and the sparse path on the A02 chain, against its size.

    python benchmarks/scaling.py [--n 5 10 20 40 80 160 320] [--dense-max 160]

For each N the A02 N-four-bar model (examples/make_n_four_bar.py) is generated and
compiled into a scratch directory, loaded once with ``linear_solver="dense"`` and once
with ``"sparse"``; from the consistent initial state, RK4 with projection at
dt = 1e-3 is timed: a warm-up run, then several runs of K steps (K chosen so that a run
takes about 0.2 s) and of 2K steps, the median of their difference over K reported
(the run's set-up excluded). Prints the table and, for each
path, the exponent p of time ~ N^p fitted by least squares of log time on log N.
The dense path above --dense-max is skipped (one step costs a second at N = 320).
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import statistics  # noqa: E402
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


def step_time(solver, q0, v0, target: float = 0.2, repeats: int = 5) -> float:
    """Median seconds per RK4 step (with projection) of warm runs: runs of 2K and K
    steps, their difference over K (so the run's set-up, the dense SVD of the initial
    rank decision and the first projections, is not counted)."""
    def run(k):
        t0 = time.perf_counter()
        solver.simulate(t_end=k * DT, dt=DT, method="rk4", q0=q0, v0=v0,
                        output_dt=k * DT)
        return time.perf_counter() - t0
    k = 4
    while run(k) < target and k < 1 << 16:
        k *= 2
    return statistics.median((run(2 * k) - run(k)) / k for _ in range(repeats))


def exponent(ns, times) -> float:
    """p of time ~ N^p, least squares in log-log."""
    return float(np.polyfit(np.log(ns), np.log(times), 1)[0])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[5, 10, 20, 40, 80, 160, 320])
    parser.add_argument("--dense-max", type=int, default=160)
    args = parser.parse_args(argv)
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
