"""Flexible members' cost (docs/flexible.md, "Cost"): a step of a 10-element cable
against a step of a rigid 10-link chain with the same method, and the generation time
against the number of elements.

    python benchmarks/cables.py [--elements 10] [--methods rk4 ali3p] [--cpu-time]

Step cost: a member of 1 m pinned at a fixed point and hanging under gravity, of
``--elements`` elements, against a chain of as many rigid links of the same length and
mass, joined by spherical joints (shared points) and pinned at the same point, each
link a typical body with its own unit vector. Both start from rest at 30 degrees
from the vertical; each method runs at the same step dt = 1e-4 (within RK4's stable
step for the member: ``fccgen check`` says 2.2e-4). The seconds per step are those of
warm runs of K and 2K steps, K doubled until the K extra steps take 0.2 s, the
difference of the fastest of 5 runs of each length over K (the run's set-up left
out); the ratio cable / chain is printed per method. Target: at most 2.

Generation time: the member with 4, 16 and 64 elements, each generated and compiled
from scratch (``force=True``) into a scratch folder: derive, print and compile times.
All elements share one element class, so the times do not grow with the number of
elements.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import fccgen  # noqa: E402
from fccgen.build import build_module  # noqa: E402

DT = 1e-4
LENGTH, MASS_PER_LENGTH = 1.0, 1.0
ANGLE = math.radians(30.0)
CLOCK = time.perf_counter


def direction() -> tuple[float, float, float]:
    return (math.sin(ANGLE), -math.cos(ANGLE), 0.0)


def cable_text(n: int) -> str:
    d = direction()
    tip = [LENGTH * x for x in d]
    return f"""name: bench_cable
gravity: [0, -9.81, 0]
points:
  O: {{at: [0, 0, 0], fixed: true}}
cables:
  rope:
    from: O
    to: {tip}
    elements: {n}
    EA: 1.0e+4
    EI: 1.0
    mass_per_length: {MASS_PER_LENGTH}
"""


def chain_text(n: int) -> str:
    """n rigid links O-P1-...-Pn, each with its unit vector u_k (perpendicular to the
    chain, out of the plane), mass and the inertia of a slender rod about its centre (a tenth of it
    about the link: a sleeve, not a line)."""
    d, h = direction(), LENGTH / n
    m = MASS_PER_LENGTH * h
    inertia = m * h * h / 12.0
    points = ["  O: {at: [0, 0, 0], fixed: true}"]
    points += [f"  P{k}: [{k * h * d[0]!r}, {k * h * d[1]!r}, 0.0]" for k in range(1, n + 1)]
    vectors = [f"  u{k}: [0, 0, 1]" for k in range(1, n + 1)]
    bodies = [f"  link{k}: {{points: [{'O' if k == 1 else f'P{k - 1}'}, P{k}], vector: u{k}, "
              f"mass: {m!r}, center: [{h / 2!r}, 0, 0], "
              f"inertia: [{0.1 * inertia!r}, {inertia!r}, {inertia!r}]}}"
              for k in range(1, n + 1)]
    return "\n".join(["name: bench_chain", "gravity: [0, -9.81, 0]", "points:", *points,
                      "vectors:", *vectors, "bodies:", *bodies]) + "\n"


# Method options of both runs: ali3p's penalty scaled to the step as its docstring
# says ((dt^2/4) penalty = 250, the default's at dt = 1e-3): with the default 1e9 at
# dt = 1e-4 a multiplier update shrinks g only 2.5-fold and the chain's steps stall.
OPTIONS = {"ali3p": {"penalty": 1e11}}


def step_time(solver, method: str, target: float = 0.2, repeats: int = 5) -> float:
    """Seconds per step of warm runs (module docstring)."""
    init = solver.initial_state()

    def run(k):
        t0 = CLOCK()
        solver.simulate(t_end=k * DT, dt=DT, method=method, q0=init.q, v0=init.v,
                        output_dt=k * DT, **OPTIONS.get(method, {}))
        return CLOCK() - t0
    k = 8
    while run(2 * k) - run(k) < target and k < 1 << 16:
        k *= 2
    shorter = min(run(k) for _ in range(repeats))
    longer = min(run(2 * k) for _ in range(repeats))
    return (longer - shorter) / k


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--elements", type=int, default=10)
    parser.add_argument("--methods", nargs="+", default=["rk4", "ali3p"])
    parser.add_argument("--generation", type=int, nargs="+", default=[4, 16, 64])
    parser.add_argument("--cpu-time", action="store_true",
                        help="time the process's CPU time, not wall time")
    args = parser.parse_args(argv)
    global CLOCK
    CLOCK = time.process_time if args.cpu_time else time.perf_counter
    warnings.simplefilter("ignore")
    n = args.elements
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "cable.yaml").write_text(cable_text(n))
        (tmp / "chain.yaml").write_text(chain_text(n))
        cable = fccgen.load(tmp / "cable.yaml", tmp / "generated")
        chain = fccgen.load(tmp / "chain.yaml", tmp / "generated")
        print(f"cable: {n} elements, n_q {cable.n_q}, n_g {cable.n_g}; "
              f"chain: {n} links, n_q {chain.n_q}, n_g {chain.n_g}; dt {DT:g}")
        print("\n| method | cable (us/step) | chain (us/step) | ratio |\n| --- | --- | --- | --- |")
        for method in args.methods:
            tc, tr = step_time(cable, method), step_time(chain, method)
            print(f"| {method} | {1e6 * tc:.1f} | {1e6 * tr:.1f} | {tc / tr:.2f} |",
                  flush=True)
        print("\n| elements | classes | derive (s) | print (s) | compile (s) |\n"
              "| --- | --- | --- | --- | --- |")
        for m in args.generation:
            path = tmp / f"cable_{m}.yaml"
            path.write_text(cable_text(m))
            plan = fccgen.api.plan_model(path)
            built = build_module(plan, tmp / "gen_time", force=True)
            t = built.timings
            print(f"| {m} | {len(plan.classes)} | {t['derive']:.2f} | {t['print']:.2f} | "
                  f"{t['compile']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
