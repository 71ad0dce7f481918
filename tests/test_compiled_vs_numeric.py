"""The compiled kernels against the independent NumPy version, on random consistent
states of every example (docs/design.md §6: agreement to ~1e-12 relative)."""
from __future__ import annotations

import numpy as np
import pytest

from states import length_scale, random_state

EXAMPLES = ["a01_pendulum", "double_pendulum", "free_body", "spherical_pendulum",
            "four_bar", "deployable", "rsup"]
N_STATES = 5

# Both versions evaluate the same formulas in double precision in different orders, so
# each entry differs by a few ulps of the largest term it sums: 1e-12 of the array's
# largest magnitude leaves room for sums of tens of terms, and nothing more.
REL = 1e-12


def close(a, b, scale, rel=REL):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert a.shape == b.shape
    err = np.max(np.abs(a - b)) if a.size else 0.0
    assert err <= rel * scale, f"max difference {err:.3g} > {rel:g} * {scale:.3g}"


def amax(x):
    x = np.asarray(x, float)
    return float(np.max(np.abs(x))) if x.size else 0.0


@pytest.mark.parametrize("name", EXAMPLES)
def test_global_quantities_agree(name, compiled, numeric):
    cs, ns = compiled(name), numeric(name)
    rng = np.random.default_rng(7)
    L = length_scale(ns.plan)
    for _ in range(N_STATES):
        q, v = random_state(ns, rng)
        for quantity in ("mass_matrix", "constraint_jacobian"):
            b = getattr(ns, quantity)(q)
            close(getattr(cs, quantity)(q), b, amax(b))
        # Terms that cancel to zero in theory come out as rounding noise in both
        # versions, so speed-dependent terms are compared against the size of the
        # terms they sum: mass times speed squared per length.
        M, B = ns.mass_matrix(q), ns.constraint_jacobian(q)
        quadratic = amax(v) ** 2 / L
        scales = {"h_vector": amax(M) * quadratic, "applied_forces": 0.0,
                  "constraint_bias": amax(B) * quadratic, "body_outputs": 0.0}
        # force Jacobians: forces per length are the size of their entries
        f_per_length = amax(ns.applied_forces(q, v)) / L
        scales.update(force_jacobian_q=f_per_length, force_jacobian_v=0.0)
        for quantity, scale in scales.items():
            b = getattr(ns, quantity)(q, v)
            close(getattr(cs, quantity)(q, v), b, max(amax(b), scale))
        # constraints vanish on these states: compare against the size of the terms
        # that cancel (quadratic in lengths).
        close(cs.constraints(q), ns.constraints(q), max(L, 1.0) ** 2)
        e_n = ns.energy(q, v)
        kinetic_scale = abs(e_n) + amax(ns.mass_matrix(q)) * amax(v) ** 2
        close(cs.energy(q, v), e_n, kinetic_scale)


@pytest.mark.parametrize("name", EXAMPLES)
def test_accelerations_agree(name, compiled, numeric):
    """The constrained solve amplifies rounding by the condition number of the reduced
    mass matrix; the examples are scaled so that 1e-10 relative holds with margin
    (measured differences are printed by `fccgen bench`)."""
    cs, ns = compiled(name), numeric(name)
    rng = np.random.default_rng(11)
    for _ in range(N_STATES):
        q, v = random_state(ns, rng)
        a_n = ns.accelerations(q, v)
        close(cs.accelerations(q, v), a_n, amax(a_n), rel=1e-10)


@pytest.mark.parametrize("name", EXAMPLES)
def test_short_runs_agree(name, compiled, numeric):
    """Twenty RK4 steps with projection from the model's own initial state: the same
    method on the same equations, so the trajectories agree to rounding."""
    cs, ns = compiled(name), numeric(name)
    dt = cs.plan.model.simulate.dt
    rc = cs.simulate(t_end=20 * dt, dt=dt)
    rn = ns.simulate(t_end=20 * dt, dt=dt)
    assert rc.names == rn.names
    L = length_scale(ns.plan)
    for col in rn.names:
        if col == "constraint_error":
            continue
        scale = max(amax(rn[col]), L if not col.endswith(("vx", "vy", "vz")) else 1.0)
        close(rc[col], rn[col], scale, rel=1e-9)
