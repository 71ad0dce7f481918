"""examples/andrews.yaml against the published problem (tests/andrews_reference.py):
its geometry at the published initial angles, its initial accelerations against the
published ones, and its motion against the published equations and the published
solution at t = 0.03 s."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

import andrews_reference as ref
from conftest import EXAMPLES

JOINT_POINTS = ("F", "E", "G", "E4", "H", "E6")      # the model's moving points
CENTRES = tuple(f"body{k}" for k in range(1, 8))
MODEL = yaml.safe_load((EXAMPLES / "andrews.yaml").read_text())


@pytest.fixture(scope="module")
def andrews(compiled):
    return compiled("andrews")


@pytest.fixture(scope="module")
def published_run():
    """The published equations over the run, at the model's output times."""
    t = np.linspace(0.0, ref.T_END, 101)
    return t, ref.solve(t)


def positions(result, k):
    """{name: (x, y)} of the joint points and mass centres at output k."""
    out = {n: np.array([result[f"{n}.x"][k], result[f"{n}.y"][k]]) for n in JOINT_POINTS}
    out.update({b: np.array([result[f"{b}.cx"][k], result[f"{b}.cy"][k]]) for b in CENTRES})
    return out


def test_the_reference_meets_the_published_values():
    g, _, _ = ref.constraints(ref.Q0, np.zeros(7))
    qdd, lam = ref.accelerations(ref.Q0, np.zeros(7))
    # the published initial values are consistent to their 16+ digits
    assert np.max(np.abs(g)) < 1e-16
    np.testing.assert_allclose(qdd, ref.QDD0, rtol=0, atol=1e-10 * np.max(np.abs(ref.QDD0)))
    np.testing.assert_allclose(lam, ref.LAMBDA0, rtol=0,
                               atol=1e-12 * np.max(np.abs(ref.LAMBDA0)))
    y = ref.solve([0.0, ref.T_END])[-1]
    # PSIDE at 1e-14 and DOP853 at 1e-13: the crank angle (15.8 rad) agrees to 1.4e-9
    # rad, the rates (up to 1424 rad/s) to 2e-7; positions to 8e-12 m (measured)
    np.testing.assert_allclose(y[:7], ref.Q_END, rtol=0, atol=5e-9)
    np.testing.assert_allclose(y[7:], ref.QD_END, rtol=0, atol=1e-6)
    ours, theirs = ref.points(y[:7]), ref.points(ref.Q_END)
    assert max(np.linalg.norm(ours[n] - theirs[n]) for n in ours) < 5e-11


def test_the_file_holds_the_published_geometry():
    p, at0, axes = ref.P, ref.points(ref.Q0), ref.body_axes(ref.Q0)
    joints = {j["name"]: j for j in MODEL["joints"]}
    named = dict(O="O", F="F", B="B", E="E", A5="A", G="G", E4="E", A7="A", H="H", E6="E")
    for joint, point in named.items():
        np.testing.assert_allclose(joints[joint]["at"][:2], at0[point], rtol=0, atol=1e-15)
        assert joints[joint]["axis"] == [0, 0, 1] and joints[joint]["type"] == "revolute"
    for k, name in enumerate(CENTRES, start=1):
        body = MODEL["bodies"][name]
        assert body["mass"] == p[f"m{k}"]
        assert body["inertia"] == [p[f"i{k}"] / 2, p[f"i{k}"] / 2, p[f"i{k}"]]
        np.testing.assert_allclose(body["center"][:2], at0[name], rtol=0, atol=1e-15)
        for axis, value in zip("xy", axes[name]):
            np.testing.assert_allclose(body["frame"][axis][:2], value, rtol=0, atol=1e-15)
    torque, spring = MODEL["loads"]
    assert torque == dict(type="torque", body="body1", value=[0, 0, p["mom"]])
    assert (spring["stiffness"], spring["length"]) == (p["c0"], p["l0"])
    assert MODEL["points"]["C"]["at"][:2] == [p["xc"], p["yc"]]
    # the spring's end, given from body3's mass centre in body3's axes, is D
    x3, y3 = axes["body3"]
    end = spring["ends"][1]["at"]
    np.testing.assert_allclose(at0["body3"] + end[0] * x3 + end[1] * y3, at0["D"],
                               rtol=0, atol=1e-15)


def test_the_initial_accelerations_are_the_published_ones(andrews):
    init = andrews.initial_state()
    qdd = andrews.accelerations(init.q, init.v)
    index = andrews.plan.index

    def acc(name):
        return qdd[3 * index[name]:3 * index[name] + 3]
    # at rest: F turns about O with the crank's published beta'' (14222 rad/s^2);
    # E, G, H stay (gamma'' = delta'' = epsilon'' = 0 in the published values)
    scale = ref.P["rr"] * ref.QDD0[0]
    x1, y1 = ref.body_axes(ref.Q0)["body1"]
    # 1e-12 relative: one solve of a 36-coordinate system (measured 2e-15)
    np.testing.assert_allclose(acc("F"), [*(scale * y1), 0.0], rtol=0, atol=1e-12 * scale)
    for name in ("E", "G", "H", "E4", "E6"):
        np.testing.assert_allclose(acc(name), 0.0, rtol=0, atol=1e-12 * scale)


def test_the_motion_follows_the_published_equations(andrews, published_run):
    t, states = published_run
    r = andrews.simulate(method="dopri5", rtol=1e-12, atol=1e-15, output_dt=ref.T_END / 100,
                         reactions=False)
    assert np.allclose(r.t, t, rtol=0, atol=1e-15)
    worst = max(np.linalg.norm(positions(r, k)[n] - ref.points(y[:7])[n])
                for k, y in enumerate(states) for n in JOINT_POINTS + CENTRES)
    # dopri5 at 1e-12 and DOP853 at 1e-13 on the angles: measured 4.6e-13 m over the
    # 2.5 turns of the crank, at every output time, every joint point and mass centre
    assert worst < 5e-12
    # and the published solution at t = 0.03 (PSIDE at 1e-14): measured 8e-12 m
    end = ref.points(ref.Q_END)
    assert max(np.linalg.norm(positions(r, -1)[n] - end[n])
               for n in JOINT_POINTS + CENTRES) < 5e-11
    # the planar motion stays in its plane
    assert max(np.max(np.abs(r[f"{n}.z"])) for n in JOINT_POINTS) == 0.0
