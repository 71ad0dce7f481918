"""The cost of a run with n_p sensitivities against the same run without them, on the
unlatched scissor boom of 12 units (examples/make_scissor_boom.py, latch=False: the
latch is an event, and runs with events do not carry sensitivities yet).

    python benchmarks/sensitivity_cost.py [--units 12] [--t-end 0.5] [--repeats 5]
    python benchmarks/sensitivity_cost.py --method dopri5 [--sensitivity-error]
    python benchmarks/sensitivity_cost.py --units 7 --instructions [--t-end 0.1]

The parameters are the torsion springs' stiffnesses, then the bars' masses, n_p = 1, 5
and 20 (capped at the model's keys: n units have 3 n, n springs' and 2 n bars'; 7 units
and more give all 20). For each n_p: the median over the repeats of the run's own time
(the integration, result.info["wall_time"]; warm: the parameter-derivative module is built
before timing), its ratio to the plain run's, the target 1 + 0.5 n_p (issue 25), and
the whole call's time (the set-up of the parameters' directions and the columns'
chain rule included). The ratio is taken against the plain run on the model's own path
(linear_solver "auto": sparse at this size), which the run with sensitivities takes
too where it can (rk4: engine/fcc_sens_sparse.h; dopri5 takes the dense path); the
same on the dense path is printed for comparison (--dense). With --method dopri5
(rtol 1e-6, atol 1e-9) the runs take the same steps with and without sensitivities,
unless --sensitivity-error puts them into the error control (then the steps taken
are printed too). Single-threaded BLAS.

With --instructions (needs valgrind): instead of times, the instructions the engine's
steps take (callgrind, collected inside fcc_rk4_advance only: deterministic, not
moved by the machine's load), rk4 at 1 ms, each run in a child process (t_end 0.1
unless --t-end is given: 100 steps), and the part of them in the generated tangent
kernels (the functions named *_tangent*, their own instructions).
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
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
    ap.add_argument("--t-end", type=float, default=None,
                    help="end of the run (default 0.5 s; with --instructions 0.1 s)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--dense", action="store_true",
                    help="also the runs on the dense path and their ratios")
    ap.add_argument("--method", choices=("rk4", "dopri5"), default="rk4")
    ap.add_argument("--sensitivity-error", action="store_true",
                    help="dopri5: the sensitivities in the error control")
    ap.add_argument("--instructions", action="store_true",
                    help="count the engine's instructions (valgrind) instead of timing")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    if args.t_end is None:
        args.t_end = 0.1 if args.instructions else 0.5
    work = Path(tempfile.mkdtemp(prefix="sens_cost_"))
    model = work / "boom.yaml"
    model.write_text(make_scissor_boom.model_text(args.units, latch=False))
    dense = fccgen.load(model, work / "generated", linear_solver="dense")
    solver = fccgen.load(model, work / "generated")
    keys = child_keys(solver)
    run = dict(t_end=args.t_end, method=args.method, output_dt=0.01, reactions=False,
               **(dict(dt=1e-3) if args.method == "rk4" else dict(rtol=1e-6, atol=1e-9)))
    setting = "dt 1e-3" if args.method == "rk4" else "rtol 1e-6"
    control = dict(sensitivity_error=True) if args.sensitivity_error else {}
    solver.simulate(**run, sensitivities=keys[:1])            # builds the d/dp module
    if args.instructions:
        instructions(model, work, solver, keys, args)
        return
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


def child(model: str, n_p: str, t_end: str) -> None:
    """The run callgrind counts: the built model, its first n_p keys."""
    import fccgen
    solver = fccgen.load(Path(model), Path(model).parent / "generated")
    keys = child_keys(solver)[:int(n_p)]
    solver.simulate(t_end=float(t_end), method="rk4", dt=1e-3, output_dt=0.01,
                    reactions=False, sensitivities=keys or None)


def child_keys(solver) -> list[str]:
    springs = [f"loads[{k}].stiffness" for k, ld in enumerate(solver.plan.model.loads)
               if getattr(ld, "stiffness", None) is not None]
    return (springs + [f"bodies.{name}.mass" for name, _ in solver.plan.bodies])[:20]


def counted(model: Path, n_p: int, t_end: float, out: Path) -> tuple[int, int]:
    """(instructions in fcc_rk4_advance, of them in the tangent kernels)."""
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                    "--toggle-collect=fcc_rk4_advance", sys.executable, __file__,
                    "--child", str(model), str(n_p), str(t_end)], check=True,
                   capture_output=True)
    text = subprocess.run(["callgrind_annotate", "--threshold=100", str(out)],
                          check=True, capture_output=True, text=True).stdout
    total = int(re.search(r"([\d,]+) \(100\.0%\)\s+PROGRAM TOTALS", text)
                .group(1).replace(",", ""))
    tangent = 0
    for line in text.splitlines():
        hit = re.match(r"\s*([\d,]+) \([^)]*\)\s+\S*:(\w+)", line)
        if hit and "_tangent" in hit.group(2):
            tangent += int(hit.group(1).replace(",", ""))
    return total, tangent


def instructions(model: Path, work: Path, solver, keys, args) -> None:
    if shutil.which("valgrind") is None or shutil.which("callgrind_annotate") is None:
        raise SystemExit("--instructions needs valgrind and callgrind_annotate")
    steps = round(args.t_end / 1e-3)
    plain, _ = counted(model, 0, args.t_end, work / "plain.callgrind")
    print(f"scissor boom, {args.units} units ({solver.plan.n_q} coordinates, "
          f"{len(keys)} keys used), rk4 dt 1e-3, {steps} steps: plain run "
          f"{plain / 1e6:.1f} M instructions (engine steps, "
          f"{'sparse' if solver.sparse else 'dense'} path)")
    print("| n_p | instructions (M) | ratio | target 1 + 0.5 n_p | tangent kernels |")
    print("| --- | --- | --- | --- | --- |")
    for n_p in sorted({min(n, len(keys)) for n in (1, 5, 20)}):
        total, tangent = counted(model, n_p, args.t_end, work / f"{n_p}.callgrind")
        print(f"| {n_p} | {total / 1e6:.1f} | {total / plain:.2f} | {1 + 0.5 * n_p:.1f} | "
              f"{100 * tangent / total:.0f} % |")


def table(timed, keys, plain) -> None:
    print("| n_p | run (ms) | ratio | target 1 + 0.5 n_p | whole call (ms) | steps |")
    print("| --- | --- | --- | --- | --- | --- |")
    for n_p in sorted({min(n, len(keys)) for n in (1, 5, 20)}):   # the model's keys
        t_run, t_whole, steps = timed(keys[:n_p])
        print(f"| {n_p} | {t_run * 1e3:.1f} | {t_run / plain:.2f} | {1 + 0.5 * n_p:.1f} | "
              f"{t_whole * 1e3:.1f} | {steps} |")


if __name__ == "__main__":
    main()
