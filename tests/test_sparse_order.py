"""The sparse path's elimination order (fccgen.runtime.sparsity.minimum_degree): a
minimum-degree order whose ties go to the node with the shorter chain of eliminations
below it. On a chain this eliminates from both ends at once: the same fill as from one
end (none), and an elimination tree half as high, which the factorisation and the
triangular solves walk one column after another."""
from __future__ import annotations

import numpy as np

from fccgen.runtime.sparsity import minimum_degree, structure


def _tree(st):
    """(strict lower nonzeros of L, height of the elimination tree) of the structure's
    upper(P A P^T), by the textbook row-subtree walk (Liu), written here apart from
    the engine's C code."""
    n = st.n
    parent = [-1] * n
    ancestor = [-1] * n
    for k in range(n):
        for p in range(st.Ap[k], st.Ap[k + 1]):
            i = int(st.Ai[p])
            while i != -1 and i < k:
                nxt = ancestor[i]
                ancestor[i] = k
                if nxt == -1:
                    parent[i] = k
                i = nxt
    height = [1] * n
    for k in range(n):
        if parent[k] >= 0:
            height[parent[k]] = max(height[parent[k]], height[k] + 1)
    fill, mark = 0, [-1] * n
    for k in range(n):
        mark[k] = k
        for p in range(st.Ap[k], st.Ap[k + 1]):
            i = int(st.Ai[p])
            while i < k and mark[i] != k:
                fill += 1
                mark[i] = k
                i = parent[i]
    return fill, max(height)


def _chain(n):
    """A chain of n coordinates, each coupled to the next (q_ptr, q_idx, couples)."""
    q_idx = np.array([i + d for i in range(n - 1) for d in (0, 1)])
    return np.arange(0, 2 * n - 1, 2), q_idx, [True] * (n - 1)


def test_a_chain_is_eliminated_from_both_ends():
    """Ten coordinates in a chain: the order alternates between the ends; L has the
    chain's 9 entries (no fill) and the tree is 5 columns high plus its root
    (one-ended: 10)."""
    q_ptr, q_idx, couples = _chain(10)
    groups = [q_idx[q_ptr[e]:q_ptr[e] + 2] for e in range(9)]
    assert minimum_degree(10, groups).tolist() == [0, 9, 1, 8, 2, 7, 3, 6, 4, 5]
    fill, height = _tree(structure(10, q_ptr, q_idx, couples))
    assert (fill, height) == (9, 6)


def test_a_chain_of_three_coordinate_points_keeps_its_fill():
    """A chain of 12 points with 3 coordinates each, each point coupled to the next
    (a clique of 6): eliminating a point from an end makes no fill beyond its own
    block, from either end, so L has 3 + 3 * 3 entries per link as from one end, and
    the tree is about half as high as the 36 columns."""
    points, coords = 12, 3
    q_ptr = np.arange(0, 2 * coords * points - 2 * coords + 1, 2 * coords)
    q_idx = np.array([coords * (i + d) + c for i in range(points - 1)
                      for d in (0, 1) for c in range(coords)])
    fill, height = _tree(structure(coords * points, q_ptr, q_idx, [True] * (points - 1)))
    one_ended = coords * (coords - 1) // 2 * points + coords * coords * (points - 1)
    assert fill == one_ended
    assert height <= coords * points // 2 + coords
