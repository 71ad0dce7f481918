"""Linearization and natural frequencies (fccgen.analysis): exact on a spring-mass on
a line, hand formulas for pendulums, rigid modes of a free body, and the state matrix
against central differences of the solver's accelerations."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fccgen
from fccgen.analysis import linearize, modes, state_from_z, statics
from fccgen.cli import main
from fccgen.errors import SimulationError

MASS, K = 3.0, 30.0

SPRING_MASS = f"""
name: spring_mass
points:
  A: {{at: [0, 0, 0], fixed: true}}
  B: {{at: [1, 0, 0], fixed: true}}
  P: [0.5, 0, 0]
  Q: [0.7, 0, 0]
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  block: {{points: [P, Q], vector: z, mass: {MASS}, center: [0.1, 0.02, 0.01],
           inertia: [0.01, 0.02, 0.03]}}
constraints:
  - {{type: point_on_line, point: P, line: [A, B]}}
  - {{type: point_on_line, point: Q, line: [A, B]}}
loads:
  - {{type: spring, ends: [A, P], stiffness: {K}, length: 0.4, damping: DAMPING}}
"""


def spring_mass(tmp_path, damping=0.0):
    path = tmp_path / f"spring_mass_{damping:g}.yaml"
    path.write_text(SPRING_MASS.replace("DAMPING", repr(damping)))
    return path


def at_equilibrium(solver):
    eq = statics(solver)
    return eq, modes(linearize(solver, eq.q))


def test_spring_mass_frequency_is_exact(tmp_path):
    """A block sliding on a line (both ends on it: 1 DOF, 3 redundant rows) on a
    linear spring: sqrt(k/m) to 1e-12 relative, since every term of the linearization
    is exact (the curvature and velocity differences are of affine/quadratic maps)."""
    solver = fccgen.load_numeric(spring_mass(tmp_path))
    eq, m = at_equilibrium(solver)
    assert eq.q[0] == pytest.approx(0.4, abs=1e-13)        # the spring's free length
    assert eq.dof == 1 and eq.redundant == 3
    assert m.method == "eigh" and not m.rigid[0]
    assert m.frequency_hz[0] == pytest.approx(np.sqrt(K / MASS) / (2 * np.pi), rel=1e-12)
    shape = m.shapes[:, 0] / m.shapes[0, 0]                # P.x and Q.x move together
    np.testing.assert_allclose(shape, [1, 0, 0, 1, 0, 0], atol=1e-12)


def test_spring_mass_damping_ratio(tmp_path):
    c = 1.5
    _, m = at_equilibrium(fccgen.load_numeric(spring_mass(tmp_path, c)))
    assert m.method == "state matrix"
    # the undamped natural frequency and zeta = c / (2 sqrt(k m)); the eigenvalues of
    # a 2 x 2 state matrix are accurate to rounding
    assert m.frequency_hz[0] == pytest.approx(np.sqrt(K / MASS) / (2 * np.pi), rel=1e-10)
    assert m.damping_ratio[0] == pytest.approx(c / (2 * np.sqrt(K * MASS)), rel=1e-10)


def test_overdamped_mode(tmp_path):
    c = 40.0            # zeta = 40 / (2 sqrt(90)) = 2.1
    _, m = at_equilibrium(fccgen.load_numeric(spring_mass(tmp_path, c)))
    assert m.damping_ratio[0] == pytest.approx(c / (2 * np.sqrt(K * MASS)), rel=1e-10)
    assert m.frequency_hz[0] == pytest.approx(np.sqrt(K / MASS) / (2 * np.pi), rel=1e-10)


def test_point_pendulum_frequency(numeric):
    _, m = at_equilibrium(numeric("a01_pendulum"))       # point mass, l = 1, g = 9.81
    assert m.frequency_hz[0] == pytest.approx(np.sqrt(9.81) / (2 * np.pi), rel=1e-10)


def test_compound_pendulum_frequency(tmp_path):
    """A rod about a hinge: omega^2 = g / l_eff, l_eff = I_O / (m d)."""
    mass, d, i_c = 1.5, 0.45, 0.2
    path = tmp_path / "rod.yaml"
    path.write_text(f"""
name: rod
gravity: [0, -9.81, 0]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  P: [0.6, -0.8, 0]
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  rod: {{points: [O, P], vector: z, mass: {mass}, center: [{d}, 0, 0],
         inertia: [0.1, {i_c}, 0.25]}}
""")                                  # e2 = z: the hinge axis is the body's second axis
    eq, m = at_equilibrium(fccgen.load_numeric(path))
    l_eff = (i_c + mass * d * d) / (mass * d)
    assert eq.q[1] == pytest.approx(-1.0, abs=1e-12)      # hanging straight down
    assert m.frequency_hz[0] == pytest.approx(np.sqrt(9.81 / l_eff) / (2 * np.pi),
                                              rel=1e-10)


def test_motion_without_inertia_is_refused(tmp_path):
    path = tmp_path / "massless.yaml"
    path.write_text("""
name: massless
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [1, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  rod: {points: [O, P], vector: z, mass: 1.0, center: [0, 0, 0], inertia: [0, 0, 0]}
""")                       # all mass at the pivot: the rod turns without inertia
    solver = fccgen.load_numeric(path)
    with pytest.raises(SimulationError, match="massless.yaml.*without inertia"):
        linearize(solver, solver.plan.q0)        # consistent as given


@pytest.mark.parametrize("damping", [0.0, 0.05])
def test_inverted_pendulum_has_a_negative_frequency(tmp_path, damping):
    """Upright, omega^2 = -m g d / I_O: reported as -sqrt(m g d / I_O) / (2 pi), by
    eigh without damping and from the saddle pair of real eigenvalues of A with a
    torsion-like damper (a damped spring of free length equal to its length);
    damping of 0.05 moves sqrt(|s1 s2|) away from sqrt(m g d / I_O) not at all
    (s1 s2 = K/M exactly), so both to 1e-10."""
    mass, d, i_c = 2.0, 0.5, 0.16
    path = tmp_path / "upright.yaml"
    path.write_text(f"""
name: upright
gravity: [0, -9.81, 0]
points:
  O: {{at: [0, 0, 0], fixed: true}}
  S: {{at: [1, 1, 0], fixed: true}}
  P: [0, 1, 0]
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  rod: {{points: [O, P], vector: z, mass: {mass}, center: [{d}, 0, 0],
         inertia: [1.0e-4, {i_c}, 0.16]}}
loads:
  - {{type: spring, ends: [S, P], stiffness: 0.0, length: 1.0, damping: {damping}}}
""")
    eq, m = at_equilibrium(fccgen.load_numeric(path))
    assert eq.stability == "unstable"
    expected = -np.sqrt(mass * 9.81 * d / (i_c + mass * d * d)) / (2 * np.pi)
    assert m.method == ("eigh" if damping == 0.0 else "state matrix")
    assert m.frequency_hz[0] == pytest.approx(expected, rel=1e-10)


def test_free_body_has_six_rigid_modes(numeric):
    eq, m = at_equilibrium(numeric("free_body"))
    assert eq.stability == "neutral"
    assert m.rigid.all() and len(m.rigid) == 6 and not np.any(m.frequency_hz)


def fd_state_matrix(solver, lin):
    """d(z', z'')/d(z, z') by central differences of the solver's accelerations through
    state_from_z; step by the cube-root rule (error ~eps^(2/3) ~ 4e-11 relative)."""
    n, N = lin.dof, lin.null_basis
    x0 = np.concatenate([np.zeros(n), N.T @ lin.v])

    def rhs(x):
        q, v = state_from_z(lin, solver, x[:n], x[n:])
        # the chart keeps z exactly (to rounding of the coordinates' size)
        assert np.max(np.abs(N.T @ (q - lin.q) - x[:n])) <= 1e-13 * max(
            1.0, np.max(np.abs(lin.q)))
        return np.concatenate([N.T @ v, N.T @ solver.accelerations(q, v)])
    h = np.finfo(float).eps ** (1 / 3) * max(1.0, np.max(np.abs(x0)))
    return np.array([(rhs(x0 + h * e) - rhs(x0 - h * e)) / (2 * h)
                     for e in np.eye(2 * n)]).T


@pytest.mark.parametrize("name", ["double_pendulum", "free_body", "deployable"])
@pytest.mark.parametrize("kind", ["compiled", "numeric"])
def test_state_matrix_matches_finite_differences(request, kind, name):
    """Away from equilibrium (the initial states: a released double pendulum, a
    spinning free body with gyroscopic terms, the loaded deployable structure) A agrees
    with differences of the dynamics to 1e-6 relative (measured: 1e-10 to 1e-8)."""
    solver = request.getfixturevalue(kind)(name)
    init = solver.initial_state()
    lin = linearize(solver, init.q, init.v)
    A, fd = lin.A, fd_state_matrix(solver, lin)
    assert np.max(np.abs(A[lin.dof:])) > 1.0                  # not vacuous
    assert np.max(np.abs(A - fd)) <= 1e-6 * np.max(np.abs(A))


def test_modes_command_writes_csv(build_dir, numeric, tmp_path, capsys):
    """The compiled deployable structure (served from the session's cache) against the
    numeric version's frequency (the two agree to ~1e-12 in their kernels; the
    equilibria differ by the Newton tolerance, hence 1e-8)."""
    from conftest import EXAMPLES
    out = tmp_path / "modes.csv"
    path = EXAMPLES / "deployable.yaml"
    assert main(["modes", str(path), "--build-dir", str(build_dir), "-q",
                 "--out", str(out)]) == 0
    rows = out.read_text().splitlines()
    assert rows[0] == "mode,frequency_hz,damping_ratio,rigid" and len(rows) == 2
    mode, f, zeta, rigid = rows[1].split(",")
    _, m = at_equilibrium(numeric("deployable"))
    assert float(f) == pytest.approx(m.frequency_hz[0], rel=1e-8)
    assert float(zeta) == 0.0 and rigid == "0" and float(f) > 0.1
    assert "frequency_hz" in capsys.readouterr().out
    with pytest.raises(SystemExit) as stop:                           # argparse's
        main(["modes", str(path), "--about", "nowhere"])
    assert stop.value.code == 2
    capsys.readouterr()
    assert main(["modes", str(tmp_path / "missing.yaml")]) == 2
    assert capsys.readouterr().err.startswith("fccgen: error: ")


def test_spatial_bars_against_exudyn():
    """Two flat bars on ball joints held by four springs (tests/data/
    spatial_bars_springs.yaml) against the frequencies Exudyn's ComputeODE2Eigenvalues
    gives for the same model (tests/data/make_exudyn_modes.py wrote the CSV).

    Both solve the same undamped eigenproblem: at rest the springs and the joints carry
    no force, so there is no constraint-curvature stiffness (which Exudyn leaves out)
    and the two tools differ only in coordinates (Exudyn: node positions and
    Tait-Bryan angles projected on an SVD null-space basis; fccgen: points and
    vectors on the null space of B). Each frequency is then computed to rounding: a
    dense symmetric eigensolve of well-separated eigenvalues (gaps over 10 %) of
    6 x 6 matrices with entries of order 1 to 40, relative error some 1e-15 x the
    condition of the projection; 1e-12 relative allows three orders for that (the CSV
    stores 17 significant digits). Measured: 9e-16. The two spins have no
    stiffness: rigid in fccgen, below 1e-8 Hz (rounding of the SVD) in Exudyn."""
    data = Path(__file__).parent / "data"
    stored = np.loadtxt(data / "exudyn_modes_spatial_bars_springs.csv", delimiter=",",
                        skiprows=2)
    _, m = at_equilibrium(fccgen.load_numeric(data / "spatial_bars_springs.yaml"))
    assert m.method == "eigh" and m.rigid.tolist() == [True, True] + [False] * 4
    exudyn_hz = stored[:, 1]
    assert np.all(exudyn_hz[:2] < 1e-6 * exudyn_hz[-1])
    np.testing.assert_allclose(m.frequency_hz[2:], exudyn_hz[2:], rtol=1e-12)
