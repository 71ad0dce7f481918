"""What the guards of every run cost: turn counting of springs' angles and the work of
the forces without potential (docs/reliability.md, "Energy"; docs/elements.md,
"Angles over turns").

    python benchmarks/run_guards.py [--reps R]

CPU per RK4 step (dt 1e-3, projection on, from the consistent initial state), timed
as benchmarks/peers/timing.py times (warm, interleaved, medians; the run's set-up
removed), of a run with the guard and of the same solver with it taken out, and
their ratio:

* turn counting (the event module's references re-based after every step and copied
  into the springs' kernels) on the scissor boom (springs and a latch), a 6-bay
  scissor mast (18 springs, no events) and a bar on a spring;
* the work tracked at every stage on the deployable structure (constant torques), the
  driven four-bar (the constraint forces' power) and the panel latch.

Single-threaded BLAS, set here before NumPy loads.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))

import fccgen  # noqa: E402
import fccgen.runtime.solver as runtime_solver  # noqa: E402
from timing import time_interleaved  # noqa: E402

DT = 1e-3
BAR = """
name: spring_bar
bodies:
  bar: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-3, 0.0833333333, 0.0833333333]}
joints:
  - {name: H, type: revolute, bodies: [ground, bar], at: [0, 0, 0], axis: [0, 0, 1]}
loads:
  - {type: torsion_spring, joint: H, stiffness: 2.0, angle: 3.0}
initial:
  joints: {H: {rate: -4.0}}
"""


class Run:
    """advance(n): an RK4 run of n steps from the consistent initial state, with the
    guard (on) or without it."""

    def __init__(self, solver, guard: str, on: bool):
        self.solver, self.guard, self.on = solver, guard, on
        init = solver.initial_state()
        self.q0, self.v0 = init.q, init.v

    def advance(self, n: int) -> None:
        s, kept_set, kept_tracker = self.solver, None, None
        if not self.on and self.guard == "turns":
            kept_set, s._event_set = s._event_set, (lambda tol, rest: None)
        if not self.on and self.guard == "work":
            kept_tracker = runtime_solver.work_tracker
            runtime_solver.work_tracker = lambda *args: (None, "off")
        try:
            s.simulate(t_end=n * DT, dt=DT, output_dt=n * DT, q0=self.q0, v0=self.v0,
                       reactions=False)
        finally:
            if kept_set is not None:
                s._event_set = kept_set
            if kept_tracker is not None:
                runtime_solver.work_tracker = kept_tracker


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--reps", type=int, default=15)
    args = parser.parse_args(argv)
    import warnings
    warnings.simplefilter("ignore")                  # the mast run warns of its rank
    with tempfile.TemporaryDirectory() as tmp:
        build = Path(tmp) / "generated"
        mast = Path(tmp) / "mast6.yaml"
        sys.path.insert(0, str(ROOT / "examples"))
        from make_scissor_mast import model_text
        mast.write_text(model_text(6))
        bar = Path(tmp) / "spring_bar.yaml"
        bar.write_text(BAR)
        cases = [("turns", ROOT / "examples" / "scissor_boom.yaml"), ("turns", mast),
                 ("turns", bar), ("work", ROOT / "examples" / "deployable.yaml"),
                 ("work", ROOT / "examples" / "four_bar_driven.yaml"),
                 ("work", ROOT / "examples" / "panel_latch.yaml")]
        print(f"{'guard':6} {'model':16} {'n_q':>4} {'with (us)':>10} {'without':>10} "
              f"{'ratio':>6}")
        for guard, path in cases:
            solver = fccgen.load(path, build)
            t = time_interleaved({"with": Run(solver, guard, True),
                                  "without": Run(solver, guard, False)}, args.reps)
            w, wo = t["with"].per_step, t["without"].per_step
            print(f"{guard:6} {solver.plan.model.name:16} {solver.n_q:4d} "
                  f"{w * 1e6:10.2f} {wo * 1e6:10.2f} {w / wo:6.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
