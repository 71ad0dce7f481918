"""The NumPy element kernels (fccgen.numeric) against finite differences, hand-derived
identities and known rigid motions, for every kind with fixed-triple and body-point
variants.

Finite differences use the five-point stencils, which are exact for polynomials of
degree four (first derivative) or five (second derivative): constraints, body points
and gravity potentials are polynomials of degree at most four in q, so only rounding
is left and tolerances can be tight.
"""
from __future__ import annotations

import numpy as np
import pytest

from fccgen.numeric import element_kernel, element_kernels
from fccgen.numeric.kinematics import skew
from fccgen.plan.classes import ElementClass
from fccgen.model.geometry import point_coefficients
from fccgen.plan.kernels import KERNEL_NAMES, KERNELS

from kernel_checks import d1, gradient, random_case, random_params

F, T = False, True
CLASSES = [
    ElementClass("body", (), (F, F, F), frozenset()),
    ElementClass("body", (), (T, F, F), frozenset()),
    ElementClass("body", (), (T, F, T), frozenset({"beta", "a2", "Ixy", "Ixz", "Iyz", "gz"})),
    ElementClass("body", (), (F, F, T), frozenset({"a3", "gx", "gy"})),
    ElementClass("unit_vector", (), (F,), frozenset()),
    ElementClass("distance", ("point", "point"), (F, F), frozenset()),
    ElementClass("distance", ("point", "point"), (T, F), frozenset()),
    ElementClass("distance", ("body_point", "point"), (F, F, F, T), frozenset({"A.b2"})),
    ElementClass("distance", ("body_point", "body_point"), (T, F, F, F, F, T), frozenset()),
    ElementClass("point_on_line", ("point", "point", "point"), (F, T, T), frozenset()),
    ElementClass("point_on_line", ("point", "point", "point"), (F, F, F), frozenset()),
    ElementClass("point_on_line", ("body_point", "point", "body_point"),
                 (F, F, F, T, T, F, F), frozenset({"K.b3"})),
    ElementClass("force", (), (F, F, F), frozenset()),
    ElementClass("force", (), (T, F, T), frozenset({"beta", "b2", "b3", "Fz"})),
    ElementClass("torque", (), (F, F, F), frozenset()),
    ElementClass("torque", (), (T, F, T), frozenset({"beta", "Tx"})),
    ElementClass("spring", ("point", "point"), (T, F), frozenset({"c"})),
    ElementClass("spring", ("body_point", "body_point"), (F, F, F, F, F, F), frozenset()),
    ElementClass("spring", ("point", "body_point"), (T, F, F, T), frozenset({"L0"})),
]
IDS = [f"{c.kind}:{'/'.join(c.ends)}:{''.join('F' if f else 'm' for f in c.fixed)}"
       for c in CLASSES]
SPECS = {k.name: k for k in KERNELS}


def kernel(cls, name, q, v, p):
    return element_kernel(cls, name, q, v, p)


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_kernel_sizes_follow_the_specs(cls):
    q, v, p = random_case(cls, 0)
    for name in KERNEL_NAMES:
        out = kernel(cls, name, q, v, p)
        if SPECS[name].applies(cls):
            assert out.shape == (SPECS[name].size(cls),)
            assert np.all(np.isfinite(out))
        else:
            assert out is None


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.n_g], ids=lambda c: c.name)
def test_jacobian_and_bias_by_finite_differences(cls):
    q, v, p = random_case(cls, 1)
    B = kernel(cls, "constraint_jacobian", q, v, p).reshape(cls.n_g, cls.n_q)
    g = lambda x: kernel(cls, "constraints", x, None, p)            # noqa: E731
    # only rounding is left (g is a quartic): eps * |g| / h with |g| ~ 1e2, h = 1e-3
    assert np.allclose(B, gradient(g, q), rtol=0, atol=1e-9 * np.abs(B).max())
    bias = kernel(cls, "constraint_bias", q, v, p)
    Bv = lambda x: kernel(cls, "constraint_jacobian", x, None, p).reshape(  # noqa: E731
        cls.n_g, cls.n_q) @ v
    assert np.allclose(bias, d1(Bv, q, v), rtol=0, atol=1e-9 * (np.abs(bias).max() + 1))


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.kind in ("body", "force")],
                         ids=lambda c: c.name)
def test_constant_forces_are_minus_the_potential_gradient(cls):
    q, v, p = random_case(cls, 2)
    f = kernel(cls, "applied_forces", q, v, p)
    potential = lambda x: kernel(cls, "energy", x, v, p)[1]        # noqa: E731
    # the potential is quadratic in q: five-point differences leave only rounding
    assert np.allclose(f, -gradient(potential, q), rtol=0, atol=1e-10 * np.abs(f).max())


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.kind == "spring"],
                         ids=lambda c: c.name)
def test_spring_force_is_minus_gradient_plus_damping(cls):
    q, v, p = random_case(cls, 3)
    names = cls.param_names
    c = p[names.index("c")]
    p_elastic = p.copy()
    p_elastic[names.index("c")] = 0.0
    f_elastic = kernel(cls, "applied_forces", q, v, p_elastic)
    potential = lambda x: kernel(cls, "energy", x, v, p)[1]        # noqa: E731
    # L = |d| is not a polynomial: the h^4 error of the stencil is ~1e-12 at h = 1e-3
    assert np.allclose(f_elastic, -gradient(potential, q), rtol=0,
                       atol=1e-8 * np.abs(f_elastic).max())
    # damping power -c L'^2, with L' the rate of the spring length along v
    length = lambda x: np.sqrt(2 * kernel(cls, "energy", x, v, _stiff(p, names))[1])  # noqa
    rate = d1(length, q, v)
    f = kernel(cls, "applied_forces", q, v, p)
    assert (f - f_elastic) @ v == pytest.approx(-c * rate ** 2, rel=1e-8, abs=1e-12)


def _stiff(p, names):
    """Parameters of a unit spring with zero free length: energy = L^2 / 2."""
    p = p.copy()
    p[names.index("k")], p[names.index("L0")] = 1.0, 0.0
    return p


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.kind == "body"], ids=lambda c: c.name)
def test_body_mass_matrix(cls):
    q, v, p = random_case(cls, 4)
    M = kernel(cls, "mass_matrix", q, v, p).reshape(cls.n_q, cls.n_q)
    scale = np.abs(M).max()
    # sums of the same products in two orders: a few ulps of the largest entry
    assert np.allclose(M, M.T, rtol=0, atol=1e-14 * scale)
    eig = np.linalg.eigvalsh(0.5 * (M + M.T))
    assert eig.min() >= -1e-12 * scale                      # positive semi-definite
    if cls.n_q == 9:
        # rank 6: three zero eigenvalues (rounding: 1e-12 of the largest), the rest
        # well away from zero for these O(1) random numbers
        assert np.sum(np.abs(eig) < 1e-12 * scale) == 3
        assert np.sort(np.abs(eig))[3] > 1e-6 * scale
    kinetic = kernel(cls, "energy", q, v, p)[0]
    assert 0.5 * v @ M @ v == pytest.approx(kinetic, rel=1e-13)   # rounding only


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.kind == "body"], ids=lambda c: c.name)
def test_body_h_vector_from_partials(cls):
    """Off the manifold: h = m Dhat^T (dDhat/dt v) + Phi_b^T (I_b (dPhi_b/dt v) +
    w_b x I_b w_b), the derivatives of Dhat(q) and Phi_b(q) along v by differences."""
    q, v, p = random_case(cls, 5)
    k = element_kernels(cls, q, v, p)
    m = p[cls.param_names.index("m")]
    dhat = lambda x: element_kernels(cls, x, v, p).dhat @ v        # noqa: E731
    phi = lambda x: element_kernels(cls, x, v, p).phi_b @ v        # noqa: E731
    a_bias, alpha_bias = d1(dhat, q, v), d1(phi, q, v)
    w_b, I = k.phi_b @ v, k.inertia
    expected = m * k.dhat.T @ a_bias + k.phi_b.T @ (I @ alpha_bias + np.cross(w_b, I @ w_b))
    h = kernel(cls, "h_vector", q, v, p)
    # Dhat and Phi_b are quadratic in q: exact differences, rounding only, relative to
    # the size of the terms (h itself cancels to zero for a hinge about a fixed u)
    scale = (m * np.abs(k.dhat).max() * np.abs(a_bias).max() + np.abs(k.phi_b).max()
             * np.abs(I).max() * (np.abs(alpha_bias).max() + np.abs(w_b).max() ** 2))
    assert np.allclose(h, expected, rtol=0, atol=1e-10 * scale)
    assert np.allclose(k.dhat, gradient(lambda x: element_kernels(cls, x, v, p).G.r, q),
                       rtol=0, atol=1e-10)          # Dhat = dr_G/dq, r_G is quadratic


# -- known rigid motions --------------------------------------------------------------
def rot(n, theta):
    """Rotation by theta about the unit axis n (Rodrigues)."""
    K = skew(n)
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


class RigidMotion:
    """R(t) = Rot(n1, th1(t)) Rot(n2, th2(t)) R0, r_i(t) a quadratic (or constant):
    positions, speeds and accelerations of the body triples, analytically. A fixed r_i
    stays put; a fixed u is the axis of both rotations."""

    def __init__(self, rng, fixed, l, gamma):
        self.l = l
        self.R0, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        self.R0 *= np.sign(np.linalg.det(self.R0))
        self.u_body = np.array([np.cos(gamma), np.sin(gamma), 0.0])
        fi, _, fu = fixed
        u0 = self.R0 @ self.u_body
        self.n = [u0, u0] if fu else [v / np.linalg.norm(v) for v in rng.normal(size=(2, 3))]
        self.th = rng.normal(size=(2, 3))                    # th_k(t) = c0 + c1 t + c2 t^2
        self.ri = rng.normal(size=(3, 3)) * (np.array([[1], [0], [0]]) if fi else 1.0)
        self.t = rng.uniform(0.2, 0.8)

    def rotation(self):
        """R, R', R'' at time t."""
        parts = []
        for n, (c0, c1, c2) in zip(self.n, self.th):
            th, dth, ddth = c0 + c1 * self.t + c2 * self.t ** 2, c1 + 2 * c2 * self.t, 2 * c2
            A, K = rot(n, th), skew(n)
            parts.append((A, dth * K @ A, ddth * K @ A + dth ** 2 * K @ K @ A))
        (A, dA, ddA), (C, dC, ddC) = parts
        return (A @ C @ self.R0, (dA @ C + A @ dC) @ self.R0,
                (ddA @ C + 2 * dA @ dC + A @ ddC) @ self.R0)

    def triples(self):
        """Per triple ri, rj, u: (position, speed, acceleration)."""
        R, dR, ddR = self.rotation()
        t = self.t
        c0, c1, c2 = self.ri
        ri = (c0 + c1 * t + c2 * t * t, c1 + 2 * c2 * t, 2 * c2)
        ex = np.array([self.l, 0.0, 0.0])
        rj = tuple(a + Rk @ ex for a, Rk in zip(ri, (R, dR, ddR)))
        u = tuple(Rk @ self.u_body for Rk in (R, dR, ddR))
        return ri, rj, u


def vee(W):
    return np.array([W[2, 1], W[0, 2], W[1, 0]])


def body_point_rho(rng, cls, alpha, beta):
    """A random body point whose coefficients honour the class's structural zeros."""
    rho = rng.normal(size=3)
    prefix = "a" if cls.kind == "body" else "b"
    if f"{prefix}2" in cls.zeros:
        rho[1] = 0.0
    if f"{prefix}3" in cls.zeros:
        rho[2] = 0.0
    if f"{prefix}1" in cls.zeros:
        rho[0] = rho[1] * beta / alpha
    return rho


def rigid_case(cls, seed):
    """Local q, q', q'' and params consistent with a rigid motion, its R, w, alpha,
    the motion of r_i and the body point rho (mass centre or load point)."""
    rng = np.random.default_rng(seed)
    p = random_params(cls, rng)
    names = cls.param_names
    l = rng.uniform(0.5, 2.0)
    gamma = np.pi / 2 if "beta" in cls.zeros else rng.uniform(0.4, 2.5)
    alpha, beta = np.sin(gamma), (0.0 if "beta" in cls.zeros else np.cos(gamma))
    motion = RigidMotion(rng, cls.fixed, l, gamma)
    for key, val in (("l", l), ("alpha", alpha), ("beta", beta)):
        p[names.index(key)] = val
    coef = ("a1", "a2", "a3") if cls.kind == "body" else ("b1", "b2", "b3")
    rho = np.zeros(3)
    if cls.kind != "torque":
        rho = body_point_rho(rng, cls, alpha, beta)
        for key, val in zip(coef, point_coefficients(rho, l, alpha, beta)):
            p[names.index(key)] = val
    trip = dict(zip(("ri", "rj", "u"), motion.triples()))
    q, dq, ddq = ([trip[n][k] for n in cls.moving_triples] for k in range(3))
    for n, fixed in zip(("ri", "rj", "u"), cls.fixed):
        if fixed:
            start = names.index(f"{n}.x")
            p[start:start + 3] = trip[n][0]
            assert np.allclose(trip[n][1], 0) and np.allclose(trip[n][2], 0)
    R, dR, ddR = motion.rotation()
    w, acc = vee(dR @ R.T), vee(ddR @ R.T + dR @ dR.T)
    return (np.concatenate(q), np.concatenate(dq), np.concatenate(ddq), p, R, w, acc,
            trip["ri"], rho)


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.kind == "body"], ids=lambda c: c.name)
def test_body_inertia_forces_on_a_known_rigid_motion(cls):
    """M q'' + h = Dhat^T m a_G + Phi^T (I_G alpha + w x I_G w) with a_G, w, alpha of
    the motion itself (Phi = R Phi_b global, I_G = R I_b R^T)."""
    q, dq, ddq, p, R, w, alpha, ri, rho = rigid_case(cls, 6)
    k = element_kernels(cls, q, dq, p)
    m = p[cls.param_names.index("m")]
    I_G = R @ k.inertia @ R.T
    a_G = ri[2] + np.cross(alpha, R @ rho) + np.cross(w, np.cross(w, R @ rho))
    expected = (m * k.dhat.T @ a_G
                + (R @ k.phi_b).T @ (I_G @ alpha + np.cross(w, I_G @ w)))
    M = kernel(cls, "mass_matrix", q, dq, p).reshape(cls.n_q, cls.n_q)
    got = M @ ddq + kernel(cls, "h_vector", q, dq, p)
    # one rounding-level evaluation on each side of O(1-10) numbers
    assert np.allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max() + 1e-13)
    out = kernel(cls, "body_outputs", q, dq, p)
    assert np.allclose(out[:3], ri[0] + R @ rho, atol=1e-13)      # mass centre
    assert np.allclose(out[3:], w, atol=1e-13)                     # angular velocity
    v_G = ri[1] + np.cross(w, R @ rho)
    kinetic = 0.5 * m * v_G @ v_G + 0.5 * w @ I_G @ w
    assert kernel(cls, "energy", q, dq, p)[0] == pytest.approx(kinetic, rel=1e-13)


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.kind in ("force", "torque")],
                         ids=lambda c: c.name)
def test_load_power_on_a_known_rigid_motion(cls):
    """f . q' = F . v_P for a force at body point P, T . w for a torque."""
    q, dq, _, p, R, w, _, ri, rho = rigid_case(cls, 7)
    s = dict(zip(cls.param_names, p))
    f = kernel(cls, "applied_forces", q, dq, p)
    if cls.kind == "force":
        power = np.array([s["Fx"], s["Fy"], s["Fz"]]) @ (ri[1] + np.cross(w, R @ rho))
    else:
        power = np.array([s["Tx"], s["Ty"], s["Tz"]]) @ w
    assert f @ dq == pytest.approx(power, rel=1e-12, abs=1e-13)   # rounding only


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.kind == "body"], ids=lambda c: c.name)
def test_constraints_vanish_on_a_rigid_motion(cls):
    q, dq, ddq, p, *_ = rigid_case(cls, 8)
    g = kernel(cls, "constraints", q, dq, p)
    B = kernel(cls, "constraint_jacobian", q, dq, p).reshape(cls.n_g, cls.n_q)
    bias = kernel(cls, "constraint_bias", q, dq, p)
    assert np.allclose(g, 0, atol=1e-13)           # l^2 - l^2 and l beta - l beta
    assert np.allclose(B @ dq, 0, atol=1e-13)      # the motion's speeds are tangent
    assert np.allclose(B @ ddq + bias, 0, atol=1e-12)   # and its accelerations too


def test_unit_vector_by_hand():
    cls = ElementClass("unit_vector", (), (F,), frozenset())
    u, du = np.array([0.6, 0.0, 0.8]), np.array([1.0, 2.0, -0.75])
    assert kernel(cls, "constraints", u, du, []) == pytest.approx([0.0], abs=1e-15)
    assert np.allclose(kernel(cls, "constraint_jacobian", u, du, []), 2 * u)
    assert kernel(cls, "constraint_bias", u, du, [])[0] == pytest.approx(2 * du @ du)


def test_wrong_sizes_are_reported():
    cls = CLASSES[0]
    with pytest.raises(ValueError, match="expected q, v of size 9"):
        kernel(cls, "mass_matrix", np.zeros(6), None, np.zeros(cls.n_p))
