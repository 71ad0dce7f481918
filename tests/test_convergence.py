"""Fixed-step and adaptive methods converge at their order down to ~1e-11 m: nothing in
the step, the projections or the rank decision puts a floor under the accuracy.

References are independent of fccgen: the A01 pendulum in its joint angle, and a planar
10-link pendulum of uniform rods in absolute angles (Lagrange's equations below),
both integrated with SciPy's DOP853 at rtol = atol = 1e-13.
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp

import fccgen
from conftest import EXAMPLES
from minimal import simple_pendulum

N_LINKS, L, MASS, AXIAL = 10, 1.0, 1.0, 1e-4
T_END = 1.0


def chain_model(n: int = N_LINKS) -> str:
    """A planar chain of n uniform rods (length 1, mass 1), hinged about the fixed z
    axis, released from rest along +x (horizontal), gravity -y."""
    points = {"O": {"at": [0, 0, 0], "fixed": True}}
    points.update({f"P{k}": [float(k), 0.0, 0.0] for k in range(1, n + 1)})
    bodies = {f"rod{k}": {"points": ["O" if k == 1 else f"P{k - 1}", f"P{k}"],
                          "vector": "z", "mass": MASS, "center": [L / 2, 0, 0],
                          "inertia": [AXIAL, MASS * L ** 2 / 12, MASS * L ** 2 / 12]}
              for k in range(1, n + 1)}
    return yaml.safe_dump({"name": f"chain{n}", "gravity": [0, -9.81, 0],
                           "points": points,
                           "vectors": {"z": {"along": [0, 0, 1], "fixed": True}},
                           "bodies": bodies, "simulate": {"t_end": T_END, "dt": 1e-3}})


def chain_reference(n: int, t_end: float, g: float = 9.81) -> np.ndarray:
    """Tip position (x, y) at t_end of the chain in absolute angles theta_k from the
    downward vertical. With a_ki = L (i < k), L/2 (i = k), 0 (i > k) and
    A_ij = sum_k m a_ki a_kj, Lagrange's equations are
    sum_j A_ij [cos(th_i - th_j) th_j'' + sin(th_i - th_j) th_j'^2] + I th_i''
        + g sin(th_i) sum_k m a_ki = 0,  I = m L^2 / 12."""
    a = np.array([[L if i < k else (L / 2 if i == k else 0.0) for i in range(n)]
                  for k in range(n)])
    A = MASS * a.T @ a
    gterm = g * MASS * a.sum(axis=0)
    inertia = MASS * L ** 2 / 12

    def rhs(_, y):
        th, w = y[:n], y[n:]
        d = th[:, None] - th[None, :]
        M = A * np.cos(d) + inertia * np.eye(n)
        f = -(A * np.sin(d)) @ (w * w) - gterm * np.sin(th)
        return np.concatenate([w, np.linalg.solve(M, f)])

    y0 = np.concatenate([np.full(n, np.pi / 2), np.zeros(n)])
    sol = solve_ivp(rhs, (0.0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-13)
    assert sol.status == 0
    th = sol.y[:n, -1]
    return np.array([L * np.sin(th).sum(), -L * np.cos(th).sum()])


@pytest.fixture(scope="module")
def chain(tmp_path_factory, build_dir):
    path = tmp_path_factory.mktemp("chain") / "chain10.yaml"
    path.write_text(chain_model())
    return fccgen.load(path, build_dir), chain_reference(N_LINKS, T_END)


def _tip(result, name):
    return np.array([result[f"{name}.x"][-1], result[f"{name}.y"][-1]])


def test_rk4_converges_at_fourth_order_on_the_10_link_chain(chain):
    """Errors at dt = 1/512 ... 1/4096: each halving divides the error by 16 at
    order 4; we ask for at least 10 (rounding and the reference's own ~1e-13 leave
    room), and 1e-11 m reached at the finest step (measured: 8.7e-10, 5.9e-11,
    3.3e-12, 1.4e-13 m)."""
    solver, ref = chain
    errors = []
    for dt in (1 / 512, 1 / 1024, 1 / 2048, 1 / 4096):
        r = solver.simulate(t_end=T_END, dt=dt, output_dt=T_END / 4)
        errors.append(np.max(np.abs(_tip(r, f"P{N_LINKS}") - ref)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 10), (errors, ratios)
    assert errors[-1] < 1e-11, errors


def test_dopri5_error_follows_its_tolerance_on_the_10_link_chain(chain):
    """dopri5 with projection: the error at t = 1 falls with rtol (atol = rtol) down
    to 1e-11 m at rtol 1e-13 (measured: 7.6e-9, 5.6e-11, 2.7e-13, 2.2e-14 m at rtol
    1e-8, 1e-10, 1e-12, 1e-13)."""
    solver, ref = chain
    errors = []
    for tol in (1e-8, 1e-10, 1e-12, 1e-13):
        r = solver.simulate(t_end=T_END, method="dopri5", rtol=tol, atol=tol,
                            output_dt=T_END / 4)
        errors.append(np.max(np.abs(_tip(r, f"P{N_LINKS}") - ref)))
    assert errors[0] > 10 * errors[2], errors
    assert errors[-1] < 1e-11, errors


def test_rk4_and_dopri5_converge_on_a01(compiled):
    """The A01 pendulum (point mass, L = 1, released horizontally) against its joint
    angle solution over 2 s: rk4 at fourth order to 1e-11 m, dopri5 to 1e-11 m at
    rtol = atol = 1e-13 (measured: rk4 4.3e-9, 2.7e-10, 1.6e-11, 2.7e-13 m at
    dt = 1/256 ... 1/2048; dopri5 9.9e-13 m)."""
    solver = compiled("a01_pendulum")
    x_ref, y_ref = simple_pendulum(1.0, 9.81, -np.pi / 2, 0.0, np.array([0.0, 2.0]))
    ref = np.array([x_ref[-1], y_ref[-1]])
    errors = []
    for dt in (1 / 256, 1 / 512, 1 / 1024, 1 / 2048):
        r = solver.simulate(t_end=2.0, dt=dt, output_dt=0.5)
        errors.append(np.max(np.abs(_tip(r, "P") - ref)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 10), (errors, ratios)
    assert errors[-1] < 1e-11, errors
    r = solver.simulate(t_end=2.0, method="dopri5", rtol=1e-13, atol=1e-13, output_dt=0.5)
    assert np.max(np.abs(_tip(r, "P") - ref)) < 1e-11
