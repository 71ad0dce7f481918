"""Turn counting of the NumPy kernels that read a joint angle (torsion springs, loads
of joint angles; docs/elements.md, "Angles over turns"), written independently of the
compiled runtime's: each such element keeps its own reference th (with cr, sr = cos,
sin th) among its parameters, and :meth:`AngleReferences.rebase` moves it to the
element's own angle at q after every accepted step. Within a step the element's
atan2 then stays near 0, so its angle is counted over turns.
"""
from __future__ import annotations

import math

import numpy as np

from ..plan.classes import REFERENCE_SCALARS
from .elements import element_kernels


def _angles(el, kernels) -> list[tuple[str, float]]:
    """(parameter prefix, angle from the initial configuration) of each reference the
    element reads, with its present reference."""
    if el.cls.kind == "torsion_spring":
        return [("", kernels.angle[0] + kernels.x.s["free"])]
    from .joint_loads import _angle
    return [(f"{joint}.angle.", _angle(kernels.x, f"{joint}.angle.")[0])
            for joint, family in el.cls.joint_families if family == "angle"]


class AngleReferences:
    """The references th, cr, sr of a solver's elements, in its parameter arrays."""

    def __init__(self, plan, params: list[np.ndarray], index: list[np.ndarray]):
        self.plan, self.params, self.index = plan, params, index
        self.elements = [e for e, el in enumerate(plan.elements)
                         if el.cls.kind == "torsion_spring" or any(
                             fam == "angle" for _, fam in el.cls.joint_families)]
        self.largest_turn = (0.0, "")

    def __bool__(self) -> bool:
        return bool(self.elements)

    def _set(self, e: int, prefix: str, th: float) -> None:
        names = self.plan.elements[e].cls.param_names
        k = names.index(prefix + REFERENCE_SCALARS[0])
        self.params[e][k:k + 3] = th, math.cos(th), math.sin(th)

    def _prefixes(self, e: int) -> list[str]:
        el = self.plan.elements[e]
        return [""] if el.cls.kind == "torsion_spring" else \
            [f"{j}.angle." for j, fam in el.cls.joint_families if fam == "angle"]

    def start(self) -> None:
        """References 0 at a run's start (its angles within half a turn of 0)."""
        for e in self.elements:
            for prefix in self._prefixes(e):
                self._set(e, prefix, 0.0)
        self.largest_turn = (0.0, "")

    def restore(self) -> None:
        """The plan's references again (outside runs: a spring's free angle)."""
        for e in self.elements:
            el = self.plan.elements[e]
            for prefix in self._prefixes(e):
                k = el.cls.param_names.index(prefix + REFERENCE_SCALARS[0])
                self.params[e][k:k + 3] = el.params[k:k + 3]

    def rebase(self, q) -> None:
        """Move every reference to its element's angle at q; keep the largest move."""
        q = np.asarray(q, float)
        for e in self.elements:
            el = self.plan.elements[e]
            p, idx = self.params[e], self.index[e]
            kernels = element_kernels(el.cls, q[idx], None, p)
            for prefix, angle in _angles(el, kernels):
                th = p[el.cls.param_names.index(prefix + REFERENCE_SCALARS[0])]
                if abs(angle - th) > self.largest_turn[0]:
                    self.largest_turn = (abs(angle - th), f"{el.label} {prefix}".strip())
                self._set(e, prefix, angle)
