"""What a run reports about its rank: the info entries and warnings from the start
decision (fccgen.rank.rule) and the statistics its factorisations gathered."""
from __future__ import annotations

import warnings

from ..errors import RunWarning
from .rule import AMBIGUOUS_LOW, GROW_TOL, KE_CUT_WARN, RankDecision


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
                    sparse_beyond_rank_solves=int(stats.get("sparse_beyond_rank", 0)),
                    sparse_iterations=int(stats.get("sparse_iterations", 0)),
                    sparse_most_iterations=int(stats.get("sparse_most_iterations", 0)))
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
