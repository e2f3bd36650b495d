"""The mass matrix's factor along the kinematic tree, and the time-stepping's products through it.

M (nv, nv) couples dof i only with its ancestors and descendants (the composite-rigid-body algorithm's pattern).
Factored from the leaves, M = L^T L with L lower triangular and L[i, j] != 0 only where j is i or one of its
ancestors: no entry fills in (Featherstone, Rigid Body Dynamics Algorithms, section 6.5, the LTL factorisation;
MuJoCo's mj_factorM is its L^T D L twin). It costs the sum over the dofs of their depth squared, not nv^3 / 3: a pile
of N free bodies factors in 6 x 6 blocks, O(N), where the dense Cholesky factor costs O(N^3).

The time-stepping's metric W = J M^-1 J^T is then A^T A with A = L^-T J^T, and a row J of a point on a body has
nonzeros only on that body's path to the root, which L^-T keeps: A's columns are as sparse as J's rows, and W is
summed dof by dof over the columns a dof carries (two bodies in contact share a column's dofs; two apart share none).

`parent` (nv,) int64: each dof's parent dof (-1 at a root), parent[i] < i (the tree's dof order). L's entries off
the ancestors are neither written nor read.
"""

import numpy as np
from numba import njit

from rbody.engine.constraints.islands import join


@njit(cache=True)
def tree_factor(M, parent, L):
    """L (nv, nv) <- the tree's factor of the symmetric positive definite M (nv, nv): M = L^T L, L[i, j] set only
    where j is i or an ancestor of i. Returns False (L partly written) where a pivot is not positive."""
    n = M.shape[0]
    for k in range(n):  # M's entries on the ancestors (the only ones the factor has)
        j = k
        while j >= 0:
            L[k, j] = M[k, j]
            j = parent[j]
    for k in range(n - 1, -1, -1):  # from the leaves: L_kk = sqrt(H_kk); the row by it; its outer product off
        if not L[k, k] > 0.0:
            return False
        d = np.sqrt(L[k, k])
        L[k, k] = d
        i = parent[k]
        while i >= 0:
            L[k, i] /= d
            i = parent[i]
        i = parent[k]
        while i >= 0:  # H_ij -= L_ki L_kj for i, j on k's path (j an ancestor of i, or i)
            lki = L[k, i]
            j = i
            while j >= 0:
                L[i, j] -= lki * L[k, j]
                j = parent[j]
            i = parent[i]
    return True


@njit(cache=True)
def tree_solve_transposed(L, parent, x):
    """x (nv,) <- L^-T x in place (the tree's factor L, tree_factor): from the leaves, each dof's value final once
    its descendants' are taken off it."""
    for i in range(x.shape[0] - 1, -1, -1):
        x[i] /= L[i, i]
        j = parent[i]
        while j >= 0:
            x[j] -= L[i, j] * x[i]
            j = parent[j]


@njit(cache=True)
def tree_solve(L, parent, x):
    """x (nv,) <- L^-1 x in place: from the roots, each dof's value from its ancestors'."""
    for i in range(x.shape[0]):
        j = parent[i]
        while j >= 0:
            x[i] -= L[i, j] * x[j]
            j = parent[j]
        x[i] /= L[i, i]


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
def gram_by_dofs(A, m, W, columns, island):
    """W (m, m) = A^T A for A (nv, m), summed dof by dof over the columns nonzero there (columns (m,) int64 scratch):
    the sum over the dofs of the square of how many rows each carries, where BLAS's product costs m^2 nv. island
    (m,) int64 <- the rows joined where they share a dof (a union-find forest: islands.label_islands reads it)."""
    for a in range(m):
        island[a] = a
        for b in range(m):
            W[a, b] = 0.0
    for i in range(A.shape[0]):
        k = 0
        for c in range(m):
            if A[i, c] != 0.0:
                columns[k] = c
                k += 1
        for x in range(k):  # the lower triangle (columns ascending: a >= b)
            a = columns[x]
            value = A[i, a]
            for y in range(x + 1):
                W[a, columns[y]] += value * A[i, columns[y]]
            if x > 0:
                join(island, columns[0], a)
    for a in range(m):
        for b in range(a):
            W[b, a] = W[a, b]


__all__ = ["tree_factor", "tree_solve_transposed", "tree_solve", "tree_solve_rows_into", "gram_by_dofs"]
