"""What a `simulate` call costs before its first step: a 1-step run after `load`, the
first call (the set-up made) and the next ones (the set-up kept, fccgen.runtime.
setup_reuse), against the cost of one step, on the A02 chain of N four-bars.

    python benchmarks/setup_cost.py                    # N = 10 40 160 320
    python benchmarks/setup_cost.py --sizes 160 --repeats 20

For each N the model (examples/make_n_four_bar.py) is built once; then, in one
process: the first 1-step call's CPU seconds and its info["setup"]; the median CPU of
REPEATS further 1-step calls; one step's CPU, the median over REPEATS of (a 201-step
run - a 1-step run) / 200. Columns: the first call, the next calls, both in steps'
worth, and the first call's phases (rank decision, the sparse path's off-constraint
test, initial state: CPU seconds, and how the off-constraint test decided).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DT = 1e-3
REPEATS = 10


def generator():
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        "make_n_four_bar", ROOT / "examples" / "make_n_four_bar.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cpu(call) -> tuple[float, object]:
    start = time.process_time()
    out = call()
    return time.process_time() - start, out


def measure(solver, repeats: int) -> dict:
    def run(steps):
        return solver.simulate(t_end=steps * DT, dt=DT, reactions=False)
    first, result = cpu(lambda: run(1))
    setup = result.info["setup"]
    again = [cpu(lambda: run(1))[0] for _ in range(repeats)]
    step = [(cpu(lambda: run(201))[0] - cpu(lambda: run(1))[0]) / 200
            for _ in range(repeats)]
    return dict(first=first, again=statistics.median(again),
                step=max(statistics.median(step), 1e-9), setup=setup)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 40, 160, 320])
    parser.add_argument("--repeats", type=int, default=REPEATS)
    args = parser.parse_args(argv)
    import fccgen
    make = generator()
    print(f"{'N':>4} {'n_q':>5} {'step us':>8} {'1st call ms':>11} {'next ms':>8} "
          f"{'1st/step':>9} {'next/step':>9} {'rank ms':>8} {'off ms':>7} {'initial ms':>10}"
          f"  off-constraint test")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            path = Path(tmp) / f"chain_{n}.yaml"
            path.write_text(make.model_text(n), encoding="utf-8")
            solver = fccgen.load(path, Path(tmp) / "generated")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = measure(solver, args.repeats)
            s = m["setup"]
            off = s.get("off_constraint_test", {})
            print(f"{n:>4} {solver.n_q:>5} {1e6 * m['step']:>8.1f} {1e3 * m['first']:>11.1f} "
                  f"{1e3 * m['again']:>8.2f} {m['first'] / m['step']:>9.0f} "
                  f"{m['again'] / m['step']:>9.1f} "
                  f"{1e3 * s['rank_decision']['seconds']:>8.1f} "
                  f"{1e3 * off.get('seconds', 0.0):>7.1f} "
                  f"{1e3 * s['initial_state']['seconds']:>10.1f}  {off.get('method', '-')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
