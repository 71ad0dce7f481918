"""ALI3-P (index-3 augmented Lagrangian, trapezoidal rule, mass-orthogonal
projections): accuracy and order against RK4, constraints held at the Newton
tolerance, bounded energy, stiff springs, redundant constraints and a singular
position."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from conftest import REFERENCE
from fccgen.bench.accuracy import reference_from_table
from fccgen.errors import SimulationError
from fccgen.model import load_model_text
from fccgen.runtime._ali3p import DEFAULTS, simulate_ali3p
from fccgen.runtime._rk4 import simulate_rk4


def run(solver, t_end, dt, every, options=None, q0=None, v0=None):
    """ALI3-P from the model's consistent initial state (or q0, v0)."""
    if q0 is None:
        init = solver.initial_state()
        q0, v0 = init.q, init.v
    n = int(round(t_end / dt))
    return simulate_ali3p(solver._engine, q0, v0, t_end, dt, n, every, options,
                          length_scale=solver.length_scale)


def reference(solver, t_end, dt, every):
    init = solver.initial_state()
    n = int(round(t_end / dt))
    arrays, _ = simulate_rk4(solver._engine, init.q, init.v, t_end, dt, n, every, True)
    return arrays


def scaled_residual(solver, q) -> float:
    """max_k |g_k| / ||B_k||, the quantity the Newton iteration drives to newton_tol L."""
    g, B = solver.constraints(q), solver.constraint_jacobian(q)
    return float(np.max(np.abs(g) / np.linalg.norm(B, axis=1)))


# Error of the positions at dt = 1e-3 over 0.5 s (11 records), measured against RK4 at
# dt = 1e-4 (its own error is below 1e-10 there, RK4 being fourth order). The
# trapezoidal rule is second order: the bounds are about twice the observed errors
# (double pendulum 7.6e-6 m, four-bar 4.6e-5 m), and halving dt must divide the error
# by 4 within [3.5, 4.5] (observed 3.96 and 3.88).
ORDER_CASES = {"double_pendulum": 1.5e-5, "four_bar": 1e-4}


@pytest.mark.parametrize("name", sorted(ORDER_CASES))
def test_second_order_against_rk4(name, compiled):
    solver = compiled(name)
    ref = reference(solver, 0.5, 1e-4, 500)
    errors = []
    for dt, every in ((1e-3, 50), (5e-4, 100)):
        arrays, stats = run(solver, 0.5, dt, every)
        assert np.allclose(arrays["t"], ref["t"], rtol=0, atol=1e-12)
        errors.append(float(np.max(np.abs(arrays["q"] - ref["q"]))))
        assert stats["projection_failures"] == 0
    assert errors[0] <= ORDER_CASES[name], errors
    assert 3.5 <= errors[0] / errors[1] <= 4.5, errors


@pytest.mark.parametrize("name, t_end, drift", [("double_pendulum", 10.0, 5e-4),
                                                ("four_bar", 2.0, 2e-3)])
def test_constraints_at_tolerance_and_energy_bounded(name, t_end, drift, compiled):
    """Every recorded state satisfies the constraints to newton_tol L (the convergence
    test, up to the rounding of the row norms: factor 1.01); the energy error stays
    within the bound, about 2.5 times the observed one (2.0e-4 J of |E| = 6.5 J over
    10 s for the double pendulum, 8.1e-4 J of 2.2 J over 2 s for the four-bar: the
    trapezoidal rule's O(dt^2) oscillation; the four-bar is the faster of the two)."""
    solver = compiled(name)
    arrays, stats = run(solver, t_end, 1e-3, 10)
    tol = DEFAULTS["newton_tol"] * solver.length_scale
    assert max(scaled_residual(solver, q) for q in arrays["q"]) <= 1.01 * tol
    assert stats["projection_failures"] == 0
    e = np.abs(arrays["energy"] - arrays["energy"][0])
    assert e.max() <= drift
    # the penalty projection leaves B q' at about 1/(1 + dt^2 penalty / 4) of what the
    # trapezoidal speeds had: far below the speeds (1e-5 of the largest one; observed
    # 6e-8 and 9e-7 of it)
    bv = max(np.max(np.abs(solver.constraint_jacobian(q) @ v))
             for q, v in zip(arrays["q"], arrays["v"]))
    assert bv <= 1e-5 * np.max(np.abs(arrays["v"]))
    assert stats["steps"] == round(t_end / 1e-3)
    assert stats["newton_iterations"] >= stats["steps"]
    assert stats["rhs_evaluations"] > stats["newton_iterations"]


def test_outputs_have_the_shapes_of_rk4(compiled):
    solver = compiled("double_pendulum")
    arrays, stats = run(solver, 0.05, 1e-3, 10)
    ref_arrays = reference(solver, 0.05, 1e-3, 10)
    assert set(arrays) == set(ref_arrays)
    for key in arrays:
        assert arrays[key].shape == ref_arrays[key].shape
    assert {"steps", "rhs_evaluations", "newton_iterations", "max_newton_iterations",
            "projection_failures", "max_constraint_error"} <= set(stats)
    assert 1 <= stats["max_newton_iterations"] <= DEFAULTS["max_newton"]


STIFF = """
name: stiff_spring
gravity: [0, -9.81, 0]
points:
  O: {at: [0, 0, 0], fixed: true}
  C: {at: [1.0, -1.0, 0], fixed: true}
  P: [0.6, -0.8, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  rod: {points: [O, P], vector: z, mass: 1.0, center: [0.5, 0, 0],
        inertia: [1.0e-5, 8.4e-2, 8.4e-2]}
loads:
  - {type: spring, ends: [C, P], stiffness: 1.0e8, length: 0.4, damping: 0}
simulate: {t_end: 0.2, dt: 1.0e-3}
"""

# Crank and rocker of equal length 0.3 m, coupler 1 m = the frame: a parallelogram.
# Without gravity the crank turns at constant speed (the kinetic energy is
# J w^2 / 2 with J constant); it starts upright at w = -2 pi rad/s and lies flat
# (all links on the x axis, where the constraint Jacobian loses rank) at t = 0.25 s.
PARALLELOGRAM = """
name: parallelogram
points:
  O: {at: [0, 0, 0], fixed: true}
  C: {at: [1.0, 0, 0], fixed: true}
  A: [0, 0.3, 0]
  B: [1.0, 0.3, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  crank: {points: [O, A], vector: z, mass: 0.3, center: [0.15, 0, 0],
          inertia: [1.0e-5, 2.5e-3, 2.5e-3]}
  coupler: {points: [A, B], vector: z, mass: 1.0, center: [0.5, 0, 0],
            inertia: [3.0e-5, 8.4e-2, 8.4e-2]}
  rocker: {points: [C, B], vector: z, mass: 0.3, center: [0.15, 0, 0],
           inertia: [1.0e-5, 2.5e-3, 2.5e-3]}
initial:
  points: {A: [1.8849555921538759, 0, 0], B: [1.8849555921538759, 0, 0]}
simulate: {t_end: 0.5, dt: 1.0e-3}
"""


@pytest.fixture(scope="module")
def text_model(build_dir, tmp_path_factory):
    """text_model(yaml) -> CompiledSolver, after validating the text."""
    folder = tmp_path_factory.mktemp("ali3p_models")

    def get(text):
        model = load_model_text(text)
        path = folder / f"{model.name}.yaml"
        path.write_text(text)
        return fccgen.load(path, build_dir)
    return get


def test_stiff_spring_stays_bounded_where_rk4_blows_up(text_model):
    """k dt^2 / m = 100: RK4 (stable for omega dt < 2.8, here omega dt ~ 10) stops
    with "diverged" (its steps leave the constraints by more than 1% of the model); ALI3-P keeps the energy at or below its initial value (the
    trapezoidal rule does not amplify, the projections only remove energy; 1e-6
    relative for rounding) and the rod on its constraints."""
    solver = text_model(STIFF)
    init = solver.initial_state()
    with pytest.raises(SimulationError, match="diverged"):
        simulate_rk4(solver._engine, init.q, init.v, 0.2, 1e-3, 200, 10, True)
    arrays, stats = run(solver, 0.2, 1e-3, 10)
    e = arrays["energy"]
    assert np.all(np.isfinite(arrays["q"])) and np.all(e <= e[0] * (1 + 1e-6))
    tol = DEFAULTS["newton_tol"] * solver.length_scale
    assert max(scaled_residual(solver, q) for q in arrays["q"]) <= 1.01 * tol


def test_parallelogram_passes_its_flat_singular_position(text_model):
    """Through the flat position (rank of B drops) and on: the coupler stays parallel
    to the frame (B - A = (1, 0, 0) to 1e-9: the parallelogram branch, not the
    crossed one), the crank angle follows pi/2 - 2 pi t within 1e-4 rad (expected
    phase error (w dt)^2 / 12 * w t ~ 1e-5) and the energy is constant to 1e-9
    relative (a uniform rotation: nothing for the trapezoidal rule to lose)."""
    solver = text_model(PARALLELOGRAM)
    arrays, stats = run(solver, 0.5, 1e-3, 10)
    q, t = arrays["q"], arrays["t"]
    a, b = q[:, 0:3], q[:, 3:6]
    assert np.max(np.abs(b - a - [1.0, 0.0, 0.0])) <= 1e-9
    angle = np.unwrap(np.arctan2(a[:, 1], a[:, 0]))
    assert np.max(np.abs(angle - (np.pi / 2 - 2 * np.pi * t))) <= 1e-4
    assert angle[-1] < -np.pi / 2 + 1e-3          # well past the flat position
    e = arrays["energy"]
    assert np.max(np.abs(e - e[0])) <= 1e-9 * e[0]
    assert stats["projection_failures"] == 0


def test_newton_failure_and_bad_options_are_reported(compiled):
    solver = compiled("four_bar")
    with pytest.raises(SimulationError, match=r"did not converge in 1 iterations.*t = 0"):
        run(solver, 0.01, 1e-3, 1, {"max_newton": 1})
    with pytest.raises(ValueError, match="no option 'tolerance'"):
        run(solver, 0.01, 1e-3, 1, {"tolerance": 1e-8})
    with pytest.raises(ValueError, match="positive"):
        run(solver, 0.01, 1e-3, 1, {"penalty": -1.0})


def test_a02_n_four_bar_meets_the_high_precision_level(compiled):
    """IFToMM benchmark A02 (40 four-bar loops, 162 constraint rows of rank 122, 20
    passages through the flat position where 40 more ranks are lost) over 20 s at
    dt = 1e-3 with the default penalty: it starts at 3.4e9 (conditioned_penalty) and
    is raised tenfold where a step stalls near a flat position (a fixed 1e9 stopped at
    the first one, t = 0.64 s: _ali3p.pyx); every step converges or is accepted as
    slow, and B0 stays within the benchmark's high-precision level (1e-3 m at the 401
    reference times; measured 4.3e-4 m, as with a fixed 1e12, the trapezoidal rule's
    phase error: 2.3e-3 m at dt = 2e-3)."""
    solver = compiled("a02_n_four_bar")
    result = solver.simulate(t_end=20.0, dt=1e-3, method="ali3p", output_dt=0.05)
    error, when = reference_from_table(
        REFERENCE / "mbsbenchmark_A02_solution_data_B0.csv", "B0").error(result)
    assert error <= 1e-3, f"B0 error {error:.3g} m at t = {when:g} s"
    y = result["B0.y"]
    assert np.sum(np.diff(np.sign(y)) != 0) == 20          # the 20 flat passages
    info = result.info
    assert info["projection_failures"] == 0
    assert 1 <= info["penalty_raises"] <= 4                 # measured 3: 3.4e12
    # slow steps are the few around each flat passage (measured 50 of 20000)
    assert info["slow_newton_steps"] <= 200
    # constraints held to the Newton tolerance: |g_k| <= 1e-10 ||B_k|| with ||B_k|| <=
    # 2 sqrt(2) for the 1 m bars (measured max |g| 9.9e-11)
    assert info["max_constraint_error"] <= 3e-10


@pytest.mark.parametrize("stiffness", ["1.0e10", "1.0e12"])
def test_springs_that_stall_newton_get_a_message_naming_what_to_use(text_model, stiffness):
    """k / m = 1e10 and 1e12 per s^2 on this rod stall Newton at t = 0 (the spring
    outweighs the default penalty 1e9: each multiplier update shrinks g by about
    k / (k + penalty)); the error names the stiffness and the methods that can run the
    model instead of advice about singular positions alone."""
    solver = text_model(STIFF.replace("stiffness: 1.0e8", f"stiffness: {stiffness}")
                        .replace("name: stiff_spring", f"name: stiff_{stiffness[-2:]}"))
    with pytest.raises(SimulationError, match=r"stopped at t = 0: .*did not converge.*"
                                              r"stiff spring.*--method dopri5.*rk4 with dt "
                                              r"well below"):
        solver.simulate(method="ali3p")
