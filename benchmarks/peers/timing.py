"""Time per step of the three tools, measured the same way for each.

A run of k steps from the initial state costs c + k s: c the tool's set-up (fccgen's
rank decision and result table, Exudyn's solver initialisation and initial
accelerations, MuJoCo's reset) and s the time per step. Each repetition times runs of
k and 2k steps; s = (median t(2k) - median t(k)) / k removes c. Times are CPU seconds
of this process (``time.process_time``), so other work on the machine counts less.
The tools take turns within every repetition (interleaved), so slow phases of the
machine fall on all of them alike.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import dataclass

TARGET_SECONDS = 0.05      # aimed CPU time of the k-step run
MAX_STEPS = 2000
MIN_STEPS = 5


@dataclass
class Timing:
    tool: str
    steps: int               # k
    per_step: float          # s, seconds per step
    setup: float             # c, seconds per run outside the steps
    spread: float            # relative half-range of the k-step runs' times


def cpu_time(run, *args) -> float:
    start = time.process_time()
    run(*args)
    return time.process_time() - start


def calibrate(model, probe: int = 10, max_steps: int = MAX_STEPS) -> int:
    """k such that a k-step run takes about TARGET_SECONDS (after a warm-up run), at
    most max_steps."""
    model.advance(probe)
    per_step = max((cpu_time(model.advance, 2 * probe) - cpu_time(model.advance, probe))
                   / probe, 1e-7)
    return int(min(max_steps, max(MIN_STEPS, round(TARGET_SECONDS / per_step))))


def time_interleaved(models: dict, reps: int, max_steps: int = MAX_STEPS,
                     fixed_steps: int | None = None) -> dict[str, Timing]:
    """{tool: Timing} of models {tool: model with advance(n_steps)}; k at most
    max_steps (the long runs: 2 max_steps steps), or k = fixed_steps for every tool
    (after a warm-up run of a few steps): then all of them time the same span of the
    motion, steps k+1 .. 2k."""
    if fixed_steps is None:
        steps = {tool: calibrate(m, max_steps=max_steps) for tool, m in models.items()}
    else:
        for m in models.values():
            m.advance(MIN_STEPS)
        steps = dict.fromkeys(models, fixed_steps)
    short = {tool: [] for tool in models}
    long = {tool: [] for tool in models}
    for _ in range(reps):
        for tool, m in models.items():
            short[tool].append(cpu_time(m.advance, steps[tool]))
            long[tool].append(cpu_time(m.advance, 2 * steps[tool]))
    out = {}
    for tool in models:
        k, t1, t2 = steps[tool], statistics.median(short[tool]), statistics.median(long[tool])
        per_step = max(t2 - t1, 0.0) / k
        spread = (max(short[tool]) - min(short[tool])) / (2 * t1) if t1 > 0 else 0.0
        out[tool] = Timing(tool, k, per_step, max(t1 - k * per_step, 0.0), spread)
    return out
