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
from fccgen.runtime.params import split_key

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
    text = DOUBLE.read_text()
    for old, new in edits:
        assert text.count(old) == 1
        text = text.replace(old, new)
    edited = tmp_path / "double_pendulum.yaml"
    edited.write_text(text)
    expected = fccgen.load(edited, build_dir).simulate(t_end=T_END).table()
    changed = solver.with_parameters(values)
    got = changed.simulate(t_end=T_END).table()
    # The same numbers reach the same compiled kernels: equal to rounding. 1e-12
    # allows for a last-digit difference in numbers computed from the positions.
    assert np.abs(got - expected).max() <= 1e-12
    base = solver.simulate(t_end=T_END).table()
    assert np.abs(got - base).max() > 1e-3               # and the numbers did change
    assert changed.module is solver.module               # nothing rebuilt or reloaded


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
