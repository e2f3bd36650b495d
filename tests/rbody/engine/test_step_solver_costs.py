"""Three properties of the time step's solver (rbody.engine.constraints: cone, solver) that decide what a step costs:

- its round-off bar (ROUND_OFF times `magnitude`) accepts impulses that solve the problem exactly, however much the
  terms of w = b + W lam cancel (a stack: the lower contacts carry the boxes above, and their terms are a hundred
  times the step's g h they sum to); a bar from |w| or |W lam| refused them and sent a solved problem through the
  whole exact finish every step;
- a sticking contact's tangent pair is solved by its block's own minimiser in one Gauss-Seidel sweep, not by tens
  of projected gradient steps at its block's condition;
- the step's M^-1/2 J^T is formed row by row across its right-hand sides, with the bits of one solve per row."""

from fractions import Fraction

import numpy as np
import pytest

from rbody.engine.constraints.cone import (NORMAL, ROUND_OFF, ROW, TANGENT, TANGENT2, cone_pgs, cone_residual,
                                           magnitude)
from rbody.engine.constraints.solver import lower_solve, lower_solve_rows


def exact_b(W, lam):
    """b = -W lam, each entry the float nearest the exact sum (the problem lam solves exactly)."""
    terms = [[Fraction(float(W[i, j])) * Fraction(float(lam[j])) for j in range(lam.size)] for i in range(lam.size)]
    return np.array([-float(sum(row)) for row in terms])


@pytest.mark.parametrize("seed", range(5))
def test_an_exact_solution_with_cancelling_terms_is_within_the_round_off_bar(seed):
    rng = np.random.default_rng(seed)
    nv, m = 30, 60                       # a stack: 60 contact rows on 30 velocities (W of rank 30)
    A = rng.normal(size=(nv, m))
    W = A.T @ A
    null = np.linalg.svd(A)[2][nv:].T    # lam's part along W's null space: large terms that cancel in W lam
    lam = rng.normal(size=m) * 0.1 + null @ rng.normal(size=m - nv) * 100.0
    b = exact_b(W, lam)
    free = np.full(m, -np.inf), np.full(m, np.inf)
    role, mu = np.full(m, ROW), np.zeros(m)
    residual = cone_residual(W, b, *free, role, mu, lam)
    bar = ROUND_OFF * magnitude(W, b, lam)
    assert residual > 0.0                # computed in floats, the exact solution shows its round-off ...
    assert residual <= bar               # ... which the bar accepts
    # the sizes that cancel: a bar from |b| and |W lam| alone would have refused it
    assert residual > ROUND_OFF * max(np.abs(b).max(), np.abs(W @ lam).max())
    # and the bar is round-off, not a tolerance: a solution off by 1e-9 of the terms is refused
    off = lam.copy()
    off[0] += 1e-9 * np.abs(lam).max()
    assert cone_residual(W, b, *free, role, mu, off) > ROUND_OFF * magnitude(W, b, off)


@pytest.mark.parametrize("condition", [3.0, 30.0, 300.0])
def test_one_sweep_solves_a_sticking_contact_exactly(condition):
    # one contact, its normal decoupled from its tangents, whose 2 x 2 block has the given condition
    angle = 0.4
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    B = R @ np.diag([condition, 1.0]) @ R.T
    W = np.zeros((3, 3))
    W[0, 0] = 2.0
    W[1:, 1:] = B
    b = np.array([-1.0, 0.05, -0.08])
    role = np.array([NORMAL, TANGENT, TANGENT2])
    mu = np.array([0.0, 1.0, 1.0])
    lo, hi = np.array([0.0, -np.inf, -np.inf]), np.array([np.inf, np.inf, np.inf])
    exact_normal = 0.5
    exact_tangents = -np.linalg.solve(B, b[1:])
    assert np.hypot(*exact_tangents) < mu[1] * exact_normal  # sticking: inside its cone
    lam = np.zeros(3)
    sweeps, residual = cone_pgs(W, b, lo, hi, role, mu, lam, 0.0, 1)
    assert sweeps == 1
    assert residual <= ROUND_OFF * magnitude(W, b, lam)
    assert abs(lam[0] - exact_normal) <= 1e-15
    assert np.abs(lam[1:] - exact_tangents).max() <= 4e-16 * condition


def test_a_sliding_contact_still_ends_on_its_cone():
    # the block's own minimiser outside the disc: the projected steps put the force on the cone's edge, against
    # the tangential velocity
    W = np.diag([1.0, 1.0, 1.0])
    b = np.array([-1.0, 3.0, 4.0])       # tangential velocity (3, 4): |.| = 5 > mu lambda_n = 0.5
    role = np.array([NORMAL, TANGENT, TANGENT2])
    mu = np.array([0.0, 0.5, 0.5])
    lo, hi = np.array([0.0, -np.inf, -np.inf]), np.array([np.inf, np.inf, np.inf])
    lam = np.zeros(3)
    _sweeps, residual = cone_pgs(W, b, lo, hi, role, mu, lam, 1e-14, 10)
    assert residual <= 1e-14
    assert lam[0] == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(lam[1:], -0.5 * np.array([3.0, 4.0]) / 5.0, rtol=0, atol=1e-15)


@pytest.mark.parametrize("n, m", [(1, 1), (6, 3), (30, 60), (45, 7)])
def test_the_rows_forward_substitution_gives_each_column_lower_solves_bits(n, m):
    # A = L^-1 J[index]^T row by row (the right-hand sides innermost) against lower_solve column by column: the
    # same sums in the same order, so the same bits; and A solves L A = J[index]^T
    rng = np.random.default_rng(n * 1000 + m)
    B = rng.normal(size=(n, n))
    L = np.linalg.cholesky(B @ B.T + n * np.eye(n))
    J = rng.normal(size=(m + 5, n))
    index = rng.permutation(m + 5)[:m].astype(np.int64)
    A = lower_solve_rows(L, J, index, m)
    for c in range(m):
        assert np.array_equal(A[:, c], lower_solve(L, J[index[c]]))
    assert np.abs(L @ A - J[index].T).max() <= 1e-13 * max(1.0, np.abs(J).max())
