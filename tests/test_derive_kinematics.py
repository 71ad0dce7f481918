"""Symbolic body kinematics (fccgen.derive.kinematics) against a known rigid motion.

The motion: a pivot point (i, or j when only j is fixed) moves on a parabola or stays
put, and the body turns with R(t) = exp(t ~a) exp(t^2/2 ~b) R0, whose angular velocity
w = a + t A(t) b and angular acceleration w' = A b + a x (t A b) are exact
(A = exp(t ~a)). Points i, j and the vector u are fixed in the body. Derivatives are
checked against central differences in time of positions and angular velocities
computed from the motion alone.
"""
import functools

import numpy as np
import pytest
import sympy
from scipy.spatial.transform import Rotation

from fccgen.derive.kinematics import body_frame
from fccgen.derive.symbols import class_symbols
from fccgen.plan.classes import ElementClass
from fccgen.model.geometry import body_frame_numbers, body_rotation, point_coefficients


def _rot(vec):
    return Rotation.from_rotvec(vec).as_matrix()


class RigidMotion:
    """A rigid motion of a body with points i, j and unit vector u.

    ``fixed`` (ri, rj, u) pins what must not move: a fixed ri or rj keeps that point
    still, a fixed u (or fixed ri and rj) turns the body about a fixed axis only.
    """

    def __init__(self, rng, fixed):
        fi, fj, fu = fixed
        self.R0 = Rotation.random(random_state=rng).as_matrix()
        self.sj = rng.uniform(-1, 1, 3) + np.array([1.5, 0, 0])   # r_ij in the motion frame
        self.uh = rng.normal(size=3)
        self.uh /= np.linalg.norm(self.uh)
        self.a, self.b = rng.normal(size=3), rng.normal(size=3)
        axis = self.R0 @ (self.uh if fu else self.sj / np.linalg.norm(self.sj))
        if fu or (fi and fj):               # turn about the fixed axis only
            self.a, self.b = rng.normal() * axis, rng.normal() * axis
        self.c = [rng.normal(size=3) for _ in range(3)]   # pivot: c0 + c1 t + c2 t^2/2
        self.pivot_j = fj and not fi        # r_j is the fixed point, r_i moves about it
        if fi or fj:
            self.c[1] = self.c[2] = np.zeros(3)

    def rotation(self, t):
        """R(t), angular velocity w(t) and angular acceleration w'(t), global frame."""
        A, B = _rot(t * self.a), _rot(t * t / 2 * self.b)
        spin = t * A @ self.b
        return A @ B @ self.R0, self.a + spin, A @ self.b + np.cross(self.a, spin)

    def anchor(self, t):
        """Position, velocity, acceleration of the pivot point (i, or j when j is fixed)."""
        c0, c1, c2 = self.c
        return c0 + c1 * t + c2 * t * t / 2, c1 + c2 * t, c2

    def body_vector(self, t, s):
        """Position, velocity and acceleration of a body vector s (motion frame)."""
        R, w, wd = self.rotation(t)
        x = R @ s
        return x, np.cross(w, x), np.cross(wd, x) + np.cross(w, np.cross(w, x))

    def point(self, t, s):
        """A body point at s (motion frame, from point i): the pivot plus R (s - s_pivot)."""
        ref = self.sj if self.pivot_j else np.zeros(3)
        return tuple(b + y for b, y in zip(self.anchor(t), self.body_vector(t, s - ref)))

    def triples(self, t):
        """(pos, vel, acc) of ri, rj and u at time t."""
        return (self.point(t, np.zeros(3)), self.point(t, self.sj),
                self.body_vector(t, self.uh))


VARIANTS = [(False, False, False), (True, False, False), (False, True, False),
            (True, False, True), (False, False, True), (True, True, False)]


@functools.lru_cache(maxsize=None)
def _setup(fixed):
    """Motion, symbolic frame and numeric functions of a body class with a fixed mask
    (built once per mask: lambdify is the slow part)."""
    rng = np.random.default_rng(sum(2 ** k for k, f in enumerate(fixed) if f))
    motion = RigidMotion(rng, fixed)
    cls = ElementClass("body", (), tuple(fixed), frozenset())
    s = class_symbols(cls)
    f = body_frame(s)
    cg = f.point(s.scalar("a1"), s.scalar("a2"), s.scalar("a3"))
    exprs = {"phi_b": s.local(f.phi_b, 3), "w_b": f.w_b, "c_w": f.c_w, "w": f.w,
             "R": f.R, "pos": cg.pos, "dhat": s.local(cg.dhat, 3), "bias": cg.bias,
             "vel": cg.vel}
    fns = {k: sympy.lambdify((s.q, s.v, s.p), e, modules="numpy", cse=True)
           for k, e in exprs.items()}
    rho = rng.uniform(-1, 1, 3)
    return motion, cls, fns, rho


def _state(cls, motion, rho, t):
    """Local q, q', q'' and parameters at time t (frame numbers from the positions)."""
    tr = motion.triples(t)
    l, alpha, beta = body_frame_numbers(tr[0][0], tr[1][0], tr[2][0])
    a = point_coefficients(rho, l, alpha, beta)
    scal = dict(zip(("l", "alpha", "beta", "a1", "a2", "a3"), (l, alpha, beta, *a)))
    p = [scal.get(n, 0.0) for n in cls.scalar_names]
    q, v, acc = [], [], []
    for (pos, vel, ac), fixed in zip(tr, cls.fixed):
        if fixed:
            p += list(pos)
        else:
            q += list(pos)
            v += list(vel)
            acc += list(ac)
    return tuple(map(np.asarray, (q, v, acc, p)))


def _ev(fn, q, v, p):
    return np.asarray(fn(q, v, p), float).reshape(-1)


def _global_point(motion, rho, t):
    """The body point at rho (body frame from point i) computed from the motion."""
    tr = motion.triples(t)
    return tr[0][0] + body_rotation(tr[0][0], tr[1][0], tr[2][0]) @ rho


@pytest.mark.parametrize("fixed", VARIANTS)
def test_fixed_triples_stay_put(fixed):
    """The test motion itself: fixed triples do not move (1e-14: rounding of O(1) values)."""
    motion = RigidMotion(np.random.default_rng(1), fixed)
    for k, (pos, vel, acc) in enumerate(motion.triples(0.3)):
        if fixed[k]:
            assert np.allclose(pos, motion.triples(-0.2)[k][0], rtol=0, atol=1e-14)
            assert np.max(abs(vel)) < 1e-14 and np.max(abs(acc)) < 1e-14


@pytest.mark.parametrize("fixed", VARIANTS)
def test_angular_velocity(fixed):
    """Phi_b q' is the body-frame angular velocity; R w_b the global one (1e-9 relative:
    exact formulas, rounding only)."""
    motion, cls, fns, rho = _setup(fixed)
    for t in (0.0, 0.37, -0.8):
        q, v, _, p = _state(cls, motion, rho, t)
        tr = motion.triples(t)
        E = body_rotation(tr[0][0], tr[1][0], tr[2][0])
        w = motion.rotation(t)[1]
        wb = _ev(fns["phi_b"], q, v, p).reshape(3, -1) @ v
        assert np.allclose(wb, E.T @ w, rtol=0, atol=1e-9 * np.linalg.norm(w))
        assert np.allclose(_ev(fns["w_b"], q, v, p), wb, rtol=0, atol=1e-12 * np.linalg.norm(w))
        assert np.allclose(_ev(fns["w"], q, v, p), w, rtol=0, atol=1e-9 * np.linalg.norm(w))
        R = _ev(fns["R"], q, v, p).reshape(3, 3)
        assert np.allclose(R, E, rtol=0, atol=1e-12)   # orthonormal on the manifold


@pytest.mark.parametrize("fixed", VARIANTS)
def test_point_position_and_velocity(fixed):
    """r = ri + E rho (1e-12: rounding); Dhat q' = central difference of r(t)
    (h = 1e-5: truncation h^2 |r'''|/6 ~ 1e-9, tolerance 1e-8 relative)."""
    motion, cls, fns, rho = _setup(fixed)
    h, t = 1e-5, 0.25
    q, v, _, p = _state(cls, motion, rho, t)
    assert np.allclose(_ev(fns["pos"], q, v, p), _global_point(motion, rho, t), rtol=0,
                       atol=1e-12)
    fd = (_global_point(motion, rho, t + h) - _global_point(motion, rho, t - h)) / (2 * h)
    dhat = _ev(fns["dhat"], q, v, p).reshape(3, -1)
    scale = np.linalg.norm(fd)
    assert np.allclose(dhat @ v, fd, rtol=0, atol=1e-8 * scale)
    assert np.allclose(_ev(fns["vel"], q, v, p), dhat @ v, rtol=0, atol=1e-13 * scale)


@pytest.mark.parametrize("fixed", VARIANTS)
def test_point_acceleration_bias(fixed):
    """Dhat q'' + bias = second derivative of r(t) by the five-point central stencil
    (h = 3e-3: truncation h^4 |r^(6)|/90 ~ 1e-9, rounding 64 eps/(12 h^2) ~ 1e-10;
    tolerance 1e-7 relative)."""
    motion, cls, fns, rho = _setup(fixed)
    h, t = 3e-3, -0.4
    r = [_global_point(motion, rho, t + k * h) for k in (-2, -1, 0, 1, 2)]
    fd = (-r[0] + 16 * r[1] - 30 * r[2] + 16 * r[3] - r[4]) / (12 * h ** 2)
    q, v, acc, p = _state(cls, motion, rho, t)
    dhat = _ev(fns["dhat"], q, v, p).reshape(3, -1)
    a = dhat @ acc + _ev(fns["bias"], q, v, p)
    assert np.allclose(a, fd, rtol=0, atol=1e-7 * np.linalg.norm(fd))


@pytest.mark.parametrize("fixed", VARIANTS)
def test_angular_acceleration_bias(fixed):
    """Phi_b q'' + c_w = d/dt of the body-frame angular velocity E^T w (central
    difference, h = 1e-4: truncation ~1e-9, tolerance 1e-7 relative), and
    R (Phi_b q'' + c_w) is the known angular acceleration (1e-9: exact formulas)."""
    motion, cls, fns, rho = _setup(fixed)
    h, t = 1e-4, 0.6

    def w_body(tt):
        tr = motion.triples(tt)
        return body_rotation(tr[0][0], tr[1][0], tr[2][0]).T @ motion.rotation(tt)[1]

    fd = (w_body(t + h) - w_body(t - h)) / (2 * h)
    q, v, acc, p = _state(cls, motion, rho, t)
    phi = _ev(fns["phi_b"], q, v, p).reshape(3, -1)
    wbd = phi @ acc + _ev(fns["c_w"], q, v, p)
    scale = max(np.linalg.norm(fd), 1e-300)
    assert np.allclose(wbd, fd, rtol=0, atol=1e-7 * scale)
    R = _ev(fns["R"], q, v, p).reshape(3, 3)
    wd = motion.rotation(t)[2]
    assert np.allclose(R @ wbd, wd, rtol=0, atol=1e-9 * np.linalg.norm(wd))
