"""What events cost on the sparse path (engine/fcc_events.c, fcc_event_actions.c): the
latched 12-unit scissor boom against the free one, and the solar array with and
without its two latches (docs/performance.md, "Events on the sparse path").

    python benchmarks/sparse_events.py [--reps R] [--mast N]

Two figures per pair, all on the sparse path (RK4, dt 1e-3, projection on, reactions
off), in one run with single-threaded BLAS:

* the step: CPU per step, timed as benchmarks/peers/timing.py times (warm,
  interleaved, medians of runs of k and 2k steps from the initial state, the set-up
  removed), of the model whose latches are locked from its first step (their events'
  conditions replaced by ``t >= 0.0005``: every step after the first carries the
  locked rows) against the model without events;
* the run: median CPU of the whole natural run (the boom 2 s, latched at 1.48 s; the
  array 3 s, latched at 1.25 and 2.06 s) with its events against the same run without
  them, interleaved, divided by its number of steps.

With ``--mast N`` it adds the scissor mast of N bays with a latch per bay
(latched_mast; the natural run 2 s) against the free mast
(examples/make_scissor_mast.py).

With ``--breakdown`` (needs valgrind) it counts instead, for the same step pairs,
the instructions per step of the whole step and of its parts (callgrind, inclusive,
collected inside ``fcc_rk4_advance`` only, over a run of 300 steps): deterministic
where CPU times on a loaded machine are not, and it names where the latched step's
extra cost goes.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))
sys.path.insert(0, str(ROOT / "examples"))

import fccgen  # noqa: E402
from timing import time_interleaved  # noqa: E402

DT = 1e-3


class Steps:
    """advance(n): a sparse-path RK4 run of n steps from the consistent initial state."""

    def __init__(self, solver):
        self.solver = solver
        init = solver.initial_state()
        self.q0, self.v0 = init.q, init.v

    def advance(self, n: int) -> None:
        self.solver.simulate(t_end=n * DT, dt=DT, output_dt=n * DT, q0=self.q0,
                             v0=self.v0, reactions=False, method="rk4")


def whole_runs(solvers: dict, t_end: float, reps: int) -> dict:
    """{name: median CPU per step} of whole runs to t_end, interleaved."""
    times = {name: [] for name in solvers}
    for _ in range(reps):
        for name, s in solvers.items():
            start = time.process_time()
            s.simulate(t_end=t_end, dt=DT, output_dt=0.01, reactions=False, method="rk4")
            times[name].append(time.process_time() - start)
    return {name: statistics.median(t) / round(t_end / DT) for name, t in times.items()}


def variants(text: str) -> tuple[str, str]:
    """(locked from the first step, without events) of a model text with events."""
    locked = re.sub(r'when: "[^"]*"', 'when: "t >= 0.0005"', text)
    free = text[:text.index("events:")] + text[text.index("simulate:"):]
    return locked, free


# the latched mast: a lock per bay on face AB's pivot, at this bar angle (deg): the
# springs (relaxed at make_scissor_mast.FREE) still drive the mast through it
MAST_LATCH = 60.0


def latched_mast(n: int) -> str:
    """The model text of the scissor mast of ``n`` bays with a latch per bay: face AB's
    pivot of each bay a revolute about the face's normal, locked by its own event when
    the bar angle reaches MAST_LATCH. The mast has one degree of freedom and its bays
    move alike, so every latch crosses in the same step."""
    from make_scissor_mast import FOLDED, model_text
    text = model_text(n)
    normal = re.search(r"nAB: \{along: (\[[^\]]*\])", text).group(1)
    text = re.sub(r"(name: XAB\d+), type: spherical, (bodies: [^}]*)\}",
                  rf"\1, type: revolute, \2, axis: {normal}}}", text)
    angle = 2.0 * (FOLDED - MAST_LATCH)
    events = ["events:"] + [f'  - {{name: latch{k}, when: "XAB{k}.angle >= '
                            f'{angle:g}*pi/180", do: lock, joint: XAB{k}}}'
                            for k in range(n)]
    head, tail = text[:text.index("simulate:")], text[text.index("simulate:"):]
    return head + "\n".join(events) + "\n" + tail


BREAKDOWN_STEPS = 300
# The parts of a step counted by --breakdown (inclusive instruction counts).
PARTS = ("fcc_rk4_advance", "fcc_sp_accelerations", "fcc_ev_constrain",
         "fcc_project_positions", "fcc_sp_project_velocities", "fcc_ev_correct")


def child(path: str, build: str) -> None:
    """The run that callgrind counts: BREAKDOWN_STEPS RK4 steps of a built model."""
    warnings.simplefilter("ignore")
    solver = fccgen.load(Path(path), Path(build), linear_solver="sparse")
    Steps(solver).advance(BREAKDOWN_STEPS)


def counted(path: Path, build: Path, out: Path) -> dict:
    """{part: instructions per step} of one model's run under callgrind."""
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                    "--toggle-collect=fcc_rk4_advance", sys.executable, __file__,
                    "--child", str(path), str(build)], check=True,
                   capture_output=True)
    text = subprocess.run(["callgrind_annotate", "--inclusive=yes", str(out)],
                          check=True, capture_output=True, text=True).stdout
    found = {}
    for line in text.splitlines():
        hit = re.match(r"\s*([\d,]+) \([^)]*\)\s+\S*:(\w+) ", line)
        if hit and hit.group(2) in PARTS and hit.group(2) not in found:
            found[hit.group(2)] = int(hit.group(1).replace(",", "")) / BREAKDOWN_STEPS
    return {part: found.get(part, 0.0) for part in PARTS}


def breakdown(cases, folder: Path, build: Path) -> None:
    """Print instructions per step (thousands) of each part, locked and free."""
    if shutil.which("valgrind") is None or shutil.which("callgrind_annotate") is None:
        raise SystemExit("--breakdown needs valgrind and callgrind_annotate")
    print(f"{'model':16} {'part':26} {'locked (k)':>11} {'free (k)':>9}")
    for name, text, free_text, _ in cases:
        counts = {}
        for key, body in (("locked", variants(text)[0]), ("free", free_text)):
            path = folder / f"{name.replace(' ', '_')}_{key}.yaml"
            path.write_text(body)
            fccgen.load(path, build, linear_solver="sparse")       # build outside
            counts[key] = counted(path, build, folder / f"{key}.callgrind")
        for part in PARTS:
            print(f"{name:16} {part:26} {counts['locked'][part] / 1e3:11.1f} "
                  f"{counts['free'][part] / 1e3:9.1f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--reps", type=int, default=15)
    parser.add_argument("--breakdown", action="store_true",
                        help="instructions per step of each part (valgrind)")
    parser.add_argument("--mast", type=int, metavar="N",
                        help="also the scissor mast of N bays with a latch per bay")
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    if args.child:
        child(*args.child)
        return 0
    from make_scissor_boom import model_text
    with tempfile.TemporaryDirectory() as tmp:
        build, folder = Path(tmp) / "generated", Path(tmp)
        array = (ROOT / "examples" / "solar_array.yaml").read_text()
        cases = [("scissor boom 12", model_text(12), model_text(12, latch=False), 2.0),
                 ("solar array", array, variants(array)[1], 3.0)]
        if args.mast:
            from make_scissor_mast import T_END, model_text as mast_text
            cases.append((f"mast {args.mast}", latched_mast(args.mast),
                          mast_text(args.mast), T_END))
        if args.breakdown:
            breakdown(cases, folder, build)
            return 0
        print(f"{'model':16} {'figure':6} {'latched (us)':>12} {'free (us)':>10} "
              f"{'ratio':>6}")
        for name, text, free_text, t_end in cases:
            solvers = {}
            for key, body in (("latched", text), ("locked", variants(text)[0]),
                              ("free", free_text)):
                path = folder / f"{name.replace(' ', '_')}_{key}.yaml"
                path.write_text(body)
                solvers[key] = fccgen.load(path, build, linear_solver="sparse")
            t = time_interleaved({k: Steps(solvers[k]) for k in ("locked", "free")},
                                 args.reps)
            step, free = t["locked"].per_step, t["free"].per_step
            print(f"{name:16} {'step':6} {step * 1e6:12.2f} {free * 1e6:10.2f} "
                  f"{step / free:6.3f}")
            runs = whole_runs({k: solvers[k] for k in ("latched", "free")}, t_end,
                              max(3, args.reps // 3))
            print(f"{name:16} {'run':6} {runs['latched'] * 1e6:12.2f} "
                  f"{runs['free'] * 1e6:10.2f} {runs['latched'] / runs['free']:6.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
