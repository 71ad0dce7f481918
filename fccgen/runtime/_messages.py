"""Error messages of the compiled engine (the codes mirror the enums of engine/fcc_base.h)."""
from __future__ import annotations

# err_detail: which input was not finite (1-based).
INPUTS = ("", "coordinates q", "speeds v", "mass matrix M", "inertia terms h",
          "applied forces f", "constraint Jacobian B", "constraint bias (dB/dt) v",
          "constraints g")

ERR_SINGULAR, ERR_LAPACK, ERR_NONFINITE_INPUT, ERR_NONFINITE_RESULT = 1, 2, 3, 4
ERR_DIVERGED = 5
ERR_PATTERN = 6      # handled by the solver (it retries on the full pattern)
AT_CALL, AT_STAGE, AT_POSITIONS, AT_VELOCITIES, AT_STEP = 0, 1, 2, 3, 4


def error_message(rec: dict, in_run: bool) -> str:
    """One sentence: what failed, where in the step, and (in a run) the time."""
    code = rec["code"]
    if code == ERR_SINGULAR:
        what = ("mass matrix singular on the constraint manifold (a body or coordinate "
                "without mass or inertia, or too few constraints): the reduced mass "
                f"matrix (dimension {rec['nullity']}: {rec['n_q']} coordinates, "
                f"constraint Jacobian of rank {rec['rank']} with {rec['n_g']} rows) is not "
                f"positive definite at pivot {rec['info']}")
        if rec.get("sparse"):
            what += ("; on the sparse path it also is when a motion is about 1e9 or more "
                     "times lighter than the heaviest coordinate (the LDL^T of "
                     "M + B^T alpha B loses its pivot): if the model is meant so, use "
                     "--linear-solver dense (docs/reliability.md)")
    elif code == ERR_LAPACK:
        what = f"LAPACK reported error {rec['info']} in the constrained solve"
    elif code == ERR_NONFINITE_INPUT:
        what = f"non-finite {INPUTS[rec['detail']]}"
    elif code == ERR_DIVERGED:
        quantity = {1: "max |q|", 2: "max |v|",
                    3: "the constraint residual after the step"}[rec["detail"]]
        what = (f"the run diverged: {quantity} reached {rec['value']:.3g}, past the "
                f"bound {rec['bound']:.3g} set at its start from the initial state (see "
                "docs/reliability.md); the step is too large for the model's stiffness "
                "or speeds: use a smaller "
                "--dt, --method dopri5 (error control), or --method ali3p (implicit, for "
                "stiff springs)")
    elif code == ERR_NONFINITE_RESULT:
        what = "the constrained solve gave non-finite values from finite inputs"
    elif code == ERR_PATTERN:
        what = ("an element block entry that was zero at the written positions is not: "
                "the sparse pattern taken there no longer holds")
    else:
        what = f"unknown engine error {code}"
    where = rec["where"]
    if code == ERR_DIVERGED:
        place = ""
    elif where == AT_STAGE:
        place = (f" in RK4 stage {rec['stage']} of the step from t = {rec['t']:.10g} "
                 f"(step size {rec['h']:.3g})")
    elif where == AT_POSITIONS:
        place = " in the position projection"
    elif where == AT_VELOCITIES:
        place = " in the velocity projection"
    elif where == AT_STEP:
        place = " after the step"
    else:
        place = ""
    if in_run:
        return f"simulation stopped at t = {rec['t']:.10g}: {what}{place}"
    return what + place
