"""Newton's step on a start's own states (rbody.engine.constraints.cone.hold_states): the warm start of a body resting
on redundant contacts keeps its share of the load and loses its round-off.

A box of 10 kg rests on four condim 6 corners (24 rows of rank 6): its sticking impulses are one of a six-parameter
family (W's null space: the corners' tangential forces can push against each other, the spins and rolling torques
trade with the tangents). The last step's finished impulses carry one member of the family and the round-off of
the velocities gathered since; the step keeps that member (the load does not jump between steps) and solves it to
round-off, where a sweep of Gauss-Seidel leaves it 7 times above and stick_polish moves to its own member. Last,
the face step of sticking_qp (the pseudo-inverse's, by a pivoted Cholesky factor) on the same rows."""

import numpy as np

from rbody.engine.constraints.cone import (NORMAL, ROLL, ROLL2, SPIN, TANGENT, TANGENT2, _face_step, cone_pgs,
                                           cone_residual, hold_states, inside_cones, magnitude, stick_polish)
from rbody.engine.constraints.stepping import cone_solve

MASS, INERTIA = 10.0, np.array([0.1, 0.2, 0.25])  # [kg], [kg m^2] about the box's axes at its centre
CORNERS = np.array([[0.2, 0.1, -0.05], [-0.2, 0.1, -0.05], [-0.2, -0.1, -0.05], [0.2, -0.1, -0.05]])  # [m]
ROLES = np.tile([NORMAL, TANGENT, TANGENT2, SPIN, ROLL, ROLL2], 4)
MU = np.tile([0.0, 0.8, 0.0, 0.02, 0.01, 0.0], 4)
STEP = 0.002  # [s]


def resting_box():
    """(W, b, lo, hi) of the box's step from rest: rows per corner the normal (z), the tangents (x, y), the spin
    (about z) and rolling (about x, y); b the rows' rates after a free step under gravity."""
    J = []
    for p in CORNERS:
        for d in np.eye(3)[[2, 0, 1]]:
            J.append(np.concatenate([d, np.cross(p, d)]))
        for axis in np.eye(3)[[2, 0, 1]]:
            J.append(np.concatenate([np.zeros(3), axis]))
    J = np.array(J)
    W = J @ np.diag(1.0 / np.concatenate([[MASS] * 3, INERTIA])) @ J.T
    b = J @ np.array([0.0, 0.0, -9.81 * STEP, 0.0, 0.0, 0.0])
    lo = np.where(ROLES == NORMAL, 0.0, -np.inf)
    return W, b, lo, np.full(24, np.inf)


def squeezed_solution(W, b, lo, hi):
    """A sticking solution that is not the least-norm one: the solved impulses plus the corners' tangential forces
    pushing the x-pairs towards each other at a tenth of mu lambda_n (in W's null space, so every velocity stays 0)."""
    lam = np.zeros(24)
    assert cone_solve(W, b, lo, hi, ROLES, MU, lam, 1e-10, 2000) <= 1e-16
    squeeze = np.zeros(24)
    squeeze[[1, 7, 13, 19]] = [-1.0, 1.0, 1.0, -1.0]
    np.testing.assert_allclose(W @ squeeze, 0.0, rtol=0, atol=1e-15)
    return lam + 0.1 * MU[1] * lam[0] * squeeze


def round_off(W, b, lam):
    return 64 * np.finfo(float).eps * magnitude(W, b, lam)


def warm_start():
    """The problem and its squeezed solution, then a start off it by 1e-13 N s a row (a residual of 2e-12 m/s)."""
    W, b, lo, hi = resting_box()
    exact = squeezed_solution(W, b, lo, hi)
    start = exact + 1e-13 * np.random.default_rng(0).normal(size=24)
    return W, b, lo, hi, exact, start


def test_the_squeezed_load_solves_the_box_inside_its_cones():
    W, b, lo, hi = resting_box()
    exact = squeezed_solution(W, b, lo, hi)
    assert cone_residual(W, b, lo, hi, ROLES, MU, exact) <= round_off(W, b, exact)
    assert inside_cones(ROLES, MU, exact)
    np.testing.assert_allclose(exact[0::6].sum(), MASS * 9.81 * STEP, rtol=1e-12)  # the weight


def test_hold_states_takes_the_round_off_and_keeps_the_start():
    W, b, lo, hi, exact, start = warm_start()
    before = cone_residual(W, b, lo, hi, ROLES, MU, start)
    assert before > 1e-12
    swept = start.copy()
    cone_pgs(W, b, lo, hi, ROLES, MU, swept, 0.0, 1)
    assert cone_residual(W, b, lo, hi, ROLES, MU, swept) > 5 * round_off(W, b, swept)  # a sweep leaves it above
    held = start.copy()
    residual = hold_states(W, b, lo, hi, ROLES, MU, held)
    assert residual == cone_residual(W, b, lo, hi, ROLES, MU, held)
    assert residual <= round_off(W, b, held)
    np.testing.assert_allclose(held, exact, rtol=0.0, atol=1e-12)  # the squeeze kept (0.004 N s)
    moved = start.copy()
    stick_polish(W, b, lo, hi, ROLES, MU, moved, 8)
    assert np.abs(moved - exact).max() > 1e-3  # the least-norm member: the squeeze gone


def test_a_warm_start_within_the_tolerance_keeps_its_share_of_the_load():
    """cone_solve from the start (its residual within 1e-3 of the tolerance 1e-8: no sweep to spend) keeps the
    squeezed member to round-off; stick_polish, before the hold, moved the load to its own member."""
    W, b, lo, hi, exact, start = warm_start()
    lam = start.copy()
    residual = cone_solve(W, b, lo, hi, ROLES, MU, lam, 1e-8, 2000)
    assert residual <= round_off(W, b, lam)
    np.testing.assert_allclose(lam, exact, rtol=0.0, atol=1e-12)


def test_a_warm_start_above_a_thousandth_of_the_tolerance_is_held_not_finished():
    """The same start against the step's own tolerance, 1e-10: its residual (2e-12) is above 1e-3 of it, as a
    five-box stack's starts at dt = 0.1 are above it (their terms' round-off is 1.8e-12). Held by Newton's step on
    its states, it keeps the squeezed member to round-off, where the finishes (stick_polish's rounds, 0.6 to 1 ms on
    that stack) moved the load to their own member."""
    W, b, lo, hi, exact, start = warm_start()
    assert 1e-3 * 1e-10 < cone_residual(W, b, lo, hi, ROLES, MU, start) <= 1e-10
    lam = start.copy()
    residual = cone_solve(W, b, lo, hi, ROLES, MU, lam, 1e-10, 2000)
    assert residual <= round_off(W, b, lam)
    np.testing.assert_allclose(lam, exact, rtol=0.0, atol=1e-12)


def test_hold_states_leaves_a_sliding_contact_alone():
    """A contact on its cone's edge (sliding) has no sticking state to hold: lam is kept as it is."""
    W = np.diag([2.0, 3.0, 3.0])
    b = np.array([-1.0, 4.0, -3.0])
    role, mu = np.array([NORMAL, TANGENT, TANGENT2]), np.array([0.0, 0.5, 0.0])
    lo, hi = np.array([0.0, -np.inf, -np.inf]), np.full(3, np.inf)
    lam = np.array([0.5, -0.2, 0.15])  # |lambda_t| = mu lambda_n: on the edge
    kept = lam.copy()
    residual = hold_states(W, b, lo, hi, role, mu, lam)
    assert residual == cone_residual(W, b, lo, hi, role, mu, kept)
    np.testing.assert_array_equal(lam, kept)


def test_the_face_step_is_the_pseudo_inverses():
    """sticking_qp's Newton step on a face, _face_step(A, r) = A^+ r, against the SVD's: the box's W (24 rows of rank
    6) and a block of it, with right sides inside A's range and outside it (the gradient's part along the null
    space, which the active-set method follows to a bound)."""
    W, _b, _lo, _hi = resting_box()
    rng = np.random.default_rng(3)
    for rows in (np.arange(24), np.arange(3, 17)):
        A = np.ascontiguousarray(W[np.ix_(rows, rows)])
        inside = A @ rng.normal(size=rows.size)
        for r in (inside, rng.normal(size=rows.size)):
            expected = np.linalg.pinv(A, rcond=1e-12) @ r
            d = _face_step(A, r)
            np.testing.assert_allclose(d, expected, rtol=0.0, atol=1e-12 * np.abs(expected).max())
            rest = r - A @ d  # r's part along the null space: orthogonal to A's range
            assert np.abs(A @ rest).max() <= 1e-12 * np.abs(r).max()
