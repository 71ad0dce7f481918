"""The element of a force or torque whose expressions read joint quantities (kinds
force_q, torque_q; docs/elements.md "Loads of joint quantities").

Per joint quantity family (fccgen.mechanism.joint_loads.JointUse) the element carries
its triples under the prefix "J.family." and the scalars that make the quantity 0 at
the initial configuration:

* angle: with p = r_ij - lam u (lam = r_ij . u, so p is perpendicular to the axis u)
  on both sides, theta_init = atan2(u.(p_A x p_B), p_A.p_B); cos0, sin0 = cos, sin
  theta_init, so that the angle atan2(S, C) with S = cos0 D - sin0 P,
  C = cos0 P + sin0 D (D = u.(p_A x p_B), P = p_A.p_B) is theta - theta_init; the
  reference th, cr, sr (0, 1, 0; the runtime moves it) counts turns, as the torsion
  spring's;
* position: s0 = u.(r_b - r_a) at the start.
"""
from __future__ import annotations

import numpy as np



def triple_value(model, name: str) -> np.ndarray:
    """The initial value of a point or vector of the (lowered) model."""
    if name in model.points:
        return np.asarray(model.points[name].at, float)
    return np.asarray(model.vectors[name].along, float)


def joint_scalars(model, use) -> dict[str, float]:
    """The scalars of one JointUse, prefixed "J.family."."""
    prefix = f"{use.joint}.{use.family}."
    value = {name: triple_value(model, name) for name in use.triples}
    if use.family == "position":
        u, ra, rb = (value[n] for n in use.triples)
        return {prefix + "s0": float(u @ (rb - ra))}
    a_i, a_j, b_i, b_j, axis = use.triples
    u = value[axis]
    lam, ref = [], []
    for i, j in ((a_i, a_j), (b_i, b_j)):
        rij = value[j] - value[i]
        lam.append(float(rij @ u))
        ref.append(rij - lam[-1] * u)
    theta = float(np.arctan2(u @ np.cross(ref[0], ref[1]), ref[0] @ ref[1]))
    return {prefix + "lA": lam[0], prefix + "lB": lam[1],
            prefix + "cos0": float(np.cos(theta)), prefix + "sin0": float(np.sin(theta)),
            prefix + "th": 0.0, prefix + "cr": 1.0, prefix + "sr": 0.0}


ROLES = {"angle": ("A.ri", "A.rj", "B.ri", "B.rj", "u"), "position": ("u", "ra", "rb")}


def joint_load_element(b, ld, label: str, kind: str, own: dict):
    """The force_q or torque_q element of ``ld`` (``own``: its body-load scalars)."""
    body = b.model.bodies[ld.body]
    l, alpha, beta = b.frames[ld.body]
    scalars = {"l": l, "alpha": alpha, "beta": beta, **own}
    triples = [("ri", body.i), ("rj", body.j), ("u", body.u)]
    for use in ld.joints:
        scalars.update(joint_scalars(b.model, use))
        triples += [(f"{use.joint}.{use.family}.{role}", name)
                    for role, name in zip(ROLES[use.family], use.triples)]
    header = ",".join(f"{u.joint}:{u.family}" for u in ld.joints)
    return b.element(kind, label, ld.where, scalars, triples,
                     function=f"{header}|{ld.function}")
