"""Whether fccgen's runs of A02 (N = 40) converge as the step shrinks: the search for a
converged reference that could judge an error target of 1e-6 over the 20 s.

    python benchmarks/a02_convergence.py [--t-end 20] [--dense]

Runs rk4 with projection at steps 0.05 / n (n = 11 ... 400) and dopri5 with projection
at rtol 1e-7 ... 3e-9, all recording every 0.05 s, on the model's path (sparse; with
--dense, the dense path as well, about 30 times slower). For each run: its steps, CPU
seconds, the largest distance of B0 from the published table (ADAMS, six digits) and,
for each pair of runs, the largest distance of any moving point over the run. A run
converges when the distances fall with the step as the method's order says (rk4: 16
times per halving); past A02's flat positions they do not (docs/accuracy.md). With
--t-end 0.6 (before the first flat position, at t = 0.72 s) the same ladder agrees to
1e-13 m. Writes docs/accuracy/a02_convergence_<t_end>.md (the table) and prints it.
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "accuracy"
TABLE = ROOT / "tests" / "reference" / "mbsbenchmark_A02_solution_data_B0.csv"
OUTPUT_DT = 0.05
RK4_DIVISIONS = (11, 22, 27, 50, 54, 100, 200, 400)      # dt = 0.05 / n
DOPRI5_RTOL = (1e-7, 3e-8, 1e-8, 3e-9)


def ladder(solver, t_end: float, label: str) -> list[tuple[str, object, float]]:
    """(name, result or failure text, CPU seconds) of every run of the ladder."""
    from fccgen.target_error.pilot import settings_of
    runs = []
    settings = ([("rk4", OUTPUT_DT / n, f"rk4 dt = 0.05/{n}") for n in RK4_DIVISIONS]
                + [("dopri5", r, f"dopri5 rtol = {r:g}") for r in DOPRI5_RTOL])
    for method, value, name in settings:
        start = time.process_time()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = solver.simulate(t_end=t_end, output_dt=OUTPUT_DT, method=method,
                                    reactions=False,
                                    **settings_of(method, value, solver.length_scale))
        except Exception as exc:          # noqa: BLE001  (a failed run is a row too)
            r = " ".join(str(exc).split())[:160]
        runs.append((f"{name} ({label})", r, time.process_time() - start))
        print(f"{runs[-1][0]}: {time.process_time() - start:.2f} s", flush=True)
    return runs


def report(runs, t_end: float, plan) -> str:
    from fccgen.bench.accuracy import reference_from_table
    from fccgen.target_error.compare import compared, distance
    ok = [(n, r) for n, r, _ in runs if not isinstance(r, str)]
    what = compared(plan, 1.0)            # every moving point
    lines = [f"A02 (N = 40) over {t_end:g} s, every {OUTPUT_DT} s.", "",
             "| run | steps | CPU (s) | B0 from the published table (m) |",
             "| --- | ---: | ---: | ---: |"]
    table = reference_from_table(TABLE, "B0").until(t_end)
    for name, r, cpu in runs:
        if isinstance(r, str):
            lines.append(f"| {name} | failed: {r} | {cpu:.2f} | |")
            continue
        lines.append(f"| {name} | {r.info['steps']} | {cpu:.2f} | "
                     f"{table.error(r)[0]:.2g} |")
    lines += ["", "Largest distance of any moving point between two runs (m):", "",
              "| | " + " | ".join(str(k) for k in range(len(ok))) + " |",
              "| --- |" + " ---: |" * len(ok)]
    for i, (name, a) in enumerate(ok):
        cells = [f"{np.max(distance(a, b, what, t_end)[1]):.1e}" for _, b in ok]
        lines.append(f"| {i}: {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--t-end", type=float, default=20.0)
    ap.add_argument("--dense", action="store_true",
                    help="the dense path too (about 30 times slower)")
    args = ap.parse_args()
    import fccgen
    from fccgen.runtime import CompiledSolver
    with tempfile.TemporaryDirectory() as tmp:
        solver = fccgen.load(ROOT / "examples" / "a02_n_four_bar.yaml", Path(tmp))
        runs = ladder(solver, args.t_end, "sparse")
        if args.dense:
            dense = CompiledSolver(solver.plan, solver.module, linear_solver="dense")
            runs += ladder(dense, args.t_end, "dense")
    text = report(runs, args.t_end, solver.plan)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"a02_convergence_{args.t_end:g}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
