"""A self-contained web page that plays a model's motion in 3-D (DESIGN section 5,
``fccgen animate``), drawn with plotly and with plotly.js inlined, so the page works
offline and can be mailed as one file.

What it shows, per recorded frame:
- each body as the segment from its point i to its point j (fixed points included),
- the mass centres of the moving bodies (result columns ``B.cx B.cy B.cz``),
- the moving points, named, and the fixed points (static).

Frames are the result's rows, decimated evenly to at most ``max_frames`` (first and
last rows always kept). The axes keep one range for the whole motion, with equal
scales. The page has a play/pause button and a time slider; ``page.html#frame=K``
opens it at frame K (a link to a moment, also what the browser test uses).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

DEFAULT_MAX_FRAMES = 300
JUMP_SCRIPT = """
var gd = document.getElementById('{plot_id}');
var m = /frame=(\\d+)/.exec(window.location.hash);
if (m && gd) {
  var names = gd._transitionData._frames.map(function (f) { return f.name; });
  var k = Math.min(parseInt(m[1], 10), names.length - 1);
  Plotly.animate(gd, [names[k]], {mode: 'immediate', frame: {duration: 0, redraw: true},
                                  transition: {duration: 0}});
}
"""


def frame_rows(n_rows: int, max_frames: int = DEFAULT_MAX_FRAMES) -> np.ndarray:
    """Row indices of the frames: every row when there are at most ``max_frames``,
    else ``max_frames`` rows evenly spread, the first and last included."""
    if max_frames < 2:
        raise ValueError(f"an animation needs at least 2 frames (got {max_frames})")
    if n_rows <= max_frames:
        return np.arange(n_rows)
    return np.unique(np.round(np.linspace(0, n_rows - 1, max_frames)).astype(int))


def point_tracks(model, result) -> dict[str, np.ndarray]:
    """(n_rows, 3) positions of every point of the model: moving ones from the result,
    fixed ones repeated. A moving point missing from the result is a ValueError."""
    n = len(result.t)
    tracks = {}
    for p in model.points.values():
        if p.fixed:
            tracks[p.name] = np.tile(np.asarray(p.at, float), (n, 1))
            continue
        names = [f"{p.name}.{c}" for c in "xyz"]
        missing = [c for c in names if c not in result.columns]
        if missing:
            raise ValueError(f"the result has no column {missing[0]}: it is not a result "
                             f"of the model {model.name} ({model.source})")
        tracks[p.name] = np.column_stack([result.columns[c] for c in names])
    return tracks


def _segments(bodies, tracks, k) -> tuple[list, list, list]:
    """x, y, z lists of the bodies' i-j segments at row k, None between bodies."""
    xyz = ([], [], [])
    for b in bodies:
        for name in (b.i, b.j):
            for c in range(3):
                xyz[c].append(float(tracks[name][k, c]))
        for c in range(3):
            xyz[c].append(None)
    return xyz


def _moving_traces(model, result, tracks, k, go):
    """The traces that move: bodies, mass centres, moving points (in that order)."""
    bodies = list(model.bodies.values())
    x, y, z = _segments(bodies, tracks, k)
    names = [b.name for b in bodies for _ in range(3)]
    traces = [go.Scatter3d(x=x, y=y, z=z, mode="lines", name="bodies", text=names,
                           hoverinfo="text", line=dict(width=6, color="#1f77b4"))]
    centres = [b.name for b in bodies if f"{b.name}.cx" in result.columns]
    traces.append(go.Scatter3d(
        x=[float(result.columns[f"{b}.cx"][k]) for b in centres],
        y=[float(result.columns[f"{b}.cy"][k]) for b in centres],
        z=[float(result.columns[f"{b}.cz"][k]) for b in centres],
        mode="markers", name="mass centres", text=centres, hoverinfo="text",
        marker=dict(size=4, symbol="diamond", color="#ff7f0e")))
    moving = [p.name for p in model.moving_points]
    traces.append(go.Scatter3d(
        x=[float(tracks[p][k, 0]) for p in moving], y=[float(tracks[p][k, 1]) for p in moving],
        z=[float(tracks[p][k, 2]) for p in moving], mode="markers+text", text=moving,
        name="moving points", textposition="top center",
        marker=dict(size=4, color="#d62728")))
    return traces


def _scene(tracks, result) -> dict:
    """Axis ranges covering the whole motion (points and mass centres), equal scales
    on the three axes; a planar motion (one coordinate constant to 1e-6 of the
    largest extent) is seen along its normal, without perspective."""
    centres = [np.column_stack([result.columns[f"{n[:-3]}.c{c}"] for c in "xyz"])
               for n in result.columns if n.endswith(".cx")]
    every = np.concatenate([*tracks.values(), *centres])
    lo, hi = every.min(axis=0), every.max(axis=0)
    pad = 0.05 * max(float((hi - lo).max()), 1e-9)
    lo, hi = lo - pad, hi + pad
    span = hi - lo
    ratio = span / span.max()
    axes = {f"{c}axis": dict(range=[float(lo[k]), float(hi[k])], title=c, autorange=False)
            for k, c in enumerate("xyz")}
    scene = dict(**axes, aspectmode="manual",
                 aspectratio=dict(x=float(ratio[0]), y=float(ratio[1]), z=float(ratio[2])))
    flat = int(np.argmin(span))
    if span[flat] - 2 * pad <= 1e-6 * span.max():
        eye, up = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        eye[flat] = 1.0
        up[(flat + 2) % 3] = 1.0
        scene["camera"] = dict(eye=dict(zip("xyz", eye)), up=dict(zip("xyz", up)),
                               projection=dict(type="orthographic"))
        scene["aspectratio"] = {c: 2.0 * v for c, v in scene["aspectratio"].items()}
    return scene


def animation_figure(model, result, max_frames: int = DEFAULT_MAX_FRAMES):
    """The plotly Figure of the motion: traces at the first frame, one plotly frame
    per row of :func:`frame_rows`, a play button and a time slider."""
    import plotly.graph_objects as go
    tracks = point_tracks(model, result)
    rows = frame_rows(len(result.t), max_frames)
    fixed = [p.name for p in model.points.values() if p.fixed]
    static = go.Scatter3d(
        x=[float(tracks[p][0, 0]) for p in fixed], y=[float(tracks[p][0, 1]) for p in fixed],
        z=[float(tracks[p][0, 2]) for p in fixed], mode="markers+text", text=fixed,
        name="fixed points", textposition="bottom center",
        marker=dict(size=5, symbol="square", color="#555555"))
    frames = [go.Frame(name=str(n), data=_moving_traces(model, result, tracks, k, go),
                       traces=[0, 1, 2]) for n, k in enumerate(rows)]
    t = result.t[rows]
    step_ms = 1000.0 * float(np.median(np.diff(t))) if len(t) > 1 else 50.0
    duration = int(min(max(step_ms, 20.0), 200.0))          # real time, within limits
    play = dict(frame=dict(duration=duration, redraw=True), fromcurrent=True,
                transition=dict(duration=0), mode="immediate")
    still = dict(frame=dict(duration=0, redraw=True), transition=dict(duration=0),
                 mode="immediate")
    slider = dict(active=0, currentvalue=dict(prefix="t = "), pad=dict(t=40),
                  steps=[dict(method="animate", label=f"{t[n]:.4g}", args=[[str(n)], still])
                         for n in range(len(rows))])
    buttons = [dict(label="play", method="animate", args=[None, play]),
               dict(label="pause", method="animate", args=[[None], still])]
    fig = go.Figure(data=[*frames[0].data, static], frames=frames)
    fig.update_layout(
        title=_title(model, result, len(rows)),
        scene=_scene(tracks, result), sliders=[slider], margin=dict(l=0, r=0, t=50, b=0),
        updatemenus=[dict(type="buttons", buttons=buttons, x=0.02, y=0.02,
                          xanchor="left", yanchor="bottom", direction="left")],
        legend=dict(x=0.01, y=0.98))
    return fig


def _title(model, result, n_frames: int) -> str:
    """The page's title: the model and frames, or which mode shape it plays."""
    info = result.info
    if info.get("kind") == "mode shape":
        what = ("a rigid-body mode" if info.get("rigid") else
                f"{info.get('frequency_hz', float('nan')):.6g} Hz, one period")
        return (f"{model.name}: mode {info.get('mode')} ({what}), amplitude "
                f"{info.get('amplitude', float('nan')):.3g}")
    return f"{model.name}: {n_frames} frames of {len(result.t)} recorded rows"


def mode_file(result, mode: int) -> Path:
    """The file of mode ``mode`` among the shapes that ``fccgen modes --shapes
    RESULT`` wrote (RESULT.mode<k><suffix>); ValueError naming the ones there are."""
    from ..analysis.mode_shapes import mode_shape_path
    if result is None or not isinstance(result, (str, Path)):
        raise ValueError("--mode needs --result NAME, the name given to fccgen modes "
                         "--shapes (e.g. --result modes.npz --mode 1)")
    if int(mode) < 1:
        raise ValueError(f"--mode counts from 1 (got {mode})")
    path = mode_shape_path(result, mode)
    if path.exists():
        return path
    base = Path(result)
    found = sorted(base.parent.glob(f"{base.stem}.mode*{base.suffix}"),
                   key=lambda p: (len(p.name), p.name))
    if not found:
        raise ValueError(f"no mode shapes named {base.stem}.mode<k>{base.suffix} in "
                         f"{base.parent}: write them first with fccgen modes MODEL "
                         f"--shapes {base}")
    raise ValueError(f"{path} does not exist; the shapes written as {base} are "
                     + ", ".join(p.name for p in found))


def write_animation(model, result, out, max_frames: int = DEFAULT_MAX_FRAMES):
    """Write the page to ``out`` (.html), plotly.js inlined; returns (path, frames)."""
    out = check_page_path(out)
    fig = animation_figure(model, result, max_frames)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.write_html(out, include_plotlyjs=True, full_html=True, auto_play=False,
                   post_script=JUMP_SCRIPT, config={"displaylogo": False})
    return out, len(fig.frames)


def check_page_path(path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ValueError(f"{path}: the animation is written as a .html page (got "
                         f"{path.suffix or 'no suffix'!r})")
    return path
