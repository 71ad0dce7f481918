"""The scissor boom example (examples/scissor_boom.yaml, written by
examples/make_scissor_boom.py): 12 units deployed by torsion springs and latched at full
length by a lock event on the pivot X0, in one compiled run. Before the latch: one
degree of freedom by rank, energy conserved, the motion symmetric about x with equal
units. At the latch: its time against the boom's energy equation in the bar angle, a
plastic impact that takes all the kinetic energy (0 DOF). After it: the boom held at
full length to the end."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from conftest import EXAMPLES, example_module

N = 12
T_END = 2.0          # s: the latch is at 1.48 s, so a quarter of the run is latched


def generator():
    return example_module("make_scissor_boom")


@pytest.fixture(scope="module")
def boom(compiled):
    """The example run to T_END with its own settings (RK4, dt = 1 ms) and the generator."""
    return compiled("scissor_boom").simulate(t_end=T_END), generator()


def latch_time(g) -> float:
    """The time the unlatched boom takes from rest at FOLDED to LATCH, from its energy
    equation in the bar angle b (minimal coordinate; every bar turns by +-b', its
    centre moves along x at (k + 1/2) d(L cos b)/dt):
        T = m(b) b'^2 / 2,  m(b) = 2 N I + 2 M L^2 sin^2 b sum_k (k + 1/2)^2,
        sum_{k<N} (k + 1/2)^2 = N (4 N^2 - 1) / 12,  I = M L^2 / 12,
        V(b) = 2 N k (b - b_free)^2   (each pivot turns by 2 (b_0 - b)),
        T + V = V(b_0)  =>  t = int_{b_latch}^{b_0} sqrt(m(b) / (2 (V(b_0) - V(b)))) db,
    with V(b_0) - V(b) = 2 N k (b_0 - b)(b_0 + b - 2 b_free): the 1/sqrt(b_0 - b) end
    is QUADPACK's algebraic weight, so the integral is good to rounding."""
    b0, bf, bl = (math.radians(x) for x in (g.FOLDED, g.FREE, g.LATCH))
    inertia = g.MASS * g.LENGTH ** 2 / 12.0
    sum_k = N * (4 * N * N - 1) / 12.0

    def f(b):
        m = 2 * N * inertia + 2 * g.MASS * g.LENGTH ** 2 * math.sin(b) ** 2 * sum_k
        return math.sqrt(m / (4 * N * g.STIFFNESS * (b0 + b - 2 * bf)))
    t, _ = quad(f, bl, b0, weight="alg", wvar=(0.0, -0.5), epsabs=1e-14, epsrel=1e-14)
    return t


def test_file_is_the_generator_output():
    """The committed example is what examples/make_scissor_boom.py writes for N = 12,
    and its latch-free form (``latch=False``) has no event and spherical pivots only."""
    g = generator()
    assert g.model_text(12) == (EXAMPLES / "scissor_boom.yaml").read_text()
    free = g.model_text(12, latch=False)
    assert "events:" not in free and "revolute" not in free
    assert "X0.angle >= 100*pi/180" in g.model_text(12)


@pytest.mark.parametrize("latch", [True, False])
def test_header_counts_are_those_of_fccgen_check(tmp_path, latch):
    """The counts the header states (coordinates, equations, rank, 1 DOF) are what
    ``fccgen check`` finds, with the revolute X0 (three redundant axis rows on b0) and
    without, on a 3-unit boom (cheap: no compiler)."""
    import re

    from fccgen.diagnostics.check import check_model
    text = generator().model_text(3, latch=latch)
    path = tmp_path / "boom3.yaml"
    path.write_text(text)
    report = check_model(path)
    nq, ng, rank = map(int, re.search(r"Coordinates (\d+), constraint equations (\d+), "
                                      r"rank (\d+)", text).groups())
    assert (report.n_q, report.n_g, report.rank, report.dof) == (nq, ng, rank, 1)


def test_before_the_latch_one_freedom_energy_and_symmetry(boom):
    """1 degree of freedom by rank; no damping and no gravity, so the energy (kinetic +
    spring) stays at its start to the RK4 error until the latch (measured 2.4e-11 J of
    131.6 J over 1.48 s; 1e-8 allowed). Through the whole run, latch included, the base
    holds the boom symmetric about x, so top and bottom nodes mirror each other, and
    one degree of freedom makes every unit equally wide: both to rounding (measured
    1.8e-13 m; 1e-10 allowed). The springs deploy it: the tip moves out."""
    r, _ = boom
    assert r.info["dof"] == 1
    before = r.t < r.events[0]["t"]
    e = r["energy"][before]
    assert np.abs(e - e[0]).max() < 1e-8
    mirror = max(np.abs(r[f"T{k}.y"] + r[f"B{k}.y"]).max() for k in range(N + 1))
    aligned = max(np.abs(r[f"T{k}.x"] - r[f"B{k}.x"]).max() for k in range(N + 1))
    equal = max(np.abs(r[f"T{k}.x"] - k * r["T1.x"]).max() for k in range(N + 1))
    assert max(mirror, aligned, equal) < 1e-10
    assert r["T12.x"][-1] > r["T12.x"][0] + 8.0
    assert not r.info["reactions"]["computed"]          # shared end nodes (section 2)


def test_latch_time_and_impact_against_the_energy_equation(boom):
    """One lock, at the time the energy equation gives: the located time's error is
    the root finder's bracket (event_tol, 1e-12 s) plus the RK4 phase error, which is
    smaller here (measured -7.7e-13, 4.0e-14, 8.8e-13 s at dt = 2, 1, 0.5 ms: the
    bracket, not the step, sets it); 1e-11 s allowed. Just before it the
    kinetic energy is the springs' energy released, V(80 deg) - V(30 deg) = 73.108 J,
    to the energy drift plus dV/dangle (168 J/rad) times the located angle's error
    (4 rad/s x 1e-12 s; measured 2.3e-13 J, 1e-9 J allowed). The boom has 1 DOF and the
    lock adds one row, so the plastic impact leaves nothing: DOF 0, kinetic energy after
    at rounding (measured 6e-30 J; 1e-18 J allowed: speeds of 1e-9 m/s) and the energy
    lost equals the kinetic energy before it (measured 9e-13 J apart; 1e-9 J allowed).
    The impulse is positive and the constraint error after small (measured 2.3e-13;
    1e-10 allowed)."""
    r, g = boom
    assert [(e["name"], e["action"], e["dof"]) for e in r.events] == [("latch", "lock", 0)]
    row = r.events[0]
    assert abs(row["t"] - latch_time(g)) < 1e-11
    released = g.spring_energy(N, g.FOLDED) - g.spring_energy(N, g.LATCH)
    assert abs(released - 73.108) < 1e-3                  # the header's figure
    assert abs(row["kinetic_energy_before"] - released) < 1e-9
    assert 0.0 <= row["kinetic_energy_after"] < 1e-18
    after = r.t > row["t"]
    lost = r["energy"][0] - r["energy"][after][0]
    assert abs(lost - row["kinetic_energy_before"]) < 1e-9
    assert row["impulse"] > 1.0
    assert row["constraint_error"] < 1e-10
    # The run's energy drift adds the latch's loss back (fccgen.events.table.
    # energy_balance): it is the integration's drift over the whole run (the 2.4e-11 J
    # before the latch, rounding after it), not the 73 J the latch took.
    assert r.info["event_energy_loss"] == pytest.approx(row["kinetic_energy_before"], abs=1e-18)
    assert r.info["energy_drift"] < 1e-8
    assert (r.info["dof"], r.info["final_dof"]) == (1, 0)  # the run ends latched


def test_after_the_latch_the_boom_stays_at_full_length(boom):
    """From the latch to the end the pivot angle stays at 2 (80 - 30) deg and every
    node stays put: the lock holds the angle at its value at the located time, whose
    error is at most the angle rate times event_tol (4 rad/s x 1e-12 s), and the tip's
    x moves by N L sin(30 deg) = 6 m per rad of it (measured 2.2e-16 rad and 1.1e-12 m;
    1e-10 allowed). Every speed is rounding (measured below 1e-30; 1e-12 allowed) and
    the energy stays the springs' energy at full length, V(30 deg) = 58.49 J."""
    r, g = boom
    after = r.t > r.events[0]["t"]
    assert after.sum() > 40                               # half a second of output
    assert np.abs(r["X0.angle"][after] - g.latch_angle()).max() < 1e-10
    full = N * g.LENGTH * math.cos(math.radians(g.LATCH))
    assert np.abs(r["T12.x"][after] - full).max() < 1e-10
    speeds = max(np.abs(r[f"{p}{k}.v{a}"][after]).max()
                 for p in "TB" for k in range(N + 1) for a in "xy")
    assert speeds < 1e-12 and np.abs(r["X0.rate"][after]).max() < 1e-12
    assert np.abs(r["energy"][after] - g.spring_energy(N, g.LATCH)).max() < 1e-9
