"""What the joint reactions add to a run whose latches lock (docs/joints.md,
"Reactions": after a lock they hold its rows, fccgen.runs.held_rows): CPU of
`simulate()` with and without reactions on the examples with locks and rests, in one
process, warm, the median of REPEATS runs each, taking turns.

    python benchmarks/held_reactions_cost.py
    python benchmarks/held_reactions_cost.py --models solar_array --repeats 9

Columns: records, those where a lock (or a rest) holds, CPU s of the run without
reactions, of the reactions alone (with minus without), and their ratio.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings

import fccgen
from fccgen.errors import RunWarning
from fccgen.runs.held_rows import held_segments

MODELS = ("panel_latch", "solar_array", "pendulum_limit")
REPEATS = 5


def cpu(call) -> float:
    start = time.process_time()
    call()
    return time.process_time() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS))
    parser.add_argument("--repeats", type=int, default=REPEATS)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore", RunWarning)
    print(f"{'model':>16} {'records':>7} {'held':>6} {'run s':>7} {'reactions s':>11} "
          f"{'ratio':>6}")
    for name in args.models:
        solver = fccgen.load(fccgen.example_path(name))
        result = solver.simulate()
        held = sum(s.stop - s.start for s in
                   held_segments(solver.plan.model, result.t, result.events) if s.keys)
        plain, whole = [], []
        for _ in range(args.repeats):
            plain.append(cpu(lambda: solver.simulate(reactions=False)))
            whole.append(cpu(lambda: solver.simulate()))
        run = statistics.median(plain)
        extra = statistics.median(whole) - run
        print(f"{name:>16} {len(result.t):>7} {held:>6} {run:>7.3f} {extra:>11.3f} "
              f"{extra / run:>6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
