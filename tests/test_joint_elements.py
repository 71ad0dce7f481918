"""The mechanism level's element kinds (attached point and vector, point on a plane,
dot product): the derived expressions against the independent NumPy version, the
Jacobian and bias against finite differences, and the attachment rows against a
rigid body placed independently."""
from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy
from scipy.spatial.transform import Rotation

from fccgen.derive import derive_class
from fccgen.numeric import element_kernel
from fccgen.plan.classes import ElementClass
from fccgen.model.geometry import body_frame_numbers, point_coefficients

from kernel_checks import d1

F, T = False, True
CLASSES = [
    ElementClass("attached_point", (), (F, F, F, F), frozenset()),
    ElementClass("attached_point", (), (T, F, T, F), frozenset({"beta"})),
    ElementClass("attached_point", (), (F, F, F, T), frozenset({"b2"})),
    ElementClass("attached_vector", (), (F, F, F, F), frozenset()),
    ElementClass("attached_vector", (), (T, F, F, T), frozenset({"b1", "b3"})),
    ElementClass("point_on_plane", ("point", "point"), (F, F, F), frozenset()),
    ElementClass("point_on_plane", ("point", "point"), (T, F, T), frozenset()),
    ElementClass("point_on_plane", ("body_point", "point"), (F, F, F, F, T), frozenset()),
    ElementClass("dot", (), (F, F), frozenset()),
    ElementClass("dot", (), (F, T), frozenset({"c"})),
    ElementClass("aligned_vector_12", (), (F, F, F, F), frozenset()),
    ElementClass("aligned_vector_12", (), (T, F, T, F), frozenset({"c1"})),
    ElementClass("aligned_vector_12", (), (F, F, F, T), frozenset()),
    ElementClass("aligned_vector_13", (), (F, F, F, T), frozenset()),
    ElementClass("aligned_vector_23", (), (T, F, F, T), frozenset({"c2"})),
    ElementClass("aligned_vector_23", (), (F, F, F, F), frozenset()),
]
IDS = [c.describe().replace(" ", "") for c in CLASSES]
KERNELS = ("constraints", "constraint_jacobian", "constraint_bias")


@functools.lru_cache(maxsize=None)
def derived(cls):
    """Per kernel a function (q, v, p) -> outputs; an identically zero kernel (which
    derive drops as None) gives None."""
    d = derive_class(cls)
    return {name: None if d.kernels[name] is None else
            sympy.lambdify((d.q, d.v, d.p), list(d.kernels[name]), modules="numpy", cse=True)
            for name in KERNELS}


def random_case(cls, seed):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=cls.n_p)
    for k, name in enumerate(cls.param_names):
        if name in cls.zeros:
            p[k] = 0.0
        elif name.split(".")[-1] in ("l", "alpha"):
            p[k] = rng.uniform(0.5, 1.0)
    return rng.normal(size=cls.n_q), rng.normal(size=cls.n_q), p


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_derived_agrees_with_numeric(cls):
    """Same formulas in two independent codes: rounding only, 1e-12 of the largest
    entry of each output (sums of a handful of O(1) products)."""
    fns = derived(cls)
    for seed in range(3):
        q, v, p = random_case(cls, seed)
        for name in KERNELS:
            b = element_kernel(cls, name, q, v, p)
            a = (np.zeros_like(b) if fns[name] is None
                 else np.array(fns[name](q, v, p), float).reshape(-1))
            assert a.shape == b.shape
            assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.abs(b).max()), name


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_jacobian_and_bias_by_finite_differences(cls):
    q, v, p = random_case(cls, 5)
    B = element_kernel(cls, "constraint_jacobian", q, v, p).reshape(cls.n_g, cls.n_q)
    g = lambda x: element_kernel(cls, "constraints", x, None, p)     # noqa: E731
    fd = np.array([d1(g, q, e) for e in np.eye(cls.n_q)]).T
    # g is a polynomial of degree <= 4: the stencil is exact, rounding ~eps |g| / h
    assert np.allclose(B, fd, rtol=0, atol=1e-9 * np.abs(B).max())
    Bv = lambda x: element_kernel(cls, "constraint_jacobian", x, None, p).reshape(  # noqa
        cls.n_g, cls.n_q) @ v
    bias = element_kernel(cls, "constraint_bias", q, v, p)
    assert np.allclose(bias, d1(Bv, q, v), rtol=0, atol=1e-9 * (np.abs(bias).max() + 1))


@pytest.mark.parametrize("kind", ["attached_point", "attached_vector", "aligned_vector_12",
                                  "aligned_vector_13", "aligned_vector_23"])
def test_attachment_holds_on_a_rigid_body(kind):
    """A body at a random pose, a point/vector with body-frame coordinates rho placed
    by the rotation itself: the rows vanish to rounding, and fail for a wrong rho."""
    rng = np.random.default_rng(3)
    R = Rotation.random(random_state=rng).as_matrix()
    ri = rng.normal(size=3)
    rj = ri + R @ np.array([1.3, 0.0, 0.0])
    u = R @ np.array([np.cos(1.1), np.sin(1.1), 0.0])
    l, alpha, beta = body_frame_numbers(ri, rj, u)
    rho = rng.normal(size=3)
    if kind != "attached_point":
        rho /= np.linalg.norm(rho)
        target = R @ rho
    else:
        target = ri + R @ rho
    cls = ElementClass(kind, (), (F, F, F, F), frozenset())
    p = np.array([l, alpha, beta, *point_coefficients(rho, l, alpha, beta)])
    if kind.startswith("aligned_vector"):     # two components, scaled as c1, c2, c3
        c = {"c1": l * rho[0], "c2": beta * rho[0] + alpha * rho[1], "c3": alpha * l * rho[2]}
        p = np.array([c[n] for n in cls.scalar_names])
    q = np.concatenate([ri, rj, u, target])
    assert np.abs(element_kernel(cls, "constraints", q, None, p)).max() < 1e-14
    q_wrong = np.concatenate([ri, rj, u, target + 1e-3])
    assert np.abs(element_kernel(cls, "constraints", q_wrong, None, p)).max() > 9e-4
