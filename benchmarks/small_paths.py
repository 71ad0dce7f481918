"""The dense and the sparse path on the small examples, and the path "auto" takes.

    python benchmarks/small_paths.py [--reps R] [--csv FILE] [examples ...]

For every example below fccgen.runtime.paths.SPARSE_MIN_COORDINATES coordinates (or
those named): CPU per RK4 step (dt 1e-3, projection on, from the consistent initial
state) on the dense and on the sparse path, timed as benchmarks/peers/timing.py times
(warm, interleaved, medians; the run's set-up removed), their ratio, and the path
"auto" takes after its rank decision at that state (runtime/paths.py,
small_model_path) with the signals it reads (models with events too: both paths run
them). Single-threaded BLAS, set here before NumPy loads.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))

import numpy as np  # noqa: E402

import fccgen  # noqa: E402
from fccgen import rank as rank_rule  # noqa: E402
from fccgen.runtime import paths  # noqa: E402
from timing import time_interleaved  # noqa: E402

DT = 1e-3


class Run:
    """advance(n_steps): an RK4 run from the consistent initial state."""

    def __init__(self, solver):
        self.solver = solver
        init = solver.initial_state()
        self.q0, self.v0 = init.q, init.v

    def advance(self, n_steps: int) -> None:
        t_end = n_steps * DT
        self.solver.simulate(t_end=t_end, dt=DT, method="rk4", output_dt=t_end,
                             q0=self.q0, v0=self.v0, reactions=False)


def signals(solver) -> tuple[float, float, float]:
    """(kept sigma, manifold sigma, reduced mass spread) at the initial state
    (CompiledSolver.small_path_signals)."""
    q = solver.initial_state().q
    B = solver.constraint_jacobian(q)
    return solver.small_path_signals(q, B, rank_rule.decide(B, solver.n_q,
                                                            solver.row_groups))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--csv", type=Path, help="also write the table as CSV")
    ap.add_argument("examples", nargs="*")
    args = ap.parse_args(argv)
    files = ([ROOT / "examples" / f"{name}.yaml" for name in args.examples]
             or sorted((ROOT / "examples").glob("*.yaml")))
    rows = []
    header = ("example", "n_q", "dense_us", "sparse_us", "dense/sparse", "auto",
              "kept_sigma", "manifold_sigma", "mass_spread")
    print(" | ".join(header), flush=True)
    with tempfile.TemporaryDirectory(prefix="fccgen-small-") as build:
        for path in files:
            auto = fccgen.load(path, build)
            if not args.examples and auto.n_q >= paths.SPARSE_MIN_COORDINATES:
                continue
            auto.initial_state()
            models = {"dense": Run(fccgen.load(path, build, linear_solver="dense")),
                      "sparse": Run(fccgen.load(path, build, linear_solver="sparse"))}
            kept, manifold, spread = signals(models["sparse"].solver)
            times = {tool: t.per_step * 1e6
                     for tool, t in time_interleaved(models, args.reps).items()}
            sparse = times.get("sparse", float("nan"))
            row = (path.stem, auto.n_q, f"{times['dense']:.2f}", f"{sparse:.2f}",
                   f"{times['dense'] / sparse:.2f}" if np.isfinite(sparse) else "",
                   "sparse" if auto.sparse else "dense",
                   f"{kept:.2g}", f"{manifold:.2g}", f"{spread:.2g}")
            rows.append(row)
            print(" | ".join(str(x) for x in row), flush=True)
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            csv.writer(f).writerows([header, *rows])
    return 0


if __name__ == "__main__":
    sys.exit(main())
