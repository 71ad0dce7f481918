"""Static equilibrium: Newton's method on the constrained equilibrium equations.

With the solver's convention M q'' + B^T lambda = f - h, an equilibrium (q' = 0,
q'' = 0, so h = 0) solves

    r(q, lambda) = f(q, 0) - B(q)^T lambda = 0,        g(q) = 0.

Newton's tangent is [[K_f - H, -B^T], [B, 0]] with K_f = df/dq and
H = sum_k lambda_k Hess(g_k) (exact, see :mod:`.tangent`). B may be rank-deficient
(redundant constraints), so each step is solved in the null-space form: with N an
orthonormal basis of ker B(q) and lambda the least-squares multipliers of the iterate
(B^T lambda ~ f, the minimum-norm set where rows are redundant),

    dq = dq_p + N z,     dq_p = -B^+ g                      (minimum-norm correction)
    K_r z = N^T (f + (K_f - H) dq_p),   K_r = N^T (H - K_f) N   (reduced stiffness).

K_r is the Hessian of the potential energy restricted to the constraint manifold when
the loads are conservative: positive definite means a stable equilibrium. Where it is
not (the iterate is near an unstable or indifferent configuration, e.g. a pendulum
started horizontal), the step is shifted towards descent and limited in length, so the
iteration settles where the structure would come to rest. When that fails from the
start, the loads are scaled by s and s is stepped up from 0 to 1 (halving the step
after a failure, doubling it after a success).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SimulationError
from ..runs.locate import loads_location
from .tangent import amax, bases, curvature, min_norm_multipliers

FORCE_RTOL = 1e-11       # max |N^T f| relative to the largest applied force entry
POSITION_RTOL = 1e-13    # max |g_k| / ||B_k|| relative to the largest body length
                         # (rounding of g = |r|^2 - l^2 is ~1e-16 l^2, of B ~1e-16 l)
STEP_RTOL = 1e-13        # a Newton step this small (relative to the largest length)
                         # ends the iteration too: stiff elastic members (EA of 1e5
                         # and more) cancel internal forces far larger than the loads,
                         # whose rounding then exceeds FORCE_RTOL of the loads
MIN_LOAD_STEP = 2.0 ** -12
MAX_ITERATIONS = 30


@dataclass
class Equilibrium:
    """A static equilibrium found by :func:`statics` and what it rests on."""
    q: np.ndarray
    multipliers: np.ndarray          # lambda per constraint row (minimum-norm if redundant)
    iterations: int                  # Newton iterations over all load steps
    load_steps: int                  # 1: a plain Newton solve from the start
    force_residual: float            # max |N^T f(q, 0)|
    force_scale: float               # max |f(q, 0)| (1 when the loads vanish)
    constraint_residual: float       # max |g(q)|
    reduced_stiffness: np.ndarray    # K_r = N^T (H - K_f) N
    null_basis: np.ndarray           # N
    rank: int                        # rank of B at q
    n_g: int
    names: list[str] = field(default_factory=list)    # coordinate names, P.x ...
    row_labels: list[str] = field(default_factory=list)   # model item of each row
    internal: set = field(default_factory=set)   # coordinates the lowering made (A_axis.x)

    @property
    def dof(self) -> int:
        return self.null_basis.shape[1]

    @property
    def redundant(self) -> int:
        return self.n_g - self.rank

    @property
    def stiffness_eigenvalues(self) -> np.ndarray:
        """Eigenvalues of the symmetric part of K_r, ascending."""
        K = self.reduced_stiffness
        return np.linalg.eigvalsh(0.5 * (K + K.T)) if K.size else np.zeros(0)

    @property
    def stability(self) -> str:
        """'stable' (K_r positive definite), 'unstable' (a negative eigenvalue) or
        'neutral' (the smallest is zero within 1e-9 of the largest: rigid motions)."""
        eig = self.stiffness_eigenvalues
        if not eig.size:
            return "stable"
        tol = 1e-9 * max(float(np.max(np.abs(eig))), 0.0)
        if eig[0] > tol:
            return "stable"
        return "neutral" if eig[0] >= -tol else "unstable"

    def text(self, multipliers: bool = True) -> str:
        """The summary, the coordinates and (``multipliers``) the Lagrange multiplier
        of each constraint row with the model item that made the row. A multiplier's
        unit is force times length over the unit of its row's equation; the reactions
        by joint and component, in the model's units, are those of
        :mod:`fccgen.analysis.statics_result` (``fccgen statics`` prints them)."""
        lines = [self.summary(), "coordinates:"]
        lines += [f"  {n:<14s} {x: .12g}" for n, x in zip(self.names, self.q)
                  if n not in self.internal]
        if not multipliers:
            return "\n".join(lines)
        note = (" (minimum-norm set: the constraints are redundant)" if self.redundant
                else "")
        lines.append(f"Lagrange multipliers lambda of the constraint rows{note}:")
        labels = self.row_labels or [""] * len(self.multipliers)
        lines += [f"  [{k}] {x: .12g}  {label}" for k, (x, label) in
                  enumerate(zip(self.multipliers, labels))]
        return "\n".join(lines)

    def summary(self) -> str:
        """Iterations, residuals, rank and stability."""
        eig = self.stiffness_eigenvalues
        lines = [f"equilibrium after {self.iterations} Newton iterations in "
                 f"{self.load_steps} load step(s)",
                 f"residual: max |N^T f| {self.force_residual:.3g} (largest force "
                 f"{self.force_scale:.3g}), max |g| {self.constraint_residual:.3g}",
                 f"degrees of freedom {self.dof}, constraint rank {self.rank} of "
                 f"{self.n_g} rows"]
        if eig.size:
            lines.append(f"stability: {self.stability} (smallest eigenvalue of the "
                         f"reduced stiffness {eig[0]:.6g}, largest {eig[-1]:.6g})")
        else:
            lines.append("stability: no degree of freedom (a structure)")
        return "\n".join(lines)


def statics(solver, q0=None, *, force_rtol=FORCE_RTOL, max_iterations=MAX_ITERATIONS,
            min_load_step=MIN_LOAD_STEP) -> Equilibrium:
    """The static equilibrium reached by Newton's method from q0 (default: the model's
    initial configuration, assembled): the nearest one, or a stable one where the
    start is not near a stable equilibrium (see the module docstring). Converged when max |N^T f| <= force_rtol times the
    largest applied-force entry and max |g_k| / ||B_k|| <= POSITION_RTOL times the
    largest body length.
    Raises SimulationError when even the smallest load step fails."""
    q = np.array(solver.initial_state().q if q0 is None else q0, float)
    s, ds, iterations, steps = 0.0, 1.0, 0, 0
    while s < 1.0:
        target = min(1.0, s + ds)
        q_new, its, ok = _newton(solver, q, target, force_rtol, max_iterations)
        iterations += its
        if ok:
            q, s, steps = q_new, target, steps + 1
            ds *= 2.0
            continue
        ds *= 0.5
        if ds < min_load_step:
            where = loads_location(solver.plan.model)
            raise SimulationError.located(
                solver.plan.model.source, where.line, where.item,
                f"statics: Newton's method did not converge at load factor "
                f"{target:.6g} even with load steps of {2 * ds:.3g} (reached load factor "
                f"{s:.6g} after {iterations} iterations): the loads may have no "
                f"equilibrium (e.g. a free body under gravity); 'fccgen modes --about "
                f"initial' linearizes about the initial state instead", where.value)
    return _equilibrium(solver, q, iterations, steps)


def _newton(solver, q, s, force_rtol, max_iterations):
    """(q, iterations, converged) of Newton's method at load factor s.

    lambda is the least-squares multiplier of the current iterate, B^T lambda ~ f.
    Where the symmetric part of K_r is not positive definite (near an unstable or
    indifferent configuration) the step is shifted towards a descent step,
    (K_r + mu I) z = rhs, and its tangential part is limited to half the largest body
    length, so that the iteration settles in a stable equilibrium rather than
    stopping at an unstable one; near a stable one it is Newton's method.
    """
    zero = np.zeros(solver.n_q)
    q = q.copy()
    scale = None
    for it in range(max_iterations + 1):
        f = s * solver.applied_forces(q, zero)
        B, g = solver.constraint_jacobian(q), solver.constraints(q)
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
            return q, it, False
        N, _, _ = bases(solver, q)
        lam = min_norm_multipliers(B, f)
        if scale is None:
            scale = max(amax(f), 1e-300)
        if (amax(N.T @ f) <= force_rtol * scale
                and _scaled(g, B) <= POSITION_RTOL * solver.length_scale):
            return q, it, True
        if it == max_iterations:
            break
        J = s * solver.force_jacobian_q(q, zero) - curvature(solver, q, lam)
        dq_p = np.linalg.lstsq(B, -g, rcond=1e-10)[0] if g.size else zero
        z = _tangential_step(-N.T @ J @ N, N.T @ (f + J @ dq_p), scale,
                             solver.length_scale)
        q = q + dq_p + N @ z
        if (amax(dq_p + N @ z) <= STEP_RTOL * solver.length_scale
                and _scaled(g, B) <= POSITION_RTOL * solver.length_scale):
            return q, it + 1, True
    return q, max_iterations, False


def _tangential_step(K_r, rhs, force_scale, length):
    """z of K_r z = rhs, shifted and limited where K_r is not positive definite."""
    if not rhs.size:
        return rhs
    eig = np.linalg.eigvalsh(0.5 * (K_r + K_r.T))
    if eig[0] > 1e-9 * max(abs(eig[-1]), 0.0):
        return np.linalg.solve(K_r, rhs)
    mu = max(-eig[0], 0.0) + max(1e-2 * abs(eig[-1]), force_scale / length)
    z = np.linalg.solve(K_r + mu * np.eye(len(rhs)), rhs)
    size = np.linalg.norm(z)
    return z if size <= 0.5 * length else z * (0.5 * length / size)


def _scaled(g, B) -> float:
    """max_k |g_k| / ||B_k||, the measure of the solver's position tolerance."""
    if not g.size:
        return 0.0
    norms = np.linalg.norm(B, axis=1)
    return amax(g / np.where(norms > 0.0, norms, 1.0))


def _equilibrium(solver, q, iterations, steps) -> Equilibrium:
    zero = np.zeros(solver.n_q)
    f = solver.applied_forces(q, zero)
    B = solver.constraint_jacobian(q)
    lam = min_norm_multipliers(B, f)           # consistent with the final q
    N, _, rank = bases(solver, q)
    K_r = N.T @ (curvature(solver, q, lam) - solver.force_jacobian_q(q, zero)) @ N
    names = [f"{name}.{c}" for name, _ in solver.plan.triples for c in "xyz"]
    mechanism = getattr(solver.plan.model, "mechanism", None)
    made = set(mechanism.internal()) if mechanism is not None else set()
    return Equilibrium(q=q, multipliers=lam, iterations=iterations, load_steps=steps,
                       force_residual=amax(N.T @ f), force_scale=amax(f) or 1.0,
                       constraint_residual=amax(solver.constraints(q)),
                       reduced_stiffness=K_r, null_basis=N, rank=rank, n_g=solver.n_g,
                       names=names, row_labels=[solver.plan.elements[e].label
                                                for e in solver.row_groups],
                       internal={n for n in names if n.rsplit(".", 1)[0] in made})
