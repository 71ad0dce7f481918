/* The engine's error record in one sentence, for programs that hold the engine
 * without Python (the Python build words the same record in
 * fccgen/runtime/_messages.py, with pointers into the documentation). */
#include <stdio.h>

#include "fcc_engine.h"

static const char *const INPUTS[] = {
    "values", "coordinates q", "speeds v", "mass matrix M", "inertia terms h",
    "applied forces f", "constraint Jacobian B", "constraint bias (dB/dt) v",
    "constraints g"
};

static const char *what(const fcc_engine *e)
{
    switch (e->err) {
    case FCC_ERR_SINGULAR:
        return "mass matrix singular on the constraint manifold (the reduced mass "
               "matrix is not positive definite)";
    case FCC_ERR_LAPACK: return "LAPACK reported an error in the constrained solve";
    case FCC_ERR_NONFINITE_INPUT: return "non-finite";
    case FCC_ERR_NONFINITE_RESULT:
        return "the constrained solve gave non-finite values from finite inputs";
    case FCC_ERR_DIVERGED: return "the run diverged: the state passed its bound";
    case FCC_ERR_PATTERN:
        return "an element block entry that was zero where the sparse pattern was "
               "taken is not";
    case FCC_ERR_MEMORY: return "an allocation failed";
    case FCC_ERR_NO_LAPACK:
        return "a feature of the dense path was asked for without a LAPACK table";
    case FCC_ERR_ARGUMENT: return "the engine cannot take this call";
    default: return "no error";
    }
}

static const char *place(const fcc_engine *e)
{
    switch (e->err_where) {
    case FCC_AT_STAGE: return " in an integrator stage";
    case FCC_AT_POSITIONS: return " in the position projection";
    case FCC_AT_VELOCITIES: return " in the velocity projection";
    case FCC_AT_STEP: return " after the step";
    default: return "";
    }
}

const char *fcc_engine_message(fcc_engine *e)
{
    int detail = e->err_detail >= 0 && e->err_detail <= 8 ? e->err_detail : 0;
    if (e->err == FCC_ERR_NONFINITE_INPUT)
        snprintf(e->message, FCC_MESSAGE_SIZE, "error %d at t = %.10g: non-finite %s%s",
                 e->err, e->err_t, INPUTS[detail], place(e));
    else
        snprintf(e->message, FCC_MESSAGE_SIZE, "error %d at t = %.10g: %s (info %d)%s",
                 e->err, e->err_t, what(e), e->err_info, place(e));
    return e->message;
}
