"""What the joint reactions add to a run: CPU and peak memory of `fccgen simulate` with
and without them, on the accordion panel array of examples/make_panel_array.py.

    python benchmarks/reactions_cost.py                       # 100 panels, 3 s, every step
    python benchmarks/reactions_cost.py --panels 50 100 200 --output-dt 0.01

For each size the model is written and built once, then each variant runs as its own
`fccgen simulate MODEL --t-end T --out FILE.npz` process (output at every step unless
--output-dt), REPEATS times; the table gives the median CPU seconds (user + system, as
/usr/bin/time -v reports them) and the largest maximum resident set size of each, and
the ratio with / without reactions. One process per run: its peak memory is its own.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REPEATS = 3


def generator():
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        "make_panel_array", ROOT / "examples" / "make_panel_array.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def measured(command: list[str], cwd: Path) -> tuple[float, float]:
    """(CPU seconds, max RSS in MB) of one child process."""
    with open(os.devnull, "w") as quiet:
        proc = subprocess.Popen(command, cwd=cwd, stdout=quiet, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(proc.pid, 0)
        err = proc.stderr.read().decode(errors="replace")
        proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{err}")
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--panels", type=int, nargs="+", default=[100])
    parser.add_argument("--t-end", type=float, default=3.0)
    parser.add_argument("--output-dt", type=float, default=None)
    parser.add_argument("--repeats", type=int, default=REPEATS)
    args = parser.parse_args(argv)
    make = generator()
    print(f"{'panels':>6} {'records':>7} {'variant':>13} {'CPU s':>7} {'max RSS MB':>10} "
          f"{'CPU ratio':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for n in args.panels:
            model = tmp / f"{make.model_name(n)}.yaml"
            model.write_text(make.model_text(n), encoding="utf-8")
            subprocess.run([sys.executable, "-m", "fccgen", "generate", str(model)],
                           cwd=tmp, check=True, capture_output=True)
            base = [sys.executable, "-m", "fccgen", "simulate", str(model), "--t-end",
                    str(args.t_end)]
            if args.output_dt:
                base += ["--output-dt", str(args.output_dt)]
            rows, records = {}, round(args.t_end / (args.output_dt or 1e-3)) + 1
            for name, extra in (("no reactions", ["--no-reactions"]), ("reactions", [])):
                runs = [measured(base + extra + ["--out", str(tmp / "out.npz")], tmp)
                        for _ in range(args.repeats)]
                rows[name] = (statistics.median(c for c, _ in runs), max(m for _, m in runs))
            for name, (cpu, rss) in rows.items():
                ratio = cpu / rows["no reactions"][0]
                print(f"{n:>6} {records:>7} {name:>13} {cpu:>7.2f} {rss:>10.0f} {ratio:>9.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
