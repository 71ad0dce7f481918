"""A static equilibrium as a result (docs/design.md §5, ``fccgen statics --out``): one
row at t = 0 of the result columns of section 4 (q at equilibrium, speeds zero), the
joint columns, each driver's force and each joint's reaction by name and component
(``A.fx`` ... ``A.tz``: the force and torque of joint A on its second body, global
frame), and, in ``info``, how it was made (provenance) and the equilibrium's figures.

At rest (v = 0) in equilibrium the accelerations vanish, so the reactions the
dynamics give at that state are the static ones (fccgen.mechanism.reactions).
A model given by points has no joints: its constraint forces are given per moving
point and vector instead, ``P.gx P.gy P.gz`` = -(B^T lambda) on P's coordinates
(with the solvers' convention M q'' + B^T lambda = f - h: what the constraints apply;
a force on a point, on a unit vector a force times a length), the sum over every
constraint row.
"""
from __future__ import annotations

import numpy as np


def equilibrium_result(solver, eq):
    """The one-row :class:`fccgen.results.result.Result` of ``eq`` (an Equilibrium of
    ``solver``)."""
    from ..mechanism.driver_forces import add_driver_columns
    from ..mechanism.reactions import add_reactions
    from ..numeric.record_loads import RecordLoads
    from ..results.provenance import provenance
    from ..results.result import _with_joint_columns, result_from_arrays
    q = np.asarray(eq.q, float)[None, :]
    v = np.zeros_like(q)
    body = np.asarray(solver.body_outputs(q[0], v[0])).reshape(1, len(solver.plan.bodies), 6)
    energy = np.array([solver.energy(q[0], v[0])])
    error = np.array([eq.constraint_residual])
    info = provenance(solver.plan)
    info.update(kind="static equilibrium", iterations=eq.iterations,
                load_steps=eq.load_steps, force_residual=eq.force_residual,
                force_scale=eq.force_scale, constraint_residual=eq.constraint_residual,
                dof=eq.dof, rank=eq.rank, constraint_rows=eq.n_g,
                stability=eq.stability, max_constraint_error=eq.constraint_residual,
                smallest_stiffness_eigenvalue=(float(eq.stiffness_eigenvalues[0])
                                               if eq.stiffness_eigenvalues.size else None))
    result = result_from_arrays(solver.plan, np.zeros(1), q, v, body, energy, error, info)
    result = _with_joint_columns(solver.plan, result)
    if getattr(solver.plan.model, "mechanism", None) is None:
        result.columns.update(constraint_forces(solver, eq))
        return result
    add_driver_columns(solver, result)
    # loads whose value is an expression and torsion springs: at t = 0 with the
    # parameters the equilibrium was solved with (the inputs' start values, the
    # planned references: a spring preloaded past half a turn is read as the
    # equilibrium's kernels read it)
    return add_reactions(solver, result, loads=RecordLoads(solver.plan, solver.put_params,
                                                           turns=False), references=True)


def constraint_forces(solver, eq) -> dict[str, np.ndarray]:
    """``N.gx N.gy N.gz`` per moving point or vector N: -B^T lambda on its
    coordinates, what the constraints apply to it."""
    forces = -(solver.constraint_jacobian(eq.q).T @ eq.multipliers)
    out = {}
    for k, (name, _) in enumerate(solver.plan.triples):
        for c, axis in enumerate("xyz"):
            out[f"{name}.g{axis}"] = np.array([forces[3 * k + c]])
    return out


def reaction_lines(result) -> list[str]:
    """The reactions and driver forces of an equilibrium result, one joint a line,
    with their units (the model's: force, force x length)."""
    from ..mechanism.reaction_bases import COMPONENTS
    lines = []
    joints = [n[:-3] for n in result.names if n.endswith(".fx")]
    if joints:
        lines.append("reactions (force fx fy fz and torque tx ty tz of each joint on its "
                     "second body, global frame; units: the model's force and force x "
                     "length):")
        for j in joints:
            parts = [f"{c} {result[f'{j}.{c}'][0]: .6g}" for c in COMPONENTS]
            lines.append(f"  {j:<10s} " + "  ".join(parts))
    for d in (n for n in result.names if n.endswith((".torque", ".force"))):
        unit = "force x length" if d.endswith(".torque") else "force"
        lines.append(f"driver {d} {result[d][0]: .12g} ({unit})")
    points = [n[:-3] for n in result.names if n.endswith(".gx")]
    if points:
        lines.append("constraint forces on each moving point and vector (-B^T lambda on "
                     "its x, y, z: what the constraints apply; units: the model's force on "
                     "a point, force x length on a vector):")
        for p in points:
            lines.append(f"  {p:<10s} " + "  ".join(
                f"{c} {result[f'{p}.{c}'][0]: .6g}" for c in ("gx", "gy", "gz")))
    return lines
