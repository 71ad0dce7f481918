"""Structured progress of long work (builds, runs, benchmarks, sweeps).

Every ``progress=`` callback of the Python API is called with one argument, a
:class:`ProgressEvent`. The event *is* the one-line message (a ``str`` subclass), so a
callback written for text (``print``, ``list.append``, ``message.startswith(...)``)
keeps working; a callback that wants numbers reads its fields:

    stage     what is going on: "derive", "print", "render", "compile", "cache",
              "simulate", "reference", "bench", "accuracy", "sweep", ...
    done      how far it is, in the unit of ``total`` (None: a stage message)
    total     where it ends: simulated seconds for "simulate", runs for "sweep",
              classes for "derive"/"print" (None: unknown)
    t         the simulated time, for runs (None otherwise)
    elapsed   wall seconds since the stage started

``fraction`` is ``done / total`` when both are known. Example::

    def show(event):
        if event.fraction is not None:
            print(f"{event.stage}: {100 * event.fraction:.0f}% after {event.elapsed:.1f} s")
    fccgen.simulate("examples/double_pendulum.yaml", progress=show)
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable


@dataclass(frozen=True, eq=False, repr=True)
class ProgressEvent(str):
    """One report of progress; the string value is ``message`` (see the module
    docstring). Equality and hashing are those of the message text."""
    message: str
    stage: str
    done: float | None = None
    total: float | None = None
    t: float | None = None
    elapsed: float = 0.0

    def __new__(cls, message, *args, **kwargs):
        return str.__new__(cls, message)

    def __reduce__(self):
        return (type(self), (self.message, self.stage, self.done, self.total, self.t,
                             self.elapsed))

    @property
    def fraction(self) -> float | None:
        """done / total, in [0, 1], when both are known."""
        if self.done is None or not self.total:
            return None
        return min(max(self.done / self.total, 0.0), 1.0)

    def with_stage(self, stage: str) -> "ProgressEvent":
        return replace(self, stage=stage)


Progress = Callable[[ProgressEvent], None] | None


class Reporter:
    """Reports to a progress callback (which may be None), keeping each stage's start
    time for ``elapsed``; ``stage`` and ``total`` are defaults for every report::

        report = Reporter(progress, "sweep", total=20)
        report("sweep: 3 of 20 runs done", done=3)
        report("compiling", stage="compile")         # another stage, its own clock
    """

    def __init__(self, progress: Progress, stage: str = "", total: float | None = None):
        self.progress = progress
        self.stage = stage
        self.total = total
        self.starts: dict[str, float] = {}

    def __call__(self, message: str, *, stage: str | None = None,
                 done: float | None = None, total: float | None = None,
                 t: float | None = None) -> None:
        if self.progress is None:
            return
        stage = self.stage if stage is None else stage
        now = time.perf_counter()
        start = self.starts.setdefault(stage, now)
        self.progress(ProgressEvent(message, stage, done,
                                    self.total if total is None else total, t, now - start))


def reads_only(progress) -> bool:
    """Whether a progress callback promised (its attribute ``reads_only``) not to call
    the solver that reports to it: a run then keeps the engine's factorisation across
    the callback, and its numbers are those of a run without the callback. Any other
    callback may use the solver (its engine's factorisation, its warm starts): the step
    after it factorises afresh, which can move the last digits of the run (more where
    the run passes near a singular position)."""
    return bool(getattr(progress, "reads_only", False))


def restaged(progress: Progress, stage: str) -> Progress:
    """A callback that passes ``progress`` the same events under another stage name
    (e.g. the runs of the accuracy reference under "reference")."""
    if progress is None:
        return None

    def forward(event):
        if isinstance(event, ProgressEvent):
            event = event.with_stage(stage)
        else:
            event = ProgressEvent(str(event), stage)
        progress(event)
    forward.reads_only = reads_only(progress)
    return forward


class RunReporter:
    """``report(t)`` for an integrator's pauses: an event "t = ... of ... (..%)" with
    done = t, total = t_end; ``finish(t)`` reports the end of a run that has reported
    before (a short, silent run stays silent)."""

    def __init__(self, progress, t_end: float, stage: str = "simulate"):
        self.t_end = float(t_end)
        self.reporter = Reporter(progress, stage, total=self.t_end)
        self.reported = False
        self.reads_only = reads_only(progress)     # see reads_only()

    def __call__(self, t) -> None:
        t = float(t)
        self.reported = True
        self.reporter(f"t = {t:.6g} of {self.t_end:.6g} ({100.0 * t / self.t_end:.0f}%)",
                      done=t, t=t)

    def finish(self, t) -> None:
        if self.reported:
            self(t)


def run_reporter(progress: Progress, t_end: float, stage: str = "simulate"):
    """A :class:`RunReporter`, or None when ``progress`` is None."""
    return None if progress is None else RunReporter(progress, t_end, stage)
