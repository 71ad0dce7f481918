"""The sparse path's set-up analysis: what the C engine's pattern (engine/fcc_sparse.h,
fcc_pattern) is made of, decided once per engine from the element blocks at a few
coordinate vectors.

* :func:`pinned_view`: the coordinates that linear constraints with constant rows hold
  still, and those rows (the solve then works on the other coordinates and rows);
* :func:`planar_masks`: the entries of each element's block of A that are nonzero at
  the samples (a model written and moving in a plane keeps the others exactly zero),
  and the guards of the entries left out;
* :func:`structure_entries`: each element's entries of A and their places, from the
  scatter maps of fccgen.runtime.sparsity.

``el`` below describes the elements (SparseEngine._elements): per element its class's
nq, ng and whether it has a mass matrix (has_m), constraint rows (has_b) and
time-dependent constraints (has_rate); qptr/qidx its coordinates, gptr its first row,
mptr/bptr the start of its mass and Jacobian blocks.
"""
from __future__ import annotations

import hashlib
import threading

import numpy as np

# A block entry zero where the pattern of A was taken (planar_masks) may grow to
# GUARD_TOL of its block's largest entry before the pattern trips: the factor of A then
# misses entries of that relative size. The refinement's residuals use the full blocks,
# so the solve still converges to the system's solution, except along directions it
# leaves undetermined: 1e-8 let Bricard's Newton projection from 1e-9 off the
# constraints land 1.8e-8 from the dense path's point (the redundant row there is
# independent to 1e-9). Rounding makes such entries nonzero too (a coordinate held at
# zero by a constraint gets 1e-17 from the solves), far below 1e-12.
GUARD_TOL = 1e-12
# A row pins its last free coordinate only when that entry is at least PIN_PIVOT of
# the row's norm: the pinned coordinate then follows from the row without amplifying
# rounding (rows of the constraints that pin in practice, planes and "perpendicular to
# a fixed vector", have entries of one size).
PIN_PIVOT = 1e-3


def _pin(taken, norms):
    """The coordinates pinned by the rows taken (pinned_view): {row: {coordinate:
    entry}}; a row with one coordinate not yet pinned pins it, repeatedly (a queue over
    the rows' counts of coordinates not yet pinned)."""
    rows_of = {}
    left = {}
    for row, coef in taken.items():
        left[row] = len(coef)
        for j in coef:
            rows_of.setdefault(j, []).append(row)
    queue = sorted(row for row, k in left.items() if k == 1)
    pinned = set()
    while queue:
        row = queue.pop()
        if left[row] != 1:
            continue
        j = next(j for j in taken[row] if j not in pinned)
        if abs(taken[row][j]) < PIN_PIVOT * norms[row]:
            continue
        pinned.add(j)
        for other in rows_of[j]:
            left[other] -= 1
            if left[other] == 1:
                queue.append(other)
    return pinned


def _constant_rows(el, blocks, g0, position_tol):
    """The rows whose Jacobian entries are the same in every block array of blocks
    (one per sample), whose element does not depend on the time, and that hold at the
    first sample to the position tolerance: ({row: {coordinate: entry}}, {row:
    (element, local row)}, {row: norm})."""
    taken, where, norms = {}, {}, {}
    for e in range(len(el.nq)):
        if not el.has_b[e] or el.has_rate[e]:
            continue
        nq, ng = int(el.nq[e]), int(el.ng[e])
        idx = [int(i) for i in el.qidx[el.qptr[e]:el.qptr[e] + nq]]
        for r in range(ng):
            at = int(el.bptr[e]) + r * nq
            entries = blocks[0][at:at + nq]
            if any(not np.array_equal(entries, b[at:at + nq]) for b in blocks[1:]):
                continue
            norm = float(np.sqrt(np.dot(entries, entries)))
            row = int(el.gptr[e]) + r
            if not (norm > 0.0 and abs(g0[row]) <= position_tol * norm):
                continue
            coef = {}
            for a in range(nq):
                coef[idx[a]] = coef.get(idx[a], 0.0) + float(entries[a])
            taken[row] = {j: x for j, x in coef.items() if x != 0.0}
            where[row] = (e, r)
            norms[row] = norm
    return taken, where, norms


def pinned_view(el, blocks, g0, position_tol):
    """The solve's view, or None when no coordinate is pinned. A row is taken when its
    Jacobian entries are the same at every sample (blocks: the Jacobian blocks at each;
    fccgen.runtime.paths.pattern_samples moves every coordinate that sits off zero or
    moves, so a row that depends on one changes), its element does not depend on the
    time, and it holds at the first sample to the position tolerance
    (|g_k| <= position_tol ||B_k||, g0 the constraints there). Among those rows, one
    whose entries are zero but for one coordinate not yet pinned (and that entry at
    least PIN_PIVOT of the row's norm) pins it; pinning repeats until no row pins
    another (a point on the plane z = 0 pins its z, then a body's "perpendicular to z"
    row pins the next point's z, and so on down a planar chain). The taken rows whose
    every entry is on pinned coordinates are *fixed*: they hold B_R x = 0 with x = 0
    on the pinned coordinates (their right-hand sides vanish: constant rows of a
    constraint that holds), so the accelerations, speed changes and Newton steps of
    the pinned coordinates are zero, and the solve works on the other coordinates and
    rows alone. The engine keeps checking that the fixed rows keep their entries
    (GUARD_TOL of the row's largest) and hold (position_tol); otherwise the pattern
    trips and the solver redoes the call on the full pattern.

    Returns the arguments of fcc_pattern_set_view as a dict of lists (kept for the
    process by the bytes of its inputs, _VIEWS: a solver of other masses, whose
    Jacobian blocks at the same samples are the same, takes the same view; the caller
    only reads it)."""
    h = hashlib.sha256(repr(float(position_tol)).encode())
    for a in [el.nq, el.ng, el.has_b, el.has_rate, el.qptr, el.qidx, el.gptr, el.bptr,
              g0, *blocks]:
        a = np.ascontiguousarray(a)
        h.update(repr((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    key = h.hexdigest()
    with _views_lock:
        if key in _VIEWS:
            return _VIEWS[key]
    view = _pinned_view(el, blocks, g0, position_tol)
    with _views_lock:
        _VIEWS[key] = view
        while len(_VIEWS) > _VIEWS_KEPT:
            _VIEWS.pop(next(iter(_VIEWS)))
    return view


_VIEWS: dict = {}
_VIEWS_KEPT = 16
_views_lock = threading.Lock()


def _pinned_view(el, blocks, g0, position_tol):
    """pinned_view's analysis, not kept."""
    taken, where, norms = _constant_rows(el, blocks, g0, position_tol)
    pinned = _pin(taken, norms)
    if not pinned:
        return None
    fixed = sorted(row for row, coef in taken.items() if set(coef) <= pinned)
    fixed_set = set(fixed)
    view = dict(snq=[], sloc=[], sng=[], srloc=[], efix=[0.0] * len(el.nq),
                fixed_off=[], fixed_val=[], fixed_tol=[])
    for e in range(len(el.nq)):
        nq, ng = int(el.nq[e]), int(el.ng[e])
        free = [a for a in range(nq) if int(el.qidx[el.qptr[e] + a]) not in pinned]
        kept = [r for r in range(ng) if int(el.gptr[e]) + r not in fixed_set]
        view["snq"].append(len(free))
        view["sloc"] += free
        view["sng"].append(len(kept))
        view["srloc"] += kept
    for row in fixed:
        e, r = where[row]
        nq = int(el.nq[e])
        at = int(el.bptr[e]) + r * nq
        entries = blocks[0][at:at + nq]
        if norms[row] > view["efix"][e]:
            view["efix"][e] = norms[row]
        view["fixed_off"] += range(at, at + nq)
        view["fixed_val"] += entries.tolist()
        view["fixed_tol"] += [GUARD_TOL * float(np.max(np.abs(entries)))] * nq
    view.update(pinned=sorted(pinned), fixed_rows=fixed,
                fixed_norm=[norms[row] for row in fixed],
                fixed_g_tol=[position_tol * norms[row] for row in fixed])
    return view


def view_entries(el, pinned, fixed, n, m):
    """(in_m, in_b): for each entry of the mass and Jacobian blocks, whether the
    solve's view reads it (its coordinates free, its row kept)."""
    is_pinned = np.zeros(n, dtype=bool)
    is_pinned[pinned] = True
    is_fixed = np.zeros(m, dtype=bool)
    is_fixed[fixed] = True
    in_m = np.zeros(el.mptr[-1], dtype=bool)
    in_b = np.zeros(el.bptr[-1], dtype=bool)
    for e in range(len(el.nq)):
        nq = int(el.nq[e])
        free = ~is_pinned[el.qidx[el.qptr[e]:el.qptr[e] + nq]]
        if el.mptr[e + 1] > el.mptr[e]:
            in_m[el.mptr[e]:el.mptr[e + 1]] = np.outer(free, free).ravel()
        rows = ~is_fixed[el.gptr[e]:el.gptr[e + 1]]
        if el.bptr[e + 1] > el.bptr[e]:
            in_b[el.bptr[e]:el.bptr[e + 1]] = np.outer(rows, free).ravel()
    return in_m, in_b


def _largest_by_row(a: np.ndarray, nz: np.ndarray) -> np.ndarray:
    """Per row of ``a`` (k x w), the largest |entry| where ``nz``, NaN ignored (0 for a
    row with none)."""
    if a.shape[1] == 0:
        return np.zeros(a.shape[0])
    a = np.abs(a)
    return np.where(nz & ~np.isnan(a), a, 0.0).max(axis=1)


def planar_masks(el, samples, view=None):
    """The pattern of A from the element blocks at the samples (a list of (Mblk,
    Bblk) arrays, one pair per coordinate vector): the entries (a, b) of each element's
    block of A nonzero at any of them (M_ab != 0 or B_ra B_rb != 0 for some row r, a
    NaN counting as nonzero), and the offsets of the block entries of M and B zero at
    all of them, each with its guard: GUARD_TOL times the largest entry of its block.
    view: (in_m, in_b) of view_entries when the solve has a view (entries on a pinned
    coordinate or in a fixed row need no guard: the solve never reads them).

    The elements of one block shape (n_q, rows, whether a mass block) are taken
    together, one array operation per shape and sample.

    Returns (mask_ptr, mask, zero_m, tol_m, zero_b, tol_b); mask is each coupling
    element's full n_q x n_q block, row-major."""
    nq_all = np.asarray(el.nq, dtype=np.intp)
    ng_all = np.asarray(el.ng, dtype=np.intp)
    mptr = np.asarray(el.mptr, dtype=np.intp)
    bptr = np.asarray(el.bptr, dtype=np.intp)
    couples = np.asarray(el.has_m, dtype=bool) | (ng_all > 0)
    ptr = np.concatenate([[0], np.cumsum(nq_all ** 2 * couples)]).astype(np.intp)
    mask = np.zeros(ptr[-1], dtype=bool)
    zero_m = np.ones(mptr[-1], dtype=bool)
    zero_b = np.ones(bptr[-1], dtype=bool)
    scale_m = np.zeros(len(nq_all))
    scale_b = np.zeros(len(nq_all))
    has_mblk = mptr[1:] > mptr[:-1]
    shapes = np.stack([nq_all, ng_all, has_mblk.astype(np.intp)], axis=1)
    for shape in np.unique(shapes[couples], axis=0):
        nq, ng, hm = (int(x) for x in shape)
        members = np.flatnonzero(couples & np.all(shapes == shape, axis=1))
        at_mask = ptr[members][:, None] + np.arange(nq * nq)
        at_m = mptr[members][:, None] + np.arange(nq * nq) if hm else None
        at_b = bptr[members][:, None] + np.arange(ng * nq)
        for mblk, bblk in samples:
            block = np.zeros((len(members), nq * nq), dtype=bool)
            if hm:
                mb = np.asarray(mblk)[at_m]
                nz = mb != 0.0
                block |= nz
                zero_m[at_m] &= ~nz
                scale_m[members] = np.maximum(scale_m[members], _largest_by_row(mb, nz))
            bb = np.asarray(bblk)[at_b]
            nzb = bb != 0.0
            zero_b[at_b] &= ~nzb
            scale_b[members] = np.maximum(scale_b[members], _largest_by_row(bb, nzb))
            rows = nzb.reshape(len(members), ng, nq)
            block |= (rows[:, :, :, None] & rows[:, :, None, :]).any(axis=1).reshape(
                len(members), nq * nq)
            mask[at_mask] |= block
    if view is not None:
        zero_m &= view[0]
        zero_b &= view[1]
    offs_m = np.flatnonzero(zero_m)
    offs_b = np.flatnonzero(zero_b)
    tol_m = GUARD_TOL * np.repeat(scale_m, np.diff(mptr))[offs_m]
    tol_b = GUARD_TOL * np.repeat(scale_b, np.diff(bptr))[offs_b]
    return ptr, mask, offs_m, tol_m, offs_b, tol_b


def view_masks(masks, locals_, couples):
    """The masks of planar_masks (mask_ptr, mask: each coupling element's full
    n_q x n_q block) narrowed to the solve's view: locals_ = (sizes, s_ptr, s_loc) of
    SparseEngine.solve_locals, couples of SparseEngine.solve_elements."""
    ptr, mask = masks
    sizes, s_ptr, s_loc = locals_
    parts = []
    for e in range(len(sizes)):
        if couples[e]:
            loc = s_loc[s_ptr[e]:s_ptr[e + 1]]
            full = np.asarray(mask[ptr[e]:ptr[e + 1]]).reshape(sizes[e], sizes[e])
            parts.append(full[np.ix_(loc, loc)].ravel())
        else:
            parts.append(np.zeros(0, dtype=bool))
    view_ptr = np.concatenate([[0], np.cumsum([p.size for p in parts])]).astype(np.intp)
    return view_ptr, (np.concatenate(parts) if parts else np.zeros(0, dtype=bool))


def structure_entries(emap_ptr, emap, snq, nnz_a):
    """Each element's entries of A on the solve's view from its scatter map (emap:
    per local pair (a, b) of the view, row-major, the value's index in A or -1):
    (ent_ptr, ent_a, ent_b, ent_pos) as intc arrays. Raises ValueError when a map does
    not match the view or points outside A."""
    epv = np.asarray(emap_ptr, dtype=np.intp)
    ev = np.asarray(emap, dtype=np.intp)
    snq = np.asarray(snq, dtype=np.intp)
    if ev.size and not (np.all(ev >= -1) and np.all(ev < nnz_a)):
        raise ValueError("scatter map index out of range")
    sizes = np.diff(epv)
    if np.any((sizes > 0) & (sizes != snq ** 2)):
        raise ValueError("the scatter map does not match the solve's view")
    element = np.repeat(np.arange(len(sizes)), sizes)
    local = np.arange(ev.size) - np.repeat(epv[:-1], sizes)
    keep = ev >= 0
    nq = snq[element]
    counts = np.bincount(element[keep], minlength=len(sizes))
    ent_ptr = np.concatenate([[0], np.cumsum(counts)])
    as_int = (lambda x: np.ascontiguousarray(x, dtype=np.intc))
    return (as_int(ent_ptr), as_int((local // np.maximum(nq, 1))[keep]),
            as_int((local % np.maximum(nq, 1))[keep]), as_int(ev[keep]))
