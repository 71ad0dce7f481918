"""The compiled constrained solve (fccgen.runtime._solve) on random matrices:

    x = argmin x^T M x / 2 - Q^T x  subject to  B x = b

against dense KKT solves with NumPy, against the numeric version's implementation of
the same algorithm, with redundant and zero rows, and on its error path."""
from __future__ import annotations

import numpy as np
import pytest

from fccgen.errors import SimulationError
from fccgen.numeric.constrained import constrained_solve as numeric_solve
from fccgen.runtime._solve import constrained_solve

# Random problems below have KKT condition numbers of at most ~1e4: a backward-stable
# solve is then accurate to ~1e-12 relative; 1e-10 leaves room for unlucky draws.
KKT_REL = 1e-10
# The numeric version runs the same algorithm (same QR, same rank, same Cholesky):
# the two differ only by rounding in different BLAS orders.
SAME_REL = 1e-12

SIZES = [(3, 1), (9, 3), (12, 7), (30, 18), (60, 40)]


def spd(rng, n):
    a = rng.normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


def kkt(M, B, Q, b):
    n, m = M.shape[0], B.shape[0]
    K = np.block([[M, B.T], [B, np.zeros((m, m))]])
    return np.linalg.solve(K, np.concatenate([Q, b]))[:n]


def rel(x, ref):
    return float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))


@pytest.mark.parametrize("n, m", SIZES)
def test_matches_kkt_on_well_posed_problems(n, m):
    rng = np.random.default_rng(n * 100 + m)
    for _ in range(5):
        M, B = spd(rng, n), rng.normal(size=(m, n))
        Q, b = rng.normal(size=n), rng.normal(size=m)
        x, rank = constrained_solve(M, B, Q, b)
        assert rank == m
        assert rel(x, kkt(M, B, Q, b)) < KKT_REL
        assert rel(x, numeric_solve(M, B, Q, b)) < SAME_REL


@pytest.mark.parametrize("n, m", SIZES)
def test_mass_matrix_singular_alone(n, m):
    """M = N D N^T + E E^T with N a basis of the null space of B and E of m // 2 random
    columns: rank n - m + m // 2 < n, singular, but well conditioned on the null space
    of B, as a body's 9 x 9 block of rank 6 is."""
    rng = np.random.default_rng(7 * n + m)
    B = rng.normal(size=(m, n))
    N = np.linalg.svd(B)[2][m:].T
    E = rng.normal(size=(n, m // 2))
    M = N @ np.diag(rng.uniform(1.0, 3.0, n - m)) @ N.T + E @ E.T
    assert np.linalg.matrix_rank(M) < n
    Q, b = rng.normal(size=n), rng.normal(size=m)
    x, _ = constrained_solve(M, B, Q, b)
    assert rel(x, kkt(M, B, Q, b)) < KKT_REL
    assert rel(x, numeric_solve(M, B, Q, b)) < SAME_REL


def redundant_problem(rng, n=15, m0=8):
    """B0 of full rank m0 and a consistent b0, plus the same constraints with copies,
    combinations, a rescaled copy, a copy off by 1e-14 relative, and zero rows."""
    M, B0 = spd(rng, n), rng.normal(size=(m0, n))
    b0 = rng.normal(size=m0)
    mix = np.array([[1, 0, 0], [2.5, 0, 0], [0, 1, -3], [1e-6, 0, 0]])
    B = np.vstack([B0, mix @ B0[:3], B0[4] * (1 + 1e-14), np.zeros((2, n))])
    b = np.concatenate([b0, mix @ b0[:3], [b0[4] * (1 + 1e-14)], [0.0, 0.0]])
    order = rng.permutation(B.shape[0])
    return M, B0, b0, B[order], b[order], rng.normal(size=n)


def test_redundant_and_zero_rows():
    rng = np.random.default_rng(11)
    for _ in range(5):
        M, B0, b0, B, b, Q = redundant_problem(rng)
        x, rank = constrained_solve(M, B, Q, b)
        assert rank == B0.shape[0]
        assert rel(x, kkt(M, B0, Q, b0)) < KKT_REL
        assert np.max(np.abs(B @ x - b)) < KKT_REL * np.max(np.abs(b))
        assert rel(x, numeric_solve(M, B, Q, b)) < SAME_REL


def test_rows_are_scaled():
    """Rows of very different sizes (1e-8 to 1e8) give the same x: each row of B and b
    is scaled by 1/||B_k|| before the rank decision."""
    rng = np.random.default_rng(5)
    M, B, Q, b = spd(rng, 10), rng.normal(size=(6, 10)), rng.normal(size=10), rng.normal(size=6)
    s = 10.0 ** np.linspace(-8, 8, 6)
    x, rank = constrained_solve(M, B * s[:, None], Q, b * s)
    assert rank == 6
    assert rel(x, kkt(M, B, Q, b)) < KKT_REL


def test_no_constraints_and_full_constraints():
    rng = np.random.default_rng(2)
    M, Q = spd(rng, 7), rng.normal(size=7)
    x, rank = constrained_solve(M, np.zeros((0, 7)), Q, np.zeros(0))
    assert rank == 0 and rel(x, np.linalg.solve(M, Q)) < KKT_REL
    B, b = rng.normal(size=(7, 7)), rng.normal(size=7)
    x, rank = constrained_solve(np.zeros((7, 7)), B, Q, b)     # M plays no part
    assert rank == 7 and rel(x, np.linalg.solve(B, b)) < KKT_REL


def test_velocity_projection_is_m_orthogonal():
    """Q = M v, b = 0 gives the M-orthogonal projection p of v onto B p = 0:
    (v - p)^T M z = 0 for every z with B z = 0 (checked on a null-space basis)."""
    rng = np.random.default_rng(9)
    M, B, v = spd(rng, 12), rng.normal(size=(5, 12)), rng.normal(size=12)
    p, _ = constrained_solve(M, B, M @ v, np.zeros(5))
    null = np.linalg.svd(B)[2][5:].T
    assert np.max(np.abs(B @ p)) < 1e-12 * np.max(np.abs(v))   # rounding of B p
    assert np.max(np.abs(null.T @ M @ (v - p))) < 1e-12 * np.max(np.abs(M @ v))


def test_singular_on_the_constraint_manifold_raises():
    """M vanishes along a direction that B leaves free: exactly (M has a zero row and
    column) and up to rounding (M = C C^T with too few columns, where Cholesky alone
    would accept pivots of a few ulps)."""
    rng = np.random.default_rng(4)
    n, m = 8, 3
    B = np.hstack([rng.normal(size=(m, n - 1)), np.zeros((m, 1))])
    M = spd(rng, n)
    M[-1, :] = M[:, -1] = 0.0
    with pytest.raises(SimulationError, match="singular on the constraint manifold"):
        constrained_solve(M, B, rng.normal(size=n), rng.normal(size=m))
    C = rng.normal(size=(n, n - m - 1))
    with pytest.raises(SimulationError, match="singular on the constraint manifold"):
        constrained_solve(C @ C.T, rng.normal(size=(m, n)), rng.normal(size=n),
                          rng.normal(size=m))


def test_inputs_untouched_and_result_fresh():
    rng = np.random.default_rng(1)
    M, B, Q, b = spd(rng, 6), rng.normal(size=(2, 6)), rng.normal(size=6), rng.normal(size=2)
    keep = [a.copy() for a in (M, B, Q, b)]
    x1, _ = constrained_solve(M, B, Q, b)
    x2, _ = constrained_solve(M, B, Q, b)
    assert not np.shares_memory(x1, x2) and np.array_equal(x1, x2)
    assert all(np.array_equal(a, k) for a, k in zip((M, B, Q, b), keep))


def test_shape_errors():
    with pytest.raises(ValueError, match="inconsistent shapes"):
        constrained_solve(np.eye(3), np.ones((1, 3)), np.ones(2), np.ones(1))
