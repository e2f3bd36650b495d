"""Tresca's problem from inside (rbody.engine.constraints.interior): the log barrier's solution against closed forms,
the states read from it, and the fixed point on the normals that finishes a crawl of Gauss-Seidel exactly."""

import numpy as np
import pytest

from rbody.engine.constraints.cone import (NORMAL, ROLL, ROLL2, ROW, SPIN, TANGENT, TANGENT2, cone_pgs,
                                           cone_residual, magnitude)
from rbody.engine.constraints.interior import friction_radii, interior_finish, snapped, tresca_barrier
from rbody.engine.constraints.stepping import cone_solve

from tests.rbody.engine.test_cone_drift import BOX, MU, ROLES, crawling_problem

SLIDING = dict(W=np.diag([2.0, 3.0, 3.0]), b=np.array([-1.0, 4.0, -3.0]), role=np.array([NORMAL, TANGENT, TANGENT2]),
               mu=np.array([0.0, 0.5, 0.0]), lo=np.array([0.0, -np.inf, -np.inf]), hi=np.full(3, np.inf))


def sliding_solution():
    """A contact on its own (W diagonal): lambda_n = -b_n / W_nn = 0.5; its free tangential impulse -b_t / W_tt
    (|.| = 5/3) is beyond mu lambda_n = 0.25, so it slides: lambda_t = -0.25 b_t / |b_t|."""
    b = SLIDING["b"]
    return np.array([0.5, -0.25 * b[1] / np.hypot(b[1], b[2]), -0.25 * b[2] / np.hypot(b[1], b[2])])


def test_the_barrier_reaches_a_sliding_contact_and_the_finish_makes_it_exact():
    exact = sliding_solution()
    p = SLIDING
    inside, steps = tresca_barrier(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], exact.copy())
    assert 0 < steps < 500
    assert np.hypot(inside[1], inside[2]) < 0.25  # strictly inside the disc (a barrier's iterate)
    np.testing.assert_allclose(inside, exact, rtol=1e-9, atol=1e-12)  # within t / |w| of the edge
    lam = np.zeros(3)
    normals = np.array([0.3, 0.0, 0.0])  # radii from a wrong normal: the next round's come from this one
    interior_finish(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], normals, lam, 0.0)
    np.testing.assert_allclose(normals[0], 0.5, rtol=1e-9)
    residual = interior_finish(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], normals, lam, 0.0)
    assert residual <= 1e-15
    np.testing.assert_allclose(lam, exact, rtol=1e-15, atol=1e-16)


def test_the_states_are_read_once_on_the_way_down():
    """Where the states read early miss the goal (here a goal no reading meets), they are read once, not again
    further down the path (on a landing quadruped, its radii from Gauss-Seidel's first round, the readings further
    down missed too): the path goes on to its end unchanged (the iterate is centred where the gap first falls below
    TRY_BELOW whether or not it is read). Where they meet it (the solution's own radii), the path is left at that
    first reading."""
    from rbody.engine.constraints.interior import _central_path

    p = SLIDING
    args = (p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"])
    normals = sliding_solution()
    full, full_steps, _early, readings = _central_path(*args, normals, 0.0, np.zeros(3), False)
    assert readings == 0
    lam = np.zeros(3)
    inside, steps, early, readings = _central_path(*args, normals, -1.0, lam, True)
    assert readings == 1 and early == np.inf
    assert steps == full_steps
    np.testing.assert_array_equal(inside, full)
    inside, steps, early, readings = _central_path(*args, normals, 1e-15, lam, True)
    assert readings == 1 and early <= 1e-15
    assert steps < full_steps  # left before the path's last steps
    np.testing.assert_allclose(lam, sliding_solution(), rtol=1e-15, atol=1e-16)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_the_central_path_is_followed_by_primal_dual_steps(seed):
    """Tresca's problem down its central path to a gap of 1e-18 of its scale: the sliding contact (seed 0) and the
    crawls of test_cone_drift from 50 sweeps (seeds 1 to 4) in at most 40 Newton steps (17, 24, 30, 29 and 31), where
    the log barrier's centrings (t shrunk 50 times between two) took 52, 66, 57, 67 and 68; and the end is Tresca's
    solution: the sliding contact's closed form, and for each its natural map at 0."""
    if seed == 0:
        p = SLIDING
        W, b, lo, hi, role, mu = p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"]
        normals = sliding_solution()
    else:
        W, b, lo, hi = crawling_problem(seed)
        role, mu = ROLES, MU
        lam = np.zeros(8)
        cone_pgs(W, b, lo, hi, role, mu, lam, 0.0, 50)
        normals = lam
    inside, steps = tresca_barrier(W, b, lo, hi, role, mu, normals.copy())
    assert 0 < steps <= 40
    if seed == 0:
        np.testing.assert_allclose(inside, sliding_solution(), rtol=1e-9, atol=1e-12)
    radius = friction_radii(role, mu, normals)
    for i, r in enumerate(role):  # inside every set (a disc's slack as the barrier takes it: within t / |w| of 0)
        if r == SPIN:
            assert abs(inside[i]) < radius[i]
        elif r in (TANGENT, ROLL):
            assert radius[i] * radius[i] - inside[i] * inside[i] - inside[i + 1] * inside[i + 1] > 0.0
        elif np.isfinite(lo[i]):
            assert inside[i] > lo[i]
    np.testing.assert_allclose(tresca_natural_map(W, b, lo, hi, role, radius, inside), 0.0, rtol=0, atol=1e-9)


def tresca_natural_map(W, b, lo, hi, role, radius, lam):
    """lam - P_K(lam - (W lam + b)), K the boxes and half-lines, the intervals [-r, r] and the discs of radius r
    (Tresca's law): 0 exactly at Tresca's solution."""
    z = lam - (W @ lam + b)
    projected = z.copy()
    for i, r in enumerate(role):
        if r in (ROW, NORMAL):
            projected[i] = np.clip(z[i], lo[i], hi[i])
        elif r == SPIN:
            projected[i] = np.clip(z[i], -radius[i], radius[i])
        elif r in (TANGENT, ROLL):
            length = np.hypot(z[i], z[i + 1])
            if length > radius[i]:
                projected[i:i + 2] = z[i:i + 2] * (radius[i] / length if radius[i] > 0.0 else 0.0)
    return lam - projected


def test_friction_radii_follow_the_normals():
    role = np.array([NORMAL, TANGENT, TANGENT2, SPIN, ROLL, ROLL2, ROW])
    mu = np.array([0.0, 0.8, 0.0, 0.02, 0.01, 0.0, 0.0])
    radius = friction_radii(role, mu, np.array([2.0, 9, 9, 9, 9, 9, 9]))
    np.testing.assert_array_equal(radius, [0.0, 1.6, 0.0, 0.04, 0.02, 0.0, 0.0])
    assert not friction_radii(role, mu, np.array([-1.0, 9, 9, 9, 9, 9, 9])).any()  # a pulling normal: no set


def test_snapped_puts_near_impulses_on_their_bounds_only():
    role = np.array([ROW, NORMAL, TANGENT, TANGENT2, SPIN])
    mu = np.array([0.0, 0.0, 0.5, 0.0, 0.1])
    lo = np.array([-1.0, 0.0, -np.inf, -np.inf, -np.inf])
    hi = np.array([1.0, np.inf, np.inf, np.inf, np.inf])
    lam = np.array([1.0 - 1e-7, 2.0, 0.6 * (1 - 1e-7), 0.8 * (1 - 1e-7), -0.2 * (1 - 1e-3)])
    x = snapped(role, mu, lo, hi, lam, 1e-5)
    assert x[0] == 1.0                       # within 1e-5 of its box's width 2
    assert x[1] == 2.0                       # a pushing normal stays
    assert np.hypot(x[2], x[3]) == pytest.approx(1.0, rel=1e-15)  # on the disc's edge mu lambda_n
    assert x[4] == lam[4]                    # 1e-3 from its end: left inside
    assert snapped(role, mu, lo, hi, lam, 1e-2)[4] == -0.2  # within 1e-2: on its end mu_s lambda_n


def round_off(W, b, lam):
    return 64 * np.finfo(float).eps * magnitude(W, b, lam)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_interior_finish_solves_a_crawl_at_once(seed):
    """The crawl of test_cone_drift (a pair of friction rows along W's null space beside a contact at its spin and
    rolling limits, its tangents sticking): from 50 sweeps of Gauss-Seidel (residual 1e-7, thousands of sweeps from
    the bound), one round of the interior finish solves it to round-off."""
    W, b, lo, hi = crawling_problem(seed)
    lam = np.zeros(8)
    cone_pgs(W, b, lo, hi, ROLES, MU, lam, 0.0, 50)
    assert cone_residual(W, b, lo, hi, ROLES, MU, lam) > 1e-9
    residual = interior_finish(W, b, lo, hi, ROLES, MU, lam.copy(), lam, 0.0)
    assert residual <= round_off(W, b, lam)
    assert residual == cone_residual(W, b, lo, hi, ROLES, MU, lam)
    w = W @ lam + b
    assert lam[0] == -BOX and w[0] > 0.0  # the lower row on its bound, as the closed form of test_cone_drift has it


@pytest.mark.parametrize("seed", [1, 4])
def test_a_crawl_within_the_tolerance_is_still_finished_from_inside(seed):
    """With a loose tolerance (1e-6) the rounds of cone_solve end within it, the crawl left at 1e-7, above the rounds'
    1e-3 of it: the interior finish is tried there too, and the problem is solved to round-off (it was left at 1e-7
    where the finish was tried only above the tolerance; the Go1's landing from its published qpos0 likewise
    crawled from 2e-11 to 7e-14 in 13 rounds, 20 ms)."""
    W, b, lo, hi = crawling_problem(seed)
    lam = np.zeros(8)
    residual = cone_solve(W, b, lo, hi, ROLES, MU, lam, 1e-6, 2000)
    assert residual <= round_off(W, b, lam)
    assert residual == cone_residual(W, b, lo, hi, ROLES, MU, lam)
    assert lam[0] == -BOX  # the crawl's row on its bound (test_cone_drift's closed form)


def test_a_residual_of_impulses_that_are_not_finite_is_infinite():
    """A finish that breaks down (NaN impulses) is not taken for a solution: max passes over NaN, so the residual
    would read 0."""
    p = SLIDING
    lam = np.array([np.nan, 0.0, 0.0])
    assert cone_residual(p["W"], p["b"], p["lo"], p["hi"], p["role"], p["mu"], lam) == np.inf


def test_a_box_of_width_zero_has_no_path_and_is_still_finished():
    """A row boxed in [0.5, 0.5] has no inside: the path is not followed (no division by its zero slack), and the
    states read from the start solve the problem: the row on its bound, the normal lambda_n = -b_n / W_nn."""
    W, b = np.diag([2.0, 3.0]), np.array([0.4, -1.5])
    role, mu = np.array([ROW, NORMAL]), np.zeros(2)
    lo, hi = np.array([0.5, 0.0]), np.array([0.5, np.inf])
    lam = np.zeros(2)
    residual = interior_finish(W, b, lo, hi, role, mu, lam.copy(), lam, 0.0)
    assert residual <= 1e-15
    np.testing.assert_allclose(lam, [0.5, 0.5], rtol=1e-15)
