"""The minimal-coordinate references (tests/minimal.py) against known facts, the A01
benchmark data against the simple-pendulum reference, and the example models against
the rules of the model file and the degrees of freedom their comments state."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.special import ellipk

import minimal
from conftest import EXAMPLES, REFERENCE, example_module

# -- simple pendulum -------------------------------------------------------------------


def _crossing_times(t, x):
    """Times where x changes sign from negative to positive, by linear interpolation."""
    k = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    return t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])


def _period(L, g, theta0, t_end, dt):
    t = np.arange(0.0, t_end, dt)
    x, _ = minimal.simple_pendulum(L, g, theta0, 0.0, t)
    return np.mean(np.diff(_crossing_times(t, x)))


def test_small_amplitude_period_is_2pi_sqrt_L_over_g():
    L, g = 0.7, 9.81
    T0 = 2 * np.pi * np.sqrt(L / g)
    T = _period(L, g, 1e-4, 10 * T0, T0 / 4000)
    # the amplitude correction theta0^2/16 is 6e-10; the crossings are at inflection
    # points, where linear interpolation is exact to third order in the step
    assert abs(T / T0 - 1) < 1e-8


def test_large_amplitude_period_is_the_elliptic_integral():
    L, g, theta0 = 1.0, 9.81, np.pi / 2          # the A01 swing
    T_exact = 4 * np.sqrt(L / g) * ellipk(np.sin(theta0 / 2) ** 2)
    T = _period(L, g, theta0, 10 * T_exact, T_exact / 4000)
    # interpolation error of the crossing ~ (dt)^3 x''' / x' ~ 1e-12 relative
    assert abs(T / T_exact - 1) < 1e-9


def test_simple_pendulum_conserves_energy():
    L, g = 1.0, 9.81
    t = np.linspace(0.0, 100.0, 2001)
    s = minimal.simple_pendulum_states(L, g, 2.5, 1.0, t)
    E = 0.5 * L**2 * s[:, 1] ** 2 - g * L * np.cos(s[:, 0])
    # rtol = atol = 1e-12 per step over ~1e4 steps: drift well below 1e-10 of E's scale
    assert np.max(np.abs(E - E[0])) < 1e-10 * (g * L)


# -- A01 benchmark data ----------------------------------------------------------------

A01_THETA0 = -np.pi / 2      # the mass starts at (-1, 0): horizontal, to the left
A01_OMEGA0 = 0.0             # at rest


def test_a01_reference_data_is_the_pendulum_released_at_rest_from_x_minus_1():
    data = np.loadtxt(REFERENCE / "mbsbenchmark_A01_solution_data.txt", skiprows=1)
    assert data.shape == (4001, 3)
    t = data[:, 0]
    assert t[0] == 0.0 and t[-1] == 2000.0
    x, y = minimal.simple_pendulum(1.0, 9.81, A01_THETA0, A01_OMEGA0, t)
    # the data carry 6 significant digits of numbers up to 1 in size: rounding alone is
    # up to 5e-7; 1e-6 (one unit in the last digit) also covers the reference's own
    # integration error (the largest difference measured is 5.6e-7)
    assert np.max(np.abs(x - data[:, 1])) < 1e-6
    assert np.max(np.abs(y - data[:, 2])) < 1e-6


def test_a01_example_starts_where_the_reference_data_start():
    data = np.loadtxt(REFERENCE / "mbsbenchmark_A01_solution_data.txt", skiprows=1)
    model = yaml.safe_load((EXAMPLES / "a01_pendulum.yaml").read_text())
    start = [np.sin(A01_THETA0), -np.cos(A01_THETA0), 0.0]
    # the data's first row is exact (-1, 0); sin/cos of -pi/2 round to 1e-16
    np.testing.assert_allclose(model["points"]["P"], start, atol=1e-15)
    np.testing.assert_allclose(data[0, 1:], start[:2], atol=1e-15)
    assert "initial" not in model and A01_OMEGA0 == 0.0           # both at rest
    assert model["gravity"] == [0, -9.81, 0]
    assert model["simulate"]["t_end"] == data[-1, 0]
    assert model["simulate"]["output_dt"] == data[1, 0] - data[0, 0]


def test_a02_reference_data_is_complete():
    lines = [ln for ln in (REFERENCE / "mbsbenchmark_A02_solution_data_B0.csv")
             .read_text().splitlines() if not ln.startswith("#")]
    assert lines[0] == "Time,DX,DY"
    data = np.loadtxt(lines[1:], delimiter=",")
    assert data.shape == (401, 3)
    np.testing.assert_allclose(data[:, 0], np.arange(401) * 0.05, atol=1e-12)
    # B0 starts at (0, 1): the top of the first crank of unit length
    np.testing.assert_allclose(data[0, 1:], [0.0, 1.0], atol=1e-12)


# -- double pendulum -------------------------------------------------------------------

RODS = {"L1": 1.0, "m1": 1.0, "c1": 0.5, "I1": 1.0 / 12, "L2": 0.8, "m2": 0.6, "c2": 0.4,
        "I2": 0.6 * 0.64 / 12, "g": 9.81}


def test_double_pendulum_conserves_energy():
    t = np.linspace(0.0, 10.0, 1001)
    s = minimal.double_pendulum_states(RODS, [0.9, 2.0], [0.0, 1.0], t)
    E = minimal.double_pendulum_energy(RODS, s)
    scale = (RODS["m1"] + RODS["m2"]) * RODS["g"] * (RODS["L1"] + RODS["L2"])
    # chaotic motion, rtol = atol = 1e-12 per step: the drift stays below 1e-10 of m g L
    assert np.max(np.abs(E - E[0])) < 1e-10 * scale


def _point_mass_double_pendulum(m1, m2, L1, L2, g):
    """The textbook closed form for two point masses on massless rods (absolute angles
    from the downward vertical), written independently of minimal.py."""
    def rhs(_t, s):
        t1, t2, w1, w2 = s
        d = t1 - t2
        den = 2 * m1 + m2 - m2 * np.cos(2 * d)
        a1 = (-g * (2 * m1 + m2) * np.sin(t1) - m2 * g * np.sin(t1 - 2 * t2)
              - 2 * np.sin(d) * m2 * (w2**2 * L2 + w1**2 * L1 * np.cos(d))) / (L1 * den)
        a2 = (2 * np.sin(d) * (w1**2 * L1 * (m1 + m2) + g * (m1 + m2) * np.cos(t1)
                               + w2**2 * L2 * m2 * np.cos(d))) / (L2 * den)
        return [w1, w2, a1, a2]
    return rhs


def test_double_pendulum_with_point_masses_matches_the_textbook_equations():
    p = {"L1": 1.2, "m1": 0.7, "c1": 1.2, "I1": 0.0, "L2": 0.9, "m2": 0.4, "c2": 0.9,
         "I2": 0.0, "g": 9.81}
    t = np.linspace(0.0, 3.0, 301)
    s = minimal.double_pendulum_states(p, [1.0, -0.5], [0.3, 0.0], t)
    s_ref = minimal.integrate(_point_mass_double_pendulum(0.7, 0.4, 1.2, 0.9, 9.81),
                              [1.0, -0.5, 0.3, 0.0], t)
    # two integrations of the same ODE at 1e-12 over 3 s of mildly chaotic motion
    assert np.max(np.abs(s - s_ref)) < 1e-8


def test_double_pendulum_positions_keep_the_rod_lengths():
    t = np.linspace(0.0, 2.0, 201)
    p1, p2 = minimal.double_pendulum(RODS, [0.9, 2.0], [0.0, 1.0], t)
    # positions are L (sin, -cos): exact to rounding
    np.testing.assert_allclose(np.linalg.norm(p1, axis=1), RODS["L1"], rtol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(p2 - p1, axis=1), RODS["L2"], rtol=1e-14)


# -- Lagrange top ----------------------------------------------------------------------

ROD_TOP = {"m": 1.0, "d": 0.5, "L": 1.0, "It": 1.0003 / 12, "Ia": 5.0e-5, "g": 9.81}


def test_top_state_round_trips_axis_and_omega():
    axis, omega = np.array([0.6, 0.0, -0.8]), np.array([0.3, -1.0, 3.0])
    e, w = minimal.top_axis_and_omega(minimal.top_state(axis, omega))
    # a 3x3 solve and back: rounding only
    np.testing.assert_allclose(e[0], axis, atol=1e-15)
    np.testing.assert_allclose(w[0], omega, atol=1e-14)


@pytest.mark.parametrize("omega", [[0.0, 0.0, 3.0], [1.0, -2.0, 4.0]])
def test_lagrange_top_conserves_energy_vertical_momentum_and_spin(omega):
    state0 = minimal.top_state([0.6, 0.0, -0.8], omega)
    t = np.linspace(0.0, 5.0, 501)
    tip, w, _ = minimal.spherical_top(ROD_TOP, state0, t)
    E, Hz, spin = minimal.top_invariants(ROD_TOP, tip / ROD_TOP["L"], w)
    scale = ROD_TOP["m"] * ROD_TOP["g"] * ROD_TOP["d"]
    # computed from the output vectors, not from the conserved Euler-angle momenta:
    # integration at 1e-12 keeps each to ~1e-11 of its scale
    assert np.max(np.abs(E - E[0])) < 1e-10 * scale
    assert np.max(np.abs(Hz - Hz[0])) < 1e-10 * max(abs(Hz[0]), 1.0)
    assert np.max(np.abs(spin - spin[0])) < 1e-10 * max(abs(spin[0]), 1.0)
    np.testing.assert_allclose(np.linalg.norm(tip, axis=1), ROD_TOP["L"], rtol=1e-14)


def test_lagrange_top_steady_precession_keeps_its_inclination():
    # w = W z with the axis at cos(th) = -0.8 below the horizontal plane: theta'' = 0
    # when A W^2 cos th - C (W cos th) W + m g d = 0, i.e. W^2 = m g d / ((C - A) cos th)
    A = ROD_TOP["It"] + ROD_TOP["m"] * ROD_TOP["d"] ** 2
    W = np.sqrt(ROD_TOP["m"] * ROD_TOP["g"] * ROD_TOP["d"] / ((ROD_TOP["Ia"] - A) * -0.8))
    state0 = minimal.top_state([0.6, 0.0, -0.8], [0.0, 0.0, W])
    t = np.linspace(0.0, 5.0, 501)
    tip, _, states = minimal.spherical_top(ROD_TOP, state0, t)
    # an equilibrium of the theta equation: only integration error moves it
    assert np.max(np.abs(tip[:, 2] + 0.8)) < 1e-9
    np.testing.assert_allclose(states[:, 4], W, rtol=1e-9)


def test_lagrange_top_small_planar_swing_has_the_compound_pendulum_period():
    A = ROD_TOP["It"] + ROD_TOP["m"] * ROD_TOP["d"] ** 2
    T0 = 2 * np.pi * np.sqrt(A / (ROD_TOP["m"] * ROD_TOP["g"] * ROD_TOP["d"]))
    eps = 1e-4
    state0 = minimal.top_state([np.sin(eps), 0.0, -np.cos(eps)], [0.0, 0.0, 0.0])
    t = np.linspace(0.0, 5 * T0, 20001)
    tip, _, _ = minimal.spherical_top(ROD_TOP, state0, t)
    T = np.mean(np.diff(_crossing_times(t, -tip[:, 0])))
    # amplitude correction eps^2/16 ~ 6e-10, interpolation error far smaller
    assert abs(T / T0 - 1) < 1e-8


# -- example models --------------------------------------------------------------------

EXAMPLE_FILES = sorted(EXAMPLES.glob("*.yaml"))
EXAMPLE_NAMES = [p.stem for p in EXAMPLE_FILES]


def test_the_examples_are_there():
    assert set(EXAMPLE_NAMES) >= {"a01_pendulum", "double_pendulum", "free_body",
                                  "spherical_pendulum", "four_bar", "deployable"}


def _stated_counts(path: Path) -> tuple[int, int, int]:
    """(coordinates, constraint equations, degrees of freedom) as the file's header
    comment states them."""
    text = path.read_text()
    counts = re.search(r"Coordinates (\d+)(?: \([^)]*\))?, constraint equations (\d+)", text)
    dof = re.search(r"^# Degrees of freedom: (\d+)$", text, re.MULTILINE)
    assert counts and dof, (f"{path.name}: the header comment must state 'Coordinates N, "
                            "constraint equations M' and '# Degrees of freedom: K'")
    return int(counts.group(1)), int(counts.group(2)), int(dof.group(1))


def _triple(entry, key):
    """(value, fixed) of a point or vector entry in either of its two forms."""
    if isinstance(entry, dict):
        return np.asarray(entry[key], float), bool(entry.get("fixed", False))
    return np.asarray(entry, float), False


def _inertia_tensor(values):
    v = [float(x) for x in values]
    if len(v) == 3:
        return np.diag(v)
    xx, yy, zz, xy, xz, yz = v
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=EXAMPLE_NAMES)
def test_example_is_physically_consistent(path):
    text = path.read_text()
    assert text.startswith("#"), "an example starts with a comment saying what it models"
    data = yaml.safe_load(text)
    assert data["name"] == path.stem
    _stated_counts(path)
    points = {n: _triple(e, "at") for n, e in data.get("points", {}).items()}
    vectors = {n: _triple(e, "along") for n, e in data.get("vectors", {}).items()}
    for name, (v, _) in vectors.items():
        assert abs(np.linalg.norm(v) - 1) < 1e-9, f"vector {name} is not a unit vector"
    for name, body in data.get("bodies", {}).items():      # none in a model of cables
        if "points" not in body:          # pose form (mechanism level)
            _check_pose_body(name, body)
            continue
        i, j = (points[p][0] for p in body["points"])
        u, u_fixed = vectors[body["vector"]]
        e1 = (j - i) / np.linalg.norm(j - i)
        # |e1 x u| = sin(gamma): well away from parallel (the frame divides by it)
        assert np.linalg.norm(np.cross(e1, u)) > 0.1, f"{name}: u nearly parallel to i-j"
        assert body["mass"] > 0
        I = _inertia_tensor(body["inertia"])
        if not I.any():
            assert u_fixed, f"{name}: a point mass needs a fixed vector to fix its orientation"
            continue
        p = np.linalg.eigvalsh(I)
        assert p[0] > 0, f"{name}: inertia not positive definite"
        # principal moments of a real body: each at most the sum of the other two
        assert p[2] <= p[0] + p[1] + 1e-12 * p[2], f"{name}: triangle inequality broken"


def _check_pose_body(name, body):
    """A body in pose form: positive mass, a real inertia, orthonormal axes."""
    assert body["mass"] > 0
    p = np.linalg.eigvalsh(_inertia_tensor(body["inertia"]))
    assert p[0] > 0 and p[2] <= p[0] + p[1] + 1e-12 * p[2], f"{name}: inertia"
    frame = body.get("frame", {"x": [1, 0, 0], "y": [0, 1, 0]})
    x, y = (np.asarray(frame[k], float) for k in "xy")
    assert abs(x @ y) < 1e-9 * np.linalg.norm(x) * np.linalg.norm(y), f"{name}: axes"


# The constraint equations of docs/design.md §1 and docs/elements.md, evaluated from the
# plan's layouts with plain NumPy (complex-safe, for complex-step derivatives).

def _element_triples(el, q):
    """Values of the element's triples by name: moving ones from q, fixed from params."""
    cls, out = el.cls, {}
    moving = iter(el.slots)
    names = list(cls.param_names)
    for t, fixed in zip(cls.triple_names, cls.fixed):
        if fixed:
            k = names.index(f"{t}.x")
            out[t] = el.params[k:k + 3].astype(complex)
        else:
            s = next(moving)
            out[t] = q[3 * s:3 * s + 3]
    return out


def _end_position(tr, scal, end, kind):
    """Position of a point end or a body-point end (docs/elements.md, Body point)."""
    if kind == "point":
        return tr[f"{end}.r"]
    ri, rj, u = tr[f"{end}.ri"], tr[f"{end}.rj"], tr[f"{end}.u"]
    l, alpha, b1, b2, b3 = (scal[f"{end}.{n}"] for n in ("l", "alpha", "b1", "b2", "b3"))
    rij = rj - ri
    return ri + b1 * rij + b2 * u + b3 / (alpha * l) * np.cross(rij, u)


def _element_constraints(el, q):
    """The element's constraint equations, in the order of cls.constraint_rows."""
    cls = el.cls
    tr = _element_triples(el, q)
    scal = dict(zip(cls.scalar_names, el.params))
    if cls.kind == "body":
        rij = tr["rj"] - tr["ri"]
        row = {"length": rij @ rij - scal["l"] ** 2,
               "angle": rij @ tr["u"] - scal["l"] * scal["beta"]}
        return [row[r] for r in cls.constraint_rows]
    if cls.kind == "unit_vector":
        return [tr["u"] @ tr["u"] - 1]
    if cls.kind in ("attached_point", "attached_vector") or cls.kind.startswith("aligned"):
        return _attached_constraints(cls, tr, scal)
    if cls.kind == "point_on_plane":
        return [tr["n"] @ (tr["K.r"] - tr["A.r"])]
    if cls.kind == "dot":
        return [tr["a"] @ tr["b"] - scal["c"]]
    if cls.kind == "slope_normal":                 # a clamp row (docs/flexible.md)
        return [tr["d"] @ tr["n"]]
    if cls.kind.startswith("driver_"):
        return [_driver_constraint(cls, tr, scal)]
    end_names = ("K", "A", "B") if cls.kind == "point_on_line" else ("A", "B")
    ends = {e: _end_position(tr, scal, e, k) for e, k in zip(end_names, cls.ends)}
    if cls.kind == "distance":
        d = ends["B"] - ends["A"]
        return [d @ d - scal["L"] ** 2]
    if cls.kind == "point_on_line":
        return list(np.cross(ends["K"] - ends["A"], ends["B"] - ends["A"]))
    return []


def _driver_constraint(cls, tr, scal):
    """A driver's row (docs/joints.md, Drivers) at the time of its parameter t."""
    from fccgen.expressions.grammar import parse_expression
    import sympy
    t = sympy.Symbol("t", real=True)
    f = float(parse_expression(cls.function, {"t": t}, source="-", line=None,
                               item="-").subs(t, scal["t"]))
    if cls.kind == "driver_angle":
        a, b, u = tr["a"], tr["b"], tr["u"]
        return b @ (-np.sin(f) * a + np.cos(f) * np.cross(u, a))
    if cls.kind == "driver_position":
        return tr["u"] @ (tr["rb"] - tr["ra"]) - f
    if cls.kind == "driver_distance":
        d = tr["rb"] - tr["ra"]
        return d @ d - f * f
    e = np.array([scal["ex"], scal["ey"], scal["ez"]])
    return e @ tr["r"] - scal["c0"] - f


def _attached_constraints(cls, tr, scal):
    """Mechanism level (docs/joints.md): r_k - [r_i + b1 r_ij + b2 u + b3 (r_ij x u) /
    (alpha l)], the same for a vector without r_i; aligned rows w.r_ij - c1,
    w.u - c2, w.(r_ij x u) - c3."""
    ri, rj, u = tr["ri"], tr["rj"], tr["u"]
    rij = rj - ri
    if cls.kind.startswith("aligned"):
        w = tr["w"]
        row = {"e1": w @ rij, "e2": w @ u, "e3": w @ np.cross(rij, u)}
        return [row[r] - scal[f"c{r[1]}"] for r in cls.constraint_rows]
    b1, b2, b3 = (scal[n] for n in ("b1", "b2", "b3"))
    offset = b1 * rij + b2 * u + b3 / (scal["alpha"] * scal["l"]) * np.cross(rij, u)
    if cls.kind == "attached_point":
        return list(tr["k"] - ri - offset)
    return list(tr["w"] - offset)


def fcc_constraints(plan, q):
    """g(q) of every constraint equation of the plan, in element order."""
    q = np.asarray(q)
    return np.array([g for el in plan.elements for g in _element_constraints(el, q)])


def fcc_jacobian(plan, q, h=1e-30):
    """B = dg/dq by complex steps (g is a polynomial: exact to rounding)."""
    q = np.asarray(q, float)
    cols = [fcc_constraints(plan, q + 1j * h * e).imag / h for e in np.eye(len(q))]
    return np.column_stack(cols)


def _load_plan(path):
    """The plan of an example, or a skip while fccgen's loader is not importable."""
    try:
        from fccgen.mechanism import lower
        from fccgen.model import load_model
        from fccgen.plan import make_plan
    except ImportError as exc:
        pytest.skip(f"fccgen.model.load_model is not importable yet ({exc})")
    return make_plan(lower(load_model(path)))


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=EXAMPLE_NAMES)
def test_example_loads_with_the_stated_degrees_of_freedom(path):
    plan = _load_plan(path)
    q0 = plan.q0
    B = fcc_jacobian(plan, q0)
    assert B.shape == (plan.n_g, plan.n_q)
    if not plan.n_g:                               # a member pinned at a point: no rows
        assert (plan.n_q, 0, plan.n_q) == _stated_counts(path)
        return
    rows = B / np.linalg.norm(B, axis=1)[:, None]
    s = np.linalg.svd(rows, compute_uv=False)
    # 1e-8 splits rounding-level zeros (exact complex-step derivatives of a structural
    # redundancy: < 1e-12) from genuine singular values (> 1e-4 away from singular poses)
    rank = int(np.sum(s > 1e-8 * s[0]))
    assert rank == len(s) or s[rank] < 1e-12 * s[0]
    assert s[rank - 1] > 1e-4 * s[0], "the configuration is close to a singular one"
    assert (plan.n_q, plan.n_g, plan.n_q - rank) == _stated_counts(path)
    # the initial positions satisfy the constraints: residual over row gradient is a
    # distance in coordinate units, rounding-level against the model's size
    g = fcc_constraints(plan, q0).real
    size = max(1.0, np.max(np.abs(q0)))
    assert np.max(np.abs(g) / np.linalg.norm(B, axis=1)) < 1e-9 * size


def _plot_script():
    return example_module("plot_deployable")


def test_deployable_folds_as_its_comment_says():
    pytest.importorskip("fccgen.numeric")
    steps, x = _plot_script().body4_x(numeric=True)
    np.testing.assert_array_equal(steps, np.arange(201))
    # starts where the geometry puts it (written with 9 decimals: rounding only)
    assert abs(x[0] - 550.0) < 1e-6
    assert np.all(np.diff(x) < 0)              # folding all the way, from rest
    assert 250.0 < x[-1] < 300.0               # "towards 280 mm" (RK4 at 1 ms)


def test_plot_deployable_writes_a_png(tmp_path):
    pytest.importorskip("matplotlib")
    pytest.importorskip("fccgen.numeric")
    script = _plot_script()
    script.main([str(tmp_path / "body4.png"), "--numeric"])
    assert (tmp_path / "body4.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
