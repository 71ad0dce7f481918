"""Where ``simulate(error=E)`` lands: the error it reached, its estimate and its cost,
next to every method's work-precision curve.

    python benchmarks/error_target.py [--cases a01,a02,top,solar] [--levels 1e-3,1e-6,1e-9]

For each case of tests/error_references.py (A01 over 2000 s, A02 N = 40 over 20 s, the
heavy top, the solar array with its latches) and each level E, one error-target run:
its true error against the case's reference, info["error_estimate"], the method and
setting it chose, and its cost in evaluations (pilot, run, estimate) and CPU seconds.
Levels a case's reference cannot judge are left out (A02's published table has six
digits: only 1e-3). The curves are the grid search of
tests/data/error_target_grid.py (error against evaluations of rk4 and dopri5 with
projection); the runs are drawn on them at their run cost (filled) and at their whole
cost (open). Writes docs/accuracy/error_target.csv, error_target.md and
error_target_<case>.png.
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
import error_references as refs  # noqa: E402

OUT = ROOT / "docs" / "accuracy"
GRID = ROOT / "tests" / "data" / "error_target_grid.json"
LEVELS = {"a01": (1e-3, 1e-6, 1e-9), "a02": (1e-3,), "top": (1e-3, 1e-6, 1e-9),
          "solar": (1e-3, 1e-6, 1e-9)}


def measure(name: str, levels, build_dir, model_dir) -> list[dict]:
    case = refs.CASES[name]
    solver = refs.load(name, build_dir, model_dir)
    ref = case.reference(solver)
    rows = []
    for level in levels:
        start = time.process_time()
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            r = solver.simulate(error=level, t_end=case.t_end, output_dt=case.output_dt)
        cpu = time.process_time() - start
        acc = r.info["accuracy"]
        row = dict(case=name, target=level, true_error=case.error(solver, r, ref),
                   estimate=r.info["error_estimate"], method=acc["method"],
                   setting=f"{acc['setting']} = {acc['value']:.4g}",
                   pilot=acc["cost"]["pilot"], run=acc["cost"]["run"],
                   estimate_cost=acc["cost"]["estimate"], cpu=cpu,
                   warned=" | ".join(str(w.message) for w in seen))
        rows.append(row)
        print(f"{name} E={level:g}: true {row['true_error']:.3g}, estimate "
              f"{row['estimate']:.3g}, {row['method']} {row['setting']}, run "
              f"{row['run']:.3g} of {row['pilot'] + row['run'] + row['estimate_cost']:.3g} "
              f"evaluations, CPU {cpu:.2f} s{' (warned)' if row['warned'] else ''}",
              flush=True)
    return rows


def plot(name: str, rows: list[dict], grid: dict) -> None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no figure")
        return
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for method, colour in (("rk4", "tab:blue"), ("dopri5", "tab:orange")):
        pts = sorted((r["evaluations"], r["error"]) for r in grid[name]["runs"]
                     if r["method"] == method and r.get("error"))
        if pts:
            ax.loglog(*zip(*pts), "-", color=colour, lw=1, label=f"{method} (grid)")
    for r in rows:
        colour = "tab:blue" if r["method"] == "rk4" else "tab:orange"
        total = r["pilot"] + r["run"] + r["estimate_cost"]
        ax.loglog(r["run"], r["true_error"], "o", color=colour)
        ax.loglog(total, r["true_error"], "o", mfc="none", color=colour)
        ax.axhline(r["target"], color="grey", ls=":", lw=0.8)
        ax.annotate(f"--error {r['target']:g}", (total, r["true_error"]),
                    textcoords="offset points", xytext=(6, -3), fontsize=8)
    ax.set_xlabel("cost (evaluations)")
    ax.set_ylabel("true error (length units)")
    ax.set_title(f"{name}: --error runs on the methods' curves")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / f"error_target_{name}.png", dpi=110)
    plt.close(fig)


def table(rows) -> str:
    lines = ["| case | E | method, setting | true error | estimate | run / whole cost "
             "(evaluations) | CPU (s) | warned |", "| --- | ---: | --- | ---: | ---: | ---: "
             "| ---: | --- |"]
    for r in rows:
        total = r["pilot"] + r["run"] + r["estimate_cost"]
        lines.append(f"| {r['case']} | {r['target']:g} | {r['method']}, {r['setting']} | "
                     f"{r['true_error']:.2g} | {r['estimate']:.2g} | {r['run']:.3g} / "
                     f"{total:.3g} | {r['cpu']:.3g} | {'yes' if r['warned'] else 'no'} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default=",".join(LEVELS))
    ap.add_argument("--levels", help="comma-separated (default: each case's)")
    args = ap.parse_args()
    grid = json.loads(GRID.read_text())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases.split(","):
            levels = ([float(x) for x in args.levels.split(",")] if args.levels
                      else LEVELS[name])
            case_rows = measure(name, levels, Path(tmp) / "generated", Path(tmp))
            rows += case_rows
            if name in grid:
                plot(name, case_rows, grid)
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / "error_target.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (OUT / "error_target.md").write_text(table(rows))
    print(table(rows))


if __name__ == "__main__":
    main()
