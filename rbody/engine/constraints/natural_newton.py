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
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.constraints.cone import (SPIN, ROLL2, TANGENT2, _bounds, _tangent_step_size, cone_residual,
                                           is_disc, normal_of)
from rbody.engine.constraints.solver import cholesky_factor, lower_solve, upper_solve

NEWTON_STEPS = 20   # Newton steps at most
STALL_STEPS = 3     # a run of this many steps that has not halved the residual ends it
ARMIJO = 1e-4       # sufficient decrease of |G|^2 / 2, of the step's slope


@njit(cache=True)
def natural_map(W, b, lo, hi, role, mu, lam, G, J, with_jacobian):
    """G (m,) <- the natural map at lam (module docstring) [w's units]; J (m, m) <- its Jacobian on G's piece where
    with_jacobian. Returns |G|^2 / 2."""
    m = b.shape[0]
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
            if length <= radius:  # sticking: w_t = 0
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
        if z <= low or z >= high:  # on a bound: lambda = bound (a spin's +-mu_s lambda_n)
            bound = low if z <= low else high
            G[i] = d * (lam[i] - bound)
            if with_jacobian:
                J[i, i] = d
                n = normal_of(role, i)
                if r == SPIN and lam[n] > 0.0:
                    J[i, n] += d * mu[i] if z <= low else -d * mu[i]
        else:  # free: w = 0
            G[i] = w[i]
            if with_jacobian:
                J[i, :] = W[i, :]
    half = 0.0
    for i in range(m):
        half += G[i] * G[i]
    return 0.5 * half


@njit(cache=True)
def newton_polish(W, b, lo, hi, role, mu, lam, goal):
    """Newton's method on the natural map (module docstring) from lam (m,), in place: until the residual is at most
    `goal`, a step finds no decrease, STALL_STEPS steps have not halved the residual, or NEWTON_STEPS are taken. lam
    ends at the iterate of least residual (the start where none is less). Returns that residual."""
    m = b.shape[0]
    G, J = np.empty(m), np.empty((m, m))
    G_trial, no_jacobian = np.empty(m), np.empty((0, 0))
    best = cone_residual(W, b, lo, hi, role, mu, lam)
    kept = lam.copy()
    floor = 0.0
    for i in range(m):
        floor = max(floor, W[i, i])
    floor = 1e-14 * floor * floor
    merit = natural_map(W, b, lo, hi, role, mu, lam, G, J, True)
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
            if natural_map(W, b, lo, hi, role, mu, trial, G_trial, no_jacobian, False) <= merit + ARMIJO * a * slope:
                break
            a *= 0.5
        if not a > 1e-10:
            break
        x[:] = trial
        merit = natural_map(W, b, lo, hi, role, mu, x, G, J, True)
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


__all__ = ["natural_map", "newton_polish", "NEWTON_STEPS"]
