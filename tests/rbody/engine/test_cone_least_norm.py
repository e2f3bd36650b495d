"""The least-norm solve of stick_polish (rbody.engine.constraints.cone): the solution of A x = r of least
sum x_i^2 / weights_i for a symmetric semidefinite block A of the step's W (a redundant contact set: a box's four
corners on a face, a figure's two feet on a floor), by pivoted Cholesky, and the rounds that reweigh it by the normal
impulses until they settle."""

import numpy as np
import pytest

from rbody.engine.constraints.cone import (NORMAL, TANGENT, TANGENT2, _least_norm, cone_residual, cone_pgs,
                                           stick_polish)


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
