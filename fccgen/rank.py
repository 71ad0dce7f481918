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

import warnings
from dataclasses import dataclass

import numpy as np

from .errors import RunWarning

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


@dataclass(frozen=True)
class RankDecision:
    """The rank decided at a configuration and the singular values it rests on."""
    rank: int
    n_q: int
    sigma: tuple[float, ...]      # scaled singular values, largest first

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
        groups = np.asarray(groups)
        largest = np.zeros(norms.size)
        for label in np.unique(groups):
            rows = groups == label
            largest[rows] = norms[rows].max()
        norms = np.maximum(norms, ROW_FLOOR * largest)
    return np.where(norms > 0.0, norms, 1.0)


def scaled_singular_values(B: np.ndarray, groups=None) -> np.ndarray:
    """Singular values of B with its rows divided by :func:`row_scales`."""
    B = np.asarray(B, float)
    if B.size == 0:
        return np.zeros(0)
    return np.linalg.svd(B / row_scales(B, groups)[:, None], compute_uv=False)


def decide(B: np.ndarray, n_q: int | None = None, groups=None) -> RankDecision:
    """The rank of B by the SVD gap test (see the module docstring); groups: the
    element of each row (:func:`row_scales`). B of more than
    fccgen.rank_sparse.DENSE_COMPONENT columns (dense or SciPy sparse) is decided a
    connected component at a time, the large ones without a dense SVD
    (:func:`fccgen.rank_sparse.decide_large`: the same rule, certified)."""
    from . import rank_sparse
    if not hasattr(B, "shape"):
        B = np.asarray(B, float)
    n_q = B.shape[1] if n_q is None else n_q
    if B.shape[1] > rank_sparse.DENSE_COMPONENT:
        return rank_sparse.decide_large(B, n_q, groups)
    B = np.asarray(B, float)
    if not np.all(np.isfinite(B)):        # the run's own checks name the bad input
        return RankDecision(-1, n_q, ())
    return dense_decision(scaled_singular_values(B, groups), n_q)


def dense_columns_max() -> int:
    """The most columns :func:`decide` takes through one dense SVD."""
    from .rank_sparse import DENSE_COMPONENT
    return DENSE_COMPONENT


def dense_decision(sigma: np.ndarray, n_q: int) -> RankDecision:
    """The decision from all the scaled singular values (largest first)."""
    if not sigma.size or not np.all(np.isfinite(sigma)) or sigma[0] <= 0.0:
        return RankDecision(0, n_q, tuple(float(s) for s in sigma))
    rank = int(np.sum(sigma > DECIDE_TOL * sigma[0]))
    return RankDecision(rank, n_q, tuple(float(s) for s in sigma))


def run_findings(decision: RankDecision, stats: dict,
                 driven: bool = False) -> tuple[dict, list[str]]:
    """(info entries, warning texts) of a run from its start decision and the rank
    statistics its factorisations gathered (Engine.rank_statistics or the numeric
    solver's equivalent); driven: the model has drivers (0 degrees of freedom is
    then a motion prescribed in full, not a mistake)."""
    increases = [tuple(x) for x in stats.get("increases", [])]
    final_rank = increases[-1][2] if increases else decision.rank
    info = dict(rank=decision.rank, dof=decision.dof,
                final_dof=decision.n_q - final_rank,
                rank_gap=list(decision.gap),
                singular_position_factorisations=int(stats.get("drops", 0)),
                smallest_kept_pivot=float(stats.get("smallest_kept", 1.0)),
                largest_dropped_pivot=float(stats.get("largest_dropped", 0.0)),
                rank_svd_checks=int(stats.get("svd_checks", 0)),
                dof_changes=[dict(t=float(t), dof_before=decision.n_q - a,
                                  dof_after=decision.n_q - b) for t, a, b in increases],
                projection_energy_cut=float(stats.get("kinetic_energy_cut", 0.0)))
    warnings = []
    if "sparse_solves" in stats:
        info.update(sparse_solves=int(stats["sparse_solves"]),
                    sparse_unconverged_solves=int(stats["sparse_unconverged"]),
                    sparse_dense_fallbacks=int(stats["sparse_dense_fallbacks"]),
                    sparse_beyond_rank_solves=int(stats.get("sparse_beyond_rank", 0)))
        text = sparse_solve_warning(info)
        if text:
            warnings.append(text)
    if decision.dof == 0 and final_rank == decision.rank and not driven:
        warnings.append(
            "the model has 0 degrees of freedom by rank (every coordinate is fixed by "
            "the constraints): nothing can move; if it should, a constraint is doubled "
            "or too strict (fccgen check lists the redundant equations)")
    if decision.uncertain:
        warnings.append(
            "the initial configuration is close to a singular position: relative "
            f"singular values {', '.join(f'{s:.2g}' for s in decision.uncertain)} of the "
            f"constraint Jacobian lie between {AMBIGUOUS_LOW:g} and {GROW_TOL:g}, so the "
            f"degrees of freedom at the start are uncertain; the run counts "
            f"{decision.dof} and raises the rank if the mechanism leaves that position; "
            "move the initial positions away from it for a clear decision")
    cut = float(stats.get("kinetic_energy_cut", 0.0))
    if cut > KE_CUT_WARN:
        warnings.append(
            f"a velocity projection removed {100 * cut:.3g}% of the kinetic energy at "
            f"t = {float(stats.get('kinetic_energy_cut_t', 0.0)):.6g} (accurate steps "
            "remove far less than 1e-6 %): the constraints forbid a motion the "
            "integrator made. Check the degrees of freedom (fccgen check), redundant or "
            "contradictory constraints, and the step size")
    for t, a, b in increases:
        warnings.append(
            f"the degrees of freedom changed from {decision.n_q - a} to {decision.n_q - b} "
            f"at t = {t:.6g}: the run started at a singular position of the constraints "
            "and left it; results before that time follow the singular configuration")
    return info, warnings


def sparse_solve_warning(info: dict) -> str:
    """The warning of a run on the sparse path whose refinement did not converge in
    some solves (info from :func:`run_findings`); "" when every solve converged."""
    bad = info["sparse_unconverged_solves"]
    if not bad:
        return ""
    redone = info["sparse_dense_fallbacks"]
    beyond = info.get("sparse_beyond_rank_solves", 0)
    why = ("the constraint Jacobian is ill-conditioned: near a singular position, or a "
           "structure with nearly dependent constraints")
    if beyond:
        why += (f"; {beyond} of them reached a row dependent only on the constraints "
                "(a linkage mobile by its geometry), which the dense path leaves out")
    text = (f"{bad} of the sparse path's {info['sparse_solves']} constrained solves did "
            f"not converge ({why}); ")
    if redone == bad:
        return text + ("the dense solve redid each of them, so the results hold; "
                       "--linear-solver dense avoids the retries")
    return text + (f"{bad - redone} of them were kept as they were (the dense solve "
                   f"redid {redone}): the accelerations there may be wrong; run with "
                   "--linear-solver dense (linear_solver='dense')")


def report_run(result, decision: RankDecision, stats: dict, driven: bool = False):
    """Add the rank findings of a run to ``result.info`` (and its ``warnings`` list)
    and issue each warning as a :class:`~fccgen.errors.RunWarning`; returns result."""
    info, texts = run_findings(decision, stats, driven)
    result.info.update(info)
    result.info.setdefault("warnings", []).extend(texts)
    for text in texts:
        warnings.warn(text, RunWarning, stacklevel=3)
    return result
