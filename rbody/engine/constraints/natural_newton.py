"""The step's problem with Coulomb cones finished by Newton's method on its natural map, compiled.

The problem of rbody.engine.constraints.cone is solved where every block of lambda is the projection of itself moved
against its velocity w = W lambda + b, scaled by the block's step 1 / d (d = W_ii for a one-row block, the largest
eigenvalue s of a disc's 2 x 2 block):

    G(lambda) = d (lambda - P_K(lambda)(lambda - w / d)) = 0,

K(lambda) the blocks' sets (boxes and half-lines, a spin's interval |lambda_s| <= mu_s lambda_n, a disc |lambda_t|
<= mu lambda_n), so that max |G| over the rows is cone_residual. G is piecewise smooth: on each block the piece
is fixed by where lambda - w / d lies,
- inside its set (a free row, a pushing normal, a sticking contact): G = w, its rows of the Jacobian W's;
- beyond a bound of an interval: G = d (lambda - bound), the bound mu_s lambda_n a spin's;
- outside a disc of radius r = mu lambda_n (sliding), with z = lambda_t - w_t / s, u = z / |z|:
  G = s (lambda_t - r u), its Jacobian s (E - (r / |z|) (I - u u^T) (E - W_t / s) - mu u e_n^T),
  E the rows' own unit rows, e_n the normal's.

Newton's method on the piece G's point lies in is the semismooth Newton of Alart and Curnier's formulation (the
natural map of Siconos's fc3d solvers, Acary and Brogliato 2008, 13.3). W of a quadruped's 36 rows has rank 18,
so the Jacobian is singular: each step is Levenberg and Marquardt's, (J^T J + nu I) dx = -J^T G with
nu = |G|^2 (Yamashita and Fukushima: quadratic near a solution set that is not a point), J^T J's diagonal's 1e-14
at least, and Armijo's backtracking on |G|^2 / 2. Newton's method does not find the pieces: from an iterate whose
rows that the solution holds on their bounds are still inside them (a barrier's iterate far up its path, Gauss-
Seidel's crawl along W's null space), it stops on a point of its wrong piece where J^T G = 0. So it finishes where the
states are already read (rbody.engine.constraints.interior: the barrier's impulses snapped onto their bounds), where
cone_polish's fixed point on a sliding contact's direction is linear and stalls (5e-7 on test_interior's crawl).

Or where the pieces are known: a robot settling on its feet gives the same problem step after step, its pieces
(which joints' dry friction slides, which feet's spin and rolling slide) those of the last step's impulses while
its b moves. G's pieces then read from those impulses (read_pieces: a row on its bound, a disc on its edge) and held
(natural_map with `pieces`), Newton's method from them reaches round-off in three steps (states_newton), where the
pieces read from where lambda - w / d lies at the new b are wrong on a few rows (a friction that stuck now pushed
past its bound) and Newton's steps stall on them (5e-8).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.constraints.cone import (ROUND_OFF, ROW, SPIN, ROLL2, TANGENT2, _bounds, _tangent_step_size,
                                           cone_residual, is_disc, magnitude, normal_of)
from rbody.engine.constraints.solver import cholesky_factor, lower_solve, upper_solve

NEWTON_STEPS = 20   # Newton steps at most
STALL_STEPS = 3     # a run of this many steps that has not halved the residual ends it
ARMIJO = 1e-4       # sufficient decrease of |G|^2 / 2, of the step's slope
# a block's piece (read_pieces): a one-row block free (w = 0), on its lower or upper bound; a disc sticking or sliding
FREE, LOWER, UPPER, STICKS, SLIDES = 0, 1, 2, 3, 4
ON_BOUND = 1e-9     # read_pieces: an impulse within this (relative) of its bound is on it
# read_newton: the widening readings of an iterate near a solution (the interior finish's best), each tried in turn
READ_LEVELS = np.array([1e-6, 1e-4, 1e-3, 1e-2])
SLIP_FLOOR = 1e3    # states_newton: a friction on its bound must slip faster than this many times w's round-off
NATURAL = np.empty(0, dtype=np.int64)  # natural_map's pieces where none are held: each block's own


@njit(cache=True)
def natural_map(W, b, lo, hi, role, mu, lam, G, J, with_jacobian, pieces):
    """G (m,) <- the natural map at lam (module docstring) [w's units]; J (m, m) <- its Jacobian on G's piece where
    with_jacobian. pieces (m,): each block's piece held (FREE, LOWER, UPPER, STICKS, SLIDES on its first row), or
    empty (NATURAL): the piece where lambda - w / d lies. Returns |G|^2 / 2."""
    m = b.shape[0]
    held = pieces.shape[0] > 0
    w = b + W @ lam
    if with_jacobian:
        J[:, :] = 0.0
    for i in range(m):
        r = role[i]
        if r == TANGENT2 or r == ROLL2:
            continue  # written with the first row of its disc
        if is_disc(r):
            s = _tangent_step_size(W, i)
            n = normal_of(role, i)
            if not s > 0.0:  # rows no impulse acts through: held where they are
                G[i], G[i + 1] = 0.0, 0.0
                if with_jacobian:
                    J[i, i], J[i + 1, i + 1] = 1.0, 1.0
                continue
            radius = mu[i] * max(lam[n], 0.0)
            zx, zy = lam[i] - w[i] / s, lam[i + 1] - w[i + 1] / s
            length = np.sqrt(zx * zx + zy * zy)
            if held and pieces[i] == SLIDES and not length > 0.0:  # held sliding with no direction: lambda_t = 0
                G[i], G[i + 1] = s * lam[i], s * lam[i + 1]
                if with_jacobian:
                    J[i, i], J[i + 1, i + 1] = s, s
                continue
            if (pieces[i] == STICKS) if held else length <= radius:  # sticking: w_t = 0
                G[i], G[i + 1] = w[i], w[i + 1]
                if with_jacobian:
                    J[i, :] = W[i, :]
                    J[i + 1, :] = W[i + 1, :]
            else:  # sliding: lambda_t = r u
                ux, uy = zx / length, zy / length
                G[i], G[i + 1] = s * (lam[i] - radius * ux), s * (lam[i + 1] - radius * uy)
                if with_jacobian:
                    k = radius / length
                    for j in range(m):  # s (E - k (I - u u^T) (E - W_t / s)), row by row
                        dx = (1.0 if j == i else 0.0) - W[i, j] / s
                        dy = (1.0 if j == i + 1 else 0.0) - W[i + 1, j] / s
                        J[i, j] = s * ((1.0 if j == i else 0.0) - k * ((1.0 - ux * ux) * dx - ux * uy * dy))
                        J[i + 1, j] = s * ((1.0 if j == i + 1 else 0.0) - k * (-ux * uy * dx + (1.0 - uy * uy) * dy))
                    if lam[n] > 0.0:  # the radius moves with the normal
                        J[i, n] -= s * mu[i] * ux
                        J[i + 1, n] -= s * mu[i] * uy
            continue
        d = W[i, i]
        if not d > 0.0:
            G[i] = 0.0
            if with_jacobian:
                J[i, i] = 1.0
            continue
        low, high = _bounds(role, mu, lo, hi, lam, i)
        z = lam[i] - w[i] / d
        lower = pieces[i] == LOWER if held else z <= low
        if lower or ((pieces[i] == UPPER) if held else z >= high):  # on a bound: lambda = bound (a spin's
            bound = low if lower else high                            # +-mu_s lambda_n)
            G[i] = d * (lam[i] - bound)
            if with_jacobian:
                J[i, i] = d
                n = normal_of(role, i)
                if r == SPIN and lam[n] > 0.0:
                    J[i, n] += d * mu[i] if lower else -d * mu[i]
        else:  # free: w = 0
            G[i] = w[i]
            if with_jacobian:
                J[i, :] = W[i, :]
    half = 0.0
    for i in range(m):
        half += G[i] * G[i]
    return 0.5 * half


@njit(cache=True)
def newton_polish(W, b, lo, hi, role, mu, lam, goal, pieces):
    """Newton's method on the natural map (module docstring) from lam (m,), in place, on the pieces `pieces` held
    (natural_map; NATURAL: each step's own): until the residual is at most `goal`, a step finds no decrease,
    STALL_STEPS steps have not halved the residual, or NEWTON_STEPS are taken. lam ends at the iterate of least
    residual (the natural one, cone_residual: the start where none is less). Returns that residual."""
    m = b.shape[0]
    G, J = np.empty(m), np.empty((m, m))
    G_trial, no_jacobian = np.empty(m), np.empty((0, 0))
    best = cone_residual(W, b, lo, hi, role, mu, lam)
    kept = lam.copy()
    floor = 0.0
    for i in range(m):
        floor = max(floor, W[i, i])
    floor = 1e-14 * floor * floor
    merit = natural_map(W, b, lo, hi, role, mu, lam, G, J, True, pieces)
    x, trial = lam.copy(), np.empty(m)
    A, L = np.empty((m, m)), np.empty((m, m))
    mark, since = best, 0
    for _step in range(NEWTON_STEPS):
        if best <= goal:
            break
        for i in range(m):  # J^T J + nu I
            for j in range(i + 1):
                acc = 0.0
                for k in range(m):
                    acc += J[k, i] * J[k, j]
                A[i, j] = A[j, i] = acc
            A[i, i] += max(2.0 * merit, floor)
        if not cholesky_factor(A, L, 0.0, 0.0):
            break
        gradient = J.T @ G  # of |G|^2 / 2
        step = -upper_solve(L, lower_solve(L, gradient))
        slope = gradient @ step  # d|G|^2/2 along the step (< 0)
        if not slope < 0.0:
            break
        a = 1.0
        while a > 1e-10:
            for i in range(m):
                trial[i] = x[i] + a * step[i]
            if natural_map(W, b, lo, hi, role, mu, trial, G_trial, no_jacobian, False, pieces) \
                    <= merit + ARMIJO * a * slope:
                break
            a *= 0.5
        if not a > 1e-10:
            break
        x[:] = trial
        merit = natural_map(W, b, lo, hi, role, mu, x, G, J, True, pieces)
        residual = cone_residual(W, b, lo, hi, role, mu, x)
        if residual < best:
            best = residual
            kept[:] = x
        since += 1
        if best <= 0.5 * mark:
            mark, since = best, 0
        elif since >= STALL_STEPS:
            break
    lam[:] = kept
    return best


@njit(cache=True)
def read_pieces(role, mu, lo, hi, lam, near=ON_BOUND):
    """Each block's piece (m,) as lam (a solution: the last step's impulses) lies: a one-row block on its lower or
    upper bound (within a relative `near` of it; a spin's +-mu_s lambda_n), else free; a disc sliding on its edge
    (within `near` of its radius; a contact that does not push: r = 0), else sticking."""
    m = lam.shape[0]
    pieces = np.zeros(m, dtype=np.int64)
    for i in range(m):
        r = role[i]
        if r == TANGENT2 or r == ROLL2:
            continue
        if is_disc(r):
            radius = mu[i] * max(lam[normal_of(role, i)], 0.0)
            length = np.sqrt(lam[i] * lam[i] + lam[i + 1] * lam[i + 1])
            pieces[i] = SLIDES if length >= (1.0 - near) * radius else STICKS
            continue
        low, high = _bounds(role, mu, lo, hi, lam, i)
        if low > -np.inf and lam[i] <= low + near * abs(low):
            pieces[i] = LOWER
        elif high < np.inf and lam[i] >= high - near * abs(high):
            pieces[i] = UPPER
        else:
            pieces[i] = FREE
    return pieces


@njit(cache=True)
def states_newton(W, b, lo, hi, role, mu, lam, goal):
    """The problem solved from lam (m,), a solution of the last step's, by Newton's method on lam's own pieces held
    (read_pieces: a robot settling on its feet), to round-off. The result is written into lam where it is within
    `goal` and every friction on its bound there (a joint's box, a spin's interval, a sliding disc that pushes) slips
    faster than SLIP_FLOOR times w's round-off: at the edge with no slip, sliding is Coulomb's too, and the step's
    finishes choose sticking there (a block at mu = tan(alpha) stays put). Returns its residual; +inf where it is
    not kept (lam unchanged)."""
    trial = lam.copy()
    exact = ROUND_OFF * magnitude(W, b, lam)  # on to round-off, one or two steps past the goal: the finishes it
    residual = newton_polish(W, b, lo, hi, role, mu, trial, min(goal, exact),  # stands in for are exact (a cube
                             read_pieces(role, mu, lo, hi, lam))  # sliding on an incline, stopped at the goal,
    if residual <= goal and _slips_clear(W, b, lo, hi, role, mu, trial):  # drifted 4e-13 m from its closed form)
        lam[:] = trial
        return residual
    return np.inf


@njit(cache=True)
def read_newton(W, b, lo, hi, role, mu, lam, goal, residual):
    """Newton's method from lam (m,), an iterate near a solution, on its pieces read at each of READ_LEVELS in turn
    (read_pieces), until one reaches `goal`; the least residual found written into lam (lam unchanged where none is
    below its own). residual: lam's own (cone_residual), as the caller's Newton's method returned it. Returns lam's
    residual. Where a contact's disc slides on its edge at a slip near w's round-off (a foot's rolling friction at
    6e-13 rad/s as a quadruped lands), the iterate's impulses lie just inside it, a reading at ON_BOUND holds it
    sticking, and the load shared between that foot and another (W's null space) is then fixed only through a
    singular value of 1e-10: Newton's method stalls at 1e-12. Read as sliding, it reaches round-off in a few
    steps."""
    best = residual
    trial, kept = np.empty_like(lam), lam.copy()
    last = np.full(lam.shape[0], -1)
    for near in READ_LEVELS:
        if best <= goal:
            break
        pieces = read_pieces(role, mu, lo, hi, lam, near)
        if np.array_equal(pieces, last):  # the wider reading changed no block's piece
            continue
        last = pieces
        trial[:] = lam
        reached = newton_polish(W, b, lo, hi, role, mu, trial, goal, pieces)
        if reached < best:
            best = reached
            kept[:] = trial
    lam[:] = kept
    return best


@njit(cache=True)
def _slips_clear(W, b, lo, hi, role, mu, lam):
    """Whether every friction on its bound at lam (read_pieces) slips faster than SLIP_FLOOR times w's round-off."""
    pieces = read_pieces(role, mu, lo, hi, lam)
    w = b + W @ lam
    floor = SLIP_FLOOR * ROUND_OFF * magnitude(W, b, lam)
    for i in range(b.shape[0]):
        r = role[i]
        if pieces[i] == SLIDES and mu[i] * lam[normal_of(role, i)] > 0.0:
            slip = np.sqrt(w[i] * w[i] + w[i + 1] * w[i + 1])
        elif (pieces[i] == LOWER or pieces[i] == UPPER) and \
                ((r == SPIN and mu[i] * lam[normal_of(role, i)] > 0.0)
                 or (r == ROW and lo[i] > -np.inf and hi[i] < np.inf)):
            slip = abs(w[i])
        else:
            continue
        if not slip > floor:
            return False
    return True


__all__ = ["natural_map", "newton_polish", "read_pieces", "read_newton", "states_newton", "NATURAL", "NEWTON_STEPS",
           "READ_LEVELS"]
