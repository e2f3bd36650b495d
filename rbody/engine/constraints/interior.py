"""The step's problem with Coulomb cones approached from inside: Tresca's problem by a log barrier, then the states.

Where rows are dependent (a quadruped standing on four condim 6 feet with dry friction in its twelve joints: 36 rows
of rank 18), Gauss-Seidel (rbody.engine.constraints.cone) settles in tens of sweeps on the velocities but then
crawls along W's null space, 1e-7 a sweep, for 10^4 sweeps until the spins and the joints' friction meet the ends
of their intervals; the states read from any iterate before that are wrong, and no exact finish holds.

With every contact's normal impulse held at a value lambda_n^0, the friction sets are fixed (discs |lambda_t| <=
mu lambda_n^0, intervals |lambda_s| <= mu_s lambda_n^0: Tresca's law) and the problem is the convex program

    min q(lambda) = lambda.W.lambda / 2 + b.lambda   over   lambda in K (boxes, half-lines, discs, intervals),

whose stationarity is the problem's complementarity (the normals' included) with those radii. A log barrier solves
it from inside (Boyd and Vandenberghe, Convex Optimization, 11.3): Newton's method on q - t sum log(slack) (a disc's
slack r^2 - |lambda_t|^2), t shrunk by BARRIER_SHRINK once a Newton decrement is below CENTRED of t, down to
BARRIER_END of the problem's scale. The barrier's Hessian makes every Newton system definite, and the iterates
follow the central path: the rows free to move on the solution set (the null space's crawl) end at its centre, not
at wherever Gauss-Seidel stopped, and a row that the solution holds at its bound ends within t / |w| of it. Its
normal impulses are the next lambda_n^0 (the fixed point is Coulomb's problem: Tresca's with radii mu lambda_n).

The states are read from it: every impulse within a relative `near` of its bound put on it (`snapped`), and the exact
finish of rbody.engine.constraints.cone (cone_polish: the held rows solved, the sliding ones on their bounds against
their velocity, the Coulomb radii moving with the normals) taken from there; several `near` (SNAP_LEVELS), the best
kept, and Newton's method on the natural map from it where none reaches the goal (rbody.engine.constraints.
natural_newton: cone_polish's fixed point on a sliding contact's direction is linear and can stall). The states
are read once before the last centrings, and the barrier stops there where they reach the goal.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.constraints.cone import (NORMAL, ROLL, ROW, SPIN, TANGENT, cone_polish, is_disc,
                                           normal_of)
from rbody.engine.constraints.natural_newton import NATURAL, newton_polish, read_newton
from rbody.engine.constraints.solver import cholesky_factor, lower_solve, symmetric_solve, upper_solve

BARRIER_START = 0.1        # the first barrier weight t, of the problem's scale max(|b|, 1) max(lambda_n^0)
BARRIER_SHRINK = 0.02      # t's factor between two centrings
BARRIER_END = 1e-18        # the last t, of that scale: a bound held at a velocity w is then within t / w of it
CENTRED = 0.01             # a centring ends where the Newton decrement -g.d is below this of t
CENTRING_STEPS = 60        # Newton steps at most per t
CENTRING_STALL = 3         # Newton steps that do not halve the least decrement so far end a centring,
ROUNDING_DECREMENT = 1e-12  # where the decrement is below this of |q| (q's rounding, not the damped phase)
TO_BOUNDARY = 0.99         # a Newton step goes at most this share of the way to the nearest bound
SNAP_LEVELS = (1e-2, 1e-3, 1e-4)  # the `near` of the states read from the barrier's impulses (1e-5 and 1e-6 too
                                  # until 2026-11-30: where the first three miss, Newton's method finishes as well)
POLISH_ROUNDS = 4
TRY_BELOW = 1e-12          # interior_finish reads the states once, after the first centring below this weight (of
                           # the scale): on the captured landing problems, readings further down were no better


@njit(cache=True)
def friction_radii(role, mu, normals):
    """Each friction row's bound mu lambda_n^0 (m,) [the impulse's units; a spin's and a rolling pair's in N m s],
    lambda_n^0 = max(normals[n], 0) at the row's normal n; 0 on the other rows."""
    radius = np.zeros(role.shape[0])
    for i in range(role.shape[0]):
        if role[i] == TANGENT or role[i] == SPIN or role[i] == ROLL:
            radius[i] = mu[i] * max(normals[normal_of(role, i)], 0.0)
    return radius


@njit(cache=True)
def _barrier(lam, role, lo, hi, radius, g, H):
    """-sum log(slack) at lam, its gradient added into g (m,) and its Hessian into H (m, m); inf outside K. A friction
    set of radius 0 (its normal not pushing) holds its rows at 0: they carry no barrier (the caller fixes them)."""
    value = 0.0
    for i in range(lam.shape[0]):
        r = role[i]
        if r == ROW or r == NORMAL:
            if lo[i] > -np.inf:
                s = lam[i] - lo[i]
                if not s > 0.0:
                    return np.inf
                value -= np.log(s)
                g[i] -= 1.0 / s
                H[i, i] += 1.0 / (s * s)
            if hi[i] < np.inf:
                s = hi[i] - lam[i]
                if not s > 0.0:
                    return np.inf
                value -= np.log(s)
                g[i] += 1.0 / s
                H[i, i] += 1.0 / (s * s)
        elif r == SPIN and radius[i] > 0.0:
            for sign in (1.0, -1.0):
                s = radius[i] - sign * lam[i]
                if not s > 0.0:
                    return np.inf
                value -= np.log(s)
                g[i] += sign / s
                H[i, i] += 1.0 / (s * s)
        elif is_disc(r) and radius[i] > 0.0:
            x, y = lam[i], lam[i + 1]
            s = radius[i] * radius[i] - x * x - y * y
            if not s > 0.0:
                return np.inf
            value -= np.log(s)
            gx, gy = 2.0 * x / s, 2.0 * y / s
            g[i] += gx
            g[i + 1] += gy
            H[i, i] += 2.0 / s + gx * gx
            H[i + 1, i + 1] += 2.0 / s + gy * gy
            H[i, i + 1] += gx * gy
            H[i + 1, i] += gx * gy
    return value


@njit(cache=True)
def _fixed(role, radius, i):
    """Whether row i is a friction row whose set has radius 0 (held at 0)."""
    if role[i] == ROW or role[i] == NORMAL:
        return False
    first = i - 1 if (role[i] == TANGENT + 1 or role[i] == ROLL + 1) else i  # a pair's second row: its first's set
    return not radius[first] > 0.0


@njit(cache=True)
def _longest_step(lam, d, role, lo, hi, radius):
    """The largest a <= 1 with lam + a d within K's closure."""
    a = 1.0
    for i in range(lam.shape[0]):
        r = role[i]
        if r == ROW or r == NORMAL:
            if d[i] < 0.0 and lo[i] > -np.inf:
                a = min(a, (lo[i] - lam[i]) / d[i])
            if d[i] > 0.0 and hi[i] < np.inf:
                a = min(a, (hi[i] - lam[i]) / d[i])
        elif r == SPIN and radius[i] > 0.0:
            if d[i] > 0.0:
                a = min(a, (radius[i] - lam[i]) / d[i])
            elif d[i] < 0.0:
                a = min(a, (-radius[i] - lam[i]) / d[i])
        elif is_disc(r) and radius[i] > 0.0:  # |lam_t + a d_t| = r: the positive root
            x, y, dx, dy = lam[i], lam[i + 1], d[i], d[i + 1]
            A = dx * dx + dy * dy
            if A > 0.0:
                B = x * dx + y * dy
                C = x * x + y * y - radius[i] * radius[i]
                a = min(a, (-B + np.sqrt(max(B * B - A * C, 0.0))) / A)
    return a


@njit(cache=True)
def _newton_direction(H, g, d):
    """d = -H^-1 g for the barrier's Hessian H (m, m), definite (Cholesky); by the eigen-decomposition where round-
    off leaves it singular (free rows that are dependent)."""
    m = g.shape[0]
    L = np.empty((m, m))
    if not cholesky_factor(H, L, 0.0, 0.0):
        symmetric_solve(H, -g, d)
        return
    x = upper_solve(L, lower_solve(L, -g))  # L^T x = L^-1 (-g)
    for i in range(m):
        d[i] = x[i]


@njit(cache=True)
def _barrier_start(lo, hi, role, normals):
    """The barrier's first iterate (m,), the centre of each set (normals at max(normals, 1e-3 of their largest)),
    and the problem's scale of impulses, max(lambda_n^0)."""
    m = role.shape[0]
    top = 1e-300
    for i in range(m):
        if role[i] == NORMAL:
            top = max(top, normals[i])
    lam = np.zeros(m)
    for i in range(m):
        if role[i] == ROW or role[i] == NORMAL:
            if lo[i] > -np.inf and hi[i] < np.inf:
                lam[i] = 0.5 * (lo[i] + hi[i])
            elif lo[i] > -np.inf:
                lam[i] = lo[i] + (max(normals[i], 1e-3 * top) if role[i] == NORMAL else top)
            elif hi[i] < np.inf:
                lam[i] = hi[i] - top
    return lam, top


@njit(cache=True)
def _centre(W, b, lo, hi, role, radius, lam, t):
    """Newton's method on q + t barrier from lam (m,), in place, until its decrement is below CENTRED of t, or has
    not fallen below half its least for CENTRING_STALL steps while below ROUNDING_DECREMENT of |q| (round-off:
    the last weights' criterion, 1e-20 of the scale, lies below q's rounding, and the steps went on to
    CENTRING_STEPS), or CENTRING_STEPS. Returns the Newton steps taken."""
    m = b.shape[0]
    g, H, d = np.empty(m), np.empty((m, m)), np.empty(m)
    gb, Hb = np.empty(m), np.empty((m, m))
    steps = 0
    least, stalled = np.inf, 0
    for _step in range(CENTRING_STEPS):
        gb[:] = 0.0
        Hb[:, :] = 0.0
        value = _barrier(lam, role, lo, hi, radius, gb, Hb)
        w = b + W @ lam
        for i in range(m):
            g[i] = w[i] + t * gb[i]
            for j in range(m):
                H[i, j] = W[i, j] + t * Hb[i, j]
        for i in range(m):  # the rows of a set of radius 0: held at 0
            if _fixed(role, radius, i):
                g[i] = 0.0
                for j in range(m):
                    H[i, j] = H[j, i] = 0.0
                H[i, i] = 1.0
        _newton_direction(H, g, d)
        steps += 1
        decrement = 0.0
        for i in range(m):
            decrement -= g[i] * d[i]
        if not decrement > CENTRED * t:
            break
        objective = 0.5 * (lam @ (w + b))  # q
        if decrement < 0.5 * least:
            least, stalled = decrement, 0
        elif decrement <= ROUNDING_DECREMENT * abs(objective):  # round-off: the decrement no longer falls (at the
            stalled += 1                                        # last weights, 1e-16 of q)
            if stalled >= CENTRING_STALL:
                break
        a = TO_BOUNDARY * _longest_step(lam, d, role, lo, hi, radius)
        start = objective + t * value  # q + t barrier
        trial = lam.copy()
        while a > 1e-16:  # Armijo's backtracking on q + t barrier
            for i in range(m):
                trial[i] = lam[i] + a * d[i]
            gb[:] = 0.0
            Hb[:, :] = 0.0
            barrier = _barrier(trial, role, lo, hi, radius, gb, Hb)
            if barrier < np.inf and (0.5 * (trial @ (W @ trial)) + b @ trial + t * barrier
                                     <= start - 0.25 * a * decrement):
                break
            a *= 0.5
        if not a > 1e-16:
            break
        lam[:] = trial
    return steps


@njit(cache=True)
def _problem_scale(b, top):
    size = 1.0
    for i in range(b.shape[0]):
        size = max(size, abs(b[i]))
    return size * top


@njit(cache=True)
def _barrier_path(W, b, lo, hi, role, mu, normals, goal, lam, read_early):
    """The barrier down its path (tresca_barrier) from the centre of each set; where read_early, the states are read
    once, after the first centring whose weight is below TRY_BELOW of the problem's scale (_read_states at the first
    of SNAP_LEVELS, into lam (m,)), and the path is left there where they reach `goal`. Returns (the last iterate
    (m,), Newton steps, the residual of lam: inf where the early reading did not reach goal, the readings taken)."""
    radius = friction_radii(role, mu, normals)
    inside, top = _barrier_start(lo, hi, role, normals)
    scale = _problem_scale(b, top)
    t = BARRIER_START * scale
    steps = 0
    readings = 0
    while True:
        steps += _centre(W, b, lo, hi, role, radius, inside, t)
        if t <= BARRIER_END * scale:
            break
        if read_early and readings == 0 and t <= TRY_BELOW * scale:
            readings = 1
            trial = lam.copy()
            early = _read_states(W, b, lo, hi, role, mu, inside, goal, 1, trial)
            if early <= goal:
                lam[:] = trial
                return inside, steps, early, readings
        t *= BARRIER_SHRINK
    return inside, steps, np.inf, readings


@njit(cache=True)
def tresca_barrier(W, b, lo, hi, role, mu, normals):
    """The solution (m,) of Tresca's problem (module docstring) with the radii friction_radii(role, mu, normals), by
    the log barrier, from the centre of each set (normals at max(normals, 1e-3 of their largest)). W (m, m), b (m,)
    as in cone_pgs. Returns (lambda, Newton steps)."""
    inside, steps, _early, _readings = _barrier_path(W, b, lo, hi, role, mu, normals, 0.0, np.empty(0), False)
    return inside, steps


@njit(cache=True)
def snapped(role, mu, lo, hi, lam, near):
    """lam (m,) with every impulse within a relative `near` of its bound put on it: a box row within near of its
    width (of max(|bound|, the largest normal) for a half-line), a normal within near of the largest normal on 0, a
    spin within near of mu_s lambda_n on it, a disc's pair within near of its radius on its edge."""
    x = lam.copy()
    m = x.shape[0]
    top = 1e-300
    for i in range(m):
        if role[i] == NORMAL:
            top = max(top, x[i])
    for i in range(m):
        if role[i] == ROW or role[i] == NORMAL:
            width = hi[i] - lo[i]
            for bound in (lo[i], hi[i]):
                reference = width if width < np.inf else max(abs(bound), top)
                if abs(bound) < np.inf and abs(x[i] - bound) <= near * reference:
                    x[i] = bound
    for i in range(m):
        if role[i] == SPIN or is_disc(role[i]):
            radius = mu[i] * max(x[normal_of(role, i)], 0.0)
            if role[i] == SPIN:
                if abs(abs(x[i]) - radius) <= near * radius:
                    x[i] = radius if x[i] > 0.0 else -radius
            else:
                length = np.sqrt(x[i] * x[i] + x[i + 1] * x[i + 1])
                if length > 0.0 and abs(length - radius) <= near * radius:
                    x[i] *= radius / length
                    x[i + 1] *= radius / length
    return x


@njit(cache=True)
def _read_states(W, b, lo, hi, role, mu, inside, goal, levels, lam):
    """The states read from the barrier's impulses inside (m,) at the first `levels` of SNAP_LEVELS, each finished
    exactly (cone_polish) until one reaches `goal`; where none does, Newton's method on the natural map from the best
    (natural_newton: a sliding contact's direction, which cone_polish's fixed point approaches linearly), and where
    that falls short, on the best's pieces read more widely (read_newton). The best written into lam (m,). Returns
    its residual."""
    best = np.inf
    for level in range(levels):
        trial = snapped(role, mu, lo, hi, inside, SNAP_LEVELS[level])
        residual = cone_polish(W, b, lo, hi, role, mu, trial, POLISH_ROUNDS)
        if residual < best:
            best = residual
            lam[:] = trial
        if best <= goal:
            return best
    best = newton_polish(W, b, lo, hi, role, mu, lam, goal, NATURAL)
    if best > goal:  # a disc on its edge at a slip near round-off, read as sticking: the pieces read more widely
        best = read_newton(W, b, lo, hi, role, mu, lam, goal, best)
    return best


@njit(cache=True)
def interior_finish(W, b, lo, hi, role, mu, normals, lam, goal):
    """One round of the fixed point on the normals: Tresca's problem with the radii of `normals` (m,) by the barrier,
    its states read and finished exactly (_read_states), written into lam (m,), and the barrier's impulses into
    normals (the next round's radii). After the first centring whose weight is below TRY_BELOW of the problem's
    scale, the states are read once (at the first of SNAP_LEVELS), and the barrier stops there where they reach
    `goal`: the last centrings (down to BARRIER_END) take half its steps, and where the radii are right (a robot
    settling) the states are right before them. Where the radii are not yet Coulomb's (a landing, its normals from
    Gauss-Seidel's first round), the states read further down the path were no better, and each reading cost as
    much as two centrings. Returns the residual of lam."""
    inside, _steps, early, _readings = _barrier_path(W, b, lo, hi, role, mu, normals, goal, lam, True)
    normals[:] = inside
    if early <= goal:
        return early
    return _read_states(W, b, lo, hi, role, mu, inside, goal, len(SNAP_LEVELS), lam)


__all__ = ["friction_radii", "interior_finish", "snapped", "tresca_barrier"]
