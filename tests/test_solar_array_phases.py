"""The solar array's deployment (examples/solar_array.yaml) done by hand in phases and
compared with the one-call run: the phase models and the impacts are written here,
independent of the event machinery.

* phase 1: the example's compiled kernels with its events removed, from the start to
  the first latch time t1 (the panel hinge P);
* impact 1: the plastic impact as the M-orthogonal projection of the velocities onto
  B v = 0 and G v = 0, G the gradient of P's angle (derived here with SymPy);
* phase 2: a second model, the example with P a weld (its spring dropped: inside one
  rigid body it does no work), from the projected state to the second latch time t2;
* impact 2 and phase 3: once the root latches too the array is one free rigid body.
  The M-orthogonal projection onto rigid motions keeps the momentum P and the
  angular momentum L (v - v+ is M-orthogonal to every rigid motion exactly when its
  P and L vanish), so v+ is the rigid motion with v = P / m, w = I^-1 L; from there
  the free rigid body turns with L fixed in space: dR/dt = [w] R, w = (R I0 R^T)^-1 L,
  integrated by SciPy's DOP853 to 1e-13.

Event times: the hand phases switch at the one-call run's located times t1 and t2,
and check them: the event-free phase 1 reaches P's latch angle pi at t1, phase 2
reaches R's pi/2 at t2, each to 1e-10 rad (the location tolerance, 1e-12 s, times
rates of ~8 rad/s, plus RK4's error). Both take the same steps: phase 1 lands on t1
by a shortened last step, as the one-call run's re-integrated partial step does;
phase 2 first takes one step to the next grid point, then steps of dt, as the
one-call run does after an event."""
from __future__ import annotations

import copy
import re
from pathlib import Path

import numpy as np
import pytest
import sympy
from scipy.integrate import solve_ivp

import fccgen.api as api
from fccgen.mechanism.outputs import _Series

from test_solar_array import INERTIA, MASS, momenta, start_series

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
DT = 1e-3


def weld_model(tmp_path) -> Path:
    """The example with the panel hinge P welded at its latch, 180 degrees (panel2
    turned about P's axis, the y axis through (0.6, 0, -0.5): its centre from
    (0.6, 0, 0) to (0.6, 0, -1); its diagonal inertia is unchanged by the half
    turn), no events, no initial speeds."""
    text = (EXAMPLES / "solar_array.yaml").read_text()
    old = ("{name: P, type: revolute, bodies: [panel1, panel2], at: [0.6, 0, -0.5], "
           "axis: [0, 1, 0]}")
    centre = "panel2: {mass: 10.0, center: [0.6, 0, 0]"
    assert old in text and centre in text
    text = text.replace(old, "{name: P, type: weld, bodies: [panel1, panel2], "
                             "at: [0.6, 0, -0.5]}")
    text = text.replace(centre, "panel2: {mass: 10.0, center: [0.6, 0, -1.0]")
    text = re.sub(r"  - \{type: torsion_spring, joint: P.*\n", "", text)
    text = text.split("initial:")[0]
    path = tmp_path / "solar_array_p_welded.yaml"
    path.write_text(text)
    return path


def state(solver, result, row=-1):
    """(q, v) of a record: every moving triple's columns, in the plan's order."""
    q = [result[f"{n}.{k}"][row] for n, _ in solver.plan.triples for k in "xyz"]
    v = [result[f"{n}.v{k}"][row] for n, _ in solver.plan.triples for k in "xyz"]
    return np.array(q), np.array(v)


def angle_gradient():
    """d(angle of P)/dq over the triples (R, P, panel2_center, P_axis): the angle is
    atan2(a . (m x x), m . x), m = R - P on panel1, x = c2 - P on panel2, a the axis."""
    R, P, C, A = (sympy.Matrix(sympy.symbols(f"{n}0:3")) for n in "RPCA")
    m, x = R - P, C - P
    theta = sympy.atan2(A.dot(m.cross(x)), m.dot(x))
    args = [*R, *P, *C, *A]
    grad = sympy.lambdify(args, [sympy.diff(theta, s) for s in args], "numpy")
    return lambda r, p, c, a: np.array(grad(*r, *p, *c, *a), float)


def project(M, A, v):
    """v+ = argmin (v+ - v)^T M (v+ - v) / 2 with A v+ = 0, from the KKT equations
    M v+ + A^T mu = M v, A v+ = 0 (least squares: M is positive only on the
    constraints' null space and B has redundant rows; v+ is unique there)."""
    n, m = len(v), A.shape[0]
    kkt = np.block([[M, A.T], [A, np.zeros((m, m))]])
    return np.linalg.lstsq(kkt, np.concatenate([M @ v, np.zeros(m)]), rcond=None)[0][:n]


def unit(x):
    return x / np.sqrt(x @ x)                     # analytic: complex steps go through


def panel1_turn(tri, tri0):
    """Panel1's rotation R(t) R(0)^T from its triples R, P and R_axis."""
    def frame(t):
        e1 = unit(t["P"] - t["R"])
        e3 = unit(np.cross(e1, t["R_axis"]))
        return np.column_stack([e1, np.cross(e3, e1), e3])
    return frame(tri) @ frame(tri0).T


def to_welded(solver, welded, q, v):
    """The revolute model's state (q, v), its hinge P at rest relative, in the welded
    model's triples: shared ones copied, P_x and P_y (panel1's axes at the weld) turned
    with panel1, their rates by a complex step along v (exact to rounding)."""
    names = [n for n, _ in solver.plan.triples]
    q0 = {n: np.array(solver.plan.q0[3 * k:3 * k + 3], float) for k, n in enumerate(names)}

    def triples(qq):
        return {n: qq[3 * k:3 * k + 3] for k, n in enumerate(names)}
    h = 1e-30
    turn = panel1_turn(triples(q), q0)
    turn_dot = panel1_turn(triples(q + 1j * h * v), q0).imag / h
    out_q, out_v = [], []
    for k, (n, _) in enumerate(welded.plan.triples):
        if n in names:
            i = names.index(n)
            out_q.append(q[3 * i:3 * i + 3])
            out_v.append(v[3 * i:3 * i + 3])
        else:
            x0 = np.array(welded.plan.q0[3 * k:3 * k + 3], float)
            out_q.append(turn @ x0)
            out_v.append(turn_dot @ x0)
    return np.concatenate(out_q), np.concatenate(out_v)


def run_to(solver, q, v, t_from, t_to):
    """From t_from: one step to the next multiple of DT if t_from is off the grid,
    then steps of DT, the last one shortened to land on t_to."""
    k = np.ceil(t_from / DT - 1e-9)
    first = min(k * DT, t_to) - t_from
    if first > 1e-14:
        r = solver.simulate(t_end=first, dt=first, method="rk4", q0=q, v0=v)
        q, v = state(solver, r)
        t_from += first
    if t_to - t_from > 1e-14:
        r = solver.simulate(t_end=t_to - t_from, dt=DT, method="rk4", q0=q, v0=v)
        q, v = state(solver, r)
    return q, v, r


def rigid_motion(solver, result, t):
    """Impact 2 and phase 3: from the last record of ``result``, the rigid motion with
    its momentum P and angular momentum L about the centre of mass c, after a time t:
    the body centres c + v t + R(t) (c_b - c) and the angular velocity, with
    I0 the inertia about c at the impact, w = R I0^-1 R^T L and dR/dt = [w] R."""
    P, L = (x[-1] for x in momenta(solver, result))
    series = _Series(solver.plan, result.columns, len(result.t))
    start = start_series(solver.plan)
    m = sum(MASS.values())
    c = {b: np.array([result[f"{b}.c{k}"][-1] for k in "xyz"]) for b in MASS}
    cg = sum(MASS[b] * c[b] for b in MASS) / m
    I0 = np.zeros((3, 3))
    for b in MASS:
        turn = series.rotation(b)[-1] @ start.rotation(b)[0].T
        d = c[b] - cg
        I0 += turn @ INERTIA[b] @ turn.T + MASS[b] * (d @ d * np.eye(3) - np.outer(d, d))
    inv = np.linalg.inv(I0)

    def rate(_, y):
        R = y.reshape(3, 3)
        w = R @ inv @ R.T @ L
        return (np.cross(w, R.T).T).ravel()              # [w] R, column by column
    sol = solve_ivp(rate, (0.0, t), np.eye(3).ravel(), method="DOP853", rtol=1e-13,
                    atol=1e-13)
    R = sol.y[:, -1].reshape(3, 3)
    centres = {b: cg + P / m * t + R @ (c[b] - cg) for b in MASS}
    return centres, R @ inv @ R.T @ L


@pytest.fixture(scope="module")
def welded(build_dir, tmp_path_factory):
    return api.load(weld_model(tmp_path_factory.mktemp("phases")), build_dir)


def test_deployment_equals_the_run_by_hand_in_phases(compiled, welded):
    """At the end (t = 3 s, 0.94 s after the second latch) every body's centre and
    angular velocity agree with the one-call run to 1e-9 (m, rad/s), as the issue
    asks; measured 1.2e-11 m and 1.9e-11 rad/s. What separates them: phase 2 holds
    the latch by the weld's rows, the one-call run by the lock row on the angle, and
    RK4's stages off the constraint manifold see the two differently (an O(dt^5) local
    difference, like RK4's own error, ~1e-11 here); phase 3 is integrated to 1e-13.
    The impact by hand also removes the kinetic energy the event table reports, to
    1e-9 relative (measured 7e-16 and 2e-16: the same projection, solved
    differently; 1e-9 as for the rest)."""
    solver = compiled("solar_array")
    t_end = 3.0
    one = solver.simulate(t_end=t_end, dt=DT, method="rk4")
    t1, t2 = (r["t"] for r in one.events)

    plain = copy.copy(solver)
    plain._event_set = lambda tol, rest: None               # phase 1: no events
    phase1 = plain.simulate(t_end=t1, dt=DT, method="rk4")
    q, v = state(plain, phase1)
    assert abs(phase1["P.angle"][-1] - np.pi) <= 1e-10

    names = [n for n, _ in solver.plan.triples]
    at = {n: 3 * names.index(n) for n in ("R", "P", "panel2_center", "P_axis")}
    G = np.zeros(len(q))
    grad = angle_gradient()(*(q[at[n]:at[n] + 3] for n in
                             ("R", "P", "panel2_center", "P_axis")))
    for k, n in enumerate(("R", "P", "panel2_center", "P_axis")):
        G[at[n]:at[n] + 3] += grad[3 * k:3 * k + 3]
    A = np.vstack([solver.constraint_jacobian(q), G])
    M = solver.mass_matrix(q)
    before = v @ M @ v / 2
    v = project(M, A, v)                                     # impact 1
    row = one.events[0]
    assert abs(before - row["kinetic_energy_before"]) <= 1e-9 * before
    assert abs(v @ M @ v / 2 - row["kinetic_energy_after"]) <= 1e-9 * before
    q, v = to_welded(solver, welded, q, v)
    q, v, phase2 = run_to(welded, q, v, t1, t2)
    assert abs(phase2["R.angle"][-1] - np.pi / 2) <= 1e-10

    t_rigid = t_end - t2                                     # impact 2, phase 3
    centres, w_end = rigid_motion(welded, phase2, t_rigid)
    for b in MASS:
        got = np.array([one[f"{b}.c{k}"][-1] for k in "xyz"])
        assert np.max(np.abs(got - centres[b])) <= 1e-9, b
        w = np.array([one[f"{b}.w{k}"][-1] for k in "xyz"])
        assert np.max(np.abs(w - w_end)) <= 1e-9, b
    assert np.linalg.norm(w_end) > 0.01                      # still turning: not vacuous
