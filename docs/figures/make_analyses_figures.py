"""Draw the figures of docs/analyses.md from the example models (Python API of fccgen).

    python docs/figures/make_analyses_figures.py

from the repository root (with fccgen importable); writes docs/figures/analyses_*.png
and builds the models under ./generated.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import fccgen  # noqa: E402
from fccgen.analysis import linearize, modes, statics  # noqa: E402
from fccgen.analysis.mode_shapes import mode_shapes  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
OUT = Path(__file__).resolve().parent


def point_xy(names, q, point):
    """(x, y) of a moving point in the coordinates q (names: P.x, P.y, ...)."""
    return q[names.index(f"{point}.x")], q[names.index(f"{point}.y")]


def statics_figure():
    """deployable.yaml: the bars at the initial configuration and at equilibrium."""
    solver = fccgen.load(EXAMPLES / "deployable.yaml")
    eq = statics(solver)
    fixed = {"A": (0, 0), "C": (165, 10), "D": (40, -350)}       # from the model file
    bars = [("D", "F"), ("C", "G"), ("F", "G"), ("A", "T")]
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for q, style, label in ((solver.plan.q0, "--", "initial"), (eq.q, "-", "equilibrium")):
        def xy(p):
            return fixed[p] if p in fixed else point_xy(eq.names, q, p)
        for k, (a, b) in enumerate(bars):
            (xa, ya), (xb, yb) = xy(a), xy(b)
            ax.plot([xa, xb], [ya, yb], style, color=f"C{k}",
                    label=label if k == 0 else None)
    ax.plot(*zip(*fixed.values()), "ks", label="fixed points")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"deployable.yaml at rest under its loads ({eq.stability})")
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.savefig(OUT / "analyses_statics_deployable.png", dpi=110)


def modes_figure(stem, axes_names, title, filename, half_width=0.5, square=False):
    """The mode shapes of a model as snapshots of its bars over one period."""
    solver = fccgen.load(EXAMPLES / f"{stem}.yaml")
    eq = statics(solver)
    m = modes(linearize(solver, eq.q))
    shapes = mode_shapes(solver, linearize(solver, eq.q), m, frames=9)
    moving = [k for k in range(len(m.frequency_hz)) if not m.rigid[k]]
    fig, axes = plt.subplots(1, len(moving), figsize=(2.6 * len(moving), 3.4),
                             sharey=True)
    hx, hy = axes_names
    for ax, k in zip(np.atleast_1d(axes), moving):
        r = shapes[k]
        for j, t in enumerate(r["t"]):
            xs = [0.0, r[f"P1.{hx}"][j], r[f"P2.{hx}"][j]]
            ys = [0.0, r[f"P1.{hy}"][j], r[f"P2.{hy}"][j]]
            ax.plot(xs, ys, "o-", color=plt.cm.viridis(j / (len(r["t"]) - 1)), lw=1)
        ax.set_title(f"mode {k + 1}: {m.frequency_hz[k]:.4f} Hz", fontsize=9)
        ax.set_xlabel(f"{hx} (m)")
        ax.set_aspect("equal")
        ax.set_xlim(-half_width, half_width)
        if square:
            ax.set_ylim(-half_width, half_width)
    np.atleast_1d(axes)[0].set_ylabel(f"{hy} (m)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / filename, dpi=110)


def inverse_figure():
    """four_bar_driven.yaml: the motor torque over one crank turn."""
    r = fccgen.inverse_dynamics(EXAMPLES / "four_bar_driven.yaml")
    turn = r["t"] <= 2 * np.pi / 10 + 1e-12                     # the crank at 10 rad/s
    fig, ax = plt.subplots(figsize=(6, 3.2))
    ax.plot(np.degrees(r["O.angle"][turn]), r["motor.torque"][turn], "C0.-")
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("crank joint angle O (deg)")
    ax.set_ylabel("motor torque (N m)")
    ax.set_title("four_bar_driven.yaml: torque to turn the crank at 10 rad/s")
    fig.tight_layout()
    fig.savefig(OUT / "analyses_inverse_four_bar.png", dpi=110)


def main():
    statics_figure()
    modes_figure("double_pendulum", ("x", "y"), "double_pendulum.yaml: mode shapes "
                 "(one period, dark to light)", "analyses_modes_double_pendulum.png")
    modes_figure("spatial_double_pendulum", ("x", "y"), "spatial_double_pendulum.yaml: "
                 "swinging modes seen from above (one period, dark to light)",
                 "analyses_modes_spatial.png", half_width=0.15, square=True)
    inverse_figure()


if __name__ == "__main__":
    main()
