"""The cost of a run with n_p sensitivities against the same run without them, on the
unlatched scissor boom of 12 units (examples/make_scissor_boom.py, latch=False: the
latch is an event, and runs with events do not carry sensitivities yet).

    python benchmarks/sensitivity_cost.py [--units 12] [--t-end 0.5] [--repeats 5]
    python benchmarks/sensitivity_cost.py --method dopri5 [--sensitivity-error]

The parameters are the torsion springs' stiffnesses, then the bars' masses, n_p = 1, 5
and 20. For each n_p: the median over the repeats of the run's own time (the
integration, result.info["wall_time"]; warm: the parameter-derivative module is built
before timing), its ratio to the plain run's, the target 1 + 0.5 n_p (issue 25), and
the whole call's time (the set-up of the parameters' directions and the columns'
chain rule included). The ratio is taken against the plain run on the model's own path
(linear_solver "auto": sparse at this size), which the run with sensitivities takes
too where it can (rk4: engine/fcc_sens_sparse.h; dopri5 takes the dense path); the
same on the dense path is printed for comparison (--dense). With --method dopri5
(rtol 1e-6, atol 1e-9) the runs take the same steps with and without sensitivities,
unless --sensitivity-error puts them into the error control (then the steps taken
are printed too). Single-threaded BLAS.
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples"))


def main() -> None:
    import fccgen
    import make_scissor_boom

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=12)
    ap.add_argument("--t-end", type=float, default=0.5)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--dense", action="store_true",
                    help="also the runs on the dense path and their ratios")
    ap.add_argument("--method", choices=("rk4", "dopri5"), default="rk4")
    ap.add_argument("--sensitivity-error", action="store_true",
                    help="dopri5: the sensitivities in the error control")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="sens_cost_"))
    model = work / "boom.yaml"
    model.write_text(make_scissor_boom.model_text(args.units, latch=False))
    dense = fccgen.load(model, work / "generated", linear_solver="dense")
    solver = fccgen.load(model, work / "generated")
    springs = [f"loads[{k}].stiffness" for k, ld in enumerate(solver.plan.model.loads)
               if getattr(ld, "stiffness", None) is not None]
    masses = [f"bodies.{name}.mass" for name, _ in solver.plan.bodies]
    keys = (springs + masses)[:20]
    run = dict(t_end=args.t_end, method=args.method, output_dt=0.01, reactions=False,
               **(dict(dt=1e-3) if args.method == "rk4" else dict(rtol=1e-6, atol=1e-9)))
    setting = "dt 1e-3" if args.method == "rk4" else "rtol 1e-6"
    control = dict(sensitivity_error=True) if args.sensitivity_error else {}
    solver.simulate(**run, sensitivities=keys[:1])            # builds the d/dp module
    path = solver.simulate(**run, sensitivities=keys[:1]).info["sensitivity_path"]

    def timed(sens, which=solver):
        runs, whole = [], []
        for _ in range(args.repeats):
            start = time.perf_counter()
            result = which.simulate(**run, sensitivities=sens, **(control if sens else {}))
            whole.append(time.perf_counter() - start)
            runs.append(result.info["wall_time"])
        return statistics.median(runs), statistics.median(whole), result.info["steps"]

    plain, _, steps = timed(None)
    print(f"scissor boom, {args.units} units ({solver.plan.n_q} coordinates), "
          f"{args.method} {setting} to t = {args.t_end}: plain run {plain * 1e3:.1f} ms "
          f"({steps} steps) on the model's own path "
          f"({'sparse' if solver.sparse else 'dense'}); sensitivities on the {path} path")
    table(timed, keys, plain)
    if args.dense:
        plain_dense, _, _ = timed(None, dense)
        print(f"dense path: plain run {plain_dense * 1e3:.1f} ms")
        table(lambda sens: timed(sens, dense), keys, plain_dense)


def table(timed, keys, plain) -> None:
    print("| n_p | run (ms) | ratio | target 1 + 0.5 n_p | whole call (ms) | steps |")
    print("| --- | --- | --- | --- | --- | --- |")
    for n_p in sorted({min(n, len(keys)) for n in (1, 5, 20)}):   # the model's keys
        t_run, t_whole, steps = timed(keys[:n_p])
        print(f"| {n_p} | {t_run * 1e3:.1f} | {t_run / plain:.2f} | {1 + 0.5 * n_p:.1f} | "
              f"{t_whole * 1e3:.1f} | {steps} |")


if __name__ == "__main__":
    main()
