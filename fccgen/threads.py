"""BLAS threading for fccgen's small dense factorisations."""
from __future__ import annotations

from threadpoolctl import threadpool_limits


def single_threaded_blas():
    """A context in which BLAS/LAPACK run on one thread. The per-step factorisations
    are small (n_q up to a few hundred): threads cost more than they give, and on a
    loaded machine an OpenBLAS that spins its threads made an A02 step 20x slower.
    Entering and leaving costs about 1 ms, so it wraps whole runs, not single calls."""
    return threadpool_limits(limits=1, user_api="blas")
