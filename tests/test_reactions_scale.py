"""Joint reactions at scale (fccgen.mechanism.reaction_solve, reaction_system): the
sparse record-by-record solve equals the dense SVD of every record, the NumPy
version's, and itself in chunks of one record; a run whose reactions fail is kept."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import fccgen
from conftest import example_module
from fccgen.errors import RunWarning
from fccgen.mechanism import reactions as reaction_module
from fccgen.mechanism.reaction_solve import DENSE_UNKNOWNS
from fccgen.mechanism.reactions import reactions

# The sparse way solves the semi-normal equations with three corrections on E itself:
# its error is about cond(E)^2 eps relative to the largest reaction (cond(E) ~ 10 on
# these models: ~1e-14 measured); 1e-9 leaves five decades for other models' E.
SPARSE_VS_DENSE = 1e-9
# The NumPy version's accelerations are computed independently (other rounding, the
# same equations): q'' agrees to ~1e-12 relative, the reactions follow.
NUMERIC_VS_COMPILED = 1e-8


def _run(solver, t_end=0.2):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        return solver.simulate(t_end=t_end, dt=1e-3, output_dt=0.01, reactions=False)


def _largest(columns) -> float:
    return max(float(np.max(np.abs(c))) for c in columns.values())


def _worst(a, b) -> float:
    return max(float(np.max(np.abs(a[k] - b[k]))) for k in b)


@pytest.fixture(scope="module")
def panels(tmp_path_factory, build_dir):
    """An accordion array of 10 panels (50 reaction unknowns: the sparse way by size)."""
    folder = tmp_path_factory.mktemp("panels")
    path = folder / "panel_array_10.yaml"
    path.write_text(example_module("make_panel_array").model_text(10), encoding="utf-8")
    return fccgen.load(path, build_dir), path


def test_sparse_reactions_equal_the_dense_ones(compiled, panels):
    """On full-rank balances every record is certified and solved sparsely; on
    redundant ones (Bricard's linkage, the driven four-bar) every record goes to the
    SVD, so both ways give the dense rule's answer."""
    cases = [(panels[0], False)] + [(compiled(name), redundant) for name, redundant in
                                    (("solar_array", False), ("bricard", True),
                                     ("four_bar_driven", True))]
    for solver, redundant in cases:
        result = _run(solver)
        sparse, info = reactions(solver, result, sparse=True)
        dense, dense_info = reactions(solver, result, sparse=False)
        name = solver.plan.model.name
        assert _worst(sparse, dense) <= SPARSE_VS_DENSE * _largest(dense), name
        assert info["unique"] == dense_info["unique"] == (not redundant), name
        assert info["rank"] == dense_info["rank"], name
        assert info["dense_records"] == (info["records"] if redundant else 0), name


def test_the_default_takes_the_sparse_way_by_size(panels):
    solver, _ = panels
    result = _run(solver)
    _, info = reactions(solver, result)
    assert info["unknowns"] > DENSE_UNKNOWNS
    assert info["dense_records"] == 0 and info["unique"]


def test_sparse_reactions_equal_the_numeric_versions(panels):
    """The same records through the NumPy version's accelerations and the dense SVD."""
    solver, path = panels
    result = _run(solver)
    compiled_cols, _ = reactions(solver, result, sparse=True)
    numeric_cols, _ = reactions(fccgen.load_numeric(path), result, sparse=False)
    assert _worst(compiled_cols, numeric_cols) <= NUMERIC_VS_COMPILED * _largest(numeric_cols)


def test_chunks_of_one_record_change_nothing(compiled, monkeypatch):
    """Chunks carry the torsion springs' turn count across: the solar array's panel
    hinge swings past half a turn within the run."""
    solver = compiled("solar_array")
    result = _run(solver, t_end=3.0)
    whole, _ = reactions(solver, result)
    monkeypatch.setattr(reaction_module, "CHUNK_BYTES", 1)
    assert reaction_module.chunk_records(solver.plan, 3) == 1
    one_by_one, _ = reactions(solver, result)
    assert _worst(one_by_one, whole) == 0.0


def test_a_run_whose_reactions_fail_is_kept_with_a_warning(compiled, monkeypatch):
    solver = compiled("solar_array")

    def out_of_memory(*args, **kwargs):
        raise MemoryError
    monkeypatch.setattr(reaction_module, "solve_records", out_of_memory)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        kept = solver.simulate(t_end=0.05, dt=1e-3, reactions=False)
    with pytest.warns(RunWarning, match="joint reactions were not computed: out of "
                      "memory; the run is kept"):
        result = solver.simulate(t_end=0.05, dt=1e-3)
    assert result.info["reactions"] == {"computed": False, "reason": "out of memory"}
    assert "R.fx" not in result.columns
    np.testing.assert_array_equal(result.t, kept.t)
    for name, column in kept.columns.items():
        np.testing.assert_array_equal(result.columns[name], column)


def test_the_example_generator_writes_a_loadable_model(tmp_path):
    path = tmp_path / "three.yaml"
    assert example_module("make_panel_array").main(["make", "3", str(path)]) == 0
    plan = fccgen.api.plan_model(path)
    assert len(plan.model.mechanism.joints) == 3


def test_a_band_too_wide_takes_superlu_with_the_same_answer(panels, monkeypatch):
    """Structures whose E^T E is not banded in the Cuthill-McKee order factorise it by
    SuperLU in symmetric mode, certified by its inertia."""
    from fccgen.mechanism import reaction_solve
    solver, _ = panels
    result = _run(solver, t_end=0.05)
    banded, _ = reactions(solver, result)
    monkeypatch.setattr(reaction_solve, "BAND_FILL", 0)
    wide, info = reactions(solver, result)
    dense, _ = reactions(solver, result, sparse=False)
    assert info["dense_records"] == 0
    assert _worst(wide, dense) <= SPARSE_VS_DENSE * _largest(dense)
    assert _worst(banded, dense) <= SPARSE_VS_DENSE * _largest(dense)
