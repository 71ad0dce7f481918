"""Stability at the extremes, part 1: ill-conditioned geometry, mass and inertia ratios,
and badly scaled units. Each case is either right to a tolerance derived from its
conditioning or stops with a clear error; none may return a silent NaN.
Measured figures are in docs/extremes.md."""
from __future__ import annotations

import math

import numpy as np
import pytest

import minimal
import test_extremes_models as em
from conftest import EXAMPLES
from fccgen.errors import ModelError
from fccgen.model import load_model_text


@pytest.fixture(scope="module")
def load(tmp_path_factory, build_dir):
    return em.make_loader(tmp_path_factory.mktemp("extremes_conditioning"), build_dir)


def columns(r, *names):
    return np.column_stack([r[n] for n in names])


# -- 1. u nearly parallel to r_ij --------------------------------------------------------

# The body of tilted_body in the frame of a u at angle gamma from r_ij = x in the x-y
# plane: e1 = x, e2 = y, e3 = z. The reference describes the same body with u at 60 deg
# in the x-z plane, whose frame is e1 = x, e2 = z, e3 = -y: rho_B = C rho, I_B = C I C^T.
RHO = np.array([0.3, 0.1, 0.05])
INERTIA = np.array([[0.02, 0.001, 0.002], [0.001, 0.04, 0.003], [0.002, 0.003, 0.05]])
TO_REFERENCE_FRAME = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
OMEGA = [1.0, 2.0, 3.0]
T_END, DT = 1.0, 1e-3


def tilted(gamma):
    return em.tilted_body([math.cos(gamma), math.sin(gamma), 0.0], RHO, INERTIA, OMEGA)


@pytest.fixture(scope="module")
def tilted_reference(load):
    C = TO_REFERENCE_FRAME
    u = [math.cos(math.pi / 3), 0.0, math.sin(math.pi / 3)]
    return load(em.tilted_body(u, C @ RHO, C @ INERTIA @ C.T, OMEGA)).simulate(
        t_end=T_END, dt=DT, output_dt=0.01)


def tilted_error(result, reference):
    """Largest difference of the tip P and of the angular velocity between two runs."""
    p = np.max(np.abs(columns(result, "P.x", "P.y", "P.z")
                      - columns(reference, "P.x", "P.y", "P.z")))
    w = np.max(np.abs(columns(result, "b.wx", "b.wy", "b.wz")
                      - columns(reference, "b.wx", "b.wy", "b.wz")))
    return p, w


def u_angle(result):
    """The angle between u and r_OP along a run (a constant of the motion)."""
    P = columns(result, "P.x", "P.y", "P.z")
    U = columns(result, "u.x", "u.y", "u.z")
    e1 = P / np.linalg.norm(P, axis=1)[:, None]
    return np.arctan2(np.linalg.norm(np.cross(e1, U), axis=1), np.sum(e1 * U, axis=1))


@pytest.mark.parametrize("gamma", [1e-2, 2e-3])
def test_u_nearly_parallel_matches_a_well_conditioned_u(load, tilted_reference, gamma):
    r = load(tilted(gamma)).simulate(t_end=T_END, dt=DT, output_dt=0.01)
    p_err, w_err = tilted_error(r, tilted_reference)
    # u's motion carries the spin about e1 scaled by sin(gamma), so the mass matrix in
    # FCC coordinates has condition ~1/gamma^2 (measured 3e14 at 1e-6) and rounding
    # grows like eps/gamma^2 (measured, dt-independent: 1.5e-9 m at 1e-3, 1e-6 at 1e-4).
    # 1e-9: RK4's difference between the two coordinate choices (measured 1.7e-10).
    bound = 1e-9 + 50 * em.EPS / gamma**2
    assert p_err < bound, (p_err, bound)
    assert w_err < 10 * bound, (w_err, bound)   # rates: one derivative rougher
    # The angle is body-fixed; it moves only with the residual of r_ij . u = l cos(gamma)
    # (by |g| / sin(gamma)), which Newton's quadratic convergence leaves far below the
    # projection tolerance: measured 3.7e-13 and 1.6e-13 rad; a factor 25 of margin.
    drift = np.max(np.abs(u_angle(r) - gamma))
    assert drift < 1e-11, drift
    assert r.info["projection_failures"] == 0


@pytest.mark.parametrize("gamma", [1e-4, 1e-6, 1e-7, 1e-9, 1e-12])
def test_u_too_nearly_parallel_is_a_model_error_naming_the_angle(gamma):
    """Below sin(gamma) = 1e-3 the rounding amplified by cond(M) ~ 1/gamma^2 would cost
    more than the solvers' accuracy (1e-6 m off after 1 s at 1e-6 rad, a singular-matrix
    stop at 1e-7: docs/extremes.md), so the loader refuses the body and says why."""
    with pytest.raises(ModelError) as info:
        load_model_text(tilted(gamma), "tilted.yaml")
    text = str(info.value)
    assert "tilted.yaml" in text and "vector u is parallel" in text
    assert f"{math.degrees(gamma):.3g} degrees" in text, text
    assert "sin(angle) >= 0.001" in text


# -- 2. mass and inertia ratios ----------------------------------------------------------

def test_deployable_axial_inertia_does_not_enter_its_planar_motion(load):
    """The paper's bars have axial inertia 653 against 1.6e7 g mm^2 transverse. Their
    hinges are all about z, so the axial inertia cannot do anything: scaling it by 1e-6
    or 1e2 (the most the triangle inequality allows for the shortest bars) must leave
    the motion unchanged, and energy is conserved."""
    text = (EXAMPLES / "deployable.yaml").read_text()
    assert text.count("inertia: [653.06,") == 4        # the replacement below bites
    runs = []
    for scale in (1.0, 1e-6, 1e2):
        s = load(text.replace("inertia: [653.06,", f"inertia: [{653.06 * scale!r},"))
        assert all(b.inertia[0, 0] == 653.06 * scale for b in s.plan.model.bodies.values())
        runs.append(s.simulate(t_end=0.2, dt=1e-3))
    names = ("F.x", "F.y", "G.x", "G.y", "T.x", "T.y")
    base = columns(runs[0], *names)
    for r in runs[1:]:
        # The axial terms vanish in the plane (measured: identical runs); the bound
        # allows rounding of quantities ~1e3 mm through 200 steps, should that change.
        assert np.max(np.abs(columns(r, *names) - base)) < 1e-9 * 1118.0
    e = runs[0]["energy"]
    # The total energy (the constant forces' potential included) holds to RK4's error:
    # measured 1.4e-9 of its size, bounded as in test_dynamics.
    drift = np.max(np.abs(e - e[0])) / np.max(np.abs(e))
    assert drift < 1e-8, drift


def test_axial_inertia_1e10_below_transverse_keeps_the_motion(load):
    """A spherical pendulum whose axial inertia is 1e-10 of its transverse one: the
    rod's motion matches the Lagrange top; its spin, carrying almost no momentum, is
    only as good as the rounding of the transverse momenta allows."""
    It, ratio, omega = 0.0833583333333333, 1e-10, [0.0, 0.0, 3.0]
    s = load(em.axisymmetric_top([0.6, 0, -0.8], [0, 1, 0], 1.0, 0.5, It * ratio, It,
                                 omega))
    init = s.initial_state()
    w0 = s.body_outputs(init.q, init.v)[0, 3:]
    r = s.simulate(t_end=3.0, dt=1e-3, output_dt=0.01)
    params = dict(m=1.0, d=0.5, L=1.0, It=It, Ia=It * ratio, g=9.81)
    tip, w, _ = minimal.spherical_top(params, minimal.top_state(init.q[:3], w0), r.t)
    P = columns(r, "P.x", "P.y", "P.z")
    W = columns(r, "rod.wx", "rod.wy", "rod.wz")
    # Positions: RK4 at 1 ms, as for the example (measured 1.6e-11 m).
    assert np.max(np.abs(P - tip)) < 1e-9
    # Spin: each evaluation resolves the axial momentum to eps*It/Ia relative (2e-6);
    # a random walk over 12000 evaluations gives sqrt(12000)*2e-6*|w| ~ 7e-4 rad/s
    # (measured 4.4e-4 in w, 6.4e-4 in the spin's range); a factor 10 of margin.
    bound = 10 * math.sqrt(4 * r.info["steps"]) * em.EPS / ratio * 3.0
    spin = np.sum(W * P, axis=1)          # |OP| = 1
    assert np.max(np.abs(W - w)) < bound
    assert np.ptp(spin) < bound
    assert np.all(np.isfinite(r["energy"]))


@pytest.mark.parametrize("ratio", [1e10, 1e-10])
def test_chain_with_mass_ratio_1e10_matches_minimal_coordinates(load, ratio):
    p = dict(m1=1.0, c1=0.5, Ia1=2e-4, It1=0.0834333333333333, m2=0.6 * ratio, c2=0.4,
             Ia2=1.2e-4 * ratio, It2=0.03206 * ratio, g=9.81)
    r = load(em.double_pendulum(p, [0.8, -0.6, 0], [1.6, -0.6, 0])).simulate(
        t_end=2.0, dt=1e-3, output_dt=0.01)
    params = dict(L1=1.0, m1=p["m1"], c1=p["c1"], I1=p["It1"], L2=0.8, m2=p["m2"],
                  c2=p["c2"], I2=p["It2"], g=9.81)
    p1, p2 = minimal.double_pendulum(params, [math.atan2(0.8, 0.6), math.pi / 2],
                                     [0.0, 0.0], r.t)
    err1 = np.max(np.abs(columns(r, "P1.x", "P1.y") - p1))
    err2 = np.max(np.abs(columns(r, "P2.x", "P2.y") - p2))
    # RK4 at 1 ms: 1e-8 m as for the example (measured 3e-10 at ratio 1e10).
    assert err1 < 1e-8, err1
    # The light rod's forces are resolved next to the heavy rod's to eps/ratio relative
    # per evaluation; a random walk over 8000 evaluations: sqrt(8000)*eps/ratio = 2e-4 m
    # at ratio 1e-10 (measured 2.2e-5 m at dt 1 ms and 1.3e-4 m at 0.5 ms: rounding,
    # not truncation).
    bound2 = 1e-8 + math.sqrt(4 * r.info["steps"]) * em.EPS / min(ratio, 1.0)
    assert err2 < bound2, (err2, bound2)


# -- 3. units ----------------------------------------------------------------------------

def test_mm_g_s_units_give_the_same_motion_as_m_kg_s(load):
    si = dict(m1=1.0, c1=0.5, Ia1=2e-4, It1=0.0834333333333333, m2=0.6, c2=0.4,
              Ia2=1.2e-4, It2=0.03206, g=9.81)
    mm = dict(m1=1e3, c1=500.0, Ia1=2e-4 * 1e9, It1=0.0834333333333333 * 1e9, m2=600.0,
              c2=400.0, Ia2=1.2e-4 * 1e9, It2=0.03206 * 1e9, g=9810.0)
    P1, P2 = np.array([0.8, -0.6, 0.0]), np.array([1.6, -0.6, 0.0])
    a = load(em.double_pendulum(si, P1, P2)).simulate(t_end=2.0, dt=1e-3, output_dt=0.01)
    b = load(em.double_pendulum(mm, 1e3 * P1, 1e3 * P2)).simulate(t_end=2.0, dt=1e-3,
                                                                output_dt=0.01)
    names = ("P1.x", "P1.y", "P2.x", "P2.y")
    rel = np.max(np.abs(columns(b, *names) / 1e3 - columns(a, *names))) / 1.6
    # Every tolerance of the runtime is relative (rank) or scaled by the body length
    # (projection), so the two runs differ by rounding only (measured 4e-15 relative).
    assert rel < 1e-9, rel
    # Energy in g mm^2/s^2 is 1e9 times the energy in J.
    e_rel = np.max(np.abs(b["energy"] / 1e9 - a["energy"])) / np.max(np.abs(a["energy"]))
    assert e_rel < 1e-9, e_rel
