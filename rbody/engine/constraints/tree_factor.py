"""The time-stepping's products through the tree's factor of the mass matrix (rbody.engine.mass_factor: M = L^T L,
L's entries only on each dof's ancestors).

The time-stepping's metric W = J M^-1 J^T is A^T A with A = L^-T J^T, and a row J of a point on a body has
nonzeros only on that body's path to the root, which L^-T keeps: A's columns are as sparse as J's rows. Each column
is solved on its row's support (the dofs of its bodies' paths), and W and A lam are summed dof by dof over the
columns a dof carries (two bodies in contact share a column's dofs; two apart share none): a step's products cost
the rows' supports, not rows x nv (a layer of 400 spheres: 1,200 rows of 2,400 dofs).

`parent` (nv,) int64: each dof's parent dof (-1 at a root), parent[i] < i (the tree's dof order). L's entries off
the ancestors are neither written nor read.
"""

import numpy as np
from numba import njit

from rbody.engine.constraints.islands import join


@njit(cache=True)
def tree_solve_rows_into(L, parent, J, index, m, A):
    """A (nv, m) = L^-T J[index[:m]]^T: the m rows solved together, from the leaves (each a column of A; the
    columns innermost, as solver.lower_solve_rows_into runs its dense twin)."""
    n = L.shape[0]
    for i in range(n):
        for c in range(m):
            A[i, c] = J[index[c], i]
    for i in range(n - 1, -1, -1):
        d = L[i, i]
        for c in range(m):
            A[i, c] /= d
        j = parent[i]
        while j >= 0:
            lij = L[i, j]
            for c in range(m):
                A[j, c] -= lij * A[i, c]
            j = parent[j]


@njit(cache=True)
def tree_solve_supports_into(L, parent, J, index, m, A, support, start, length):
    """tree_solve_rows_into column by column, each on its row's support: the dofs support[start[c]:start[c] +
    length[c]] (ascending, closed under parent: the paths of a contact's two bodies to the root) where row index[c]
    of J may be nonzero, or every dof where length[c] < 0. L^-T keeps a path's sparsity, so a column is 0 off its
    support, and those entries are not written (the readers below take the support). Each entry gets the operations
    the rows' solve gives it, in its order: the same bits."""
    n = L.shape[0]
    for c in range(m):
        a, s0, k = index[c], start[c], length[c]
        if k < 0:
            for i in range(n):
                A[i, c] = J[a, i]
            for i in range(n - 1, -1, -1):
                _eliminate(L, parent, A, i, c)
        else:
            for x in range(k):
                A[support[s0 + x], c] = J[a, support[s0 + x]]
            for x in range(k - 1, -1, -1):  # from the leaves
                _eliminate(L, parent, A, support[s0 + x], c)


@njit(cache=True, inline="always")
def _eliminate(L, parent, A, i, c):
    """A[i, c] final (divided by L_ii), then taken off its ancestors' entries: A[j, c] -= L_ij A[i, c]."""
    A[i, c] /= L[i, i]
    j = parent[i]
    while j >= 0:
        A[j, c] -= L[i, j] * A[i, c]
        j = parent[j]


@njit(cache=True)
def dof_columns(A, m, support, start, length, first, columns):
    """The columns of A (nv, m) nonzero on each dof, as lists: dof i's are columns[first[i]:first[i + 1]], ascending
    (first (nv + 1,) int64), read on each column's support (tree_solve_supports_into). Returns how many there are; when
    columns (int64) is too short for them it is left unwritten (the caller gives a longer one)."""
    n = A.shape[0]
    for i in range(n + 1):
        first[i] = 0
    for c in range(m):  # counted by dof, at first[i + 1]
        if length[c] < 0:
            for i in range(n):
                if A[i, c] != 0.0:
                    first[i + 1] += 1
        else:
            for x in range(length[c]):
                i = support[start[c] + x]
                if A[i, c] != 0.0:
                    first[i + 1] += 1
    for i in range(n):
        first[i + 1] += first[i]
    total = first[n]
    if total > columns.size:
        return total
    for c in range(m):  # then placed, columns ascending; first[i] runs to dof i's end and is moved back after
        if length[c] < 0:
            for i in range(n):
                if A[i, c] != 0.0:
                    columns[first[i]] = c
                    first[i] += 1
        else:
            for x in range(length[c]):
                i = support[start[c] + x]
                if A[i, c] != 0.0:
                    columns[first[i]] = c
                    first[i] += 1
    for i in range(n, 0, -1):
        first[i] = first[i - 1]
    first[0] = 0
    return total


@njit(cache=True)
def gram_by_dofs(A, m, W, first, columns, island):
    """W (m, m) = A^T A for A (nv, m), summed dof by dof over the columns nonzero there (dof_columns' lists): the sum
    over the dofs of the square of how many rows each carries, where BLAS's product costs m^2 nv. island (m,) int64 <-
    the rows joined where they share a dof (a union-find forest: islands.label_islands reads it)."""
    _clear(W, island, m)
    for i in range(A.shape[0]):
        _add_dof(A, i, W, columns, first[i], first[i + 1], island)
    _mirror(W, m)


@njit(cache=True)
def gram_by_scan(A, m, W, columns, island):
    """gram_by_dofs with each dof's nonzero columns found by a scan of its row of A (columns (m,) int64 scratch):
    for a tree of few dofs, whose rows are read whole (the same sums, in the same order)."""
    _clear(W, island, m)
    for i in range(A.shape[0]):
        k = 0
        for c in range(m):
            if A[i, c] != 0.0:
                columns[k] = c
                k += 1
        _add_dof(A, i, W, columns, 0, k, island)
    _mirror(W, m)


BLAS_GAIN = 25     # a product of the sums by dof (gram_by_scan's, indexed) costs as much as 25 of BLAS's m^2 nv
BLAS_CALL = 2750   # and BLAS's call as much as 2,750 of its products (0.11 us; an AMD EPYC: 1 ns and 0.04 ns each)


@njit(cache=True)
def gram_of_few_dofs(A, m, W, columns, island):
    """gram_by_scan's W (m, m) and islands for a tree of few dofs, W by BLAS's product (np.dot: its own order of
    the sums) where its m^2 nv products and its call cost less than the sums by dof: a robot's feet, whose rows all
    share the base's dofs and a leg's (robotis_op3 standing, 68 rows of 26 dofs: 4.7 us where gram_by_scan takes
    17.5). The rows are joined into islands by a scan of A's rows either way. Returns whether BLAS formed W."""
    for a in range(m):
        island[a] = a
    work = 0  # the sums by dof's products: over the dofs, k (k + 1) / 2 for the k rows each carries
    for i in range(A.shape[0]):
        k, first = 0, -1
        for c in range(m):
            if A[i, c] != 0.0:
                if first < 0:
                    first = c
                else:
                    join(island, first, c)
                k += 1
        work += k * (k + 1) // 2
    if m * m * A.shape[0] + BLAS_CALL < BLAS_GAIN * work:
        np.dot(A.T, A, W)
        return True
    gram_by_scan(A, m, W, columns, island)
    return False


@njit(cache=True, inline="always")
def _clear(W, island, m):
    for a in range(m):
        island[a] = a
        for b in range(m):
            W[a, b] = 0.0


@njit(cache=True, inline="always")
def _add_dof(A, i, W, columns, k0, k1, island):
    """W's lower triangle += dof i's products of its nonzero columns columns[k0:k1] (ascending: a >= b), which it
    joins into one island."""
    for x in range(k0, k1):
        a = columns[x]
        value = A[i, a]
        for y in range(k0, x + 1):
            W[a, columns[y]] += value * A[i, columns[y]]
        if x > k0:
            join(island, columns[k0], a)


@njit(cache=True, inline="always")
def _mirror(W, m):
    for a in range(m):
        for b in range(a):
            W[b, a] = W[a, b]


@njit(cache=True)
def product_by_dofs(A, lam, first, columns, x):
    """x (nv,) = A lam for A (nv, m), dof by dof over the columns nonzero there (dof_columns' lists)."""
    for i in range(A.shape[0]):
        total = 0.0
        for k in range(first[i], first[i + 1]):
            total += A[i, columns[k]] * lam[columns[k]]
        x[i] = total


__all__ = ["tree_solve_rows_into", "tree_solve_supports_into", "dof_columns", "gram_by_dofs", "gram_by_scan",
           "gram_of_few_dofs", "product_by_dofs"]
