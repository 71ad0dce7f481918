"""The stacked Newton-Euler rows E x = b of the joint reactions
(:mod:`fccgen.mechanism.reactions`), with E in sparse form.

Each joint's unknowns touch only the six balance rows of its (at most two) moving
bodies, and a coordinate driver's one unknown the six rows of the body that carries its
point, so E (6 n_b x unknowns) has a fixed pattern over the records: a list of dense
6 x w blocks at fixed (row, column) offsets. :class:`System` keeps that pattern once
and the block values per record, (n, nnz); :meth:`System.matrix` gives one record's E
as CSR without ever forming the dense (n, 6 n_b, unknowns) array.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .body_motion import Motion
from .reaction_bases import bases


@dataclass
class System:
    """E (sparse, per record) and b of the reaction balance over n records.

    rows, cols: the pattern of E in CSR order (fixed); values: (n, nnz) in that order;
    b: (n, 6 n_b); spans: (Pf, Pt) per joint, (n, 3, n_f) and (n, 3, n_t)."""
    shape: tuple[int, int]
    indices: np.ndarray
    indptr: np.ndarray
    values: np.ndarray
    b: np.ndarray
    spans: list

    @property
    def n(self) -> int:
        return len(self.b)

    def matrix(self, k: int) -> sp.csr_matrix:
        """E of record k (CSR)."""
        return sp.csr_matrix((self.values[k], self.indices, self.indptr), shape=self.shape)

    def dense(self, rows=slice(None)) -> np.ndarray:
        """(n, 6 n_b, unknowns) E of the records ``rows`` as a dense array (small
        models and checks only)."""
        values = self.values[rows]
        out = np.zeros((len(values),) + self.shape)
        row_of = np.repeat(np.arange(self.shape[0]), np.diff(self.indptr))
        out[:, row_of, self.indices] = values
        return out


def system(plan, motion: Motion, index: dict[str, int], applied: np.ndarray,
           drivers, held=frozenset()) -> System:
    """The balance rows of the records of ``motion`` (module docstring;
    fccgen.mechanism.reactions for the rows' meaning). applied: (n, 6 n_b) applied
    forces and torques about the mass centres; drivers: (body, direction e, arm from
    its mass centre (n, 3)) of each coordinate driver, whose force acts along e at its
    point on that body; held: the (joint, quantity) pairs that events hold at these
    records (a lock widens its joint's subspace as a driver does)."""
    n, nb = motion.n, len(index)
    blocks: list[tuple[int, int, np.ndarray]] = []     # (row0, col0, (n, 6, w))
    spans, col = [], 0
    lowering = plan.model.mechanism
    driven: dict[str, set[str]] = {}
    for d in lowering.drivers:
        driven.setdefault(d.joint, set()).add(d.quantity)
    for joint, kind in held:
        driven.setdefault(joint, set()).add(kind)
    for jl in lowering.joints:
        p, Pf, Pt = bases(jl, motion, driven.get(jl.joint.name, frozenset()))
        nf, nt = Pf.shape[2], Pt.shape[2]
        for body, sign in zip(jl.joint.bodies, (-1.0, 1.0)):
            if body not in index:
                continue
            arm = p - motion.centre(body)[0]
            block = np.zeros((n, 6, nf + nt))
            block[:, :3, :nf] = sign * Pf
            block[:, 3:, :nf] = sign * np.cross(arm[:, :, None], Pf, axis=1)
            block[:, 3:, nf:] = sign * Pt
            blocks.append((6 * index[body], col, block))
        spans.append((Pf, Pt))
        col += nf + nt
    for body, e, arm in drivers:
        block = np.zeros((n, 6, 1))
        block[:, :3, 0] = e
        block[:, 3:, 0] = np.cross(arm, e)
        blocks.append((6 * index[body], col, block))
        col += 1
    indices, indptr, values = _csr(blocks, n, 6 * nb)
    inertial = np.zeros((n, 6 * nb))
    for body, k in index.items():
        inertial[:, 6 * k:6 * k + 3] = plan.model.bodies[body].mass * motion.centre(body)[1]
        inertial[:, 6 * k + 3:6 * k + 6] = motion.momentum_rate(body)
    return System((6 * nb, col), indices, indptr, values, inertial - applied, spans)


def _csr(blocks, n: int, n_rows: int):
    """(indices, indptr, values (n, nnz)) of the blocks in CSR order."""
    if not blocks:
        return np.zeros(0, np.int32), np.zeros(n_rows + 1, np.int32), np.zeros((n, 0))
    rows = np.concatenate([np.repeat(r0 + np.arange(6), b.shape[2]) for r0, _, b in blocks])
    cols = np.concatenate([np.tile(c0 + np.arange(b.shape[2]), 6) for _, c0, b in blocks])
    values = np.concatenate([b.reshape(n, -1) for _, _, b in blocks], axis=1)
    order = np.lexsort((cols, rows))
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n_rows))])
    return cols[order].astype(np.int32), indptr.astype(np.int32), values[:, order]

