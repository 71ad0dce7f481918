"""Mode shapes as results the animation can play (``fccgen modes --shapes``).

Mode k of :func:`fccgen.analysis.modes` about q* (the linearization's point) becomes
the small-amplitude motion over one period

    z(tau) = a phi_k sin(2 pi tau),     tau = t / T in [0, 1],

in the independent coordinates z = N^T (q - q*) (phi_k = N^T shape_k, scaled so that
its largest coordinate is 1), projected onto the constraints: q(tau) solves g(q) = 0
with N^T (q - q*) = z(tau) exactly (:func:`fccgen.analysis.state_from_z`), and q' from
z' = a phi_k (2 pi / T) cos(2 pi tau) with B q' = 0. T = 1 / |f_k| for a vibration;
a rigid-body mode (frequency 0) has no period and is shown with T = 1 (time units).
The amplitude a is in the model's length unit: by default a tenth of its largest body
length.

Each shape is a :class:`~fccgen.results.result.Result` with every column of a run (points,
vectors, bodies, energy, constraint_error) and ``info`` saying what it is: ``mode``,
``frequency_hz``, ``damping_ratio``, ``rigid``, ``period``, ``amplitude``,
``about`` and the model's metadata. Written by :func:`write_mode_shapes` as one file
per mode, ``<stem>.mode<k><suffix>`` (modes.npz -> modes.mode1.npz, modes.mode2.npz,
...), which ``fccgen animate MODEL --result modes.npz --mode k`` finds.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..results.files import mode_shape_path
from .linearize import Linearization, state_from_z
from .modes import Modes

DEFAULT_FRAMES = 41
DEFAULT_AMPLITUDE = 0.1          # times the largest body length


def mode_shapes(solver, lin: Linearization, modes: Modes, *, amplitude=None,
                frames: int = DEFAULT_FRAMES, about: str = "equilibrium") -> list:
    """One Result per mode (see the module docstring); ``amplitude`` in length units
    (default: DEFAULT_AMPLITUDE times the largest body length), ``frames`` rows over
    the period, both ends included."""
    if frames < 3:
        raise ValueError(f"a mode shape needs at least 3 frames (got {frames})")
    a = DEFAULT_AMPLITUDE * solver.length_scale if amplitude is None else float(amplitude)
    if not a > 0.0:
        raise ValueError(f"the amplitude of a mode shape must be positive (got {amplitude})")
    return [_shape(solver, lin, modes, k, a, frames, about)
            for k in range(len(modes.frequency_hz))]


def _direction(lin: Linearization, shape: np.ndarray) -> np.ndarray:
    """phi = N^T shape, scaled to a largest q-coordinate of 1 and signed so that this
    coordinate is positive (a definite direction for each mode)."""
    phi = lin.null_basis.T @ shape
    q_dir = lin.null_basis @ phi
    biggest = int(np.argmax(np.abs(q_dir)))
    return phi / q_dir[biggest]


def _shape(solver, lin, modes, k, a, frames, about):
    from ..results.provenance import provenance
    from ..results.result import result_from_arrays, _with_joint_columns
    f = float(modes.frequency_hz[k])
    rigid = bool(modes.rigid[k])
    period = 1.0 / abs(f) if (f != 0.0 and not rigid) else 1.0
    phi = _direction(lin, modes.shapes[:, k])
    tau = np.linspace(0.0, 1.0, frames)
    qs, vs = [], []
    for s in tau:
        q, v = state_from_z(lin, solver, a * phi * np.sin(2 * np.pi * s),
                            a * phi * (2 * np.pi / period) * np.cos(2 * np.pi * s))
        qs.append(q)
        vs.append(v)
    q, v = np.array(qs), np.array(vs)
    body = np.array([solver.body_outputs(x, y) for x, y in zip(q, v)]).reshape(
        frames, len(solver.plan.bodies), 6)
    energy = np.array([solver.energy(x, y) for x, y in zip(q, v)])
    error = np.array([np.max(np.abs(solver.constraints(x)), initial=0.0) for x in q])
    info = provenance(solver.plan)
    info.update(kind="mode shape", mode=k + 1, frequency_hz=f,
                damping_ratio=float(modes.damping_ratio[k]), rigid=rigid, period=period,
                amplitude=a, about=about, method=modes.method, frames=frames,
                max_constraint_error=float(error.max()))
    result = result_from_arrays(solver.plan, tau * period, q, v, body, energy, error, info)
    return _with_joint_columns(solver.plan, result)


def write_mode_shapes(shapes: list, path) -> list[Path]:
    """Save each shape as ``mode_shape_path(path, k)``; returns the paths."""
    return [shape.save(mode_shape_path(path, shape.info["mode"])) for shape in shapes]
