"""The compiled assembler of a plan: a generated module's kernels bound to the plan's
instance data (the element classes, coordinates, parameters and time slots)."""
from __future__ import annotations

import numpy as np

from ..errors import BuildError
from ._assemble import Assembler


def make_assembler(plan, module) -> Assembler:
    """Bind a generated module's kernels to the plan's instance data (checked)."""
    try:
        capsule = module.table_capsule()
        structure_hash = module.STRUCTURE_HASH
    except AttributeError as exc:
        raise BuildError(f"{getattr(module, '__name__', module)!r} is not a generated "
                         f"kernel module ({exc})") from None
    els = plan.elements
    q_idx = [el.q_index() for el in els]
    q_ptr = np.concatenate([[0], np.cumsum([len(i) for i in q_idx])])
    p_ptr = np.concatenate([[0], np.cumsum([len(el.params) for el in els])])
    asm = Assembler(
        capsule, [c.name for c in plan.classes],
        np.array([(c.n_q, c.n_p, c.n_g) for c in plan.classes], dtype=np.intc).reshape(-1, 3),
        np.asarray(plan.class_of, dtype=np.intc), q_ptr,
        np.concatenate(q_idx) if q_idx else np.zeros(0, np.intc), p_ptr,
        np.concatenate([el.params for el in els]) if els else np.zeros(0),
        plan.n_q, np.array([e for _, e in plan.bodies], dtype=np.intc),
        structure_hash=structure_hash, owner=module)
    asm.set_time_slots(time_slots(plan))
    return asm


def time_slots(plan) -> np.ndarray:
    """Indices into the concatenated element parameters of every parameter named "t"
    (element classes whose equations depend on the time, such as drivers)."""
    slots, start = [], 0
    for el in plan.elements:
        if "t" in el.cls.param_names:
            slots.append(start + el.cls.param_names.index("t"))
        start += len(el.params)
    return np.array(slots, dtype=np.intc)
