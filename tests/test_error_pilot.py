"""The pilot's rungs (fccgen.target_error.ladder): the third rung lies on the side of
the choice, a coarser rung that fails gives way to a finer one, and fixed steps
coarser than the pilot's output interval record on the multiples of it they divide
(the accuracy the choices reach: test_error_target.py)."""
from __future__ import annotations

import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from fccgen.errors import FccgenError, RunWarning
from fccgen.target_error import ladder
from fccgen.target_error.ladder import recording_interval
from fccgen.target_error.pilot import Fit, Pilot

SHORT = dict(t_end=1.0, output_dt=0.01)
# rk4 alone over 1 s of the double pendulum: with no dopri5 steps to start from, its
# pair is a sixteenth and an eighth of the 10 ms output interval
PAIR = [1.25e-3, 6.25e-4]


@pytest.fixture(scope="module")
def double(compiled):
    return compiled("double_pendulum")


def rk4_to(solver, error=1e-5):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        result = solver.simulate(error=error, method="rk4", **SHORT)
    [fit] = result.info["accuracy"]["candidates"]
    return result, fit


def test_a_fixed_step_records_on_the_multiples_of_the_output_interval_it_divides():
    assert recording_interval(0.01, 0.005) == 0.01
    assert recording_interval(0.01, 0.02) == pytest.approx(0.02)
    assert recording_interval(0.01, 0.015) == pytest.approx(0.03)
    # A02's first 0.6 s: the pilot records every 0.05 / 9 s, its coarse rk4 rung
    # steps twice that
    assert recording_interval(0.05 / 9, 0.1 / 9) == pytest.approx(0.1 / 9)
    with pytest.raises(ValueError, match="shares no output time"):
        recording_interval(0.01, 0.01 * math.pi)


def test_the_third_rung_lies_coarser_when_the_pair_places_the_choice_above_it(double):
    result, fit = rk4_to(double)
    steps = [r[0] for r in fit["rungs"]]
    # the pair's error places the choice at the output interval, far above its finer
    # step: the third rung doubles the coarse step rather than halving the fine one
    assert steps == pytest.approx([2 * PAIR[0], *PAIR])
    assert fit["status"] == "ok" and fit["judged_by"] == "rungs"
    # the choice goes beyond four times the pair's coarse step (choice.EXTRAPOLATION),
    # which the coarser rung measured
    dt = result.info["dt"]
    assert dt == pytest.approx(0.01) and dt > 4 * PAIR[0]
    # each rung's cost is counted once in the pilot's (the rungs record theirs)
    assert result.info["accuracy"]["cost"]["pilot"] == pytest.approx(
        sum(r[1] for r in fit["rungs"]))


class _LeftTheMotion:
    """A run whose compared columns are not finite (it diverged without raising)."""

    def __init__(self, result):
        self._result = result
        self.t, self.info, self.columns = result.t, result.info, result.columns
        self.events = result.events

    def __getitem__(self, name):
        return np.full(len(self.t), np.nan)


@pytest.mark.parametrize("how", ["raises", "diverges"])
def test_a_coarser_rung_that_fails_gives_way_to_the_finer_one(double, monkeypatch, how):
    real = Pilot.run

    def run(self, method, setting, t_end, output_dt=None, stage="pilot"):
        if stage == "pilot" and setting > 2 * PAIR[0] * (1 - 1e-9):
            if how == "raises":
                raise FccgenError(f"the state is not finite at dt = {setting:g}")
            return _LeftTheMotion(real(self, method, setting, t_end, output_dt, stage))
        return real(self, method, setting, t_end, output_dt, stage)

    monkeypatch.setattr(Pilot, "run", run)
    result, fit = rk4_to(double)
    assert [r[0] for r in fit["rungs"]] == pytest.approx([*PAIR, PAIR[1] / 2])
    assert fit["status"] == "ok"
    assert "a coarser rung failed" in fit["note"] and "a finer one ran" in fit["note"]
    # the pair measured, the choice holds to four times its coarse step
    assert result.info["dt"] <= 4 * PAIR[0] + 1e-12
    assert result.info["error_estimate"] <= 1e-5


@pytest.mark.parametrize("method, kappa, order", [("dopri5", 16.0, 1.0), ("rk4", 2.0, 4.0)])
def test_a_pairs_difference_is_the_error_of_its_coarser_rung(monkeypatch, method, kappa,
                                                              order):
    """The provisional choice from a pair alone: with errors C s^a, rungs at kappa s and
    s differ by C s^a (kappa^a - 1), and the setting that meets E is (E / C)^(1/a)."""
    C, s, E = 1e-3, 1e-2 if method == "rk4" else 1e-8, 1e-12
    t = np.linspace(0.0, 1.0, 11)
    d = C * s ** order * (kappa ** order - 1) * t        # grows like t over the piece
    monkeypatch.setattr(ladder, "distance", lambda a, b, what, t_end: (t, d))
    pilot = SimpleNamespace(noise=1e-18, length_scale=1.0, what=None)
    fit = Fit(method, "rtol" if method == "dopri5" else "dt", 1.0,
              rungs=[(kappa * s, 10.0, 1, 0), (s, 20.0, 2, 0)])
    # aimed at the end of the piece, where the growth adds nothing
    found = ladder._provisional(fit, pilot, [None, None], (E, 1.0))
    assert found == pytest.approx((E / C) ** (1 / order), rel=1e-9)
