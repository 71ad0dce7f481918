"""The rank of the constraint Jacobian, decided once per run and kept.

``rule`` holds the SVD gap test and its numbers, ``sparse`` the same decision for large
Jacobians without a dense SVD, ``rows`` the choice of a basis of B's rows and the
weights of its dependencies, ``report`` what a run says about its rank. This module is
the face: :func:`decide` picks the dense or the component-wise decision.
"""
from __future__ import annotations

import numpy as np

from . import sparse
from .report import report_run, run_findings, sparse_solve_warning
from .rule import (AMBIGUOUS_LOW, DECIDE_TOL, GROW_TOL, KE_CUT_WARN, RANK_TOL, ROW_FLOOR,
                   SPLIT_COLUMNS, RankDecision, dense_decision, row_scales,
                   scaled_singular_values, scales_from_norms)

__all__ = ["AMBIGUOUS_LOW", "DECIDE_TOL", "GROW_TOL", "KE_CUT_WARN", "RANK_TOL",
           "ROW_FLOOR", "SPLIT_COLUMNS", "RankDecision", "decide", "dense_columns_max",
           "dense_decision", "report_run", "row_scales", "run_findings",
           "scaled_singular_values", "scales_from_norms", "sparse_solve_warning"]


def decide(B: np.ndarray, n_q: int | None = None, groups=None,
           dense_max: int | None = None, rank_only: bool = False) -> RankDecision:
    """The rank of B by the SVD gap test (see fccgen.rank.rule); groups: the
    element of each row (:func:`row_scales`). B of more than SPLIT_COLUMNS columns
    (dense or SciPy sparse) is decided a connected component at a time (its singular
    values are the union of the components': the same rule, several small SVDs in place
    of one large), components of more than fccgen.rank.sparse.DENSE_COMPONENT columns
    without a dense SVD (:func:`fccgen.rank.sparse.decide_large`: the same rule,
    certified). dense_max: the most columns of a component that takes the dense SVD
    (default DENSE_COMPONENT); B of more columns is decided a component at a time.
    rank_only: for callers that read only the rank (fccgen.rank.sparse.certified)."""
    if not hasattr(B, "shape"):
        B = np.asarray(B, float)
    n_q = B.shape[1] if n_q is None else n_q
    if dense_max is not None and B.shape[1] > dense_max:
        return sparse.decide_large(B, n_q, groups, dense_max, rank_only)
    if B.shape[1] > SPLIT_COLUMNS:
        return sparse.decide_large(B, n_q, groups)
    B = np.asarray(B, float)
    if not np.all(np.isfinite(B)):        # the run's own checks name the bad input
        return RankDecision(-1, n_q, ())
    return dense_decision(scaled_singular_values(B, groups), n_q)


def dense_columns_max() -> int:
    """The most columns :func:`decide` takes through one dense SVD."""
    return sparse.DENSE_COMPONENT

