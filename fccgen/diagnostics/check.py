"""``fccgen check``: what a model is made of, its degrees of freedom counted and by
rank, which constraint equations are redundant, and the assembly residual.

Loading the model runs every rule of the model file, including the run settings of its
``simulate`` section exactly as ``fccgen simulate`` checks them (fccgen.settings.run),
so a model that check passes is one that simulate accepts with its own settings. A
number of the report that is not finite is an error, never a line of the report.

Generation too: unless told not to (``generate=False``, ``--no-generate``; the report
then says so), check derives every element class's kernels, prints them to C and
renders the sources, and does the same for the event kernels, as a build does before
it compiles: a model whose kernels cannot be generated fails check as it would fail
simulate (:class:`BuildError`, naming the file and the class). Only the compiler is
not run. Printed classes are kept per class key for the process, so that checking
models of the same structure again costs no derivation.

A model of more than fccgen.rank.sparse.DENSE_COMPONENT coordinates is checked a
connected component of its constraint Jacobian at a time (the rows of one component
depend only on each other), from B assembled sparse: a small component as a small
model is; a large one takes the rank decision of fccgen.rank.sparse, its redundant
rows from a certified LU (rank_rows.independent_rows) and the rows taking part in
its dependencies from the weights of rank_rows.dependency_weights (the same rule as
small models' SVD), left unnamed with a note above DEPENDENCY_REDUNDANT_MAX redundant
rows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ..analysis.cables import cable_lines
from ..mechanism.report import DEPENDENT_TOL, dependency_text, dependent_rows, rows_text
from .. import rank as rank_rule
from ..rank import rows as rank_rows
from ..rank import sparse as rank_sparse
from ..runs.explain import explained
from ..errors import BuildError, FccgenError, SimulationError, located_text
from ..settings.limits import check_notes
from ..settings.methods import names as method_names
from ..progress import Reporter
from ..threads import single_threaded_blas

# The rows taking part in the dependencies of a large component: from the weights of
# rank_rows.dependency_weights, O(R^3 + R^2 n) in its R redundant rows (2 s at the
# 1000-bar mast's 2002), left unnamed with a note above DEPENDENCY_REDUNDANT_MAX; where
# the LU's basis is not certified, from the dense SVD of small models (U: m x m, about
# 1.5 s at 1000 rows, 90 s at 5000), up to DEPENDENCY_ROWS_MAX rows.
DEPENDENCY_REDUNDANT_MAX = 3000
DEPENDENCY_ROWS_MAX = 1500
# Printed element classes by class key (see the module docstring), at most this many.
_PRINTED: dict = {}
PRINTED_KEPT = 1000
NOT_GENERATED = ("kernels not generated (check was told not to): simulate may still "
                 "refuse the model when it derives and prints its kernels")



@dataclass
class CheckReport:
    name: str
    source: str
    n_points: int
    n_vectors: int
    n_bodies: int
    n_q: int
    n_g: int
    rank: int
    rows: list[str]                           # label of every constraint equation
    redundant: list[str]                      # equations that depend on the others
    classes: list[str]                        # element class descriptions
    init_report: str
    notes: list[str] = field(default_factory=list)
    joints: list[str] = field(default_factory=list)    # what each joint was lowered to
    dependent: str = ""          # joints (and other rows) that take part in dependencies
    rank_gap: tuple[float, float] = (1.0, 0.0)    # sigma_r / sigma_1, sigma_{r+1} / sigma_1
    uncertain: list[float] = field(default_factory=list)   # sigma / sigma_1 in the band
    generation: str = ""         # what check generated (kernels, events), or that it did not
    cables: list[str] = field(default_factory=list)    # flexible members (analysis.cables)

    @property
    def dof_counted(self) -> int:
        return self.n_q - self.n_g

    @property
    def dof(self) -> int:
        return self.n_q - self.rank

    def text(self) -> str:
        lines = [
            f"model {self.name} ({self.source})",
            f"  moving points {self.n_points}, moving vectors {self.n_vectors}, "
            f"moving bodies {self.n_bodies}",
            f"  coordinates {self.n_q}, constraint equations {self.n_g}, "
            f"rank {self.rank}",
            f"  degrees of freedom: {self.dof_counted} counted (coordinates - equations), "
            f"{self.dof} by rank",
            f"  rank decision: last kept singular value {self.rank_gap[0]:.2g}, first "
            f"dropped {self.rank_gap[1]:.2g} (relative; the rule: docs/reliability.md)"
            + (f"; UNCERTAIN: {', '.join(f'{x:.2g}' for x in self.uncertain)} between "
               "1e-10 and 1e-6, the initial configuration is near a singular position"
               if self.uncertain else ""),
            f"  redundant constraint equations: {len(self.redundant)}",
        ]
        lines += [f"    {r}" for r in self.redundant]
        if self.dependent:
            lines.append(f"    rows taking part in the dependencies: {self.dependent}")
        if self.joints:
            lines.append("  joints (lowering):")
            lines += [f"    {j}" for j in self.joints]
        if self.cables:
            lines.append("  flexible members:")
            lines += [f"    {c}" for c in self.cables]
        lines.append(f"  element classes: {len(self.classes)}")
        lines += [f"    {c}" for c in self.classes]
        if self.generation:
            lines.append(f"  {self.generation}")
        lines.append("  initial state:")
        lines += ["    " + s for s in self.init_report.splitlines()]
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def constraint_row_labels(plan) -> list[str]:
    return [f"{el.label} ({row})" for el in plan.elements for row in el.cls.constraint_rows]


def redundant_rows(B: np.ndarray, labels: list[str], rank: int, groups=None):
    """The rows that depend on earlier ones, given the rank of B (fccgen.rank): those
    past the first ``rank`` columns of the QR with column pivoting of the scaled B^T
    (rows scaled per element, ``groups``)."""
    return [labels[k] for k in redundant_indices(B, rank, groups)]


def redundant_indices(B: np.ndarray, rank: int, groups=None) -> list[int]:
    """:func:`redundant_rows` as row indices, in increasing order."""
    if B.shape[0] == 0:
        return []
    scaled = B / rank_rule.row_scales(B, groups)[:, None]
    _, _, piv = scipy.linalg.qr(scaled.T, mode="economic", pivoting=True)
    return sorted(int(k) for k in piv[rank:])


def check_model(path, progress=None, *, generate: bool = True) -> CheckReport:
    """Validate a model and report its structure (needs no compiler). Errors name the
    model file. progress: a callback of fccgen.progress events ("check" stage), told
    of each step of a large model. generate: derive, print and render the kernels as a
    build does, without compiling them (module docstring); False: the report says
    they were not."""
    from ..api import load_numeric
    solver = load_numeric(path)
    source = str(solver.plan.model.source)
    say = Reporter(progress, "check")
    try:
        with single_threaded_blas():     # a spinning OpenBLAS doubled the CPU time of
            report = _report(solver, say)    # the 1000-bar check
    except SimulationError as exc:       # located at the written state (fccgen.runs.locate)
        raise explained(exc, solver, *_written_state(solver)) from None
    except FccgenError:                  # ModelError (a ValueError too) names its item
        raise
    except (ArithmeticError, ValueError) as exc:      # an expression at the start, ...
        raise explained(SimulationError(
            f"the initial state cannot be evaluated ({type(exc).__name__}: {exc})"),
            solver, *_written_state(solver)) from None
    report.generation = generate_kernels(solver.plan, say) if generate else NOT_GENERATED
    return report


def generate_kernels(plan, say=None) -> str:
    """Derive, print and render the kernels of ``plan`` (and its event kernels) as a
    build does before compiling; a line for the report. BuildError naming the model
    file and the class when a class cannot be generated."""
    from ..build.cache import structure_hash
    from ..derive import derive_class
    from ..printing import print_class
    from ..render import render_sources
    say = say or (lambda *args, **kwargs: None)
    source = plan.model.source
    classes = list(plan.classes)
    printed = []
    for k, cls in enumerate(classes, 1):
        if cls.key not in _PRINTED:
            say(f"check: deriving and printing class {k}/{len(classes)}", done=k - 1,
                total=len(classes))
            try:
                done = print_class(derive_class(cls))
            except Exception as exc:          # noqa: BLE001 -- any failure is the answer
                el = next(e for e in plan.elements if e.cls.key == cls.key)
                raise BuildError(located_text(
                    source, el.where.line, el.label,
                    f"the kernels of element class {cls.name} ({cls.describe()}) cannot "
                    f"be generated: {type(exc).__name__}: {exc}", show_value=False)) from None
            if len(_PRINTED) >= PRINTED_KEPT:
                _PRINTED.clear()
            _PRINTED[cls.key] = done
        printed.append(_PRINTED[cls.key])
    render_sources(plan.model.name, structure_hash(classes), printed, ["-O2"], [])
    line = (f"kernels: {len(classes)} element class{'es' if len(classes) != 1 else ''} "
            "derived, printed to C and rendered (not compiled)")
    if plan.model.events:
        from ..events.build import event_hash, print_kernels, render
        from ..events.symbolic import event_system
        try:
            system = event_system(plan)
            render(plan.model.name, f"{plan.model.name}_events", system,
                   [e.name for e in plan.model.events], print_kernels(system),
                   event_hash(system), ["-O2"])
        except Exception as exc:              # noqa: BLE001
            first = plan.model.events[0]
            raise BuildError(located_text(
                source, first.where.line, "events", "the event kernels cannot be "
                f"generated: {type(exc).__name__}: {exc}", show_value=False)) from None
        line += f"; event kernels of {len(plan.model.events)} events too"
    return line


def _report(solver, report) -> CheckReport:
    plan = solver.plan
    large = plan.n_q > rank_rule.dense_columns_max()
    say = report if large else (lambda *args, **kwargs: None)
    say(f"check: initial state ({plan.n_q} coordinates, {plan.n_g} equations)")
    init = _initial_state(solver)
    labels = constraint_row_labels(plan)
    B = solver.constraint_jacobian_sparse(init.q) if large else \
        solver.constraint_jacobian(init.q)
    model = plan.model
    _require_finite(model.source, {
        "the assembled positions q": init.q, "the projected velocities v": init.v,
        "the constraint Jacobian B": B.data if large else B,
        "the residuals": [init.position_residual_given, init.position_residual,
                          init.velocity_change, init.velocity_residual]})
    with np.errstate(all="ignore"):               # a nan is the answer, not a warning
        forces = solver.applied_forces(init.q, init.v)
    _require_finite(model.source, {"the applied forces (loads and springs)": forces},
                    "; a load or spring is singular at the start (a spring whose ends "
                    "coincide?)")
    say("check: rank decision")
    decision = rank_rule.decide(B, B.shape[1], plan.row_groups)
    rank = max(decision.rank, 0)
    notes = list(plan.notes)
    notes += check_notes(model, method_names())
    joints = model.mechanism is not None         # the dependencies are named by joint
    if large:
        redundant, dependent = _large_rows(B, labels, rank, plan.row_groups, notes, say,
                                           joints)
    else:
        redundant = redundant_rows(B, labels, rank, plan.row_groups)
        dependent = dependency_text(B, rank, labels) if joints else ""
    return CheckReport(
        name=model.name, source=str(model.source),
        n_points=len(model.moving_points), n_vectors=len(model.moving_vectors),
        n_bodies=len(plan.bodies), n_q=plan.n_q, n_g=plan.n_g, rank=rank,
        rows=labels, redundant=redundant,
        classes=[f"{c.name}: {c.describe()}" for c in plan.classes],
        init_report=init.report(), notes=notes,
        joints=model.mechanism.describe() if model.mechanism is not None else [],
        dependent=dependent,
        rank_gap=tuple(decision.gap), uncertain=list(decision.uncertain),
        cables=cable_lines(plan))


def _initial_state(solver):
    """The solver's initial state; a division by zero or an invalid value met on the
    way (a warning of NumPy, which would only be printed) is a SimulationError naming
    the file, as simulate stops on the nan it makes."""
    import warnings
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            return solver.initial_state()
    except (RuntimeWarning, ArithmeticError) as exc:
        raise explained(SimulationError(
            f"the initial state cannot be evaluated ({exc}): a load or spring is "
            "singular at the start"), solver, *_written_state(solver)) from None


def _written_state(solver):
    """(q, v) as the model file writes them, where a failure at the start is located."""
    return np.array(solver.plan.q0, float), np.array(solver.plan.v_target, float)


def _large_rows(B, labels, rank, groups, notes, say,
                dependencies: bool = True) -> tuple[list[str], str]:
    """(redundant rows, rows taking part in the dependencies: '' unless
    ``dependencies``) of a large model, a connected component of B at a time (module
    docstring); notes gets what was not computed. The components' ranks must add up to ``rank`` (the decision of the
    whole), else the whole is taken as one dense component (slow, the small models'
    rule)."""
    groups = None if groups is None else np.asarray(groups)
    B = sp.csr_matrix(B, copy=True)
    B.eliminate_zeros()          # components() labels a row by its first stored column
    parts = [(rows, cols) for rows, cols in rank_sparse.components(B) if rows.size]
    small = rank_rule.dense_columns_max()
    ranks = [rank_rule.decide(B[rows][:, cols].toarray() if cols.size <= small
                              else B[rows][:, cols], cols.size,
                              None if groups is None else groups[rows]).rank
             for rows, cols in parts]
    if sum(ranks) != rank or min(ranks, default=0) < 0:
        say(f"check: redundant equations by a dense QR of {B.shape[0]} x {B.shape[1]}")
        notes.append("the ranks of the connected components of the constraint "
                     "Jacobian do not add up to its rank (singular values near the "
                     "rule's threshold): the redundant equations are those of the "
                     "whole, the rows taking part in the dependencies are not named")
        return redundant_rows(B.toarray(), labels, rank, groups), ""
    redundant, dependent, unnamed = [], [], []          # row indices of B
    for (rows, cols), r in zip(parts, ranks):
        if r == rows.size:
            continue
        part_groups = None if groups is None else groups[rows]
        Bc = B[rows][:, cols]
        if cols.size <= rank_rule.dense_columns_max():
            Bc = Bc.toarray()
            found = redundant_indices(Bc, r, part_groups)
            taking = dependent_rows(Bc, r) if dependencies else []
        else:
            found, taking = _large_component(Bc, r, part_groups, say, dependencies)
        if taking is None:
            unnamed.append(f"{rows.size} x {cols.size}")
        else:
            dependent += [int(rows[k]) for k in taking]
        redundant += [int(rows[k]) for k in found]
    if unnamed:
        notes.append(
            "the rows taking part in the dependencies of the component(s) of "
            f"{', '.join(unnamed)} equations x coordinates are not named: at this size "
            f"(over {DEPENDENCY_REDUNDANT_MAX} redundant rows, or {DEPENDENCY_ROWS_MAX} "
            "rows where the LU's choice was not certified) that costs O(m^3) (an "
            "orthonormal basis of the left null space); the redundant equations listed "
            "are exact. To see which joints take part, check a smaller model of the same "
            "structure (fewer repeated units) or the one part of interest")
    return [labels[k] for k in sorted(redundant)], rows_text(sorted(dependent), labels)


def _large_component(Bc, r: int, groups, say, dependencies: bool = True):
    """(redundant rows, rows taking part in the dependencies: None when not computed,
    [] unless ``dependencies``) of one component of more than DENSE_COMPONENT coordinates, indices of
    its rows: the certified LU's basis (rank_rows.independent_rows) and the weights
    of rank_rows.dependency_weights; the dense QR and SVD of small models where the
    LU's choice is not certified."""
    m, n = Bc.shape
    say(f"check: redundant equations of a component of {m} x {n} (LU)")
    keep = rank_rows.independent_rows(rank_sparse.scaled(Bc, groups), r)
    if keep is None:
        say(f"check: redundant equations of a component of {m} x {n} (dense QR: the "
            "LU's choice was not certified)")
        dense = Bc.toarray()
        found = redundant_indices(dense, r, groups)
        if not dependencies:
            return found, []
        if m > DEPENDENCY_ROWS_MAX:
            return found, None
        say(f"check: rows taking part in the dependencies (dense SVD of {m} rows)")
        return found, dependent_rows(dense, r)
    found = np.setdiff1d(np.arange(m), keep)
    if not dependencies:
        return found, []
    if found.size > DEPENDENCY_REDUNDANT_MAX:
        return found, None
    say(f"check: rows taking part in the dependencies ({found.size} redundant rows)")
    norms = np.sqrt(np.asarray(Bc.multiply(Bc).sum(axis=1)).ravel())
    Bs = (sp.diags(1.0 / np.where(norms > 0.0, norms, 1.0)) @ Bc).tocsr()
    weights = rank_rows.dependency_weights(Bs, keep)
    return found, np.flatnonzero(weights > DEPENDENT_TOL)


def _require_finite(source: str, arrays: dict, why: str = "; the model's numbers are "
                    "too far apart in size for double precision"):
    """SimulationError naming the first of ``arrays`` holding a nan or an infinity."""
    for what, values in arrays.items():
        values = np.asarray(values, dtype=float)
        if not np.all(np.isfinite(values)):
            bad = next(float(x) for x in values.ravel() if not math.isfinite(x))
            raise SimulationError(f"{source}: {what} of the initial state are not finite "
                                  f"(found {bad!r}){why}")
