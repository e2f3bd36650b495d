"""Coulomb's circular cone in the complementarity problem of a time step, compiled: projected Gauss-Seidel by blocks.

A contact with friction (condim 3) has three rows in the step's problem, consecutive: its normal n (an impulse
lambda_n >= 0, its velocity w_n >= 0 after the step, complementary) and its two tangents (t1, t2) whose impulse
lambda_t = (lambda_t1, lambda_t2) stays in the disc |lambda_t| <= mu lambda_n: inside it the contact sticks
(w_t = 0), on its edge it slides against its velocity (lambda_t = -mu lambda_n w_t / |w_t|: Coulomb's law with the
principle of maximal dissipation). This is the exact Coulomb problem at the velocity level, as Siconos's
nonsmooth Gauss-Seidel poses it (not Anitescu's convexified cone, which lifts a sliding contact off its surface),
with the other rows of the layer (equalities free, limits and frictionless contacts >= 0, joint friction in a box)
solved alongside them.

Torsional and rolling friction (condim 4 and 6) follow the tangents as more rows of the contact: a spin row (the
torque about the normal, |lambda_s| <= mu_s lambda_n: an interval, sticking inside, at its end against the spin) and a
rolling pair (the torque about the tangents, in the disc |lambda_r| <= mu_r lambda_n, as the tangents' force). Each
is its own Coulomb law sharing the normal impulse (the textbook model of spinning and rolling resistance: a rolling
ball's torque reaches mu_r N whatever its sliding friction does), not MuJoCo's single cone over all five.

Sweep: every ordinary row i: lambda_i <- clamp(lambda_i - w_i / W_ii, lo_i, hi_i); every contact's tangent pair:
its block's own minimiser lambda_t - B^-1 w_t (B the pair's 2 x 2 block of W) where that lies in the disc (the
contact sticks: the block solved at once, where the steps below would take tens of iterations at B's condition of
3), else the projected gradient step lambda_t <- P_disc(lambda_t - w_t / s), s the largest eigenvalue of B (a
step that decreases the quadratic and whose fixed points are exactly the points where w_t lies in the normal cone
of the disc, i.e. Coulomb's law), repeated within the block until it settles. The residual is the
natural residual of the whole problem in the units of w (0 exactly at a solution): the caller compares it with
its tolerance. Roles: ROW (ordinary), NORMAL (a contact's normal), TANGENT (its first tangent; the second,
TANGENT2, follows), then SPIN, ROLL and ROLL2 where the contact has them; a contact's rows in that order.
"""

from __future__ import annotations

import numpy as np
from numba import carray, njit

from rbody.engine.constraints.solver import clamp, lower_solve, upper_solve
from rbody.engine.memory import stack_floats

ROW, NORMAL, TANGENT, TANGENT2, SPIN, ROLL, ROLL2 = range(7)
INNER_STEPS = 50
BLOCK_RTOL = 1e-10  # a tangent pair's 2 x 2 block with det below this of a c is solved by its steps
ROUND_OFF = 64 * np.finfo(np.float64).eps  # a residual this small relative to the velocities' terms (magnitude):
                                           # solved to round-off
QP_STALL = 1e-13  # sticking_qp: a fall of q below this relative to |q| is round-off


@njit(cache=True, inline="always")
def is_friction(r):
    """Whether role r is one of a contact's friction rows (they follow its normal)."""
    return r >= TANGENT


@njit(cache=True, inline="always")
def is_disc(r):
    """Whether role r leads a pair of rows held in a disc (the tangents, the rolling pair)."""
    return r == TANGENT or r == ROLL


@njit(cache=True, inline="always")
def normal_of(role, i):
    """The row of the normal of the contact whose friction row is i (its rows: normal, tangents, spin, rolling)."""
    return i - (role[i] - NORMAL)


@njit(cache=True, inline="always")
def _disc(x, y, radius):
    """The point of the disc of the given radius nearest to (x, y)."""
    length = np.sqrt(x * x + y * y)
    if length <= radius:
        return x, y
    if length == 0.0:
        return 0.0, 0.0
    return x * radius / length, y * radius / length


@njit(cache=True)
def _tangent_step_size(W, i):
    a, b, c = W[i, i], W[i, i + 1], W[i + 1, i + 1]
    return 0.5 * (a + c) + np.sqrt(0.25 * (a - c) * (a - c) + b * b)


@njit(cache=True, inline="always")
def _velocities(W, b, lam, w):
    """w (m,) = b + W lam: BLAS's product into w, then b added (the same bits as b + W @ lam, without its two
    arrays)."""
    np.dot(W, lam, w)
    for i in range(b.shape[0]):
        w[i] += b[i]


SMALL = 4096  # a problem of at most this many rows keeps its rows' velocities on the stack (32 kB)
COLUMNS_ON_STACK = 16384  # a problem's W of at most this many entries is transposed on the stack (128 kB) by cone_pgs


@njit(cache=True)
def cone_residual(W, b, lo, hi, role, mu, lam):
    """The natural residual of the problem (module docstring) at lam: max over rows of W_ii |lambda_i -
    clamp(lambda_i - w_i / W_ii)| and over tangent pairs of s |lambda_t - P_disc(lambda_t - w_t / s)|; inf where an
    impulse or a velocity is not finite."""
    m = b.shape[0]
    w = carray(stack_floats(m), m) if m <= SMALL else np.empty(m)
    _velocities(W, b, lam, w)
    for i in range(m):  # (max below passes over a NaN: a finish that broke down is no solution)
        if not (np.isfinite(lam[i]) and np.isfinite(w[i])):
            return np.inf
    worst = 0.0
    for i in range(m):
        if is_disc(role[i]):
            s = _tangent_step_size(W, i)
            if s > 0.0:
                radius = mu[i] * max(lam[normal_of(role, i)], 0.0)
                x, y = _disc(lam[i] - w[i] / s, lam[i + 1] - w[i + 1] / s, radius)
                worst = max(worst, s * np.sqrt((lam[i] - x) ** 2 + (lam[i + 1] - y) ** 2))
        elif role[i] != TANGENT2 and role[i] != ROLL2:
            low, high = _bounds(role, mu, lo, hi, lam, i)
            d = W[i, i]
            if d > 0.0:
                worst = max(worst, d * abs(lam[i] - clamp(lam[i] - w[i] / d, low, high)))
            elif lam[i] > low and lam[i] < high:
                worst = max(worst, abs(w[i]))
    return worst


@njit(cache=True, inline="always")
def _bounds(role, mu, lo, hi, lam, i):
    """The interval of a one-row impulse: a spin row's +-mu_s lambda_n, an ordinary or normal row's own."""
    if role[i] == SPIN:
        bound = mu[i] * max(lam[normal_of(role, i)], 0.0)
        return -bound, bound
    return lo[i], hi[i]


@njit(cache=True)
def cone_pgs(W, b, lo, hi, role, mu, lam, tolerance, max_sweeps, start=-1.0):
    """Solve the step's problem with Coulomb cones by block projected Gauss-Seidel from lam (a warm start), until
    cone_residual <= tolerance or max_sweeps sweeps. role (m,) each row's ROW, NORMAL, TANGENT, TANGENT2, SPIN, ROLL
    or ROLL2; mu (m,) the friction coefficient on TANGENT, SPIN [m] and ROLL [m] rows; start: lam's cone_residual
    where the caller has it (negative: computed here). Returns (sweeps, residual)."""
    m = b.shape[0]
    residual = start if start >= 0.0 else cone_residual(W, b, lo, hi, role, mu, lam)
    if residual <= tolerance:
        return 0, residual
    w = carray(stack_floats(m), m) if m <= SMALL else np.empty(m)
    # columns[i] = W[:, i]: a row's update of every velocity, w += W[:, i] delta, read along memory (W need not be
    # symmetric: an event's J M^-1 F^T is not)
    columns = carray(stack_floats(m * m), (m, m)) if m * m <= COLUMNS_ON_STACK else np.empty((m, m))
    for i in range(m):
        for j in range(m):
            columns[i, j] = W[j, i]
    for sweep in range(max_sweeps):
        _velocities(W, b, lam, w)  # afresh each sweep: the updates below keep it in step without drift
        for i in range(m):
            if role[i] == TANGENT2 or role[i] == ROLL2:
                continue
            if is_disc(role[i]):
                s = _tangent_step_size(W, i)
                if not s > 0.0:
                    continue
                radius = mu[i] * max(lam[normal_of(role, i)], 0.0)
                a, c, off = W[i, i], W[i + 1, i + 1], W[i, i + 1]
                det = a * c - off * off
                if det > BLOCK_RTOL * a * c:  # the pair's own minimiser lam_t - B^-1 w_t (B its 2 x 2 block of W):
                    x = lam[i] - (c * w[i] - off * w[i + 1]) / det  # where it lies in the disc, the block's
                    y = lam[i + 1] - (a * w[i + 1] - off * w[i]) / det  # exact step (the contact sticks)
                    if x * x + y * y <= radius * radius:
                        dx, dy = x - lam[i], y - lam[i + 1]
                        lam[i], lam[i + 1] = x, y
                        for j in range(m):
                            w[j] += columns[i, j] * dx + columns[i + 1, j] * dy
                        continue
                for _inner in range(INNER_STEPS):  # else projected gradient steps within the block (sliding)
                    x, y = _disc(lam[i] - w[i] / s, lam[i + 1] - w[i + 1] / s, radius)
                    dx, dy = x - lam[i], y - lam[i + 1]
                    if dx == 0.0 and dy == 0.0:
                        break
                    lam[i], lam[i + 1] = x, y
                    for j in range(m):
                        w[j] += columns[i, j] * dx + columns[i + 1, j] * dy
                    if s * np.sqrt(dx * dx + dy * dy) <= 0.01 * tolerance:
                        break
                continue
            d = W[i, i]
            if not d > 0.0:
                continue
            low, high = _bounds(role, mu, lo, hi, lam, i)
            new = clamp(lam[i] - w[i] / d, low, high)
            delta = new - lam[i]
            if delta != 0.0:
                lam[i] = new
                for j in range(m):
                    w[j] += columns[i, j] * delta
        residual = cone_residual(W, b, lo, hi, role, mu, lam)
        if residual <= tolerance:
            return sweep + 1, residual
    return max_sweeps, residual


@njit(cache=True)
def follow_drift(W, b, lo, hi, role, mu, lam):
    """Where dependent rows leave Gauss-Seidel crawling, take the crawl's whole way at once. d1, d2: what two more
    sweeps change lam by; rho = d2.d1 / d1.d1 their ratio. Two ends of the crawl are tried from the second sweep's
    lam, each with every impulse put back within its own set (boxes, intervals, discs):
    - its drift along W's null space (rho near 1: the residual falls by the same amount every sweep) followed to the
      first bound a box row (an ordinary row's lo or hi, a normal's 0) meets along d2, that row set at its bound;
    - its geometric tail (0 < rho < 1), summed: lam + d2 rho / (1 - rho) (Aitken's extrapolation).
    A quadruped standing with dry friction in its joints and condim 6 feet (rolling and spinning at their limits)
    has 36 rows of rank 18: its hips' friction torques and the feet's lateral forces drift together along a null
    direction, 5e-8 a sweep, 14,000 sweeps to the hip's bound, where the problem is solved to round-off; a few steps
    later its problem converges at rho = 0.9965 a sweep, 7,000 sweeps to round-off, and the states read from any
    iterate before that give no exact finish. lam is replaced by the better end only where that lowers the
    residual (the finishes then start from it). Returns the residual of lam."""
    m = b.shape[0]
    before = cone_residual(W, b, lo, hi, role, mu, lam)
    first = lam.copy()
    cone_pgs(W, b, lo, hi, role, mu, first, 0.0, 1)
    second = first.copy()
    cone_pgs(W, b, lo, hi, role, mu, second, 0.0, 1)
    across, along = 0.0, 0.0
    for i in range(m):
        across += (second[i] - first[i]) * (first[i] - lam[i])
        along += (first[i] - lam[i]) * (first[i] - lam[i])
    best = before
    alpha, hit, bound = np.inf, -1, 0.0  # the drift: the first bound met along d2
    for i in range(m):
        if role[i] != ROW and role[i] != NORMAL:
            continue
        step = second[i] - first[i]
        target = hi[i] if step > 0.0 else lo[i] if step < 0.0 else np.nan
        if np.isfinite(target) and second[i] != target and (target - second[i]) / step < alpha:
            alpha, hit, bound = (target - second[i]) / step, i, target
    if hit >= 0:
        best = _take_end(W, b, lo, hi, role, mu, first, second, alpha, hit, bound, lam, best)
    rho = across / along if along > 0.0 else 0.0  # the geometric tail
    if rho > 0.0 and rho < 1.0:
        best = _take_end(W, b, lo, hi, role, mu, first, second, rho / (1.0 - rho), -1, 0.0, lam, best)
    return best


@njit(cache=True)
def _take_end(W, b, lo, hi, role, mu, first, second, factor, hit, bound, lam, best):
    """follow_drift's end second + factor (second - first), row `hit` (if >= 0) set at its bound, every impulse
    within its own set: written into lam where its residual is below best. Returns the lower residual."""
    trial = second.copy()
    for i in range(trial.shape[0]):
        trial[i] += factor * (second[i] - first[i])
    if hit >= 0:
        trial[hit] = bound
    _within_sets(role, mu, lo, hi, trial)
    residual = cone_residual(W, b, lo, hi, role, mu, trial)
    if residual < best:
        lam[:] = trial
        return residual
    return best


@njit(cache=True)
def _within_sets(role, mu, lo, hi, lam):
    """Every impulse of lam put back within its own set in place: boxes (ordinary rows, normals), then the friction
    rows' intervals (spin) and discs (tangents, rolling) about the normals so found."""
    m = lam.shape[0]
    for i in range(m):
        if role[i] == ROW or role[i] == NORMAL:
            lam[i] = clamp(lam[i], lo[i], hi[i])
    for i in range(m):
        if is_disc(role[i]):
            lam[i], lam[i + 1] = _disc(lam[i], lam[i + 1], mu[i] * max(lam[normal_of(role, i)], 0.0))
        elif role[i] == SPIN:
            low, high = _bounds(role, mu, lo, hi, lam, i)
            lam[i] = clamp(lam[i], low, high)


__all__ = ["cone_pgs", "cone_residual", "follow_drift", "slide_polish", "stick_polish", "magnitude", "ROUND_OFF", "ROW", "NORMAL", "TANGENT", "TANGENT2", "SPIN", "ROLL",
           "ROLL2"]


@njit(cache=True)
def cone_polish(W, b, lo, hi, role, mu, lam, rounds):
    """Finish a Gauss-Seidel solution exactly: with the contacts' states read from lam (a normal pushing or not; a
    pushing contact sticking inside its cone or sliding on its edge, against its tangential velocity), the rows
    that must have w = 0 (free ordinary rows, pushing normals, sticking tangents) are solved for the impulses within
    those states (least squares, minimum norm), a sliding contact's force on its cone's edge against its velocity
    (its direction from the last round's velocities; in the first round from Gauss-Seidel's force); `rounds`
    rounds, the best kept. Returns the residual of the lam kept."""
    return _polish(W, b, lo, hi, role, mu, lam, rounds, np.zeros(b.shape[0], dtype=np.bool_))


@njit(cache=True)
def slide_polish(W, b, lo, hi, role, mu, lam, rounds):
    """cone_polish with sticking contacts made to slide against the tangential velocity the others leave them (their
    force on their cone's edge), chosen greedily: each pass tries every sticking contact that slips, keeps the one
    that lowers the residual most, and goes on from there while one does. Where contacts' tangent rows are nearly
    dependent (a capsule pivoting on a box's edge as its end lands on the face; a foot's capsule ends) no set of
    impulses holds them all, and Gauss-Seidel and the stick states settle on a point that is not a solution: some
    of them slide. Returns the residual kept."""
    m = b.shape[0]
    best = cone_residual(W, b, lo, hi, role, mu, lam)
    forced = np.zeros(m, dtype=np.bool_)
    for _pass in range(m):
        w = b + W @ lam
        chosen, chosen_residual = -1, best
        chosen_lam = lam.copy()
        for i in range(m):
            if forced[i] or role[i] != NORMAL or lam[i] <= 0.0 or i + 1 >= m or role[i + 1] != TANGENT:
                continue
            j = i + 1
            if np.sqrt(lam[j] ** 2 + lam[j + 1] ** 2) >= mu[j] * lam[i] or (w[j] == 0.0 and w[j + 1] == 0.0):
                continue  # sliding already, or not slipping
            trial = lam.copy()
            forced[i] = True
            residual = _polish(W, b, lo, hi, role, mu, trial, rounds, forced)
            forced[i] = False
            if residual < chosen_residual:
                chosen, chosen_residual = i, residual
                chosen_lam[:] = trial
        if chosen < 0:
            break
        forced[chosen] = True
        best = chosen_residual
        lam[:] = chosen_lam
    return best


@njit(cache=True)
def _polish(W, b, lo, hi, role, mu, lam, rounds, forced):
    """cone_polish, the pushing contacts whose normal row is flagged in forced (m,) sliding whatever their force,
    against their tangential velocity."""
    m = b.shape[0]
    best = cone_residual(W, b, lo, hi, role, mu, lam)
    for _round in range(rounds):
        w = b + W @ lam
        scale = 0.0
        for i in range(m):
            scale = max(scale, abs(lam[i]))
        tiny = 1e-14 * max(scale, 1e-300)
        B = np.zeros((m, m))
        rows = np.empty(m, dtype=np.int64)
        k = 0
        e = 0
        for i in range(m):
            if role[i] == ROW:
                if lam[i] > lo[i] and lam[i] < hi[i]:
                    B[i, k] = 1.0
                    k += 1
                    rows[e] = i
                    e += 1
            elif role[i] == NORMAL:
                if lam[i] <= tiny:
                    continue
                rows[e] = i
                e += 1
                column = k  # the normal's: a sliding group's force on its edge moves with it
                B[i, column] = 1.0
                k += 1
                j = i + 1
                while j < m and is_friction(role[j]):
                    radius = mu[j] * lam[i]
                    if is_disc(role[j]):
                        tx, ty = lam[j], lam[j + 1]
                        held = np.sqrt(tx * tx + ty * ty) < radius * (1.0 - 1e-10)
                        if held and not (forced[i] and role[j] == TANGENT):  # sticking (rolling): rows held
                            B[j, k], B[j + 1, k + 1] = 1.0, 1.0
                            k += 2
                            rows[e], rows[e + 1] = j, j + 1
                            e += 2
                        else:  # sliding: its force on the cone's edge, against the velocity (round 0: along the
                            # force Gauss-Seidel found, whose direction is good where the sliding speed is small)
                            sx, sy = (tx, ty) if _round == 0 and not forced[i] else (-w[j], -w[j + 1])
                            length = np.sqrt(sx * sx + sy * sy)
                            if length <= tiny:
                                sx, sy = tx, ty
                                length = np.sqrt(sx * sx + sy * sy)
                            if length > 0.0:
                                sx, sy = sx / length, sy / length
                            else:
                                sx, sy = 0.0, 0.0
                            B[j, column], B[j + 1, column] = mu[j] * sx, mu[j] * sy
                        j += 2
                    else:  # a spin row: held inside its interval, else at its end against the spin
                        if abs(lam[j]) < radius * (1.0 - 1e-10):
                            B[j, k] = 1.0
                            k += 1
                            rows[e] = j
                            e += 1
                        else:
                            sign = lam[j] if _round == 0 or abs(w[j]) <= tiny else -w[j]
                            B[j, column] = mu[j] * (1.0 if sign > 0.0 else -1.0 if sign < 0.0 else 0.0)
                        j += 1
        if k == 0 or e == 0:
            break
        base = lam.copy()  # the impulses not in any column (rows at a bound), the others solved for whole
        for c in range(k):
            for i in range(m):
                if B[i, c] != 0.0:
                    base[i] = 0.0
        w = b + W @ base
        A = np.empty((e, k))
        r = np.empty(e)
        for a in range(e):
            r[a] = -w[rows[a]]
            for c in range(k):
                acc = 0.0
                for i in range(m):
                    acc += W[rows[a], i] * B[i, c]
                A[a, c] = acc
        x = np.linalg.lstsq(A, r, 1e-13)[0]
        trial = base + np.ascontiguousarray(B[:, :k]) @ x
        residual = cone_residual(W, b, lo, hi, role, mu, trial)
        if residual < best:
            best = residual
            for i in range(m):
                lam[i] = trial[i]
    return best


@njit(cache=True)
def sticking_qp(W, b, lo, hi, role, mu, lam):
    """Finish with every contact sticking: minimise q(lam) = lam.W.lam / 2 + b.lam within the rows' own bounds lo, hi
    (ordinary rows' boxes, normals >= 0; the friction rows free), by a primal active-set method (Nocedal and Wright,
    16.5: from a feasible point, step to the minimiser on the face of the bounds held, stopping at the first bound
    met, which joins the set; at a face's minimiser release the held bound whose multiplier w has the wrong sign).
    W is only semidefinite where rows are dependent (a robot standing on four feet with dry friction in its
    joints: 24 rows of rank 18): on such a face the minimiser is the least-norm solution plus, where the gradient
    has a part along the face's null space, a descent along it to the next bound (a full step on a face reaches its
    minimiser: after it and one refining step the release test follows at once); Gauss-Seidel crawls along those
    directions (200,000 sweeps), the state-reading finishes jump between the same few states. Where the result keeps
    every contact's friction within its cone it solves the whole problem (stationarity is w = 0 on every free row,
    the sticking contacts' law). lam (m,): the start (clipped to the bounds), the answer if better. Returns the
    residual kept."""
    m = b.shape[0]
    best = cone_residual(W, b, lo, hi, role, mu, lam)
    x = lam.copy()
    for i in range(m):
        x[i] = min(max(x[i], lo[i]), hi[i])
    held = np.zeros(m, dtype=np.bool_)  # a row held at one of its bounds
    for i in range(m):
        held[i] = x[i] == lo[i] or x[i] == hi[i]
    free = np.empty(m, dtype=np.int64)
    least, stalled = np.inf, 0
    unblocked = 0  # full steps in a row on the face held: the first reaches its minimiser, the second refines it
    for _iteration in range(6 * m + 10):
        g = b + W @ x  # the gradient: the rows' velocities w
        value = 0.5 * (x @ (g + b))  # q(x): it falls at every step that is not degenerate; 2 m steps in a row that
        if value < least - QP_STALL * abs(value):  # leave it within round-off are a cycle of releases and zero-length
            least, stalled = value, 0               # steps (a quadruped's feet rolling at their limits: to the cap of
        else:                                       # 6 m + 10 steps, 20 ms, at one q to 1e-15)
            stalled += 1
            if stalled > 2 * m:
                break
        k = 0
        for i in range(m):
            if not held[i]:
                free[k] = i
                k += 1
        step = np.zeros(m)
        moving = False
        along, scale = 0.0, 1.0
        if k > 0 and unblocked < 2:  # (a third solve on the face moves x by round-off only: 1e-14 a step, 100
            A = np.empty((k, k))    # of them on the ANYmal's hard steps, a factorisation each)
            r = np.empty(k)
            for a in range(k):
                r[a] = -g[free[a]]
                for c in range(k):
                    A[a, c] = W[free[a], free[c]]
            d = _face_step(A, r)  # the face's least-norm Newton step
            rest = r - A @ d  # the gradient's part along the face's null space: q falls linearly along it
            for a in range(k):
                scale = max(scale, abs(r[a]))
                along = max(along, abs(rest[a]))
            if along > 1e-10 * scale:
                for a in range(k):
                    d[a] = rest[a] * 1e6  # a long step down the null space: the ratio test stops it at a bound
            for a in range(k):
                step[free[a]] = d[a]
                moving = moving or abs(d[a]) > 1e-15 * max(1.0, abs(x[free[a]]))
        if not moving:  # the face's minimiser: release a held bound that pulls the wrong way, else done
            worst, release = 0.0, -1
            for i in range(m):
                if held[i]:
                    pull = -g[i] if x[i] == lo[i] else g[i]  # > 0: q falls moving inward
                    if pull > worst:
                        worst, release = pull, i
            if release < 0:
                break
            held[release] = False
            unblocked = 0
            continue
        alpha, blocking = 1.0, -1  # the ratio test: the first bound met along the step
        for i in range(m):
            if step[i] > 0.0 and hi[i] < np.inf and x[i] + step[i] > hi[i]:
                t = (hi[i] - x[i]) / step[i]
                if t < alpha:
                    alpha, blocking = t, i
            elif step[i] < 0.0 and lo[i] > -np.inf and x[i] + step[i] < lo[i]:
                t = (lo[i] - x[i]) / step[i]
                if t < alpha:
                    alpha, blocking = t, i
        if blocking < 0 and along > 1e-10 * scale:
            break  # unbounded along the null space (no bound stops it): no sticking solution
        for i in range(m):
            x[i] += alpha * step[i]
        if blocking >= 0:
            x[blocking] = lo[blocking] if step[blocking] < 0.0 else hi[blocking]
            held[blocking] = True
            unblocked = 0
        else:
            unblocked += 1
    residual = cone_residual(W, b, lo, hi, role, mu, x)
    if residual < best:
        best = residual
        for i in range(m):
            lam[i] = x[i]
    return best


LEAST_NORM_RTOL = 1e-13  # a pivot (an eigenvalue's share) below this of the largest diagonal entry is round-off


@njit(cache=True)
def _pivoted_cholesky(S, rtol, perm):
    """S (k, k) symmetric semidefinite, overwritten: its columns' order perm (k,) and, in S's lower trapezoid, L (k,
    rank) with S[perm][:, perm] = L L^T, by outer products with the largest remaining diagonal entry as pivot (the
    rank-revealing Cholesky factorisation, Higham, Accuracy and Stability, 10.3), stopping where it is below rtol
    of the largest diagonal entry. Returns the rank."""
    k = S.shape[0]
    top = 0.0
    for a in range(k):
        perm[a] = a
        top = max(top, S[a, a])
    for j in range(k):
        pivot, at = S[j, j], j
        for i in range(j + 1, k):
            if S[i, i] > pivot:
                pivot, at = S[i, i], i
        if not pivot > rtol * top:
            return j
        if at != j:  # the symmetric swap of rows and columns j and at
            for c in range(k):
                S[j, c], S[at, c] = S[at, c], S[j, c]
            for a in range(k):
                S[a, j], S[a, at] = S[a, at], S[a, j]
            perm[j], perm[at] = perm[at], perm[j]
        d = np.sqrt(pivot)
        S[j, j] = d
        for i in range(j + 1, k):
            S[i, j] /= d
            S[j, i] = S[i, j]  # (the column as row j too: the update below reads it along memory)
        rest = k - j - 1
        for c in range(j + 1, k):  # the Schur complement, kept whole (both triangles: a later swap reads them), row
            f = S[j, c]            # by row along memory, each loop from 0 (which numba's loops vectorise)
            for t in range(rest):
                S[c, j + 1 + t] -= S[j, j + 1 + t] * f
    return k


@njit(cache=True)
def _least_norm(A, r, weights):
    """x = the solution of A x = r of least sum x_i^2 / weights_i, A (k, k) symmetric semidefinite (a block of W):
    _nearest_solution from 0."""
    return _nearest_solution(A, r, weights, np.zeros(weights.shape[0]))


@njit(cache=True)
def _nearest_solution(A, r, weights, start):
    """x = the solution of A x = r nearest start (k,): of least sum (x_i - start_i)^2 / weights_i, A (k, k)
    symmetric semidefinite (a block of W). x = start + d, A d = r - A start: with D = diag(weights), d = D^1/2 z, z
    the least-norm solution of S z = D^1/2 (r - A start), S = D^1/2 A D^1/2 (the same solutions z as A D^1/2 z):
    S[p][:, p] = L L^T (pivoted Cholesky, rank n), u from the first n rows of L u = (D^1/2 (r - A start))[p], then
    z[p] = L (L^T L)^-1 u, the least-norm solution of L^T z[p] = u, and one step of iterative refinement. 7 us where
    the SVD takes 42 (24 rows). Where A x = r is inconsistent beyond the round-off of its terms (dependent rows that
    cannot all hold) the least-squares change of the SVD instead."""
    k = weights.shape[0]
    root = np.sqrt(weights)
    S = np.empty((k, k))
    for a in range(k):
        for c in range(k):
            S[a, c] = root[a] * A[a, c] * root[c]
    perm = np.empty(k, dtype=np.int64)
    n = _pivoted_cholesky(S, LEAST_NORM_RTOL, perm)
    T, order, definite = _gram_factor(S, n)
    if not definite:
        return start + _least_squares(A, _miss(A, r, start), root)
    x = start.copy()
    for _solve in range(2):  # the solve, then one step of iterative refinement: the factors' own rounding taken
        change = _factored_least_norm(S, n, perm, T, order, root, _miss(A, r, x))  # back (a lone contact's
        for a in range(k):                                                          # impulse to the last bit, as a
            x[a] += change[a]                                                       # division gives it)
    worst, size = 0.0, 0.0  # A x = r to round-off, else inconsistent: least squares
    for a in range(k):
        acc, terms = -r[a], abs(r[a])
        for c in range(k):
            acc += A[a, c] * x[c]
            terms += abs(A[a, c] * x[c])
        worst, size = max(worst, abs(acc)), max(size, terms)
    if worst > ROUND_OFF * size:
        return start + _least_squares(A, _miss(A, r, start), root)
    return x


@njit(cache=True)
def _gram_factor(S, n):
    """T = L^T L (n, n) of the pivoted factor L (k, n) in S's lower trapezoid (_pivoted_cholesky's, rank n): definite,
    its eigenvalues S's nonzero ones; T overwritten by its own pivoted factor T[q][:, q] = N N^T. Returns (T, its
    order q, whether T is definite to round-off)."""
    k = S.shape[0]
    T = np.zeros((n, n))
    for i in range(k):  # T[a, c] = sum over i >= a of S[i, a] S[i, c], summed in i's order, by S's rows
        for a in range(min(i + 1, n)):
            f = S[i, a]
            for c in range(a + 1):
                T[a, c] += f * S[i, c]
    for a in range(n):
        for c in range(a):
            T[c, a] = T[a, c]
    order = np.empty(n, dtype=np.int64)
    return T, order, _pivoted_cholesky(T, 0.0, order) == n


@njit(cache=True)
def _miss(A, r, x):
    """r - A x (k,)."""
    k = r.shape[0]
    miss = np.empty(k)
    for a in range(k):
        acc = r[a]
        for c in range(k):
            acc -= A[a, c] * x[c]
        miss[a] = acc
    return miss


@njit(cache=True)
def _factored_least_norm(S, n, perm, T, order, root, r):
    """_least_norm's solve from its factors: S's pivoted factor L (k, n) in S's lower trapezoid with its order perm,
    T's (L^T L's) factor N in T's lower triangle with its order, root (k,) D^1/2's diagonal; r (k,) the right side."""
    k = root.shape[0]
    u = np.empty(n)
    for i in range(n):  # L1 u = (D^1/2 r)[p][:n], L1 the factor's leading triangle
        acc = root[perm[i]] * r[perm[i]]
        for c in range(i):
            acc -= S[i, c] * u[c]
        u[i] = acc / S[i, i]
    uq = np.empty(n)
    for a in range(n):
        uq[a] = u[order[a]]
    sq = upper_solve(T, lower_solve(T, uq))
    s = np.empty(n)
    for a in range(n):
        s[order[a]] = sq[a]
    x = np.empty(k)
    for i in range(k):  # z[p] = L s, x = D^1/2 z
        acc = 0.0
        for c in range(min(i + 1, n)):
            acc += S[i, c] * s[c]
        x[perm[i]] = acc * root[perm[i]]
    return x


@njit(cache=True)
def _face_step(A, r):
    """d (k,) = A^+ r, the least-norm least-squares solution of A d = r, A (k, k) symmetric semidefinite (a face of
    sticking_qp): A[p][:, p] = L L^T (pivoted Cholesky, rank n, T = L^T L), r's part in A's range L T^-1 L^T r[p]
    solved as _least_norm solves a consistent system (its refinement included). A third of the SVD's cost (36 rows
    of rank 18: 20 us against 57); the SVD where T is not definite to round-off."""
    k = r.shape[0]
    S = A.copy()
    perm = np.empty(k, dtype=np.int64)
    n = _pivoted_cholesky(S, LEAST_NORM_RTOL, perm)
    if n == 0:
        return np.zeros(k)
    T, order, definite = _gram_factor(S, n)
    if not definite:
        return np.linalg.lstsq(A, r, 1e-12)[0]
    projected = np.empty(n)  # (L^T r[p])[order]
    for a in range(n):
        c = order[a]
        acc = 0.0
        for i in range(c, k):
            acc += S[i, c] * r[perm[i]]
        projected[a] = acc
    solved = upper_solve(T, lower_solve(T, projected))
    s = np.empty(n)
    for a in range(n):
        s[order[a]] = solved[a]
    ranged = np.empty(k)  # L s: r's part in A's range
    for i in range(k):
        acc = 0.0
        for c in range(min(i + 1, n)):
            acc += S[i, c] * s[c]
        ranged[perm[i]] = acc
    ones = np.ones(k)
    d = np.zeros(k)
    for _solve in range(2):  # the solve, then one step of iterative refinement
        change = _factored_least_norm(S, n, perm, T, order, ones, _miss(A, ranged, d))
        for a in range(k):
            d[a] += change[a]
    return d


@njit(cache=True)
def _least_squares(A, r, root):
    """x = D^1/2 z, z the least-norm least-squares solution of A D^1/2 z = r (root (k,): D^1/2's diagonal), by the
    SVD."""
    k = root.shape[0]
    scaled = np.empty_like(A)
    for c in range(k):
        for a in range(A.shape[0]):
            scaled[a, c] = A[a, c] * root[c]
    z = np.linalg.lstsq(scaled, r, 1e-13)[0]
    for c in range(k):
        z[c] *= root[c]
    return z


@njit(cache=True)
def inside_cones(role, mu, lam):
    """True when every contact's friction impulses lie strictly inside their bounds (a relative 1e-9 within)."""
    for i in range(lam.shape[0]):
        if role[i] == TANGENT or role[i] == ROLL:
            size = np.sqrt(lam[i] * lam[i] + lam[i + 1] * lam[i + 1])
        elif role[i] == SPIN:
            size = abs(lam[i])
        else:
            continue
        if size > 0.0 and size >= (1.0 - 1e-9) * mu[i] * lam[i - (role[i] - NORMAL)]:
            return False
    return True


@njit(cache=True)
def magnitude(W, b, lam):
    """max over rows of |b_i| + sum_j |W_ij lambda_j|: the size of the terms whose sum is a row's velocity w = b +
    W lam, which bounds the round-off of w (Higham 3.1: |fl(w) - w| <= m eps times it). Not |w| or |W lam|: in a
    stack the contacts' impulses carry the weight of the boxes above, and their terms (12 m/s in a five-box stack
    at dt = 0.01) cancel to the step's g h (0.098 m/s)."""
    big = 0.0
    for i in range(b.shape[0]):
        acc = abs(b[i])
        for j in range(b.shape[0]):
            acc += abs(W[i, j] * lam[j])
        big = max(big, acc)
    return big


@njit(cache=True)
def _sticking_rows(role, lo, hi, lam):
    """The rows that have w = 0 where every pushing contact sticks: each pushing normal (lam > 0) with its tangents,
    spin and rolling rows, and the ordinary rows strictly inside their bounds. Returns (rows (m,), their first k
    those; owner (m,), the normal row whose impulse weighs each (-1: an ordinary row); inside (m,), True on them; k;
    the pushing normals' mean impulse, an ordinary row's weight: 0 where none pushes)."""
    m = lam.shape[0]
    rows = np.empty(m, dtype=np.int64)
    owner = np.empty(m, dtype=np.int64)
    inside = np.zeros(m, dtype=np.bool_)
    k = 0
    total, count = 0.0, 0
    for i in range(m):
        if role[i] == NORMAL and lam[i] > 0.0:
            rows[k], owner[k] = i, i
            k += 1
            total += lam[i]
            count += 1
            j = i + 1
            while j < m and is_friction(role[j]):
                rows[k], owner[k] = j, i
                k += 1
                j += 1
        elif role[i] == ROW and lam[i] > lo[i] and lam[i] < hi[i]:
            rows[k], owner[k] = i, -1
            k += 1
    for a in range(k):
        inside[rows[a]] = True
    return rows, owner, inside, k, total / count if count else 0.0


@njit(cache=True)
def _held_system(W, b, lam, rows, k, inside, A, r):
    """A (k, k), W's block of the rows rows[:k] (inside (m,) marks them), and r (k,) = -(b + W lam) over them with
    their own impulses left out: A x = r puts their velocities at 0 with every other row's impulse held."""
    m = b.shape[0]
    for a in range(k):
        acc = b[rows[a]]
        for j in range(m):
            if not inside[j]:
                acc += W[rows[a], j] * lam[j]
        r[a] = -acc
        for c in range(k):
            A[a, c] = W[rows[a], rows[c]]


@njit(cache=True)
def hold_states(W, b, lo, hi, role, mu, lam):
    """Newton's step on lam's own states: where every pushing contact of lam sticks strictly inside its cones, the
    rows that then have w = 0 (_sticking_rows) solved again for the change of lam of least sum d_j^2 / lambda_n (each
    contact's rows weighted by its normal impulse, as stick_polish), the other rows held. A start that nearly solves
    the problem (the last step's finished impulses) keeps its share of a redundant set's load and loses the round-off
    gathered since, where a sweep of Gauss-Seidel leaves it (a quadruped standing on condim 6 feet: 40 rows of rank
    18, a sweep 8e-14, this step 3e-17). lam is replaced where the natural residual falls; returns the residual
    kept."""
    best = cone_residual(W, b, lo, hi, role, mu, lam)
    if not inside_cones(role, mu, lam):
        return best
    rows, owner, inside, k, mean = _sticking_rows(role, lo, hi, lam)
    if mean == 0.0:  # no contact pushes
        return best
    A = np.empty((k, k))
    r = np.empty(k)
    weights = np.empty(k)
    start = np.empty(k)
    _held_system(W, b, lam, rows, k, inside, A, r)
    for a in range(k):
        weights[a] = lam[owner[a]] if owner[a] >= 0 else mean
        start[a] = lam[rows[a]]
    x = _nearest_solution(A, r, weights, start)
    trial = lam.copy()
    for a in range(k):
        trial[rows[a]] = x[a]
    residual = cone_residual(W, b, lo, hi, role, mu, trial)
    if residual < best:
        best = residual
        lam[:] = trial
    return best


@njit(cache=True)
def stick_polish(W, b, lo, hi, role, mu, lam, rounds):
    """The exact solution in which every pushing contact sticks, if there is one near lam: the impulses of the
    rows that must have w = 0 (pushing normals and their tangents, free ordinary rows) solved together, of least
    sum lambda_j^2 / lambda_n (each contact's rows weighted by its normal impulse, repeated with the new normals
    `rounds` times). Among the many solutions of a redundant set (four corners of a box on a face) this one is
    lambda_j = lambda_n (J_j u) for one generalised velocity u: the tangential load follows the normal load, so
    that every corner stays inside its cone wherever the face as a whole can hold (a block on an incline at
    mu = tan(alpha) (1 + 1e-6)). lam is replaced when the natural residual falls, or by a round that solves it to
    round-off with other impulses (beyond round-off: the latest such round's weights are the nearest to their fixed
    point); the rounds end early where one gives the last one's impulses again to round-off (every later one would
    too); returns the residual kept."""
    m = b.shape[0]
    best = cone_residual(W, b, lo, hi, role, mu, lam)
    rows, owner, inside, k, mean = _sticking_rows(role, lo, hi, lam)
    if mean == 0.0:  # no contact pushes
        return best
    trial = lam.copy()
    A = np.empty((k, k))
    r = np.empty(k)
    weights = np.empty(k)
    for _round in range(rounds):
        pushing = True  # a round left a contact pulling (its normal <= 0): no sticking solution here, and no weight
        for a in range(k):
            pushing = pushing and (owner[a] < 0 or trial[owner[a]] > 0.0)
        if not pushing:
            break
        _held_system(W, b, trial, rows, k, inside, A, r)
        for a in range(k):
            weights[a] = max(trial[owner[a]], 1e-300) if owner[a] >= 0 else mean
        x = _least_norm(A, r, weights)
        change, size = 0.0, 0.0  # settled: the last round's impulses again to round-off (its weights again, every
        for a in range(k):       # later round the same; the rounds otherwise trade the last bits, 8 SVDs a step);
            change = max(change, abs(trial[rows[a]] - x[a]))  # the first round's are compared with lam's, which no
            size = max(size, abs(x[a]))                       # round solved: never settled
            trial[rows[a]] = x[a]
        settled = _round > 0 and change <= ROUND_OFF * size
        residual = cone_residual(W, b, lo, hi, role, mu, trial)
        moved = 0.0  # from the impulses kept: beyond round-off, another of a redundant set's solutions
        for a in range(k):
            moved = max(moved, abs(lam[rows[a]] - x[a]))
        if residual < best or (moved > ROUND_OFF * size and residual <= ROUND_OFF * magnitude(W, b, trial)):
            best = residual  # (of the solutions to round-off, the latest round's: its weights the nearest to their
            for i in range(m):  # fixed point; not the one whose last bits happen to give the least residual)
                lam[i] = trial[i]
        if settled:
            break
    return best

