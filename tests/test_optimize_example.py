"""examples/optimize_deployment.py: the gradients it hands the optimiser are the
derivatives of what it optimises. Its objective and constraints (the rate and time at
the scissor boom's latch, from a run that stops there) against central differences of
the same functions, on one unit (2 design numbers), at the start design and at a
stiffer, more damped one."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import example_module

# Central differences at a relative step of 1e-4 leave a truncation error of about
# 1e-8 of the gradient (the rate and the latch time are smooth here, far from the
# designs that barely reach the latch) and a rounding/event-location part of about
# 1e-12 / 1e-4 = 1e-8; 1e-6 of the gradient's size leaves a margin of 100 over both,
# and is 1e4 times below the error of a gradient missing the event's time shift.
TOL = 1e-6


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    import fccgen

    mod = example_module("optimize_deployment")
    folder = tmp_path_factory.mktemp("optimize")
    _, to_latch = mod.boom_files(1, folder)
    return mod.Problem(fccgen.load(to_latch, folder / "generated"), 0.2, 1.0)


@pytest.mark.parametrize("scale", [(1.0, 1.0), (1.25, 4.0)])
def test_the_exact_gradients_are_the_derivatives_of_the_goal(problem, scale):
    design = problem.start() * np.repeat(scale, problem.n)
    J, grad = problem.objective(design, True)
    C, jac = problem.constraints(design, True), problem.constraints_gradient(design)
    # the run with sensitivities and the plain run take different paths (dense, sparse)
    assert J == pytest.approx(problem.objective(design), rel=1e-10)
    np.testing.assert_allclose(C, problem.constraints(design), rtol=1e-10, atol=1e-12)
    for i, x in enumerate(design):
        h = 1e-4 * x
        up, down = design.copy(), design.copy()
        up[i] += h
        down[i] -= h
        dJ = (problem.objective(up) - problem.objective(down)) / (2 * h)
        dC = (problem.constraints(up) - problem.constraints(down)) / (2 * h)
        assert abs(grad[i] - dJ) <= TOL * np.max(np.abs(grad)), (i, grad[i], dJ)
        for k in range(2):
            assert abs(jac[k, i] - dC[k]) <= TOL * np.max(np.abs(jac[k])), (k, i, jac[k, i], dC[k])
