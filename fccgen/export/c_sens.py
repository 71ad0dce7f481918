"""Sensitivities in an exported C project (``fccgen export --c DIR --sensitivities``,
docs/export.md "Sensitivities").

The project then carries the model's parameter-derivative kernels (``dp_kernels.c``,
printed by fccgen.runtime.sensitivity.build, the module simulate(sensitivities=...)
compiles) and, per exported parameter key, what the Python run's set-up computes
before a run with sensitivities (fccgen.runtime.sensitivity.parameters.directions):
the elements' parameters' derivative dP and the start's derivative S0. The exported
engine carries them through RK4's stages, its projections and the events as
``simulate(sensitivities=...)`` does on the sparse path (engine/fcc_sens.h), so the two
agree to rounding. Golden values of a Python run with every key make the selftest.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FccgenError, ModelError
from ..render.escape import c_identifier
from . import c_data


def sens_keys(solver, keys) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(key, dP, S0) of each exported key that has a sensitivity (a key the set-up
    refuses, e.g. a structural zero, is left out), in the keys' order."""
    from ..runtime.sensitivity.parameters import directions
    out = []
    for key in keys:
        try:
            dP, S0 = directions(solver, [key])
        except ModelError:
            continue
        out.append((key, dP[0], S0[0]))
    return out


def table_symbol(model_name: str) -> str:
    """The C name of the parameter-derivative table (fccgen.runtime.sensitivity.build)."""
    return c_identifier(f"fccgen_dp_{model_name}")


def check(solver, keys, error_type) -> list:
    """The keys with sensitivities, or error_type saying why the model's run cannot
    carry them (the refusals of simulate(sensitivities=...))."""
    from ..runtime.sensitivity.geometry import kind
    from ..runtime.sensitivity.run import check_request
    # the exported engine runs the sparse path, which takes no geometry key (they can
    # move the coordinates it holds fixed): those keys are left out like the refused
    names = [k for k, _, _ in keys if kind(k) is None]
    if not names:
        raise error_type(f"{solver.plan.model.source}: --sensitivities: the export sets "
                         "no parameter of this model, so it has none to differentiate by")
    try:
        check_request(solver, names, solver.plan.model.simulate.method, True)
    except (ModelError, ValueError) as exc:
        raise error_type(f"--sensitivities: {exc}") from None
    found = sens_keys(solver, names)
    if not found:
        raise error_type(f"{solver.plan.model.source}: --sensitivities: no exported "
                         "parameter has a sensitivity (each was refused by the set-up)")
    return found


def golden_run(solver, found):
    """The Python run with every key's sensitivity (the model's simulate: settings)."""
    return solver.simulate(reactions=False, sensitivities=[k for k, _, _ in found])


def data(found, keys, solver) -> str:
    """The constants of the sensitivities in <name>_data.h (HAS_SENS 0 without)."""
    if found is None:
        return c_data.define("HAS_SENS", 0)
    plan = solver.plan
    n_q, n_p = plan.n_q, sum(len(el.params) for el in plan.elements)
    names = [k for k, _, _ in keys]
    index = {k: names.index(k) for k, _, _ in found}
    ptr, slots, values = [0], [], []
    for _, dP, _ in found:
        nz = np.flatnonzero(dP)
        slots += list(nz)
        values += list(dP[nz])
        ptr.append(len(slots))
    s0 = np.concatenate([S0 for _, _, S0 in found]) if n_q else []
    return "".join([
        c_data.define("HAS_SENS", 1), c_data.define("N_SENS", len(found)),
        c_data.define("N_PARAMS_ALLOC", max(1, n_p)),
        c_data.define("LENGTH_SCALE", float(solver.length_scale)),
        c_data.c_array("int", "SENS_KEY", [index[k] for k, _, _ in found]),
        c_data.c_array("int", "SENS_PTR", ptr), c_data.c_array("int", "SENS_SLOT", slots),
        c_data.c_array("double", "SENS_DP", values),
        c_data.c_array("double", "SENS_S0", s0)])


def golden(result, found, table) -> str:
    """selftest's sensitivities: d(column)/d(key) of the coordinate and speed columns
    (in the outputs' order) of every key, key-major, at the run's last record."""
    from ..runtime.sensitivity.columns import column_name
    from .c_outputs import Q, V
    names = [c for c, kind, _ in table.columns if kind in (Q, V)]
    values = [result.columns[column_name(col, key)][-1] for key, _, _ in found
              for col in names]
    return (c_data.define("N_GOLDEN_SENS", len(names))
            + c_data.c_array("double", "GOLDEN_SENS", values))


def files(solver, build_dir, progress=None) -> dict[str, str]:
    """dp_kernels.c and dp_kernels.h of the model (built, or found in build_dir)."""
    from ..runtime.sensitivity.build import build_dp
    built = build_dp(solver.plan, build_dir, progress=progress)
    folder = Path(built.directory)
    out = {}
    for name in ("dp_kernels.c", "dp_kernels.h"):
        path = folder / name
        if not path.exists():
            raise FccgenError(f"the parameter-derivative module in {folder} has no {name}: "
                              "remove the folder and export again")
        out[name] = path.read_text()
    return out
