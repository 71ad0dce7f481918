"""The mechanism-level examples against independent checks: the spatial slider-crank
against a minimal-coordinate reference (tests/rsup_reference.py) and the deployable
structure in joint form against its section-2 form (the scissor boom:
tests/test_scissor_boom_latch.py)."""
from __future__ import annotations

import numpy as np

import rsup_reference


def test_rsup_crank_angle_against_the_minimal_coordinate_reference(compiled):
    """examples/rsup.yaml, RK4 at 0.25 ms for 2 s (the crank turns 3.5 times) against
    the energy equation in the crank angle integrated at 1e-13: the RK4 error shrinks
    as dt^4 (measured 2.1e-6 rad at 1 ms, 6.0e-8 at 0.5 ms, 4.7e-10 at 0.25 ms),
    so 1e-8 rad holds with margin; the rate to 1e-7 rad/s (measured 7.7e-9)."""
    r = compiled("rsup").simulate(t_end=2.0, dt=2.5e-4, output_dt=0.01, reactions=False)
    theta, rate = rsup_reference.crank_angle(6.0, r.t)
    assert abs(r["A.rate"][0] - 6.0) < 1e-12                 # the given joint rate
    assert np.abs(r["A.angle"] - theta).max() < 1e-8
    assert np.abs(r["A.rate"] - rate).max() < 1e-7
    assert theta[-1] > 20.0                                  # several turns


def test_deployable_in_joint_form_moves_as_the_section_2_form(compiled):
    """examples/deployable_joints.yaml (pose-form bodies, five revolutes and a
    point_on_line joint, 5 redundant equations) against examples/deployable.yaml
    (shared points and a fixed hinge vector): the same equations of motion in other
    coordinates, so the mass centres agree to the RK4 error difference of two
    formulations at the same step plus rounding (measured 3.5e-8 mm over 0.2 s while
    the boom's centre moves 270 mm; 1e-6 mm allowed), and the motion is the paper's
    folding."""
    section2, joints = compiled("deployable").simulate(), compiled("deployable_joints").simulate()
    assert np.array_equal(section2.t, joints.t)
    for body in ("body1", "body2", "body3", "body4"):
        for axis in "xyz":
            column = f"{body}.c{axis}"
            assert np.abs(section2[column] - joints[column]).max() < 1e-6, column
    assert joints["body4.cx"][0] - joints["body4.cx"][-1] > 250.0
