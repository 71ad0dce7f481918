"""Time every stage of fccgen on a large deployable structure, against its number of bodies.

    python benchmarks/large_models.py [--bodies 100 250 500 1000] [--structure mast|boom]
                                      [--profile BODIES]

The structure is the triangular scissor mast of examples/make_scissor_mast.py (6 bars
per bay: N bodies are round(N / 6) bays) or, with --structure boom, the planar scissor
boom of examples/make_scissor_boom.py (2 bars per unit). For each size, in one process
and a fresh build directory (a cold cache), the stages are timed in CPU seconds:

* load: reading and validating the model file (fccgen.model.load_model);
* lower: the mechanism level onto points, vectors and constraints (fccgen.mechanism);
* plan: element classes and instances (fccgen.plan);
* generate: derivation, printing and rendering (CPU of this process during the build);
* compile: Cython and the C compiler (CPU of the child processes during the build); the
  build's wall time is printed too (on a shared machine it counts the others' work);
* solver: binding the kernels and the sparse path's load-time analysis (ordering,
  pattern, scatter maps: fccgen.runtime.sparsity);
* assemble: the initial positions onto the constraints (Newton) and the initial speeds;
* rank: the initial rank decision of the run (fccgen.rank) inside that initial state;
* step: CPU time per RK4 step with projection at dt = 1e-3, warm: runs of K and 2K
  steps, the difference over K (the runs' set-up excluded), the fastest of 3; with the
  constrained solves per step whose refinement did not converge ("unconverged": the
  run's sparse_unconverged_solves over its steps), or "failed" if the run stops.

Prints the table, ms per step per coordinate, and the exponent p of time ~ N^p of each
stage (least squares of log time on log N). --profile BODIES runs cProfile over the
stages after generation at that size and prints the 25 costliest functions.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import cProfile  # noqa: E402
import importlib.util  # noqa: E402
import pstats  # noqa: E402
import resource  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from fccgen.build import build_module, load_module  # noqa: E402
from fccgen.errors import SimulationError  # noqa: E402
from fccgen.mechanism import lower  # noqa: E402
from fccgen.model import load_model  # noqa: E402
from fccgen.plan import make_plan  # noqa: E402
from fccgen.runtime import CompiledSolver  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DT = 1e-3
STAGES = ("load", "lower", "plan", "generate", "compile", "solver", "assemble", "rank")


BARS_PER_UNIT = {"mast": 6, "boom": 2}


def model_text(structure: str, units: int) -> str:
    """The model of the scissor mast (bays) or the scissor boom (units)."""
    name = {"mast": "make_scissor_mast", "boom": "make_scissor_boom"}[structure]
    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if structure == "boom":                 # the boom without its latch event (its cost
        return module.model_text(units, latch=False)   # is benchmarks/sparse_events.py's)
    return module.model_text(units)


def timed(times: dict, stage: str, call):
    """call() with its CPU seconds added to times[stage]."""
    t0 = time.process_time()
    out = call()
    times[stage] = times.get(stage, 0.0) + time.process_time() - t0
    return out


def step_time(solver, q0, v0, repeats: int = 3, target: float = 0.3):
    """(CPU seconds per warm RK4 step, unconverged solves per step): runs of K and 2K
    steps, K doubled until the K extra steps take about ``target`` s, the fastest
    difference over K."""
    unconverged = []

    def run(k):
        t0 = time.process_time()
        result = solver.simulate(t_end=k * DT, dt=DT, method="rk4", q0=q0, v0=v0,
                                 output_dt=k * DT, reactions=False)
        unconverged.append(result.info.get("sparse_unconverged_solves", 0) / k)
        return time.process_time() - t0
    k = 2
    while run(2 * k) - run(k) < target and k < 1 << 14:
        k *= 2
    return min(run(2 * k) - run(k) for _ in range(repeats)) / k, max(unconverged)


def after_generation(times: dict, plan, built):
    """Solver, initial assembly, rank decision and the step (times in place)."""
    module = load_module(built)
    solver = timed(times, "solver", lambda: CompiledSolver(plan, module))
    decide, found = solver.decide_rank, []

    def timed_decision(q):                      # the decision inside initial_state
        found.append(timed(times, "rank", lambda: decide(q)))
        return found[-1]
    solver.decide_rank = timed_decision
    init = timed(times, "assemble", solver.initial_state)
    del solver.decide_rank
    times["assemble"] -= times["rank"]          # the rank decision is counted apart
    rank = found[-1]
    try:
        times["step"], times["unconverged"] = step_time(solver, init.q, init.v)
    except SimulationError as exc:              # reported in the table, not timed
        print(f"the run failed: {exc}", flush=True)
        times["step"], times["unconverged"] = float("nan"), float("nan")
    return solver, rank


def measure(structure: str, bodies: int, tmp: Path, profile: bool = False) -> dict:
    """The stage times (s) of the structure of about ``bodies`` bars, and its sizes."""
    bays = max(1, round(bodies / BARS_PER_UNIT[structure]))
    path = tmp / f"{structure}_{bays}.yaml"
    path.write_text(model_text(structure, bays))
    times: dict = {}
    model = timed(times, "load", lambda: load_model(path))
    lowered = timed(times, "lower", lambda: lower(model))
    plan = timed(times, "plan", lambda: make_plan(lowered))
    wall, children = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    built = timed(times, "generate",
                  lambda: build_module(plan, tmp / f"generated_{bays}", force=True))
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    times["compile"] = (after.ru_utime + after.ru_stime
                        - children.ru_utime - children.ru_stime)
    times["build wall"] = time.perf_counter() - wall
    if profile:
        prof = cProfile.Profile()
        prof.enable()
    solver, rank = after_generation(times, plan, built)
    if profile:
        prof.disable()
        pstats.Stats(prof).sort_stats("cumulative").print_stats(25)
    return dict(bodies=BARS_PER_UNIT[structure] * bays, n_q=plan.n_q, n_g=plan.n_g,
                dof=rank.dof, path="sparse" if solver.sparse else "dense", **times)


def exponent(ns, times) -> float:
    """p of time ~ N^p, least squares in log-log."""
    return float(np.polyfit(np.log(ns), np.log(times), 1)[0])


def table(rows) -> str:
    head = ["bodies", "n_q", "n_g", "dof", *STAGES, "gen+compile (wall)", "step",
            "step/n_q", "unconverged"]
    out = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for r in rows:
        cells = [str(r["bodies"]), str(r["n_q"]), str(r["n_g"]), str(r["dof"])]
        cells += [f"{r[s]:.3g} s" for s in STAGES]
        failed = np.isnan(r["step"])
        cells += [f"{r['generate'] + r['compile']:.3g} s ({r['build wall']:.3g} s)",
                  "failed" if failed else f"{1e3 * r['step']:.3g} ms",
                  "" if failed else f"{1e6 * r['step'] / r['n_q']:.3g} us",
                  "" if failed else f"{r['unconverged']:.2g}"]
        out.append("| " + " | ".join(cells) + " |")
    if len(rows) > 1:
        ns = [r["bodies"] for r in rows]
        fits = [f"{exponent(ns, [max(r[s], 1e-6) for r in rows]):.2f}" for s in STAGES]
        steps = [(n, r["step"]) for n, r in zip(ns, rows) if not np.isnan(r["step"])]
        step_fit = f"{exponent(*zip(*steps)):.2f}" if len(steps) > 1 else ""
        out.append("| exponent | | | | " + " | ".join(fits) + f" | | {step_fit} | | |")
    return "\n".join(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, nargs="+", default=[100, 250, 500, 1000])
    parser.add_argument("--structure", choices=sorted(BARS_PER_UNIT), default="mast")
    parser.add_argument("--profile", type=int, default=None,
                        help="profile the stages after generation at this size only")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        sizes = [args.profile] if args.profile else args.bodies
        for n in sizes:
            row = measure(args.structure, n, Path(tmp), profile=bool(args.profile))
            rows.append(row)
            print(" ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                           for k, v in row.items()), flush=True)
    print()
    print(table(rows))


if __name__ == "__main__":
    main()
