"""The complementarity problems of the constraint layer, and their solvers, compiled.

Every problem the layer meets (forces at an event, impulses at an impact, impulses over a time step) is one mixed
linear complementarity problem (MLCP) in the constraint rows, with the Delassus matrix W = J M^-1 J^T (m, m),
symmetric positive semi-definite (singular where rows are redundant: a closed loop with more rows than it needs):

    w = W lambda + b,   lo_i <= lambda_i <= hi_i,
    lambda_i = lo_i  =>  w_i >= 0,    lambda_i = hi_i  =>  w_i <= 0,    lo_i < lambda_i < hi_i  =>  w_i = 0.

Bilateral rows (equalities, held limits) have (lo, hi) = (-inf, inf): w_i = 0. Unilateral rows (limits, and the
normal rows of contacts to come) have (0, inf): lambda >= 0, w >= 0, lambda w = 0. Box rows (dry friction of a
dof) have (-F, F) [or F h for an impulse]: the dof sticks (w = 0) while |lambda| < F and slides against it
otherwise. Contacts' Coulomb rows will have bounds mu lambda_normal that move with the solution: the projected
Gauss-Seidel below takes them row by row as the normal updates (the issue of contacts extends `hi` to that).

Since W is positive semi-definite, the MLCP is the optimality condition of the convex box-constrained quadratic
program  min 1/2 lambda^T W lambda + b^T lambda,  lo <= lambda <= hi,  whose minimisers share one w (the gradient
of a convex quadratic is constant on its minimisers): accelerations and velocities are unique even where the
forces of a redundant loop are not (the minimum-norm forces are reported).

Two solvers (Drake, Siconos and MuJoCo frame the same problem: Drake's SAP and MuJoCo regularise it into a strictly
convex one, which makes the constraints soft; Siconos solves the complementarity problem itself, as here):

- mlcp_exact, a primal active-set method on that program (Nocedal and Wright, Numerical Optimization, 16.5): on
  the set of rows not at a bound, a Newton step to the face's minimiser (the minimum-norm one where W is singular,
  by its eigen-decomposition), shortened to the first bound it meets; at the face's minimiser the bound row whose
  multiplier w has the wrong sign is freed. Finite, exact to round-off, O(m^3) per step: for the event problems
  (few rows) and the time steps of small models;
- mlcp_pgs, projected Gauss-Seidel: lambda_i <- clamp(lambda_i - w_i / W_ii, lo_i, hi_i), row by row, until the
  natural residual falls below the tolerance asked, or its budget of sweeps is spent: for many rows.

Both report the natural residual r = max_i W_ii |lambda_i - clamp(lambda_i - w_i / W_ii, lo_i, hi_i)| (0 exactly at
a solution; in the units of w) so that a caller refuses a result above its tolerance (SimulationError).
"""

from __future__ import annotations

import numpy as np
from numba import njit

RANK_RTOL = 1e-12      # eigenvalues of W below this fraction of its largest are its null space (redundant rows)
EXACT_MAX_STEPS = 50   # active-set steps of mlcp_exact: per row, plus this
UNBOUNDED = -1         # status of a problem whose bilateral rows contradict each other (no solution)


@njit(cache=True)
def lower_solve(L, b):
    """x = L^-1 b for a lower-triangular L (n, n) and b (n,)."""
    x = np.empty(b.shape[0])
    lower_solve_into(L, b, x)
    return x


@njit(cache=True)
def lower_solve_into(L, b, x):
    """x (n,) <- L^-1 b for a lower-triangular L (n, n) and b (n,); x may be b (solved in place)."""
    for i in range(b.shape[0]):
        acc = b[i]
        for j in range(i):
            acc -= L[i, j] * x[j]
        x[i] = acc / L[i, i]


@njit(cache=True)
def cholesky_factor(A, L, rtol, atol=0.0):
    """L (m, m) <- the lower Cholesky factor of the symmetric A (m, m) when every pivot exceeds rtol times its diagonal
    entry and atol (rtol = atol = 0: A positive definite), returning True; False (L partly written) otherwise."""
    m = A.shape[0]
    for i in range(m):
        for j in range(m):
            L[i, j] = 0.0
    for i in range(m):
        for j in range(i + 1):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            if i == j:
                if not (acc > rtol * A[i, i] and acc > atol):
                    return False
                L[i, i] = np.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    return True


@njit(cache=True)
def lower_solve_rows(L, J, index, m):
    """lower_solve_rows_into's A, allocated."""
    A = np.empty((L.shape[0], m))
    lower_solve_rows_into(L, J, index, m, A)
    return A


@njit(cache=True)
def lower_solve_rows_into(L, J, index, m, A):
    """A (n, m) = L^-1 J[index[:m]]^T for a lower-triangular L (n, n) and rows J (rows, n): column c is what
    lower_solve(L, J[index[c]]) gives, to the bit (each entry's sum in the same order), but forward substitution
    runs over A's rows with the m right-hand sides innermost. Column by column, each entry is a chain of dependent
    additions the processor waits on; across the columns they are independent and vectorise (a five-box stack's
    60 rows on 30 dofs: the chain took a quarter of its step)."""
    n = L.shape[0]
    for i in range(n):
        for c in range(m):
            A[i, c] = J[index[c], i]
        for j in range(i):
            lij = L[i, j]
            for c in range(m):
                A[i, c] -= lij * A[j, c]
        d = L[i, i]
        for c in range(m):
            A[i, c] = A[i, c] / d


@njit(cache=True)
def upper_solve(L, b):
    """x = L^-T b for a lower-triangular L (n, n)."""
    x = np.empty(b.shape[0])
    upper_solve_into(L, b, x)
    return x


@njit(cache=True)
def upper_solve_into(L, b, x):
    """x (n,) <- L^-T b for a lower-triangular L (n, n); x may be b (solved in place)."""
    n = b.shape[0]
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= L[j, i] * x[j]
        x[i] = acc / L[i, i]


@njit(cache=True)
def clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


@njit(cache=True)
def natural_residual(W, b, lo, hi, lam):
    """max_i W_ii |lambda_i - clamp(lambda_i - w_i / W_ii, lo_i, hi_i)| with w = W lambda + b (rows with W_ii = 0:
    |w_i| where the bounds leave lambda free, else 0 unless w_i has the wrong sign at the bound)."""
    m = b.shape[0]
    worst = 0.0
    for i in range(m):
        wi = b[i]
        for j in range(m):
            wi += W[i, j] * lam[j]
        d = W[i, i]
        if d > 0.0:
            r = d * abs(lam[i] - clamp(lam[i] - wi / d, lo[i], hi[i]))
        else:
            r = abs(wi) if (lam[i] > lo[i] and lam[i] < hi[i]) else (
                max(-wi, 0.0) if lam[i] <= lo[i] else max(wi, 0.0))
        worst = max(worst, r)
    return worst


@njit(cache=True)
def symmetric_solve(A, r, x):
    """x = the minimum-norm least-squares solution of A x = r for a symmetric positive semi-definite A (k, k), by its
    eigen-decomposition with eigenvalues below RANK_RTOL of the largest taken as 0. Returns the part of r outside
    A's range, |r - A x|_inf (0 when A x = r is consistent)."""
    k = r.shape[0]
    if k == 0:
        return 0.0
    values, vectors = np.linalg.eigh(A)
    top = max(abs(values[k - 1]), 0.0)
    for i in range(k):
        x[i] = 0.0
    for e in range(k):
        if values[e] > RANK_RTOL * top and values[e] > 0.0:
            coefficient = 0.0
            for i in range(k):
                coefficient += vectors[i, e] * r[i]
            coefficient /= values[e]
            for i in range(k):
                x[i] += coefficient * vectors[i, e]
    worst = 0.0
    for i in range(k):
        acc = r[i]
        for j in range(k):
            acc -= A[i, j] * x[j]
        worst = max(worst, abs(acc))
    return worst


@njit(cache=True)
def mlcp_exact(W, b, lo, hi, lam):
    """Solve the MLCP (module docstring) by the primal active-set method, from lambda = clamp(0, lo, hi); lam (m,)
    out. Returns (status, steps): status 0 solved, UNBOUNDED when rows free of bounds contradict each other (no
    lambda makes their w vanish), 1 when the step budget ran out."""
    for i in range(b.shape[0]):
        lam[i] = 0.0
    return mlcp_exact_from(W, b, lo, hi, lam)


@njit(cache=True)
def mlcp_exact_from(W, b, lo, hi, lam):
    """mlcp_exact from the lambda given in lam (clamped to its bounds; a warm start: the rows at a bound start on
    it, the others free), the time-stepping's last impulses: where the set of rows at their bounds does not change
    from one step to the next, the method stops after one face's solve."""
    m = b.shape[0]
    state = np.zeros(m, dtype=np.int64)  # 0 free, -1 at lo, +1 at hi
    for i in range(m):
        lam[i] = clamp(lam[i], lo[i], hi[i])
        if lam[i] == lo[i]:
            state[i] = -1
        elif lam[i] == hi[i]:
            state[i] = 1
    grad = np.empty(m)
    free = np.empty(m, dtype=np.int64)
    stationary = False
    budget = EXACT_MAX_STEPS + 4 * m
    for steps in range(budget):
        scale = 0.0
        for i in range(m):
            acc = b[i]
            row = abs(b[i])
            for j in range(m):
                acc += W[i, j] * lam[j]
                row += abs(W[i, j] * lam[j])
            grad[i] = acc
            scale = max(scale, row)
        if not stationary:
            k = 0
            for i in range(m):
                if state[i] == 0:
                    free[k] = i
                    k += 1
            Wf = np.empty((k, k))
            rf = np.empty(k)
            for a in range(k):
                rf[a] = -grad[free[a]]
                for c in range(k):
                    Wf[a, c] = W[free[a], free[c]]
            step = np.empty(k)
            outside = symmetric_solve(Wf, rf, step)
            null = outside > 1e-9 * scale
            if null:  # no step on this face cancels the gradient: go down its null-space part (zero curvature)
                for a in range(k):
                    acc = rf[a]
                    for c in range(k):
                        acc -= Wf[a, c] * step[c]
                    step[a] = acc
            alpha = np.inf if null else 1.0
            blocking, to_lower = -1, True
            for a in range(k):
                i = free[a]
                if step[a] < 0.0 and lo[i] > -np.inf:
                    limit = (lo[i] - lam[i]) / step[a]
                elif step[a] > 0.0 and hi[i] < np.inf:
                    limit = (hi[i] - lam[i]) / step[a]
                else:
                    continue
                if limit < alpha:
                    alpha, blocking, to_lower = max(limit, 0.0), i, step[a] < 0.0
            if alpha == np.inf:
                return UNBOUNDED, steps
            for a in range(k):
                lam[free[a]] += alpha * step[a]
            if blocking >= 0:
                if to_lower:
                    lam[blocking], state[blocking] = lo[blocking], -1
                else:
                    lam[blocking], state[blocking] = hi[blocking], 1
                continue
            stationary = True
            continue
        # at the face's minimiser: free the bound row whose multiplier has the wrong sign, the worst first
        worst, leaving = 0.0, -1
        tolerance = 1e-13 * scale
        for i in range(m):
            if state[i] == -1 and grad[i] < -tolerance and -grad[i] > worst:
                worst, leaving = -grad[i], i
            elif state[i] == 1 and grad[i] > tolerance and grad[i] > worst:
                worst, leaving = grad[i], i
        if leaving < 0:
            return 0, steps
        state[leaving] = 0
        stationary = False
    return 1, budget


@njit(cache=True)
def mlcp_pgs(W, b, lo, hi, lam, tolerance, max_sweeps):
    """Solve the MLCP by projected Gauss-Seidel from the lam given (a warm start); stop when natural_residual <=
    tolerance. Returns (sweeps, residual); sweeps = max_sweeps and residual > tolerance when the budget ran out."""
    m = b.shape[0]
    residual = natural_residual(W, b, lo, hi, lam)
    for sweep in range(max_sweeps):
        if residual <= tolerance:
            return sweep, residual
        for i in range(m):
            d = W[i, i]
            if not d > 0.0:
                continue
            wi = b[i]
            for j in range(m):
                wi += W[i, j] * lam[j]
            lam[i] = clamp(lam[i] - wi / d, lo[i], hi[i])
        residual = natural_residual(W, b, lo, hi, lam)
    return max_sweeps, residual


__all__ = ["cholesky_factor", "lower_solve", "upper_solve", "natural_residual", "symmetric_solve", "mlcp_exact",
           "mlcp_exact_from", "mlcp_pgs", "clamp", "RANK_RTOL", "UNBOUNDED"]
