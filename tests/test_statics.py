"""Static equilibrium (fccgen.analysis.statics) against hand solutions: a hinged rod
held by a spring under gravity, a two-bar truss, an inverted pendulum, the
deployable example; and the exactness of the constraint-curvature difference."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import fccgen
from fccgen.analysis import statics
from fccgen.analysis.tangent import curvature
from fccgen.cli import main

M, L, D, B_AT, K, L0, G = 2.0, 1.0, 0.5, 0.8, 50.0, 0.3, 9.81
S = np.array([1.0, 0.8, 0.0])          # the spring's fixed end

SPRUNG_ROD = f"""
name: sprung_rod
gravity: [0, {-G}, 0]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  S: {{at: {S.tolist()}, fixed: true}}
  P: [{L}, 0, 0]
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  rod: {{points: [O, P], vector: z, mass: {M}, center: [{D}, 0, 0],
         inertia: [1.0e-4, 0.16, 0.16]}}
loads:
  - {{type: spring, ends: [S, {{body: rod, at: [{B_AT}, 0, 0]}}], stiffness: {K},
     length: {L0}}}
"""

TRUSS = """
name: truss
points:
  O1: {at: [0, 0, 0], fixed: true}
  O2: {at: [2, 0, 0], fixed: true}
  P: [1.2, -0.9, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  bar1: {points: [O1, P], vector: z, mass: 1.0, center: [0.5, 0, 0], inertia: [0, 0, 0]}
  bar2: {points: [O2, P], vector: z, mass: 1.0, center: [0.5, 0, 0], inertia: [0, 0, 0]}
loads:
  - {type: force, body: bar1, at: [1.5, 0, 0], value: [3.0, -40.0, 8.0]}
"""


def write(tmp_path, text, name):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def moment(theta):
    """z-moment about O of gravity and the spring on the rod at angle theta."""
    e = np.array([np.cos(theta), np.sin(theta), 0.0])
    d = B_AT * e - S
    spring = -K * (np.linalg.norm(d) - L0) * d / np.linalg.norm(d)
    return np.cross(B_AT * e, spring)[2] + np.cross(D * e, [0.0, -M * G, 0.0])[2]


def test_sprung_rod_angle_matches_moment_balance(tmp_path):
    eq = statics(fccgen.load_numeric(write(tmp_path, SPRUNG_ROD, "sprung_rod")))
    theta = np.arctan2(eq.q[1], eq.q[0])
    exact = brentq(moment, theta - 0.3, theta + 0.3, xtol=1e-15)
    # Newton stops at max |N^T f| <= 1e-11 x the largest force (~20 N) with a
    # stiffness of order 10 N m/rad: the angle is then right to ~1e-12 rad
    assert abs(theta - exact) <= 1e-10
    assert abs(moment(exact)) <= 1e-12 and abs(exact) > 0.1     # not a trivial root
    assert eq.stability == "stable" and eq.stiffness_eigenvalues[0] > 0.0
    assert eq.constraint_residual <= 1e-12


def test_damped_motion_settles_where_statics_says(tmp_path):
    """The sprung rod with a damper in its spring, released from horizontal, comes to
    rest at the static equilibrium. zeta = 0.66 at 1.08 Hz (fccgen modes): after 6 s
    the swing has decayed by exp(-zeta w t) ~ 2e-12 of its start, and dopri5 at
    rtol 1e-8, atol 1e-10 ends within ~1e-10 of rest (measured: 3e-12)."""
    text = SPRUNG_ROD.replace(f"length: {L0}}}", f"length: {L0}, damping: 16.0}}")
    assert text != SPRUNG_ROD
    solver = fccgen.load_numeric(write(tmp_path, text, "damped_rod"))
    eq = statics(solver)
    run = solver.simulate(t_end=6.0, method="dopri5", output_dt=0.5, rtol=1e-8, atol=1e-10)
    assert np.hypot(run["P.x"][0] - eq.q[0], run["P.y"][0] - eq.q[1]) > 0.1   # far
    assert abs(run["P.x"][-1] - eq.q[0]) <= 1e-9
    assert abs(run["P.y"][-1] - eq.q[1]) <= 1e-9


def test_two_bar_truss_reactions_are_the_bar_forces(tmp_path):
    eq = statics(fccgen.load_numeric(write(tmp_path, TRUSS, "truss")))
    P = np.array([1.2, -0.9, 0.0])
    assert eq.dof == 0 and eq.redundant == 1      # both bars fix P.z: one row redundant
    np.testing.assert_allclose(eq.q, P, atol=1e-14)
    # joint P: F - T1 e1 - T2 e2 = 0 in the plane (T: tension, pulling P to a support)
    e1 = P / np.linalg.norm(P)
    e2 = (P - [2, 0, 0]) / np.linalg.norm(P - [2, 0, 0])
    F = np.array([3.0, -40.0, 8.0])
    T1, T2 = np.linalg.solve(np.array([e1[:2], e2[:2]]).T, F[:2])
    solver = fccgen.load_numeric(tmp_path / "truss.yaml")
    B = solver.constraint_jacobian(eq.q)
    for row, lam in zip(B, eq.multipliers):
        if abs(row[2]) > 0.5 * np.linalg.norm(row):   # "bar perpendicular to z": the two share F_z
            assert lam == pytest.approx(F[2] / 2, rel=1e-12)     # minimum-norm split
            continue
        # |r|^2 - l^2 = 0: row = 2 (P - O) = 2 l e; its force on P is -lambda row
        # (M q'' + B^T lambda = f - h), i.e. -T e with T = 2 l lambda
        tension = lam * np.linalg.norm(row)
        e = row / np.linalg.norm(row)
        expected = T1 if abs(e @ e1) > 0.999 else T2
        assert tension == pytest.approx(expected, rel=1e-12)
    assert eq.force_residual <= 1e-12 * 40.0


def test_inverted_pendulum_is_found_unstable(tmp_path):
    text = SPRUNG_ROD.replace(f"P: [{L}, 0, 0]", "P: [0, 1, 0]").split("loads:")[0]
    eq = statics(fccgen.load_numeric(write(tmp_path, text, "upright")))
    assert eq.iterations == 0 and eq.stability == "unstable"
    # -m g d: the gravity moment's stiffness about the upright position
    assert eq.stiffness_eigenvalues[0] == pytest.approx(-M * G * D, rel=1e-12)


def test_curvature_difference_is_exact_for_any_step(numeric):
    """B(q) is affine in q, so d(B^T lambda)/dq by central differences does not depend
    on the step: steps of 1, 10 and 100 mm (coordinates ~1000 mm) agree to 1e-12
    relative. Only rounding, ~eps |B| |lambda| / h, limits it (1e-13 relative at 1 mm;
    it is what makes steps far below the coordinates' size worse, not truncation)."""
    solver = numeric("deployable")
    q = solver.initial_state().q
    lam = np.random.default_rng(3).normal(size=solver.n_g) * 1e3
    H = [curvature(solver, q, lam, h) for h in (10.0, 1.0, 100.0)]
    scale = np.max(np.abs(H[0]))
    assert scale > 1.0
    for other in H[1:]:
        assert np.max(np.abs(other - H[0])) <= 1e-12 * scale


def test_deployable_statics_compiled_and_numeric_agree(compiled, numeric):
    eq = statics(compiled("deployable"))
    # rounding floor: the loads are 1e7 (g mm/s^2) on lengths of ~1000 mm
    assert eq.force_residual <= 1e-9 * eq.force_scale
    assert eq.constraint_residual <= 1e-12 * 1118.0 ** 2
    assert eq.stability == "stable" and eq.redundant == 3
    other = statics(numeric("deployable"))
    np.testing.assert_allclose(other.q, eq.q, rtol=0, atol=1e-8 * 1118.0)


def test_statics_command(build_dir, capsys):
    from conftest import EXAMPLES
    path = EXAMPLES / "double_pendulum.yaml"
    assert main(["statics", str(path), "--build-dir", str(build_dir), "-q"]) == 0
    out = capsys.readouterr().out
    assert "stability: stable" in out and "P2.y" in out
    # both rods hang down: P2 at y = -(1.0 + 0.8)
    value = next(line.split()[1] for line in out.splitlines()
                 if line.strip().startswith("P2.y"))
    assert float(value) == pytest.approx(-1.8, abs=1e-12)
    assert main(["statics", str(path.parent / "missing.yaml")]) == 2
    assert capsys.readouterr().err.startswith("fccgen: error: ")


def test_no_equilibrium_is_an_error_naming_the_way_out(tmp_path):
    """A free body under gravity has no equilibrium: every load step fails (few
    iterations and coarse load steps keep the test short)."""
    from conftest import EXAMPLES

    from fccgen.errors import SimulationError
    text = (EXAMPLES / "free_body.yaml").read_text().replace(
        "name: free_body", "name: falling_body\ngravity: [0, 0, -9.81]")
    solver = fccgen.load_numeric(write(tmp_path, text, "falling_body"))
    with pytest.raises(SimulationError, match="no equilibrium.*--about initial"):
        statics(solver, max_iterations=4, min_load_step=0.25)


PRELOADED = """\
name: preloaded
bodies:
  arm: {mass: 1.0, center: [0.5, 0, 0], inertia: [0.001, 0.1, 0.1]}
joints:
  - {name: H, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 0, 1]}
loads:
  - {type: torsion_spring, joint: H, stiffness: 20.0, angle: 4.5, damping: 0.0}
gravity: [0, -9.81, 0]
"""


@pytest.mark.parametrize("numeric", [False, True])
def test_a_spring_preloaded_past_half_a_turn_has_the_static_reactions(numeric, tmp_path):
    """An arm on a hinge spring free at 4.5 rad, stowed at 0: the equilibrium is where
    the spring, read within half a turn of its free angle as the kernels read it
    outside a run, holds the weight's moment (k (4.5 - theta) = m g D cos theta,
    theta = 4.541 rad, the arm below the hinge). The hinge carries the weight alone,
    F = (0, m g, 0), and no torque across its axis. Before, the reactions read the
    spring within half a turn of the stowed angle (-1.74 rad, 6.2 rad from its free
    angle, a torque of 125 N m) and reported F = (49.5, 1.27, 0) N with exit 0.
    1e-9 N: the equilibrium is solved to about 1e-12."""
    path = write(tmp_path, PRELOADED, "preloaded")
    eq, r = fccgen.api.equilibrium(path, numeric=numeric)
    theta = float(np.arctan2(eq.q[1], eq.q[0])) + 2 * np.pi
    assert abs(20.0 * (4.5 - theta) - 9.81 * 0.5 * np.cos(theta)) < 1e-9
    info = r.info["reactions"]
    assert info["computed"] and info["balanced"] and info["residual"] < 1e-9
    force = [r[f"H.f{c}"][0] for c in "xyz"]
    torque = [r[f"H.t{c}"][0] for c in "xyz"]
    assert np.abs(np.subtract(force, [0.0, 9.81, 0.0])).max() < 1e-9
    assert np.abs(torque).max() < 1e-9


def test_reactions_that_do_not_balance_the_bodies_warn(tmp_path):
    """The guard on the reactions: the same equilibrium with the spring read on the
    stowed angle's branch (as the reactions did before) leaves 125 N m of the arm's
    balance unexplained. The reactions say so, with a warning, and mark themselves
    unbalanced (the least squares leave O(1) of the largest term)."""
    from fccgen.mechanism.reactions import add_reactions
    from fccgen.numeric.record_loads import RecordLoads
    path = write(tmp_path, PRELOADED, "preloaded")
    solver = fccgen.load_numeric(path)
    eq, r = fccgen.api.equilibrium(path, numeric=True)
    loads = RecordLoads(solver.plan, solver.put_params, turns=False)
    with pytest.warns(fccgen.errors.RunWarning, match="leave an imbalance of"):
        add_reactions(solver, r, loads=loads, references=False)
    info = r.info["reactions"]
    assert not info["balanced"] and info["residual"] > 0.1 * info["balance_scale"]
    assert any("not to be trusted" in w for w in r.info["warnings"])
