"""The outputs of the accuracy ladder (:mod:`fccgen.bench.accuracy`): the CSV table, the
work-precision plot (matplotlib, imported lazily: it is optional) and the text summary
that names the fastest run at each accuracy level."""
from __future__ import annotations

import csv
import os
import math
from dataclasses import dataclass, field, fields
from pathlib import Path

from .accuracy import (COLUMNS, Ladder, Reference, Row, Variant, converged_reference,
                       default_steps, default_variants, run_ladder)

def write_csv(rows: list[Row], path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([_cell(getattr(r, c)) for c in COLUMNS])
    return path


def _cell(x):
    if isinstance(x, float):
        return "" if math.isnan(x) else f"{x:.6g}"
    return x


def read_csv(path) -> list[Row]:
    """Rows written by :func:`write_csv`."""
    kinds = {f.name: f.type for f in fields(Row)}
    out = []
    with open(path, newline="") as fh:
        for rec in csv.DictReader(fh):
            vals = {}
            for k, s in rec.items():
                if kinds[k] == "float":
                    vals[k] = float(s) if s else math.nan
                elif kinds[k] == "bool":
                    vals[k] = s == "True"
                else:
                    vals[k] = s
            out.append(Row(**vals))
    return out


def write_plot(rows: list[Row], path, title: str, levels=()) -> Path | None:
    """Error against CPU time, log-log, one curve per variant, the accuracy levels as
    dashed lines. Returns None (nothing written) when matplotlib is not installed."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, ax = plt.subplots(figsize=(10, 5.5))
    colors = _method_colors(rows)
    for variant, curve in _curves(rows).items():
        ax.plot([r.cpu_time for r in curve], [r.error for r in curve],
                color=colors[variant.method], linestyle="-" if variant.project else "--",
                marker="o" if variant.version == "compiled" else "s",
                label=variant.label, markersize=4)
    for level in levels:
        ax.axhline(level, color="grey", linestyle=":", linewidth=1)
    ax.set(xscale="log", yscale="log", xlabel="CPU time of the run (s)",
           ylabel="largest position error (m)", title=title)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
          "#7f7f7f", "#bcbd22", "#17becf", "#000000", "#aec7e8")


def write_svg(rows: list[Row], path, title: str, levels=()) -> Path:
    """The same plot as :func:`write_plot` as a plain SVG file (no dependency): log-log
    axes with decade ticks, one polyline per variant, the levels dashed, a legend."""
    curves = _curves(rows)
    xs = [math.log10(r.cpu_time) for c in curves.values() for r in c] or [0.0]
    ys = [math.log10(r.error) for c in curves.values() for r in c] or [0.0]
    ys += [math.log10(v) for v in levels]
    x0, x1 = math.floor(min(xs)), math.ceil(max(xs)) + (min(xs) == max(xs))
    y0, y1 = math.floor(min(ys)), math.ceil(max(ys)) + (min(ys) == max(ys))
    w, h, left, top, pw = 760, 430 + 14 * len(curves), 70, 40, 640
    ph = 330

    def px(x):
        return left + (x - x0) / (x1 - x0) * pw

    def py(y):
        return top + (y1 - y) / (y1 - y0) * ph
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
           f'font-family="sans-serif" font-size="11">',
           f'<rect width="{w}" height="{h}" fill="white"/>',
           f'<text x="{left + pw / 2}" y="20" text-anchor="middle" font-size="13">'
           f'{_esc(title)}</text>',
           f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="none" '
           f'stroke="black"/>']
    for k in range(x0, x1 + 1):
        out.append(f'<line x1="{px(k):.1f}" y1="{top}" x2="{px(k):.1f}" y2="{top + ph}" '
                   f'stroke="#ddd"/><text x="{px(k):.1f}" y="{top + ph + 14}" '
                   f'text-anchor="middle">1e{k}</text>')
    for k in range(y0, y1 + 1):
        out.append(f'<line x1="{left}" y1="{py(k):.1f}" x2="{left + pw}" y2="{py(k):.1f}" '
                   f'stroke="#ddd"/><text x="{left - 4}" y="{py(k) + 4:.1f}" '
                   f'text-anchor="end">1e{k}</text>')
    for v in levels:
        out.append(f'<line x1="{left}" y1="{py(math.log10(v)):.1f}" x2="{left + pw}" '
                   f'y2="{py(math.log10(v)):.1f}" stroke="grey" stroke-dasharray="4,3"/>')
    out.append(f'<text x="{left + pw / 2}" y="{top + ph + 32}" text-anchor="middle">'
               'CPU time of the run (s)</text>')
    out.append(f'<text x="16" y="{top + ph / 2}" text-anchor="middle" '
               f'transform="rotate(-90 16 {top + ph / 2})">largest position error (m)'
               '</text>')
    colors = _method_colors(rows)
    for n, (variant, curve) in enumerate(curves.items()):
        color = colors[variant.method]
        dash = "" if variant.project else ' stroke-dasharray="6,3"'
        pts = " ".join(f"{px(math.log10(r.cpu_time)):.1f},{py(math.log10(r.error)):.1f}"
                       for r in curve)
        out.append(f'<polyline points="{pts}" fill="none" stroke="{color}"{dash}/>')
        out += [_marker(*map(float, p.split(",")), color, variant.version)
                for p in pts.split()]
        ly = top + ph + 50 + 14 * n
        out.append(f'<line x1="{left}" y1="{ly - 4}" x2="{left + 24}" y2="{ly - 4}" '
                   f'stroke="{color}"{dash}/><text x="{left + 30}" y="{ly}">'
                   f'{_esc(variant.label)}</text>')
    out.append("</svg>")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(out) + "\n")
    return path


def _marker(x: float, y: float, color: str, version: str) -> str:
    """A dot for a compiled run, a square for a numeric one."""
    if version == "compiled":
        return f'<circle cx="{x:.1f}" cy="{y:.1f}" r="2.5" fill="{color}"/>'
    return f'<rect x="{x - 3:.1f}" y="{y - 3:.1f}" width="6" height="6" fill="{color}"/>'


def _esc(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _method_colors(rows: list[Row]) -> dict[str, str]:
    """One colour per method, in order of appearance."""
    names = list(dict.fromkeys(r.method for r in rows))
    return {m: COLORS[k % len(COLORS)] for k, m in enumerate(names)}


def _curves(rows: list[Row]) -> dict[Variant, list[Row]]:
    curves: dict[Variant, list[Row]] = {}
    for r in rows:
        if r.status == "ok" and r.error > 0:
            curves.setdefault(r.variant, []).append(r)
    return curves


def markdown_table(rows: list[Row]) -> str:
    """The runs as a Markdown table (for docs): one line per run, failures included."""
    out = ["| method | version | projection | setting | error (m) | CPU time (s) | steps "
           "| rhs evaluations | max constraint error | status |",
           "| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        status = r.status if r.status == "ok" else f"{r.status}: {r.failure}"
        out.append(f"| {r.method} | {r.version} | {'yes' if r.project else 'no'} "
                   f"| {r.setting} = {r.value:g} | {_num(r.error)} | {_num(r.cpu_time, 3)} "
                   f"| {_num(r.steps, 0)} | {_num(r.rhs_evaluations, 0)} "
                   f"| {_num(r.max_constraint_error)} | {status.replace('|', '/')} |")
    return "\n".join(out)


def _num(x: float, digits: int = -1) -> str:
    if math.isnan(x):
        return ""
    if digits == 0:
        return f"{x:.0f}"
    return f"{x:.{digits}g}" if digits > 0 else f"{x:.2e}"


def fastest_at(rows: list[Row], level: float) -> Row | None:
    """The cheapest run (CPU time) whose error is at most ``level``."""
    ok = [r for r in rows if r.status == "ok" and r.error <= level]
    return min(ok, key=lambda r: r.cpu_time) if ok else None


def summary(rows: list[Row], reference: Reference, levels=None) -> str:
    """The reference, the fastest run at each accuracy level, the cost of projection,
    the numeric version's, and every failure."""
    levels = sorted(levels or _decades(rows), reverse=True)
    lines = [f"reference: {reference.kind}: {reference.description}",
             "fastest run at each accuracy level (largest position error, CPU time):"]
    for level in levels:
        r = fastest_at(rows, level)
        lines.append(f"  <= {level:.0e} m: " + (
            "no run" if r is None else
            f"{r.variant.label} at {r.setting} = {r.value:g}: error {r.error:.2e} m, "
            f"{r.cpu_time:.3g} s"))
    lines += _ratio_lines(rows)
    failed = [r for r in rows if r.status == "failed"]
    if failed:
        lines.append("failed runs:")
        lines += [f"  {r.variant.label} at {r.setting} = {r.value:g}: {r.failure}"
                  for r in failed]
    missing = sorted({r.variant.label for r in rows if r.status == "unsupported"})
    if missing:
        lines.append("not offered by this version: " + ", ".join(missing))
    return "\n".join(lines)


def _decades(rows: list[Row], most: int = 10) -> list[float]:
    """1e-1, 1e-2, ... down to the smallest error measured (at most ``most`` levels)."""
    errs = [r.error for r in rows if r.status == "ok" and 0 < r.error]
    if not errs:
        return [1e-3]
    lo = max(math.floor(math.log10(min(errs))), -most)
    return [10.0 ** k for k in range(-1, lo - 1, -1)] or [10.0 ** lo]


def _ratio_lines(rows: list[Row]) -> list[str]:
    """CPU-time ratios at equal settings: projected / unprojected, numeric / compiled."""
    by_key = {(r.method, r.version, r.project, r.setting, r.value): r
              for r in rows if r.status == "ok"}
    proj, numer = [], []
    for (m, ver, p, s, val), r in by_key.items():
        other = by_key.get((m, ver, False, s, val))
        if p and other:
            ratio = r.cpu_time / other.cpu_time
            proj.append(f"  {m} ({ver}) at {s} = {val:g}: {ratio:.2f}x "
                        f"the CPU time; error {r.error:.2e} vs {other.error:.2e} m, "
                        f"constraint error {r.max_constraint_error:.1e} vs "
                        f"{other.max_constraint_error:.1e}")
        base = by_key.get((m, "compiled", p, s, val))
        if ver == "numeric" and base:
            numer.append(f"  {r.variant.label} at {s} = {val:g}: "
                         f"{r.cpu_time / base.cpu_time:.1f}x the compiled CPU time; errors "
                         f"differ by {abs(r.error - base.error):.1e} m")
    out = []
    if proj:
        out += ["cost of projection (with / without, same setting):", *sorted(proj)]
    if numer:
        out += ["numeric version (NumPy) against the compiled one:", *sorted(numer)]
    return out


@dataclass
class AccuracyReport:
    rows: list[Row]
    reference: Reference
    title: str
    levels: tuple[float, ...] = ()
    files: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        return summary(self.rows, self.reference, self.levels or None)

    def write(self, out_dir, stem: str) -> dict[str, Path]:
        """``<stem>.csv``, ``<stem>.svg``, ``<stem>.png`` (if matplotlib is there),
        ``<stem>.md`` (the table in Markdown) and ``<stem>.txt`` (the summary)."""
        out_dir = Path(out_dir)
        self.files = {"csv": write_csv(self.rows, out_dir / f"{stem}.csv")}
        self.files["svg"] = write_svg(self.rows, out_dir / f"{stem}.svg", self.title,
                                      self.levels)
        png = write_plot(self.rows, out_dir / f"{stem}.png", self.title, self.levels)
        if png is None:
            self.notes.append("PNG plot skipped: matplotlib is not installed "
                              "(pip install fccgen[plot]); the SVG plot was written")
        else:
            self.files["png"] = png
        path = out_dir / f"{stem}.md"
        path.write_text(markdown_table(self.rows) + "\n")
        self.files["md"] = path
        text = self.summary() + "".join(f"\n{n}" for n in self.notes)
        path = out_dir / f"{stem}.txt"
        path.write_text(text + "\n")
        self.files["txt"] = path
        return self.files


def bench_accuracy(path, build_dir="generated", out_dir="accuracy", *, t_end=None,
                   output_dt=None, steps=None, tolerances=None, methods=None,
                   numeric_rungs=1, reference=None, levels=(), progress=None
                   ) -> AccuracyReport:
    """The whole measurement for one model file: ladder, reference, CSV, plot, summary.

    t_end, output_dt: default from the model's ``simulate`` section (output_dt: its
    output_dt, else 10 dt). steps: the fixed-step ladder (default output_dt / 1 ... 16).
    reference: a :class:`Reference` (its times then set output_dt, and t_end unless
    given: the reference is cut there); None: a converged run at a quarter of the
    finest step. numeric_rungs: 0 leaves the numeric
    version out. Writes ``<model>_accuracy.{csv,png,txt}`` into ``out_dir``.
    """
    from ..api import load, load_numeric
    compiled = load(path, build_dir, progress=progress)
    sim = compiled.plan.model.simulate
    if reference is None:
        t_end = float(sim.t_end if t_end is None else t_end)
        output_dt = float(output_dt or sim.output_dt or 10 * sim.dt)
    else:
        if t_end is not None:
            reference = reference.until(float(t_end))
        t_end, output_dt = reference.t_end, reference.output_dt
    ladder = Ladder(tuple(steps or default_steps(output_dt)),
                    numeric_rungs=int(numeric_rungs))
    if tolerances:
        ladder.tolerances = tuple(tolerances)
    if reference is None:
        if progress:
            progress("computing the converged reference run")
        reference = converged_reference(compiled, t_end, output_dt, min(ladder.steps) / 4,
                                        progress)
    numeric = load_numeric(path) if numeric_rungs > 0 else None
    variants = default_variants(methods)
    rows = run_ladder(compiled, reference, ladder, variants, numeric, progress)
    name = compiled.plan.model.name
    report = AccuracyReport(rows, reference, f"{name}: error against CPU time, "
                            f"t_end = {t_end:g}", tuple(levels))
    if os.environ.get("OPENBLAS_NUM_THREADS") != "1":
        report.notes.append("BLAS may run several threads (OPENBLAS_NUM_THREADS is not 1): "
                            "the small dense solves of the runtime then run slower and "
                            "the CPU times are noisier")
    report.write(out_dir, f"{name}_accuracy")
    return report
