"""The least-norm solve of stick_polish (rbody.engine.constraints.cone): the solution of A x = r of least
sum x_i^2 / weights_i for a symmetric semidefinite block A of the step's W (a redundant contact set: a box's four
corners on a face, a figure's two feet on a floor), by pivoted Cholesky, and the rounds that reweigh it by the normal
impulses until they settle."""

import numpy as np
import pytest

from rbody.engine.constraints.cone import (LEAST_NORM_RTOL, NORMAL, TANGENT, TANGENT2, _gram_factor, _least_norm,
                                           _pivoted_cholesky, cone_residual, cone_pgs, stick_polish)


def semidefinite(rng, k, rank):
    """A (k, k) = B^T B of the given rank, its nonzero eigenvalues spread over two decades."""
    Q, _ = np.linalg.qr(rng.normal(size=(k, k)))
    values = np.zeros(k)
    values[:rank] = np.logspace(-1, 1, rank)
    return (Q * values) @ Q.T


def weighted_pinv_solution(A, r, weights):
    """The reference: D^1/2 (A D^1/2)^+ r, numpy's SVD pseudo-inverse."""
    root = np.sqrt(weights)
    return root * (np.linalg.pinv(A * root, rcond=1e-13) @ r)


@pytest.mark.parametrize("k, rank", [(1, 1), (3, 3), (6, 4), (12, 5), (24, 11), (30, 30)])
def test_least_norm_is_the_weighted_minimum_norm_solution(k, rank):
    rng = np.random.default_rng(k * 100 + rank)
    for _ in range(20):
        A = semidefinite(rng, k, rank)
        weights = np.exp(rng.normal(size=k))  # normal impulses over a decade or two
        r = A @ rng.normal(size=k)            # consistent: in A's range
        x = _least_norm(A, r, weights)
        assert np.abs(A @ x - r).max() <= 1e-13 * np.abs(r).max()
        expected = weighted_pinv_solution(A, r, weights)
        assert np.abs(x - expected).max() <= 1e-11 * np.abs(expected).max()
        # no other solution is shorter: x is orthogonal (in the weights' metric) to A's null space
        null = np.linalg.eigh(A)[1][:, :k - rank]
        if rank < k:
            assert np.abs(null.T @ (x / weights)).max() <= 1e-11 * np.abs(x / weights).max()


def test_least_norm_of_an_inconsistent_system_is_the_least_squares_solution():
    """Dependent rows that cannot all hold (r outside A's range): the least-squares solution, as the SVD gives it."""
    rng = np.random.default_rng(7)
    A = semidefinite(rng, 8, 5)
    weights = np.exp(rng.normal(size=8))
    r = rng.normal(size=8)
    x = _least_norm(A, r, weights)
    assert np.linalg.norm(A @ x - r) > 0.1  # not solvable
    np.testing.assert_allclose(x, weighted_pinv_solution(A, r, weights), rtol=0, atol=1e-12 * np.abs(x).max())


def box_on_face_problem():
    """A box's four bottom corners on a floor (12 rows, rank 6: the box's six dofs), the box pushed sideways within
    its cones: W = J M^-1 J^T of a cube of side 2a, mass m, and b its free velocities' rows."""
    m, a = 2.0, 0.1
    inertia = m * (2 * a) ** 2 / 6
    rows = []
    for x, y in ((-a, -a), (a, -a), (-a, a), (a, a)):
        r = np.array([x, y, -a])
        for e in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
            rows.append(np.concatenate([e, np.cross(r, e)]))  # the corner's velocity along e: e.(v + w x r)
    J = np.array(rows)
    Minv = np.diag([1 / m] * 3 + [1 / inertia] * 3)
    W = J @ Minv @ J.T
    v_free = np.array([3e-3, -1e-3, -9.81e-3, 0.0, 0.0, 0.01])  # sliding a little, turning, falling one step's g h
    b = J @ v_free
    role = np.array([NORMAL, TANGENT, TANGENT2] * 4)
    mu = np.array([0.0, 50.0, 0.0] * 4)  # sticks
    lo, hi = np.array([0.0, -np.inf, -np.inf] * 4), np.full(12, np.inf)
    return W, b, lo, hi, role, mu


def test_stick_polish_ends_at_the_fixed_point_of_its_weights():
    """The rounds stop where a round gives the last one's impulses again to round-off: the answer is then its own
    weights' least-norm solution (one more round changes nothing beyond round-off), and it solves the problem."""
    W, b, lo, hi, role, mu = box_on_face_problem()
    assert np.linalg.matrix_rank(W) == 6
    lam = np.zeros(12)
    cone_pgs(W, b, lo, hi, role, mu, lam, 1e-6, 50)
    residual = stick_polish(W, b, lo, hi, role, mu, lam, 8)
    scale = np.abs(b).max()
    assert residual <= 1e-14 * scale
    normals = lam[role == NORMAL]
    assert normals.min() > 0 and cone_residual(W, b, lo, hi, role, mu, lam) == residual
    weights = np.repeat(normals, 3)  # each corner's rows weighed by its normal impulse
    again = _least_norm(W, -b, weights)  # one more round: every row of the problem is held (all push and stick)
    assert np.abs(again - lam).max() <= 1e-13 * np.abs(lam).max()
    # the corners' loads differ (the box turns and slides as it is stopped): not a trivial fixed point
    assert normals.max() - normals.min() > 0.1 * normals.max()


def column_cholesky(S, rtol):
    """The rank-revealing Cholesky factorisation by outer products, column by column as Higham writes it (10.3): the
    reference for cone._pivoted_cholesky, which takes the same operations row by row along memory. Returns (S with
    L in its lower trapezoid, perm, rank)."""
    S = S.copy()
    k = S.shape[0]
    perm = np.arange(k)
    top = max(S[a, a] for a in range(k))
    for j in range(k):
        at = j + int(np.argmax(np.diag(S)[j:]))  # the first of the largest remaining diagonal entries
        pivot = S[at, at]
        if not pivot > rtol * top:
            return S, perm, j
        S[[j, at], :] = S[[at, j], :]
        S[:, [j, at]] = S[:, [at, j]]
        perm[[j, at]] = perm[[at, j]]
        d = np.sqrt(pivot)
        S[j, j] = d
        for i in range(j + 1, k):
            S[i, j] /= d
        for c in range(j + 1, k):
            f = S[c, j]
            for i in range(j + 1, k):
                S[i, c] -= S[i, j] * f
    return S, perm, k


@pytest.mark.parametrize("k, rank, repeated", [(1, 1, 0), (5, 5, 0), (9, 4, 2), (16, 7, 3), (24, 24, 0)])
def test_pivoted_cholesky_is_the_column_factorisation_to_the_bit(k, rank, repeated):
    """The factor taken row by row along memory (each Schur update one contiguous loop) does the column-wise
    algorithm's operations: the same pivots, rank and factor to the last bit, and L L^T is S permuted; a redundant
    contact set repeats rows (a corner counted twice), which the rank sees."""
    rng = np.random.default_rng(k + 10 * rank + 100 * repeated)
    for _ in range(10):
        S = semidefinite(rng, k, rank) * 10.0 ** rng.uniform(-3, 3)
        if repeated:
            S = np.vstack([S, S[:repeated]])
            S = np.hstack([S, S[:, :repeated]])
        size = S.shape[0]
        expected, expected_perm, expected_rank = column_cholesky(S, LEAST_NORM_RTOL)
        factor, perm = S.copy(), np.empty(size, dtype=np.int64)
        rank_found = _pivoted_cholesky(factor, LEAST_NORM_RTOL, perm)
        assert rank_found == expected_rank == rank
        np.testing.assert_array_equal(perm, expected_perm)
        lower = np.tril(np.ones((size, rank_found), dtype=bool))
        np.testing.assert_array_equal(factor[:, :rank_found][lower], expected[:, :rank_found][lower])
        L = np.where(lower, factor[:, :rank_found], 0.0)
        assert np.abs(L @ L.T - S[perm][:, perm]).max() <= 1e-13 * np.abs(S).max()
        T, order, definite = _gram_factor(factor, rank_found)  # L^T L, summed in the rows' order, then factored
        assert definite
        gram = L.T @ L
        N = np.tril(T)
        assert np.abs(N @ N.T - gram[order][:, order]).max() <= 1e-13 * np.abs(gram).max()


def test_gauss_seidel_updates_by_columns_of_an_unsymmetric_W():
    """cone_pgs's sweep moves every row's velocity by W's column i times row i's change (an event's W = J M^-1 F^T
    is not symmetric: a sliding contact's force columns F differ from its rows J); the sweep reads that column from a
    transposed copy: it equals the textbook sweep, which a row of W in its place would not."""
    rng = np.random.default_rng(11)
    m = 9
    W = semidefinite(rng, m, m) + 0.3 * rng.normal(size=(m, m))
    W[np.diag_indices(m)] = np.abs(np.diag(W)) + 1.0
    b = rng.normal(size=m)
    lo, hi = np.full(m, -0.2), np.full(m, 0.3)
    role, mu = np.zeros(m, dtype=np.int64), np.zeros(m)
    lam = np.zeros(m)
    for _sweep in range(3):
        w = W @ lam + b
        lam = lam.copy()
        for i in range(m):
            new = min(max(lam[i] - w[i] / W[i, i], lo[i]), hi[i])
            w += W[:, i] * (new - lam[i])
            lam[i] = new
        cone_lam = np.zeros(m)
        cone_pgs(W, b, lo, hi, role, mu, cone_lam, 0.0, _sweep + 1)
        np.testing.assert_allclose(cone_lam, lam, rtol=0, atol=1e-14)
    by_rows = np.zeros(m)  # the transposed problem, whose columns are W's rows: another answer
    cone_pgs(W.T.copy(), b, lo, hi, role, mu, by_rows, 0.0, 3)
    assert np.abs(by_rows - lam).max() > 1e-3
