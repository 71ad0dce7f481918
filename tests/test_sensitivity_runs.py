"""Forward sensitivities of fixed-step runs (solver.simulate(sensitivities=[...]))
against central differences of the same fixed-step runs, every kind of parameter
supported, on the double pendulum, the driven four-bar, RSUP, a sprung double
pendulum (tests/data/sprung_pendulum.yaml: spring, damper, free length, force) and the
unlatched scissor boom of 2 units (torsion springs on its pivots).

Reference: central differences D(d) of two runs at p +- d (d = 1e-4 |p|) and D(d/2),
combined by Richardson, R = (4 D(d/2) - D(d)) / 3: error O(d^4) ~ 1e-14 relative plus
rounding. Where D(d) and D(d/2) agree to 1e-6 of the column's largest |D|, the step is
in its asymptotic range and the sensitivity must equal R to 1e-7 of that largest |D|;
every parameter has such columns (on the driven four-bar, whose motion is prescribed,
the energy is one). A column whose two differences disagree by more
(rounding dominates: its derivative is nearly zero, like the energy's, a sum of
larger terms, with respect to an inertia of a pendulum released from rest) must
agree within 10 times that disagreement, the differences' own uncertainty, or within
1e-7 of the parameter's largest derivative of any column: the same 1e-7 relative, on
the only scale a vanishing derivative has (the energy of the springy boom without
gravity does not depend on a bar's mass; its computed derivative, 1e-7 where the
largest one is 21, is the projections' drift-sized terms on a sum of larger terms).

Why 1e-7: the engine's sensitivity is the derivative of RK4's stages exactly; only
the projections are linearised at the projected state, which leaves out terms of the
size of the constraint drift one step makes. They fall with the step as the drift
does: on RSUP (a spatial loop with a universal joint, the largest drift of these
models) they reach 1.4e-7 at dt = 1 ms and 9e-9 at 0.5 ms on its positions (measured), more on
its energy's derivative, a small difference of larger terms (2.8e-7 at 0.5 ms), so
RSUP runs at 0.25 ms over 0.15 s; the others pass at 1 ms over 0.3 s.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT

from fccgen.runtime.sensitivity.parameters import current_value

RUN = dict(t_end=0.3, dt=1e-3, method="rk4")
CASES = {
    "double_pendulum": ["bodies.rod1.mass", "bodies.rod2.inertia[1]",
                        "bodies.rod2.center[0]", "gravity[1]"],
    "four_bar_driven": ["bodies.coupler.mass", "bodies.rocker.center[0]",
                        "bodies.crank.inertia[2]"],
    "rsup": ["bodies.slider.mass", "bodies.rod.inertia[1]", "bodies.crank.center[2]"],
    "sprung_pendulum": ["loads[0].stiffness", "loads[0].damping", "loads[0].length",
                        "loads[1].value[0]"],
    # torsion springs on joint angles counted over turns (references re-based between
    # steps), 4 redundant equations
    "scissor_boom_2": ["loads[0].stiffness", "bodies.a1.mass"],
}


@pytest.fixture(scope="session")
def solver_of(compiled, build_dir):
    import fccgen
    cache = {}

    def get(name):
        if name in cache:
            return cache[name]
        if name == "sprung_pendulum":
            cache[name] = fccgen.load(ROOT / "tests" / "data" / f"{name}.yaml", build_dir)
        elif name == "scissor_boom_2":           # the boom of 2 units without its latch
            from conftest import example_module
            path = build_dir / "scissor_boom_2.yaml"
            path.write_text(example_module("make_scissor_boom").model_text(2, latch=False))
            cache[name] = fccgen.load(path, build_dir)
        else:
            cache[name] = compiled(name)
        return cache[name]
    return get


STEP = {"rsup": dict(dt=2.5e-4, t_end=0.15)}


def central(solver, key, columns, d, run):
    x = current_value(solver.plan.model, key)
    plus = solver.with_parameters({key: x + d}).simulate(**run, reactions=False)
    minus = solver.with_parameters({key: x - d}).simulate(**run, reactions=False)
    return {c: (plus[c] - minus[c]) / (2 * d) for c in columns}


def state_columns(result, key):
    """The columns that have a sensitivity: all but t, constraint_error and the
    constraint forces (driver torques)."""
    cols = [c for c in result.names if f"d({c})/d({key})" in result.columns]
    assert not {c for c in result.names if not c.startswith("d(")} - set(cols) - {
        "t", "constraint_error"} - {c for c in result.names if c.endswith(
            (".torque", ".force"))}
    return cols


def check_against_differences(result, solver, key, columns, run, rel=1e-4, label="",
                              normwise=False) -> int:
    """The module docstring's comparison of ``result``'s sensitivities to ``key`` with
    Richardson central differences at d = rel |p| and d / 2; normwise: 1e-7 is also
    taken of the key's largest derivative of any column where the step is in its
    asymptotic range. Returns how many columns were checked at 1e-7 (in that range)."""
    d = rel * max(abs(current_value(solver.plan.model, key)), 1e-3)
    D1, D2 = central(solver, key, columns, d, run), central(solver, key, columns, d / 2, run)
    strict = 0
    floor = 1e-7 * max(np.max(np.abs(D2[c])) for c in columns)
    for c in columns:
        scale, spread = np.max(np.abs(D2[c])), np.max(np.abs(D1[c] - D2[c]))
        want = (4 * D2[c] - D1[c]) / 3
        error = np.max(np.abs(result.sensitivity(c, key) - want))
        if 0 < scale and spread <= 1e-6 * scale:
            strict += 1
            bound = max(1e-7 * scale, floor) if normwise else 1e-7 * scale
            assert error <= bound, (label, key, c, error / scale)
        else:
            assert error <= max(10 * spread, floor), (label, key, c, error, spread)
    return strict


@pytest.mark.parametrize("name", list(CASES))
def test_sensitivities_match_central_differences(solver_of, name):
    solver = solver_of(name)
    keys = CASES[name]
    run = {**RUN, **STEP.get(name, {})}
    result = solver.simulate(**run, reactions=False, sensitivities=keys)
    assert result.info["sensitivities"] == keys
    columns = state_columns(result, keys[0])
    for key in keys:
        strict = check_against_differences(result, solver, key, columns, run, label=name)
        assert strict >= 1, (name, key, "no column's step in its asymptotic range")


def test_sensitivities_match_minimal_coordinates(solver_of, build_dir):
    """The compound pendulum (tests/data/compound_pendulum.yaml): theta'' = f(theta; p)
    with f = m g_y c sin(theta) / (Iyy + m c^2), its sensitivity equations
    s'' = f_theta s + f_p derived by SymPy and integrated by SciPy (DOP853, rtol 1e-12),
    against d(P.x)/dp = l cos(theta) s, d(P.y)/dp = l sin(theta) s of fccgen's RK4 at
    dt = 1e-3 (its own error, O(dt^4), is below 1e-10 relative here): 1e-7 relative to
    the largest |dP/dp| over the run."""
    import sympy
    from scipy.integrate import solve_ivp

    import fccgen
    solver = fccgen.load(ROOT / "tests" / "data" / "compound_pendulum.yaml", build_dir)
    keys = ["bodies.rod.mass", "bodies.rod.inertia[1]", "bodies.rod.center[0]",
            "gravity[1]"]
    result = solver.simulate(output_dt=0.01, reactions=False, sensitivities=keys)
    th, om, m, I, c, g = sympy.symbols("theta omega m I c g")
    f = m * g * c * sympy.sin(th) / (I + m * c ** 2)
    values = {m: 1.3, I: 0.05, c: 0.6, g: -9.81}
    params = [m, I, c, g]
    n = len(params)
    S, W = sympy.symbols(f"s0:{n}"), sympy.symbols(f"w0:{n}")
    # y = [theta, omega, s_0 .. s_{n-1}, w_0 .. w_{n-1}], w = s'
    rhs = [om, f, *W, *(sympy.diff(f, th) * s + sympy.diff(f, p) for s, p in zip(S, params))]
    fn = sympy.lambdify([th, om, *S, *W], [sympy.sympify(r).subs(values) for r in rhs])
    ref = solve_ivp(lambda t, y: fn(*y), (0, 1.0), [1.0, 0.0] + [0.0] * (2 * n),
                    method="DOP853", rtol=1e-12, atol=1e-14, t_eval=result.t)
    assert ref.success
    theta = ref.y[0]
    for k, key in enumerate(keys):
        s = ref.y[2 + k]
        want = {"P.x": np.cos(theta) * s, "P.y": np.sin(theta) * s}
        for col, w in want.items():
            got = result.sensitivity(col, key)
            assert np.max(np.abs(got - w)) <= 1e-7 * np.max(np.abs(w)), (key, col)


def test_sensitivities_of_a_closed_loop_match_minimal_coordinates(build_dir):
    """The slider-crank (tests/data/slider_crank.yaml), a closed loop: in the crank
    angle theta, B = (r cos theta + sqrt(l^2 - r^2 sin^2 theta), 0) and the rod's
    angle phi = atan2(-r sin theta, B_x - r cos theta) are explicit, so Lagrange's
    equation m(theta) theta'' + m'(theta) theta'^2 / 2 + V'(theta) = 0, with
    m = I1 + m1 c1^2 + m2 |dG2/dtheta|^2 + I2 (dphi/dtheta)^2 and V = -g_y (m1 G1_y +
    m2 G2_y), and its sensitivity equations s'' = f_theta s + f_omega s' + f_p are
    derived by SymPy and integrated by SciPy (DOP853, rtol 1e-12). Against them
    d(B.x)/dp = dB_x/dtheta s and d(A.y)/dp = r cos(theta) s of fccgen's RK4 over 1 s,
    every kind of parameter the loop's motion depends on (masses, inertias, mass
    centres, gravity): 1e-7 relative to the largest |d/dp| over the run, as for the
    compound pendulum. At dt = 1e-3 RK4's own error on the sensitivities is 1.2e-7
    here (the crank passes its lowest point fast); at 5e-4 it is 6e-9 .. 1.4e-8
    (measured: 16 times less, O(dt^4)), so the run takes dt = 5e-4."""
    import sympy
    from scipy.integrate import solve_ivp

    import fccgen
    solver = fccgen.load(ROOT / "tests" / "data" / "slider_crank.yaml", build_dir)
    keys = ["bodies.crank.mass", "bodies.rod.mass", "bodies.crank.inertia[1]",
            "bodies.rod.inertia[1]", "bodies.crank.center[0]", "bodies.rod.center[0]",
            "gravity[1]"]
    result = solver.simulate(output_dt=0.01, dt=5e-4, reactions=False, sensitivities=keys)
    th, om = sympy.symbols("theta omega")
    m1, m2, I1, I2, c1, c2, g = sympy.symbols("m1 m2 I1 I2 c1 c2 g")
    r, l = sympy.Rational(1, 10), sympy.Rational(3, 10)
    A = sympy.Matrix([r * sympy.cos(th), r * sympy.sin(th)])
    B = sympy.Matrix([r * sympy.cos(th) + sympy.sqrt(l ** 2 - r ** 2 * sympy.sin(th) ** 2), 0])
    G1, G2 = c1 * A / r, A + c2 * (B - A) / l
    phi = sympy.atan2(-r * sympy.sin(th), B[0] - r * sympy.cos(th))
    dG2 = G2.diff(th)
    mass = I1 + m1 * c1 ** 2 + m2 * dG2.dot(dG2) + I2 * phi.diff(th) ** 2
    V = -g * (m1 * G1[1] + m2 * G2[1])
    f = (-mass.diff(th) * om ** 2 / 2 - V.diff(th)) / mass
    values = {m1: 0.4, m2: 0.9, I1: 4.0e-4, I2: 7.0e-3, c1: 0.04, c2: 0.12, g: -9.81}
    params = [m1, m2, I1, I2, c1, c2, g]
    n = len(params)
    S, W = sympy.symbols(f"s0:{n}"), sympy.symbols(f"w0:{n}")
    rhs = [om, f, *W, *(f.diff(th) * s + f.diff(om) * w + f.diff(p)
                        for s, w, p in zip(S, W, params))]
    fn = sympy.lambdify([th, om, *S, *W], [sympy.sympify(e).subs(values) for e in rhs])
    ref = solve_ivp(lambda t, y: fn(*y), (0, 1.0), [np.pi / 3, 0.0] + [0.0] * (2 * n),
                    method="DOP853", rtol=1e-12, atol=1e-14, t_eval=result.t)
    assert ref.success
    theta = ref.y[0]
    dbx = sympy.lambdify(th, B[0].diff(th))(theta)
    np.testing.assert_allclose(result["B.x"], sympy.lambdify(th, B[0])(theta), rtol=0,
                               atol=1e-9)
    for k, key in enumerate(keys):
        s = ref.y[2 + k]
        want = {"B.x": dbx * s, "A.y": 0.1 * np.cos(theta) * s}
        for col, w in want.items():
            got = result.sensitivity(col, key)
            assert np.max(np.abs(got - w)) <= 1e-7 * np.max(np.abs(w)), (key, col)
