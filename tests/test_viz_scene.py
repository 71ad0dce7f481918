"""What the animation page draws (fccgen.viz.scene): every example's page holds its
bodies -- named, at their mass centres, with their solids and segments -- and its
joints, read back from the page's own data; inertia boxes against the closed form of
a box's inertia."""
from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest

from conftest import EXAMPLES
from fccgen.model import load_model
from fccgen.viz.animate import write_animation
from fccgen.viz.scene import inertia_box

MODELS = sorted(p.stem for p in EXAMPLES.glob("*.yaml"))


def _array(value):
    """A page's array: a JSON list, or plotly's typed array {dtype, bdata (base64)}."""
    if isinstance(value, dict) and "bdata" in value:
        return np.frombuffer(base64.b64decode(value["bdata"]), dtype=value["dtype"]).tolist()
    return value


def page_data(html: str) -> list[dict]:
    """The traces of the first frame, as the page gives them to Plotly.newPlot."""
    start = html.index("Plotly.newPlot(")
    after_id = html.index(",", start) + 1          # Plotly.newPlot("id", [traces], ...
    data, _ = json.JSONDecoder().raw_decode(html[after_id:].lstrip())
    return [{k: _array(v) for k, v in trace.items()} for trace in data]


def by_name(data, name):
    found = [t for t in data if t.get("name") == name]
    return found[0] if found else None


@pytest.mark.parametrize("name", MODELS)
def test_every_example_page_draws_its_bodies_and_joints(name, compiled, tmp_path):
    solver = compiled(name)
    model = load_model(EXAMPLES / f"{name}.yaml")
    dt = solver.plan.model.simulate.dt
    result = solver.simulate(t_end=4 * dt, dt=dt, output_dt=dt)
    page, n_frames = write_animation(model, result, tmp_path / f"{name}.html", 5)
    assert n_frames == len(result.t) == 5
    data = page_data(page.read_text(encoding="utf-8"))
    bodies = [*model.bodies, *model.pose_bodies]
    centres = by_name(data, "bodies (mass centres)")
    assert centres["text"] == bodies
    for k, b in enumerate(bodies):                  # each body where the run put it
        for c, axis in enumerate("xyz"):
            assert centres[axis][k] == pytest.approx(result[f"{b}.c{axis}"][0],
                                                     abs=1e-9)
    segments = by_name(data, "body segments")
    assert set(bodies) <= set(segments["text"])
    assert sum(x is None for x in segments["x"]) >= len(bodies)
    drawn = set()
    for kind in ("bodies (shapes)", "bodies (inertia boxes)"):
        mesh = by_name(data, kind)
        if mesh is not None:
            assert len(mesh["i"]) >= 12 and len(mesh["x"]) >= 8     # a box at least
            drawn |= set(mesh["hovertext"])
    with_inertia = [b for b in bodies
                    if np.trace((model.bodies.get(b) or model.pose_bodies[b]).inertia) > 0]
    assert set(with_inertia) <= drawn
    joints = by_name(data, "joints")
    assert set(j.name for j in model.joints) <= set(joints["text"])
    members = by_name(data, "cables")                # flexible members as curves
    assert (members is not None) == bool(model.cables)
    if members is not None:                          # one curve each, tip where the run put it
        assert members["x"].count(None) == len(model.cables)
        tip = f"{next(iter(model.cables))}.tip"
        assert members["x"][members["x"].index(None) - 1] == pytest.approx(
            result[f"{tip}.x"][0], abs=1e-12)
    # only names the user wrote are shown: no point the lowering made
    labels = [t for trace in data for t in (trace.get("text") or []) if isinstance(t, str)]
    assert not [t for t in labels if re.search(r"_(axis\d?|center|end|[xyz]|a|b|n\d|nb|"
                                               r"drive_[ab]|spring\d)$", t)], labels


@pytest.mark.parametrize("edges", [(1.0, 0.1, 0.02), (0.3, 0.3, 0.3), (2.0, 0.5, 1.0)])
def test_inertia_box_of_a_box_is_the_box(edges):
    """A uniform box of mass m: I_x = m (b^2 + c^2) / 12, ...; rotated by R."""
    m = 3.0
    a, b, c = edges
    principal = m / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    angle = 0.7
    R = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0],
                  [0, 0, 1]])
    size, axes = inertia_box(m, R @ np.diag(principal) @ R.T)
    order = np.argsort(size)
    assert np.allclose(np.sort(size), np.sort(edges), rtol=1e-12)
    if len(set(edges)) == 3:                        # distinct edges: distinct axes
        longest = axes[order[-1]]
        assert abs(abs(longest @ R[:, int(np.argmax(edges))]) - 1.0) < 1e-12
    assert inertia_box(1.0, np.zeros((3, 3))) is None
