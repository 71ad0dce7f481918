"""The rank of the constraint Jacobian: decided once by an SVD gap test, then kept.

Redundant constraint equations are normal in closed loops (docs/design.md §1), so the
solvers need the rank r of B to split the coordinates into n - r free directions and r
constrained ones. Deciding r afresh at every factorisation from the QR pivots is
fragile: rounding and the position error lift the zero singular values of redundant
equations to 1e-13, and the QR pivot that should reveal them can be five decades larger
(7.7e-8 on Bricard's linkage against a threshold of 1e-10). One equation counted too
many removes a degree of freedom and the mechanism freezes, while its energy and
constraint error look perfect.

So a run decides r once, at its start, from the singular values of B with its rows
scaled to unit length (sigma_1 >= sigma_2 >= ...):

* r = the number of sigma_k > DECIDE_TOL sigma_1;
* the decision is *clear* when no sigma_k lies in the band
  [AMBIGUOUS_LOW, GROW_TOL] sigma_1; otherwise the start is near a singular position
  and the run says so.

The factorisations then keep r (runtime/_solve.pyx, numeric/constrained.py), dropping
rows only at a singular position met during the run (a pivot within r at or below
rank_tol) and raising r only when an SVD confirms sigma_{r+1} > GROW_TOL sigma_1 (the
run started at a singular position and left it). Each increase is a change of the
degrees of freedom and is reported with its time.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


# Redundant equations at an assembled configuration (position error ~1e-11 of the body
# length) have sigma ~1e-11 or less; independent ones of a mechanism away from a
# singular position have sigma of order 1e-3..1. The bands below sit between the two.
DECIDE_TOL = 1e-8        # sigma_k / sigma_1 above this counts as independent at the start
AMBIGUOUS_LOW = 1e-10    # ... and in [1e-10, 1e-6] the decision is called uncertain
GROW_TOL = 1e-6          # a rank increase during a run needs sigma_{r+1} / sigma_1 above
ROW_FLOOR = 1e-4         # rows are scaled to unit length, but not below this fraction
                         # of the largest row of their element (see row_scales)
KE_CUT_WARN = 1e-2       # a velocity projection removing this fraction of the kinetic
                         # energy is reported (accurate steps: ~1e-12 and less)
RANK_TOL = 1e-10         # QR pivot ratio at or below which a row is dropped (singular
                         # position) for one factorisation
SPLIT_COLUMNS = 150      # B of more columns is decided a connected component at a time
                         # (a 483-coordinate chain: 0.05 s in place of 0.25 s)


@dataclass(frozen=True)
class RankDecision:
    """The rank decided at a configuration and the singular values it rests on."""
    rank: int
    n_q: int
    sigma: tuple[float, ...]      # scaled singular values, largest first
    # how it was decided: "svd" (all singular values, one SVD per component),
    # "certified" (fccgen.rank.sparse, no dense SVD), or the SVD after a sparse test
    # that could not certify the gap (the reason follows "svd")
    how: str = field(default="svd", compare=False)

    @property
    def dof(self) -> int:
        return self.n_q - self.rank

    @property
    def uncertain(self) -> list[float]:
        """The relative singular values inside the uncertain band (empty: clear)."""
        if not self.sigma or self.sigma[0] <= 0.0:
            return []
        s1 = self.sigma[0]
        return [s / s1 for s in self.sigma if AMBIGUOUS_LOW * s1 <= s <= GROW_TOL * s1]

    @property
    def gap(self) -> tuple[float, float]:
        """(sigma_r / sigma_1, sigma_{r+1} / sigma_1): the last kept and the first
        dropped relative singular value (1 and 0 where there is none)."""
        if not self.sigma or self.sigma[0] <= 0.0:
            return 1.0, 0.0
        s1 = self.sigma[0]
        kept = self.sigma[self.rank - 1] / s1 if self.rank > 0 else 1.0
        dropped = self.sigma[self.rank] / s1 if self.rank < len(self.sigma) else 0.0
        return kept, dropped


def row_scales(B: np.ndarray, groups=None) -> np.ndarray:
    """The divisor of each row of B: max(||B_k||, ROW_FLOOR * the largest row norm of
    the element B_k belongs to), 1 for a zero row. ``groups``: per row, a label of its
    element (None: each row alone). A row whose gradient nearly vanishes (the
    component of point_on_line's cross product along its line) is a redundant
    combination of its element's other rows: scaled to unit length it would turn the
    position error into an apparent independent row."""
    return scales_from_norms(np.linalg.norm(np.asarray(B, float), axis=1), groups)


def scales_from_norms(norms: np.ndarray, groups=None) -> np.ndarray:
    """:func:`row_scales` from the row norms ||B_k||."""
    norms = np.asarray(norms, float)
    if groups is not None and norms.size:
        _, element = np.unique(np.asarray(groups), return_inverse=True)
        element = element.ravel()
        largest = np.zeros(element.max() + 1)
        # each element's largest row; a NaN row stays NaN (the run's checks name it)
        with np.errstate(invalid="ignore"):
            np.maximum.at(largest, element, norms)
        norms = np.maximum(norms, ROW_FLOOR * largest[element])
    return np.where(norms > 0.0, norms, 1.0)


def scaled_singular_values(B: np.ndarray, groups=None) -> np.ndarray:
    """Singular values of B with its rows divided by :func:`row_scales`."""
    B = np.asarray(B, float)
    if B.size == 0:
        return np.zeros(0)
    return np.linalg.svd(B / row_scales(B, groups)[:, None], compute_uv=False)



def dense_decision(sigma: np.ndarray, n_q: int) -> RankDecision:
    """The decision from all the scaled singular values (largest first)."""
    if not sigma.size or not np.all(np.isfinite(sigma)) or sigma[0] <= 0.0:
        return RankDecision(0, n_q, tuple(float(s) for s in sigma))
    rank = int(np.sum(sigma > DECIDE_TOL * sigma[0]))
    return RankDecision(rank, n_q, tuple(float(s) for s in sigma))

