"""A self-contained web page that plays a model's motion in 3-D (docs/design.md §5,
``fccgen animate``), drawn with plotly and with plotly.js inlined, so the page works
offline and can be mailed as one file.

It draws the model as the solvers see it -- joints and pose-form bodies lowered
(:mod:`fccgen.mechanism`) -- so a model written with joints is drawn like one
written with points. Per recorded frame (:mod:`fccgen.viz.scene`):
- each body as its solid: its ``shape:``, else its inertia box (the uniform box of
  its mass and principal moments); and its segments (i to j, the mass centre to
  each joint point it carries), its name at its mass centre;
- each joint at its point, named; the points a user named in a model given by
  points; the ground's points (static).

Frames are the result's rows, decimated evenly to at most ``max_frames`` (first and
last rows always kept). The axes keep one range for the whole motion, with equal
scales. The page has a play/pause button and a time slider; ``page.html#frame=K``
opens it at frame K (a link to a moment, also what the browser test uses).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import scene
from .cables import cable_trace

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


def lowered(model):
    """The model as the solvers see it: joints and pose-form bodies lowered
    (:func:`fccgen.mechanism.lower`; a model given by points is itself)."""
    from ..mechanism import lower
    return lower(model) if (model.pose_bodies or model.joints or model.drivers) else model


def named_points(model) -> list[str]:
    """The points of the lowered ``model`` a user named: all of a model given by
    points; none of those the lowering made for joints and body frames."""
    mech = getattr(model, "mechanism", None)
    if mech is None:
        return list(model.points)
    made = {t.name for jl in mech.joints for t in jl.triples}
    made |= {n for i, j, _ in mech.frames.values() for n in (i, j)}
    made |= set(mech.internal())          # e.g. the end points of lowered springs
    return [p for p in model.points if p not in made]


def _xyz(points: list[np.ndarray]) -> tuple[list, list, list]:
    """x, y, z lists of (3,) points."""
    return tuple([float(p[c]) for p in points] for c in range(3))


def _lines(segments: list[np.ndarray], k: int) -> tuple[list, list, list]:
    """x, y, z lists of segments (each (n, 2, 3)) at row k, None between them."""
    xyz = ([], [], [])
    for seg in segments:
        for c in range(3):
            xyz[c].extend([float(seg[k, 0, c]), float(seg[k, 1, c]), None])
    return xyz


class _Scene:
    """The drawn things of a model and its result (:mod:`fccgen.viz.scene`)."""

    def __init__(self, model, result):
        self.model = model
        self.result = result
        self.tracks = scene.triple_tracks(model, result)
        self.frames = scene.body_frames(model, self.tracks)
        self.solids = scene.body_solids(model, self.frames)
        self.skeletons = scene.skeletons(model, self.frames, self.tracks)
        self.joints = scene.joint_points(model)
        named = named_points(model)
        self.moving = [p for p in named if not model.points[p].fixed]
        self.ground = [p.name for p in model.points.values() if p.fixed]
        self.ground_labels = [p if p in named else "" for p in self.ground]
        self.centres = {b: ri + np.einsum("nij,j->ni", R, np.asarray(
            model.bodies[b].center, float)) for b, (ri, R) in self.frames.items()}

    def points(self) -> np.ndarray:
        """The positions of the points and mass centres over the whole motion, (m, 3)."""
        return np.concatenate([*(self.tracks[p] for p in self.model.points),
                               *self.centres.values()])

    def extent(self) -> np.ndarray:
        """Every drawn position over the whole motion, (m, 3)."""
        return np.concatenate([self.points(),
                               *(s.vertices.reshape(-1, 3) for s in self.solids)])

    def meshes(self, go, k: int, full: bool) -> list:
        """One Mesh3d per kind of solid (shapes, inertia boxes) at row k."""
        traces = []
        for kind, colour, opacity in (("shape", "#4c78a8", 0.85),
                                      ("inertia box", "#9ecae9", 0.5)):
            solids = [s for s in self.solids if s.kind == kind]
            if not solids:
                continue
            v = np.concatenate([s.vertices[k] for s in solids])
            args = dict(x=v[:, 0], y=v[:, 1], z=v[:, 2])
            if full:
                offsets = np.cumsum([0] + [len(s.vertices[k]) for s in solids])
                f = np.concatenate([s.faces + o for s, o in zip(solids, offsets)])
                text = [s.body for s in solids for _ in range(s.vertices.shape[1])]
                args.update(i=f[:, 0], j=f[:, 1], k=f[:, 2], color=colour,
                            opacity=opacity, flatshading=True, hovertext=text,
                            hoverinfo="text", showlegend=True,
                            name="bodies (shapes)" if kind == "shape" else
                            "bodies (inertia boxes)")
            traces.append(go.Mesh3d(**args))
        return traces

    def moving_traces(self, go, k: int, full: bool = False) -> list:
        """The traces that move, at row k: solids, flexible members (curves),
        skeletons, body names at the mass centres, joints, named moving points."""
        segments = [s for b in self.skeletons.values() for s in b]
        x, y, z = _lines(segments, k)
        hover = [b for b, segs in self.skeletons.items() for _ in segs for _ in range(3)]
        bodies = list(self.centres)
        cx, cy, cz = _xyz([self.centres[b][k] for b in bodies])
        jx, jy, jz = _xyz([self.tracks[p][k] for _, p in self.joints])
        px, py, pz = _xyz([self.tracks[p][k] for p in self.moving])
        members = cable_trace(self.model, self.result, k, go)
        return [*self.meshes(go, k, full),
                *([members] if members is not None else []),
                go.Scatter3d(x=x, y=y, z=z, mode="lines", name="body segments",
                             text=hover, hoverinfo="text",
                             line=dict(width=5, color="#1f4e79")),
                go.Scatter3d(x=cx, y=cy, z=cz, mode="markers+text", text=bodies,
                             name="bodies (mass centres)", textposition="middle right",
                             hoverinfo="text",
                             marker=dict(size=3, symbol="diamond", color="#ff7f0e")),
                go.Scatter3d(x=jx, y=jy, z=jz, mode="markers+text",
                             text=[j for j, _ in self.joints], name="joints",
                             textposition="top center", hoverinfo="text",
                             marker=dict(size=5, symbol="circle-open", color="#2ca02c")),
                go.Scatter3d(x=px, y=py, z=pz, mode="markers+text", text=self.moving,
                             name="points", textposition="top center", hoverinfo="text",
                             marker=dict(size=4, color="#d62728"))]

    def ground_trace(self, go):
        gx, gy, gz = _xyz([self.tracks[p][0] for p in self.ground])
        return go.Scatter3d(x=gx, y=gy, z=gz, mode="markers+text", text=self.ground_labels,
                            hovertext=["ground" + (f" ({n})" if n else "")
                                       for n in self.ground_labels], hoverinfo="text",
                            name="ground", textposition="bottom center",
                            marker=dict(size=7, symbol="square", color="#555555"))


def _scene_layout(every: np.ndarray, points: np.ndarray) -> dict:
    """Axis ranges covering the whole motion (``every`` drawn position), equal scales
    on the three axes; a planar motion (one coordinate of the ``points`` constant to
    1e-6 of the largest extent) is seen along its normal, without perspective."""
    lo, hi = every.min(axis=0), every.max(axis=0)
    pad = 0.05 * max(float((hi - lo).max()), 1e-9)
    lo, hi = lo - pad, hi + pad
    span = hi - lo
    ratio = span / span.max()
    axes = {f"{c}axis": dict(range=[float(lo[k]), float(hi[k])], title=c, autorange=False)
            for k, c in enumerate("xyz")}
    layout = dict(**axes, aspectmode="manual",
                  aspectratio=dict(x=float(ratio[0]), y=float(ratio[1]), z=float(ratio[2])))
    flat_span = points.max(axis=0) - points.min(axis=0)
    flat = int(np.argmin(flat_span))
    if flat_span[flat] <= 1e-6 * (span.max() - 2 * pad):
        eye, up = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        eye[flat] = 1.0
        up[(flat + 2) % 3] = 1.0
        layout["camera"] = dict(eye=dict(zip("xyz", eye)), up=dict(zip("xyz", up)),
                                projection=dict(type="orthographic"))
        layout["aspectratio"] = {c: 2.0 * v for c, v in layout["aspectratio"].items()}
    return layout


def animation_figure(model, result, max_frames: int = DEFAULT_MAX_FRAMES):
    """The plotly Figure of the motion of ``model`` (as loaded, or lowered) in
    ``result``: traces at the first frame, one plotly frame per row of
    :func:`frame_rows`, a play button and a time slider."""
    import plotly.graph_objects as go
    drawn = _Scene(lowered(model), result)
    rows = frame_rows(len(result.t), max_frames)
    first = drawn.moving_traces(go, rows[0], full=True)
    moving = list(range(len(first)))
    frames = [go.Frame(name=str(n), data=drawn.moving_traces(go, k), traces=moving)
              for n, k in enumerate(rows)]
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
    fig = go.Figure(data=[*first, drawn.ground_trace(go)], frames=frames)
    fig.update_layout(
        title=_title(drawn.model, result, len(rows)),
        scene=_scene_layout(drawn.extent(), drawn.points()), sliders=[slider],
        margin=dict(l=0, r=0, t=50, b=0),
        updatemenus=[dict(type="buttons", buttons=buttons, x=0.02, y=0.02,
                          xanchor="left", yanchor="bottom", direction="left")],
        legend=dict(x=0.01, y=0.98))
    return fig


def _title(model, result, n_frames: int) -> str:
    """The page's title: the model, its bodies and frames, or which mode shape it
    plays."""
    info = result.info
    if info.get("kind") == "mode shape":
        what = ("a rigid-body mode" if info.get("rigid") else
                f"{info.get('frequency_hz', float('nan')):.6g} Hz, one period")
        return (f"{model.name}: mode {info.get('mode')} ({what}), amplitude "
                f"{info.get('amplitude', float('nan')):.3g}")
    return (f"{model.name}: {len(model.bodies)} bodies, {n_frames} frames of "
            f"{len(result.t)} recorded rows")


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
