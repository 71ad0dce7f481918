"""Mode shapes as results the animation plays: one period of small motion about the
equilibrium along each mode, on the constraints, against the double pendulum's closed
form; rigid-body modes labelled; the command line writes them and animate finds them."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from conftest import EXAMPLES
from fccgen.analysis import linearize, modes, statics
from fccgen.analysis.mode_shapes import mode_shape_path, mode_shapes
from fccgen.cli import main
from fccgen.results.result import Result

DOUBLE = EXAMPLES / "double_pendulum.yaml"
G = 9.81
# examples/double_pendulum.yaml: rod i of length l, mass m, centre at c from its first
# point, central inertia about the hinge axis (z) I
L1, M1, C1, I1 = 1.0, 1.0, 0.5, 0.0834333333333333
L2, M2, C2, I2 = 0.8, 0.6, 0.4, 0.03206


def closed_form():
    """Small oscillations of the hanging double pendulum in the rod angles (th1, th2)
    from the downward vertical: M th'' + K th = 0 with
    M = [[I1 + m1 c1^2 + m2 l1^2, m2 l1 c2], [m2 l1 c2, I2 + m2 c2^2]],
    K = g diag(m1 c1 + m2 l1, m2 c2). Returns (frequencies in Hz, shapes as columns)."""
    M = np.array([[I1 + M1 * C1 ** 2 + M2 * L1 ** 2, M2 * L1 * C2],
                  [M2 * L1 * C2, I2 + M2 * C2 ** 2]])
    K = G * np.diag([M1 * C1 + M2 * L1, M2 * C2])
    w2, shapes = scipy.linalg.eigh(K, M)
    return np.sqrt(w2) / (2 * np.pi), shapes


@pytest.fixture(scope="module")
def double_shapes(compiled):
    solver = compiled("double_pendulum")
    eq = statics(solver)
    lin = linearize(solver, eq.q)
    return mode_shapes(solver, lin, modes(lin))


def test_first_mode_of_the_double_pendulum_has_the_closed_form_ratio(double_shapes):
    """About the hanging equilibrium the independent coordinates are P1.x and P2.x,
    kept exactly by the projection, so P1.x = l1 sin th1 and P2.x - P1.x = l2 sin th2
    carry the linear shape: (P2.x - P1.x) / P1.x = l2 th2 / (l1 th1) at every phase.
    The linearization at an equilibrium is exact (docs/linearization.md) and the 2 x 2
    eigenproblem well conditioned: 1e-9 relative leaves room for the Newton tolerance
    of the equilibrium (1e-13) and rounding."""
    f, shapes = closed_form()
    first = double_shapes[0]
    assert first.info["mode"] == 1 and not first.info["rigid"]
    assert first.info["frequency_hz"] == pytest.approx(f[0], rel=1e-9)
    ratio = (L2 * shapes[1, 0]) / (L1 * shapes[0, 0])
    quarter = len(first.t) // 4                       # tau = 0.25: the largest excursion
    p1, p2 = first["P1.x"], first["P2.x"]
    assert (p2[quarter] - p1[quarter]) / p1[quarter] == pytest.approx(ratio, rel=1e-9)
    # and not the second mode's ratio (the test can tell the modes apart)
    assert abs(ratio - L2 * shapes[1, 1] / (L1 * shapes[0, 1])) > 1.0


def test_a_shape_is_one_period_of_sine_motion_on_the_constraints(double_shapes):
    f, _ = closed_form()
    for k, shape in enumerate(double_shapes):
        tau = shape.t / shape.info["period"]
        assert shape.info["period"] == pytest.approx(1.0 / f[k], rel=1e-9)
        np.testing.assert_allclose(tau, np.linspace(0.0, 1.0, len(tau)), atol=1e-15)
        # the independent coordinates follow a sin(2 pi tau) exactly (1e-12: rounding
        # of the projection's Newton steps); the largest excursion is the default
        # amplitude, a tenth of the longest rod
        biggest = max(np.max(np.abs(shape["P1.x"])), np.max(np.abs(shape["P2.x"])))
        assert biggest == pytest.approx(0.1 * L1, rel=1e-12)
        a = shape["P2.x"][len(tau) // 4]
        np.testing.assert_allclose(shape["P2.x"], a * np.sin(2 * np.pi * tau), atol=1e-12)
        # rods keep their lengths (projected, not just linear)
        assert np.max(shape["constraint_error"]) <= 1e-12
        assert np.allclose(np.hypot(shape["P1.x"], shape["P1.y"]), L1, atol=1e-12)
        assert shape.info["kind"] == "mode shape"


def test_rigid_body_modes_are_labelled(numeric):
    solver = numeric("free_body")
    eq = statics(solver)
    lin = linearize(solver, eq.q)
    shapes = mode_shapes(solver, lin, modes(lin), amplitude=0.05, frames=9)
    assert len(shapes) == 6
    for shape in shapes:
        assert shape.info["rigid"] and shape.info["frequency_hz"] == 0.0
        assert shape.info["period"] == 1.0 and len(shape.t) == 9
        assert np.max(shape["constraint_error"]) <= 1e-12
    with pytest.raises(ValueError, match="amplitude of a mode shape must be positive"):
        mode_shapes(solver, lin, modes(lin), amplitude=0.0)


def test_the_commands_write_shapes_and_animate_one(build_dir, tmp_path, capsys):
    shapes = tmp_path / "modes.npz"
    assert main(["modes", str(DOUBLE), "--build-dir", str(build_dir), "-q",
                 "--shapes", str(shapes), "--amplitude", "0.05"]) == 0
    out = capsys.readouterr().out
    files = [mode_shape_path(shapes, k) for k in (1, 2)]
    assert f"mode shapes: {files[0]}, {files[1]}" in out
    assert f"--result {shapes} --mode 1" in out
    second = Result.load(files[1])
    assert second.info["mode"] == 2 and second.info["amplitude"] == 0.05
    assert second.info["model"]["name"] == "double_pendulum"
    page = tmp_path / "mode2.html"
    assert main(["animate", str(DOUBLE), "--result", str(shapes), "--mode", "2",
                 "--out", str(page), "-q"]) == 0
    assert "41 frames" in capsys.readouterr().out
    assert "double_pendulum: mode 2 (1.1" in page.read_text()[-200000:]
    assert main(["animate", str(DOUBLE), "--result", str(shapes), "--mode", "3",
                 "--out", str(page), "-q"]) == 1
    err = capsys.readouterr().err
    assert "modes.mode3.npz does not exist" in err and "modes.mode1.npz, modes.mode2.npz" in err
    assert main(["modes", str(DOUBLE), "--build-dir", str(build_dir), "-q",
                 "--shapes", str(tmp_path / "modes.txt")]) == 1
    assert ".csv, .npz or .h5" in capsys.readouterr().err
