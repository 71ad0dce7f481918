"""Flexible members' kernels (docs/flexible.md): the NumPy version against its own
finite differences and against the energy, SymPy's small kernels against the NumPy
version, and the compiled kernels of whole models against the NumPy version to
1e-12 (docs/design.md, section 6)."""
from __future__ import annotations

import numpy as np
import pytest

from fccgen.numeric import element_kernel
from fccgen.plan.classes import ElementClass

from kernel_checks import assert_derived_matches_numeric, gradient

GRAVITY = ("gx", "gy", "gz")


def cable_case(cls: ElementClass, seed: int):
    """A state near a straight element of length L = 0.5 along x (slopes near unit
    length, so the strain stays small and |r'| far from 0), random speeds and numbers."""
    rng = np.random.default_rng(seed)
    near = {"r1": [0.0, 0.0, 0.0], "d1": [1.0, 0.0, 0.0], "r2": [0.5, 0.0, 0.0],
            "d2": [1.0, 0.0, 0.0]}
    q = np.concatenate([np.array(near[t]) + 0.1 * rng.normal(size=3)
                        for t in cls.moving_triples]) if cls.moving_triples else np.zeros(0)
    p = []
    for name in cls.param_names:
        if name in cls.zeros:
            p.append(0.0)
        elif name == "L":
            p.append(0.5)
        elif name == "EA":
            p.append(rng.uniform(1e3, 1e4))
        elif name in ("EI", "rhoA", "c"):
            p.append(rng.uniform(0.5, 2.0))
        elif "." in name:                                  # a fixed triple
            p.append(near[name.split(".")[0]]["xyz".index(name[-1])] + 0.1 * rng.normal())
        else:
            p.append(rng.normal())
    return q, rng.normal(size=q.size), np.array(p)


CLASSES = {
    "moving, damped": ElementClass("cable", (), (False,) * 4, frozenset()),
    "pinned, undamped": ElementClass("cable", (), (True, False, False, False),
                                     frozenset({"c"})),
}


@pytest.mark.parametrize("name", list(CLASSES))
def test_numeric_force_jacobians_are_the_derivatives_of_the_forces(name):
    """df/dq and df/dq' of the NumPy version against five-point differences of its
    forces with h = 1e-4: truncation h^4 f^(5) ~ 1e-16 x EA, rounding eps |f| / h ~ 1e-12
    |f|; 1e-8 of the largest entry leaves room for both."""
    cls = CLASSES[name]
    for seed in range(2):
        q, v, p = cable_case(cls, seed)
        n = cls.n_q
        jq = element_kernel(cls, "force_jacobian_q", q, v, p).reshape(n, n)
        fq = gradient(lambda x: element_kernel(cls, "applied_forces", x, v, p), q, 1e-4)
        assert np.max(np.abs(jq - fq)) <= 1e-8 * np.max(np.abs(fq))
        jv = element_kernel(cls, "force_jacobian_v", q, v, p).reshape(n, n)
        fv = gradient(lambda x: element_kernel(cls, "applied_forces", q, x, p), v, 1e-4)
        assert np.max(np.abs(jv - fv)) <= 1e-8 * max(np.max(np.abs(fv)), 1.0)


def test_undamped_forces_are_minus_the_gradient_of_the_potential():
    """Without damping, f = -dV/dq with V the energy kernel's potential (strain energy,
    gravity and the distributed load), five-point differences as above; and the
    kinetic energy is v^T M v / 2 with the mass matrix kernel."""
    cls = ElementClass("cable", (), (False,) * 4, frozenset({"c"}))
    q, v, p = cable_case(cls, 7)
    f = element_kernel(cls, "applied_forces", q, v, p)

    def potential(x):
        return np.array([element_kernel(cls, "energy", x, v, p)[1]])
    grad = gradient(potential, q, 1e-4).ravel()
    assert np.max(np.abs(f + grad)) <= 1e-8 * np.max(np.abs(f))
    M = element_kernel(cls, "mass_matrix", q, v, p).reshape(cls.n_q, cls.n_q)
    assert element_kernel(cls, "energy", q, v, p)[0] == pytest.approx(0.5 * v @ M @ v,
                                                                       rel=1e-13)


def test_mass_matrix_is_the_closed_form():
    """The NumPy version integrates S^T S by Gauss points; the closed form of the cubic
    Hermite element is rhoA L / 420 [[156, 22L, 54, -13L], ...] per component."""
    cls = ElementClass("cable", (), (False,) * 4, frozenset())
    L, rhoA = 0.7, 1.3
    p = np.array([{"L": L, "rhoA": rhoA}.get(n, 1.0) for n in cls.param_names])
    M = element_kernel(cls, "mass_matrix", np.zeros(12), np.zeros(12), p).reshape(12, 12)
    ref = rhoA * L / 420 * np.array([[156, 22 * L, 54, -13 * L],
                                     [22 * L, 4 * L ** 2, 13 * L, -3 * L ** 2],
                                     [54, 13 * L, 156, -22 * L],
                                     [-13 * L, -3 * L ** 2, -22 * L, 4 * L ** 2]])
    assert np.max(np.abs(M - np.kron(ref, np.eye(3)))) <= 1e-15


def test_stress_free_element_has_no_force_and_its_stiffness_is_the_beam_one():
    """A straight element at rest of unit slopes has no elastic force, and its tangent
    stiffness in the transverse direction is the Euler-Bernoulli beam element's
    EI / L^3 [[12, 6L, -12, 6L], ...] (the Hermite element); in the axial direction
    (positions and slopes along x) EA int S'^T S' dx."""
    cls = ElementClass("cable", (), (False,) * 4, frozenset({"c", *GRAVITY}))
    L, EA, EI = 0.5, 300.0, 2.0
    p = np.array([{"L": L, "EA": EA, "EI": EI, "rhoA": 1.0}.get(n, 0.0)
                  for n in cls.param_names])
    e = np.array([0, 0, 0, 1, 0, 0, L, 0, 0, 1, 0, 0], float)
    f = element_kernel(cls, "applied_forces", e, np.zeros(12), p)
    assert np.max(np.abs(f)) <= 1e-12
    K = -element_kernel(cls, "force_jacobian_q", e, np.zeros(12), p).reshape(12, 12)
    beam = EI / L ** 3 * np.array([[12, 6 * L, -12, 6 * L], [6 * L, 4 * L ** 2, -6 * L, 2 * L ** 2],
                                   [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L ** 2, -6 * L, 4 * L ** 2]])
    y = [1, 4, 7, 10]
    assert np.max(np.abs(K[np.ix_(y, y)] - beam)) <= 1e-12 * np.max(np.abs(beam))
    axial = EA / (30 * L) * np.array([[36, 3 * L, -36, 3 * L], [3 * L, 4 * L ** 2, -3 * L, -L ** 2],
                                      [-36, -3 * L, 36, -3 * L], [3 * L, -L ** 2, -3 * L, 4 * L ** 2]])
    x = [0, 3, 6, 9]
    assert np.max(np.abs(K[np.ix_(x, x)] - axial)) <= 1e-12 * np.max(np.abs(axial))


@pytest.mark.parametrize("cls", [
    ElementClass("slope_normal", (), (False, False), frozenset()),
    ElementClass("slope_normal", (), (False, True), frozenset()),
    ElementClass("point_force", (), (False,), frozenset()),
    ElementClass("point_force_t", (), (False,), frozenset(), "sin(t);2*t;1"),
], ids=lambda c: c.describe())
def test_small_kernels_derived_match_numeric(cls):
    """The clamp row and the point forces: SymPy's kernels against the NumPy version
    (polynomials: 1e-13 of the largest entry is rounding)."""
    assert_derived_matches_numeric(cls, rtol=1e-13)


def test_derived_cable_kernels_match_numeric():
    """The cable element's kernels as SymPy derives them (lambdified) against the
    NumPy version on an undamped pinned class (the damped class is compared in its
    compiled form below): 1e-12 of the largest entry (about 2e-16 is measured)."""
    cls = CLASSES["pinned, undamped"]
    assert_derived_matches_numeric(cls, rtol=1e-12,
                                   cases=[cable_case(cls, s) for s in range(2)])


MODELS = ("cantilever", "flexible_pendulum", "solar_array_boom")


@pytest.mark.parametrize("name", MODELS)
def test_compiled_matches_numeric(name, compiled, numeric):
    """Every global quantity of the compiled model against the NumPy version at random
    states near the model's initial one, to 1e-12 of the largest entry (docs/design.md,
    section 6): clamped, pinned on ground and on a moving body, damped and undamped
    members, gravity and point forces."""
    c, n = compiled(name), numeric(name)
    rng = np.random.default_rng(3)
    for _ in range(2):
        q = c.plan.q0 + 0.02 * rng.normal(size=c.n_q)
        v = rng.normal(size=c.n_q)
        pairs = [(c.mass_matrix(q), n.mass_matrix(q)),
                 (c.applied_forces(q, v), n.applied_forces(q, v)),
                 (c.force_jacobian_q(q, v), n.force_jacobian_q(q, v)),
                 (c.force_jacobian_v(q, v), n.force_jacobian_v(q, v)),
                 (c.constraints(q), n.constraints(q)),
                 (c.constraint_jacobian(q), n.constraint_jacobian(q)),
                 (c.constraint_bias(q, v), n.constraint_bias(q, v)),
                 (np.array([c.energy(q, v)]), np.array([n.energy(q, v)]))]
        for got, want in pairs:
            scale = max(1.0, float(np.max(np.abs(want)))) if want.size else 1.0
            assert np.max(np.abs(got - want), initial=0.0) <= 1e-12 * scale
