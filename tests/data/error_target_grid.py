"""The cheapest hand-tuned method and setting that meets each error level of the
error-target tests: a grid search, stored in error_target_grid.json.

    python tests/data/error_target_grid.py [--cases a01,a02,top,solar]

For every case of tests/error_references.py, rk4 with projection runs at steps
output_dt / n (n on a geometric ladder, ratio about 1.2) and dopri5 with projection at
tolerances 10^(-k/6) (atol = rtol * 1e-3 * the length scale, as the error target sets
it). Each run's true error is measured against the case's reference and its cost in
evaluations (fccgen.target_error.pilot.evaluations: deterministic counts, no times).
For each level the cheapest run that meets it is stored; the test
(test_error_target.py) holds the error target's run within 2x of it. The grid's
ratio (1.2 in the setting) makes the stored optimum at most ~1.2x above the true one.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import error_references as refs  # noqa: E402
from fccgen.target_error.pilot import evaluations, settings_of  # noqa: E402

OUT = HERE / "error_target_grid.json"
# ladders per case: rk4 steps as divisors n of output_dt, dopri5 tolerances
LADDERS = {
    "a01": dict(n=(2, 2000), rtol=(1e-7, 1e-13)),
    "a02": dict(n=(1, 12), rtol=(1e-6, 1e-9)),
    "top": dict(n=(1, 400), rtol=(1e-4, 1e-12)),
    "solar": dict(n=(1, 200), rtol=(1e-3, 1e-10)),
    "andrews": dict(n=(1, 300), rtol=(1e-3, 1e-12)),
    "a02s": dict(n=(1, 60), rtol=(1e-4, 1e-12)),
}



def reason(exc: Exception) -> str:
    """The failure's text with the model file named by its file name alone (the
    folder it ran from belongs to the machine, not to the data)."""
    return re.sub(r"^\S*/([^/\s]+\.yaml):", r"\1:", str(exc))

def ladder(case: str):
    lo, hi = LADDERS[case]["n"]
    ns = sorted(set(int(round(x)) for x in np.geomspace(lo, hi, int(np.log(hi / lo)
                                                                     / np.log(1.2)) + 2)))
    a, b = LADDERS[case]["rtol"]
    ks = range(int(round(-6 * np.log10(a))), int(round(-6 * np.log10(b))) + 1)
    return ([("rk4", None, n) for n in ns]
            + [("dopri5", 10.0 ** (-k / 6), None) for k in ks])


def search(name: str, build_dir, model_dir) -> dict:
    case = refs.CASES[name]
    solver = refs.load(name, build_dir, model_dir)
    ref = case.reference(solver)
    runs = []
    for method, rtol, n in ladder(name):
        value = rtol if method == "dopri5" else case.output_dt / n
        kwargs = settings_of(method, value, solver.length_scale)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = solver.simulate(t_end=case.t_end, output_dt=case.output_dt,
                                    method=method, reactions=False, **kwargs)
            err = case.error(solver, r, ref)
        except Exception as exc:          # noqa: BLE001  (a failed rung is recorded)
            runs.append(dict(method=method, value=value, error=None, failure=reason(exc)))
            continue
        runs.append(dict(method=method, value=value, error=err,
                         evaluations=evaluations(r.info)))
        print(f"{name} {method} {value:.4g}: error {err:.3g}, {evaluations(r.info):.4g} "
              "evaluations", flush=True)
    best = {}
    for level in case.levels:
        ok = [r for r in runs if r["error"] is not None and r["error"] <= level]
        best[f"{level:g}"] = min(ok, key=lambda r: r["evaluations"]) if ok else None
    return dict(t_end=case.t_end, output_dt=case.output_dt, cheapest=best, runs=runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default=",".join(refs.CASES))
    args = ap.parse_args()
    data = json.loads(OUT.read_text()) if OUT.exists() else {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases.split(","):
            data[name] = search(name, Path(tmp) / "generated", Path(tmp))
            OUT.write_text(json.dumps(data, indent=1) + "\n")
    print(f"written: {OUT}")


if __name__ == "__main__":
    main()
