"""The mass matrix's factor along the kinematic tree and its two solves.

M (nv, nv) couples dof i only with its ancestors and descendants (the composite-rigid-body algorithm's pattern).
Factored from the leaves, M = L^T L with L lower triangular and L[i, j] != 0 only where j is i or one of its
ancestors: no entry fills in (Featherstone, Rigid Body Dynamics Algorithms, section 6.5, the LTL factorisation;
MuJoCo's mj_factorM is its L^T D L twin). It costs the sum over the dofs of their depth squared, not nv^3 / 3: a pile
of N free bodies factors in 6 x 6 blocks, O(N), where the dense Cholesky factor costs O(N^3). Any matrix with M's
pattern factors the same way: MuJoCo's Euler step solves with M + h diag(damping) (mujoco_steps.euler_factor).

`parent` (nv,) int64: each dof's parent dof (-1 at a root), parent[i] < i (the tree's dof order). L's entries off
the ancestors are neither written nor read.
"""

import numpy as np
from numba import njit


@njit(cache=True)
def tree_factor(M, parent, L):
    """L (nv, nv) <- the tree's factor of the symmetric positive definite M (nv, nv): M = L^T L, L[i, j] set only
    where j is i or an ancestor of i. Returns False (L partly written) where a pivot is not positive."""
    ancestors_into(M, parent, L)
    return factor_in_place(L, parent)


@njit(cache=True)
def ancestors_into(M, parent, L):
    """L[i, j] <- M[i, j] where j is i or an ancestor of i (the only entries the tree's factor has)."""
    for k in range(M.shape[0]):
        j = k
        while j >= 0:
            L[k, j] = M[k, j]
            j = parent[j]


@njit(cache=True)
def factor_in_place(L, parent):
    """L (nv, nv) <- the tree's factor of the matrix whose entries on each dof's ancestors L holds (tree_factor's
    pattern: L[i, j], j i or an ancestor of i). Returns False (L partly written) where a pivot is not positive."""
    for k in range(L.shape[0] - 1, -1, -1):  # from the leaves: L_kk = sqrt(H_kk); the row by it; its outer
        if not L[k, k] > 0.0:  # product off its ancestors' entries
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


__all__ = ["tree_factor", "ancestors_into", "factor_in_place", "tree_solve_transposed", "tree_solve"]
