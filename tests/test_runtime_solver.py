"""The compiled runtime end to end: small models built in the test (fccgen.model.types,
no model file), their kernels generated and compiled into pytest's temporary folders,
and CompiledSolver checked against physics (energy, a minimal-coordinate pendulum),
against the NumPy version, and on its error paths."""
from __future__ import annotations

import ctypes
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fccgen.build import build_module, load_module
from fccgen.errors import BuildError, SimulationError
from fccgen.model.types import (AngularVelocity, Body, BodyPoint, Initial, Model, Point,
                                SimulateDefaults, Spring, Torque, Vector, Where)
from fccgen.numeric import NumericSolver
from fccgen.plan import make_plan
from fccgen.runtime import CompiledSolver
from fccgen.runtime._assemble import ABI_VERSION, Assembler
from fccgen.runtime._rk4 import simulate_rk4

ROOT = Path(__file__).resolve().parent.parent
W = Where("test.yaml", None)
Z = np.array([0.0, 0.0, 1.0])

# Pendulum numbers: rod of length L, mass centre at C from the pivot, inertia about z.
L, C, MASS, IZ, G = 1.2, 0.5, 2.0, 0.07, 9.81
THETA0 = 0.9


def _model(name, points, vectors, bodies, gravity, loads=(), initial=None, **sim):
    return Model(name, "test.yaml", np.asarray(gravity, float),
                 {p.name: p for p in points}, {v.name: v for v in vectors},
                 {b.name: b for b in bodies}, [], list(loads), initial or Initial(),
                 SimulateDefaults(**sim))


def pendulum_model():
    """A planar compound pendulum: the fixed axis z is the body's u, so e2 = z and the
    inertia about the axis is Iyy."""
    p = np.array([L * math.sin(THETA0), -L * math.cos(THETA0), 0.0])
    return _model("pendulum", [Point("O", np.zeros(3), True, W), Point("P", p, False, W)],
                  [Vector("z", Z, True, W)],
                  [Body("arm", "O", "P", "z", MASS, np.array([C, 0, 0]),
                        np.diag([0.01, IZ, 0.08]), W)],
                  [0.0, -G, 0.0], t_end=1.0, dt=1e-3)


def four_bar_model():
    """A planar four-bar built from 3-D hinges about the fixed z axis: the three
    "perpendicular to z" rows have rank 2, so B (6 x 6) has rank 5: redundant."""
    pts = [Point("O", np.zeros(3), True, W), Point("A", np.array([2.0, 0, 0]), True, W),
           Point("P1", np.array([0.0, 1.0, 0]), False, W),
           Point("P2", np.array([2.0, 1.5, 0]), False, W)]
    rod = dict(center=np.array([0.5, 0, 0]), inertia=np.diag([1e-3, 0.1, 0.1]), where=W)
    bodies = [Body("crank", "O", "P1", "z", 1.0, **rod),
              Body("coupler", "P1", "P2", "z", 1.5, **rod),
              Body("rocker", "A", "P2", "z", 1.2, **rod)]
    init = Initial(body_angular_velocities={
        "crank": AngularVelocity(np.array([0.0, 0.0, 3.0]), "global", W)})
    return _model("four_bar", pts, [Vector("z", Z, True, W)], bodies, [0.0, -G, 0.0],
                  initial=init, t_end=0.5, dt=1e-3)


def top_model():
    """A spatial body with a moving vector, springs to body points and a torque:
    unit-vector, spring and torque classes (some kernels NULL)."""
    pts = [Point("O", np.zeros(3), True, W), Point("P", np.array([0.0, 0.0, 1.0]), False, W),
           Point("K", np.array([0.5, 0.5, 1.5]), True, W)]
    body = Body("top", "O", "P", "u", 3.0, np.array([0.6, 0.05, 0.02]),
                np.array([[0.02, 0.001, 0], [0.001, 0.05, 0.002], [0, 0.002, 0.06]]), W)
    loads = [Spring(("K", BodyPoint("top", (1.0, 0.1, 0.0))), 40.0, 0.3, 0.0, W),
             Torque("top", np.array([0.0, 0.2, 0.1]), W),
             # both ends on the body, and P twice among the spring's triples: the
             # element has more local coordinates (9) than the model (6)
             Spring(("P", BodyPoint("top", (0.5, 0.3, 0.1))), 25.0, 0.2, 0.5, W)]
    init = Initial(body_angular_velocities={
        "top": AngularVelocity(np.array([0.3, 0.2, 6.0]), "body", W)})
    return _model("top", pts, [Vector("u", np.array([1.0, 0, 0]), False, W)], [body],
                  [0.0, 0.0, -G], loads, init, t_end=0.2, dt=1e-3)


MODELS = {"pendulum": pendulum_model, "four_bar": four_bar_model, "top": top_model}


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """name -> (plan, generated module), each model built once into a temporary folder."""
    out = tmp_path_factory.mktemp("generated")
    cache = {}

    def get(name):
        if name not in cache:
            plan = make_plan(MODELS[name]())
            cache[name] = plan, load_module(build_module(plan, out))
        return cache[name]
    return get


@pytest.fixture(scope="module")
def solvers(built):
    def get(name, **options):
        plan, module = built(name)
        return CompiledSolver(plan, module, **options), NumericSolver(plan, **options)
    return get


def amax(x):
    return float(np.max(np.abs(x))) if np.size(x) else 0.0


def random_state(ns, rng, spread=0.05):
    """A consistent state near the initial one (projected by the numeric version)."""
    q0 = ns.initial_state().q
    q, _ = ns.project_positions(q0 + rng.normal(scale=spread, size=q0.shape))
    return q, ns.project_velocities(q, rng.normal(size=q.shape))


# -- physics -----------------------------------------------------------------------------

def test_pendulum_matches_minimal_coordinates(solvers):
    """The angle from the FCC solution against theta'' = -m g c sin(theta) / I_O
    integrated with DOP853 at rtol 1e-12: RK4 at dt = 1e-3 over 1 s is off by ~7e-12
    rad here (measured), so 1e-10 rad bounds both errors with room."""
    cs, _ = solvers("pendulum")
    r = cs.simulate(output_dt=0.1)
    i_o = IZ + MASS * C ** 2
    ref = solve_ivp(lambda t, s: [s[1], -MASS * G * C / i_o * math.sin(s[0])], (0, 1.0),
                    [THETA0, 0.0], method="DOP853", t_eval=r.t, rtol=1e-12, atol=1e-12)
    theta = np.arctan2(r["P.x"], -r["P.y"])
    assert np.allclose(r.t, np.arange(11) * 0.1, rtol=0, atol=1e-12)
    assert amax(theta - ref.y[0]) < 1e-10


def test_pendulum_energy_is_conserved(solvers):
    """RK4 (dt 1e-3, 1 s) conserves energy to its local error: ~1.3e-12 of the energy
    scale m g L here (measured); 1e-11 of it catches any wrong term in h or f."""
    cs, _ = solvers("pendulum")
    r = cs.simulate()
    assert amax(r["energy"] - r["energy"][0]) < 1e-11 * MASS * G * L
    assert r.info["rhs_evaluations"] == 4 * 1000 and r.info["steps"] == 1000


def scaled_residuals(cs, result):
    """max_k |g_k| / ||B_k|| at every recorded state."""
    cols = [f"{name}.{c}" for name, _ in cs.plan.triples for c in "xyz"]
    out = []
    for q in np.column_stack([result[c] for c in cols]):
        g, B = cs.constraints(q), cs.constraint_jacobian(q)
        out.append(amax(g / np.linalg.norm(B, axis=1)))
    return np.array(out)


@pytest.mark.parametrize("name", ["four_bar", "top"])
def test_projection_keeps_the_constraints(solvers, name):
    """With projection every recorded state meets the Newton tolerance exactly as
    defined; without it, RK4 at a coarse step (dt 1e-2, 1 s) drifts far beyond."""
    cs, _ = solvers(name)
    kw = dict(t_end=1.0, dt=1e-2, output_dt=0.1)
    r = cs.simulate(**kw)
    assert np.all(scaled_residuals(cs, r) <= cs.position_tol)
    assert r.info["projection_failures"] == 0 and r.info["max_newton_iterations"] >= 1
    free = cs.simulate(project=False, **kw)
    assert amax(scaled_residuals(cs, free)) > 1e3 * cs.position_tol


def test_four_bar_energy_is_conserved(solvers):
    """RK4 at dt 1e-3 over 0.5 s with projection: energy error at the level of the
    integrator's local error (measured 8e-10 J of 32 J); 1e-8 J bound."""
    cs, _ = solvers("four_bar")
    r = cs.simulate()
    assert amax(r["energy"] - r["energy"][0]) < 1e-8


def test_four_bar_has_redundant_rows(solvers):
    """6 coordinates, 6 rows of rank 5: the engine reports the rank it found."""
    cs, ns = solvers("four_bar")
    q, v = random_state(ns, np.random.default_rng(1))
    cs.accelerations(q, v)
    assert (cs.n_q, cs.n_g, cs._engine.rank) == (6, 6, 5)


# -- compiled against numeric ---------------------------------------------------------------

# Same formulas and the same algorithm in double precision, summed in different orders:
# differences are rounding, amplified a little by the solve's conditioning.
REL = 1e-12


@pytest.mark.parametrize("name", list(MODELS))
def test_accelerations_and_projections_agree(solvers, name):
    cs, ns = solvers(name)
    rng = np.random.default_rng(3)
    for _ in range(4):
        q, v = random_state(ns, rng)
        a = ns.accelerations(q, v)
        assert amax(cs.accelerations(q, v) - a) <= REL * amax(a)
        w = rng.normal(size=q.shape)
        pv = ns.project_velocities(q, w)
        assert amax(cs.project_velocities(q, w) - pv) <= REL * amax(w)
        off = q + rng.normal(scale=1e-3, size=q.shape)
        qc, itc = cs.project_positions(off)
        qn, itn = ns.project_positions(off)
        assert itc == itn
        assert amax(qc - qn) <= REL * amax(q)


@pytest.mark.parametrize("name", list(MODELS))
def test_short_simulations_agree(solvers, name):
    """25 projected steps, the last one shortened (t_end not a multiple of dt)."""
    cs, ns = solvers(name)
    dt = 1e-3
    kw = dict(t_end=24.5 * dt, dt=dt, output_dt=5 * dt)
    rc, rn = cs.simulate(**kw), ns.simulate(**kw)
    assert rc.names == rn.names
    assert np.allclose(rc.t, [0, 5e-3, 1e-2, 1.5e-2, 2e-2, 24.5e-3], rtol=0, atol=1e-15)
    for col in rn.names:
        if col != "constraint_error":    # differences of rounding-level numbers
            assert amax(rc[col] - rn[col]) <= REL * max(amax(rn[col]), 1.0), col
    assert rc.info["steps"] == rn.info["steps"] == 25


def test_initial_state_agrees(solvers):
    cs, ns = solvers("four_bar")
    ic, inn = cs.initial_state(), ns.initial_state()
    assert amax(ic.q - inn.q) <= REL and amax(ic.v - inn.v) <= REL * amax(inn.v)
    assert ic.velocity_residual <= 1e-13         # B v = 0 to rounding of |v| ~ 3
    assert ic.velocity_change > 0.1              # P2 was given at rest: it had to move


# -- interface -------------------------------------------------------------------------------

def test_arrays_are_fresh(solvers):
    """Every returned array is a new array (docs/design.md §7), inputs are not modified."""
    cs, ns = solvers("four_bar")
    q, v = random_state(ns, np.random.default_rng(5))
    for fn, args in ((cs.accelerations, (q, v)), (cs.mass_matrix, (q,)),
                     (cs.constraint_jacobian, (q,)), (cs.h_vector, (q, v)),
                     (cs.body_outputs, (q, v)), (cs.project_velocities, (q, v))):
        a, b = fn(*args), fn(*args)
        assert not np.shares_memory(a, b)
        a[...] = np.nan
        assert np.all(np.isfinite(fn(*args)))
    frozen_q, frozen_v = q.copy(), v.copy()
    frozen_q.flags.writeable = frozen_v.flags.writeable = False      # read-only inputs
    assert np.array_equal(cs.accelerations(frozen_q, frozen_v), cs.accelerations(q, v))
    assert np.array_equal(cs.mass_matrix(frozen_q), cs.mass_matrix(q))
    q_in = q + 1e-3
    keep = q_in.copy()
    q_out, _ = cs.project_positions(q_in)
    assert np.array_equal(q_in, keep) and not np.shares_memory(q_in, q_out)
    r1, r2 = cs.simulate(t_end=0.01), cs.simulate(t_end=0.01)
    assert not np.shares_memory(r1["P1.x"], r2["P1.x"])
    assert np.array_equal(r1.table(), r2.table())


def test_output_schedule_and_argument_errors(solvers):
    cs, _ = solvers("pendulum")
    r = cs.simulate(t_end=0.0105, dt=1e-3, output_dt=4e-3)
    assert np.allclose(r.t, [0, 4e-3, 8e-3, 0.0105], rtol=0, atol=1e-15)
    assert r.info["steps"] == 11
    with pytest.raises(ValueError, match="multiple of dt"):
        cs.simulate(t_end=0.01, dt=1e-3, output_dt=2.5e-3)
    with pytest.raises(ValueError, match="available: rk4"):
        cs.simulate(method="euler")
    with pytest.raises(ValueError, match="t_end"):
        cs.simulate(t_end=-1.0)


def test_progress_pauses_do_not_change_the_run(solvers):
    """A pause after every step (progress interval 0) gives the same numbers bit for
    bit: the pause only drops the reused factorisation, refactored identically."""
    cs, _ = solvers("four_bar")
    init = cs.initial_state()
    args = (init.q, init.v, 0.02, 1e-3, 20, 1, True)
    seen = []
    paused, _ = simulate_rk4(cs._engine, *args, progress=seen.append, progress_interval=0.0)
    plain, _ = simulate_rk4(cs._engine, *args)
    assert np.allclose(seen, np.arange(1, 20) * 1e-3, rtol=0, atol=1e-15)
    for key in plain:
        assert np.array_equal(paused[key], plain[key]), key
    messages = []
    cs.simulate(t_end=0.01, progress=messages.append)   # well under 0.5 s: no message
    assert messages == []


def test_a_failing_callback_stops_the_run_and_leaves_the_engine_usable(solvers):
    cs, _ = solvers("pendulum")
    init = cs.initial_state()

    def stop(_t):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        simulate_rk4(cs._engine, init.q, init.v, 0.01, 1e-3, 10, 1, True, progress=stop,
                                progress_interval=0.0)
    assert cs.simulate(t_end=0.01).info["steps"] == 10


def test_timing_helpers(solvers):
    cs, ns = solvers("top")
    q, v = random_state(ns, np.random.default_rng(2))
    times = cs.time_kernels(q, v, repeats=10)
    assert set(times) == {"mass_matrix", "h_vector", "applied_forces", "constraints",
                          "constraint_jacobian", "constraint_bias", "energy",
                          "body_outputs", "force_jacobian_q", "force_jacobian_v"}
    assert all(t > 0 for t in times.values()) and cs.time_accelerations(q, v, 10) > 0


def test_runtime_does_not_import_sympy(tmp_path):
    from conftest import run_python
    code = ("import sys, fccgen.runtime, fccgen.runtime.solver, fccgen.runtime._engine;"
            "assert 'sympy' not in sys.modules, 'sympy imported'")
    run_python(code, tmp_path)


# -- errors ------------------------------------------------------------------------------------

def with_params(plan, element, **values):
    """A copy of the plan with some parameters of one element changed (same classes,
    so the same compiled module serves it)."""
    els = list(plan.elements)
    el = els[element]
    params = el.params.copy()
    for name, value in values.items():
        params[el.cls.param_names.index(name)] = value
    els[element] = dataclasses.replace(el, params=params)
    return dataclasses.replace(plan, elements=els)


def test_singular_mass_matrix_raises(built):
    plan, module = built("pendulum")
    massless = with_params(plan, 0, m=0.0, Ixx=0.0, Iyy=0.0, Izz=0.0)
    cs = CompiledSolver(massless, module)
    q, v = plan.q0, np.zeros(3)
    with pytest.raises(SimulationError, match="singular on the constraint manifold"):
        cs.accelerations(q, v)
    with pytest.raises(SimulationError, match=r"stopped at t = 0: mass matrix singular.*"
                                              r"RK4 stage 1"):
        cs.simulate(t_end=0.01, q0=q, v0=v)


def test_non_finite_forces_stop_the_run(built):
    plan, module = built("pendulum")
    cs = CompiledSolver(with_params(plan, 0, gy=np.inf), module)
    with pytest.raises(SimulationError, match="non-finite applied forces f in RK4 stage 1"):
        cs.simulate(t_end=0.01, q0=plan.q0, v0=np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        cs.simulate(t_end=0.01, q0=np.full(3, np.nan), v0=np.zeros(3))


def test_position_projection_that_cannot_converge_raises(solvers):
    cs, _ = solvers("pendulum", max_newton=1)
    off = cs.plan.q0 * 1.3
    with pytest.raises(SimulationError, match="did not converge"):
        cs.project_positions(off)


def test_module_that_does_not_match_the_plan(built):
    plan, _ = built("pendulum")
    _, other = built("four_bar")
    with pytest.raises(BuildError, match="does not match the model's plan|element classes"):
        CompiledSolver(plan, other)
    with pytest.raises(BuildError, match="not a generated kernel module"):
        CompiledSolver(plan, math)


class _Table(ctypes.Structure):
    _fields_ = [("abi_version", ctypes.c_int), ("structure_hash", ctypes.c_char_p),
                ("n_classes", ctypes.c_int), ("classes", ctypes.c_void_p)]


def _capsule(obj, name: bytes):
    new = ctypes.pythonapi.PyCapsule_New
    new.restype = ctypes.py_object
    new.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p]
    return new(ctypes.addressof(obj), name, None)


def test_capsule_name_and_abi_version_are_checked():
    table = _Table(ABI_VERSION + 1, b"x", 0, None)
    empty = dict(class_names=[], class_sizes=np.zeros((0, 3)), class_of=[], q_ptr=[0],
                 q_idx=[], param_ptr=[0], params=[], n_q=0, body_elements=[])
    with pytest.raises(BuildError, match="ABI version"):
        Assembler(_capsule(table, b"fccgen.model_table"), **empty)
    with pytest.raises(BuildError, match="PyCapsule named 'fccgen.model_table'"):
        Assembler(_capsule(table, b"something.else"), **empty)
