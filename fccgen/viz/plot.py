"""Time histories of named result columns (docs/design.md §4), drawn with matplotlib.

Columns are grouped by the quantity their name's suffix says (``P.x`` a position,
``P.vx`` a speed, ``arm.wz`` an angular velocity, ...), one panel per quantity with a
shared time axis, so that numbers of different kinds never share a y axis. Units are
the model file's, which fccgen does not know: the labels name the quantity only.
matplotlib is imported lazily, with the Agg backend when a file is written.
"""
from __future__ import annotations

import difflib
from pathlib import Path

FIGURE_SUFFIXES = (".png", ".svg", ".pdf")

# Column-name suffix -> the quantity it holds (label of its panel).
QUANTITIES = (
    (("x", "y", "z"), "position"),            # a point's (a unit vector's: component)
    (("vx", "vy", "vz"), "speed"),
    (("cx", "cy", "cz"), "mass-centre position"),
    (("wx", "wy", "wz"), "angular velocity (rad per time unit)"),
    (("angle",), "joint angle (rad)"),
    (("rate",), "joint rate (rad per time unit)"),
    (("position",), "joint position"),
    (("speed",), "joint speed"),
    (("fx", "fy", "fz", "force"), "reaction force"),
    (("tx", "ty", "tz", "torque"), "reaction torque"),
)
WHOLE_NAMES = {"energy": "energy", "constraint_error": "constraint error, max |g|"}


def quantity(column: str) -> str:
    """The panel label of a column, from its name (``'value'`` when unknown)."""
    if column in WHOLE_NAMES:
        return WHOLE_NAMES[column]
    suffix = column.rpartition(".")[2]
    for suffixes, label in QUANTITIES:
        if suffix in suffixes:
            return label
    return "value"


def check_figure_path(path) -> Path:
    """A figure file name with a suffix matplotlib writes (ValueError otherwise)."""
    path = Path(path)
    if path.suffix.lower() not in FIGURE_SUFFIXES:
        raise ValueError(f"{path}: figures are written as {', '.join(FIGURE_SUFFIXES)} "
                         f"(got {path.suffix or 'no suffix'!r})")
    return path


def check_columns(result, columns) -> list[str]:
    """The columns asked for, each checked against the result's names; an unknown one
    is a ValueError naming the closest names and all available ones."""
    if isinstance(columns, str):
        columns = [c.strip() for c in columns.split(",") if c.strip()]
    columns = list(columns)
    if not columns:
        raise ValueError("no columns to plot; the result has: "
                         + ", ".join(result.names[1:]))
    available = result.names[1:]
    for name in columns:
        if name not in available:
            close = difflib.get_close_matches(name, available, n=3)
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise ValueError(f"no column {name!r} in the result{hint}; columns are: "
                             + ", ".join(available))
    return columns


def default_columns(result) -> list[str]:
    """Without a choice: the positions of the first moving point, else energy."""
    for name in result.names[1:]:
        if name.endswith(".x"):
            stem = name[:-2]
            return [f"{stem}.{c}" for c in "xyz" if f"{stem}.{c}" in result.columns]
    return ["energy"]


def require_matplotlib() -> None:
    """HostError saying how to install matplotlib when it is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        from ..errors import HostError
        raise HostError("plotting needs matplotlib: pip install 'fccgen[plot]' (or "
                        "pip install matplotlib)") from None


def plot_columns(result, columns=None, ax=None, title: str | None = None, figure=None):
    """Draw the columns against ``t``; returns the matplotlib Figure.

    ax None: one panel per quantity (position, speed, ...) with a legend in each, in
    ``figure`` (a new pyplot-free Figure when None). ax given: every column on that
    axes (labelled with the quantity when they all share one).
    """
    columns = default_columns(result) if columns is None else check_columns(result,
                                                                             columns)
    groups: dict[str, list[str]] = {}
    for name in columns:
        groups.setdefault(quantity(name), []).append(name)
    if ax is not None:
        _panel(ax, result, columns, next(iter(groups)) if len(groups) == 1 else "value")
        return ax.figure
    if figure is None:
        from matplotlib.figure import Figure      # no pyplot: no global state, no GUI
        figure = Figure()
    fig = figure
    fig.set_size_inches(7.0, 1.2 + 2.2 * len(groups))
    fig.set_layout_engine("constrained")
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
    for a, (label, names) in zip(axes, groups.items()):
        _panel(a, result, names, label)
    axes[-1].set_xlabel("time t")
    if title:
        fig.suptitle(title)
    return fig


def _panel(ax, result, names, label) -> None:
    for name in names:
        ax.plot(result.t, result[name], label=name, linewidth=1.2)
    ax.set_ylabel(label)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small", ncol=1 + len(names) // 6)


def save_plot(result, columns, out, title: str | None = None) -> Path:
    """Plot the columns and write the figure to ``out`` (.png, .svg or .pdf)."""
    out = check_figure_path(out)
    require_matplotlib()
    fig = plot_columns(result, columns, title=title)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return out
