"""The systems of the comparison and their fccgen model files.

``a02``: the IFToMM A02 chain of N four-bar loops (``examples/make_n_four_bar.py``);
``cart``: the n-link pendulum on a cart (``examples/make_pendulum_on_cart.py``);
``boom``: the planar scissor boom of n units (2n bars) deployed by torsion springs,
without its latch (``examples/make_scissor_boom.py``, ``model_text(n, latch=False)``).
The generators hold the geometry, masses and initial state; the MuJoCo and Exudyn
models (``mujoco_models.py``, ``exudyn_models.py``) read the same constants from them,
so every tool integrates the same system. MuJoCo has no model of the boom
(``PEERS``).
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SYSTEMS = ("a02", "cart", "boom")
TITLES = {"a02": "A02 N-four-bar chain (N loops)",
          "cart": "n-link pendulum on a cart (n links)",
          "boom": "planar scissor boom (n units, 2n bars)"}
# The peer tools that have a model of each system (fccgen has all of them).
PEERS = {"a02": ("mujoco", "exudyn"), "cart": ("mujoco", "exudyn"), "boom": ("exudyn",)}
# Simulated time the timed runs stay within (s), per system. The A02 chain's loops all
# reach their flat (singular) position together at t = 1.245 s; from 80 loops on, an
# RK4 step of 1 ms through it is not sound on either of fccgen's paths, which stop
# with an error there (docs/performance.md, "With the sparse path"). The runs of
# every tool end before it.
# The boom swings between its bars' angles of 80 and 20 degrees to x, away from its
# flat (singular) position at 0: its runs need no cap.
TIMED_SPAN = {"a02": 1.2, "cart": None, "boom": None}
# The steps k of every tool's timed runs (k and 2k steps: the steps k+1 .. 2k are
# timed) where a tool's cost per step changes along the motion, so that each tool's own
# calibrated k would time a different span. The boom starts at rest and Exudyn's step
# costs more as it speeds up (100 units, whole runs: 0.66 ms per step in runs of 50
# steps, 1.45 ms in runs of 4000; fccgen 0.72 and 0.56 ms); the calibration gave 13 to 33
# steps from 250 units on, the slow start. So every tool times the steps 2001 .. 4000
# (t = 2 s to 4 s), the span the calibration gives the cheapest sizes (k = 2000).
TIMED_STEPS = {"a02": None, "cart": None, "boom": 2000}


def _module(stem: str):
    spec = importlib.util.spec_from_file_location(stem, EXAMPLES / f"{stem}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


FOUR_BAR = _module("make_n_four_bar")
CART = _module("make_pendulum_on_cart")
BOOM = _module("make_scissor_boom")


def generator(system: str):
    """The example script's module that writes the system's model file."""
    if system not in SYSTEMS:
        raise ValueError(f"unknown system {system!r}: one of {', '.join(SYSTEMS)}")
    return {"a02": FOUR_BAR, "cart": CART, "boom": BOOM}[system]


def model_file(system: str, n: int, directory: Path) -> Path:
    """Write (if changed) and return the fccgen model file of size n in directory."""
    gen = generator(system)
    directory.mkdir(parents=True, exist_ok=True)
    if system == "boom":       # unlatched: its own file name, apart from the latched one
        path = directory / f"{gen.model_name(n)}_unlatched.yaml"
        text = gen.model_text(n, latch=False)
    else:
        path = directory / f"{gen.model_name(n)}.yaml"
        text = gen.model_text(n)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


def n_coordinates(system: str, n: int) -> int:
    """fccgen's coordinates n_q of the system of size n."""
    if system == "boom":       # the unlatched boom's header: 9n + 15
        return 9 * n + 15
    return 3 * (n + 1) if system == "a02" else 3 * (n + 2)


def tracked_point(system: str, n: int) -> str:
    """The point compared between tools: B0 of the chain (the benchmark's), the chain's
    tip P<n> on the cart, the boom's tip node T<n> (the far end of bar a<n-1>)."""
    return {"a02": "B0", "cart": f"P{n}", "boom": f"T{n}"}[system]
