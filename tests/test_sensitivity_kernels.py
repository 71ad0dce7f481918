"""The compiled parameter derivatives of the element kernels (SymPy, fccgen.derive.
parameters, printed and compiled by fccgen.runtime.sensitivity.build) against the NumPy
version (five-point differences of the hand-written NumPy kernels in each parameter).
Structural zeros (``cls.zeros``) are folded out of the compiled class, so their
derivatives are not compared: a value that unfolds one needs a new build and
with_parameters refuses it. The time t (a parameter slot of timed classes) is no
design parameter and is not compared either.

Tolerance 1e-9 of the largest entry of each derivative: the five-point stencil is exact
for parameters entering as polynomials of degree <= 4 (then only rounding, about
eps / h ~ 1e-12, is left) and within h^4 |K^(5)| / 30 otherwise (below 1e-11 with
h = 2e-4 for lengths down to 0.5 and sin gamma down to 0.4, the random cases' range).
"""
from __future__ import annotations

import numpy as np
import pytest

from kernel_checks import random_case

from fccgen.api import plan_model
from fccgen.derive.parameters import PARAMETER_KERNELS
from fccgen.numeric.parameter_derivatives import kernel_dp
from fccgen.runtime.sensitivity.build import build_dp, load_dp

MODELS = ("double_pendulum", "four_bar_driven", "rsup")


@pytest.fixture(scope="session")
def dp_module(build_dir):
    from conftest import EXAMPLES
    cache = {}

    def get(name):
        if name not in cache:
            plan = plan_model(EXAMPLES / f"{name}.yaml")
            cache[name] = (plan, load_dp(plan, build_dir))
        return cache[name]
    return get


@pytest.mark.parametrize("name", MODELS)
def test_compiled_dp_matches_numeric(dp_module, name):
    plan, module = dp_module(name)
    for c, cls in enumerate(plan.classes):
        for seed in range(2):
            q, v, p = random_case(cls, seed)
            for kernel in PARAMETER_KERNELS:
                live = [j for j, n in enumerate(cls.param_names) if n not in cls.zeros and n != "t"]
                got = module.evaluate(c, kernel, q, v, p)[live]
                want = kernel_dp(cls, kernel, q, v, p)[live]
                if want.size == 0:
                    assert not np.any(got), (cls.name, kernel)
                    continue
                scale = max(1.0, np.max(np.abs(want)))
                assert np.max(np.abs(got - want)) <= 1e-9 * scale, (cls.name, kernel)


def test_dp_module_is_cached(dp_module, build_dir):
    plan, _ = dp_module("double_pendulum")
    assert build_dp(plan, build_dir).cache_hit


def test_mass_derivative_of_mass_matrix_is_mass_matrix_over_m(dp_module):
    """M = m Dhat^T Dhat + Phi^T I Phi is linear in m: dM/dm = (M(m) - M(0)) / m."""
    from fccgen.numeric import element_kernel
    plan, module = dp_module("double_pendulum")
    cls = plan.classes[0]
    q, v, p = random_case(cls, 7)
    j = cls.param_names.index("m")
    p0 = p.copy()
    p0[j] = 0.0
    want = (element_kernel(cls, "mass_matrix", q, v, p)
            - element_kernel(cls, "mass_matrix", q, v, p0)) / p[j]
    got = module.evaluate(0, "mass_matrix", q, v, p)[j]
    assert np.max(np.abs(got - want)) <= 1e-13 * max(1.0, np.max(np.abs(want)))


@pytest.mark.parametrize("name", ("double_pendulum", "four_bar_driven"))
def test_tangent_kernel_matches_numeric(dp_module, name):
    """The tangent kernel (the directional derivatives of the equations' residuals the
    sensitivities integrate) against five-point differences of the NumPy kernels along
    the same direction; same tolerance and reasons as above. The direction leaves the
    structural zeros and the time slot alone."""
    from fccgen.numeric.parameter_derivatives import tangent
    plan, module = dp_module(name)
    rng = np.random.default_rng(3)
    for c, cls in enumerate(plan.classes):
        q, v, p = random_case(cls, c)
        a, lam = rng.normal(size=cls.n_q), rng.normal(size=cls.n_g)
        dq, dv = rng.normal(size=cls.n_q), rng.normal(size=cls.n_q)
        dp = np.array([0.0 if n in cls.zeros or n == "t" else rng.normal()
                       for n in cls.param_names])
        got = module.tangent(c, q, v, p, a, lam, dq, dv, dp)
        want = tangent(cls, q, v, p, a, lam, dq, dv, dp)
        assert np.max(np.abs(got - want)) <= 1e-9 * max(1.0, np.max(np.abs(want))), cls.name
