"""The mechanism-level examples against independent checks: the spatial slider-crank
against a minimal-coordinate reference (tests/rsup_reference.py), the scissor boom's
degree of freedom, energy and symmetry, and the deployable structure in joint form
against its section-2 form."""
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


def test_scissor_boom_one_freedom_energy_and_symmetry(compiled):
    """examples/scissor_boom.yaml (12 units, 24 bars, torsion springs at the pivots):
    1 degree of freedom by rank; no damping and no gravity, so the energy (kinetic +
    spring) stays at its start to the RK4 error (measured 1.2e-9 J of 131.6 J over
    the whole 4 s swing; 1e-8 allowed over 0.5 s); the base holds the boom symmetric
    about x, so top and bottom nodes mirror each other, and one degree of freedom
    makes every unit equally wide: both to rounding (measured 3e-14 m; 1e-10 allowed).
    The springs deploy it: the tip moves out."""
    solver = compiled("scissor_boom")
    r = solver.simulate(t_end=0.5)
    assert r.info["dof"] == 1
    e = r["energy"]
    assert np.abs(e - e[0]).max() < 1e-8
    n = 12
    mirror = max(np.abs(r[f"T{k}.y"] + r[f"B{k}.y"]).max() for k in range(n + 1))
    aligned = max(np.abs(r[f"T{k}.x"] - r[f"B{k}.x"]).max() for k in range(n + 1))
    equal = max(np.abs(r[f"T{k}.x"] - k * r["T1.x"]).max() for k in range(n + 1))
    assert max(mirror, aligned, equal) < 1e-10
    assert r["T12.x"][-1] > r["T12.x"][0] + 1.0
    assert not r.info["reactions"]["computed"]          # shared end nodes (section 2)


def test_scissor_boom_file_is_the_generator_output():
    """The committed example is what examples/make_scissor_boom.py writes for N = 12."""
    import importlib.util
    from conftest import EXAMPLES
    spec = importlib.util.spec_from_file_location("make_scissor_boom",
                                                  EXAMPLES / "make_scissor_boom.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.model_text(12) == (EXAMPLES / "scissor_boom.yaml").read_text()
