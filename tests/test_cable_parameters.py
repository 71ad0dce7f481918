"""A member's numbers as with_parameters keys (cables.NAME.EA, EI, mass_per_length,
damping, distributed_load): the same compiled module, the same motion as a model file
with those numbers written in, and the closed form of the cantilever's tip."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from fccgen.analysis import statics
from fccgen.errors import ModelError

from conftest import EXAMPLES


def tip_y(solver) -> float:
    q = statics(solver).q
    k = solver.plan.triples.index(next(t for t in solver.plan.triples
                                       if t[0] == "beam.tip"))
    return float(q[3 * k + 1])


def test_a_member_set_by_keys_runs_as_the_file_with_those_numbers(compiled, build_dir,
                                                                    tmp_path):
    """Bit-for-bit the run of the model file with the numbers written in (the same
    module, the same parameters): 1e-12 of each column's size allows for nothing but
    the order in which a parameter list is filled."""
    solver = compiled("cantilever")
    keys = {"cables.beam.EI": 40.0, "cables.beam.EA": 2.0e5,
            "cables.beam.mass_per_length": 3.0}
    changed = solver.with_parameters(keys)
    assert changed.module is solver.module
    text = (EXAMPLES / "cantilever.yaml").read_text()
    text = (text.replace("EI: 20.0", "EI: 40.0").replace("EA: 1.0e5", "EA: 2.0e5")
            .replace("mass_per_length: 2.0", "mass_per_length: 3.0"))
    assert text.count("40.0") == 1 and text.count("2.0e5") == 1
    path = tmp_path / "cantilever.yaml"
    path.write_text(text)
    written = fccgen.load(path, build_dir)
    a = changed.simulate(t_end=0.005, dt=1e-4, method="rk4", reactions=False)
    b = written.simulate(t_end=0.005, dt=1e-4, method="rk4", reactions=False)
    assert a.names == b.names
    for name in a.names:
        scale = max(1.0, float(np.max(np.abs(b[name]))))
        assert np.max(np.abs(a[name] - b[name])) <= 1e-12 * scale, name


def test_twice_the_bending_stiffness_halves_the_tip_deflection(compiled):
    """P L^3 / (3 EI): the tip's static deflection scales as 1/EI (the example's load
    bends it by 2.5e-3 m, where the large-deflection correction is 1e-6 of it)."""
    solver = compiled("cantilever")
    stiff = solver.with_parameters({"cables.beam.EI": 40.0})
    d1, d2 = tip_y(solver), tip_y(stiff)
    assert d1 == pytest.approx(-0.15 / (3 * 20.0), rel=1e-3)
    assert d2 / d1 == pytest.approx(0.5, rel=1e-5)


@pytest.mark.parametrize("key, value, rule", [
    ("cables.beam.EI", -1.0, "must be a positive number"),
    ("cables.beam.EA", 0.0, "must be a positive number"),
    ("cables.beam.damping", -0.1, "must be a number >= 0"),
    ("cables.mast.EI", 1.0, "no cable named 'mast'; cables: beam"),
    ("cables.beam.elements", 4, "is not a number fccgen can set"),
    # the example has no damping and no distributed load: its kernels fold them away
    ("cables.beam.damping", 1e-4, "folded away as a structural zero"),
    ("cables.beam.distributed_load[1]", -0.5, "folded away as a structural zero"),
])
def test_bad_member_numbers_are_refused_with_their_key(compiled, key, value, rule):
    with pytest.raises(ModelError) as caught:
        compiled("cantilever").with_parameters({key: value})
    assert key in str(caught.value) and rule in str(caught.value)
