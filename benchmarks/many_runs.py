"""Many runs of one model at once: ``solver.simulate_many`` on 1 and 2 threads against
a loop of single runs, and against MuJoCo's ``rollout`` on 2 threads (when the
``mujoco`` package is installed; it is a test-time reference, never a dependency).

    python benchmarks/many_runs.py                      # 200 variants, 3 repetitions
    python benchmarks/many_runs.py --runs 50 --repeats 5

The workload: RUNS variants of the A02 chain of N = 10 four-bars (examples/
make_n_four_bar.py; MuJoCo's model from benchmarks/peers/mujoco_models.py), the mass
of the first rocker set to MASS x (0.5 + k / RUNS), each run 1 s of RK4 at dt = 1e-3
from the model's initial state. fccgen records the start and the end of each run
(output_dt = t_end) without reactions; MuJoCo's rollout writes the state after every
step (its interface has no other way). The fccgen timings include each run's set-up
(its numbers' solver, consistent initial state and rank decision), MuJoCo's the
copies of the model per variant are made before the clock starts.

Each of the ways runs REPEATS times, in turn, in one process; the figures are the
median wall seconds and their ratios (the machine's other load moves them all alike),
and the median CPU seconds of the process (all its threads).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))

N = 10
DT = 1e-3
T_END = 1.0
BODY = "rocker0"


def fccgen_ways(n_runs: int):
    """{name: callable} of the fccgen ways, and the parameter sets."""
    import fccgen
    from systems import FOUR_BAR, model_file
    path = model_file("a02", N, ROOT / "generated" / "peers")
    solver = fccgen.load(path, str(ROOT / "generated"))
    sets = [{f"bodies.{BODY}.mass": FOUR_BAR.MASS * (0.5 + k / n_runs)}
            for k in range(n_runs)]
    options = dict(t_end=T_END, dt=DT, method="rk4", output_dt=T_END, reactions=False)

    def loop():
        return [solver.with_parameters(p).simulate(**options) for p in sets]

    def many(threads):
        runs = solver.simulate_many(sets, threads=threads, **options)
        failed = [r for r in runs if not r.ok]
        if failed:
            raise SystemExit(f"{len(failed)} runs failed, e.g. {failed[0]}")
        return runs
    return {"loop of single runs": loop,
            "simulate_many, 1 thread": lambda: many(1),
            "simulate_many, 2 threads": lambda: many(2)}


def mujoco_way(n_runs: int):
    """MuJoCo's rollout of the same variants on 2 threads, or None without mujoco."""
    try:
        import mujoco
        from mujoco import rollout
    except ImportError:
        return None
    import numpy as np
    from mujoco_models import MujocoModel, a02_mjcf
    from systems import FOUR_BAR
    base = MujocoModel("a02", N, DT)
    models = []
    for k in range(n_runs):
        model = mujoco.MjModel.from_xml_string(a02_mjcf(N, DT))
        model.body(BODY).mass[0] = FOUR_BAR.MASS * (0.5 + k / n_runs)
        models.append(model)
    datas = [mujoco.MjData(models[0]) for _ in range(2)]
    base.reset()                                  # the initial speeds of the chain
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(base.model, spec))
    mujoco.mj_getState(base.model, base.data, initial, spec)
    n_steps = round(T_END / DT)

    def run():
        return rollout.rollout(models, datas, initial[None, :], nstep=n_steps)
    return run


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    ways = fccgen_ways(args.runs)
    reference = mujoco_way(args.runs)
    if reference is not None:
        ways["MuJoCo rollout, 2 threads"] = reference
    for call in ways.values():                  # warm: builds, imports, first calls
        call()
    seconds = {name: [] for name in ways}
    cpu = {name: [] for name in ways}
    for _ in range(args.repeats):
        for name, call in ways.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            call()
            seconds[name].append(time.perf_counter() - start)
            cpu[name].append(time.process_time() - start_cpu)
    median = {name: statistics.median(s) for name, s in seconds.items()}
    median_cpu = {name: statistics.median(s) for name, s in cpu.items()}
    print(f"{args.runs} variants of the A02 chain (N = {N}), {T_END:g} s of RK4 at dt = "
          f"{DT:g}; median wall seconds of {args.repeats} repetitions")
    base = median["simulate_many, 1 thread"]
    mj = median.get("MuJoCo rollout, 2 threads")
    print(f"{'way':<28} {'seconds':>9} {'per run':>9} {'vs 1 thread':>12} {'vs MuJoCo':>10}"
          f" {'CPU s':>8}")
    for name, value in median.items():
        vs_mj = f"{value / mj:10.2f}" if mj else f"{'-':>10}"
        print(f"{name:<28} {value:9.3f} {1e3 * value / args.runs:7.2f}ms "
              f"{base / value:11.2f}x {vs_mj} {median_cpu[name]:8.3f}")
    if mj is None:
        print("MuJoCo is not installed: its rollout was not timed (pip install mujoco)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
