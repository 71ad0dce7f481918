"""The kernels every element class may have: the list is data, in the order of the
fields of ``fcc_element_class`` (fccgen/runtime/fccgen_model.h).

The two force Jacobians return the derivatives of the applied forces f themselves,
``df/dq`` and ``df/dq'`` (n_q x n_q, row-major). Implicit integrators build their
tangent from K = -df/dq and C = -df/dq' (e.g. M + (dt/2) C + (dt^2/4) K).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from .classes import DRIVER_KINDS, ElementClass


@dataclass(frozen=True)
class KernelSpec:
    name: str
    uses_v: bool                              # signature (q, v, p, out) or (q, p, out)
    size: Callable[[ElementClass], int]       # number of outputs (row-major)
    equation: str                             # one line for generated headers

    def applies(self, cls: ElementClass) -> bool:
        """Whether the kernel can exist for the class at all (it may still be
        identically zero, in which case derive drops it)."""
        return self.size(cls) > 0


_LOADED = ("body", "force", "torque", "spring", "torsion_spring", "force_t",
           "torque_t", "linear_spring", "force_q", "torque_q",       # applied forces
           "cable", "point_force", "point_force_t")
_DAMPED = ("spring", "torsion_spring", "linear_spring",   # forces that read speeds
           "force_q", "torque_q", "cable")
_MASSIVE = ("body", "cable")                               # kinds with a mass matrix


def _body_only(n: int):
    return lambda cls: n if cls.kind == "body" else 0


KERNELS: tuple[KernelSpec, ...] = (
    KernelSpec("mass_matrix", False,
               lambda c: c.n_q * c.n_q if c.kind in _MASSIVE else 0,
               "M = m Dhat^T Dhat + Phi_b^T I_b Phi_b (cable: rhoA int S^T S dx)"),
    KernelSpec("h_vector", True, lambda c: c.n_q if c.kind == "body" else 0,
               "h = m Dhat^T (2c r_ij' x u') + Phi_b^T (I_b c_w + w_b x I_b w_b)"),
    KernelSpec("applied_forces", True,
               lambda c: c.n_q if c.kind in _LOADED else 0,
               "f = sum Dhat^T F + Phi^T T"),
    KernelSpec("constraints", False, lambda c: c.n_g, "g(q)"),
    KernelSpec("constraint_jacobian", False, lambda c: c.n_g * c.n_q, "B = dg/dq"),
    KernelSpec("constraint_bias", True, lambda c: c.n_g,
               "g'' - B q'' = q'^T (d2g/dq2) q' (+ 2 (d2g/dq dt) q' + d2g/dt2)"),
    KernelSpec("energy", True,
               lambda c: 2 if c.kind in ("body", "force", "spring", "torsion_spring",
                                         "linear_spring", "cable", "point_force") else 0,
               "[kinetic, potential]"),
    KernelSpec("body_outputs", True, _body_only(6), "[r_G, w] (global frame)"),
    # f of a spring-damper depends on q' only linearly, so df/dq' needs no speeds;
    # df/dq of a damper does.
    KernelSpec("force_jacobian_q", True,
               lambda c: c.n_q * c.n_q if c.kind in _LOADED else 0,
               "df/dq of the applied forces (tangent stiffness K = -df/dq)"),
    KernelSpec("force_jacobian_v", False,
               lambda c: c.n_q * c.n_q if c.kind in _DAMPED else 0,
               "df/dq' of the applied forces (tangent damping C = -df/dq')"),
    KernelSpec("constraint_rate", False,
               lambda c: c.n_g if c.kind in DRIVER_KINDS else 0,
               "partial dg/dt (rheonomic rows)"),
)

KERNEL_NAMES = tuple(k.name for k in KERNELS)
