"""The Python side of ALI3-P (fccgen/runtime/_ali3p.pyx): its options, its starting
accelerations, multipliers and penalties, and the sentences of its failures."""
from __future__ import annotations

import math

import numpy as np

from ..errors import SimulationError
from ..methods import METHODS
from ._assemble import FLAGS
from ._messages import INPUTS

# penalty: per time unit squared, scaled per constraint row (see initial_state);
# newton_tol: relative to the largest body length; max_newton: iterations per step.
# The reasons for the values are in the docstring of _ali3p.pyx.
DEFAULTS = METHODS["ali3p"].defaults()      # one source: the method registry

# failure codes of _ali3p.pyx
FAIL_NEWTON, FAIL_TANGENT, FAIL_NONFINITE = 1, 2, 3
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
    return opts


def initial_state(engine, q0, v0, penalty: float):
    """(q'', multipliers, alpha) at the initial state: the accelerations of the
    engine's constrained solve, the least-squares multipliers of
    M q'' + B^T lambda = f - h (unique up to redundant rows, which the iteration
    leaves alone), and the per-row penalties alpha_k = penalty * m_ref / ||B_k||^2
    with m_ref the largest diagonal entry of M (a zero row gets penalty * m_ref).
    Refuses (SimulationError) a model whose springs outweigh the penalty
    (:func:`check_stiffness`)."""
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
    if B.shape[0]:
        check_stiffness(M, asm.quantity(FLAGS["force_jacobian_q"], q0, v0), penalty, m_ref)
    norms = np.sum(B * B, axis=1)
    alpha = penalty * m_ref / np.where(norms > 0, norms, 1.0)
    return a0, lam, alpha


# The stiffness of the applied forces may be at most this multiple of the penalty's
# contribution to the tangent. Measured on a rod held by a spring (k / m = 1e8, 1e10,
# 1e12 per s^2, dt = 1e-3, default penalty 1e9): ratio 0.1 runs in 2-5 iterations per
# step, ratio 10 and 1000 stop at t = 0 with Newton stalled (each multiplier update
# shrinks g only by k / (k + penalty)); raising the penalty to outweigh the spring
# makes the tangent so ill-conditioned that Newton diverges (1e13 and up).
STIFFNESS_RATIO_MAX = 1.0


def check_stiffness(M, df_dq, penalty: float, m_ref: float) -> None:
    """Refuse, at the start, a model whose applied-force stiffness K = -df/dq
    outweighs the penalty (max |K_ii| > STIFFNESS_RATIO_MAX * penalty * m_ref): the
    augmented-Lagrangian iteration then cannot converge, and the message says what to
    use instead."""
    k_max = float(np.max(np.abs(np.diag(df_dq)))) if df_dq.size else 0.0
    if not k_max > STIFFNESS_RATIO_MAX * penalty * m_ref:
        return
    masses = np.diag(M)[np.diag(M) > 0]
    omega = float(np.sqrt(k_max / masses.min()))
    raise SimulationError(
        f"ali3p cannot converge on this model: its stiffest applied force (largest "
        f"|df/dq| diagonal entry {k_max:.3g}, a stiff spring) outweighs the constraint "
        f"penalty (penalty x largest mass entry = {penalty * m_ref:.3g}) by "
        f"{k_max / (penalty * m_ref):.3g} times, and the augmented-Lagrangian iteration "
        f"stalls. Use --method dopri5 (error control follows the spring's frequency, "
        f"about {omega:.3g} rad/s) or rk4 with dt well below 2.8 / {omega:.3g} = "
        f"{2.8 / omega:.3g}")


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
