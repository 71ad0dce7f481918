"""Plot the x-motion of body 4's mass centre in the deployable structure against the
time step, like Fig. 3 of the FCC paper's example.

    python3 examples/plot_deployable.py [OUT.png] [--numeric]

Runs examples/deployable.yaml through the Python API (compiled solver, built and
cached on first use; ``--numeric`` uses the NumPy version instead, which needs no C
compiler) and saves the figure (default: deployable_body4_x.png). Needs matplotlib.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import fccgen

MODEL = Path(__file__).resolve().parent / "deployable.yaml"


def body4_x(model=MODEL, numeric: bool = False):
    """Simulate the model with its own settings (200 steps of 1 ms); return the step
    numbers and the x-coordinate of body 4's mass centre (mm) at every step."""
    solver = fccgen.load_numeric(model) if numeric else fccgen.load(model)
    result = solver.simulate()
    dt = float(result.t[1] - result.t[0])
    steps = np.rint(result.t / dt).astype(int)
    return steps, result["body4.cx"]


def plot(steps, x, out) -> Path:
    """Draw x against the step number and save it as a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(steps, x, color="black")
    ax.set_xlabel("time step (0.001 s)")
    ax.set_ylabel("x of the mass centre of body 4 (mm)")
    ax.set_title("Deployable structure: mass centre motion of body 4")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=150)
    plt.close(fig)
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default="deployable_body4_x.png",
                        help="PNG file to write (default: deployable_body4_x.png)")
    parser.add_argument("--numeric", action="store_true",
                        help="use the NumPy version of the solver (no compiler needed)")
    args = parser.parse_args(argv)
    steps, x = body4_x(numeric=args.numeric)
    path = plot(steps, x, args.out)
    print(f"body 4 mass centre x: {x[0]:.1f} mm at step {steps[0]}, "
          f"{x[-1]:.1f} mm at step {steps[-1]}; figure written to {path}")


if __name__ == "__main__":
    main()
