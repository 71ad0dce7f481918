"""Where ``simulate(error=E)`` lands: the error it reached, its estimate and its cost,
next to every method's work-precision curve.

    python benchmarks/error_target.py [--cases a01,a02,a02s,top,solar,andrews]
                                      [--levels 1e-3,1e-6,1e-9]

For each case of tests/error_references.py (A01 over 2000 s, A02 N = 40 over 20 s and
over its first 0.6 s, the heavy top, the solar array with its latches, Andrews'
mechanism) and each level E, one error-target run: its true error against the case's
reference, info["error_estimate"], the method and setting it chose, and its cost in
evaluations (pilot, run, estimate, and the first run with its estimate when the run
was repeated) and CPU seconds, next to the cheapest hand-tuned run of the grid search
that meets E: the chosen run's cost over it ("run / best") and the whole command's
("whole / best"). Levels a case's reference cannot judge are left out (A02 over 20 s:
only 1e-3). The curves are the grid search of tests/data/error_target_grid.py (error
against evaluations of rk4 and dopri5 with projection); the runs are drawn on them at
their run cost (filled) and at their whole cost (open). Writes
docs/accuracy/error_target.csv, error_target.md and error_target_<case>.png (with
--out-name NAME: NAME.csv, NAME.md, NAME_<case>.png). A level a case's reference
cannot judge may be asked for all the same (--cases a02 --levels 1e-6,1e-9): its
true error is then the distance from that reference.
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
LEVELS = {"a01": (1e-3, 1e-6, 1e-9), "a02": (1e-3,), "a02s": (1e-6, 1e-9),
          "top": (1e-3, 1e-6, 1e-9), "solar": (1e-3, 1e-6, 1e-9),
          "andrews": (1e-3, 1e-6, 1e-9)}


def cheapest(grid: dict, name: str, level: float) -> float:
    """Evaluations of the cheapest hand-tuned run of the grid that meets level."""
    meets = [r["evaluations"] for r in grid.get(name, {}).get("runs", [])
             if r.get("error") is not None and r["error"] <= level]
    return min(meets) if meets else float("nan")


def measure(name: str, levels, build_dir, model_dir, grid: dict) -> list[dict]:
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
        cost = acc["cost"]
        row = dict(case=name, target=level, true_error=case.error(solver, r, ref),
                   estimate=r.info["error_estimate"], method=acc["method"],
                   setting=f"{acc['setting']} = {acc['value']:.4g}",
                   repeated=bool(acc["repeated"]), pilot=cost["pilot"], run=cost["run"],
                   estimate_cost=cost["estimate"], repeat=cost["repeat"],
                   whole=cost["whole"], best=cheapest(grid, name, level), cpu=cpu,
                   # the files name the model relative to the repository
                   warned=" | ".join(str(w.message) for w in seen).replace(
                       f"{ROOT}{os.sep}", ""))
        rows.append(row)
        print(f"{name} E={level:g}: true {row['true_error']:.3g}, estimate "
              f"{row['estimate']:.3g}, {row['method']} {row['setting']}"
              f"{' (repeated)' if row['repeated'] else ''}, run {row['run']:.3g} of "
              f"{row['whole']:.3g} evaluations (best hand-tuned {row['best']:.3g}), "
              f"CPU {cpu:.2f} s{' (warned)' if row['warned'] else ''}", flush=True)
    return rows


def plot(name: str, rows: list[dict], grid: dict, out_name: str = "error_target") -> None:
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
        total = r["whole"]
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
    fig.savefig(OUT / f"{out_name}_{name}.png", dpi=110)
    plt.close(fig)


def table(rows) -> str:
    lines = ["| case | E | method, setting | true error | estimate | pilot + run + estimate "
             "(+ first run) = whole | best hand-tuned | run / best | whole / best | CPU (s) "
             "| warned |",
             "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        parts = f"{r['pilot']:.3g} + {r['run']:.3g} + {r['estimate_cost']:.3g}"
        if r["repeat"]:
            parts += f" + {r['repeat']:.3g}"
        lines.append(f"| {r['case']} | {r['target']:g} | {r['method']}, {r['setting']}"
                     f"{' (repeated)' if r['repeated'] else ''} | {r['true_error']:.2g} | "
                     f"{r['estimate']:.2g} | {parts} = {r['whole']:.3g} | {r['best']:.3g} | "
                     f"{r['run'] / r['best']:.2f} | {r['whole'] / r['best']:.2f} | "
                     f"{r['cpu']:.3g} | {'yes' if r['warned'] else 'no'} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default=",".join(LEVELS))
    ap.add_argument("--levels", help="comma-separated (default: each case's)")
    ap.add_argument("--out-name", default="error_target",
                    help="the written files' stem (default error_target)")
    args = ap.parse_args()
    grid = json.loads(GRID.read_text())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases.split(","):
            levels = ([float(x) for x in args.levels.split(",")] if args.levels
                      else LEVELS[name])
            case_rows = measure(name, levels, Path(tmp) / "generated", Path(tmp), grid)
            rows += case_rows
            if name in grid:
                plot(name, case_rows, grid, args.out_name)
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / f"{args.out_name}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (OUT / f"{args.out_name}.md").write_text(table(rows))
    print(table(rows))


if __name__ == "__main__":
    main()
