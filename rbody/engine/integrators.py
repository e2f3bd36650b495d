"""The integration methods, as compiled loops over a batch of states.

Every loop has the same shape: for each batch element b (in parallel), copy y0[b], take
`nsteps` steps of size dt, store every `save_every`-th state into out[s, b], and record the first
step whose state is not finite (-1 when none). The scene supplies

    rhs(y, p, out)    y' = f(y)            (every general method)
    accel(q, p, out)  q'' = a(q), y = (q, q')  (the symplectic methods: the Hamiltonian is separable)

Methods (order in brackets):
    euler [1]             y += dt f(y)
    symplectic_euler [1]  v += dt a(q); q += dt v
    verlet [2]            velocity Verlet (kick-drift-kick), symmetric and symplectic
    rk4 [4]               classical Runge-Kutta
    yoshida6 [6]          Yoshida's 7-stage symmetric composition of verlet (solution A)
    gauss6 [6]            3-stage Gauss-Legendre collocation, implicit, symmetric and symplectic for
                          any Hamiltonian; solved by fixed-point iteration to round-off
    splitting [2]         the scene's own symmetric splitting into exact flows (free rotation)
    reference             scipy DOP853 at rtol 1e-13: for checks only, never for speed
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

METHOD_ORDER = {
    "euler": 1,
    "symplectic_euler": 1,
    "verlet": 2,
    "rk4": 4,
    "yoshida6": 6,
    "gauss6": 6,
    "splitting": 2,
    "reference": None,
}
METHODS = tuple(METHOD_ORDER)
SYMPLECTIC = ("symplectic_euler", "verlet", "yoshida6", "gauss6", "splitting")
SYMMETRIC = ("verlet", "yoshida6", "gauss6", "splitting")

# Yoshida (1990), 6th order, solution A: weights w3 w2 w1 w0 w1 w2 w3 of the symmetric base step.
_W1, _W2, _W3 = -1.17767998417887, 0.235573213359357, 0.784513610477560
YOSHIDA6 = np.array([_W3, _W2, _W1, 1.0 - 2.0 * (_W1 + _W2 + _W3), _W1, _W2, _W3])

# Gauss-Legendre, 3 stages (Butcher tableau).
_S15 = np.sqrt(15.0)
GAUSS6_A = np.array([
    [5 / 36, 2 / 9 - _S15 / 15, 5 / 36 - _S15 / 30],
    [5 / 36 + _S15 / 24, 2 / 9, 5 / 36 - _S15 / 24],
    [5 / 36 + _S15 / 30, 2 / 9 + _S15 / 15, 5 / 36],
])
GAUSS6_B = np.array([5 / 18, 4 / 9, 5 / 18])
GAUSS6_MAX_ITERATIONS = 60


@njit(cache=True, inline="always")
def _finite(y):
    for j in range(y.size):
        if not np.isfinite(y[j]):
            return False
    return True


@njit(cache=True, parallel=True)
def run_euler(rhs, y0, params, dt, nsteps, save_every, out):
    batch, n = y0.shape
    failed = np.full(batch, -1, dtype=np.int64)
    for b in prange(batch):
        y = y0[b].copy()
        k = np.empty(n)
        p = params[b]
        out[0, b] = y
        for i in range(1, nsteps + 1):
            rhs(y, p, k)
            for j in range(n):
                y[j] += dt * k[j]
            if i % save_every == 0:
                out[i // save_every, b] = y
                if not _finite(y):
                    failed[b] = i
                    break
    return failed


@njit(cache=True, parallel=True)
def run_rk4(rhs, y0, params, dt, nsteps, save_every, out):
    batch, n = y0.shape
    failed = np.full(batch, -1, dtype=np.int64)
    for b in prange(batch):
        y = y0[b].copy()
        p = params[b]
        k1, k2, k3, k4, tmp = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        out[0, b] = y
        for i in range(1, nsteps + 1):
            rhs(y, p, k1)
            for j in range(n):
                tmp[j] = y[j] + 0.5 * dt * k1[j]
            rhs(tmp, p, k2)
            for j in range(n):
                tmp[j] = y[j] + 0.5 * dt * k2[j]
            rhs(tmp, p, k3)
            for j in range(n):
                tmp[j] = y[j] + dt * k3[j]
            rhs(tmp, p, k4)
            for j in range(n):
                y[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
            if i % save_every == 0:
                out[i // save_every, b] = y
                if not _finite(y):
                    failed[b] = i
                    break
    return failed


@njit(cache=True, parallel=True)
def run_symplectic_euler(accel, y0, params, dt, nsteps, save_every, out):
    batch, n = y0.shape
    m = n // 2
    failed = np.full(batch, -1, dtype=np.int64)
    for b in prange(batch):
        y = y0[b].copy()
        p = params[b]
        a = np.empty(m)
        out[0, b] = y
        for i in range(1, nsteps + 1):
            accel(y[:m], p, a)
            for j in range(m):
                y[m + j] += dt * a[j]
                y[j] += dt * y[m + j]
            if i % save_every == 0:
                out[i // save_every, b] = y
                if not _finite(y):
                    failed[b] = i
                    break
    return failed


@njit(cache=True, parallel=True)
def run_composed_verlet(accel, weights, y0, params, dt, nsteps, save_every, out):
    """Velocity Verlet with step weights (weights = [1.0] is verlet itself; YOSHIDA6 its 6th-order
    composition). The acceleration at the end of one sub-step is reused at the start of the next."""
    batch, n = y0.shape
    m = n // 2
    failed = np.full(batch, -1, dtype=np.int64)
    for b in prange(batch):
        y = y0[b].copy()
        p = params[b]
        a = np.empty(m)
        accel(y[:m], p, a)
        out[0, b] = y
        for i in range(1, nsteps + 1):
            for w in weights:
                h = w * dt
                for j in range(m):
                    y[m + j] += 0.5 * h * a[j]
                    y[j] += h * y[m + j]
                accel(y[:m], p, a)
                for j in range(m):
                    y[m + j] += 0.5 * h * a[j]
            if i % save_every == 0:
                out[i // save_every, b] = y
                if not _finite(y):
                    failed[b] = i
                    break
    return failed


@njit(cache=True, parallel=True)
def run_gauss6(rhs, A, weights, y0, params, dt, nsteps, save_every, out):
    batch, n = y0.shape
    stages = weights.size
    failed = np.full(batch, -1, dtype=np.int64)
    for b in prange(batch):
        y = y0[b].copy()
        p = params[b]
        K = np.empty((stages, n))
        K_new = np.empty((stages, n))
        tmp = np.empty(n)
        k0 = np.empty(n)
        out[0, b] = y
        for i in range(1, nsteps + 1):
            rhs(y, p, k0)
            for s in range(stages):
                K[s] = k0
            for _ in range(GAUSS6_MAX_ITERATIONS):
                change = 0.0
                scale = 0.0
                for s in range(stages):
                    for j in range(n):
                        acc = 0.0
                        for r in range(stages):
                            acc += A[s, r] * K[r, j]
                        tmp[j] = y[j] + dt * acc
                    rhs(tmp, p, K_new[s])
                for s in range(stages):
                    for j in range(n):
                        change = max(change, abs(K_new[s, j] - K[s, j]))
                        scale = max(scale, abs(K_new[s, j]))
                        K[s, j] = K_new[s, j]
                if not change > 2e-16 * scale:  # converged (also stops on NaN)
                    break
            for j in range(n):
                acc = 0.0
                for s in range(stages):
                    acc += weights[s] * K[s, j]
                y[j] += dt * acc
            if i % save_every == 0:
                out[i // save_every, b] = y
                if not _finite(y):
                    failed[b] = i
                    break
    return failed


@njit(cache=True, parallel=True)
def run_composed_flow(step, weights, y0, params, dt, nsteps, save_every, out):
    """A scene's own symmetric one-step map step(y, p, h) composed with the given weights
    (weights = [1.0]: the map itself; YOSHIDA6: its 6th-order composition)."""
    batch, n = y0.shape
    failed = np.full(batch, -1, dtype=np.int64)
    for b in prange(batch):
        y = y0[b].copy()
        p = params[b]
        out[0, b] = y
        for i in range(1, nsteps + 1):
            for w in weights:
                step(y, p, w * dt)
            if i % save_every == 0:
                out[i // save_every, b] = y
                if not _finite(y):
                    failed[b] = i
                    break
    return failed


def run_reference(rhs, y0: np.ndarray, params: np.ndarray, dt: float, nsteps: int, save_every: int,
                  out: np.ndarray, rtol: float = 1e-13) -> np.ndarray:
    """scipy's DOP853 at rtol 1e-13, sampled at the same times as the fixed-step methods."""
    from scipy.integrate import solve_ivp

    batch, n = y0.shape
    samples = np.arange(out.shape[0]) * save_every * dt
    failed = np.full(batch, -1, dtype=np.int64)
    for b in range(batch):
        p = params[b]

        def f(_t, y, p=p):
            k = np.empty(n)
            rhs(np.ascontiguousarray(y), p, k)
            return k

        scale = max(float(np.max(np.abs(y0[b]))), 1.0)
        solution = solve_ivp(f, (0.0, samples[-1]), y0[b], method="DOP853", t_eval=samples,
                             rtol=rtol, atol=rtol * 1e-2 * scale)
        if not solution.success:
            failed[b] = 1
            continue
        out[:, b] = solution.y.T
    return failed
