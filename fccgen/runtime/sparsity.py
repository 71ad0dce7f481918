"""Load-time analysis of the sparse path (runtime/_sparse.pyx): ordering, pattern and
scatter maps of the matrix it factors.

The sparse path factors A = M + B^T diag(alpha) B (n x n). Every element couples only
its own coordinates: its mass block and its constraint rows add a dense block on the
element's local coordinates (a clique of the coordinate graph) to A. So the pattern of
A is the union of these cliques, known from the elements' local -> global coordinate
maps before any number is computed. Here, once per solver:

0. the solver may narrow the cliques to the entries the element blocks hold at the
   written positions and at nearby ones where only the coordinates that sit off zero
   or move are moved (paths.pattern_samples, SparseBlocks.planar_pattern): a model
   written in a plane leaves out its out-of-plane couplings, guarded at every
   assembly;
1. a fill-reducing order of the coordinate graph (ORDERS: minimum degree, ties to
   the shorter chain of eliminations, then by index; reverse Cuthill-McKee as the
   alternative), with the coordinates no element couples (the pinned ones) moved to
   its end;
2. the upper triangle of the permuted A in compressed sparse columns (Ap, Ai);
3. for each element, where each of its local entries (a, b) goes: the index in A's
   value array of (perm(i), perm(j)), i = idx[a], j = idx[b], when perm(i) <= perm(j),
   else -1 (the symmetric entry is added by the pair (b, a) instead).

The symbolic factorisation (elimination tree, column counts) is done in C from (Ap, Ai)
when the structure is handed to the engine.
"""
from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee


@dataclass(frozen=True)
class Structure:
    """The pattern of A and the scatter maps (see the module docstring)."""
    n: int
    perm: np.ndarray          # new index -> coordinate
    Ap: np.ndarray            # n + 1 column starts of upper(P A P^T)
    Ai: np.ndarray            # row indices (each column sorted, diagonal last)
    emap_ptr: np.ndarray      # per element: start in emap (n_el + 1)
    emap: np.ndarray          # per element local pair (a, b), row-major: value index or -1


def cliques(q_ptr, q_idx, couples) -> list[np.ndarray]:
    """The distinct global coordinates of each element that adds to A (couples[e]:
    it has a mass matrix or constraint rows), an empty array for the others."""
    return [np.unique(q_idx[q_ptr[e]:q_ptr[e + 1]]) if couples[e] else
            np.zeros(0, dtype=np.intc) for e in range(len(couples))]


def adjacency(n: int, groups) -> list[set]:
    """The coordinate graph: i and j adjacent when an element couples both."""
    adj = [set() for _ in range(n)]
    for g in groups:
        for i in g:
            adj[i].update(g)
    for i in range(n):
        adj[i].discard(i)
    return adj


def minimum_degree(n: int, groups) -> np.ndarray:
    """Minimum-degree elimination order of the coordinate graph (eliminating a node
    joins its neighbours into a clique; the lowest current degree goes first). Ties go
    to the node with the shorter chain of eliminations below it (its level: one more
    than the highest level of the neighbours eliminated before it), then by index.
    The tie-break only chooses among equal degrees, and on the models measured the
    fill is the same as with ties by index (docs/performance.md); what it changes is
    the elimination tree: a chain of bodies is eliminated from both ends at once, in
    alternation, so that the factorisation and the triangular solves, which go down
    the tree one column after another, see two independent chains of arithmetic
    instead of one twice as long (the cart of 20 links: a tree 22 columns high
    instead of 42). Exact degrees, a heap with lazy deletion: fine for the few
    thousand coordinates of a model, run once per solver."""
    adj = adjacency(n, groups)
    level = [0] * n
    heap = [(len(adj[i]), 0, i) for i in range(n)]
    heapq.heapify(heap)
    done = np.zeros(n, dtype=bool)
    order = []
    while heap:
        d, h, i = heapq.heappop(heap)
        if done[i] or d != len(adj[i]) or h != level[i]:
            continue
        done[i] = True
        order.append(i)
        nbrs = adj[i]
        for j in nbrs:
            adj[j].discard(i)
            adj[j].update(nbrs)
            adj[j].discard(j)
            level[j] = max(level[j], level[i] + 1)
            heapq.heappush(heap, (len(adj[j]), level[j], j))
        adj[i] = set()
    return np.asarray(order, dtype=np.intc)


def rcm(n: int, groups) -> np.ndarray:
    """Reverse Cuthill-McKee order of the coordinate graph (SciPy)."""
    rows, cols = [], []
    for g in groups:
        rows.append(np.repeat(g, len(g)))
        cols.append(np.tile(g, len(g)))
    r = np.concatenate(rows + [np.arange(n)])
    c = np.concatenate(cols + [np.arange(n)])
    graph = coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)).tocsr()
    return np.asarray(reverse_cuthill_mckee(graph, symmetric_mode=True), dtype=np.intc)


ORDERS = {"minimum_degree": minimum_degree, "rcm": rcm}


def isolated_last(perm: np.ndarray, groups) -> np.ndarray:
    """perm with the coordinates that no group holds moved to its end, in their order.
    They couple to nothing, so the fill is the same; at the end they are columns that
    the factorisation and solves can leave out (SparseBlocks.set_structure: the pinned
    coordinates, whose column of A is a unit diagonal)."""
    held = np.zeros(len(perm), dtype=bool)
    for g in groups:
        held[np.asarray(g, dtype=np.intp)] = True
    return np.concatenate([perm[held[perm]], perm[~held[perm]]]).astype(np.intc)


def masked_edges(q_ptr, q_idx, couples, masks) -> list[np.ndarray]:
    """The coordinate pairs (i, j), i < j, that some element's block of A holds
    (masks: (mask_ptr, mask), element e's n_q x n_q mask row-major), each a 2-array."""
    mask_ptr, mask = masks
    pairs = set()
    for e in range(len(couples)):
        if not couples[e]:
            continue
        local = q_idx[q_ptr[e]:q_ptr[e + 1]]
        nq = len(local)
        blk = np.asarray(mask[mask_ptr[e]:mask_ptr[e + 1]]).reshape(nq, nq)
        for a, b in zip(*np.nonzero(blk | blk.T)):
            i, j = int(local[a]), int(local[b])
            if i < j:
                pairs.add((i, j))
    return [np.array(p, dtype=np.intp) for p in sorted(pairs)]


def structure(n: int, q_ptr, q_idx, couples, order: str = "minimum_degree",
              masks=None) -> Structure:
    """The :class:`Structure` of A for elements with local -> global maps (q_ptr,
    q_idx) (CSR style), of which those with couples[e] add to A: every element's
    block full (a clique of its coordinates), or with masks
    (``SparseBlocks.planar_pattern``) only the entries they hold, the others mapped
    to -1 (not assembled)."""
    q_ptr = np.asarray(q_ptr, dtype=np.intp)
    q_idx = np.asarray(q_idx, dtype=np.intp)
    groups = (cliques(q_ptr, q_idx, couples) if masks is None
              else masked_edges(q_ptr, q_idx, couples, masks))
    perm = isolated_last(ORDERS[order](n, [g for g in groups if len(g)]), groups)
    pinv = np.empty(n, dtype=np.intp)
    pinv[perm] = np.arange(n)
    entries = set((k, k) for k in range(n))          # the diagonal is always there
    for g in groups:
        p = pinv[g]
        for a in p:
            for b in p:
                if a <= b:
                    entries.add((int(a), int(b)))
    cols = [[] for _ in range(n)]
    for a, b in entries:
        cols[b].append(a)
    Ap = np.zeros(n + 1, dtype=np.intc)
    Ai = []
    where = {}
    for b in range(n):
        rows = sorted(cols[b])
        for a in rows:
            where[(a, b)] = len(Ai)
            Ai.append(a)
        Ap[b + 1] = len(Ai)
    emap_ptr = np.zeros(len(couples) + 1, dtype=np.intc)
    emap = []
    for e in range(len(couples)):
        local = q_idx[q_ptr[e]:q_ptr[e + 1]]
        if couples[e]:
            p = pinv[local]
            nq = len(local)
            keep = (np.ones((nq, nq), dtype=bool) if masks is None else
                    np.asarray(masks[1][masks[0][e]:masks[0][e + 1]]).reshape(nq, nq))
            keep = keep | keep.T
            for ia, a in enumerate(p):
                for ib, b in enumerate(p):
                    emap.append(where[(a, b)] if a <= b and (keep[ia, ib] or a == b)
                                else -1)
        emap_ptr[e + 1] = len(emap)
    return Structure(n, perm, Ap, np.asarray(Ai, dtype=np.intc), emap_ptr,
                     np.asarray(emap, dtype=np.intc))


def jacobian_csr(asm, q):
    """The constraint Jacobian B at q as a SciPy CSR matrix (n_g x n_q), from the
    assembler's element blocks (``Assembler.jacobian_triplets``; repeated entries of a
    shared coordinate are summed): no dense n_g x n_q array, what large models use."""
    rows, cols, values = asm.jacobian_triplets(q)
    return coo_matrix((values, (rows, cols)), shape=(asm.n_g, asm.n_q)).tocsr()
