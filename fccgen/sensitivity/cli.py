"""``fccgen sensitivity MODEL --params KEY,KEY [--out S.csv]``: one call of
:func:`fccgen.api.sensitivity` and a summary of what it found."""
from __future__ import annotations

import numpy as np


def run_sensitivity(args, progress) -> int:
    from .. import api
    result = api.sensitivity(args.model, args.params, t_end=args.t_end, dt=args.dt,
                             output_dt=args.output_dt, out=args.out,
                             build_dir=args.build_dir, force=args.force, progress=progress)
    keys = result.info["sensitivities"]
    print(f"rk4: {result.info.get('steps')} steps to t = {result.t[-1]:.6g} with the "
          f"sensitivities to {', '.join(keys)} in {result.info.get('wall_time', 0.0):.3g} s")
    for key in keys:
        cols = [c for c in result.names if not c.startswith("d(")
                and f"d({c})/d({key})" in result.columns]
        best = max(cols, key=lambda c: np.max(np.abs(result.sensitivity(c, key))))
        s = result.sensitivity(best, key)
        print(f"  d/d({key}): largest in d({best})/d({key}) = {s[np.argmax(np.abs(s))]:.6g}"
              f", at t_end {s[-1]:.6g}")
    if args.out:
        n = sum(1 for c in result.columns if c.startswith("d(") and c not in result.hidden)
        print(f"results: {args.out} ({len(result.t)} rows, {n} columns d(<column>)/d(<param>))")
    else:
        print("no --out given: results not written")
    return 0
