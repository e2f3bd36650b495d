"""How large a time step each method can take on a scene, and what float64 can resolve at all.

Linear stability. A method applied to y' = f(y) is stable on a linear mode y' = lambda y while
h lambda lies in its stability region. Along an oscillation lambda = +-i w, so each method keeps the
amplitude bounded only while h w < beta, its interval on the imaginary axis. beta is a field of the
method's record (rbody.engine.methods, where each value is derived): euler 0 (none), symplectic_euler
and verlet 2, rk4 2 sqrt(2), yoshida6 2.2690..., gauss6 1 / (2 rho(A)) = 2.32 (the reach of its
fixed-point iteration), splitting 2, reference inf.

A method without an interval (euler, beta = 0): its limit here is the step at which the fastest linear
mode grows by a factor EULER_GROWTH (2) in amplitude over the run, (1 + (h w)^2)^(t / 2h) = 2, i.e.
h = 2 ln 2 / (w^2 t) to first order.

The rate w of a scene is the largest |eigenvalue| of the Jacobian df/dy along its motion, read from the
scene's native model, never from its class (model_rate):
- model.rate(method): the scene's own estimate where it knows its motion. Pendulum: w0 = sqrt(M g d / I)
  (the linearisation at the bottom, or the growth rate at the top). Free rotation
  (rbody.scenes.free_rotation.rotation_rates): max
  over one period of the exact motion of |omega|/2 (the quaternion's rotation rate) and the eigenvalues
  of Euler's equations linearised, I^-1 ([L]x - [omega]x I) (a wobble, or the growth rate near the
  intermediate axis), and for the splitting and its yoshida6 composition also |omega_perp| sqrt(I3/I1),
  the rate of its sub-rotations on the smallest moment;
- model.rate_from_jacobian: the spectral radius of df/dy by central differences at y0, and at
  model.rest (a state of equilibrium: the fastest normal mode) where given (any tree, chains). For a batch
  the Jacobians are formed in one compiled loop and their eigenvalues in one stacked call;
- neither: no estimate (rolling: constant accelerations, any step is exact; other scenes: an infinite
  limit; the check for non-finite states after every step remains).

Float64 resolution. A pendulum released near the top (k^2 -> 1) carries the margin of its swing below
the top, 1 - k^2 = cos^2(theta0/2) - omega0^2 / (4 w0^2), in its state only as the speed at the bottom,
2 k w0 = 2 w0 sqrt(1 - (1 - k^2)): that speed is stored to a relative eps = 2.2e-16, so once
|1 - k^2| is below a few eps every time-stepped run in (theta, omega) passes the bottom in a state that
float64 cannot tell from a whirl or the separatrix (theta0 = pi - 1e-9 gives 1 - k^2 = 2.5e-19).
Above that, every step's rounding moves 1 - k^2 by ~eps at random: over n steps by ~eps sqrt(n), which
changes the period by ~eps sqrt(n) / (2 |1 - k^2| K(k^2)) (theta0 = pi - 1e-6: 1 - k^2 = 2.5e-13, about
0.1 % after one period at dt w0 = 0.05, and a whirl within 10^4 periods).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from rbody.engine import integrators
from rbody.engine.methods import method as method_record, yoshida6_interval
from rbody.errors import SimulationError
from rbody.engine.native import Experiment, NativeModel

EPS = float(np.finfo(np.float64).eps)
# Euler's method: the amplitude growth over the run that its limit allows.
EULER_GROWTH = 2.0
# A pendulum run is refused when this many times the round-off drift eps sqrt(steps) reaches |1 - k^2|.
RESOLUTION_FACTOR = 4.0
# Relative step of the central differences of the Jacobian (truncation ~ step^2, round-off ~ eps / step).
JACOBIAN_STEP = 1e-6


def stability_interval(method: str) -> float:
    """beta (float): the method keeps an oscillation of angular frequency w bounded while dt w < beta
    (0 for euler, which has no such interval; inf for 'reference', an adaptive solver): its record's interval
    (rbody.engine.methods)."""
    return method_record(method).interval


# ----- the fastest rate of a scene ------------------------------------------------------------------

def fastest_rate(scene: Experiment, method: str | None = None) -> np.ndarray:
    """(B,) largest |eigenvalue| of df/dy along the motion of each batch element [1/s], from the scene's native
    model (model_rate): the scene's own estimate (model.rate), else the Jacobian of its rhs, else 0.

    The rate may depend on the method (a free rotation's splitting moves angular momentum at a rate of its
    own), and simulate asks for it on every call: it is computed once per method and kept in the scene's own
    __dict__ (read-only). Scenes are frozen dataclasses holding arrays, hence unhashable, so no outside cache
    could key on them; the scene's __dict__ is where its cached_property values live too, and a frozen scene
    never changes, so the kept rate never goes stale."""
    cache = scene.__dict__.setdefault("_fastest_rate", {})  # frozen: no setattr, but __dict__ is writable
    if method not in cache:
        model = scene.native_model
        rate = model_rate(model, method)
        rate = np.array(rate, dtype=np.float64).reshape(model.y0.shape[0])
        rate.setflags(write=False)
        cache[method] = rate
    return cache[method]


def _largest_rate(scene: Experiment, method: str | None) -> float:
    """max over the batch of fastest_rate(scene, method), kept beside it."""
    cache = scene.__dict__.setdefault("_largest_rate", {})
    if method not in cache:
        cache[method] = float(np.max(fastest_rate(scene, method)))
    return cache[method]


def model_rate(model: NativeModel, method: str | None = None) -> np.ndarray:
    """(B,) fastest rate [1/s] of a NativeModel: model.rate(method) where the scene gives its own; else, with
    model.rate_from_jacobian, the spectral radius of df/dy at y0 and (when model.rest is given) at the state of
    rest; else zeros (no estimate: constant accelerations, or a scene whose Jacobian at the start says little
    about its motion; the check for non-finite states after every step remains)."""
    batch = model.y0.shape[0]
    if model.rate is not None:
        return np.broadcast_to(np.asarray(model.rate(method), dtype=np.float64), (batch,))
    if not model.rate_from_jacobian:
        return np.zeros(batch)
    y0 = np.ascontiguousarray(model.y0, dtype=np.float64)
    params = np.ascontiguousarray(model.params, dtype=np.float64)
    rate = jacobian_rate(model.rhs, y0, params)
    if model.rest is not None:
        rest = np.ascontiguousarray(np.broadcast_to(np.asarray(model.rest, dtype=np.float64), y0.shape))
        rate = np.maximum(rate, jacobian_rate(model.rhs, rest, params))
    return rate


def jacobian_rate(rhs, y: np.ndarray, params: np.ndarray) -> np.ndarray:
    """(B,) spectral radius of df/dy at each row of y (B, n), by central differences of the compiled rhs: the
    Jacobians of a block of elements in one compiled loop (threads over chunks of it), their eigenvalues in one
    stacked numpy call; blocks of at most JACOBIAN_BLOCK numbers bound the memory of a long chain's batch.
    A state of more than DENSE_STATE_LIMIT numbers (a big tree) is not formed densely (2n evaluations, n^2
    numbers, a cubic eigenproblem): krylov_rate finds its spectral radius from Jacobian-vector products."""
    y, params = np.ascontiguousarray(y, dtype=np.float64), np.ascontiguousarray(params, dtype=np.float64)
    batch, n = y.shape
    if n > DENSE_STATE_LIMIT:
        return np.array([krylov_rate(rhs, y[b], params[b]) for b in range(batch)])
    rates = np.empty(batch)
    block = max(1, JACOBIAN_BLOCK // (n * n))
    pointer = integrators.pointer_function(rhs)
    for start in range(0, batch, block):
        stop = min(batch, start + block)
        jacobians = np.empty((stop - start, n, n))
        loop = _jacobians_serial if stop - start <= JACOBIAN_CHUNK else _jacobians  # one chunk: no threads to wake
        loop(pointer, y[start:stop], params[start:stop], JACOBIAN_STEP, jacobians)
        finite = np.all(np.isfinite(jacobians), axis=(1, 2))
        rates[start:stop] = np.inf  # a Jacobian that is not finite: no step is safe
        if np.any(finite):
            rates[start:stop][finite] = np.max(np.abs(np.linalg.eigvals(jacobians[finite])), axis=-1)
    return rates


def jacobian_matrices(rhs, y: np.ndarray, params: np.ndarray) -> np.ndarray:
    """(B, n, n) df/dy at each row of y (B, n), by the central differences of jacobian_rate."""
    y, params = np.ascontiguousarray(y, dtype=np.float64), np.ascontiguousarray(params, dtype=np.float64)
    out = np.empty((y.shape[0], y.shape[1], y.shape[1]))
    _jacobians(integrators.pointer_function(rhs), y, params, JACOBIAN_STEP, out)
    return out


JACOBIAN_BLOCK = 2**21  # numbers (16 MB) of Jacobians held at once
JACOBIAN_CHUNK = 256    # elements per thread's task in the compiled loop
# States longer than this are not linearised densely (krylov_rate): at n = 64 the dense Jacobian costs 128
# evaluations and a 64 x 64 eigenproblem (~1 ms); a tree of 1,000 ball joints (n = 10,000) would cost 20,000
# evaluations, 0.8 GB and a cubic eigenproblem (measured before: 41 s and 2.6 GB).
DENSE_STATE_LIMIT = 64
KRYLOV_TOLERANCE = 1e-3   # relative accuracy of the spectral radius from Arnoldi's iteration
KRYLOV_VECTORS = 24       # its basis size (ARPACK's ncv)
KRYLOV_MAX_RESTARTS = 60  # restarts before the best estimate so far is taken


def krylov_rate(rhs, y: np.ndarray, params: np.ndarray) -> float:
    """Spectral radius of df/dy at y (n,) [1/s], from Jacobian-vector products by central differences
    (jvp_difference: two evaluations each) and the implicitly restarted Arnoldi iteration (scipy's ARPACK eigs,
    the eigenvalue of largest magnitude, to KRYLOV_TOLERANCE): a few dozen products, O(n) memory, whatever n.
    inf when a product is not finite (no step is known to be safe there); 0 for a zero Jacobian."""
    from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, LinearOperator, eigs

    y, params = np.ascontiguousarray(y, dtype=np.float64), np.ascontiguousarray(params, dtype=np.float64)
    n = y.size
    pointer = integrators.pointer_function(rhs)
    scale = JACOBIAN_STEP * max(1.0, float(np.max(np.abs(y))))
    work = np.empty((4, n))
    bad = [False]

    def product(v):
        v = np.ascontiguousarray(np.real(v), dtype=np.float64).reshape(n)
        size = float(np.max(np.abs(v)))
        out = np.empty(n)
        if size == 0.0:
            out[:] = 0.0
            return out
        _jvp(pointer, y, params, v, scale / size, work, out)
        if not np.all(np.isfinite(out)):
            bad[0] = True
            out[:] = 0.0
        return out

    operator = LinearOperator((n, n), matvec=product, dtype=np.float64)
    start = np.random.default_rng(0).standard_normal(n)  # a fixed start: the same rate on every call
    try:
        values = eigs(operator, k=1, which="LM", tol=KRYLOV_TOLERANCE, ncv=min(n - 1, KRYLOV_VECTORS),
                      maxiter=KRYLOV_MAX_RESTARTS, v0=start, return_eigenvectors=False)
    except ArpackNoConvergence as partial:  # the best converged value, else the power estimate below
        values = partial.eigenvalues
    except ArpackError:
        values = np.zeros(0)
    if bad[0]:
        return math.inf
    if values.size:
        return float(np.max(np.abs(values)))
    vector = start / np.linalg.norm(start)  # a few power steps: a lower estimate, never 0 when J is not 0
    rate = 0.0
    for _ in range(30):
        image = product(vector)
        rate = float(np.linalg.norm(image))
        if rate == 0.0:
            break
        vector = image / rate
    return math.inf if bad[0] else rate


@njit(cache=True)
def _jvp(rhs_address, y, params, v, step, work, out):
    """out = (f(y + step v) - f(y - step v)) / (2 step): df/dy v by central differences; work (4, n); f the model's
    rhs at its C address (integrators.pointer_function)."""
    rhs = integrators._rhs_at(rhs_address)
    n, m = y.size, params.size
    for j in range(n):
        work[0, j] = y[j] + step * v[j]
        work[1, j] = y[j] - step * v[j]
    rhs(integrators._row(work, 0), integrators._row(params.reshape(1, m), 0), integrators._row(work, 2), n, m)
    rhs(integrators._row(work, 1), integrators._row(params.reshape(1, m), 0), integrators._row(work, 3), n, m)
    for j in range(n):
        out[j] = (work[2, j] - work[3, j]) / (2.0 * step)


@njit(cache=True, parallel=True)
def _jacobians(rhs_address, y, params, relative, out):
    """out[b] (n, n) = df/dy at y[b], by central differences (step relative * max(1, |y_j|))."""
    rhs = integrators._rhs_at(rhs_address)
    batch, n = y.shape
    m = params.shape[1]
    for c in prange(-(-batch // JACOBIAN_CHUNK)):
        state, row = np.empty((1, n)), np.empty((1, m))
        plus, minus = np.empty((1, n)), np.empty((1, n))
        for b in range(c * JACOBIAN_CHUNK, min(batch, (c + 1) * JACOBIAN_CHUNK)):
            for k in range(m):
                row[0, k] = params[b, k]
            for j in range(n):
                state[0, j] = y[b, j]
            for j in range(n):
                step = relative * max(1.0, abs(y[b, j]))
                state[0, j] = y[b, j] + step
                rhs(integrators._row(state, 0), integrators._row(row, 0), integrators._row(plus, 0), n, m)
                state[0, j] = y[b, j] - step
                rhs(integrators._row(state, 0), integrators._row(row, 0), integrators._row(minus, 0), n, m)
                state[0, j] = y[b, j]
                for i in range(n):
                    out[b, i, j] = (plus[0, i] - minus[0, i]) / (2.0 * step)


# The same loop without threads (prange runs as range), for a batch of one chunk: compiled in a fraction of the
# parallel loop's time, which a model's first run pays (integrators._serial_twin: its own cache entry).
_jacobians_serial = integrators._serial_twin(_jacobians)


# ----- the limit and the check --------------------------------------------------------------------

def stability_limit(scene: Experiment, method: str, t_end: float | None = None) -> float:
    """Largest time step [s] at which `method` stays stable on every batch element of `scene`:
    stability_interval(method) / fastest_rate(scene); for euler, the step whose amplitude growth over
    t_end [s] (default scene.t_end) is EULER_GROWTH; inf where the scene has no rate (rolling) or the
    method no bound (reference). Event-driven scenes: inf (dt only samples them)."""
    if scene.event_driven:
        return math.inf
    beta = stability_interval(method)
    if beta == math.inf:
        return math.inf
    rate = _largest_rate(scene, method)
    if rate == 0.0:
        return math.inf
    if beta == 0.0:  # no interval (euler): the step whose amplitude growth over the run is EULER_GROWTH
        t_end = scene.t_end if t_end is None else float(t_end)
        return 2.0 * math.log(EULER_GROWTH) / (rate**2 * t_end)
    return beta / rate


def resolution_problem(scene: Experiment, dt: float | None = None, t_end: float | None = None) -> str | None:
    """Why float64 time stepping cannot resolve `scene` over t_end [s] at step dt [s] (str), or None.

    Pendulums near the top only: 1 - k^2 is carried at the bottom of the swing only to ~eps (module
    docstring), and every step's rounding moves it by ~eps at random, sigma = eps sqrt(steps) over the
    run (measured: 0.13 eps sqrt(steps) for verlet, 0.3 for yoshida6). The run is refused when
    RESOLUTION_FACTOR sigma reaches |1 - k^2|: beyond it the round-off alone changes the period by
    ~ sigma / (2 |1 - k^2| K) or turns the swing into a whirl. Without dt, one step is assumed."""
    margin = _separatrix_margin(scene)
    if margin is None:
        return None
    t_end = scene.t_end if t_end is None else float(t_end)
    steps = 1 if dt is None else max(1, math.ceil(t_end / dt))
    drift = EPS * math.sqrt(steps)
    if scene.__dict__["_smallest_margin"] >= RESOLUTION_FACTOR * drift:  # the common case, without array work
        return None
    bad = (margin > 0) & (margin < RESOLUTION_FACTOR * drift)
    if not np.any(bad):
        return None
    b = int(np.argmax(bad))
    return (f"its margin below the top, |1 - k^2| = |cos^2(theta0/2) - omega0^2/(4 w0^2)| = {margin[b]:.3g} "
            f"(batch element {b}), is below {RESOLUTION_FACTOR:g} eps sqrt(steps) = {RESOLUTION_FACTOR * drift:.3g} "
            f"for {steps} steps: float64 carries 1 - k^2 only as the speed 2 w0 sqrt(1 - (1 - k^2)) at the bottom, "
            "and the rounding of every step moves it by ~eps, so the period would be set by round-off or the swing "
            "turn into a whirl; use fewer steps (a larger dt or a shorter run) or scene.exact(t), which evaluates "
            "the motion from the complement 1 - k^2")


def _separatrix_margin(scene: Experiment) -> np.ndarray | None:
    """(B,) |1 - k^2| of a motion carried in its state only to ~eps (model.separatrix_margin), or None; kept in
    the scene's __dict__ like its rate (simulate asks on every call)."""
    cache = scene.__dict__
    if "_separatrix_margin" not in cache:
        model = scene.native_model
        margin = model.separatrix_margin
        smallest = math.inf
        if margin is not None:
            margin = np.abs(np.asarray(margin, dtype=np.float64)).reshape(-1)
            margin.setflags(write=False)
            positive = margin[margin > 0]
            smallest = float(positive.min()) if positive.size else math.inf
        cache["_separatrix_margin"], cache["_smallest_margin"] = margin, smallest
    return cache["_separatrix_margin"]


def check_state(model: NativeModel, description: str, method: str, dt: float, t_end: float) -> None:
    """Raise SimulationError when dt [s] is beyond `method`'s stability limit at the initial states of `model` (a
    NativeModel whose y0 a prepared run replaced: rbody.simulation.PreparedRun.run(qpos0=...)), from model_rate,
    as check_step does for a scene's own states."""
    beta = stability_interval(method)
    if beta == math.inf:
        return
    rate = float(np.max(model_rate(model, method)))
    if rate == 0.0:
        return
    limit = 2.0 * math.log(EULER_GROWTH) / (rate**2 * t_end) if beta == 0.0 else beta / rate
    if dt > limit:
        raise SimulationError(f"scene {description}: method {method!r}: dt={dt:g} s is beyond its estimated stability "
                              f"limit {limit:.6g} s at the initial state given (w = {rate:.6g} rad/s, the fastest rate "
                              f"of the linearised motion there); use dt <= {limit:.6g} s")


def check_step(scene: Experiment, method: str, dt: float, t_end: float | None = None) -> None:
    """Raise SimulationError, before any step, when dt [s] is beyond stability_limit(scene, method, t_end)
    or the scene is beyond float64's resolution (resolution_problem); return None otherwise."""
    if scene.event_driven or stability_interval(method) == math.inf:  # an adaptive solver: no step to check
        return
    problem = resolution_problem(scene, dt, t_end)
    if problem is not None:
        raise SimulationError(f"scene {scene.describe()}: method {method!r} cannot run it: {problem}")
    limit = stability_limit(scene, method, t_end)
    if dt > limit:
        rate = float(np.max(fastest_rate(scene, method)))
        if not math.isfinite(rate):  # no rate at all: say so, rather than "use dt <= 0 s"
            b = int(np.argmax(~np.isfinite(fastest_rate(scene, method))))
            raise SimulationError(
                f"scene {scene.describe()}: method {method!r}: the stability limit cannot be estimated: the Jacobian of "
                f"the dynamics is not finite at the initial state (batch element {b}), so no step is known to be "
                "stable. The dynamics there are singular or carry no digits (e.g. a mass matrix that is singular, or "
                "a tiny inertia far from the origin: TreeScene.precision_problem); check the model's masses, inertias "
                "and initial state")
        if stability_interval(method) == 0.0:
            why = (f"{method} has no stability interval (|1 + i dt w| > 1): at dt={dt:g} s the fastest linear mode "
                   f"(w = {rate:.6g} rad/s) grows by more than {EULER_GROWTH:g}x over t_end; its limit here is "
                   f"2 ln {EULER_GROWTH:g} / (w^2 t_end) = {limit:.6g} s")
        else:
            why = (f"dt={dt:g} s is beyond its estimated stability limit {limit:.6g} s = "
                   f"{stability_interval(method):.4g}"
                   f" / w, w = {rate:.6g} rad/s the fastest rate of the scene's linearised motion")
        raise SimulationError(f"scene {scene.describe()}: method {method!r}: {why}; use dt <= {limit:.6g} s")


__all__ = ["stability_interval", "yoshida6_interval", "fastest_rate", "model_rate", "jacobian_rate", "jacobian_matrices",
           "stability_limit", "resolution_problem", "check_step", "check_state", "EULER_GROWTH", "RESOLUTION_FACTOR"]
