"""The NumPy solver: the constrained solve against the KKT system, then short runs of
small models built here (pendulum, free tumbling body, four-bar with redundant hinge
constraints, slider-crank with point_on_line) against conservation laws and an
independent minimal-coordinate solution."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

from fccgen.errors import SimulationError
from fccgen.model.types import (AngularVelocity, Body, Distance, Force, Initial, Model,
                                Point, PointOnLine, SimulateDefaults, Spring, Vector, Where)
from fccgen.numeric import NumericSolver, constrained_solve
from fccgen.plan import make_plan
from fccgen.model.geometry import body_rotation

HERE = Where("test.yaml", None)


# -- constrained_solve ----------------------------------------------------------------
def kkt_case(seed, n=9, m=4):
    """M of rank 6 (PSD, like one body), random B, Q, b: the KKT matrix is regular."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, 6))
    return A @ A.T, rng.normal(size=(m, n)), rng.normal(size=n), rng.normal(size=m)


def kkt_solve(M, B, Q, b):
    m = B.shape[0]
    K = np.block([[M, B.T], [B, np.zeros((m, m))]])
    return np.linalg.solve(K, np.concatenate([Q, b]))[:M.shape[0]]


@pytest.mark.parametrize("seed", range(3))
def test_constrained_solve_matches_the_kkt_system(seed):
    M, B, Q, b = kkt_case(seed)
    x_ref = kkt_solve(M, B, Q, b)
    x = constrained_solve(M, B, Q, b)
    # both are backward stable solves of a well-conditioned system
    assert np.allclose(x, x_ref, rtol=0, atol=1e-10 * np.abs(x_ref).max())


def test_constrained_solve_with_redundant_and_badly_scaled_rows():
    M, B, Q, b = kkt_case(5)
    x_ref = kkt_solve(M, B, Q, b)
    # duplicated rows, a combination of rows, and rows scaled by 1e6 and 1e-4
    B2 = np.vstack([B, B[0], 2 * B[1] - B[2], 1e6 * B[3], 1e-4 * B[1]])
    b2 = np.concatenate([b, b[:1], [2 * b[1] - b[2]], [1e6 * b[3]], [1e-4 * b[1]]])
    x = constrained_solve(M, B2, Q, b2)
    assert np.allclose(x, x_ref, rtol=0, atol=1e-10 * np.abs(x_ref).max())
    # a zero row is left alone
    x0 = constrained_solve(M, np.vstack([B, np.zeros(9)]), Q, np.append(b, 0.0))
    assert np.allclose(x0, x_ref, rtol=0, atol=1e-10 * np.abs(x_ref).max())


def test_constrained_solve_without_constraints_is_a_plain_solve():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(5, 5))
    M, Q = A @ A.T + np.eye(5), rng.normal(size=5)
    x = constrained_solve(M, np.zeros((0, 5)), Q, np.zeros(0))
    assert np.allclose(M @ x, Q, atol=1e-12)


@pytest.mark.parametrize("M", [np.diag([1.0, 2.0, 3.0, 0.0, 0.0, 0.0]), np.zeros((6, 6))])
def test_singular_mass_on_the_null_space_is_an_error(M):
    B = np.hstack([np.eye(3), np.zeros((3, 3))])       # constrains only what has mass
    with pytest.raises(SimulationError, match="singular on the constraint manifold"):
        constrained_solve(M, B, np.ones(6), np.zeros(3))


# -- small models -----------------------------------------------------------------------
def make_model(points, vectors, bodies, constraints=(), loads=(), gravity=(0, 0, 0),
               initial=None, simulate=None, name="test"):
    """A validated Model from plain data: points/vectors {name: (xyz, fixed)}, bodies
    {name: (i, j, u, mass, center, inertia 3x3)}."""
    return Model(
        name=name, source="test.yaml", gravity=np.array(gravity, float),
        points={n: Point(n, np.array(at, float), fixed, HERE)
                for n, (at, fixed) in points.items()},
        vectors={n: Vector(n, np.array(a, float) / np.linalg.norm(a), fixed, HERE)
                 for n, (a, fixed) in vectors.items()},
        bodies={n: Body(n, i, j, u, float(m), np.array(c, float), np.array(I, float), HERE)
                for n, (i, j, u, m, c, I) in bodies.items()},
        constraints=list(constraints), loads=list(loads),
        initial=initial or Initial(), simulate=simulate or SimulateDefaults())


Z = ((0, 0, 1), True)
G = 9.81


def pendulum(theta0=-np.pi / 3, at=None, **kw):
    """A planar pendulum: O fixed, P moving, hinge axis z fixed; gravity -y."""
    P = at if at is not None else (np.cos(theta0), np.sin(theta0), 0.0)
    return make_model({"O": ((0, 0, 0), True), "P": (P, False)}, {"z": Z},
                      {"arm": ("O", "P", "z", 2.0, (0.6, 0, 0), np.diag([0.01, 0.05, 0.05]))},
                      gravity=(0, -G, 0), **kw)


def test_pendulum_follows_the_minimal_coordinate_solution_and_keeps_energy():
    solver = NumericSolver(make_plan(pendulum()))
    t_end = 0.4
    res = solver.simulate(t_end=t_end, dt=1e-3, output_dt=0.1)
    assert np.allclose(res.t, [0, 0.1, 0.2, 0.3, 0.4])
    # minimal coordinates: I_O th'' = -m g c cos(th), I_O = Izz + m c^2
    m, c, I_O = 2.0, 0.6, 0.05 + 2.0 * 0.36
    ref = scipy.integrate.solve_ivp(lambda t, y: [y[1], -m * G * c * np.cos(y[0]) / I_O],
                                    (0, t_end), [-np.pi / 3, 0.0], rtol=1e-12, atol=1e-12)
    th = ref.y[0, -1]
    # RK4 at 1 ms: global error ~1e-12 (measured 1.5e-12) on this slow motion
    assert res["P.x"][-1] == pytest.approx(np.cos(th), abs=1e-10)
    assert res["P.y"][-1] == pytest.approx(np.sin(th), abs=1e-10)
    # energy drift of RK4 at 1 ms over 400 steps plus projection: measured 1.4e-12
    assert np.ptp(res["energy"]) <= 1e-10 * abs(res["energy"][0])
    # positions projected to |g_k| / ||B_k|| <= 1e-11 l with ||B_length|| = 2 l, l = 1
    assert res.info["max_constraint_error"] <= 2e-11
    assert res.info["steps"] == 400 and res.info["rhs_evaluations"] == 1600


def test_output_schedule_lands_on_t_end():
    solver = NumericSolver(make_plan(pendulum()))
    res = solver.simulate(t_end=0.0105, dt=1e-3, output_dt=5e-3)
    assert np.allclose(res.t, [0, 0.005, 0.01, 0.0105], rtol=0, atol=1e-15)
    assert res.info["steps"] == 11 and res.info["method"] == "rk4"
    import fccgen.settings.methods
    assert set(fccgen.settings.methods.INFO_KEYS) | {"max_newton_iterations"} <= set(res.info)
    with pytest.raises(ValueError, match="whole multiple of dt"):
        solver.simulate(t_end=0.01, dt=1e-3, output_dt=2.5e-3)
    with pytest.raises(ValueError, match="available: rk4"):
        solver.simulate(t_end=0.01, dt=1e-3, method="euler")


def test_initial_state_projection_reports_residuals():
    """K given 0.05 off its line: Newton assembly moves it; A's given speed is made
    consistent with the mechanism's single degree of freedom."""
    solver = NumericSolver(make_plan(slider_crank(K_offset=0.05)))
    init = solver.initial_state()
    # the body numbers come from the given positions, so only the line is violated:
    # (K - O) x (X - O) = (0, K_z, -K_y)
    assert init.position_residual_given == pytest.approx(0.05, rel=1e-14)
    assert init.newton_iterations >= 2
    assert init.position_residual <= 2e-11              # 1e-11 l scaled, ||B_k|| <= 2 l
    assert abs(init.q[4]) <= 1e-11                       # K.y back on the line
    # one degree of freedom: the projection is the M-orthogonal one onto the tangent t
    B = solver.constraint_jacobian(init.q)
    t = scipy.linalg.null_space(B)
    assert t.shape == (6, 1)
    M, v_given = solver.mass_matrix(init.q), solver.plan.v_target
    expected = t @ np.linalg.solve(t.T @ M @ t, t.T @ M @ v_given)
    assert np.allclose(init.v, expected, atol=1e-12)    # rounding of O(1) speeds
    assert init.velocity_change == pytest.approx(np.abs(expected - v_given).max(), rel=1e-10)
    assert init.velocity_residual <= 1e-13
    assert "Newton assembly" in init.report()


def test_failed_assembly_names_the_residual():
    # a distance of 3 from O to a point the body keeps at 1 from O: no solution
    model = pendulum(constraints=[Distance(("O", "P"), 3.0, HERE)])
    solver = NumericSolver(make_plan(model), max_newton=5)
    with pytest.raises(SimulationError, match=r"did not converge in 5 Newton .*residual"):
        solver.initial_state()


def test_massless_body_cannot_be_solved():
    model = make_model({"O": ((0, 0, 0), True), "P": ((1, 0, 0), False)}, {"z": Z},
                       {"arm": ("O", "P", "z", 0.0, (0.5, 0, 0), np.zeros((3, 3)))})
    solver = NumericSolver(make_plan(model))
    with pytest.raises(SimulationError, match="singular on the constraint manifold"):
        solver.accelerations(solver.plan.q0, np.zeros(3))


def test_arrays_are_fresh():
    solver = NumericSolver(make_plan(pendulum()))
    q, v = solver.plan.q0, np.array([0.1, 0.2, 0.0])
    for name, args in [("mass_matrix", (q,)), ("constraints", (q,)),
                       ("constraint_jacobian", (q,)), ("accelerations", (q, v)),
                       ("body_outputs", (q, v)), ("project_velocities", (q, v))]:
        a, b = getattr(solver, name)(*args), getattr(solver, name)(*args)
        assert not np.shares_memory(a, b), name
    q1, _ = solver.project_positions(q)
    assert not np.shares_memory(q1, q)


def angular_momentum(res, k, I_b):
    """R I_b R^T w about the mass centre at output k, R from the result's columns."""
    A = np.array([res[f"A.{c}"][k] for c in "xyz"])
    B = np.array([res[f"B.{c}"][k] for c in "xyz"])
    u = np.array([res[f"u.{c}"][k] for c in "xyz"])
    R = body_rotation(A, B, u)
    w = np.array([res[f"box.w{c}"][k] for c in "xyz"])
    return R @ I_b @ R.T @ w


def test_free_tumbling_body_conserves_energy_and_momentum():
    I_b = np.array([[0.4, 0.03, 0.0], [0.03, 0.9, 0.02], [0.0, 0.02, 1.5]])
    center = (0.4, 0.1, -0.05)
    model = make_model({"A": ((0, 0, 0), False), "B": ((1.0, 0.2, 0.1), False)},
                       {"u": ((0.1, 1.0, 0.3), False)},
                       {"box": ("A", "B", "u", 3.0, center, I_b)})
    solver = NumericSolver(make_plan(model))
    q0 = solver.initial_state().q
    # spin near the unstable middle axis with the mass centre at rest
    w = np.array([0.4, 3.0, 0.8])
    r_G = solver.body_outputs(q0, np.zeros(9))[0, :3]
    v0 = np.concatenate([np.cross(w, q0[0:3] - r_G), np.cross(w, q0[3:6] - r_G),
                         np.cross(w, q0[6:9])])
    res = solver.simulate(t_end=0.3, dt=2e-3, output_dt=0.1, q0=q0, v0=v0)
    # RK4 at 2 ms over 150 steps with |w| ~ 3/s: measured drifts 3e-13 (energy) and
    # 4e-12 (momentum, relative); the bounds leave a factor ~30
    assert np.ptp(res["energy"]) <= 1e-11 * res["energy"][0]
    H = np.array([angular_momentum(res, k, I_b) for k in range(len(res.t))])
    assert np.abs(H - H[0]).max() <= 1e-10 * np.linalg.norm(H[0])
    c = np.array([res[f"box.c{x}"] for x in "xyz"])
    assert np.abs(c - r_G[:, None]).max() <= 1e-11        # linear momentum stays zero
    assert np.linalg.norm(res["box.wx"][-1] - w[0]) > 1e-3  # the body does tumble


def four_bar(**kw):
    """A planar four-bar of 3-D hinges sharing the fixed axis z: the three angle rows
    A.z = 0, (B - A).z = 0, B.z = 0 have rank two."""
    a, b, c, d = 0.5, 1.6, 1.0, 1.4                         # crank, coupler, rocker, ground
    A = a * np.array([np.cos(1.0), np.sin(1.0), 0.0])
    # B on the circles |B - A| = b and |B - O2| = c
    O2 = np.array([d, 0.0, 0.0])
    e = O2 - A
    dist = np.linalg.norm(e)
    x = (b ** 2 - c ** 2 + dist ** 2) / (2 * dist)
    B = A + x * e / dist + np.sqrt(b ** 2 - x ** 2) * np.array([-e[1], e[0], 0]) / dist
    inertia = lambda L, m: np.diag([1e-3, m * L ** 2 / 12, m * L ** 2 / 12])  # noqa: E731
    return make_model(
        {"O1": ((0, 0, 0), True), "O2": (O2, True), "A": (A, False), "B": (B, False)},
        {"z": Z},
        {"crank": ("O1", "A", "z", 1.0, (a / 2, 0, 0), inertia(a, 1.0)),
         "coupler": ("A", "B", "z", 2.0, (b / 2, 0, 0), inertia(b, 2.0)),
         "rocker": ("O2", "B", "z", 1.5, (c / 2, 0, 0), inertia(c, 1.5))},
        gravity=(0, -G, 0), **kw)


def test_four_bar_with_redundant_hinges_stays_on_the_manifold():
    spin = AngularVelocity(np.array([0, 0, 4.0]), "global", HERE)
    model = four_bar(initial=Initial(body_angular_velocities={"crank": spin}),
                     loads=[Spring(("O1", "B"), 20.0, None, 0.0, HERE),
                            Force("coupler", np.array([0, 3.0, 0]), (0.3, 0, 0), HERE)])
    solver = NumericSolver(make_plan(model))
    init = solver.initial_state()
    B = solver.constraint_jacobian(init.q)
    assert B.shape == (6, 6) and np.linalg.matrix_rank(B) == 5     # one redundant row
    assert init.velocity_change > 0.1                  # B was at rest: now it moves
    res = solver.simulate(t_end=0.15, dt=1e-3, output_dt=0.05, q0=init.q, v0=init.v)
    # projected to |g_k| / ||B_k|| <= 1e-11 l_max each step, ||B_length|| = 2 l <= 3.2
    assert res.info["max_constraint_error"] <= 1.6e-11 * 2
    # gravity, spring and constant force are conservative: RK4 drift over 150 steps,
    # measured 2e-13 relative
    assert np.ptp(res["energy"]) <= 1e-11 * np.abs(res["energy"]).max()
    assert np.abs(res["A.z"]).max() <= 1e-11 and np.abs(res["B.z"]).max() <= 1e-11


def slider_crank(K_offset=0.0):
    """Crank O-A and rod A-K hinged about the fixed z; K slides on the line O-X (the
    x axis): point_on_line adds a zero row and a row redundant with the hinges."""
    A = 0.3 * np.array([np.cos(0.7), np.sin(0.7), 0.0])
    K = np.array([A[0] + np.sqrt(1.0 - A[1] ** 2), K_offset, 0.0])
    return make_model(
        {"O": ((0, 0, 0), True), "X": ((1, 0, 0), True), "A": (A, False), "K": (K, False)},
        {"z": Z},
        {"crank": ("O", "A", "z", 1.0, (0.15, 0, 0), np.diag([1e-3, 0.01, 0.01])),
         "rod": ("A", "K", "z", 1.0, (0.5, 0, 0), np.diag([1e-3, 0.08, 0.08]))},
        constraints=[PointOnLine("K", ("O", "X"), HERE)], gravity=(0, -G, 0),
        initial=Initial(point_velocities={"A": np.array([-2.0, 2.5, 0.0])}))


def test_slider_crank_with_point_on_line():
    solver = NumericSolver(make_plan(slider_crank()))
    init = solver.initial_state()
    assert init.newton_iterations == 0
    assert np.linalg.matrix_rank(solver.constraint_jacobian(init.q)) == 5   # 7 rows
    res = solver.simulate(t_end=0.1, dt=1e-3, output_dt=0.05, q0=init.q, v0=init.v)
    assert res.info["max_constraint_error"] <= 2e-11    # 1e-11 l scaled, ||B_k|| <= 2 l
    assert np.abs(res["K.y"]).max() <= 1e-11 and np.abs(res["K.z"]).max() <= 1e-11
    # rk4 drift over 100 steps of a 1-dof mechanism at ~10 rad/s: measured 1.1e-10
    assert np.ptp(res["energy"]) <= 1e-9 * np.abs(res["energy"]).max()


def test_projection_removes_the_drift_of_large_steps():
    """At 5 ms the RK4 step leaves the manifold by ~1e-8: without projection the error
    stays, with it Newton brings every step back below the tolerance."""
    solver = NumericSolver(make_plan(slider_crank()))
    init = solver.initial_state()
    kw = dict(t_end=0.1, dt=5e-3, q0=init.q, v0=init.v)
    free = solver.simulate(project=False, **kw)
    projected = solver.simulate(project=True, **kw)
    assert free.info["max_constraint_error"] > 1e-9
    assert free.info["max_newton_iterations"] == 0
    assert projected.info["max_constraint_error"] <= 2e-11   # 1e-11 l, ||B_k|| <= 2 l
    assert projected.info["max_newton_iterations"] >= 1
