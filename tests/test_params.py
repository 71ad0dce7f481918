"""Other numbers for a compiled model from Python (CompiledSolver.with_parameters) and
compiled solvers that cross processes (pickling): the same results as editing the
model file, structure-changing values refused, identical runs after a round trip."""
from __future__ import annotations

import multiprocessing
import operator
import pickle
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.errors import ModelError
from fccgen.runtime.params import split_key, value_of

DOUBLE = EXAMPLES / "double_pendulum.yaml"
T_END = 0.5


@pytest.fixture(scope="module")
def solver(build_dir):
    return fccgen.load(DOUBLE, build_dir)


def test_keys_split_into_items_and_components():
    assert split_key("bodies.arm.center[0]") == ["bodies", "arm", "center", 0]
    assert split_key("loads[1].stiffness") == ["loads", 1, "stiffness"]
    with pytest.raises(ModelError, match="settable numbers"):
        split_key("bodies..mass")


def runs_of_edit_and_keys(solver, path, edits, values, build_dir, tmp_path):
    """(the run of the model file with ``edits`` made, the solver with ``values`` set,
    its run): each edit (old, new) replaces text that occurs once."""
    text = path.read_text()
    for old, new in edits:
        assert text.count(old) == 1
        text = text.replace(old, new)
    edited = tmp_path / path.name
    edited.write_text(text)
    expected = fccgen.load(edited, build_dir).simulate(t_end=T_END).table()
    changed = solver.with_parameters(values)
    return expected, changed, changed.simulate(t_end=T_END).table()


@pytest.mark.parametrize("values, edits", [
    ({"bodies.rod2.mass": 0.9}, [("mass: 0.6", "mass: 0.9")]),
    ({"points.P2.at": [1.7, -0.6, 0.0], "bodies.rod2.center[0]": 0.45,
      "gravity[1]": -9.7},
     [("P2: [1.6, -0.6, 0]", "P2: [1.7, -0.6, 0]"), ("center: [0.4, 0, 0]",
                                                      "center: [0.45, 0, 0]"),
      ("gravity: [0, -9.81, 0]", "gravity: [0, -9.7, 0]")]),
])
def test_with_parameters_is_editing_the_model_file(solver, build_dir, tmp_path, values,
                                                   edits):
    expected, changed, got = runs_of_edit_and_keys(solver, DOUBLE, edits, values,
                                                   build_dir, tmp_path)
    # The same numbers reach the same compiled kernels: equal to rounding. 1e-12
    # allows for a last-digit difference in numbers computed from the positions.
    assert np.abs(got - expected).max() <= 1e-12
    base = solver.simulate(t_end=T_END).table()
    assert np.abs(got - base).max() > 1e-3               # and the numbers did change
    assert changed.module is solver.module               # nothing rebuilt or reloaded



def test_inertia_components_set_together_are_judged_as_one_tensor(solver):
    """rod2's [1.2e-4, 0.03206, 0.03206]: Iyy = 0.05 alone breaks Iyy <= Ixx + Izz,
    with Izz = 0.05 beside it the tensor is fine; its rules still hold for the set."""
    with pytest.raises(ModelError, match="triangle inequality"):
        solver.with_parameters({"bodies.rod2.inertia[1]": 0.05})
    moved = solver.with_parameters({"bodies.rod2.inertia[1]": 0.05,
                                    "bodies.rod2.inertia[2]": 0.05})
    assert np.allclose(value_of(moved.plan.model, "bodies.rod2.inertia"),
                       [1.2e-4, 0.05, 0.05, 0, 0, 0], rtol=1e-15, atol=0)
    with pytest.raises(ModelError, match=r"inertia\[1\], bodies.rod2.inertia\[2\]: "
                                         "principal moments"):
        solver.with_parameters({"bodies.rod2.inertia[1]": 0.05,
                                "bodies.rod2.inertia[2]": 0.2})

RSUP = EXAMPLES / "rsup.yaml"


@pytest.mark.parametrize("values, edits", [
    # a body with a tilted frame: Iyy in that frame, not in the body's internal one
    ({"bodies.rod.inertia[1]": 3.72e-3},
     [("inertia: [5.0e-5, 3.75e-3, 3.75e-3]", "inertia: [5.0e-5, 3.72e-3, 3.75e-3]")]),
    # the crank turns about x; its frame puts x along the global z: Izz of the file
    ({"bodies.crank.inertia[2]": 1.5e-5},
     [("inertia: [1.0e-4, 1.0e-4, 1.0e-5]", "inertia: [1.0e-4, 1.0e-4, 1.5e-5]")]),
    # the mass centre of a pose-form body is a global position, as in the file (the
    # crank's moves along its axis A-B, the slider's along its guide: both keep the
    # compiled structural zeros)
    ({"bodies.crank.center": [0, 0.1, 0.17], "bodies.slider.center[0]": 0.26},
     [("center: [0, 0.1, 0.16]", "center: [0, 0.1, 0.17]"),
      ("center: [0.25, 0, 0]", "center: [0.26, 0, 0]")]),
])
def test_pose_form_keys_are_the_model_files_terms(build_dir, tmp_path, values, edits):
    """A pose-form body keeps its inertia and centre in the frame the lowering chose
    (i, j, u); its keys must still address the numbers as the file writes them, in
    its ``frame`` and globally."""
    solver = fccgen.load(RSUP, build_dir)
    expected, changed, got = runs_of_edit_and_keys(solver, RSUP, edits, values,
                                                   build_dir, tmp_path)
    # the same numbers through the same kernels; 1e-12 of each column's size (at
    # least 1) for the rotation to the internal frame and back, a few roundings that
    # the reactions (forces of tens of newtons) carry in their own units
    scale = np.maximum(1.0, np.abs(expected).max(axis=0))
    assert (np.abs(got - expected) / scale).max() <= 1e-12
    assert np.abs(got - solver.simulate(t_end=T_END).table()).max() > 1e-6
    for key, value in values.items():
        assert np.allclose(value_of(changed.plan.model, key), value, rtol=1e-14, atol=0)


@pytest.mark.parametrize("values, words", [
    ({"bodies.rod2.mass": -1.0}, ["double_pendulum.yaml:", "bodies.rod2.mass",
                                  "must be a positive number", "-1.0"]),
    ({"bodies.rod9.mass": 1.0}, ["no body named 'rod9'", "bodies: rod1, rod2"]),
    ({"bodies.rod2.colour": 1.0}, ["is not a number fccgen can set", "bodies.NAME.mass"]),
    ({"loads[0].stiffness": 1.0}, ["the model has no loads"]),
    ({"vectors.z.along": [0, 0, 2]}, ["must be a unit vector"]),
    ({"bodies.rod1.inertia[0]": 1.0}, ["triangle inequality"]),
    ({"bodies.rod1.mass": "heavy"}, ["must be a number"]),
    # structural zeros: folded terms cannot come back, kept ones cannot vanish
    ({"bodies.rod2.center[1]": 0.1}, ["a2 of bodies.rod2 nonzero", "structural zero",
                                      "new build"]),
    ({"gravity[2]": 1.0}, ["gz of bodies.rod1 nonzero"]),
    ({"gravity[1]": 0.0}, ["gy of bodies.rod1 exactly 0", "keeps"]),
])
def test_bad_values_are_refused_with_the_rule(solver, values, words):
    with pytest.raises(ModelError) as info:
        solver.with_parameters(values)
    for w in words:
        assert w in str(info.value)


def test_with_parameters_leaves_the_solver_alone(solver):
    before = solver.simulate(t_end=T_END).table()
    solver.with_parameters({"bodies.rod1.mass": 3.0})
    assert np.array_equal(solver.simulate(t_end=T_END).table(), before)


def test_pickled_solver_runs_identically_in_another_process(solver):
    changed = solver.with_parameters({"bodies.rod2.mass": 0.9})
    here = changed.simulate(t_end=T_END)
    assert pickle.loads(pickle.dumps(changed)).plan.model.bodies["rod2"].mass == 0.9
    spawn = multiprocessing.get_context("spawn")       # a fresh interpreter
    with ProcessPoolExecutor(max_workers=1, mp_context=spawn) as pool:
        there = pool.submit(operator.methodcaller("simulate", t_end=T_END), changed).result()
    # the same compiled module, inputs and single-threaded BLAS: bit for bit
    assert there.names == here.names
    assert np.array_equal(there.table(), here.table())


def _same(a, b) -> bool:
    """Deep equality of two model parts (dataclasses, dicts, lists, arrays, numbers)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b))
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if hasattr(a, "__dict__"):
        return _same(vars(a), vars(b))
    return a == b


def _changed_values(model) -> dict:
    """Every settable number of the model, moved by a small step that keeps it valid."""
    from fccgen.runtime.params import value_of
    keys = ["gravity", "simulate.t_end"]
    keys += [f"bodies.{n}.{f}" for n in model.bodies for f in ("mass", "center", "inertia")]
    keys += [f"points.{n}.at" for n in model.points if "." not in n]   # not cable nodes
    keys += [f"vectors.{n}.along" for n in model.vectors if "." not in n]
    keys += [f"constraints[{k}].length" for k, c in enumerate(model.constraints)
             if getattr(c, "length", None) is not None]
    keys += [f"loads[{k}].{f}" for k, ld in enumerate(model.loads)
             for f in ("value", "stiffness", "damping")
             if np.ndim(getattr(ld, f, None)) == 0 and getattr(ld, f, None) is not None]
    keys += [f"cables.{n}.{f}" for n in (model.cables or {})
             for f in ("EA", "EI", "mass_per_length")]
    keys += [f"initial.points.{n}" for n in model.initial.point_velocities]
    values = {}
    for key in keys:
        x = value_of(model, key)
        if key.endswith(".along"):
            values[key] = list(-np.asarray(x))            # still a unit vector
        elif key.endswith((".at", ".center")) or key.startswith("initial."):
            values[key] = list(np.asarray(x) + 1e-3)
        else:
            values[key] = (np.asarray(x) * 1.01).tolist()
    return values


@pytest.mark.parametrize("name", ["double_pendulum", "solar_array", "andrews", "cantilever",
                                  "free_body", "deployable_joints", "tape_spring_hinge"])
def test_set_parameters_copies_what_it_sets_and_leaves_the_model_alone(name):
    """set_parameters copies only the parts its keys set (copy on write). With every
    settable number of the model moved at once, the copy equals the one a full deep
    copy of the model gives (the rule it replaced), the plans made from both hold the
    same numbers, and the model it was given is unchanged, part for part."""
    import copy

    from fccgen.api import plan_model
    from fccgen.plan import make_plan
    from fccgen.runtime import params
    model = plan_model(EXAMPLES / f"{name}.yaml").model
    values = _changed_values(model)
    snapshot = copy.deepcopy(model)
    got = params.set_parameters(model, values)
    assert _same(model, snapshot)
    reference = copy.deepcopy(model)
    for key, value in values.items():
        params._set_one(reference, key, value)
    assert _same(got, reference)
    assert not _same(got, snapshot)
    for a, b in zip(make_plan(got).elements, make_plan(reference).elements):
        assert np.array_equal(a.params, b.params)
