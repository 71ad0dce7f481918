"""The two systems of the comparison and their fccgen model files.

``a02``: the IFToMM A02 chain of N four-bar loops (``examples/make_n_four_bar.py``);
``cart``: the n-link pendulum on a cart (``examples/make_pendulum_on_cart.py``). The
generators hold the geometry, masses and initial state; the MuJoCo and Exudyn models
(``mujoco_models.py``, ``exudyn_models.py``) read the same constants from them, so all
three tools integrate the same system.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SYSTEMS = ("a02", "cart")
TITLES = {"a02": "A02 N-four-bar chain (N loops)",
          "cart": "n-link pendulum on a cart (n links)"}
# Simulated time the timed runs stay within (s), per system. The A02 chain's loops all
# reach their flat (singular) position together at t = 1.245 s; from 80 loops on, an
# RK4 step of 1 ms through it is not sound on either of fccgen's paths, which stop
# with an error there (docs/performance.md, "With the sparse path"). The runs of
# every tool end before it.
TIMED_SPAN = {"a02": 1.2, "cart": None}


def _module(stem: str):
    spec = importlib.util.spec_from_file_location(stem, EXAMPLES / f"{stem}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


FOUR_BAR = _module("make_n_four_bar")
CART = _module("make_pendulum_on_cart")


def generator(system: str):
    """The example script's module that writes the system's model file."""
    if system not in SYSTEMS:
        raise ValueError(f"unknown system {system!r}: one of {', '.join(SYSTEMS)}")
    return FOUR_BAR if system == "a02" else CART


def model_file(system: str, n: int, directory: Path) -> Path:
    """Write (if changed) and return the fccgen model file of size n in directory."""
    gen = generator(system)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{gen.model_name(n)}.yaml"
    text = gen.model_text(n)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


def n_coordinates(system: str, n: int) -> int:
    """fccgen's coordinates n_q of the system of size n."""
    return 3 * (n + 1) if system == "a02" else 3 * (n + 2)


def tracked_point(system: str, n: int) -> str:
    """The point compared between tools: B0 of the chain (the benchmark's), the chain's
    tip P<n> on the cart."""
    return "B0" if system == "a02" else f"P{n}"
