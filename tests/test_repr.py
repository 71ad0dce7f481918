"""The summaries ``repr`` gives of solvers and results (fccgen.results.summary)."""
import numpy as np

import fccgen
from fccgen.results.result import Result
from conftest import EXAMPLES

FOUR_BAR = EXAMPLES / "four_bar.yaml"


def test_compiled_solver_repr_names_model_sizes_path_and_build(build_dir):
    solver = fccgen.load(FOUR_BAR, build_dir)            # fresh: rank not decided yet
    text = repr(solver)
    assert text.startswith("<CompiledSolver four_bar: ")
    assert f"{solver.n_q} coordinates, {solver.n_g} constraint equations" in text
    assert "DOF undecided" in text
    assert "method rk4" in text                          # the model's default method
    assert "linear solver " in text and "-> dense" in text
    assert f"build {build_dir}" in text
    solver.decide_rank(solver.initial_state().q)
    assert "DOF 1 (decided)" in repr(solver)             # a four-bar has one DOF


def test_numeric_solver_repr_has_the_same_content():
    solver = fccgen.load_numeric(FOUR_BAR)
    text = repr(solver)
    assert text.startswith("<NumericSolver four_bar: ")
    assert "6 coordinates, 6 constraint equations, DOF undecided" in text
    assert "dense (NumPy)" in text and "build" not in text
    solver.decide_rank(solver.initial_state().q)
    assert "DOF 1 (decided)" in repr(solver)


def _result(n_columns=6, partial=False, events=()):
    columns = {f"c{k}": np.zeros(3) for k in range(n_columns)}
    info = {"method": "dopri5", "partial": partial}
    return Result(np.array([0.0, 0.5, 1.25]), columns, info, list(events))


def test_result_repr_abbreviates_columns_and_flags_partial():
    text = repr(_result())
    assert text == ("<Result: 3 rows, t 0 .. 1.25, 6 columns (c0, c1, c2, c3, ...), "
                    "method dopri5, 0 events>")
    assert repr(_result(2)).count("c1") == 1 and "..." not in repr(_result(2))
    partial = repr(_result(partial=True, events=[{"name": "latch"}]))
    assert partial.endswith("1 events, partial>")


def test_result_html_is_an_escaped_table():
    result = _result()
    result.columns["a<b"] = np.zeros(3)
    page = result._repr_html_()
    assert page.startswith("<table>") and page.endswith("</table>")
    assert "<th style='text-align:left'>rows</th><td style='text-align:left'>3</td>" in page
    assert "a<b" not in page                              # the 7th column is abbreviated
    assert "method" in page and "dopri5" in page and "partial" not in page
    few = Result(np.zeros(2), {"a<b": np.zeros(2)}, {"method": "rk4"})._repr_html_()
    assert "a&lt;b" in few and "a<b" not in few
