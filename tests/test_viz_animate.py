"""The 3-D animation page (docs/design.md §5, ``fccgen animate``): one self-contained
file (plotly.js inlined, nothing fetched), one frame per recorded row up to a limit,
and, where a Chromium is installed, a page that draws different pictures at two
positions of its time slider."""
from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.model import load_model
from fccgen.viz.animate import animation_figure, frame_rows

DOUBLE = EXAMPLES / "double_pendulum.yaml"


def run(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def short_result(tmp_path_factory, build_dir):
    """0.5 s of the double pendulum, 51 rows, saved as CSV."""
    import fccgen
    solver = fccgen.load(DOUBLE, build_dir)
    result = solver.simulate(t_end=0.5, output_dt=0.01)
    return result.save(tmp_path_factory.mktemp("animate") / "short.csv")


@pytest.fixture(scope="module")
def page(tmp_path_factory, build_dir, short_result):
    out = tmp_path_factory.mktemp("page") / "motion.html"
    code = main(["animate", str(DOUBLE), "--result", str(short_result), "--out", str(out),
                 "--build-dir", str(build_dir), "-q"])
    assert code == 0
    return out


def test_page_is_self_contained(page):
    html = page.read_text(encoding="utf-8")
    assert not re.search(r"<script[^>]*\bsrc\s*=", html)         # nothing fetched
    assert "plotly.js v" in html                                  # the library inlined
    assert len(html) > 1_000_000                                  # plotly.js is ~4.5 MB
    assert "frame=" in html                                       # #frame=K jumps


def _trace(frame_or_fig, name):
    return next(t for t in frame_or_fig.data if t.name == name)


def test_one_frame_per_row_when_few(short_result):
    from fccgen.results.result import Result
    result = Result.load(short_result)
    fig = animation_figure(load_model(DOUBLE), result)
    assert len(result.t) == 51 and len(fig.frames) == 51
    # the last frame is the last row: P2 where the result ends
    last = _trace(fig.frames[-1], "points")                 # moving points P1, P2
    assert list(last.text) == ["P1", "P2"]
    assert last.x[1] == pytest.approx(result["P2.x"][-1], abs=0)
    segments = _trace(fig.frames[0], "body segments")       # O-P1, P1-P2 with a gap
    assert list(segments.x[:2]) == [0.0, pytest.approx(0.8, abs=1e-12)]
    assert segments.x[2] is None
    centres = _trace(fig.frames[-1], "bodies (mass centres)")
    assert list(centres.text) == ["rod1", "rod2"]
    assert centres.x[1] == pytest.approx(result["rod2.cx"][-1], abs=1e-12)
    ground = _trace(fig, "ground")
    assert list(ground.text) == ["O"]


def test_rows_are_decimated_evenly():
    rows = frame_rows(501, 300)
    assert len(rows) == 300 and rows[0] == 0 and rows[-1] == 500
    assert np.all(np.diff(rows) >= 1) and np.diff(rows).max() <= 2
    assert list(frame_rows(10, 300)) == list(range(10))
    with pytest.raises(ValueError, match="at least 2 frames"):
        frame_rows(10, 1)


def test_without_result_runs_the_model(tmp_path, build_dir, capsys):
    out = tmp_path / "run.html"
    code, text, err = run(["animate", DOUBLE, "--out", out, "--frames", "40",
                           "--build-dir", build_dir, "-q"], capsys)
    assert code == 0, err
    # the model's own settings: 5 s recorded every 0.01 s, 501 rows, shown in 40 frames
    assert "40 frames of 501 rows" in text
    assert out.stat().st_size > 1_000_000


@pytest.mark.parametrize("args, words", [
    (["--out", "motion.png"], ["motion.png", ".html"]),
    (["--out", "m.html", "--result", "other.csv"],
     ["no column P1.x", "not a result of the model double_pendulum"]),
])
def test_animate_errors_are_one_clear_line(tmp_path, build_dir, capsys, args, words):
    from fccgen.results.result import Result
    t = np.linspace(0, 1, 5)            # a result of another model: a point Q only
    Result(t, {"Q.x": t, "Q.y": t, "Q.z": t}).save(tmp_path / "other.csv")
    args = [tmp_path / a if "." in a else a for a in args]
    code, out, err = run(["animate", DOUBLE, "--build-dir", build_dir, "-q", *args],
                         capsys)
    assert code == 1 and out == ""
    assert err.startswith("fccgen: error: ") and err.count("\n") == 1
    for w in words:
        assert w in err
    assert not list(tmp_path.glob("*.html")) and not list(tmp_path.glob("*.png"))


def _chromium():
    return shutil.which("chromium") or shutil.which("chromium-browser")


def _screenshot(browser, page, frame, png):
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu",
                    "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
                    "--hide-scrollbars", "--window-size=800,600",
                    "--virtual-time-budget=8000", f"--screenshot={png}",
                    f"{page.as_uri()}#frame={frame}"],
                   check=True, capture_output=True, timeout=120)
    import matplotlib.image
    return matplotlib.image.imread(str(png))[..., :3]


@pytest.mark.skipif(_chromium() is None, reason="no Chromium installed (apt-get install "
                    "chromium) to draw the page")
def test_page_draws_the_motion_in_a_browser(page, tmp_path):
    first = _screenshot(_chromium(), page, 0, tmp_path / "first.png")
    last = _screenshot(_chromium(), page, 50, tmp_path / "last.png")
    assert first.shape == last.shape == (600, 800, 3)
    # drawn, not blank: a white page has std 0; axes, bodies and the slider give more
    assert first.std() > 0.05 and last.std() > 0.05
    # the pendulum moved: a visible share of the pixels changed (slider, bodies, label)
    changed = np.abs(first - last).max(axis=2) > 0.1
    assert changed.mean() > 0.001
