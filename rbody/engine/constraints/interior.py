"""The step's problem with Coulomb cones approached from inside: Tresca's problem down its central path, then states.

Where rows are dependent (a quadruped standing on four condim 6 feet with dry friction in its twelve joints: 36 rows
of rank 18), Gauss-Seidel (rbody.engine.constraints.cone) settles in tens of sweeps on the velocities but then
crawls along W's null space, 1e-7 a sweep, for 10^4 sweeps until the spins and the joints' friction meet the ends
of their intervals; the states read from any iterate before that are wrong, and no exact finish holds.

With every contact's normal impulse held at a value lambda_n^0, the friction sets are fixed (discs |lambda_t| <=
mu lambda_n^0, intervals |lambda_s| <= mu_s lambda_n^0: Tresca's law) and the problem is the convex program

    min q(lambda) = lambda.W.lambda / 2 + b.lambda   over   lambda in K (boxes, half-lines, discs, intervals),

whose stationarity is the problem's complementarity (the normals' included) with those radii. Written as
inequalities f_k(lambda) <= 0 (a bound's lo - lambda_i or lambda_i - hi, a disc's (|lambda_t|^2 - r^2) / 2r), its
central path is the minimiser of q - t sum log(-f_k) for t > 0: W lambda + b + sum u_k grad f_k = 0 with
u_k (-f_k) = t. A primal-dual interior point follows it (Boyd and Vandenberghe, Convex Optimization, 11.7): Newton's
step on those equations in (lambda, u), t aimed at the duality gap -f.u over GAP_SHRINK K at every step, the step
kept inside K with u > 0 and backtracked on the equations' residual. On the 45 interior finishes met in four
captured quadruped suites it took 970 Newton steps where the log barrier's centrings (t shrunk 50 times between
two, each centred by Newton's method on q - t sum log) took 2,950 (2026-11-30). The barrier's Hessian makes every
Newton system definite, and on the path the rows free to move on the solution set (the null space's crawl) are at
its centre, not wherever Gauss-Seidel stopped, and a row that the solution holds at its bound is within t / |w| of
it. The
primal-dual iterates only follow the path within a neighbourhood (a long step leaves some pairs u_k (-f_k) far
from t), so where the states are read the iterate is first centred by the barrier's Newton steps at t = gap / K
(_centre: a few steps). Its normal impulses are the next lambda_n^0 (the fixed point is Coulomb's problem:
Tresca's with radii mu lambda_n).

The states are read from it: every impulse within a relative `near` of its bound put on it (`snapped`), and the exact
finish of rbody.engine.constraints.cone (cone_polish: the held rows solved, the sliding ones on their bounds against
their velocity, the Coulomb radii moving with the normals) taken from there; several `near` (SNAP_LEVELS), the best
kept, and Newton's method on the natural map from it where none reaches the goal (rbody.engine.constraints.
natural_newton: cone_polish's fixed point on a sliding contact's direction is linear and can stall). The states
are read once where the gap first falls below TRY_BELOW, and the path stops there where they reach the goal.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.constraints.cone import (NORMAL, ROLL, ROW, SPIN, TANGENT, cone_polish, is_disc,
                                           normal_of)
from rbody.engine.constraints.natural_newton import NATURAL, newton_polish, read_newton
from rbody.engine.constraints.solver import cholesky_factor, lower_solve, symmetric_solve, upper_solve

BARRIER_START = 0.1        # the first barrier weight t, of the problem's scale max(|b|, 1) max(lambda_n^0)
GAP_SHRINK = 50.0          # each primal-dual step aims at t = gap / (GAP_SHRINK K) (Boyd and Vandenberghe's mu; of
                           # 20, 50 and 100, 50 took the fewest steps on the captured quadruped problems)
PATH_STEPS = 200           # primal-dual steps at most
DUAL_FEASIBLE = 1e-12      # the path is read, or left at its end, only where |W lambda + b + sum u grad f| is below
                           # this of max(|b|, 1)
PATH_STALL = 3             # primal-dual steps that do not halve the least gap so far end the path (round-off: the
                           # gap stays near 1e-17 of the scale)
BARRIER_END = 1e-18        # the last gap / K, of that scale: a bound held at a velocity w is then within t / w of it
CENTRED = 0.01             # a centring ends where the Newton decrement -g.d is below this of t
CENTRING_STEPS = 60        # Newton steps at most per t
CENTRING_STALL = 3         # Newton steps that do not halve the least decrement so far end a centring,
ROUNDING_DECREMENT = 1e-12  # where the decrement is below this of |q| (q's rounding, not the damped phase)
TO_BOUNDARY = 0.99         # a Newton step goes at most this share of the way to the nearest bound (and u's to 0)
SNAP_LEVELS = (1e-2, 1e-3, 1e-4)  # the `near` of the states read from the path's impulses (1e-5 and 1e-6 too
                                  # until 2026-11-30: where the first three miss, Newton's method finishes as well)
POLISH_ROUNDS = 4
TRY_BELOW = 1e-12          # the path is centred and its states read once, where gap / K is first below this weight
                           # (of the scale): on the captured landing problems, readings further down were no better

LOWER, UPPER, DISC = 0, 1, 2  # an inequality's kind: lo - lambda_i, lambda_i - hi, (|lambda_t|^2 - r^2) / 2r


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
def _inequalities(role, lo, hi, radius):
    """K's sets as inequalities f_k(lambda) <= 0: (kind (K,) of LOWER, UPPER, DISC; row (K,), a disc's first;
    bound (K,), lo, hi or the radius). A spin's interval is two bounds; a set of radius 0 has none (held at 0)."""
    m = role.shape[0]
    kind = np.empty(2 * m, np.int64)
    row = np.empty(2 * m, np.int64)
    bound = np.empty(2 * m)
    K = 0
    for i in range(m):
        r = role[i]
        if r == ROW or r == NORMAL or (r == SPIN and radius[i] > 0.0):
            low, high = (lo[i], hi[i]) if r != SPIN else (-radius[i], radius[i])
            if low > -np.inf:
                kind[K], row[K], bound[K] = LOWER, i, low
                K += 1
            if high < np.inf:
                kind[K], row[K], bound[K] = UPPER, i, high
                K += 1
        elif is_disc(r) and radius[i] > 0.0:
            kind[K], row[K], bound[K] = DISC, i, radius[i]
            K += 1
    return kind[:K], row[:K], bound[:K]


@njit(cache=True)
def _gradient(kind, row, bound, lam, k):
    """grad f_k's entries at rows row[k] and row[k] + 1 (a disc's pair; 0 for a bound)."""
    i = row[k]
    if kind[k] == LOWER:
        return -1.0, 0.0
    if kind[k] == UPPER:
        return 1.0, 0.0
    return lam[i] / bound[k], lam[i + 1] / bound[k]


@njit(cache=True)
def _constraint_values(lam, kind, row, bound, f):
    """f_k(lambda) into f (K,). Returns whether every one is negative (lambda inside K)."""
    for k in range(kind.shape[0]):
        i = row[k]
        if kind[k] == LOWER:
            f[k] = bound[k] - lam[i]
        elif kind[k] == UPPER:
            f[k] = lam[i] - bound[k]
        else:
            # -(the barrier's slack r^2 - x^2 - y^2, rounded as _barrier rounds it) / 2r: a point _barrier finds
            # inside is inside here (x^2 + y^2 - r^2 rounds to 0 where the slack is 1e-20 of r^2)
            f[k] = -(bound[k] * bound[k] - lam[i] * lam[i] - lam[i + 1] * lam[i + 1]) / (2.0 * bound[k])
        if not f[k] < 0.0:
            return False
    return True


@njit(cache=True)
def _stationarity(W, b, lam, u, kind, row, bound, fixed, out):
    """W lambda + b + sum u_k grad f_k into out (m,); 0 on the rows held at 0."""
    out[:] = b + W @ lam
    for k in range(kind.shape[0]):
        gx, gy = _gradient(kind, row, bound, lam, k)
        out[row[k]] += u[k] * gx
        if kind[k] == DISC:
            out[row[k] + 1] += u[k] * gy
    for i in range(lam.shape[0]):
        if fixed[i]:
            out[i] = 0.0


@njit(cache=True)
def _path_residual(stationarity, u, f, t):
    """|(W lambda + b + sum u grad f, u (-f) - t)|: the central path's equations at t."""
    total = stationarity @ stationarity
    for k in range(u.shape[0]):
        total += (u[k] * f[k] + t) ** 2
    return np.sqrt(total)


@njit(cache=True)
def _primal_dual_step(W, b, role, lo, hi, radius, kind, row, bound, fixed, lam, u, f, stationarity, t):
    """One Newton step on the central path's equations at t from (lambda (m,), u (K,)), u eliminated:

        (W + sum u_k H_k + sum u_k / (-f_k) g_k g_k^T) d = -(W lambda + b + sum t / (-f_k) g_k),
        du_k = -u_k - (t + u_k g_k.d) / f_k            (g_k, H_k: f_k's gradient and Hessian, I / r on a disc),

    taken TO_BOUNDARY of the way to u's and K's boundaries at most and halved until the equations' residual falls
    (Armijo's rule, 0.01). lambda, u, f and stationarity (m,) updated in place. Returns False where no step lowers
    the residual."""
    m, K = lam.shape[0], kind.shape[0]
    H = W.copy()
    g = stationarity.copy()
    for k in range(K):
        i = row[k]
        gx, gy = _gradient(kind, row, bound, lam, k)
        weight = u[k] / -f[k]
        c = t / -f[k] - u[k]
        g[i] += c * gx
        H[i, i] += weight * gx * gx
        if kind[k] == DISC:
            g[i + 1] += c * gy
            H[i, i] += u[k] / bound[k]
            H[i + 1, i + 1] += u[k] / bound[k] + weight * gy * gy
            H[i, i + 1] += weight * gx * gy
            H[i + 1, i] += weight * gx * gy
    for i in range(m):  # the rows of a set of radius 0: held at 0
        if fixed[i]:
            g[i] = 0.0
            for j in range(m):
                H[i, j] = H[j, i] = 0.0
            H[i, i] = 1.0
    d = np.empty(m)
    _newton_direction(H, g, d)
    du = np.empty(K)
    longest = 1.0
    for k in range(K):
        gx, gy = _gradient(kind, row, bound, lam, k)
        along = gx * d[row[k]] + (gy * d[row[k] + 1] if kind[k] == DISC else 0.0)
        du[k] = -u[k] - (t + u[k] * along) / f[k]
        if du[k] < 0.0:
            longest = min(longest, -u[k] / du[k])
    a = TO_BOUNDARY * min(longest, _longest_step(lam, d, role, lo, hi, radius))
    before = _path_residual(stationarity, u, f, t)
    trial, trial_u, trial_f, trial_stationarity = np.empty(m), np.empty(K), np.empty(K), np.empty(m)
    while a > 1e-16:
        trial[:] = lam + a * d
        trial_u[:] = u + a * du
        if _constraint_values(trial, kind, row, bound, trial_f):
            _stationarity(W, b, trial, trial_u, kind, row, bound, fixed, trial_stationarity)
            if _path_residual(trial_stationarity, trial_u, trial_f, t) <= (1.0 - 0.01 * a) * before:
                lam[:] = trial
                u[:] = trial_u
                f[:] = trial_f
                stationarity[:] = trial_stationarity
                return True
        a *= 0.5
    return False


@njit(cache=True)
def _centred_on_path(W, b, lo, hi, role, radius, kind, row, bound, fixed, lam, u, f, stationarity, t):
    """lambda (m,) centred at t by the barrier's Newton steps (_centre), u = t / (-f) (K,) and f, stationarity
    brought along. Returns the Newton steps."""
    steps = _centre(W, b, lo, hi, role, radius, lam, t)
    _constraint_values(lam, kind, row, bound, f)
    for k in range(kind.shape[0]):
        u[k] = t / -f[k]
    _stationarity(W, b, lam, u, kind, row, bound, fixed, stationarity)
    return steps


@njit(cache=True)
def _central_path(W, b, lo, hi, role, mu, normals, goal, lam, read_early):
    """The central path (module docstring) followed by primal-dual steps from the centre of each set to a gap of
    BARRIER_END of the problem's scale (or until it stalls at round-off), and centred there. Where the gap is first
    below TRY_BELOW, the iterate is centred, and where read_early, the states are read from it (_read_states at the
    first of SNAP_LEVELS, into lam (m,)) and the path is left there where they reach `goal`. Returns (the last
    iterate (m,), Newton steps, the residual of lam: inf where the early reading did not reach goal, the readings
    taken)."""
    radius = friction_radii(role, mu, normals)
    inside, top = _barrier_start(lo, hi, role, normals)
    scale = _problem_scale(b, top)
    size = scale / top
    kind, row, bound = _inequalities(role, lo, hi, radius)
    K = max(kind.shape[0], 1)
    m = role.shape[0]
    fixed = np.zeros(m, np.bool_)
    for i in range(m):
        fixed[i] = _fixed(role, radius, i)
    f = np.empty(kind.shape[0])
    if not _constraint_values(inside, kind, row, bound, f):  # a box of width 0: no inside to follow a path in
        return inside, 0, np.inf, 0
    u = BARRIER_START * scale / -f  # on the path's equation u (-f) = t at the first weight
    stationarity = np.empty(m)
    _stationarity(W, b, inside, u, kind, row, bound, fixed, stationarity)
    steps = 0
    readings = 0
    centred = False  # once at TRY_BELOW
    least, stalled = np.inf, 0
    while steps < PATH_STEPS:
        gap = -(f @ u)
        if gap < 0.5 * least:
            least, stalled = gap, 0
        else:
            stalled += 1
            if stalled >= PATH_STALL:
                break
        if np.max(np.abs(stationarity)) <= DUAL_FEASIBLE * size:
            if gap <= BARRIER_END * scale * K:
                break
            if not centred and gap <= TRY_BELOW * scale * K:
                centred = True
                steps += _centred_on_path(W, b, lo, hi, role, radius, kind, row, bound, fixed, inside, u, f,
                                          stationarity, gap / K)
                least, stalled = np.inf, 0
                if read_early:
                    readings = 1
                    trial = lam.copy()
                    early = _read_states(W, b, lo, hi, role, mu, inside, goal, 1, trial)
                    if early <= goal:
                        lam[:] = trial
                        return inside, steps, early, readings
                continue
        steps += 1
        if not _primal_dual_step(W, b, role, lo, hi, radius, kind, row, bound, fixed, inside, u, f, stationarity,
                                 gap / (GAP_SHRINK * K)):
            break
    # the end: centred at BARRIER_END of the scale (the gap stalls at round-off above it, 3e-17 of the scale on the
    # ANYmal C's step 45, where the states read were 8e-12 from a solution, 1.7e-12 when centred at the end)
    steps += _centred_on_path(W, b, lo, hi, role, radius, kind, row, bound, fixed, inside, u, f, stationarity,
                              min(-(f @ u) / K, BARRIER_END * scale))
    return inside, steps, np.inf, readings


@njit(cache=True)
def tresca_barrier(W, b, lo, hi, role, mu, normals):
    """The solution (m,) of Tresca's problem (module docstring) with the radii friction_radii(role, mu, normals), down
    the log barrier's central path by primal-dual steps, from the centre of each set (normals at max(normals, 1e-3
    of their largest)). W (m, m), b (m,) as in cone_pgs. Returns (lambda, Newton steps)."""
    inside, steps, _early, _readings = _central_path(W, b, lo, hi, role, mu, normals, 0.0, np.empty(0), False)
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
    """The states read from the path's impulses inside (m,) at the first `levels` of SNAP_LEVELS, each finished
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
    """One round of the fixed point on the normals: Tresca's problem with the radii of `normals` (m,) along its central
    path (_central_path), its states read and finished exactly (_read_states), written into lam (m,), and the path's
    impulses into normals (the next round's radii). Where the path's gap is first below TRY_BELOW of the problem's
    scale, the states are read once from the centred iterate (at the first of SNAP_LEVELS), and the path stops there
    where they reach `goal`: where the radii are right (a robot settling) the states are right before its last
    steps. Where the radii are not yet Coulomb's (a landing, its normals from Gauss-Seidel's first round), the states
    read further down the path were no better. Returns the residual of lam."""
    inside, _steps, early, _readings = _central_path(W, b, lo, hi, role, mu, normals, goal, lam, True)
    normals[:] = inside
    if early <= goal:
        return early
    return _read_states(W, b, lo, hi, role, mu, inside, goal, len(SNAP_LEVELS), lam)


__all__ = ["friction_radii", "interior_finish", "snapped", "tresca_barrier"]
