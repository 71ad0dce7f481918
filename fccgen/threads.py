"""BLAS threading for fccgen's small dense factorisations."""
from __future__ import annotations

from functools import lru_cache

from threadpoolctl import ThreadpoolController


def single_threaded_blas():
    """A context in which BLAS/LAPACK run on one thread. The per-step factorisations
    are small (n_q up to a few hundred): threads cost more than they give, and on a
    loaded machine an OpenBLAS that spins its threads made an A02 step 20x slower.
    The BLAS libraries are found once per process (a scan of the loaded libraries
    costs milliseconds, as much as a short run); entering and leaving then costs tens
    of microseconds. It wraps whole runs, not single calls."""
    return _controller().limit(limits=1, user_api="blas")


@lru_cache(maxsize=1)
def _controller() -> ThreadpoolController:
    """The process's BLAS libraries, NumPy's and SciPy's (SciPy's wheels bring their
    own, loaded with scipy.linalg: imported first so that the scan finds it)."""
    import scipy.linalg  # noqa: F401
    return ThreadpoolController()
