"""``fccgen bench``: the compiled version against the numeric one, measured in one run.

Timings are medians over many repetitions of warm calls. Compiled kernels are timed
inside compiled loops (no Python call in the measurement); the numeric version is timed
through its Python functions, which is how it runs.
"""
from __future__ import annotations

import json
import statistics
import time
from dataclasses import dataclass, field

import numpy as np

from ..plan.kernels import KERNEL_NAMES
from ..progress import Reporter
from ..threads import single_threaded_blas

GLOBAL_KERNELS = {  # kernel -> (solver method, takes v)
    "mass_matrix": ("mass_matrix", False),
    "h_vector": ("h_vector", True),
    "applied_forces": ("applied_forces", True),
    "constraints": ("constraints", False),
    "constraint_jacobian": ("constraint_jacobian", False),
    "constraint_bias": ("constraint_bias", True),
    "energy": ("energy", True),
    "body_outputs": ("body_outputs", True),
    "force_jacobian_q": ("force_jacobian_q", True),
    "force_jacobian_v": ("force_jacobian_v", True),
}


@dataclass
class BenchRow:
    what: str
    compiled: float        # seconds per call
    numeric: float
    max_rel_diff: float    # largest |compiled - numeric| / max |numeric|

    @property
    def speedup(self) -> float:
        return self.numeric / self.compiled if self.compiled > 0 else float("inf")


@dataclass
class BenchReport:
    name: str
    n_q: int
    n_g: int
    rows: list[BenchRow] = field(default_factory=list)
    build: dict = field(default_factory=dict)      # timings of the last real build
    absent: list[str] = field(default_factory=list)  # kernels structurally zero here
    cache_hit_seconds: float = float("nan")

    def row(self, what: str) -> BenchRow:
        return next(r for r in self.rows if r.what == what)

    def text(self) -> str:
        out = [f"model {self.name}: {self.n_q} coordinates, {self.n_g} constraint equations",
               f"{'':24}{'compiled':>12}{'numeric':>12}{'speed-up':>10}{'max rel diff':>14}"]
        for r in self.rows:
            out.append(f"{r.what:24}{_fmt(r.compiled):>12}{_fmt(r.numeric):>12}"
                       f"{r.speedup:>9.1f}x{r.max_rel_diff:>14.2e}")
        if self.absent:
            out.append("structurally zero in this model (no code generated): "
                       + ", ".join(self.absent))
        if self.build:
            parts = ", ".join(f"{k} {v:.2f} s" for k, v in self.build.items())
            out.append(f"last build: {parts}")
        out.append(f"cache hit: {self.cache_hit_seconds * 1e3:.1f} ms")
        return "\n".join(out)


def _fmt(seconds: float) -> str:
    if seconds < 1e-3:
        return f"{seconds * 1e6:.2f} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def median_time(fn, repeats: int, min_batch_seconds: float = 2e-4) -> float:
    """Median seconds per call of ``fn()``, calls batched so each sample is long enough
    to time, after a warm-up."""
    fn()
    batch = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(batch):
            fn()
        if time.perf_counter() - t0 >= min_batch_seconds or batch >= 1 << 16:
            break
        batch *= 2
    samples = []
    for _ in range(max(repeats // 10, 5)):
        t0 = time.perf_counter()
        for _ in range(batch):
            fn()
        samples.append((time.perf_counter() - t0) / batch)
    return statistics.median(samples)


def _rel(a, b, scale=None) -> float:
    """Largest difference relative to ``scale`` (default: the largest |b|)."""
    a, b = np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(b, float))
    if not b.size:
        return 0.0
    if scale is None:
        scale = float(np.max(np.abs(b)))
    diff = float(np.max(np.abs(a - b)))
    return diff / scale if scale > 0 else diff


def _last_build_timings(built) -> dict:
    """Stage timings of the build that produced the module (a cache hit has none)."""
    if not built.cache_hit:
        return dict(built.timings)
    try:
        return dict(json.loads((built.directory / "fccgen.json").read_text())["timings"])
    except (OSError, ValueError, KeyError):
        return {}


def bench_model(path, *args, **kwargs) -> BenchReport:
    """Time one model's compiled and numeric versions (see the module docstring)."""
    with single_threaded_blas():
        return _bench_model(path, *args, **kwargs)


def _bench_model(path, build_dir="generated", *, repeats=200, progress=None,
                rk4_steps=2000, seed=0) -> BenchReport:
    from ..api import generate, load, load_numeric

    t0 = time.perf_counter()
    plan, built = generate(path, build_dir, progress=progress)
    hit = time.perf_counter() - t0
    cs = load(path, build_dir)
    t0 = time.perf_counter()
    generate(path, build_dir)
    hit = min(hit, time.perf_counter() - t0)
    ns = load_numeric(path)

    rng = np.random.default_rng(seed)
    init = ns.initial_state()
    q, v = init.q, ns.project_velocities(init.q, init.v + rng.normal(size=init.v.shape))
    report = BenchReport(plan.model.name, plan.n_q, plan.n_g,
                         build=_last_build_timings(built), cache_hit_seconds=hit)
    length = max([el.params[0] for el in plan.elements if el.cls.kind == "body"] or [1.0])
    tick = _ticker(progress, len(GLOBAL_KERNELS) + 9)
    tick(f"timing up to {len(KERNEL_NAMES)} kernels, accelerations and RK4 steps")
    c_kernels = cs.time_kernels(q, v, repeats)
    for kernel, (method, takes_v) in GLOBAL_KERNELS.items():
        tick(f"timing the numeric {kernel}")
        if kernel not in c_kernels:
            report.absent.append(kernel)
            continue
        args = (q, v) if takes_v else (q,)
        n_fn = getattr(ns, method)
        # g vanishes on the manifold: compare it with the size of the terms that cancel
        scale = length ** 2 if kernel == "constraints" else None
        report.rows.append(BenchRow(kernel, c_kernels[kernel], median_time(lambda: n_fn(*args),
                                                                            repeats),
                                    _rel(getattr(cs, method)(*args), n_fn(*args), scale)))
    tick("timing the accelerations")
    report.rows.append(BenchRow(
        "accelerations", cs.time_accelerations(q, v, repeats),
        median_time(lambda: ns.accelerations(q, v), repeats),
        _rel(cs.accelerations(q, v), ns.accelerations(q, v))))
    dt = plan.model.simulate.dt
    n_steps = 20
    tick("timing numeric RK4 steps")
    t_num = median_time(lambda: ns.simulate(t_end=n_steps * dt, dt=dt, q0=q, v0=v,
                                            output_dt=n_steps * dt, reactions=False),
                        max(repeats // 40, 3), min_batch_seconds=0.0) / n_steps
    c_steps = []
    for k in range(5):
        tick(f"timing compiled RK4 steps ({k + 1} of 5)")
        r = cs.simulate(t_end=rk4_steps * dt, dt=dt, q0=q, v0=v, output_dt=rk4_steps * dt)
        c_steps.append(r.info["wall_time"] / rk4_steps)
    tick("comparing the two versions' runs")
    rn = ns.simulate(t_end=n_steps * dt, dt=dt, q0=q, v0=v, output_dt=n_steps * dt)
    rc = cs.simulate(t_end=n_steps * dt, dt=dt, q0=q, v0=v, output_dt=n_steps * dt)
    diff = _state_difference(plan, rc, rn)
    report.rows.append(BenchRow("rk4 step (projected)", statistics.median(c_steps), t_num, diff))
    tick("done")
    return report


def _ticker(progress, total: int):
    """``tick(message)``: one more of ``total`` measurements begins (stage "bench")."""
    report = Reporter(progress, "bench", total=total)
    done = iter(range(total + 1))
    return lambda message: report(f"bench: {message}", done=min(next(done, total), total))


def _state_difference(plan, a, b) -> float:
    """Largest difference of the final positions and speeds of two runs, relative to
    the largest position and the largest speed of ``b``."""
    names = [n for n, _ in plan.triples]
    pos = [f"{n}.{c}" for n in names for c in "xyz"]
    vel = [f"{n}.v{c}" for n in names for c in "xyz"]
    out = 0.0
    for cols in (pos, vel):
        xa = np.array([a[c][-1] for c in cols])
        xb = np.array([b[c][-1] for c in cols])
        out = max(out, _rel(xa, xb))
    return out
