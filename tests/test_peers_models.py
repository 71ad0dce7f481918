"""The MuJoCo and Exudyn models of benchmarks/peers describe the same systems as
fccgen's model files: 0.5 s runs at the same step end at the same point (the scissor
boom, which only Exudyn models: 0.2 s runs, Exudyn converging to fccgen's point).

The peer tests need the ``peers`` extra (mujoco, exudyn) and are skipped without it.
"""
from __future__ import annotations

import sys

import numpy as np
import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))

DT = 1e-3
STEPS = 500          # 0.5 s
CASES = [("a02", 1), ("a02", 3), ("cart", 2)]

# Largest distance (m) of the tracked point (B0 of the chain, the pendulum's tip) from
# fccgen's after 0.5 s, by tool and system, from each tool's method (measured: MuJoCo
# 6.5e-12 on the cart, 9.1e-7 on the chains; Exudyn 4.0e-6 and 3.5e-7):
# - MuJoCo on the cart: RK4 on the same ODE in joint coordinates, fccgen RK4 in
#   Cartesian ones with projection to 1e-11 m: only the methods' truncation errors
#   (O(dt^4)) differ, well below 1e-9 m.
# - MuJoCo on the chains: its loops are closed by soft constraints (spring-dampers of
#   time constant 3 ms), which give way by about 1e-6 m; 1e-5 m allows ten times that.
# - Exudyn: generalized-alpha is second order (error O(dt^2) ~ 1e-6 here, plus its
#   slight numerical damping, spectral radius 0.9): 5e-5 m.
# A 1 % change of a rod's mass or of the initial speed moves the point by 1.6 to 7.6 mm
# in 0.5 s (measured in MuJoCo): far beyond every tolerance.
TOL = {("mujoco", "cart"): 1e-9, ("mujoco", "a02"): 1e-5,
       ("exudyn", "cart"): 5e-5, ("exudyn", "a02"): 5e-5}


@pytest.fixture(scope="module")
def fccgen_points(build_dir, tmp_path_factory):
    """{(system, n): (x, y)} of fccgen's RK4 run (with projection) of 0.5 s."""
    import fccgen_models
    models = tmp_path_factory.mktemp("peers_models")
    out = {}
    for system, n in CASES:
        model = fccgen_models.make(system, n, DT, build_dir=build_dir, models=models)
        model.advance(STEPS)
        out[system, n] = model.point()
    return out


@pytest.mark.parametrize("tool", ["mujoco", "exudyn"])
@pytest.mark.parametrize("system, n", CASES)
def test_the_peer_model_runs_like_fccgen(tool, system, n, request):
    pytest.importorskip(tool)         # before fccgen's builds: no cost without the tool
    fccgen_points = request.getfixturevalue("fccgen_points")
    module = __import__(f"{tool}_models")
    model = module.make(system, n, DT)
    model.advance(STEPS)
    error = np.linalg.norm(model.point() - fccgen_points[system, n])
    assert error <= TOL[tool, system], f"{tool} {system} n={n}: {error:.3g} m from fccgen"


@pytest.mark.parametrize("system, n, nv", [("a02", 3, 7), ("cart", 5, 6)])
def test_the_mujoco_model_has_the_systems_joints_and_mass(system, n, nv):
    pytest.importorskip("mujoco")
    import mujoco_models
    model = mujoco_models.make(system, n, DT).model
    # One coordinate per hinge (and the cart's slide); every rod and the cart 1 kg.
    assert model.nv == nv
    assert model.body_subtreemass[0] == pytest.approx(nv, rel=1e-12)
    assert model.neq == (n if system == "a02" else 0)


def test_the_pendulum_on_a_cart_has_n_plus_1_freedoms_and_no_redundant_equation(tmp_path):
    from fccgen.diagnostics.check import check_model
    from systems import model_file
    report = check_model(model_file("cart", 3, tmp_path))
    assert (report.n_q, report.n_g, report.rank, report.dof) == (15, 11, 11, 4)
    assert report.redundant == []


def test_the_scissor_boom_has_the_coordinates_the_table_gives_and_one_freedom(tmp_path):
    from fccgen.diagnostics.check import check_model
    from systems import model_file, n_coordinates
    report = check_model(model_file("boom", 2, tmp_path))
    assert report.n_q == n_coordinates("boom", 2) == 33
    assert report.dof == 1


# The scissor boom of 3 units (6 bars), at rest at 80 deg, deployed by its springs for
# 0.2 s (the tip node T3 moves 0.78 m along x): fccgen's RK4 at dt 1e-3 against
# Exudyn's generalized-alpha at dt 2e-4 and 1e-4. fccgen's point is its converged one
# (RK4 at dt 1e-4 lands within 1e-11 m of it). Generalized-alpha is second order:
# Exudyn's distance from it was measured 3.16e-6, 1.26e-7, 3.16e-8 and 7.9e-9 m at
# dt 1e-3, 2e-4, 1e-4 and 5e-5, i.e. 3.2 m/s^2 dt^2 at every step. So at 1e-4 the
# distance is at most 1e-7 m (three times the measured 3.2e-8 m), and halving the step
# divides it by 4 (measured 4.00; bounds 3 to 5): a model that differed (a spring's
# sign or rest angle, a mass, an inertia, a base joint) would leave a floor that does
# not shrink with dt. A 1 % change of the springs' stiffness or of the bars' mass
# moves T3 by 7 mm in the 0.2 s (measured in Exudyn).
BOOM_UNITS = 3
BOOM_SPAN = 0.2
BOOM_TOL = 1e-7


@pytest.fixture(scope="module")
def boom_point(build_dir, tmp_path_factory):
    """(x, y) of the boom's tip T3 after fccgen's RK4 run (with projection) of 0.2 s."""
    import fccgen_models
    models = tmp_path_factory.mktemp("peers_boom")
    model = fccgen_models.make("boom", BOOM_UNITS, DT, build_dir=build_dir, models=models)
    model.advance(round(BOOM_SPAN / DT))
    return model.point()


def test_the_exudyn_scissor_boom_converges_to_fccgens_at_second_order(request):
    pytest.importorskip("exudyn")
    point = request.getfixturevalue("boom_point")
    import exudyn_models
    error = {}
    for dt in (2e-4, 1e-4):
        model = exudyn_models.make("boom", BOOM_UNITS, dt)
        model.advance(round(BOOM_SPAN / dt))
        error[dt] = np.linalg.norm(model.point() - point)
    assert error[1e-4] <= BOOM_TOL, f"Exudyn boom at dt 1e-4: {error[1e-4]:.3g} m from fccgen"
    assert 3.0 <= error[2e-4] / error[1e-4] <= 5.0, (
        f"Exudyn boom: {error[2e-4]:.3g} m at dt 2e-4, {error[1e-4]:.3g} m at dt 1e-4")
