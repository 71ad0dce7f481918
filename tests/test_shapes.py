"""Shapes of pose-form bodies (fccgen.model.shapes): the mass terms against the closed
forms written out here and against a numeric integration over the solid, a shaped
body equal to the same body given by mass and inertia, the shape drawn where the body
is, and a clear error for each misuse."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from fccgen.errors import ModelError
from fccgen.mechanism import lower
from fccgen.model.load import load_model_text
from fccgen.model.shapes import principal_inertia, volume
from fccgen.model.types import Solid

# Numeric integration of a uniform solid of density 1 (nquad, adaptive Gauss-Kronrod,
# its default tolerance 1.5e-8 relative): mass and the three moments about the centre.


def integrated(kind: str, size) -> tuple[float, np.ndarray]:
    if kind == "box":
        a, b, c = size
        box = [[-a / 2, a / 2], [-b / 2, b / 2], [-c / 2, c / 2]]

        def f(w):
            return lambda x, y, z: w(x, y, z)
        ranges, jac = box, (lambda *p: 1.0)
        to_xyz = (lambda x, y, z: (x, y, z))
    elif kind == "sphere":
        r = size[0]
        ranges = [[0, r], [0, math.pi], [0, 2 * math.pi]]
        jac = (lambda s, th, ph: s * s * math.sin(th))
        to_xyz = (lambda s, th, ph: (s * math.cos(th), s * math.sin(th) * math.cos(ph),
                                     s * math.sin(th) * math.sin(ph)))
    else:                                             # cylinder along x
        r, length = size
        ranges = [[-length / 2, length / 2], [0, r], [0, 2 * math.pi]]
        jac = (lambda x, s, ph: s)
        to_xyz = (lambda x, s, ph: (x, s * math.cos(ph), s * math.sin(ph)))

    def moment(weight):
        return integrate.nquad(lambda *p: weight(*to_xyz(*p)) * jac(*p), ranges)[0]
    mass = moment(lambda x, y, z: 1.0)
    inertia = np.array([moment(lambda x, y, z: y * y + z * z),
                        moment(lambda x, y, z: x * x + z * z),
                        moment(lambda x, y, z: x * x + y * y)])
    return mass, inertia


CASES = [("box", (0.4, 0.1, 0.03)), ("cylinder", (0.05, 0.3)), ("rod", (0.01, 1.2)),
         ("sphere", (0.2,))]


@pytest.mark.parametrize("kind, size", CASES)
def test_mass_terms_match_a_numeric_integration(kind, size):
    solid = Solid(kind, size)
    mass, inertia = integrated(kind, size)
    # the integration's own tolerance is 1.5e-8 relative; 1e-7 leaves room for its sum
    assert volume(solid) == pytest.approx(mass, rel=1e-7)
    assert principal_inertia(solid, mass) == pytest.approx(inertia, rel=1e-7)


def test_mass_terms_match_the_closed_forms():
    m = 2.0
    assert principal_inertia(Solid("box", (1.0, 2.0, 3.0)), m) == pytest.approx(
        [m * 13 / 12, m * 10 / 12, m * 5 / 12], rel=1e-15)
    assert principal_inertia(Solid("rod", (0.0 + 1e-3, 1.0)), m)[1] == pytest.approx(
        m / 12, rel=1e-5)                           # a slender rod: m L^2 / 12
    assert principal_inertia(Solid("sphere", (0.5,)), m) == pytest.approx([0.2] * 3)
    assert principal_inertia(Solid("cylinder", (1.0, 0.0 + 1e-9)), m)[0] == m / 2


BODY = """
name: shaped
gravity: [0, -9.81, 0]
bodies:
  plate: {{center: [0.5, 0.2, 0.1], frame: {{x: [0, 1, 0], y: [-1, 0, 0]}}, {spec}}}
joints:
  - {{name: A, type: revolute, bodies: [ground, plate], at: [0.5, 0, 0.1], axis: [0, 0, 1]}}
"""


def shaped(spec: str):
    return load_model_text(BODY.format(spec=spec), "shaped.yaml")


def test_a_shaped_body_is_the_body_with_its_mass_and_inertia():
    box = shaped("shape: {box: [0.4, 0.1, 0.02]}, density: 2700.0")
    m = 2700.0 * 0.4 * 0.1 * 0.02
    I = m / 12 * np.array([0.1 ** 2 + 0.02 ** 2, 0.4 ** 2 + 0.02 ** 2, 0.4 ** 2 + 0.1 ** 2])
    plain = shaped(f"mass: {m!r}, inertia: [{float(I[0])!r}, {float(I[1])!r}, {float(I[2])!r}]")
    a, b = box.pose_bodies["plate"], plain.pose_bodies["plate"]
    assert a.mass == pytest.approx(b.mass, rel=1e-15)
    assert np.allclose(a.inertia, b.inertia, rtol=1e-15, atol=0)
    la, lb = lower(box).bodies["plate"], lower(plain).bodies["plate"]
    assert np.allclose(la.inertia, lb.inertia, rtol=1e-12, atol=1e-18)
    assert lb.shape is None and la.shape.kind == "box"


def test_the_shape_is_drawn_where_the_body_is():
    """The box's corners at the centre +- half edges along the frame's axes (x = global
    y, y = -global x) at t = 0."""
    from fccgen.results.result import Result
    from fccgen.viz.scene import body_frames, body_solids, triple_tracks
    model = lower(shaped("shape: {box: [0.4, 0.1, 0.02]}, mass: 1.0"))
    columns = {}
    for p in [*model.points.values(), *model.vectors.values()]:
        value = p.at if hasattr(p, "at") else p.along
        for c in range(3):
            columns[f"{p.name}.{'xyz'[c]}"] = np.array([value[c]])
    tracks = triple_tracks(model, Result(np.zeros(1), columns))
    (solid,) = body_solids(model, body_frames(model, tracks))
    assert solid.kind == "shape"
    corners = solid.vertices[0]
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    assert np.allclose(lo, [0.5 - 0.05, 0.2 - 0.2, 0.1 - 0.01], atol=1e-12)
    assert np.allclose(hi, [0.5 + 0.05, 0.2 + 0.2, 0.1 + 0.01], atol=1e-12)


@pytest.mark.parametrize("spec, words", [
    ("shape: {box: [1, 1, 1]}, mass: 1.0, inertia: [1, 1, 1]", ["inertia", "not both"]),
    ("shape: {box: [1, 1, 1]}", ["exactly one of mass: or density:"]),
    ("shape: {box: [1, 1, 1]}, mass: 1.0, density: 2.0", ["exactly one of"]),
    ("shape: {cone: 1.0}, mass: 1.0", ["shape.cone", "unknown key"]),
    ("shape: {box: [1, 1]}, mass: 1.0", ["shape.box", "3 items"]),
    ("shape: {rod: {length: 1.0}}, mass: 1.0", ["shape.rod.radius", "missing"]),
    ("shape: {sphere: -1}, mass: 1.0", ["shape.sphere", "positive"]),
])
def test_misused_shapes_are_one_clear_error(spec, words):
    with pytest.raises(ModelError) as err:
        shaped(spec)
    text = str(err.value)
    assert "shaped.yaml" in text and "bodies.plate" in text
    for w in words:
        assert w in text, text
