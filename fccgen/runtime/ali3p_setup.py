"""The Python side of ALI3-P (fccgen/runtime/_ali3p.pyx): its options, its starting
accelerations, multipliers and penalties, and the sentences of its failures."""
from __future__ import annotations

import math

import numpy as np

from ..errors import SimulationError
from ..settings.methods import METHODS
from ._assemble import FLAGS
from ._messages import INPUTS

# penalty: per time unit squared, scaled per constraint row (see initial_state);
# newton_tol: relative to the largest body length; max_newton: iterations per step.
# The reasons for the values are in the docstring of _ali3p.pyx.
DEFAULTS = METHODS["ali3p"].defaults()      # one source: the method registry

# failure codes of _ali3p.pyx
FAIL_NEWTON, FAIL_TANGENT, FAIL_NONFINITE = 1, 2, 3
# The default penalty is raised at the start of a run until the slowest direction of
# the multiplier update shrinks at least (1 + PENALTY_RATIO)-fold per update (see
# initial_state), at most to PENALTY_AUTO_MAX; a step whose Newton iteration stalls
# raises it tenfold, at most MAX_PENALTY_RAISES times a run (_ali3p.pyx).
PENALTY_RATIO = 2.5
PENALTY_AUTO_MAX = 1e16
MAX_PENALTY_RAISES = 4
# non-finite inputs beyond those of _messages.INPUTS (1-based detail codes)
EXTRA_INPUTS = {9: "force Jacobian df/dq", 10: "force Jacobian df/dq'"}


def run_options(options, length: float) -> dict:
    """DEFAULTS updated with ``options`` (checked), plus ``tolerance``, the absolute
    Newton tolerance newton_tol * length."""
    opts = dict(DEFAULTS)
    for key, value in dict(options or {}).items():
        if key not in opts:
            raise ValueError(f"ali3p takes no option {key!r} (its options: "
                             f"{', '.join(DEFAULTS)})")
        value = float(value)
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f"option {key} of ali3p must be a positive number "
                             f"(got {value!r})")
        opts[key] = value
    if opts["max_newton"] != int(opts["max_newton"]):
        raise ValueError(f"option max_newton of ali3p must be a whole number "
                         f"(got {opts['max_newton']!r})")
    opts["max_newton"] = int(opts["max_newton"])
    opts["tolerance"] = opts["newton_tol"] * length
    opts["max_penalty_raises"] = MAX_PENALTY_RAISES
    return opts


def initial_state(engine, q0, v0, penalty: float, dt: float | None = None):
    """(q'', multipliers, alpha, hint, penalty) at the initial state: the accelerations
    of the engine's constrained solve, the least-squares multipliers of
    M q'' + B^T lambda = f - h (unique up to redundant rows, which the iteration
    leaves alone), and the per-row penalties alpha_k = penalty * m_ref / ||B_k||^2
    with m_ref the largest diagonal entry of M (a zero row gets penalty * m_ref).
    Also returns the text added to a failure of the first step (:func:`stiffness_hint`)
    and the penalty used: with ``dt`` (the penalty not given by the user), at least
    :func:`conditioned_penalty`."""
    asm = engine.asm
    a0 = engine.accelerations(q0, v0)
    M = asm.quantity(FLAGS["mass_matrix"], q0)
    B = asm.quantity(FLAGS["constraint_jacobian"], q0)
    rhs = (asm.quantity(FLAGS["applied_forces"], q0, v0)
           - asm.quantity(FLAGS["h_vector"], q0, v0) - M @ a0)
    lam = np.linalg.lstsq(B.T, rhs, rcond=None)[0] if B.shape[0] else np.zeros(0)
    m_ref = float(np.max(np.diag(M)))
    if not m_ref > 0:
        raise SimulationError("ali3p needs a mass matrix with a positive diagonal entry")
    hint = stiffness_hint(M, asm.quantity(FLAGS["force_jacobian_q"], q0, v0), penalty,
                          m_ref) if B.shape[0] else ""
    norms = np.sum(B * B, axis=1)
    if dt is not None and B.shape[0]:
        penalty = max(penalty, conditioned_penalty(B, norms, dt, engine.decided_rank))
    alpha = penalty * m_ref / np.where(norms > 0, norms, 1.0)
    return a0, lam, alpha, hint, penalty


def conditioned_penalty(B, norms, dt: float, rank: int) -> float:
    """The penalty at which a multiplier update shrinks g along the smallest kept
    singular direction of the row-scaled B (singular value s_r, r the decided rank)
    at least (1 + PENALTY_RATIO)-fold: PENALTY_RATIO * 4 / (dt^2 s_r^2), at most
    PENALTY_AUTO_MAX. The shrink factor is about 1 / (1 + (dt^2/4) penalty s^2) with
    alpha_k = penalty m_ref / ||B_k||^2 (docstring of _ali3p.pyx); the mass in that
    direction, at most m_ref, only makes it faster.

    Measured (h = 1e-3): the 12-unit scissor boom has s_r = 3.0e-3 and the 50-bay
    scissor mast 3.1e-4 (the four-bar 0.54, A02's chain 0.054, the A01 pendulum 1):
    with the fixed 1e9 (factor 0.998) their Newton iterations stall at corrections
    about twice the tolerance from t = 0.013 and 0.031 s on; with 1e12 (boom) and 1e14
    (mast), 2.2 and 2.4 in the formula above, they converge in at most 4 and 2
    iterations."""
    scaled = B / np.sqrt(np.where(norms > 0, norms, 1.0))[:, None]
    s = np.linalg.svd(scaled, compute_uv=False)
    if not s.size or not s[0] > 0:
        return 0.0
    r = rank if 0 < rank <= s.size else int(np.sum(s > 1e-8 * s[0]))
    s_r = s[r - 1]
    if not s_r > 0:
        return PENALTY_AUTO_MAX
    return min(PENALTY_RATIO * 4.0 / (dt * dt * s_r * s_r), PENALTY_AUTO_MAX)


def stiffness_hint(M, df_dq, penalty: float, m_ref: float) -> str:
    """What to use instead when ALI3-P's first steps fail on a model with a stiff
    spring: the largest |df/dq| diagonal entry K against the penalty's contribution
    penalty * m_ref. Measured on a rod held by a spring: with K / (penalty m_ref) of 0.1
    steps converge in 2-5 iterations; at 25 and 2,500 Newton stalls at t = 0 (each
    multiplier update shrinks g only by about K / (K + penalty m_ref)), although other
    geometries run at 1e4 -- so this is a hint for a failure, never a refusal. Empty
    when the stiffness is below the penalty."""
    k_max = float(np.max(np.abs(np.diag(df_dq)))) if df_dq.size else 0.0
    if not k_max > penalty * m_ref:
        return ""
    masses = np.diag(M)[np.diag(M) > 0]
    omega = float(np.sqrt(k_max / masses.min()))
    return (f"; its stiffest applied force (largest |df/dq| diagonal entry {k_max:.3g}, a "
            f"stiff spring) outweighs the constraint penalty (penalty x largest mass "
            f"entry = {penalty * m_ref:.3g}) {k_max / (penalty * m_ref):.3g} times, which "
            "stalls the augmented-Lagrangian iteration: use --method dopri5 (error "
            f"control follows the spring's frequency, about {omega:.3g} rad/s) or rk4 "
            f"with dt well below 2.8 / {omega:.3g} = {2.8 / omega:.3g}")


def failure_message(code: int, info: int, detail: int, t: float, h: float,
                    last_dq: float, tol: float) -> str:
    """One sentence: what failed in which step."""
    if code == FAIL_NEWTON:
        what = (f"the ALI3-P Newton iteration did not converge in {info} iterations "
                f"(last correction {last_dq:.3g}, tolerance {tol:.3g}); try a smaller dt "
                "or, near a singular position, a larger penalty")
    elif code == FAIL_TANGENT:
        what = (f"the ALI3-P tangent matrix M + (dt/2) C + (dt^2/4)(B^T alpha B + K) is "
                f"singular (LU pivot {info}): a coordinate without mass or too few "
                f"constraints")
    elif code == FAIL_NONFINITE:
        name = INPUTS[detail] if 0 < detail < len(INPUTS) else EXTRA_INPUTS.get(
            detail, "values")
        what = f"non-finite {name}"
    else:
        what = f"unknown ALI3-P failure {code}"
    return (f"simulation stopped at t = {t:.10g}: {what} in the ALI3-P step from "
            f"t = {t:.10g} (step size {h:.3g})")
