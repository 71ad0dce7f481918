"""The solar-array boom (examples/solar_array_boom.yaml, docs/flexible.md): a hinge
fitting deployed by a torsion spring and latched by a lock event, with a flexible
boom clamped to it, in one compiled run: it deploys, latches once, and rings down at
the first bending frequency and damping ratio that ``fccgen modes`` gives for the
latched state (examples/solar_array_boom_latched.yaml)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fccgen.analysis import linearize, modes, statics


@pytest.fixture(scope="module")
def run(compiled):
    solver = compiled("solar_array_boom")
    return solver, solver.simulate()


@pytest.fixture(scope="module")
def latched(compiled):
    solver = compiled("solar_array_boom_latched")
    return modes(linearize(solver, statics(solver).q))


def ringing(result, after: float):
    """(frequency, damping ratio) of the boom tip's y motion after ``after``: the
    frequency from the zero crossings (linear interpolation between outputs), the
    damping ratio from the decay of the half-cycle peaks, ln(A0/An) / (pi n)."""
    t, y = result.t, result["boom.tip.y"]
    keep = t > after
    t, y = t[keep], y[keep]
    k = np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0)
    crossings = t[k] - y[k] * (t[k + 1] - t[k]) / (y[k + 1] - y[k])
    frequency = (len(crossings) - 1) / (2.0 * (crossings[-1] - crossings[0]))
    peaks = [np.max(np.abs(y[(t >= a) & (t < b)])) for a, b in zip(crossings, crossings[1:])]
    zeta = math.log(peaks[0] / peaks[-1]) / (math.pi * (len(peaks) - 1))
    return frequency, zeta


def test_deploys_and_latches_once(run):
    solver, result = run
    assert [e["name"] for e in result.events] == ["latch"]
    latch = result.events[0]
    assert 0.5 < latch["t"] < 2.0
    after = result.t > latch["t"]
    assert np.allclose(result["R.angle"][after], math.pi / 2, atol=1e-9)
    assert result.info["energy_check"]["conservative"] is False     # a damped boom


def test_rings_down_at_the_latched_first_mode(run, latched):
    """Zero crossings of the tip over the last 1.2 s (10 periods, from 0.2 s after the
    latch, when the second mode, damped at 3 % of critical, has died out) against the
    first mode of the latched state: frequency within 0.2 % (measured 3e-5: the
    amplitude, 5 % of the length, hardens the mode by less than 1e-4) and damping ratio
    within 5 % of its value (measured 0.6 %: the decay read from peaks at output
    times 1 ms apart)."""
    _, result = run
    frequency, zeta = ringing(result, result.events[0]["t"] + 0.2)
    first = latched.frequency_hz[0]
    assert frequency == pytest.approx(first, rel=2e-3)
    assert zeta == pytest.approx(latched.damping_ratio[0], rel=5e-2)
    assert 8.0 < first < 9.5                            # the example's 8.8 Hz


def test_latched_model_is_the_same_member(compiled):
    """The latched model's boom is the deployment model's (numbers and mesh), clamped
    where the latch holds it: the two files cannot drift apart."""
    a = compiled("solar_array_boom").plan.model.cables["boom"]
    b = compiled("solar_array_boom_latched").plan.model.cables["boom"]
    for key in ("elements", "EA", "EI", "mass_per_length", "damping", "length"):
        assert getattr(a, key) == getattr(b, key), key
    assert b.ends[0].at == pytest.approx((0.2, 0.0, 0.0))
    assert b.ends[1].at == pytest.approx((2.2, 0.0, 0.0))
