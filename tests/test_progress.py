"""Progress of long work: structured events for Python callbacks (still usable as the
text they were before), a bar with a time estimate on a terminal that is cleared when
done, plain lines in a log, nothing with --quiet."""
from __future__ import annotations

import io
import os
import pickle
import sys

import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.progress.terminal import LOG_INTERVAL, ProgressDisplay
from fccgen.progress import ProgressEvent, Reporter, restaged, run_reporter

DOUBLE = EXAMPLES / "double_pendulum.yaml"
# the command line in a child whose runs pause (and report) after every step
CHILD_EVERY_STEP = ("import sys; from fccgen.runtime.solver import CompiledSolver; "
                    "CompiledSolver.progress_interval = 0.0; from fccgen.cli import main; "
                    "sys.exit(main(sys.argv[1:]))")


class Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.fixture(autouse=True)
def drawing_terminal(monkeypatch):
    """The fake terminal draws bars whatever TERM the tests run under."""
    monkeypatch.setenv("TERM", "xterm")


def test_an_event_is_its_message_and_carries_numbers():
    e = ProgressEvent("t = 1 of 4 (25%)", "simulate", 1.0, 4.0, 1.0, 0.5)
    assert e == "t = 1 of 4 (25%)" and e.startswith("t = ") and f"{e}" == e.message
    assert (e.stage, e.done, e.total, e.t, e.elapsed, e.fraction) == (
        "simulate", 1.0, 4.0, 1.0, 0.5, 0.25)
    assert ProgressEvent("compiling", "compile").fraction is None
    back = pickle.loads(pickle.dumps(e))
    assert back == e and back.total == 4.0 and type(back) is ProgressEvent
    assert e.with_stage("reference").stage == "reference" and e.stage == "simulate"


def test_reporter_keeps_a_clock_per_stage_and_forwards_under_another_name():
    seen = []
    report = Reporter(restaged(seen.append, "renamed"), "sweep", total=3)
    report("a", done=1)
    report("b", stage="other")
    assert [(e.stage, e.done, e.total) for e in seen] == [("renamed", 1, 3),
                                                         ("renamed", None, 3)]
    assert all(e.elapsed >= 0.0 for e in seen)
    Reporter(None, "x")("nobody listens")                 # no callback: no error
    quiet = run_reporter(seen.append, 2.0)
    quiet.finish(2.0)                   # a run that never paused stays silent
    assert len(seen) == 2


@pytest.mark.parametrize("method", ["rk4", "dopri5", "ali3p", "baumgarte"])
def test_a_run_reports_its_simulated_time(compiled, monkeypatch, method):
    """A run that pauses after every step (progress_interval 0, so that no machine is
    too fast for it): events of stage 'simulate' with done = t rising to total =
    t_end, the last one at t_end."""
    solver = compiled("double_pendulum")
    monkeypatch.setattr(solver, "progress_interval", 0.0)
    seen = []
    solver.simulate(t_end=2.0, output_dt=0.5, method=method, progress=seen.append)
    assert len(seen) >= 3
    assert all(isinstance(e, ProgressEvent) and e.stage == "simulate" for e in seen)
    assert [e.total for e in seen] == [2.0] * len(seen)
    done = [e.done for e in seen]
    assert done == sorted(done) and done[-1] == 2.0 and seen[-1].fraction == 1.0
    assert seen[-1].startswith("t = 2 of 2")
    assert [e.elapsed for e in seen] == sorted(e.elapsed for e in seen)


def events(stage, total, n):
    return [ProgressEvent(f"{stage} {k}", stage, float(k), float(total), None, 0.1 * k)
            for k in range(n)]


def test_a_terminal_gets_a_bar_that_is_cleared():
    screen = Terminal()
    display = ProgressDisplay(quiet=False, stream=screen)
    assert display.bars
    for e in events("sweep", 20, 5):
        display(e)
    drawn = screen.getvalue()
    assert "sweep:" in drawn and "/20" in drawn and "<" in drawn    # elapsed<remaining
    display.close()
    last = screen.getvalue().rsplit("\r", 1)[-1]
    assert last.strip() == "" and "\n" not in screen.getvalue()     # nothing left


def test_a_bar_ends_with_its_stage_and_before_stdout(monkeypatch):
    screen, out = Terminal(), io.StringIO()
    monkeypatch.setattr(sys, "stdout", out)
    display = ProgressDisplay(quiet=False, stream=screen)
    display(ProgressEvent("compiling m", "compile"))
    assert display.bar is not None and "compiling m" in screen.getvalue()
    print("result line")                     # what a command prints when it is done
    assert display.bar is None and out.getvalue() == "result line\n"
    display(ProgressEvent("t = 2 of 2", "simulate", 2.0, 2.0, 2.0, 1.0))
    assert display.bar is None                 # done == total: the stage has ended
    display.close()
    assert sys.stdout is out


def test_a_log_gets_lines_at_most_every_few_seconds(monkeypatch):
    log = io.StringIO()
    display = ProgressDisplay(quiet=False, stream=log)
    assert not display.bars
    clock = iter([0.0, 1.0, 2.0, LOG_INTERVAL + 1.0, LOG_INTERVAL + 2.0])
    monkeypatch.setattr("fccgen.progress.terminal.time.monotonic", lambda: next(clock))
    display(ProgressEvent("compiling m", "compile"))          # a stage message: shown
    for e in events("simulate", 10, 4):                       # first shown, then 5 s
        display(e)
    assert log.getvalue().splitlines() == ["fccgen: compiling m", "fccgen: simulate 0",
                                           "fccgen: simulate 2"]


@pytest.mark.parametrize("term, columns", [("dumb", 80), ("xterm", 0)])
def test_a_terminal_that_cannot_draw_gets_plain_lines(monkeypatch, term, columns):
    """TERM=dumb, or a terminal that reports 0 columns: the lines of a log, not
    nothing and not a bar."""
    monkeypatch.setenv("TERM", term)
    monkeypatch.setattr("fccgen.progress.terminal._columns", lambda stream: columns)
    screen = Terminal()
    display = ProgressDisplay(quiet=False, stream=screen)
    assert not display.bars
    display(ProgressEvent("compiling m", "compile"))
    display(events("simulate", 10, 1)[0])
    display.close()
    assert screen.getvalue().splitlines() == ["fccgen: compiling m", "fccgen: simulate 0"]


def test_quiet_shows_nothing():
    screen = Terminal()
    display = ProgressDisplay(quiet=True, stream=screen)
    for e in events("sweep", 3, 3):
        display(e)
    display.close()
    assert screen.getvalue() == ""


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_the_command_draws_and_clears_a_bar_on_a_terminal(build_dir, tmp_path):
    """fccgen simulate with stderr on a pseudo-terminal (100 columns): a bar with the
    time left, then nothing of it on the last line; stdout unchanged.

    The child runs the command with the solver's progress_interval at 0, so the run
    pauses and reports after every step: the bar is drawn whatever the machine's speed
    or load (a run sized from a timing drew no bar when the child ran much faster than
    the parent had measured)."""
    import fcntl
    import struct
    import subprocess
    import termios
    import threading
    fccgen.load(DOUBLE, build_dir)                             # built: no compile here
    t_end = 2                                                  # 2000 steps, 2000 reports
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    chunks = []

    def read_screen():
        while True:
            try:
                data = os.read(master, 65536)
            except OSError:                      # EIO: the terminal's last writer left
                return
            if not data:
                return
            chunks.append(data)
    reader = threading.Thread(target=read_screen)
    reader.start()
    package_parent = os.path.dirname(os.path.dirname(fccgen.__file__))
    env = {**os.environ, "PYTHONPATH": package_parent}
    try:
        proc = subprocess.Popen(
            [sys.executable, "-c", CHILD_EVERY_STEP, "simulate", str(DOUBLE),
             "--build-dir", str(build_dir), "--t-end", str(t_end), "--output-dt", "1"],
            stdout=subprocess.PIPE, stderr=slave, cwd=tmp_path, env=env, text=True)
    finally:
        os.close(slave)
    out, _ = proc.communicate(timeout=300)     # a guard against a hang, not a timing
    reader.join(timeout=60)
    os.close(master)
    screen = b"".join(chunks).decode("utf-8", "replace")
    assert proc.returncode == 0, screen
    assert f"rk4: {1000 * t_end} steps" in out                 # dt 1e-3
    assert "simulate:" in screen and "s/s]" in screen, screen
    assert screen.rsplit("\r", 1)[-1].strip() == "", screen
