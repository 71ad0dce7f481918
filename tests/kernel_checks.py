"""Random element cases and the checks that compare an element class's kernels in two
independent codes (a helper module of the element tests).

* ``random_case``: random q, v and parameters of a class (lengths, masses positive, an
  inertia positive definite, structural zeros zero, time t in [0, 2]);
* ``assert_derived_matches_numeric``: SymPy's kernels (``fccgen.derive``) against the
  NumPy version written by hand (``fccgen.numeric``);
* ``assert_force_jacobians_match``: the NumPy version's df/dq and df/dq' against
  five-point differences of its applied forces.

Five-point stencils are exact for polynomials of degree four, so on the polynomial
kernels only rounding is left and tolerances can be tight.
"""
from __future__ import annotations

import numpy as np
import sympy

from fccgen.derive import derive_class
from fccgen.numeric import element_kernel
from fccgen.plan.classes import ElementClass


def d1(f, x, direction, h=1e-3):
    """Five-point first derivative of f along direction (exact for degree <= 4)."""
    return (-f(x + 2 * h * direction) + 8 * f(x + h * direction)
            - 8 * f(x - h * direction) + f(x - 2 * h * direction)) / (12 * h)


def gradient(f, x, h=1e-3):
    """The Jacobian of f at x, column by column with ``d1``."""
    return np.array([d1(f, x, e, h) for e in np.eye(x.size)]).T


def random_inertia(rng) -> np.ndarray:
    """A positive definite inertia tensor with three different principal values."""
    Rq, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return Rq @ np.diag(rng.uniform(0.5, 2.0, 3)) @ Rq.T


def random_params(cls: ElementClass, rng) -> np.ndarray:
    """Random values of cls.param_names (zeros where cls.zeros says; the time t, where
    the class reads it, in [0, 2])."""
    I = random_inertia(rng)
    inertia = {"Ixx": I[0, 0], "Iyy": I[1, 1], "Izz": I[2, 2], "Ixy": I[0, 1],
               "Ixz": I[0, 2], "Iyz": I[1, 2]}
    values = []
    for name in cls.param_names:
        short = name.split(".")[-1]
        if name in cls.zeros:
            values.append(0.0)
        elif short in ("l", "L", "L0", "k", "c"):
            values.append(rng.uniform(0.5, 2.0))
        elif short == "alpha":
            values.append(rng.uniform(0.4, 1.0))
        elif short == "m":
            values.append(rng.uniform(1.0, 3.0))
        elif short in inertia:
            values.append(inertia[short])
        elif name == "t":
            values.append(rng.uniform(0.0, 2.0))
        else:
            values.append(rng.normal())
    return np.array(values)


def random_case(cls: ElementClass, seed: int):
    """Random (q, v, p) of a class; q is off the rigid-body manifold, which the
    kernels do not need."""
    rng = np.random.default_rng(seed)
    return rng.normal(size=cls.n_q), rng.normal(size=cls.n_q), random_params(cls, rng)


def _numpy_kernel(name, cls, q, v, p):
    return element_kernel(cls, name, q, v, p)


def assert_derived_matches_numeric(cls: ElementClass, seeds=range(3), numeric=None,
                                   rtol: float = 1e-12, cases=None) -> None:
    """Every kernel SymPy derives for ``cls`` equals the NumPy version at random
    cases, to ``rtol`` of the kernel's largest entry (the caller states why).
    ``numeric(name, cls, q, v, p)`` defaults to ``fccgen.numeric.element_kernel``;
    ``cases`` replaces the random cases of ``seeds``."""
    numeric = numeric or _numpy_kernel
    d = derive_class(cls)
    fns = {name: sympy.lambdify((d.q, d.v, d.p), list(m), cse=True)
           for name, m in d.kernels.items() if m is not None}
    for q, v, p in cases if cases is not None else [random_case(cls, s) for s in seeds]:
        for name, fn in fns.items():
            got = np.array(fn(q, v, p), float)
            want = numeric(name, cls, q, v, p)
            scale = max(1.0, np.max(np.abs(want)))
            assert np.max(np.abs(got - want)) <= rtol * scale, (name, q, v, p)


def assert_force_jacobians_match(cls: ElementClass, q, v, p, h: float, rtol: float,
                                 numeric=None) -> None:
    """df/dq and df/dq' of the NumPy version against five-point differences of its
    applied forces with step h, to ``rtol`` of the differences' largest entry."""
    numeric = numeric or _numpy_kernel
    n = cls.n_q
    jq = numeric("force_jacobian_q", cls, q, v, p).reshape(n, n)
    jv = numeric("force_jacobian_v", cls, q, v, p).reshape(n, n)
    fq = gradient(lambda x: numeric("applied_forces", cls, x, v, p), q, h)
    fv = gradient(lambda x: numeric("applied_forces", cls, q, x, p), v, h)
    assert np.max(np.abs(jq - fq)) <= rtol * max(1.0, np.max(np.abs(fq)))
    assert np.max(np.abs(jv - fv)) <= rtol * max(1.0, np.max(np.abs(fv)))
