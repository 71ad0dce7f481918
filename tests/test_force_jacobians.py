"""The force Jacobians df/dq and df/dq' (kernels force_jacobian_q / force_jacobian_v)
against finite differences of the applied forces, in the NumPy version, the SymPy
derivation and the compiled module (element by element and assembled)."""
from __future__ import annotations

import numpy as np
import pytest
import sympy

from fccgen.derive import derive_class
from fccgen.numeric import element_kernel
from fccgen.plan.classes import ElementClass
from fccgen.runtime._assemble import FLAGS

from kernel_checks import d1, random_case

F, T = False, True
CLASSES = [
    ElementClass("body", (), (F, F, F), frozenset()),
    ElementClass("body", (), (T, F, F), frozenset()),
    ElementClass("body", (), (F, F, T), frozenset({"a2", "gx"})),
    ElementClass("force", (), (F, F, F), frozenset()),
    ElementClass("force", (), (T, F, T), frozenset({"beta", "b2", "Fz"})),
    ElementClass("torque", (), (F, F, F), frozenset()),
    ElementClass("torque", (), (T, F, F), frozenset({"beta", "Tx"})),
    ElementClass("torque", (), (F, T, T), frozenset()),
    ElementClass("spring", ("point", "point"), (F, F), frozenset()),
    ElementClass("spring", ("point", "point"), (T, F), frozenset({"c"})),
    ElementClass("spring", ("body_point", "body_point"), (F, F, F, F, F, F), frozenset()),
    ElementClass("spring", ("point", "body_point"), (T, F, F, T), frozenset({"L0"})),
]
IDS = [f"{c.kind}:{'/'.join(c.ends)}:{''.join('F' if f else 'm' for f in c.fixed)}"
       for c in CLASSES]


def fd_jacobian(fun, x):
    """Five-point differences, one column per coordinate (h = 1e-3: the truncation
    error of the spring's square roots is ~h^4 f^(5) ~ 1e-12 at unit lengths)."""
    return np.array([d1(fun, x, e) for e in np.eye(x.size)]).T


def jacobians(cls, q, v, p, ev):
    n = cls.n_q
    jq = ev("force_jacobian_q", q, v, p)
    jv = ev("force_jacobian_v", q, v, p)
    return (np.zeros((n, n)) if jq is None else jq.reshape(n, n),
            np.zeros((n, n)) if jv is None else jv.reshape(n, n))


def check_against_fd(cls, ev, seed):
    """Both Jacobians of ev's kernels match differences of ev's applied forces within
    1e-8 of their largest entry (rounding of differences at h = 1e-3 is ~1e-13 / h)."""
    q, v, p = random_case(cls, seed)
    jq, jv = jacobians(cls, q, v, p, ev)
    fq = fd_jacobian(lambda x: ev("applied_forces", x, v, p), q)
    fv = fd_jacobian(lambda x: ev("applied_forces", q, x, p), v)
    scale = max(1.0, np.max(np.abs(fq)), np.max(np.abs(fv)))
    assert np.max(np.abs(jq - fq)) <= 1e-8 * scale
    assert np.max(np.abs(jv - fv)) <= 1e-8 * scale
    return jq, jv


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_numeric_jacobians_match_finite_differences(cls):
    for seed in range(3):
        jq, _ = check_against_fd(cls, lambda *a: element_kernel(cls, *a), seed)
    # gravity and a point force depend on q only through c ~u and c ~r_ij blocks that
    # pair with u: with u fixed df/dq is zero; otherwise the check is not vacuous
    if cls.kind in ("spring", "torque") or not cls.fixed[2]:
        assert np.max(np.abs(jq)) > 1e-3


def _lambdified(cls):
    d = derive_class(cls)
    fns = {name: sympy.lambdify((d.q, d.v, d.p), list(m), modules="numpy", cse=True)
           for name, m in d.kernels.items() if m is not None}

    def ev(name, q, v, p):
        return np.array(fns[name](q, v, p), float) if name in fns else None
    return d, ev


# The spring between two body points (18 coordinates) is left out here: lambdify's CSE
# of its 324 entries takes half a minute, and its expressions are built by the same
# code as the point/body-point spring's.
SYMPY_CASES = [c for c in CLASSES if c.n_q <= 12]


@pytest.mark.parametrize("cls", SYMPY_CASES,
                         ids=[i for c, i in zip(CLASSES, IDS) if c in SYMPY_CASES])
def test_derived_jacobians_match_numeric(cls):
    """The SymPy kernels against the NumPy ones (1e-12 relative: same quantity, two
    independent formulas in double precision) and against differences."""
    d, ev = _lambdified(cls)
    if cls.kind != "spring":
        assert d.kernels["force_jacobian_v"] is None   # f of q alone
    for seed in range(2):
        q, v, p = random_case(cls, seed)
        ours = jacobians(cls, q, v, p, ev)
        theirs = jacobians(cls, q, v, p, lambda *a: element_kernel(cls, *a))
        for a, b in zip(ours, theirs):
            assert np.max(np.abs(a - b), initial=0.0) <= 1e-12 * max(1.0, np.max(np.abs(b),
                                                                              initial=0.0))
    check_against_fd(cls, ev, 5)


SPRING_MODEL = """
name: spring_jacobians
gravity: [0.3, -9.81, 0.2]
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [0.3, -0.9, 0.2]
  Q: [0.9, -1.1, 0.5]
vectors:
  z: {along: [0, 0, 1], fixed: false}
bodies:
  rod:
    points: [P, Q]
    vector: z
    mass: 1.3
    center: [0.2, 0.1, 0.05]
    inertia: [0.01, 0.05, 0.06]
loads:
  - {type: spring, ends: [O, {body: rod, at: [0.1, 0.2, 0.3]}], stiffness: 40,
     length: 0.5, damping: 1.5}
  - {type: force, body: rod, value: [1, 2, 3], at: [0.2, -0.1, 0.4]}
  - {type: torque, body: rod, value: [0.5, -0.2, 0.7]}
"""


@pytest.fixture(scope="module")
def spring_solvers(tmp_path_factory):
    import fccgen
    path = tmp_path_factory.mktemp("jac") / "spring_jacobians.yaml"
    path.write_text(SPRING_MODEL)
    return fccgen.load(path, path.parent / "build"), fccgen.load_numeric(path)


def test_compiled_assembly_matches_finite_differences(spring_solvers):
    """The assembled K and C of the compiled module (flags force_jacobian_q/v) against
    differences of its applied forces and against the numeric elements (1e-12
    relative: same quantities, different evaluation order)."""
    cs, ns = spring_solvers
    rng = np.random.default_rng(3)
    q0 = np.array(ns.plan.q0, float)
    for _ in range(3):
        q, v = q0 + 0.05 * rng.normal(size=q0.size), rng.normal(size=q0.size)
        jq = cs._asm.quantity(FLAGS["force_jacobian_q"], q, v)
        jv = cs._asm.quantity(FLAGS["force_jacobian_v"], q, v)
        fq = fd_jacobian(lambda x: cs.applied_forces(x, v), q)
        fv = fd_jacobian(lambda x: cs.applied_forces(q, x), v)
        scale = max(np.max(np.abs(fq)), np.max(np.abs(fv)))
        assert np.max(np.abs(jq - fq)) <= 1e-8 * scale     # as check_against_fd
        assert np.max(np.abs(jv - fv)) <= 1e-8 * scale
        num_q, num_v = numeric_assembly(ns, q, v)
        assert np.max(np.abs(jq - num_q)) <= 1e-12 * scale
        assert np.max(np.abs(jv - num_v)) <= 1e-12 * scale
        assert np.max(np.abs(jv)) > 0.1               # the damper is there


def numeric_assembly(ns, q, v):
    """df/dq and df/dq' of the whole model from the numeric element kernels."""
    n = ns.n_q
    out = [np.zeros((n, n)), np.zeros((n, n))]
    for el in ns.plan.elements:
        idx = el.q_index()
        for k, name in enumerate(("force_jacobian_q", "force_jacobian_v")):
            block = element_kernel(el.cls, name, q[idx], v[idx], el.params)
            if block is not None:
                out[k][np.ix_(idx, idx)] += block.reshape(len(idx), len(idx))
    return out
