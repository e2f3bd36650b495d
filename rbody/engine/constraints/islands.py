"""The step's problem split into islands: sets of rows that share no dof, through M^-1, with the others.

Two rows are coupled (W = J M^-1 J^T nonzero between them) only where their columns of A = L^-T J^T share a dof
(tree_factor). A pile of bodies resting apart, or towers standing side by side, make one problem of many
independent blocks: solved as one, its exact finishes factor the whole of W, O(m^3); island by island they cost
the sum of the islands' cubes, and each island's Gauss-Seidel stops where that island is solved (MuJoCo's
mj_island does the same for its solver). A contact's rows (its normal, then its tangents, spin and rolling) stay
in one island whatever their Jacobians (a cone is solved whole).

island (m,) int64: a union-find forest over the rows (each row's parent; a root its own), then each row's island
(0 to count - 1, in the order of their first rows).
"""

import numpy as np
from numba import njit

from rbody.engine.constraints.cone import NORMAL


@njit(cache=True)
def find(island, a):
    """The root of row a's tree (its path pointed at the root on the way)."""
    root = a
    while island[root] != root:
        root = island[root]
    while island[a] != root:
        up = island[a]
        island[a] = root
        a = up
    return root


@njit(cache=True)
def join(island, a, b):
    """Rows a and b in one island (the root the smaller row)."""
    ra, rb = find(island, a), find(island, b)
    if ra < rb:
        island[rb] = ra
    elif rb < ra:
        island[ra] = rb


@njit(cache=True)
def label_islands(island, role, m):
    """island[:m] (the forest joined by shared dofs) <- each row's island, a contact's rows joined first. Returns
    the count."""
    for c in range(1, m):
        if role[c] > NORMAL:  # a tangent, spin or rolling row: with its contact's normal, the row before
            join(island, c - 1, c)
    for c in range(m):  # every row pointed at its root, the smallest row of its island
        island[c] = find(island, c)
    count = 0
    for c in range(m):  # rows ascending: a root's label is set before its other rows read it
        if island[c] == c:
            island[c] = count
            count += 1
        else:
            island[c] = island[island[c]]
    return count


__all__ = ["find", "join", "label_islands"]
