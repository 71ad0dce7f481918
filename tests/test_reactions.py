"""Joint reactions (docs/design.md §2b, fccgen.mechanism.reactions): the force and
torque each joint applies on its second body, from a Newton-Euler balance per body,
against analytic pendulum and slider solutions, the system's total momentum rate, and
for every joint type the balance closing within its reaction subspace."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from fccgen.errors import ModelError
from fccgen.mechanism.reactions import reactions
from test_joints import JOINTS, model_text, write

G = 9.81


def vec(r, joint, kind):
    return np.column_stack([r[f"{joint}.{kind}{c}"] for c in "xyz"])


# -- a hinged pendulum with its mass centre off the hinge plane ------------------------
D, H, MASS, THETA0 = 0.5, 0.2, 1.5, 2.0         # arm, offset along the axis, kg, rad
I_AXIS, I_ROD = 0.12, 0.002                     # inertias about the body's z and x


def pendulum() -> str:
    """A body on a revolute joint at the origin, axis y; its mass centre at D from the
    axis and H along it, released at THETA0 from hanging down."""
    e = [float(np.sin(THETA0)), 0.0, float(-np.cos(THETA0))]
    return (f"name: rx_hinge\ngravity: [0, 0, {-G}]\nbodies:\n"
            f"  bar: {{mass: {MASS}, center: [{D * e[0]!r}, {H}, {D * e[2]!r}], "
            f"inertia: [{I_ROD}, {I_AXIS}, {I_AXIS}],\n"
            f"        frame: {{x: [{e[0]!r}, 0, {e[2]!r}], y: [0, 1, 0]}}}}\n"
            "joints:\n  - {name: A, type: revolute, bodies: [ground, bar], at: [0, 0, 0], "
            "axis: [0, 1, 0]}\n")


def test_hinged_pendulum_reaction_against_the_analytic_solution(tmp_path):
    """theta (from hanging, towards +x) obeys I_o theta'' = -m g D sin theta with
    I_o = I_AXIS + m D^2 and theta'^2 = 2 m g D (cos theta - cos theta0) / I_o; then
    F = m (a_G - g) and the torque about the hinge point is the part of
    (r_G - p) x m (a_G - g) + H_G' that the hinge carries: perpendicular to the axis,
    here H ey x m (a_G - g) (the body turns about a principal axis, H_G' is along y).
    Both sides from the same RK4 states at 1 ms; the analytic side uses theta only,
    so they differ by the RK4 error in the energy (measured 8e-10 N; 1e-7 allowed)."""
    r = fccgen.load_numeric(write(tmp_path, pendulum())).simulate(
        t_end=0.4, dt=1e-3, output_dt=0.01)
    assert r.info["reactions"]["unique"] and r.info["reactions"]["residual"] < 1e-9
    theta = np.arctan2(r["bar.cx"], -r["bar.cz"])
    i_o = I_AXIS + MASS * D ** 2
    rate2 = 2 * MASS * G * D / i_o * (np.cos(theta) - np.cos(THETA0))
    acc = -MASS * G * D / i_o * np.sin(theta)
    e = np.column_stack([np.sin(theta), 0 * theta, -np.cos(theta)])
    et = np.column_stack([np.cos(theta), 0 * theta, np.sin(theta)])
    a_g = D * (acc[:, None] * et - rate2[:, None] * e)
    f = MASS * (a_g - [0.0, 0.0, -G])
    torque = np.cross([0.0, H, 0.0], f)
    assert np.abs(vec(r, "A", "f") - f).max() < 1e-7
    assert np.abs(vec(r, "A", "t") - torque).max() < 1e-7
    assert np.abs(r["A.ty"]).max() < 1e-12                  # none along the axis
    assert np.abs(torque).max() > 1.0                       # the check is not empty


def test_spherical_pendulum_force_is_m_a_minus_g(tmp_path):
    """A ball joint carries no torque; its force is m (a_G - g) with a_G from second
    differences of the recorded mass centre (at 1 ms the differences err by
    h^2 |a''| / 12 < 1e-5 m/s^2 here; 1e-4 N allowed)."""
    text = ("name: rx_ball\ngravity: [0, 0, -9.81]\nbodies:\n"
            "  rod: {mass: 2.0, center: [0.3, 0, -0.4], inertia: [0.001, 0.04, 0.04],\n"
            "        frame: {x: [0.6, 0, -0.8], y: [0, 1, 0]}}\n"
            "joints:\n  - {name: B, type: spherical, bodies: [ground, rod], at: [0, 0, 0]}\n"
            "initial:\n  bodies: {rod: {angular_velocity: [0, 0, 3.0]}}\n")
    r = fccgen.load_numeric(write(tmp_path, text)).simulate(t_end=0.2, dt=1e-3)
    c = np.column_stack([r[f"rod.c{k}"] for k in "xyz"])
    a_g = (c[2:] - 2 * c[1:-1] + c[:-2]) / 1e-6
    f = 2.0 * (a_g - [0.0, 0.0, -G])
    assert np.abs(vec(r, "B", "f")[1:-1] - f).max() < 1e-4
    assert np.abs(vec(r, "B", "t")).max() == 0.0
    assert r.info["reactions"]["residual"] < 1e-9        # the moments balance too


def test_slider_on_an_inclined_prismatic_joint(tmp_path):
    """A block sliding down a frictionless rail at 30 degrees: the rail pushes with
    m g cos(30 deg) along the normal, nothing along the rail, and, with the mass
    centre h off the joint point, a torque (r_G - p) x F keeps the block from
    turning. Exact apart from rounding and the RK4 drift (1e-9 allowed)."""
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    axis, normal = np.array([c, 0, -s]), np.array([s, 0, c])
    h = 0.05
    centre = 0.1 * axis + h * normal
    text = ("name: rx_slider\ngravity: [0, 0, -9.81]\nbodies:\n"
            f"  block: {{mass: 3.0, center: {centre.tolist()}, inertia: [0.01, 0.02, 0.03],"
            f"\n          frame: {{x: {axis.tolist()}, y: [0, 1, 0]}}}}\n"
            "joints:\n  - {name: S, type: prismatic, bodies: [ground, block], "
            f"at: [0, 0, 0], axis: {axis.tolist()}}}\n")
    r = fccgen.load_numeric(write(tmp_path, text)).simulate(t_end=0.2, dt=1e-3)
    assert np.abs(r["S.position"][-1] - 0.5 * G * s * 0.04) < 1e-9    # g sin30 t^2/2
    f = 3.0 * G * c * normal
    assert np.abs(vec(r, "S", "f") - f).max() < 1e-9
    p = np.column_stack([r[f"S_b.{k}"] for k in "xyz"])
    arm = np.column_stack([r[f"block.c{k}"] for k in "xyz"]) - p
    assert np.abs(vec(r, "S", "t") - np.cross(arm, f)).max() < 1e-9
    assert np.abs(np.cross(arm, f)).max() > 0.5


# -- the system as a whole ---------------------------------------------------------------

def test_ground_reactions_sum_to_the_momentum_rate(compiled):
    """The spatial slider-crank (compiled): the forces of the two ground joints on the
    crank and the slider plus gravity equal sum m a_G, a_G by fourth-order central
    differences of the recorded mass centres (independent of the reaction code's
    kinematics). Their error is O(h^4): measured 6.2e-4 N at 1 ms and 5.5e-5 N at
    0.5 ms, against forces up to 79 N; 2e-3 N allowed."""
    h = 1e-3
    r = compiled("rsup").simulate(t_end=0.3, dt=h)
    assert r.info["reactions"]["unique"]
    total = np.zeros((len(r.t) - 4, 3))
    for body in compiled("rsup").plan.model.bodies.values():
        c = np.column_stack([r[f"{body.name}.c{k}"] for k in "xyz"])
        a = (-c[4:] + 16 * c[3:-1] - 30 * c[2:-2] + 16 * c[1:-3] - c[:-4]) / (12 * h * h)
        total += body.mass * (a - [0.0, 0.0, -G])
    ground = vec(r, "A", "f") + vec(r, "S", "f")
    assert np.abs(ground[2:-2] - total).max() < 2e-3
    assert np.abs(total).max() > 10.0


FOUR_BAR = """name: rx_four_bar
gravity: [0, -9.81, 0]
bodies:
  crank:   {mass: 1.0, center: [0.15, 0.2, 0], inertia: [1.0e-4, 0.02, 0.02],
            frame: {x: [0.6, 0.8, 0], y: [-0.8, 0.6, 0]}}
  coupler: {mass: 2.0, center: [0.75, 0.6, 0], inertia: [1.0e-4, 0.16, 0.16],
            frame: {x: [0.9138115486202573, 0.40613846605344767, 0],
                    y: [-0.40613846605344767, 0.9138115486202573, 0]}}
  rocker:  {mass: 1.5, center: [1.1, 0.4, 0], inertia: [1.0e-4, 0.085, 0.085],
            frame: {x: [0.24253562503633297, 0.9701425001453319, 0],
                    y: [-0.9701425001453319, 0.24253562503633297, 0]}}
joints:
  - {name: O, type: revolute, bodies: [ground, crank],   at: [0, 0, 0],     axis: [0, 0, 1]}
  - {name: A, type: revolute, bodies: [crank, coupler],  at: [0.3, 0.4, 0], axis: [0, 0, 1]}
  - {name: B, type: revolute, bodies: [coupler, rocker], at: [1.2, 0.8, 0], axis: [0, 0, 1]}
  - {name: C, type: revolute, bodies: [rocker, ground],  at: [1.0, 0, 0],   axis: [0, 0, 1]}
initial:
  joints: {O: {rate: 2.0}}
"""


def test_redundant_four_bar_gives_the_minimum_norm_set(tmp_path):
    """Four parallel revolutes: 20 reaction components, 18 balance rows of which the
    motion takes 1, so 3 components are undetermined. The set reported balances every
    body (residual at rounding) and has no part along the undetermined directions:
    adding any balanced self-stress (here the axial force pair and the out-of-plane
    torques that the redundancy allows) makes it longer."""
    solver = fccgen.load_numeric(write(tmp_path, FOUR_BAR))
    r = solver.simulate(t_end=0.2, dt=1e-3, output_dt=0.01)
    info = r.info["reactions"]
    assert not info["unique"] and info["unknowns"] == 20 and info["rank"] == 17
    assert "minimum-norm" in info["note"]
    assert info["residual"] < 1e-9
    # planar loads and motion: the out-of-plane balance rows are homogeneous, so the
    # minimum-norm set has no axial force and no torque (about x, y) at any hinge,
    # while any of the undetermined self-stresses would add some
    out_of_plane = np.column_stack([r[f"{j}.{c}"] for j in "OABC" for c in ("fz", "tx", "ty")])
    assert np.abs(out_of_plane).max() < 1e-9
    # the ground forces still sum to the system's momentum rate minus gravity
    masses = {"crank": 1.0, "coupler": 2.0, "rocker": 1.5}
    total = sum(m * (np.column_stack([np.gradient(np.gradient(r[f"{b}.c{k}"], r.t), r.t)
                                      for k in "xyz"]) - [0, -G, 0])
                for b, m in masses.items())
    ground = vec(r, "O", "f") - vec(r, "C", "f")        # C acts on ground
    assert np.abs(ground - total)[2:-2].max() < 0.05     # O(h^2) differences at 10 ms


@pytest.mark.parametrize("kind", JOINTS)
def test_every_joint_type_closes_the_balance_within_its_subspace(kind, tmp_path):
    """Two free-ish bodies (the first free, the second held by the joint), gravity and
    a spin: 12 balance rows and at most 6 unknowns, so a subspace missing a direction
    the joint really transmits leaves a residual of the size of the loads (~10 N);
    a right one closes to rounding (1e-8 allowed)."""
    text = model_text(kind, "a").replace(f"name: j_{kind}\n",
                                         f"name: rx_{kind}\ngravity: [0, 0, -9.81]\n")
    text += ("initial:\n  bodies: {a: {angular_velocity: [1.5, 0.5, 0]},\n"
             "           b: {angular_velocity: [0.5, -1.0, 2.0]}}\n")
    r = fccgen.load_numeric(write(tmp_path, text)).simulate(t_end=0.05, dt=1e-3)
    info = r.info["reactions"]
    assert info["computed"] and info["residual"] < 1e-8, info
    f, t = vec(r, "J", "f"), vec(r, "J", "t")
    assert np.abs(np.concatenate([f, t], axis=1)).max() > 1e-2      # not empty


def test_a_spring_on_a_shared_joint_point_refuses_reactions(tmp_path):
    """A section-2 spring on the ball joint's point acts on both bodies at once: the
    run keeps going without reaction columns and says why; asking for them is an
    error naming the load."""
    text = ("name: rx_refused\npoints:\n  Q: {at: [1, 1, 1], fixed: true}\n"
            "  P: [0.1, 0.2, 0.3]\n  R: [0.6, 0.2, 0.3]\nvectors:\n  w: [0, 1, 0]\n"
            "bodies:\n  a: {mass: 1.0, center: [-0.4, 0.1, 0.0], inertia: [0.02, 0.03, 0.04]}\n"
            "  b: {points: [P, R], vector: w, mass: 1.0, inertia: [0.01, 0.01, 0.01]}\n"
            "joints:\n  - {name: J, type: spherical, bodies: [a, b], at: [0.1, 0.2, 0.3]}\n"
            "loads:\n  - {type: spring, ends: [Q, P], stiffness: 10}\n")
    solver = fccgen.load_numeric(write(tmp_path, text))
    r = solver.simulate(t_end=0.01, dt=1e-3)
    assert not r.info["reactions"]["computed"] and "J.fx" not in r.columns
    with pytest.raises(ModelError, match=r"m\.yaml:\d+: loads\[0\]: joint reactions "
                                         r"cannot be computed: its end P is shared by a "
                                         r"and b.*\(got 'P'\)"):
        reactions(solver, r)
    assert "J.fx" not in solver.simulate(t_end=0.01, dt=1e-3, reactions=False).columns


def test_cli_says_when_reactions_are_minimum_norm_and_can_skip_them(tmp_path, capsys):
    from fccgen.cli import main
    path, out = write(tmp_path, FOUR_BAR), tmp_path / "r.csv"
    assert main(["simulate", "--numeric", str(path), "--t-end", "0.01", "--dt", "1e-3",
                 "--out", str(out)]) == 0
    assert "reaction components are undetermined" in capsys.readouterr().err
    assert "O.fx" in out.read_text().splitlines()[0].split(",")
    assert main(["simulate", "--numeric", str(path), "--t-end", "0.01", "--dt", "1e-3",
                 "--no-reactions", "--out", str(out)]) == 0
    assert "O.fx" not in out.read_text().splitlines()[0].split(",")


def test_a_body_held_by_a_fixed_vector_outside_joints_refuses_reactions(tmp_path):
    """A section-2 body using a fixed vector z as its u is held by ground through it
    (a hidden hinge carrying torque): no joint's reaction holds that torque, so the
    balance cannot be closed; the run says which triple."""
    text = model_text("revolute").replace("name: j_revolute\n", "name: rx_fixed\n") + (
        "points:\n  P: [2, 0, 0]\n  Q: [3, 0, 0]\n"
        "vectors:\n  z: {along: [0, 0, 1], fixed: true}\n")
    text = text.replace("bodies:\n", "bodies:\n  c: {points: [P, Q], vector: z, mass: 1.0, "
                                      "inertia: [0.01, 0.1, 0.1]}\n", 1)
    r = fccgen.load_numeric(write(tmp_path, text)).simulate(t_end=0.002, dt=1e-3)
    reason = r.info["reactions"]["reason"]
    assert "z: joint reactions cannot be computed: body c is held by this fixed triple" \
        in reason, reason


def test_torsion_spring_torque_given_to_its_bodies(tmp_path):
    """The body balance's torque of a torsion spring (the hinge of
    tests/test_torsion_spring.py: ground and an arm turning about z): on the arm
    -(k phi + c phi') z with phi the arm's turn from its start minus the free angle,
    as docs/elements.md defines the element (rounding: 1e-12)."""
    from fccgen.mechanism.body_motion import Motion
    from fccgen.mechanism.reactions import applied
    from test_torsion_spring import HINGE
    k, angle, c = 3.0, 0.5, 0.2
    solver = fccgen.load_numeric(write(tmp_path, HINGE.format(k=k, angle=angle, c=c)))
    r = solver.simulate(t_end=0.3, dt=1e-3, output_dt=0.05)
    plan = solver.plan
    names = [name for name, _ in plan.triples]
    q = np.column_stack([r[f"{t}.{x}"] for t in names for x in "xyz"])
    v = np.column_stack([r[f"{t}.v{x}"] for t in names for x in "xyz"])
    a = np.array([solver.accelerations(qk, vk) for qk, vk in zip(q, v)])
    index = {name: b for b, (name, _) in enumerate(plan.bodies)}
    wrench = applied(plan, Motion(plan, q, v, a), index)[:, 6 * index["arm"]:][:, :6]
    phi = np.arctan2(r["P.y"], r["P.x"]) - np.arctan2(0.8, 0.6) - angle
    torque = -(k * phi + c * r["arm.wz"])
    assert np.abs(wrench[:, 5] - torque).max() < 1e-12
    assert np.abs(wrench[:, :5]).max() < 1e-12
    assert np.abs(torque).max() > 1.0
