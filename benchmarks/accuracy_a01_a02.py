"""Work-precision of every integration method on the IFToMM benchmarks A01 and A02.

    python benchmarks/accuracy_a01_a02.py [--only a01|a02] [--out-dir docs/accuracy]

A01 (pendulum, 2000 s) and A02 (N-four-bar, N = 40, 20 s): every method of
fccgen.settings.methods over a ladder of steps or tolerances, with and without projection where
the method offers it, in the compiled version; the numeric version at the coarsest rung
only (it is slow): on A02 every method with its own integration loop (for SciPy's, the
numeric/compiled ratio is that of the right-hand side, which rk4 already shows), on A01
rk4 with projection only (one numeric run over 2000 s already takes minutes).
The error is the largest distance of the benchmark's point (P, B0) from the published
reference solution over all its output times (tests/reference/). Writes
``<out-dir>/{a01,a02}_accuracy.{csv,png,txt}`` and prints the summaries. Run with
single-threaded BLAS (set here before NumPy loads): the runtime's dense solves are small,
and several BLAS threads make them slower and the times noisy.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import fccgen  # noqa: E402
from fccgen.settings import methods as registry
from fccgen.bench.accuracy import (Ladder, Variant, default_variants,  # noqa: E402
                             published_reference, run_ladder)
from fccgen.bench.accuracy_report import AccuracyReport, read_csv, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = ROOT / "tests" / "reference"
LEVELS = (1e-1, 1e-3)      # the benchmarks' low and high precision levels (m)

# SciPy's implicit methods stop at 1e-8: at 1e-10 one run takes tens of minutes here.
IMPLICIT_SCIPY = {f"scipy-{m}": (1e-4, 1e-6, 1e-8) for m in ("Radau", "BDF", "LSODA")}

CASES = {
    "a01": dict(
        model="a01_pendulum.yaml", point="P",
        reference=("mbsbenchmark_A01_solution_data.txt", None),
        title="A01 pendulum, 2000 s",
        steps=(0.02, 0.01, 0.005, 0.0025, 0.001),
        tolerances=(1e-4, 1e-6, 1e-8, 1e-10),
        per_method={"ali3p": (0.005, 0.0025, 0.001, 0.0005),   # 2nd order: finer steps
                    **IMPLICIT_SCIPY},
        numeric=[Variant("rk4", True, "numeric")], numeric_steps=(0.05,)),
    "a02": dict(
        model="a02_n_four_bar.yaml", point="B0",
        reference=("mbsbenchmark_A02_solution_data_B0.csv", ","),
        title="A02 N-four-bar (N = 40), 20 s",
        steps=(0.05, 0.025, 0.0125, 0.01, 0.005),
        tolerances=(1e-4, 1e-6, 1e-8, 1e-10),
        # SciPy's methods step in Python: at n = 246 first-order states one RK45 run at
        # 1e-6 takes 37 s of CPU, at 1e-8 it would take minutes; DOP853 goes to 1e-8.
        per_method={"ali3p": (0.01, 0.005, 0.0025, 0.001),     # 2nd order: finer steps
                    "scipy-DOP853": (1e-4, 1e-6, 1e-8),
                    **{f"scipy-{m}": (1e-4, 1e-6)
                       for m in ("RK45", "Radau", "BDF", "LSODA")}},
        numeric=None, numeric_steps=(0.05,)),     # None: every method with its own loop
}


def reference(key: str):
    file, delimiter = CASES[key]["reference"]
    point = CASES[key]["point"]
    return published_reference(REFERENCE / file, point, [f"{point}.x", f"{point}.y"],
                               f"the benchmark's published solution "
                               f"(tests/reference/{file}), position of {point}", delimiter)


def run_case(key: str, out_dir: Path, build_dir: str, methods=None) -> AccuracyReport:
    case = CASES[key]
    path = ROOT / "examples" / case["model"]
    ref = reference(key)
    compiled = fccgen.load(path, build_dir)
    numeric = fccgen.load_numeric(path)
    variants = default_variants(methods)
    progress = _progress()
    ladder = Ladder(case["steps"], case["tolerances"], per_method=case["per_method"])
    partial = out_dir / f"{key}_accuracy.partial.csv"
    done: list = []

    def save(rows):            # a long run that is stopped keeps what it measured
        write_csv(done + rows, partial)
    rows = run_ladder(compiled, ref, ladder, variants, None, progress, save)
    done = list(rows)
    numeric_variants = case["numeric"] or [
        v for v in variants if registry.get(v.method).compiled_loop]
    coarsest = {m: v[:1] for m, v in case["per_method"].items()}
    rows += run_ladder(None, ref, Ladder(case["numeric_steps"], case["tolerances"][:1],
                                         numeric_rungs=1, per_method=coarsest),
                       [Variant(v.method, v.project) for v in numeric_variants],
                       numeric, progress, save)
    report = finish(key, rows, out_dir)
    partial.unlink(missing_ok=True)
    return report


def finish(key: str, rows, out_dir: Path) -> AccuracyReport:
    """The report of measured rows: CSV, plots and summary in ``out_dir``."""
    report = AccuracyReport(rows, reference(key), CASES[key]["title"], LEVELS)
    report.notes.append(f"measured on {platform.machine()} {platform.system()}, "
                        f"{os.cpu_count()} CPUs, Python {platform.python_version()}, "
                        f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, "
                        f"{time.strftime('%Y-%m-%d')}")
    report.write(out_dir, f"{key}_accuracy")
    return report


def _progress():
    start = time.perf_counter()

    def show(message: str) -> None:
        print(f"[{time.perf_counter() - start:7.1f} s] {message}", flush=True)
    return show


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=sorted(CASES), action="append",
                    help="run only this benchmark (repeatable)")
    ap.add_argument("--out-dir", type=Path, default=ROOT / "docs" / "accuracy")
    ap.add_argument("--build-dir", default=str(ROOT / "generated"))
    ap.add_argument("--methods", help="comma-separated methods (default: all registered)")
    ap.add_argument("--from-csv", type=Path, nargs="+", metavar="CSV",
                    help="no runs: rebuild the report of the --only benchmark from these "
                         "measured tables (e.g. methods split over several processes)")
    args = ap.parse_args(argv)
    methods = args.methods.split(",") if args.methods else None
    for key in args.only or sorted(CASES):
        if args.from_csv:
            report = finish(key, [r for f in args.from_csv for r in read_csv(f)],
                            args.out_dir)
        else:
            report = run_case(key, args.out_dir, args.build_dir, methods)
        print(f"\n== {report.title} ==\n{report.summary()}")
        print("\n".join(report.notes))
        print("written: " + ", ".join(str(p) for p in report.files.values()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
