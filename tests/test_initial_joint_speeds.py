"""Initial speeds given as joint rates are kept exactly (``initial: joints:``); the
velocity projection alone moved a crank's 6 rad/s to another value."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.errors import ModelError

JOINT_FORM = "  joints: {A: {rate: 6.0}}"
BODY_FORM = "  bodies: {crank: {angular_velocity: [6.0, 0, 0]}}"
RSUP = (EXAMPLES / "rsup.yaml").read_text().replace(JOINT_FORM, BODY_FORM)


def rsup_with(tmp_path, initial: str, name: str = "rsup_rate"):
    path = tmp_path / f"{name}.yaml"
    path.write_text(RSUP.replace(BODY_FORM, initial).replace("name: rsup", f"name: {name}"))
    return path


def test_a_crank_rate_is_kept_exactly(tmp_path, build_dir):
    """The spatial slider-crank with its crank given 6 rad/s as a joint rate: J.rate at
    t = 0 is 6 to rounding, B v = 0 holds, and the numeric solver finds the same speeds.
    The same 6 rad/s given as the crank's angular velocity is projected to another
    rate (the projection spreads it over the coupled bodies in the mass metric)."""
    path = rsup_with(tmp_path, "  joints: {A: {rate: 6.0}}")
    solver = fccgen.load(path, build_dir)
    init = solver.initial_state()
    result = solver.simulate(t_end=0.01, q0=init.q, v0=init.v)
    assert result["A.rate"][0] == pytest.approx(6.0, abs=1e-12)
    assert np.max(np.abs(solver.constraint_jacobian(init.q) @ init.v)) < 1e-12
    numeric = fccgen.load_numeric(path).initial_state()
    assert np.max(np.abs(numeric.v - init.v)) < 1e-12
    projected = fccgen.load_numeric(rsup_with(tmp_path, BODY_FORM, "rsup_body")).simulate(
        t_end=0.01)
    assert abs(projected["A.rate"][0] - 6.0) > 0.1


def test_speeds_the_constraints_refuse_are_an_error(tmp_path):
    """The mechanism has one degree of freedom: the crank rate fixes the slider
    speed, so asking for both with a slider speed of 1 m/s cannot hold."""
    path = rsup_with(tmp_path, "  joints: {A: {rate: 6.0}, S: {speed: 1.0}}",
                     name="rsup_clash")
    with pytest.raises(ModelError, match=r"rsup_clash\.yaml:\d+: initial\.joints: these "
                                         r"joint speeds cannot all hold.*nearest "
                                         r"consistent speeds are A\.rate = .*"
                                         r"\(got 'A\.rate = 6, S\.speed = 1'\)"):
        fccgen.load_numeric(path).initial_state()


@pytest.mark.parametrize("initial, item, rule", [
    ("  joints: {Z: {rate: 1.0}}", "initial.joints.Z", "names no joint; joints are: A"),
    ("  joints: {S: {rate: 1.0}}", "initial.joints.S.rate",
     "a prismatic joint has no rate; rate is for revolute and cylindrical joints"),
    ("  joints: {A: {speed: 1.0}}", "initial.joints.A.speed",
     "a revolute joint has no speed"),
    ("  joints: {A: {rate: 1.0, speed: 2.0}}", "initial.joints.A",
     "must give exactly one of rate"),
    ("  joints: {A: {rate: fast}}", "initial.joints.A.rate", "must be a number"),
])
def test_bad_initial_joint_speeds(tmp_path, initial, item, rule):
    path = rsup_with(tmp_path, initial, name="rsup_bad")
    with pytest.raises(ModelError) as info:
        fccgen.load_numeric(path)
    text = str(info.value)
    assert f"rsup_bad.yaml:" in text and f"{item}: {rule}" in text, text
