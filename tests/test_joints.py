"""Joints and pose-form bodies (docs/design.md §2b): each joint type leaves exactly
its freedoms, a finite motion of the allowed kind keeps g = 0 (and one of another
kind does not), a hinged pendulum in joint form against its period and its
minimal-coordinate solution, Bricard's linkage, and the lowering's errors."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.special
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import fccgen
from fccgen.diagnostics.check import check_model
from fccgen.errors import ModelError
from fccgen.model import load_model_text

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

BODY = ("  b: {mass: 2.0, center: [0.6, 0.3, 0.2], inertia: [0.05, 0.07, 0.09],\n"
        "      frame: {x: [1, 0, 0], y: [0, 1, 0]}}\n")
P, AXIS = np.array([0.1, 0.2, 0.3]), np.array([0.0, 0.6, 0.8])
AXIS2 = np.array([1.0, 0.0, 0.0])                 # perpendicular to AXIS
JOINTS = {   # type: (joint keys, freedoms)
    "spherical": ("at: [0.1, 0.2, 0.3]", 3),
    "revolute": ("at: [0.1, 0.2, 0.3], axis: [0, 0.6, 0.8]", 1),
    "cylindrical": ("at: [0.1, 0.2, 0.3], axis: [0, 0.6, 0.8]", 2),
    "prismatic": ("at: [0.1, 0.2, 0.3], axis: [0, 0.6, 0.8]", 1),
    "universal": ("at: [0.1, 0.2, 0.3], axes: [[0, 0.6, 0.8], [1, 0, 0]]", 2),
    "weld": ("at: [0.1, 0.2, 0.3]", 0),
    "planar": ("at: [0.1, 0.2, 0.3], normal: [0, 0.6, 0.8]", 3),
    "point_on_line": ("at: [0.1, 0.2, 0.3], axis: [0, 0.6, 0.8]", 4),
    "point_on_plane": ("at: [0.1, 0.2, 0.3], normal: [0, 0.6, 0.8]", 5),
    "distance": ("at: [[0.1, 0.2, 0.3], [0.6, 0.3, 0.2]]", 5),
    "angle": ("axes: [[0, 0.6, 0.8], [1, 0, 0]]", 5),
}


def model_text(kind: str, first: str = "ground") -> str:
    keys = JOINTS[kind][0]
    extra = ("  a: {mass: 1.0, center: [-0.4, 0.1, 0.0], inertia: [0.02, 0.03, 0.04]}\n"
             if first != "ground" else "")
    return (f"name: j_{kind}\nbodies:\n{extra}{BODY}joints:\n"
            f"  - {{name: J, type: {kind}, bodies: [{first}, b], {keys}}}\n")


def write(tmp_path: Path, text: str, name="m.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("kind", JOINTS)
def test_each_joint_leaves_its_freedoms(kind, tmp_path):
    """Ground + body: the joint's freedoms; free body + body: 6 more."""
    assert check_model(write(tmp_path, model_text(kind))).dof == JOINTS[kind][1]
    report = check_model(write(tmp_path, model_text(kind, "a"), "free.yaml"))
    assert report.dof == 6 + JOINTS[kind][1]
    assert report.joints and report.joints[0].startswith(f"joint J ({kind}")


def rot(axis, angle):
    return Rotation.from_rotvec(angle * np.asarray(axis) / np.linalg.norm(axis)).as_matrix()


# type: (rotation, translation) of an allowed motion of b about the point P
ALLOWED = {
    "spherical": (rot([1, 2, 3], 0.7), 0),
    "revolute": (rot(AXIS, 0.7), 0),
    "cylindrical": (rot(AXIS, 0.7), 0.3 * AXIS),
    "prismatic": (np.eye(3), 0.3 * AXIS),
    "universal": (rot(AXIS, 0.5) @ rot(AXIS2, 0.4), 0),
    "weld": (np.eye(3), 0),
    "planar": (rot(AXIS, 0.7), 0.3 * AXIS2),
    "point_on_line": (rot([1, 2, 3], 0.7), 0.3 * AXIS),
    "point_on_plane": (rot([1, 2, 3], 0.7), 0.3 * AXIS2),
    "distance": (rot([1, 2, 3], 0.7), 0),
    "angle": (rot(AXIS, 0.7), np.array([0.1, -0.2, 0.3])),
}


def moved(solver, R, d, pivot):
    """Coordinates of every moving triple (all carried by body b) after the rigid
    motion r -> pivot + R (r - pivot) + d, vectors -> R v."""
    plan, q0 = solver.plan, solver.initial_state().q
    q = q0.copy()
    for k, (_, kind) in enumerate(plan.triples):
        x = q0[3 * k:3 * k + 3]
        q[3 * k:3 * k + 3] = R @ x if kind == "vector" else pivot + R @ (x - pivot) + d
    return q


@pytest.mark.parametrize("kind", JOINTS)
def test_allowed_motion_keeps_the_constraints(kind, tmp_path):
    """g stays zero to rounding (O(1) numbers: 1e-13) under a finite motion of the
    joint's kind, and breaks (> 1e-3) under a rotation about another axis."""
    solver = fccgen.load_numeric(write(tmp_path, model_text(kind)))
    R, d = ALLOWED[kind]
    pivot = np.array([0.1, 0.2, 0.3]) if kind != "distance" else P
    g = solver.constraints(moved(solver, R, d, pivot))
    assert np.abs(g).max() < 1e-13
    if kind != "weld":
        g_bad = solver.constraints(moved(solver, rot([0.3, -1, 0.2], 0.5), 0.2 * AXIS2,
                                         pivot + 0.1))
        assert np.abs(g_bad).max() > 1e-3


# -- a hinged pendulum in joint form ---------------------------------------------------
THETA0 = 2.0                           # initial angle from hanging down (rad)
D, LENGTH, MASS, G = 0.5, 1.0, 1.0, 9.81


def pendulum_text() -> str:
    """A uniform bar on a hinge at the origin (axis y), released at THETA0 from
    hanging down: its centre at D (sin, 0, -cos)."""
    e = [float(np.sin(THETA0)), 0.0, float(-np.cos(THETA0))]
    c = [D * x for x in e]
    i_t = MASS * LENGTH ** 2 / 12
    return (f"name: hinge\ngravity: [0, 0, {-G}]\nbodies:\n"
            f"  bar: {{mass: {MASS}, center: [{c[0]!r}, 0, {c[2]!r}], "
            f"inertia: [1.0e-4, {i_t!r}, {i_t!r}],\n"
            f"        frame: {{x: [{e[0]!r}, 0, {e[2]!r}], y: [0, 1, 0]}}}}\n"
            "joints:\n  - {name: A, type: revolute, bodies: [ground, bar], at: [0, 0, 0], "
            "axis: [0, 1, 0]}\n")


@pytest.fixture(scope="module")
def pendulum_run(tmp_path_factory, build_dir):
    path = write(tmp_path_factory.mktemp("pendulum"), pendulum_text())
    solver = fccgen.load(path, build_dir)
    return solver.simulate(t_end=3.0, dt=1e-3)


def pendulum_constants():
    i_o = MASS * LENGTH ** 2 / 12 + MASS * D ** 2      # about the hinge (1e-4: on axis)
    return MASS * G * D / i_o


def test_pendulum_period_against_elliptic_integral(pendulum_run):
    """T = 4 K(sin^2(theta0/2)) / w0. Half a period is where the rate crosses zero,
    interpolated linearly between 1 ms samples (the rate is nearly linear there).
    Measured: 5.5e-11 relative; 1e-8 allowed."""
    w0 = np.sqrt(pendulum_constants())
    period = 4 * scipy.special.ellipk(np.sin(THETA0 / 2) ** 2) / w0
    t, rate = pendulum_run.t, pendulum_run["A.rate"]
    k = np.nonzero((rate[1:] * rate[:-1] < 0) & (t[1:] > 0.1))[0][0]
    half = t[k] - rate[k] * (t[k + 1] - t[k]) / (rate[k + 1] - rate[k])
    assert 2 * half == pytest.approx(period, rel=1e-8)


def test_pendulum_angle_against_minimal_coordinates(pendulum_run):
    """theta'' = -(m g d / I_O) sin(theta); a right-handed rotation about +y lowers
    theta, so A.angle = theta0 - theta and A.rate = -theta'. Measured against the
    1e-12 ODE solution over 3 s with RK4 at 1 ms: 2.4e-10 rad and 6e-10 rad/s;
    1e-8 allowed for both."""
    w2 = pendulum_constants()
    t = pendulum_run.t
    sol = solve_ivp(lambda _, y: [y[1], -w2 * np.sin(y[0])], (0, t[-1]), [THETA0, 0.0],
                    t_eval=t, rtol=1e-12, atol=1e-12, method="DOP853")
    assert np.abs(pendulum_run["A.angle"] - (THETA0 - sol.y[0])).max() < 1e-8
    assert np.abs(pendulum_run["A.rate"] + sol.y[1]).max() < 1e-8


# -- Bricard's linkage -----------------------------------------------------------------

def test_bricard_has_one_freedom_by_rank():
    """Gruebler's count says -1 here (0 for the linkage), the rank says 1."""
    report = check_model(EXAMPLES / "bricard.yaml")
    assert report.dof == 1
    assert report.dof_counted < 1
    text = report.text()
    assert "joint J1 (revolute, ground -> bar1)" in text
    # the loop's dependency runs through the joints between moving bars
    assert "rows taking part in the dependencies: joints J2, J3, J4, J5;" in text


def test_rsup_has_no_redundant_row():
    """Fixed and shared axes held by two rows where three would be dependent."""
    report = check_model(EXAMPLES / "rsup.yaml")
    assert (report.dof, report.dof_counted, report.redundant) == (1, 1, [])
    assert "rows taking part" not in report.text()


def test_bricard_keeps_energy_and_one_dof_for_10_s_and_matches_the_hand_encoding(
        compiled, tmp_path, build_dir):
    """RK4 at 1 ms with projection over 10 s (the linkage swings through three and a
    half cycles): energy kept to 1e-8 relative (measured 1.7e-9 J of 29.4 J), one degree
    of freedom throughout, no warning. The joint form's J1.angle equals the rotation of
    bar 1 about y in the hand-written section-2 encoding of tests/bricard.py (shared
    points and vectors plus point_on_line at the other hinges) to 1e-6 rad (both runs'
    RK4 error is ~2e-7)."""
    import bricard
    r = compiled("bricard").simulate(t_end=10.0, dt=1e-3, output_dt=0.05)
    e = r["energy"]
    assert np.abs(e - e[0]).max() < 1e-8 * abs(e[0])
    assert r.info["dof"] == 1 and r.info["final_dof"] == 1 and r.info["warnings"] == []
    assert np.ptp(r["J1.angle"]) > 2.5
    path = tmp_path / "bricard_line.yaml"
    path.write_text(bricard.text("line"))
    hand = fccgen.load(path, build_dir).simulate(t_end=10.0, dt=1e-3, output_dt=0.05)
    theta = np.unwrap(np.arctan2(-hand["P2.z"], hand["P2.x"]))
    assert np.max(np.abs(r["J1.angle"] - theta)) < 1e-6


def test_bricard_short_run_with_ali3p(compiled):
    """The augmented-Lagrangian method needs no rank decision: over 1 s at 1 ms its
    energy error is 3.3e-6 of 29.4 J (1.1e-7, measured; the trapezoidal rule's O(dt^2)),
    so 1e-6 relative would catch a jump like RK4's (4e-2) with margin."""
    r = compiled("bricard").simulate(t_end=1.0, dt=1e-3, method="ali3p")
    e = r["energy"]
    assert np.abs(e - e[0]).max() < 1e-6 * abs(e[0])
    assert r["constraint_error"].max() < 1e-9
    assert r["J1.angle"][-1] > 0.5             # it moved: about 1 rad in 1 s


# -- errors ----------------------------------------------------------------------------
GOOD = model_text("revolute")
ERRORS = [
    ("bad type", ("type: revolute", "type: hinge"), "joints[0].type",
     "unknown joint type; expected one of: spherical", "hinge"),
    ("zero axis", ("axis: [0, 0.6, 0.8]", "axis: [0, 0, 0]"), "joints[0].axis",
     "must be a direction of non-zero length", [0, 0, 0]),
    ("same body", ("bodies: [ground, b]", "bodies: [b, b]"), "joints[0].bodies",
     "must name two different bodies", ["b", "b"]),
    ("unknown body", ("bodies: [ground, b]", "bodies: [ground, c]"), "joints[0].bodies[1]",
     "names no body; bodies are: ground, b", "c"),
    ("missing at", ("at: [0.1, 0.2, 0.3], ", ""), "joints[0].at", "missing required key",
     None),
    ("missing axis", (", axis: [0, 0.6, 0.8]", ""), "joints[0].axis",
     "missing required key", None),
    ("name clash", ("name: J,", "name: b,"), "joints[0].name", "name already used by the body",
     "b"),
    ("duplicate joint", ("axis: [0, 0.6, 0.8]}\n", "axis: [0, 0.6, 0.8]}\n"
                         "  - {name: J, type: spherical, bodies: [ground, b], at: [0, 0, 0]}\n"),
     "joints[1].name", "name already used by the joint", "J"),
    ("ground declared", ("bodies:\n", "bodies:\n  ground: {mass: 1, center: [0, 0, 0], "
                                      "inertia: [1, 1, 1]}\n"),
     "bodies.ground", "is the fixed body that joints name", "ground"),
    ("frame not orthogonal", ("y: [0, 1, 0]", "y: [1, 1, 0]"), "bodies.b.frame",
     "axes x and y must be orthogonal", None),
    ("distance at one place", ("type: revolute, bodies: [ground, b], at: [0.1, 0.2, 0.3], "
                               "axis: [0, 0.6, 0.8]",
                               "type: distance, bodies: [ground, b], at: [[1, 2, 3], [1, 2, 3]]"),
     "joints[0].at", "must be two different locations", [[1, 2, 3], [1, 2, 3]]),
    ("angle range", ("type: revolute, bodies: [ground, b], at: [0.1, 0.2, 0.3], "
                     "axis: [0, 0.6, 0.8]",
                     "type: angle, bodies: [ground, b], axes: [[1, 0, 0], [0, 1, 0]], "
                     "angle: 4"), "joints[0].angle", "must be an angle in radians", 4),
]


@pytest.mark.parametrize("edit, item, rule, value", [c[1:] for c in ERRORS],
                         ids=[c[0] for c in ERRORS])
def test_joint_errors(edit, item, rule, value):
    assert edit[0] in GOOD
    with pytest.raises(ModelError) as info:
        load_model_text(GOOD.replace(edit[0], edit[1]), "m.yaml")
    err = info.value
    assert err.item == item and rule in err.rule, str(err)
    assert err.line is not None and err.file == "m.yaml"
    if value is not None:
        assert err.value == value


def test_joint_on_a_body_given_by_points(tmp_path):
    """A section-2 rod on a fixed point O (spin about O: 3 freedoms) and the pose body
    b hinged to its end E: 3 + 1. The rod keeps its own i, j, u; the joint's point is
    the rod's E (no triple of its own), its axis is attached to the rod."""
    text = GOOD.replace("bodies:\n", "points:\n  O: {at: [0, 0, 0], fixed: true}\n"
                        "  E: [0.1, 0.2, 0.3]\nvectors:\n  z: [0, 0, 1]\nbodies:\n"
                        "  rod: {points: [O, E], vector: z, mass: 1, inertia: [0.01, 0.1, "
                        "0.1]}\n")
    text = text.replace("bodies: [ground, b]", "bodies: [rod, b]")
    report = check_model(write(tmp_path, text))
    assert report.dof == 3 + 1
    text = report.text()
    assert "joint J (revolute, rod -> b): point E on rod, b;" in text
    assert "joint J (revolute): vector J_axis on rod" in text
    assert report.n_points == 2                      # E and b's centre: no J


def test_generated_name_clash(tmp_path):
    """The joint's axis vector J_axis would take the name of a declared point."""
    text = GOOD.replace("bodies:\n", "points:\n  J_axis: {at: [5, 5, 5], fixed: true}\n"
                        "bodies:\n")
    with pytest.raises(ModelError, match="joints.J: the name J_axis, which this joint's "
                                         "lowering needs, is already used"):
        fccgen.load_numeric(write(tmp_path, text))


def test_generated_body_name_clash(tmp_path):
    """A body without joint points takes <body>_center; a declared joint has it."""
    text = ("name: m\nbodies:\n" + BODY + "  c: {mass: 1, center: [3, 0, 0], inertia: "
            "[1, 1, 1]}\njoints:\n  - {name: c_center, type: spherical, bodies: [ground, b], "
            "at: [0, 0, 0]}\n")
    with pytest.raises(ModelError, match="bodies.c: the name c_center, which this body's "
                                         "frame needs, is already used"):
        fccgen.load_numeric(write(tmp_path, text))


def test_joint_without_name():
    with pytest.raises(ModelError, match="joints\\[0\\].name: missing required key"):
        load_model_text(GOOD.replace("name: J, ", ""), "m.yaml")


# -- pose-form bodies: mass terms, loads and initial speeds in the pose frame -----------
POSE = ("name: pose\nbodies:\n"
        "  box: {mass: 2.0, center: [0.3, -0.2, 0.5],\n"
        "        inertia: [0.05, 0.07, 0.09, 0.004, -0.003, 0.002],\n"
        "        frame: {x: [0.6, 0.8, 0], y: [0, 0, 1]}}\n"
        "loads:\n  - {type: force, body: box, at: [0.1, 0.2, -0.3], value: [1.0, -2.0, 0.5]}\n"
        "initial:\n  bodies: {box: {angular_velocity: [0.3, -0.5, 0.7], frame: body}}\n")


def test_pose_body_force_at_a_pose_frame_point(tmp_path):
    """A free body at rest: a_G = F / m and alpha = I_G^-1 (r x F) with r the force
    point from the centre, F I F^T the inertia in the global frame. The body's i is its
    mass centre and j a point d away, so a_j - a_i = alpha x d (rounding: 1e-12)."""
    solver = fccgen.load_numeric(write(tmp_path, POSE))
    plan, q = solver.plan, solver.initial_state().q
    a = solver.accelerations(q, np.zeros_like(q))
    idx = {name: 3 * k for k, (name, _) in enumerate(plan.triples)}
    frame = np.column_stack([[0.6, 0.8, 0], [0, 0, 1], np.cross([0.6, 0.8, 0], [0, 0, 1])])
    inertia = np.array([[0.05, 0.004, -0.003], [0.004, 0.07, 0.002], [-0.003, 0.002, 0.09]])
    force, r = np.array([1.0, -2.0, 0.5]), frame @ np.array([0.1, 0.2, -0.3])
    alpha = np.linalg.solve(frame @ inertia @ frame.T, np.cross(r, force))
    a_i, a_j = (a[idx[n]:idx[n] + 3] for n in ("box_center", "box_end"))
    d = q[idx["box_end"]:idx["box_end"] + 3] - q[idx["box_center"]:idx["box_center"] + 3]
    assert np.allclose(a_i, force / 2.0, rtol=0, atol=1e-12)
    assert np.allclose(a_j - a_i, np.cross(alpha, d), rtol=0, atol=1e-12)


def test_pose_body_angular_velocity_in_the_pose_frame(tmp_path):
    """initial.bodies.box.angular_velocity with frame: body is in the pose axes."""
    solver = fccgen.load_numeric(write(tmp_path, POSE))
    init = solver.initial_state()
    frame = np.column_stack([[0.6, 0.8, 0], [0, 0, 1], np.cross([0.6, 0.8, 0], [0, 0, 1])])
    w = solver.body_outputs(init.q, init.v).reshape(-1, 6)[0, 3:]
    assert np.allclose(w, frame @ np.array([0.3, -0.5, 0.7]), rtol=0, atol=1e-12)


# -- joint outputs ---------------------------------------------------------------------

def test_rsup_joint_outputs_against_point_columns(compiled):
    """A.angle from the crank pin B: the crank starts along +z from A, and a rotation
    by theta about +x takes z to (0, -sin, cos). S.position and S.speed are the
    slider's joint point S_b along x from its start. Both sides are rounding apart
    (measured 2e-16; 1e-12 allowed). The rate against central differences of the
    angle, which err by dt^2 |theta_ttt| / 6 = 1.3e-2 here (|theta_ttt| < 7.9e4 rad/s^3
    by differences at 0.1 ms)."""
    r = compiled("rsup").simulate(t_end=0.3, dt=1e-3)
    assert r.names[1:] == compiled("rsup").plan.columns()      # the same names in order
    theta = np.unwrap(np.arctan2(-(r["B.y"] - 0.1), r["B.z"] - 0.12))
    assert np.abs(r["A.angle"] - theta).max() < 1e-12
    assert np.abs(np.gradient(theta, r.t) - r["A.rate"])[1:-1].max() < 1.5e-2
    assert r["A.angle"][-1] > 1.0                      # the crank turns
    assert np.abs(r["S.position"] - (r["S_b.x"] - 0.2)).max() < 1e-12
    assert np.abs(r["S.speed"] - r["S_b.vx"]).max() < 1e-12


def test_cylindrical_outputs_of_a_steady_spin(tmp_path):
    """No gravity, a spin w about the joint axis: the angle grows as w t (the axial
    angular momentum is conserved), the slide stays 0 (RK4 at 1 ms: 1e-10)."""
    text = model_text("cylindrical") + ("initial:\n  bodies: {b: {angular_velocity: "
                                        "[0, 1.2, 1.6]}}\n")          # 2 rad/s along a
    r = fccgen.load_numeric(write(tmp_path, text)).simulate(t_end=0.2, dt=1e-3)
    assert np.abs(r["J.angle"] - 2.0 * r.t).max() < 1e-10
    assert np.abs(r["J.rate"] - 2.0).max() < 1e-10
    assert np.abs(r["J.position"]).max() < 1e-10 and np.abs(r["J.speed"]).max() < 1e-10


# -- the same rows as section-2 constraints on named points and vectors ---------------
SECTION2 = """name: plane_rod
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [1, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
  u: [0, 0.6, 0.8]
bodies:
  rod: {points: [O, P], vector: u, mass: 1.0, inertia: [0.01, 0.1, 0.1]}
constraints:
  - {type: point_on_plane, point: P, origin: O, normal: z}
  - {type: angle, vectors: [u, z], angle: 0.6435011087932844}
"""


def test_section2_plane_and_angle_constraints(tmp_path):
    """A rod on a fixed point: 3 freedoms; P on the plane z = 0 takes one, u at a
    fixed angle (acos 0.8) to z another."""
    report = check_model(write(tmp_path, SECTION2))
    assert (report.dof, report.dof_counted) == (1, 1)
    assert "constraints[0] (plane)" in report.rows and "constraints[1] (dot)" in report.rows


SECTION2_ERRORS = [
    ("normal: z", "normal: w", "constraints[0].normal", "names no vector; vectors are: z, u",
     "w"),
    ("origin: O", "origin: P", "constraints[0].origin", "must be another point", "P"),
    ("vectors: [u, z]", "vectors: [u, u]", "constraints[1].vectors",
     "must name two different vectors", ["u", "u"]),
    ("angle: 0.6435011087932844", "angle: -1", "constraints[1].angle",
     "must be an angle in radians from 0 to pi", -1),
]


@pytest.mark.parametrize("old, new, item, rule, value", SECTION2_ERRORS,
                         ids=[c[2] for c in SECTION2_ERRORS])
def test_section2_plane_and_angle_errors(old, new, item, rule, value):
    with pytest.raises(ModelError) as info:
        load_model_text(SECTION2.replace(old, new), "m.yaml")
    err = info.value
    assert (err.item, err.value) == (item, value) and rule in err.rule, str(err)
    assert err.line is not None
