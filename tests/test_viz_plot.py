"""Plots of result columns (docs/design.md §5, ``fccgen plot``): a figure is written,
what it shows depends on the columns asked for, and bad requests are one clear line."""
from __future__ import annotations

import numpy as np
import pytest

from fccgen.cli import main
from fccgen.results.result import Result
from fccgen.viz.plot import quantity


@pytest.fixture()
def result_file(tmp_path):
    """A small made-up result of one moving point: no solver needed."""
    t = np.linspace(0.0, 2.0, 201)
    cols = {"P.x": np.cos(3 * t), "P.y": np.sin(3 * t), "P.z": 0 * t,
            "P.vx": -3 * np.sin(3 * t), "P.vy": 3 * np.cos(3 * t), "P.vz": 0 * t,
            "energy": 1 + 1e-9 * t, "constraint_error": 1e-15 + 0 * t}
    return Result(t, cols).save(tmp_path / "run.csv")


def run(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def pixels(path):
    import matplotlib.image
    return matplotlib.image.imread(str(path))


def test_plot_writes_a_png_that_depends_on_the_columns(result_file, tmp_path, capsys):
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    code, out, err = run(["plot", result_file, "--columns", "P.x,P.y", "--out", a], capsys)
    assert code == 0, err
    assert str(a) in out
    code, _, err = run(["plot", result_file, "--columns", "P.vx,energy", "--out", b],
                       capsys)
    assert code == 0, err
    pa, pb = pixels(a), pixels(b)
    assert pa.ndim == 3 and pa.shape[0] > 100 and pa.shape[1] > 100
    assert pa.std() > 0.05          # not a blank page: lines, text and a grid drawn
    # two panels (speed, energy) against one (position): not even the same size
    assert pa.shape != pb.shape or np.abs(pa - pb).max() > 0.1


def test_plot_defaults_to_the_result_name(result_file, capsys):
    code, out, err = run(["plot", result_file], capsys)
    assert code == 0, err
    png = result_file.with_suffix(".png")
    assert png.stat().st_size > 1000 and str(png) in out


@pytest.mark.parametrize("args, words", [
    (["--columns", "P.q"], ["no column 'P.q'", "columns are: P.x, P.y"]),
    (["--columns", "P.vv"], ["did you mean", "P.vx"]),
    (["--out", "fig.txt"], ["fig.txt", ".png, .svg, .pdf", "'.txt'"]),
])
def test_plot_errors_are_one_clear_line(result_file, tmp_path, capsys, args, words):
    args = [a if a != "fig.txt" else tmp_path / a for a in args]
    code, out, err = run(["plot", result_file, *args], capsys)
    assert code == 1 and out == ""
    assert err.startswith("fccgen: error: ") and err.count("\n") == 1
    for w in words:
        assert w in err
    assert not list(tmp_path.glob("*.png"))


def test_plot_of_a_missing_file(tmp_path, capsys):
    code, _, err = run(["plot", tmp_path / "none.csv"], capsys)
    assert code == 1 and err.startswith("fccgen: error: ") and "none.csv" in err


def test_result_plot_on_given_axes(result_file):
    from matplotlib.figure import Figure
    ax = Figure().subplots()
    fig = Result.load(result_file).plot(["P.x", "P.vx"], ax=ax)
    assert fig is ax.figure
    assert [line.get_label() for line in ax.get_lines()] == ["P.x", "P.vx"]
    assert ax.get_ylabel() == "value"       # two quantities on one axes


def test_result_plot_panels_per_quantity(result_file):
    import matplotlib.pyplot as plt
    fig = Result.load(result_file).plot("P.x,P.y,P.vx")
    try:
        labels = [a.get_ylabel() for a in fig.axes]
        assert labels == ["position", "speed"]
    finally:
        plt.close(fig)


def test_quantity_labels_name_no_unit_of_length():
    assert quantity("P.x") == "position" and quantity("P.vz") == "speed"
    assert quantity("arm.wz").startswith("angular velocity")
    assert quantity("mystery") == "value"
    assert not any(" m" in quantity(c) for c in ("P.x", "P.vx", "arm.cx", "energy"))


def test_plot_without_matplotlib_says_how_to_install_it(result_file, tmp_path, capsys,
                                                        monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "matplotlib", None)      # import fails
    code, out, err = run(["plot", result_file, "--out", tmp_path / "a.png"], capsys)
    assert code == 1 and err.startswith("fccgen: error: plotting needs matplotlib")
    assert "fccgen[plot]" in err and not list(tmp_path.glob("*.png"))
