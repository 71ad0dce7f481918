"""How the command line shows progress (``fccgen.progress`` events) on stderr.

- stderr is a terminal (and no ``--quiet``): a tqdm bar per stage with a known total
  (derivation, printing, a run, bench, the accuracy ladder and reference runs, a sweep)
  showing the fraction, elapsed time, rate and time left; a stage without a total
  (compiling) shows its message and a clock that keeps ticking. A bar is cleared when
  its stage ends, when anything is written to stdout, and when the command ends, so
  no progress line is left on the screen.
- stderr is not a terminal (a log file, a pipe), or a terminal that cannot draw a bar
  (``TERM=dumb``, or one that reports 0 columns, as some CI consoles and editors'
  terminals do): plain lines ``fccgen: message``; a stage message always, a progress
  report when it begins a stage or at least 5 s after the last line.
- ``--quiet``: nothing.
"""
from __future__ import annotations

import os
import sys
import threading
import time

from . import ProgressEvent

LOG_INTERVAL = 5.0          # seconds between progress lines when not on a terminal
TICK = 0.5                  # seconds between redraws of a bar without a total


def write_line(text: str, stream=None) -> None:
    """Write one line to stderr without breaking a progress bar drawn there."""
    stream = stream or sys.stderr
    tqdm = sys.modules.get("tqdm")
    if tqdm is not None:
        tqdm.tqdm.write(text, file=stream)
    else:
        stream.write(text + "\n")
    stream.flush()


class ProgressDisplay:
    """The progress callback of the command line (see the module docstring)."""

    reads_only = True       # it writes text and never calls the solver (reads_only())

    def __init__(self, quiet: bool, stream=None):
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.bars = not quiet and _can_draw(self.stream) and _tqdm() is not None
        self.last = 0.0             # when the last line was written (log mode)
        self.stage = None           # the stage of the last line (log mode)
        self.bar = None             # (stage, tqdm) on a terminal
        self._ticker = None
        self._stdout = None

    # -- the callback ----------------------------------------------------------------
    def __call__(self, event) -> None:
        if self.quiet:
            return
        if not isinstance(event, ProgressEvent):
            event = ProgressEvent(str(event), "")
        if self.bars:
            self._draw(event)
        else:
            self._log(event)

    def _log(self, event: ProgressEvent) -> None:
        now = time.monotonic()
        report = event.done is not None
        if report and event.stage == self.stage and now - self.last < LOG_INTERVAL:
            return
        self.last, self.stage = now, event.stage
        self.stream.write(f"fccgen: {event}\n")
        self.stream.flush()

    def _draw(self, event: ProgressEvent) -> None:
        tqdm = _tqdm()
        known = event.total is not None and event.done is not None
        stage, bar = self.bar or (None, None)
        if bar is None or stage != event.stage or (known != (bar.total is not None)):
            self.close_line()
            self._redirect_stdout()
            if known:
                bar = tqdm(total=event.total, desc=event.stage, leave=False,
                           file=self.stream, unit=_unit(event), dynamic_ncols=True,
                           bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.4g}/"
                                      "{total:.4g} [{elapsed}<{remaining}, {rate_fmt}]")
            else:
                bar = tqdm(total=None, desc=str(event), leave=False, file=self.stream,
                           dynamic_ncols=True, bar_format="{desc} [{elapsed}]")
                self._start_ticker(bar)
            self.bar = (event.stage, bar)
        if known:
            bar.update(max(float(event.done) - bar.n, 0.0))
            if event.done >= event.total:
                self.close_line()
        else:
            bar.set_description_str(str(event))

    # -- ending ------------------------------------------------------------------------
    def close_line(self) -> None:
        """Clear the bar on the screen, if any (before a final message)."""
        if self._ticker is not None:
            self._ticker.set()
            self._ticker = None
        if self.bar is not None:
            self.bar[1].close()
            self.bar = None

    def close(self) -> None:
        """End of the command: clear the bar and give stdout back."""
        self.close_line()
        if self._stdout is not None:
            sys.stdout = self._stdout
            self._stdout = None

    # -- helpers -----------------------------------------------------------------------
    def _start_ticker(self, bar) -> None:
        """Redraw ``bar`` every TICK seconds so its clock runs during a long stage."""
        stop = threading.Event()

        def tick():
            while not stop.wait(TICK):
                bar.refresh()
        threading.Thread(target=tick, daemon=True, name="fccgen-progress").start()
        self._ticker = stop

    def _redirect_stdout(self) -> None:
        """Clear the bar before anything is written to stdout (the same terminal)."""
        if self._stdout is None:
            self._stdout = sys.stdout
            sys.stdout = _ClearingStream(self._stdout, self)


class _ClearingStream:
    """stdout that clears the progress bar before each write."""

    def __init__(self, stream, display: ProgressDisplay):
        self._stream = stream
        self._display = display

    def write(self, text):
        if text:
            self._display.close_line()
        return self._stream.write(text)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _can_draw(stream) -> bool:
    """Whether ``stream`` is a terminal that can redraw a bar in place: not dumb, and
    at least one column wide (a width of 0 means the terminal does not say)."""
    if not _isatty(stream) or os.environ.get("TERM", "") == "dumb":
        return False
    return _columns(stream) != 0


def _columns(stream) -> int | None:
    """The terminal's width in columns, None when the stream has no terminal size."""
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, ValueError, OSError):
        return None


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def _tqdm():
    """tqdm's bar class, or None when tqdm is not installed (then: plain lines)."""
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm


def _unit(event: ProgressEvent) -> str:
    """Simulated seconds for runs, else what the stage counts."""
    if event.t is not None:
        return "s"
    return {"sweep": "run", "accuracy": "run", "bench": "step", "derive": "class",
            "print": "class"}.get(event.stage, "it")
