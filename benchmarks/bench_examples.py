"""Compiled vs numeric on every example, measured in one run.

    python benchmarks/bench_examples.py [--repeats N] [--json FILE]

For each example: a cold generation + compile into a fresh directory (stage timings),
the cache-hit time, and per kernel, per acceleration evaluation (assembly + solve) and
per RK4 step the compiled and numeric times (medians of warm, batched calls) with the
speed-up and the largest relative difference between the two. Run with single-threaded
BLAS (set here before NumPy loads) so that timings are comparable and repeatable.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import fccgen  # noqa: E402
from fccgen.bench.speed import bench_model  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ["a01_pendulum", "double_pendulum", "free_body", "spherical_pendulum",
            "four_bar", "deployable"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--json", type=Path, help="also write the figures as JSON")
    ap.add_argument("examples", nargs="*", default=EXAMPLES)
    args = ap.parse_args(argv)
    summary = {}
    with tempfile.TemporaryDirectory(prefix="fccgen-bench-") as tmp:
        for name in args.examples:
            path = ROOT / "examples" / f"{name}.yaml"
            t0 = time.perf_counter()
            _, built = fccgen.generate(path, tmp)           # cold: fresh directory
            cold = time.perf_counter() - t0
            report = bench_model(path, tmp, repeats=args.repeats)
            print(report.text())
            print(f"cold generate + compile: {cold:.2f} s\n", flush=True)
            summary[name] = {
                "n_q": report.n_q, "n_g": report.n_g, "cold_build_s": cold,
                "build_stages_s": built.timings, "cache_hit_s": report.cache_hit_seconds,
                "rows": {r.what: {"compiled_s": r.compiled, "numeric_s": r.numeric,
                                  "speedup": r.speedup, "max_rel_diff": r.max_rel_diff}
                         for r in report.rows},
            }
    print("| example | n_q | cold build | cache hit | accelerations (compiled / numeric) "
          "| speed-up | RK4 step compiled | speed-up |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, s in summary.items():
        a, k = s["rows"]["accelerations"], s["rows"]["rk4 step (projected)"]
        print(f"| {name} | {s['n_q']} | {s['cold_build_s']:.2f} s | "
              f"{s['cache_hit_s'] * 1e3:.1f} ms | {a['compiled_s'] * 1e6:.2f} us / "
              f"{a['numeric_s'] * 1e3:.2f} ms | {a['speedup']:.0f}x | "
              f"{k['compiled_s'] * 1e6:.2f} us | {k['speedup']:.0f}x |")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
