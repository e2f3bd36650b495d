"""The step's cone solver where dependent rows leave Gauss-Seidel crawling (rbody.engine.constraints.cone.follow_drift).

Two rows with dry friction that act through opposite columns (W's null direction (1, 1)) beside a contact rolling and
spinning at its limits: w_a + w_b = b_a + b_b > 0 whatever the impulses, so one of the two rows must rest at its
lower bound; Gauss-Seidel moves both down together by (b_a + b_b) / W_aa a sweep, thousands of sweeps, and every
finish that reads the states from its iterate solves the pair's dependent rows by least squares and misses. A
quadruped standing on condim 6 feet with friction in its hips meets the same problem (its hips' friction torques and
the feet's lateral forces along a null direction). The solution is exact: the lower row at its bound, the other's
velocity 0, the contact's normal velocity 0, its rolling and spinning torques on their limits."""

import numpy as np
import pytest

from rbody.engine.constraints.cone import (NORMAL, ROLL, ROLL2, ROW, SPIN, TANGENT, TANGENT2, cone_pgs,
                                           cone_residual, follow_drift)
from rbody.engine.constraints.stepping import cone_solve

ROLES = np.array([ROW, ROW, NORMAL, TANGENT, TANGENT2, SPIN, ROLL, ROLL2])
MU = np.array([0.0, 0.0, 0.0, 0.8, 0.0, 0.02, 0.01, 0.0])
BOX = 1e-3      # the two rows' friction bound [N s]
CRAWL = 1e-7    # (b_a + b_b) / 2: what Gauss-Seidel moves the pair by per sweep / 2
TOLERANCE = 1e-10


def crawling_problem(seed: int):
    """(W, b, lo, hi): the module docstring's problem, W = A^T A over 6 dofs, the pair's columns opposite and apart
    from the contact's (dof 0 theirs alone)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(6, 8))
    A[0, 2:] = 0.0
    A[:, 0] = 0.0
    A[0, 0] = 1.0
    A[:, 1] = -A[:, 0]
    b = 0.1 * rng.normal(size=8)
    b[0], b[1] = CRAWL + 2e-4, CRAWL - 2e-4  # the pair's difference settles inside the box, its sum crawls down
    b[2] = -1.0                              # the contact pushes
    b[6], b[7] = 0.5, -0.3                   # and rolls at its limit
    lo = np.array([-BOX, -BOX, 0.0] + [-np.inf] * 5)
    hi = np.array([BOX, BOX] + [np.inf] * 6)
    return A.T @ A, b, lo, hi


@pytest.mark.parametrize("seed", range(4))
def test_a_crawl_along_dependent_rows_is_solved_exactly(seed):
    W, b, lo, hi = crawling_problem(seed)
    lam = np.zeros(8)
    residual = cone_solve(W, b, lo, hi, ROLES, MU, lam, TOLERANCE, 2000)
    assert residual <= TOLERANCE  # what the step accepts (without follow_drift: 1e-7)
    assert cone_residual(W, b, lo, hi, ROLES, MU, lam) == residual
    w = W @ lam + b
    assert lam[0] == -BOX and w[0] > 0.0             # the first row at its lower bound, pushed further by w
    assert -BOX < lam[1] < BOX and abs(w[1]) < 1e-14  # the other inside its box, at rest
    assert lam[2] > 0.0 and abs(w[2]) < 1e-13        # the contact pushes and holds
    rolling = np.hypot(lam[6], lam[7])
    np.testing.assert_allclose(rolling, MU[6] * lam[2], rtol=1e-12)  # rolling torque on its limit
    np.testing.assert_allclose(abs(lam[5]), MU[5] * lam[2], rtol=1e-12)  # and the spin's
    # against the rolling and spinning velocities (Coulomb's maximal dissipation)
    assert lam[6] * w[6] + lam[7] * w[7] < 0.0 and lam[5] * w[5] < 0.0


def test_follow_drift_takes_the_crawl_to_the_bound_at_once():
    W, b, lo, hi = crawling_problem(0)
    lam = np.zeros(8)
    cone_pgs(W, b, lo, hi, ROLES, MU, lam, 0.0, 200)
    before = cone_residual(W, b, lo, hi, ROLES, MU, lam)
    crawled = lam.copy()
    cone_pgs(W, b, lo, hi, ROLES, MU, crawled, 0.0, 1)
    np.testing.assert_allclose(crawled[:2] - lam[:2], -2 * CRAWL / W[0, 0], rtol=1e-6)  # the pair's crawl
    after = follow_drift(W, b, lo, hi, ROLES, MU, lam)
    assert after < before
    assert lam[0] == -BOX  # the row that meets its bound first, set on it
    assert after == cone_residual(W, b, lo, hi, ROLES, MU, lam)


def test_follow_drift_keeps_a_solution():
    """At a solution the crawl is round-off: lam is kept or moved by round-off, never to a worse residual."""
    W, b, lo, hi = crawling_problem(1)
    lam = np.zeros(8)
    cone_solve(W, b, lo, hi, ROLES, MU, lam, TOLERANCE, 2000)
    solved = lam.copy()
    residual = cone_residual(W, b, lo, hi, ROLES, MU, lam)
    assert follow_drift(W, b, lo, hi, ROLES, MU, lam) <= residual
    np.testing.assert_allclose(lam, solved, rtol=0.0, atol=1e-14)
