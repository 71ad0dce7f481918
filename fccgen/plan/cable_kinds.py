"""The element kinds of flexible members (docs/flexible.md), as data
for the registries of :mod:`fccgen.plan.classes`.

* ``cable``: one ANCF cable element between nodes 1 and 2, each a point r and a slope
  d = dr/dx (x the stress-free arc length): r(x) = S1 r1 + S2 d1 + S3 r2 + S4 d2 with
  the cubic Hermite shape functions of xi = x / L. Scalars: the element's stress-free
  length L, EA, EI, the mass per length rhoA, the stiffness-proportional damping c
  (time), gravity g and the distributed load q (force per length, global frame).
* ``slope_normal``: one row d . n = 0 of a clamp (a slope d held perpendicular to a
  unit vector n of the clamping body; two such rows hold d's direction).
* ``point_force``, ``point_force_t``: a force F, or F(t), on one point r.

Both the symbolic kernels (fccgen.derive.cables) and the NumPy version
(fccgen.numeric.cables) integrate the strain energy by the same Gauss rule of
:data:`GAUSS_POINTS` points on every element; the mass matrix and the loads are exact.
"""
from __future__ import annotations

CABLE_TRIPLES = ("r1", "d1", "r2", "d2")
CABLE_SCALARS = ("L", "EA", "EI", "rhoA", "c", "gx", "gy", "gz", "qx", "qy", "qz")
# Gauss-Legendre points per element for the axial and bending energy. Three integrate
# the small-deflection energy exactly (eps ~ u', degree 4 in xi; kappa ~ v'', degree 2)
# without the zero-energy axial mode that two points leave (eps' orthogonal to the
# linear functions, the same on every element: all slopes stretched alike with the
# positions kept); docs/flexible.md shows the convergence it gives.
GAUSS_POINTS = 3

# kind: (scalars, ends, triples, foldable, constraint rows), as MECHANISM_KINDS
CABLE_KINDS = {
    "cable": (CABLE_SCALARS, (), CABLE_TRIPLES,
              {"c", "gx", "gy", "gz", "qx", "qy", "qz"}, ()),
    "slope_normal": ((), (), ("d", "n"), set(), ("clamp",)),
    "point_force": (("Fx", "Fy", "Fz"), (), ("r",), {"Fx", "Fy", "Fz"}, ()),
}
# a force of time: its class's ``function`` is "Fx;Fy;Fz" (expressions of t)
TIMED_POINT_KINDS = {"point_force_t": (("t",), (), ("r",), set(), ())}
