"""Newton's method on the natural map of the step's problem with Coulomb cones
(rbody.engine.constraints.natural_newton): the map against the residual it stands for, its Jacobian against
differences, quadratic convergence on a sliding contact's closed form, and its limit (it does not find the pieces)."""

import numpy as np
import pytest

from rbody.engine.constraints.cone import (NORMAL, ROLL, ROLL2, ROW, SPIN, TANGENT, TANGENT2, cone_pgs,
                                           cone_residual, magnitude, ROUND_OFF)
from rbody.engine.constraints.interior import interior_finish
from rbody.engine.constraints.natural_newton import natural_map, newton_polish

from tests.rbody.engine.test_cone_drift import MU as CRAWL_MU, ROLES as CRAWL_ROLES, crawling_problem
from tests.rbody.engine.test_interior import SLIDING, sliding_solution

# one contact with condim 6 and two ordinary rows: a joint's dry friction (a box) and a limit (a half-line)
ROLES = np.array([ROW, ROW, NORMAL, TANGENT, TANGENT2, SPIN, ROLL, ROLL2])
MU = np.array([0.0, 0.0, 0.0, 0.8, 0.0, 0.02, 0.01, 0.0])
LO = np.array([-0.3, 0.0, 0.0] + [-np.inf] * 5)
HI = np.array([0.3] + [np.inf] * 7)


def random_problem(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(10, 8))
    return A.T @ A, rng.normal(size=8), rng.normal(size=8)


@pytest.mark.parametrize("seed", range(20))
def test_the_natural_map_is_the_residual_row_by_row(seed):
    """max |G| over the rows is cone_residual (a disc's pair counted by its length, as the residual does)."""
    W, b, lam = random_problem(seed)
    lam[2] = abs(lam[2])
    G, J = np.empty(8), np.empty((8, 8))
    half = natural_map(W, b, LO, HI, ROLES, MU, lam, G, J, True)
    assert half == pytest.approx(0.5 * G @ G, rel=1e-15)
    per_block = [abs(G[0]), abs(G[1]), abs(G[2]), np.hypot(G[3], G[4]), abs(G[5]), np.hypot(G[6], G[7])]
    assert max(per_block) == pytest.approx(cone_residual(W, b, LO, HI, ROLES, MU, lam), rel=1e-12)


@pytest.mark.parametrize("seed", range(20))
def test_the_jacobian_is_the_map_s_derivative_on_its_piece(seed):
    """Central differences of G at a random point (no block within 1e-4 of a kink there) against J."""
    W, b, lam = random_problem(seed)
    lam[2] = abs(lam[2]) + 0.1
    G, J = np.empty(8), np.empty((8, 8))
    natural_map(W, b, LO, HI, ROLES, MU, lam, G, J, True)
    h = 1e-7
    plus, minus, unused = np.empty(8), np.empty(8), np.empty((0, 0))
    for j in range(8):
        step = np.zeros(8)
        step[j] = h
        natural_map(W, b, LO, HI, ROLES, MU, lam + step, plus, unused, False)
        natural_map(W, b, LO, HI, ROLES, MU, lam - step, minus, unused, False)
        np.testing.assert_allclose((plus - minus) / (2 * h), J[:, j], rtol=1e-5, atol=1e-6 * np.abs(J).max())


def test_a_sliding_contact_converges_quadratically_to_its_closed_form():
    """test_interior's contact sliding on its cone's edge (lambda_t = -mu lambda_n b_t / |b_t|), from a start 1e-3
    off: the residual falls to round-off, each step squaring it."""
    p = SLIDING
    exact = sliding_solution()
    lam = exact + np.array([1e-3, -2e-3, 1e-3])
    residual = newton_polish(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], lam, 0.0)
    assert residual <= ROUND_OFF * magnitude(p["W"], p["b"], lam)
    np.testing.assert_allclose(lam, exact, rtol=1e-14, atol=1e-16)


def test_the_iterates_residuals_fall_quadratically():
    p = SLIDING
    lam = sliding_solution() + np.array([1e-2, -2e-2, 1e-2])
    history = [cone_residual(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], lam)]
    for _ in range(3):  # one step at a time (the goal the residual's half: newton_polish stops after one step)
        history.append(newton_polish(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], lam, 0.5 * history[-1]))
    assert history[1] < 1e-2 * history[0]
    assert history[2] <= max(10 * history[1] ** 2 / history[0], 1e-15)


def test_newton_does_not_find_the_pieces_and_keeps_its_start():
    """From Gauss-Seidel's crawl (test_cone_drift: the lower friction row still inside its box, 1e-7 a sweep from it)
    the map's piece is the wrong one and Newton's method stops on a point of it that is not a solution; lam is left
    no worse than its start. The interior finish reads the pieces first (test_interior)."""
    W, b, lo, hi = crawling_problem(0)
    lam = np.zeros(8)
    cone_pgs(W, b, lo, hi, CRAWL_ROLES, CRAWL_MU, lam, 0.0, 50)
    start = cone_residual(W, b, lo, hi, CRAWL_ROLES, CRAWL_MU, lam)
    residual = newton_polish(W, b, lo, hi, CRAWL_ROLES, CRAWL_MU, lam, 0.0)
    assert residual <= start
    assert residual > 1e-12
    assert residual == cone_residual(W, b, lo, hi, CRAWL_ROLES, CRAWL_MU, lam)


def test_the_interior_finish_with_newton_solves_a_tangential_slide():
    """Seed 0's contact slides (0.12 m/s) on its cone's edge: cone_polish's fixed point on the sliding direction
    stalls at 5e-7 from the barrier's states; Newton's method on the natural map from there reaches round-off."""
    W, b, lo, hi = crawling_problem(0)
    lam = np.zeros(8)
    cone_pgs(W, b, lo, hi, CRAWL_ROLES, CRAWL_MU, lam, 0.0, 50)
    residual = interior_finish(W, b, lo, hi, CRAWL_ROLES, CRAWL_MU, lam.copy(), lam, 0.0)
    assert residual <= ROUND_OFF * magnitude(W, b, lam)
    assert np.hypot(lam[3], lam[4]) == pytest.approx(CRAWL_MU[3] * lam[2], rel=1e-12)  # on the edge


def test_a_start_that_solves_is_kept_as_it_is():
    p = SLIDING
    lam = sliding_solution()
    start = cone_residual(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], lam)
    kept = lam.copy()
    assert newton_polish(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], lam, start) == start
    np.testing.assert_array_equal(lam, kept)


def test_a_disc_no_impulse_acts_through_is_held_not_divided_by():
    """A contact whose tangents act on nothing (their 2 x 2 block of W zero, s = 0): the map holds them (G = 0,
    unit rows of J) instead of dividing by s (numba raises ZeroDivisionError), and Newton's method still solves the
    normal, lambda_n = -b_n / W_nn."""
    W = np.diag([2.0, 0.0, 0.0])
    b = np.array([-1.0, 0.3, 0.0])
    role, mu = np.array([NORMAL, TANGENT, TANGENT2]), np.array([0.0, 0.5, 0.0])
    lo, hi = np.array([0.0, -np.inf, -np.inf]), np.full(3, np.inf)
    lam = np.array([0.2, 0.0, 0.0])
    G, J = np.empty(3), np.empty((3, 3))
    natural_map(W, b, lo, hi, role, mu, lam, G, J, True)
    assert G[1] == 0.0 and G[2] == 0.0
    np.testing.assert_array_equal(J[1:], [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    assert newton_polish(W, b, lo, hi, role, mu, lam, 0.0) <= 1e-15
    assert lam[0] == pytest.approx(0.5, rel=1e-15)
