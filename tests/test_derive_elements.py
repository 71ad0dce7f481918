"""Kernels of every element kind (fccgen.derive) against finite differences and
against numbers computed independently from a consistent rigid-body state.

A state is sampled per class: every body (the element's own, or the body of a
body-point end) is a rigid body at a random pose with random angular velocity and
acceleration, its frame numbers l, alpha, beta come from fccgen.model.geometry, and a
body point is placed by body-frame coordinates rho (point i + E rho).
"""
import functools
import time
from dataclasses import dataclass

import numpy as np
import pytest
import sympy
from scipy.spatial.transform import Rotation

from fccgen.derive import derive_class
from fccgen.plan.classes import BODY_TRIPLES, KIND_ENDS, KIND_TRIPLES, ElementClass
from fccgen.model.geometry import body_frame_numbers, body_rotation, point_coefficients
from fccgen.plan.kernels import KERNEL_NAMES, KERNELS

BP, PT = "body_point", "point"


def C(kind, ends=(), fixed=(), zeros=()):
    """An element class with the named triples fixed and the named scalars folded."""
    names = list(KIND_TRIPLES[kind])
    for end, end_kind in zip(KIND_ENDS[kind], ends):
        names += [f"{end}.{t}" for t in BODY_TRIPLES] if end_kind == BP else [f"{end}.r"]
    return ElementClass(kind, tuple(ends), tuple(n in fixed for n in names), frozenset(zeros))


BODIES = [C("body"), C("body", fixed={"ri"}), C("body", fixed={"rj"}),
          C("body", fixed={"ri", "u"}), C("body", fixed={"u"}), C("body", fixed={"ri", "rj"}),
          C("body", zeros={"beta", "a2", "a3", "Ixy", "Ixz", "Iyz", "gx", "gy"}),
          C("body", fixed={"ri"}, zeros={"a1", "a2", "a3", "gx", "gy", "gz"})]
CONSTRAINTS = [C("unit_vector"),
               C("distance", (PT, PT)), C("distance", (PT, PT), fixed={"A.r"}),
               C("distance", (PT, BP)),
               C("distance", (BP, BP), fixed={"A.ri"}, zeros={"B.b3", "A.beta"}),
               C("point_on_line", (PT, PT, PT)),
               C("point_on_line", (PT, PT, PT), fixed={"A.r", "B.r"}),
               C("point_on_line", (BP, PT, PT), fixed={"A.r"}),
               C("point_on_line", (PT, BP, BP), fixed={"B.u"})]
LOADS = [C("force"), C("force", fixed={"ri"}, zeros={"b2", "b3", "Fz"}),
         C("torque"), C("torque", fixed={"ri"}), C("torque", zeros={"beta", "Tx"}),
         C("spring", (PT, PT), zeros={"c"}), C("spring", (PT, PT)),
         C("spring", (PT, BP), fixed={"A.r"}), C("spring", (BP, BP), zeros={"L0"}),
         C("spring", (BP, PT), zeros={"L0", "c"})]
ALL = BODIES + CONSTRAINTS + LOADS


def _id(cls):
    return cls.describe().replace(" ", "")


@dataclass
class Rigid:
    """A consistent instant of a rigid body: triples (pos, vel, acc) of ri, rj, u."""
    triples: tuple
    w: np.ndarray
    wd: np.ndarray
    E: np.ndarray
    frame: tuple

    def point(self, rho):
        """(pos, vel, acc) of the body point at body-frame rho from point i."""
        (ri, vi, ai), x = self.triples[0], self.E @ rho
        return (ri + x, vi + np.cross(self.w, x),
                ai + np.cross(self.wd, x) + np.cross(self.w, np.cross(self.w, x)))


def rigid_state(rng, fixed, perpendicular=False) -> Rigid:
    """Random consistent state; a fixed ri/rj is still, a fixed u (or fixed ri and rj)
    allows rotation about that axis only; u is normal to r_ij when ``perpendicular``."""
    fi, fj, fu = fixed
    R = Rotation.random(random_state=rng).as_matrix()
    sj = rng.uniform(-1, 1, 3) + np.array([1.5, 0.0, 0.0])
    uh = rng.normal(size=3)
    if perpendicular:
        uh -= (uh @ sj) / (sj @ sj) * sj
    rij, u = R @ sj, R @ (uh / np.linalg.norm(uh))
    w, wd = rng.normal(size=3), rng.normal(size=3)
    axis = u if fu else rij / np.linalg.norm(rij) if fi and fj else None
    if axis is not None:
        w, wd = (w @ axis) * axis, (wd @ axis) * axis
    if fu and fi and fj:
        w, wd = np.zeros(3), np.zeros(3)

    def motion(x):
        return x, np.cross(w, x), np.cross(wd, x) + np.cross(w, np.cross(w, x))

    ri = rng.normal(size=3)
    vi, ai = rng.normal(size=3), rng.normal(size=3)
    if fi:
        vi, ai = np.zeros(3), np.zeros(3)
    elif fj:
        vi, ai = -motion(rij)[1], -motion(rij)[2]
    rj = tuple(a + b for a, b in zip((ri, vi, ai), motion(rij)))
    return Rigid(((ri, vi, ai), rj, motion(u)), w, wd, body_rotation(ri, rj[0], u),
                 body_frame_numbers(ri, rj[0], u))


@dataclass
class Scene:
    """Numbers of every triple and scalar of a class, and the independent truths."""
    triples: dict
    scalars: dict
    bodies: dict        # prefix ("" or "A.") -> Rigid
    rho: dict           # prefix -> body-frame coordinates of the element's body point
    ends: dict          # end name -> (pos, vel, acc) of that end's point


def _place(scene, cls, prefix, names, rng):
    """Coefficients b of a random body point, folded ones set to 0, and its rho:
    r_ij = l e1 and u = beta e1 + alpha e2 give r = ri + E (l b1 + beta b2, alpha b2, b3)."""
    l, alpha, beta = scene.bodies[prefix].frame
    b = list(point_coefficients(rng.uniform(-1, 1, 3), l, alpha, beta))
    b = [0.0 if n in cls.zeros else x for n, x in zip(names, b)]
    scene.scalars.update(zip(names, b))
    scene.rho[prefix] = np.array([l * b[0] + beta * b[1], alpha * b[1], b[2]])


# Positive where physics asks (mass, principal inertia, stiffness, lengths, damping);
# small products of inertia keep the tensor positive definite.
SCALAR_RANGES = {**dict.fromkeys(("m", "Ixx", "Iyy", "Izz", "k", "L0", "L"), (1.0, 2.0)),
                 **dict.fromkeys(("Ixy", "Ixz", "Iyz"), (-0.2, 0.2)), "c": (0.1, 0.5)}


def sample(cls, seed=0) -> Scene:
    """A consistent random state of every triple and scalar of ``cls``."""
    rng = np.random.default_rng(seed)
    fixed = dict(zip(cls.triple_names, cls.fixed))
    sc = Scene({}, {}, {}, {}, {})
    own = [""] if cls.kind in ("body", "force", "torque") else []
    ends = list(zip(KIND_ENDS[cls.kind], cls.ends))
    for g in own + [f"{e}." for e, k in ends if k == BP]:
        body = rigid_state(rng, tuple(fixed[g + t] for t in BODY_TRIPLES),
                           perpendicular=g + "beta" in cls.zeros)
        sc.bodies[g] = body
        sc.triples.update({g + t: x for t, x in zip(BODY_TRIPLES, body.triples)})
        sc.scalars.update(zip((g + "l", g + "alpha", g + "beta"), body.frame))
        if g:
            _place(sc, cls, g, [f"{g}b1", f"{g}b2", f"{g}b3"], rng)
            sc.ends[g[:-1]] = body.point(sc.rho[g])
    if cls.kind in ("body", "force"):
        _place(sc, cls, "", ["a1", "a2", "a3"] if cls.kind == "body" else ["b1", "b2", "b3"],
               rng)
    for e, k in ends:
        if k == PT:
            moving = not fixed[f"{e}.r"]
            sc.triples[f"{e}.r"] = sc.ends[e] = (rng.normal(size=3),
                                                 rng.normal(size=3) * moving,
                                                 rng.normal(size=3) * moving)
    if cls.kind == "unit_vector":
        sc.triples["u"] = rigid_state(rng, (False,) * 3).triples[2]
    for n in cls.scalar_names:
        if n not in sc.scalars:
            low, high = SCALAR_RANGES.get(n, (-1.0, 1.0))
            sc.scalars[n] = rng.uniform(low, high)
        if n in cls.zeros:
            sc.scalars[n] = 0.0
    return sc


def pack(cls, sc: Scene):
    """Local q, v, q'' and parameters p of a scene (layouts of fccgen.plan.classes)."""
    p = [sc.scalars[n] for n in cls.scalar_names]
    q, v, a = [], [], []
    for name, fixed in zip(cls.triple_names, cls.fixed):
        pos, vel, acc = sc.triples[name]
        if fixed:
            p += list(pos)
        else:
            q, v, a = q + list(pos), v + list(vel), a + list(acc)
    return tuple(np.array(x, float) for x in (q, v, a, p))


@functools.lru_cache(maxsize=None)
def compiled(cls):
    """The derived class and one numeric function (q, v, p) -> outputs per kernel."""
    d = derive_class(cls)
    fns = {name: sympy.lambdify((d.q, d.v, d.p), list(m), modules="numpy", cse=True)
           for name, m in d.kernels.items() if m is not None}
    sizes = {k.name: k.size(cls) for k in KERNELS}

    def ev(name, q, v, p):
        if name not in fns:
            return np.zeros(sizes[name])
        return np.array(fns[name](q, v, p), float)
    return d, ev


def fd(fun, x, h):
    """Central-difference Jacobian of fun at x (columns per coordinate)."""
    cols = []
    for k in range(len(x)):
        dx = np.zeros(len(x))
        dx[k] = h
        cols.append((fun(x + dx) - fun(x - dx)) / (2 * h))
    return np.array(cols).T


@pytest.mark.parametrize("cls", ALL, ids=_id)
def test_layout_and_symbols(cls):
    """Symbol names and counts, output sizes, no v in q-only kernels, folded
    scalars absent, mass matrix structurally symmetric."""
    d, _ = compiled(cls)
    assert [s.name for s in d.q] == [f"q{k}" for k in range(cls.n_q)]
    assert [s.name for s in d.v] == [f"v{k}" for k in range(cls.n_q)]
    assert [s.name for s in d.p] == [f"p{k}" for k in range(cls.n_p)]
    assert set(d.kernels) == set(KERNEL_NAMES)
    folded = {d.p[cls.param_names.index(n)] for n in cls.zeros}
    for spec in KERNELS:
        m = d.kernels[spec.name]
        if m is None:
            continue
        assert m.shape == (spec.size(cls), 1)
        free = m.free_symbols
        assert free <= set(d.q) | set(d.v) | set(d.p)
        assert not free & folded
        if not spec.uses_v:
            assert not free & set(d.v), spec.name
    M = d.kernels["mass_matrix"]
    if M is not None:
        M = M.reshape(cls.n_q, cls.n_q)
        assert all(M[i, j] == M[j, i] for i in range(cls.n_q) for j in range(i))


@pytest.mark.parametrize("cls", [c for c in ALL if c.n_g and c.n_q], ids=_id)
def test_constraint_jacobian_and_bias(cls):
    """B = dg/dq and (dB/dt) v by central differences (h = 1e-6; g is a polynomial of
    degree <= 4, so truncation ~1e-11 and rounding ~1e-10: tolerance 1e-7 relative,
    the bias scale floored at 1e-3 for rows that nearly vanish)."""
    _, ev = compiled(cls)
    q, v, _, p = pack(cls, sample(cls, 1))

    def jac(x):
        return ev("constraint_jacobian", x, v, p).reshape(cls.n_g, cls.n_q)

    B_fd = fd(lambda x: ev("constraints", x, v, p), q, 1e-6)
    assert np.allclose(jac(q), B_fd, rtol=0, atol=1e-7 * np.abs(B_fd).max())
    bias_fd = (jac(q + 1e-6 * v) @ v - jac(q - 1e-6 * v) @ v) / 2e-6
    bias = ev("constraint_bias", q, v, p)
    assert np.allclose(bias, bias_fd, rtol=0, atol=1e-7 * max(np.abs(bias_fd).max(), 1e-3))


@pytest.mark.parametrize("cls", [c for c in ALL if c.n_g], ids=_id)
def test_constraint_values(cls):
    """g at a consistent state: zero for a rigid body and a unit vector; the distance
    and point-on-line residuals of the independently placed points (1e-11: rounding
    of O(10) values)."""
    sc = sample(cls, 2)
    q, v, _, p = pack(cls, sc)
    g = compiled(cls)[1]("constraints", q, v, p)
    if cls.kind == "distance":
        expect = [np.sum((sc.ends["B"][0] - sc.ends["A"][0]) ** 2) - sc.scalars["L"] ** 2]
    elif cls.kind == "point_on_line":
        rk, ra, rb = (sc.ends[e][0] for e in "KAB")
        expect = np.cross(rk - ra, rb - ra)
    else:
        expect = np.zeros(cls.n_g)
    assert np.allclose(g, expect, rtol=0, atol=1e-11)


# -- bodies -------------------------------------------------------------------------

def _point_formula(qb, frame, b):
    """r = ri + b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l) (the FCC point off the manifold)."""
    l, alpha, _ = frame
    ri, rj, u = qb[:3], qb[3:6], qb[6:]
    return ri + b[0] * (rj - ri) + b[1] * u + b[2] / (alpha * l) * np.cross(rj - ri, u)


def _omega_definition(qb, vb, frame):
    """w = e1 (e2'.e3) + e2 (e3'.e1) + e3 (e1'.e2) (seed eq. 13), frame numbers given."""
    l, alpha, beta = frame
    rij, u, rd, ud = qb[3:6] - qb[:3], qb[6:], vb[3:6] - vb[:3], vb[6:]
    e1, e1d = rij / l, rd / l
    e2, e2d = (u - beta * e1) / alpha, (ud - beta * e1d) / alpha
    e3 = np.cross(rij, u) / (alpha * l)
    e3d = (np.cross(rd, u) + np.cross(rij, ud)) / (alpha * l)
    return e1 * (e2d @ e3) + e2 * (e3d @ e1) + e3 * (e1d @ e2)


def _body_truth(cls, sc):
    """Full q_B, moving mask, and the centre-of-mass motion of the element's body."""
    body = sc.bodies[""]
    qb = np.concatenate([t[0] for t in body.triples])
    mask = np.repeat(~np.array(cls.fixed), 3)
    return body, qb, mask, body.point(sc.rho[""])


def _inertia(sc):
    s = sc.scalars
    return np.array([[s["Ixx"], s["Ixy"], s["Ixz"]], [s["Ixy"], s["Iyy"], s["Iyz"]],
                     [s["Ixz"], s["Iyz"], s["Izz"]]])


@pytest.mark.parametrize("cls", BODIES, ids=_id)
def test_body_mass_matrix_and_energy(cls):
    """M symmetric PSD (three zero eigenvalues for a free body, 1e-10 of the largest:
    rounding); v^T M v / 2 = kinetic energy kernel (1e-12) = m |v_G|^2/2 + w.I_G w/2
    from the rigid state (1e-10: rounding in the frame numbers)."""
    _, ev = compiled(cls)
    sc = sample(cls, 3)
    q, v, _, p = pack(cls, sc)
    body, _, _, (_, vg, _) = _body_truth(cls, sc)
    M = ev("mass_matrix", q, v, p).reshape(cls.n_q, cls.n_q)
    assert np.array_equal(M, M.T)
    lam = np.linalg.eigvalsh(M)
    assert lam[0] > -1e-10 * lam[-1]
    if not any(cls.fixed):
        assert np.all(np.abs(lam[:3]) < 1e-10 * lam[-1]) and lam[3] > 1e-6 * lam[-1]
    kin = ev("energy", q, v, p)[0]
    assert kin == pytest.approx(v @ M @ v / 2, rel=1e-12)
    I_g = body.E @ _inertia(sc) @ body.E.T
    m = sc.scalars["m"]
    assert kin == pytest.approx(m * vg @ vg / 2 + body.w @ I_g @ body.w / 2, rel=1e-10)


@pytest.mark.parametrize("cls", BODIES, ids=_id)
def test_body_equation_of_motion(cls):
    """M q'' + h = Dhat^T m a_G + Phi^T (I_G w' + w x I_G w) for the known rigid
    accelerations; Dhat by central differences of the point formula (exact for a
    bilinear map up to rounding) and Phi from the definition of w (1e-9 relative)."""
    _, ev = compiled(cls)
    sc = sample(cls, 4)
    q, v, a, p = pack(cls, sc)
    body, qb, mask, (_, _, ag) = _body_truth(cls, sc)
    b = [sc.scalars[n] for n in ("a1", "a2", "a3")]
    dhat = fd(lambda x: _point_formula(x, body.frame, b), qb, 1e-6)[:, mask]
    phi = np.array([_omega_definition(qb, e, body.frame) for e in np.eye(9)]).T[:, mask]
    I_g = body.E @ _inertia(sc) @ body.E.T
    moment = I_g @ body.wd + np.cross(body.w, I_g @ body.w)
    rhs = dhat.T @ (sc.scalars["m"] * ag) + phi.T @ moment
    M = ev("mass_matrix", q, v, p).reshape(cls.n_q, cls.n_q)
    lhs = M @ a + ev("h_vector", q, v, p)
    assert np.allclose(lhs, rhs, rtol=0, atol=1e-9 * np.abs(rhs).max())


@pytest.mark.parametrize("cls", BODIES, ids=_id)
def test_body_gravity_and_outputs(cls):
    """f = -grad(potential) (central differences of a quadratic: 1e-8 relative);
    potential -m g.r_G and body_outputs [r_G, w] match the rigid state (1e-10)."""
    _, ev = compiled(cls)
    sc = sample(cls, 5)
    q, v, _, p = pack(cls, sc)
    body, _, _, (rg, _, _) = _body_truth(cls, sc)
    grav = np.array([sc.scalars[n] for n in ("gx", "gy", "gz")])
    f = ev("applied_forces", q, v, p)
    grad = fd(lambda x: ev("energy", x, v, p)[1:], q, 1e-5)[0]
    assert np.allclose(f, -grad, rtol=0, atol=1e-8 * max(np.abs(f).max(), 1.0))
    assert ev("energy", q, v, p)[1] == pytest.approx(-sc.scalars["m"] * grav @ rg,
                                                     rel=1e-10, abs=1e-12)
    assert np.allclose(ev("body_outputs", q, v, p), np.concatenate([rg, body.w]),
                       rtol=0, atol=1e-10)


# -- loads --------------------------------------------------------------------------

@pytest.mark.parametrize("cls", [c for c in LOADS if c.kind in ("force", "spring")], ids=_id)
def test_load_is_minus_gradient_of_potential(cls):
    """Force and undamped part of a spring: f = -dV/dq (central differences, h = 1e-6;
    tolerance 1e-7 relative), with V from the independently placed points (1e-12)."""
    _, ev = compiled(cls)
    sc = sample(cls, 6)
    q, v, _, p = pack(cls, sc)
    s = sc.scalars
    if cls.kind == "force":
        F = np.array([s["Fx"], s["Fy"], s["Fz"]])
        expect_v = -F @ sc.bodies[""].point(sc.rho[""])[0]
    else:
        length = np.linalg.norm(sc.ends["B"][0] - sc.ends["A"][0])
        expect_v = s["k"] * (length - s["L0"]) ** 2 / 2
    assert ev("energy", q, v, p)[1] == pytest.approx(expect_v, rel=1e-12, abs=1e-12)
    v0 = np.zeros_like(v)          # no damping force at rest
    f = ev("applied_forces", q, v0, p)
    grad = fd(lambda x: ev("energy", x, v0, p)[1:], q, 1e-6)[0]
    assert np.allclose(f, -grad, rtol=0, atol=1e-7 * max(np.abs(f).max(), 1.0))


@pytest.mark.parametrize("cls", [c for c in LOADS if c.kind in ("torque", "spring")], ids=_id)
def test_load_power(cls):
    """f . v is the power of the load for consistent speeds: T . w for a torque,
    -(k (L - L0) + c L') L' for a spring with L' from the end velocities (1e-10)."""
    _, ev = compiled(cls)
    sc = sample(cls, 7)
    q, v, _, p = pack(cls, sc)
    s = sc.scalars
    if cls.kind == "torque":
        expect = np.array([s["Tx"], s["Ty"], s["Tz"]]) @ sc.bodies[""].w
    else:
        d = sc.ends["B"][0] - sc.ends["A"][0]
        length = np.linalg.norm(d)
        rate = d @ (sc.ends["B"][1] - sc.ends["A"][1]) / length
        expect = -(s["k"] * (length - s["L0"]) + s["c"] * rate) * rate
    assert ev("applied_forces", q, v, p) @ v == pytest.approx(expect, rel=1e-10, abs=1e-12)


# -- structure ----------------------------------------------------------------------

def _present(cls):
    d = derive_class(cls)
    return {k for k, m in d.kernels.items() if m is not None}, d


def test_structural_zeros_drop_kernels():
    """Kernels that are identically zero for a class are None."""
    present, d = _present(C("body", zeros={"gx", "gy", "gz"}))
    assert "applied_forces" not in present and d.kernels["energy"][1] == 0
    assert "energy" not in _present(C("torque"))[0]
    present, _ = _present(C("force", zeros={"Fx", "Fy", "Fz"}))
    assert not present & {"applied_forces", "energy"}
    present, _ = _present(C("unit_vector", fixed={"u"}))
    assert present == {"constraints"}
    # spinning about the fixed line r_ij through the mass centre: w x I w is normal to
    # the axis, so no inertia terms; only the angle row is left
    present, d = _present(C("body", fixed={"ri", "rj"},
                            zeros={"a1", "a2", "a3", "gx", "gy", "gz"}))
    assert "h_vector" not in present and d.cls.constraint_rows == ("angle",)
    _, d = _present(C("spring", (PT, PT), zeros={"c"}))
    assert not d.kernels["applied_forces"].free_symbols & set(d.v)


@pytest.mark.parametrize("fixed, n_q", [((), 9), ({"ri"}, 6), ({"ri", "u"}, 3),
                                        ({"ri", "rj", "u"}, 0)])
def test_fixed_triples_reduce_coordinates(fixed, n_q):
    """A fixed triple is three parameters, not coordinates."""
    cls = C("body", fixed=fixed)
    d = derive_class(cls)
    assert len(d.q) == len(d.v) == n_q
    assert len(d.p) == 16 + 3 * len(fixed)
    if n_q == 0:
        assert d.kernels["mass_matrix"] is None and d.kernels["constraints"] is None
        return
    assert d.kernels["mass_matrix"].free_symbols & set(d.q) == set(d.q)
    fixed_params = {d.p[cls.param_names.index(f"{t}.{c}")] for t in fixed for c in "xyz"}
    assert fixed_params <= d.kernels["constraints"].free_symbols


def test_derive_time_of_largest_body_class():
    """Reports how long the full body class (nothing fixed, no zeros) takes to derive."""
    start = time.perf_counter()
    d = derive_class(C("body"))
    elapsed = time.perf_counter() - start
    print(f"derive_class(full body): {elapsed:.3f} s")
    assert d.kernels["mass_matrix"] is not None
