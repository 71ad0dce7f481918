"""Stability at the extremes, part 2: stiff springs, long runs, a singular
configuration with redundant constraints, and high spin. Each case is either right
or a clear error, never a silent NaN. Measured figures are in docs/extremes.md."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import minimal
import test_extremes_models as em
from fccgen.errors import RunWarning, SimulationError

IMPLICIT = "ali3p"


@pytest.fixture(scope="module")
def load(tmp_path_factory, build_dir):
    return em.make_loader(tmp_path_factory.mktemp("extremes_dynamics"), build_dir)


def columns(r, *names):
    return np.column_stack([r[n] for n in names])


def available_methods() -> tuple[str, ...]:
    """The methods the compiled solver accepts (the registry's, less those whose
    optional compiled module is not built)."""
    from fccgen.runtime.solver import METHODS
    return tuple(METHODS)


# -- 4. stiff spring ---------------------------------------------------------------------

DT, V0 = 1e-3, 0.01


def spring_omega(stiffness_ratio):
    """Angular frequency of the spring pendulum: k/m from k dt^2/m, plus g/L."""
    return math.sqrt(stiffness_ratio / DT**2 + 9.81)


def oscillation_energy(r):
    """Energy above the hanging rest state: kinetic plus the spring's (exactly the
    total energy minus the potential of gravity at rest, -m g L = -9.81)."""
    return r["energy"] + 9.81


@pytest.mark.parametrize("stiffness_ratio", [1e-2, 1.0])
def test_rk4_inside_its_stability_interval_keeps_the_spring_bounded(load, stiffness_ratio):
    s = load(em.spring_pendulum(stiffness_ratio / DT**2, V0))
    if stiffness_ratio < 0.1:
        r = s.simulate(t_end=0.5, dt=DT)
    else:           # w dt = 1: RK4's damping takes the oscillation's energy, which the
        with pytest.warns(RunWarning, match="energy changed"):   # energy check reports
            r = s.simulate(t_end=0.5, dt=DT)
    e = oscillation_energy(r)
    # One degree of freedom, amplitude 1e-4 rad: linear. RK4 multiplies the energy of an
    # oscillation by |R(i w dt)|^2 per step, R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24: it
    # damps (never amplifies) for w dt < 2.83. Measured and predicted agree to 1%.
    z = 1j * spring_omega(stiffness_ratio) * DT
    decay = abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) ** (2 * r.info["steps"])
    assert e[0] == pytest.approx(0.5 * V0**2, rel=1e-6)
    assert e[-1] / e[0] == pytest.approx(decay, rel=0.05, abs=1e-3 * decay + 1e-9)
    assert np.all(e <= e[0] * (1 + 1e-6))            # never gains energy


@pytest.mark.parametrize("stiffness_ratio", [1e2, 1e4])
def test_rk4_outside_its_stability_interval_stops_with_a_clear_error(load, stiffness_ratio):
    s = load(em.spring_pendulum(stiffness_ratio / DT**2, V0))
    # w dt = 10 and 100: RK4 amplifies by ~4e2 and ~4e6 per step; the engine stops as
    # soon as a step leaves the constraints by 1% of the model or the state passes the
    # run's bounds (measured: t = 0.003 s), long before a non-finite quantity.
    with pytest.raises(SimulationError, match=r"simulation stopped at t = .*diverged"):
        s.simulate(t_end=0.5, dt=DT)


@pytest.mark.parametrize("stiffness_ratio", [1e-2, 1.0, 1e2, 1e4])
def test_implicit_method_keeps_a_stiff_spring_bounded(load, stiffness_ratio):
    if IMPLICIT not in available_methods():
        pytest.skip(f"the implicit method {IMPLICIT!r} is not among the available methods "
                    f"{available_methods()}")
    s = load(em.spring_pendulum(stiffness_ratio / DT**2, V0))
    r = s.simulate(t_end=0.5, dt=DT, method=IMPLICIT)
    e, g = oscillation_energy(r), r["constraint_error"]
    assert np.all(np.isfinite(e))
    # The rod stays a rod: ALI3-P's Newton tolerance is 1e-10 L (measured max |g|
    # 9e-13 at the softest spring to 1e-10 at the stiffest).
    assert np.max(g) < 1e-9, np.max(g)
    # The trapezoidal rule keeps the energy of a linear oscillation at any w dt; what
    # it may gain is gravity's work over the constraint residual, m g max|g| (measured:
    # half of that). RK4 at k dt^2/m = 1 loses 99.8% of it in the same run.
    assert np.max(e) - e[0] < 2 * 9.81 * np.max(g) + 1e-15, (np.max(e) - e[0], np.max(g))
    assert np.min(e) > e[0] * (1 - 1e-4), np.min(e) / e[0]      # measured 1 - 1.1e-6


# -- 5. long runs ------------------------------------------------------------------------

def test_a01_one_million_rk4_steps_with_projection(compiled):
    s = compiled("a01_pendulum")
    r = s.simulate(t_end=1000.0, dt=1e-3, output_dt=10.0, project=True)
    assert r.info["steps"] == 1_000_000 and r.info["projection_failures"] == 0
    e = r["energy"]
    # Energy scale m g L = 9.81 J. Measured drift after 1e6 steps: 6.8e-10 J, i.e.
    # 7e-11 relative (RK4's local error ~1e-16 per step at dt 1 ms summed over 1e6
    # steps, with rounding of the same order); bounded with a factor ~15.
    assert np.max(np.abs(e - e[0])) < 1e-8, np.max(np.abs(e - e[0]))
    # Projection keeps max |g| at its tolerance (1e-11 l on |g|/|B|, |B| = 2 l):
    # measured 1.9e-11 at the end, 2.0e-11 over the run.
    assert r["constraint_error"][-1] < 3e-11
    assert r.info["max_constraint_error"] < 3e-11


def test_a01_one_million_rk4_steps_without_projection_drifts(compiled):
    s = compiled("a01_pendulum")
    r = s.simulate(t_end=1000.0, dt=1e-3, output_dt=10.0, project=False)
    e, g = r["energy"], r["constraint_error"]
    # Without projection RK4's error accumulates in the constraints: measured |g|
    # 7.2e-5 and energy drift 4.8e-4 J after 1e6 steps, growing with time. Bounded
    # from above (not blowing up) and from below (the projection above is what removes
    # it: six decades less).
    assert 1e-6 < g[-1] < 1e-3, g[-1]
    assert 1e-5 < abs(e[-1] - e[0]) < 1e-2, e[-1] - e[0]
    assert g[-1] > 10 * g[len(g) // 10]        # grows over the run


# -- 6. singular configuration and redundant constraints ---------------------------------

@pytest.mark.parametrize("omega0", [20.0, 3.0])
def test_parallelogram_passes_its_flat_position_on_its_branch(load, omega0):
    """The flat position of a parallelogram four-bar (all bars collinear) is where the
    parallelogram and the crossed (antiparallelogram) branches meet: the constraint
    Jacobian loses one more rank there, on top of the redundant hinge rows. The
    motion must keep the parallelogram branch (coupler parallel to the ground)."""
    theta0 = math.radians(60)
    s = load(em.parallelogram(theta0, omega0))
    r = s.simulate(t_end=2.0, dt=1e-3, output_dt=1e-3)
    A = columns(r, "A.x", "A.y")
    coupler = columns(r, "B.x", "B.y") - A
    theta = np.unwrap(np.arctan2(A[:, 1], A[:, 0]))
    flats = np.sum(np.diff(np.floor(theta / math.pi)) != 0)
    assert flats >= 2                   # omega0 = 20: 15 passes; 3: through 0 and -pi
    # On the parallelogram branch the coupler keeps its direction: measured 8e-12 m off.
    assert np.max(np.abs(coupler - [0.4, 0.0])) < 1e-9
    # One degree of freedom: J theta'' = -g K cos(theta), J and K from the bars.
    J = 2 * (2e-4 + 0.2 * 0.05**2) + 0.7 * 0.1**2
    K = 2 * 0.2 * 0.05 + 0.7 * 0.1
    ref = solve_ivp(lambda _t, y: [y[1], -9.81 * K * math.cos(y[0]) / J], (0.0, 2.0),
                    [theta0, omega0], t_eval=r.t, rtol=1e-12, atol=1e-12, method="DOP853")
    # RK4 at 1 ms: measured 3.5e-7 rad at omega0 = 20 (4 ms turns: 1.5e-8 at 0.5 ms,
    # a 24x drop) and 2.3e-8 at 3; a factor ~3 of margin.
    assert np.max(np.abs(theta - ref.y[0])) < 1e-6
    assert r.info["projection_failures"] == 0


def parallelogram_small_steps(load):
    """The omega0 = 20 parallelogram with steps of 0.1 ms: over 3 s some steps land
    within 1e-4 rad of a flat position. Returns (run, energy range / kinetic energy,
    largest distance of the coupler from its parallelogram position)."""
    r = load(em.parallelogram(math.radians(60), 20.0)).simulate(t_end=3.0, dt=1e-4)
    J = 2 * (2e-4 + 0.2 * 0.05**2) + 0.7 * 0.1**2
    coupler = columns(r, "B.x", "B.y") - columns(r, "A.x", "A.y")
    return r, np.ptp(r["energy"]) / (0.5 * J * 20.0**2), np.max(np.abs(coupler - [0.4, 0]))


def test_parallelogram_keeps_its_branch_at_small_steps(load):
    _, _, branch = parallelogram_small_steps(load)
    # Still the parallelogram branch (the crossed one is 0.2 m away); measured 1.4e-8 m
    # over 3 s, 1000 times the 1 ms run's 8e-12: the flat positions perturb the run.
    assert branch < 1e-6, branch


@pytest.mark.xfail(strict=True, reason=(
    "RK4 with projection near a flat (singular) position of a parallelogram: steps "
    "that land within ~1e-4 rad of it change the energy by up to 1e-3 of the kinetic "
    "energy, silently (no projection failure); at dt = 1 ms the same run keeps it to "
    "3e-8. See docs/extremes.md"))
def test_parallelogram_conserves_energy_through_flat_positions_at_small_steps(load):
    r, energy_range, _ = parallelogram_small_steps(load)
    # RK4 at 0.1 ms: its truncation error is 1e4 times below the 1 ms run's 3e-8.
    assert energy_range < 1e-6, energy_range
    assert r.info["projection_failures"] == 0


# -- 7. high spin ------------------------------------------------------------------------

TOP = dict(m=15.0, d=0.15, L=0.3, It=0.08, Ia=0.1, g=9.81)


def top_run(load, dt):
    axis = np.array([math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))])
    omega = 150.0 * axis + [0.0, 0.0, 1.0]
    s = load(em.axisymmetric_top(TOP["L"] * axis, [0, 1, 0], TOP["m"], TOP["d"], TOP["Ia"],
                                 TOP["It"], omega))
    init = s.initial_state()
    w0 = s.body_outputs(init.q, init.v)[0, 3:]
    r = s.simulate(t_end=0.5, dt=dt, output_dt=0.01)
    tip, w, _ = minimal.spherical_top(TOP, minimal.top_state(axis, w0), r.t)
    P = columns(r, "P.x", "P.y", "P.z")
    W = columns(r, "rod.wx", "rod.wy", "rod.wz")
    return r, np.max(np.abs(P - tip)), np.max(np.abs(W - w)), P, W


def test_heavy_top_at_150_rad_s_matches_the_lagrange_top(load):
    _, tip_coarse, _, _, _ = top_run(load, 1e-3)
    _, tip_half, _, _, _ = top_run(load, 5e-4)
    # w dt = 0.15 at 1 ms: RK4's error is large (measured 3.7e-6 m) but converges at
    # fourth order (measured ratio 23 on halving; 8 asked for robustness).
    assert tip_half < tip_coarse / 8, (tip_coarse, tip_half)
    r, tip_err, w_err, P, W = top_run(load, 1e-4)
    # dt = 0.1 ms: measured 1.7e-10 m and 7.5e-8 rad/s; a factor ~10 of margin.
    assert tip_err < 2e-9, tip_err
    assert w_err < 1e-6, w_err
    energy, hz, spin = minimal.top_invariants(TOP, P / TOP["L"], W)
    # Spin w.e and vertical angular momentum are constants of the Lagrange top:
    # measured ranges 6e-8 rad/s (of 151) and 5.4e-9 (of 13.2), both 4e-10 relative;
    # bounded at 1e-8 relative.
    assert np.ptp(spin) < 1e-8 * 150.0, np.ptp(spin)
    assert np.ptp(hz) < 1e-8 * abs(hz[0]), (np.ptp(hz), hz[0])
    # The solver's own energy equals the invariant computed from the vectors (two
    # formulas for the same number: measured 8e-15 relative).
    assert np.max(np.abs(r["energy"] - energy)) < 1e-12 * abs(energy[0])
