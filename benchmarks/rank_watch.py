"""What the sparse path's rank-growth watch costs a step, with and without it, on the
pendulum on a cart with redundant rows.

    python benchmarks/rank_watch.py                 # n = 10
    python benchmarks/rank_watch.py --sizes 5 10 15 --repeats 9

The model: examples/make_pendulum_on_cart.py's n-link pendulum on a cart (n + 1
degrees of freedom) with three plane equations more, each redundant everywhere (D, P1
and P2 on the plane z = 0, which the "perpendicular to z" rows of the cart and rods
already keep them on), as a point-mass model written with one plane equation per
particle has. The watch (engine/fcc_sparse_watch.c) tracks the n + 1 directions of the
null space at every velocity projection; since the rank off the constraints is no
higher than the decided one, the solver leaves it off (CompiledSolver._rank_may_grow).
"forced on" runs the same solver with that decision overridden, as every such model
ran before. Figures: median CPU microseconds per RK4 step (dt = 1e-3, 1 s, recording
only the end) of REPEATS runs, both ways in turn in one process.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))

EXTRA = """  - {type: point_on_plane, point: D, origin: O, normal: z}
  - {type: point_on_plane, point: P1, origin: O, normal: z}
  - {type: point_on_plane, point: P2, origin: O, normal: z}
"""


def model_file(n: int, directory: Path) -> Path:
    from systems import CART
    text = CART.model_text(n).replace(f"name: {CART.model_name(n)}",
                                      f"name: {CART.model_name(n)}_redundant")
    marker = "  - {type: point_on_plane, point: D, origin: O, normal: y}\n"
    if marker not in text:
        raise SystemExit("the cart's model text has changed: update benchmarks/rank_watch.py")
    path = directory / f"{CART.model_name(n)}_redundant.yaml"
    text = text.replace(marker, marker + EXTRA)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


def step_cpu(solver, init, repeats: int) -> float:
    def one():
        start = time.process_time()
        solver.simulate(t_end=1.0, dt=1e-3, output_dt=1.0, q0=init.q, v0=init.v,
                        reactions=False)
        return time.process_time() - start
    return statistics.median(one() for _ in range(repeats)) / 1000


def main(argv=None) -> int:
    import fccgen
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    directory = ROOT / "generated" / "peers"
    directory.mkdir(parents=True, exist_ok=True)
    print(f"{'n':>4} {'DOF':>4} {'redundant':>9} {'watch off':>10} {'forced on':>10} "
          f"{'ratio':>6}   (CPU us per RK4 step)")
    for n in args.sizes:
        solver = fccgen.load(model_file(n, directory), str(ROOT / "generated"),
                             linear_solver="sparse")
        init = solver.initial_state()
        decision = solver.decide_rank(init.q)
        forced = fccgen.load(model_file(n, directory), str(ROOT / "generated"),
                             linear_solver="sparse")
        forced._rank_may_grow = lambda decision: True    # as before: always on
        forced.decide_rank(init.q)
        assert solver._engine.watched_directions == 0
        assert forced._engine.watched_directions == solver.n_q - decision.rank
        off, on = [], []
        for _ in range(3):
            off.append(step_cpu(solver, init, args.repeats))
            on.append(step_cpu(forced, init, args.repeats))
        off, on = statistics.median(off), statistics.median(on)
        print(f"{n:>4} {solver.n_q - decision.rank:>4} {solver.n_g - decision.rank:>9} "
              f"{1e6 * off:>10.2f} {1e6 * on:>10.2f} {off / on:>6.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
