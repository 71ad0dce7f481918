"""Statics and modes of flexible members against closed forms and an independent
elastica (docs/flexible.md): the cantilever under a small tip load (P L^3 / 3 EI),
its convergence with the mesh, a large deflection against the elastica of the same
strain energy integrated by SciPy's solve_bvp, and the natural frequencies of the
clamped cantilever against Euler-Bernoulli and the axial bar.

Every variant of the cantilever has the same element classes, so one compiled module
serves them all (one build per session)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_bvp

import fccgen
from fccgen.analysis import linearize, modes, statics

CANTILEVER = """
name: {name}
cables:
  beam:
    from: {{body: ground, at: [0, 0, 0], clamp: true}}
    to: [{length}, 0, 0]
    elements: {elements}
    EA: {EA}
    EI: {EI}
    mass_per_length: 2.0
loads:
  - {{type: force, point: beam.tip, value: [0, {P}, 0]}}
"""


def cantilever(tmp_path, build_dir, elements, P, EA=1.0e5, EI=20.0, length=1.0):
    path = tmp_path / f"cantilever_{elements}.yaml"
    path.write_text(CANTILEVER.format(name="cantilever", elements=elements, P=P, EA=EA,
                                      EI=EI, length=length))
    return fccgen.load(path, build_dir)


def tip(solver, q) -> np.ndarray:
    k = solver.plan.index["beam.tip"]
    return q[3 * k:3 * k + 3]


def test_small_tip_load_matches_beam_theory_and_converges(tmp_path, build_dir):
    """A tip load P with P L^2 / EI = 1e-3 (tip deflection 1/3000 of the length):
    the deflection is within 0.1 % of P L^3 / (3 EI) with 8 elements, as the issue
    asks. The cubic elements hold the small-deflection solution exactly (a cubic), so
    what is left is the large-deflection theory's own correction, of order
    (P L^2 / EI)^2 = 1e-6 here: 2, 4 and 8 elements are each within 1e-5 of the
    closed form (measured: 1.1e-7 to 1.2e-7 relative), so refining does not move away
    from it."""
    P, EI, L = -0.02, 20.0, 1.0
    exact = P * L ** 3 / (3 * EI)
    errors = []
    for n in (2, 4, 8):
        s = cantilever(tmp_path, build_dir, n, P)
        eq = statics(s)
        errors.append(abs(tip(s, eq.q)[1] / exact - 1.0))
    assert errors[-1] <= 1e-3
    assert max(errors) <= 1e-5


def elastica(P, EA, EI=1.0, L=1.0):
    """Tip (x, y) of a cantilever under a tip force P along +y, for the strain energy
    of the cable element (EA/2 eps^2 + EI/2 kappa^2 per unit stress-free length, kappa
    the curvature of the deformed line): with r' = (1 + eps)(cos th, sin th), the
    bending moment M = EI th' / (1 + eps)^2, the axial balance
    EA eps - M^2 (1 + eps) / EI = P sin th, and M' = -P (1 + eps) cos th, integrated
    over s in [0, L] by solve_bvp (x = y = th = 0 at s = 0, M = 0 at s = L)."""
    def eps(th, M):
        return (P * np.sin(th) + M ** 2 / EI) / (EA - M ** 2 / EI)

    def f(s, y):
        e = eps(y[2], y[3])
        return np.vstack([(1 + e) * np.cos(y[2]), (1 + e) * np.sin(y[2]),
                          y[3] * (1 + e) ** 2 / EI, -P * (1 + e) * np.cos(y[2])])

    s = np.linspace(0, L, 101)
    y0 = np.zeros((4, s.size))
    y0[0] = s
    sol = solve_bvp(f, lambda a, b: np.array([a[0], a[1], a[2], b[3]]), s, y0,
                    tol=1e-10, max_nodes=100000)
    assert sol.status == 0, sol.message
    return sol.sol(L)


def test_large_deflection_matches_the_elastica(tmp_path, build_dir):
    """P L^2 / EI = 3: the tip turns by 56 degrees (> 45). 16 elements are within
    1e-4 m of the elastica (measured: 5e-6 m; 8 elements 2e-4 m, 4 elements 4e-3 m:
    the error falls by a factor of 17 to 40 per halving of the elements)."""
    EI, EA, P = 1.0, 1.0e5, 3.0
    ref = elastica(P, EA, EI)
    assert np.degrees(ref[2]) > 45.0
    s = cantilever(tmp_path, build_dir, 16, P, EA=EA, EI=EI)
    eq = statics(s)
    assert np.max(np.abs(tip(s, eq.q)[:2] - ref[:2])) <= 1e-4


def test_cantilever_modes_match_euler_bernoulli_and_the_bar(compiled):
    """examples/cantilever.yaml (8 elements, EI 20, rhoA 2, L 1, EA 1e5): the first
    three bending frequencies (each twice: two planes) within 0.5 % of Euler-Bernoulli,
    (beta L)^2 / (2 pi L^2) sqrt(EI / rhoA) with beta L = 1.8751, 4.6941, 7.8548, and
    the first axial one within 0.5 % of sqrt(EA / rhoA) / (4 L). The tip load of the
    example (0.15 N) moves them by less than 1e-5 (geometric stiffness P / EA)."""
    s = compiled("cantilever")
    eq = statics(s)
    f = modes(linearize(s, eq.q)).frequency_hz
    EI, rhoA, L, EA = 20.0, 2.0, 1.0, 1.0e5
    bending = (np.array([1.8751, 4.6941, 7.8548]) ** 2 / (2 * np.pi * L ** 2)
               * np.sqrt(EI / rhoA))
    axial = np.sqrt(EA / rhoA) / (4 * L)
    for k, ref in enumerate(bending):
        assert f[2 * k] == pytest.approx(ref, rel=5e-3)
        assert f[2 * k + 1] == pytest.approx(ref, rel=5e-3)
    assert np.min(np.abs(f / axial - 1.0)) <= 5e-3
