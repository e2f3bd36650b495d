"""How large a time step each method can take on a scene, and what float64 can resolve at all.

Linear stability. A method applied to y' = f(y) is stable on a linear mode y' = lambda y while
h lambda lies in its stability region. Along an oscillation lambda = +-i w, so each method keeps the
amplitude bounded only while h w < beta, its interval on the imaginary axis:

    euler             none: |1 + i h w| = sqrt(1 + (h w)^2) > 1, the amplitude grows at every step
    symplectic_euler  2:    the step matrix has trace 2 - (h w)^2, which must stay in [-2, 2]
    verlet            2:    the same trace
    rk4               2 sqrt(2): |1 + z + z^2/2 + z^3/6 + z^4/24| <= 1 for z = i h w
    yoshida6          2.2690579963976...: the trace of its seven verlet steps (weights YOSHIDA6)
                      first leaves [-2, 2] there (computed by bisection, yoshida6_interval())
    gauss6            A-stable, but rbody solves its stage equations by fixed-point iteration, which
                      contracts by h w rho(A) per sweep, rho(A) = 0.2153 the spectral radius of the
                      tableau: beta = 1 / (2 rho(A)) = 2.32 keeps the contraction at 1/2 or better
    splitting         the scene's exact sub-flows (free rotation): taken as verlet's 2, the interval of
                      a second-order symmetric splitting; its yoshida6 composition as yoshida6's

Euler's explicit method has no interval: its limit here is the step at which the fastest linear
mode grows by a factor `growth` (2) in amplitude over the run, (1 + (h w)^2)^(t / 2h) = 2, i.e.
h = 2 ln 2 / (w^2 t) to first order.

The rate w of a scene is the largest |eigenvalue| of the Jacobian df/dy along its motion:
pendulum: w0 = sqrt(M g d / I) (the linearisation at the bottom, or the growth rate at the top);
free rotation: max over one period of the exact motion of |omega|/2 (the quaternion's rotation
rate) and the eigenvalues of Euler's equations linearised, I^-1 ([L]x - [omega]x I) (a wobble, or the
growth rate near the intermediate axis), and for the splitting and its yoshida6 composition also
|omega_perp| sqrt(I3/I1), the rate of its sub-rotations on the smallest moment (fastest_rate); rolling: 0 (the
accelerations are constant, any step is exact); chains: the Jacobian at the initial state and the
fastest normal mode; other scenes: no estimate (an infinite limit; the check for non-finite states
after every step remains).

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
from functools import lru_cache

import numpy as np

from rbody.errors import SimulationError
from rbody.scene import Scene

EPS = float(np.finfo(np.float64).eps)
# Euler's method: the amplitude growth over the run that its limit allows.
EULER_GROWTH = 2.0
# A pendulum run is refused when this many times the round-off drift eps sqrt(steps) reaches |1 - k^2|.
RESOLUTION_FACTOR = 4.0
# Samples of one period of the exact free rotation at which the Jacobian is evaluated.
ROTATION_SAMPLES = 65


@lru_cache(maxsize=None)
def yoshida6_interval() -> float:
    """h w bound (float) of yoshida6 on the harmonic oscillator: the first h at which the trace of the
    composed verlet steps leaves [-2, 2] (bisection to round-off)."""
    from rbody.engine.integrators import YOSHIDA6

    def trace(h: float) -> float:
        step = np.eye(2)
        for w in YOSHIDA6:
            kick = np.array([[1.0, 0.0], [-0.5 * w * h, 1.0]])
            drift = np.array([[1.0, w * h], [0.0, 1.0]])
            step = kick @ drift @ kick @ step
        return float(np.trace(step))

    # The first exit on a grid of 1e-3 (the unstable windows beyond it are wider), then bisection.
    grid = np.arange(1, 4001) * 1e-3
    first = next(i for i, h in enumerate(grid) if abs(trace(h)) > 2.0)
    low, high = float(grid[first - 1]), float(grid[first])
    for _ in range(60):
        middle = 0.5 * (low + high)
        if abs(trace(middle)) <= 2.0:
            low = middle
        else:
            high = middle
    return low


@lru_cache(maxsize=None)
def _gauss6_interval() -> float:
    from rbody.engine.integrators import GAUSS6_A

    return 0.5 / float(np.max(np.abs(np.linalg.eigvals(GAUSS6_A))))


def stability_interval(method: str) -> float:
    """beta (float): the method keeps an oscillation of angular frequency w bounded while dt w < beta
    (0 for euler, which has no such interval; inf for 'reference', an adaptive solver)."""
    intervals = {"euler": 0.0, "symplectic_euler": 2.0, "verlet": 2.0, "rk4": 2.0 * math.sqrt(2.0),
                 "yoshida6": yoshida6_interval(), "gauss6": _gauss6_interval(), "splitting": 2.0,
                 "reference": math.inf}
    if method not in intervals:
        raise ValueError(f"method={method!r}: expected one of {', '.join(map(repr, intervals))}")
    return intervals[method]


# ----- the fastest rate of a scene ------------------------------------------------------------------

def fastest_rate(scene: Scene, method: str | None = None) -> np.ndarray:
    """(B,) largest |eigenvalue| of df/dy along the motion of each batch element [1/s] (module docstring).

    method "splitting" or "yoshida6" on a free rotation: also |omega_perp| sqrt(I3 / I1), omega_perp the
    part of omega across the axis of the smallest moment: the rate at which the exact sub-rotations about
    the other axes move angular momentum onto that axis, where omega_1 = L_1 / I1. The splitting's error
    grows as (dt |omega_perp| sqrt(I3/I1))^2 (measured on tumbling needles: 0.0165 (I3/I1) (dt |omega|)^2
    over 2 s, for I3/I1 from 17 to 1.7e7), so a needle's splitting needs far smaller steps than its
    dynamics. yoshida6 (6th order) gets a quarter of that rate: measured on the same needles its error is
    ~1.4e-11 (dt |omega_perp| sqrt(I3/I1))^6 (6.6e-8 at 4.1, 6 % at 41).

    The rate depends only on the scene and the kind of method (the splitting, its yoshida6 composition, or
    any other), and simulate asks for it on every call: it is computed once and kept in the scene's own
    __dict__ (read-only). Scenes are frozen dataclasses holding arrays, hence unhashable, so no outside
    cache could key on them; the scene's __dict__ is where its cached_property values live too, and a
    frozen scene never changes, so the kept rate never goes stale."""
    from rbody.scenes.free_rotation import FreeRotation

    kind = {"splitting": "splitting", "yoshida6": "yoshida6"}.get(method) if isinstance(scene, FreeRotation) else None
    cache = scene.__dict__.setdefault("_fastest_rate", {})  # frozen: no setattr, but __dict__ is writable
    if kind not in cache:
        rate = np.array(_fastest_rate(scene, kind), dtype=np.float64)
        rate.setflags(write=False)
        cache[kind] = rate
    return cache[kind]


def _fastest_rate(scene: Scene, method: str | None) -> np.ndarray:
    from rbody.scenes.chain import PendulumChain
    from rbody.scenes.free_rotation import FreeRotation
    from rbody.scenes.pendulum import Pendulum

    if isinstance(scene, Pendulum):
        return np.sqrt(scene._w0_squared())
    if isinstance(scene, FreeRotation):
        split = {"splitting": 1.0, "yoshida6": 0.25}.get(method, 0.0)
        return np.array([_rotation_rate(scene.item(index), split) for index in np.ndindex(*scene.batch_shape)])
    if isinstance(scene, PendulumChain):
        return np.maximum(_jacobian_rate(scene), float(np.max(scene.normal_modes()[0])))
    if scene.native_model.rate_from_jacobian:  # a tree (Scene.from_layout): the linearisation of its model
        return _jacobian_rate(scene)
    # Rolling: constant accelerations, any step is exact. Other scenes: no estimate (their Jacobian at the
    # start says little about the motion, and costs O(n) right-hand sides for n coordinates): the limit is
    # inf there and the non-finite check after each step is the guard.
    return np.zeros(scene.native_model.y0.shape[0])


def _rotation_rate(scene, split: float = 0.0) -> float:
    """max over one period (or the run) of the exact motion of |omega|/2 and |eig(I^-1 ([L]x - [w]x I))|
    (and split x |omega_perp| sqrt(I3/I1))."""
    moments = scene.principal_moments
    _moments, axes = scene.inertia.principal()
    period = scene.period
    span = scene.t_end if not np.isfinite(period) else min(period, scene.t_end)
    t = np.linspace(0.0, span, ROTATION_SAMPLES)
    omega = scene.exact(t)["omega_body"].reshape(-1, 3) @ axes  # principal components
    rate = 0.0
    for w in omega:
        momentum = moments * w
        jacobian = (_cross_matrix(momentum) - _cross_matrix(w) * moments) / moments[:, None]
        rate = max(rate, 0.5 * float(np.linalg.norm(w)), float(np.max(np.abs(np.linalg.eigvals(jacobian)))))
        if split:  # the rotations about axes 2 and 3 move L onto axis 1, where omega_1 = L_1 / I1
            rate = max(rate, split * float(np.hypot(w[1], w[2])) * math.sqrt(moments[2] / moments[0]))
    return rate


def _cross_matrix(v: np.ndarray) -> np.ndarray:
    """[v]x (3, 3): [v]x u = v x u."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _jacobian_rate(scene: Scene) -> np.ndarray:
    """(B,) spectral radius of df/dy at the initial state, by central differences of the scene's rhs."""
    model = scene.native_model
    y0, params = np.ascontiguousarray(model.y0, dtype=np.float64), np.ascontiguousarray(model.params)
    batch, n = y0.shape
    rates = np.empty(batch)
    plus, minus = np.empty(n), np.empty(n)
    for b in range(batch):
        jacobian = np.empty((n, n))
        for j in range(n):
            step = 1e-6 * max(1.0, abs(y0[b, j]))
            y = y0[b].copy()
            y[j] += step
            model.rhs(y, params[b], plus)
            y[j] -= 2 * step
            model.rhs(y, params[b], minus)
            jacobian[:, j] = (plus - minus) / (2 * step)
        rates[b] = float(np.max(np.abs(np.linalg.eigvals(jacobian))))
    return rates


# ----- the limit and the check --------------------------------------------------------------------

def stability_limit(scene: Scene, method: str, t_end: float | None = None) -> float:
    """Largest time step [s] at which `method` stays stable on every batch element of `scene`:
    stability_interval(method) / fastest_rate(scene); for euler, the step whose amplitude growth over
    t_end [s] (default scene.t_end) is EULER_GROWTH; inf where the scene has no rate (rolling) or the
    method no bound (reference). Event-driven scenes: inf (dt only samples them)."""
    if scene.event_driven:
        return math.inf
    beta = stability_interval(method)
    rate = float(np.max(fastest_rate(scene, method)))
    if rate == 0.0 or beta == math.inf:
        return math.inf
    if method == "euler":
        t_end = scene.t_end if t_end is None else float(t_end)
        return 2.0 * math.log(EULER_GROWTH) / (rate**2 * t_end)
    return beta / rate


def resolution_problem(scene: Scene, dt: float | None = None, t_end: float | None = None) -> str | None:
    """Why float64 time stepping cannot resolve `scene` over t_end [s] at step dt [s] (str), or None.

    Pendulums near the top only: 1 - k^2 is carried at the bottom of the swing only to ~eps (module
    docstring), and every step's rounding moves it by ~eps at random, sigma = eps sqrt(steps) over the
    run (measured: 0.13 eps sqrt(steps) for verlet, 0.3 for yoshida6). The run is refused when
    RESOLUTION_FACTOR sigma reaches |1 - k^2|: beyond it the round-off alone changes the period by
    ~ sigma / (2 |1 - k^2| K) or turns the swing into a whirl. Without dt, one step is assumed."""
    from rbody.scenes.pendulum import Pendulum

    if not isinstance(scene, Pendulum):
        return None
    t_end = scene.t_end if t_end is None else float(t_end)
    steps = 1 if dt is None else max(1, math.ceil(t_end / dt))
    drift = EPS * math.sqrt(steps)
    margin = np.abs(scene._one_minus_modulus())
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


def check_step(scene: Scene, method: str, dt: float, t_end: float | None = None) -> None:
    """Raise SimulationError, before any step, when dt [s] is beyond stability_limit(scene, method, t_end)
    or the scene is beyond float64's resolution (resolution_problem); return None otherwise."""
    if scene.event_driven or method == "reference":
        return
    problem = resolution_problem(scene, dt, t_end)
    if problem is not None:
        raise SimulationError(f"scene {scene.describe()}: method {method!r} cannot run it: {problem}")
    limit = stability_limit(scene, method, t_end)
    if dt > limit:
        rate = float(np.max(fastest_rate(scene, method)))
        if method == "euler":
            why = (f"euler has no stability interval (|1 + i dt w| > 1): at dt={dt:g} s the fastest linear mode "
                   f"(w = {rate:.6g} rad/s) grows by more than {EULER_GROWTH:g}x over t_end; its limit here is "
                   f"2 ln {EULER_GROWTH:g} / (w^2 t_end) = {limit:.6g} s")
        else:
            why = (f"dt={dt:g} s is beyond its estimated stability limit {limit:.6g} s = "
                   f"{stability_interval(method):.4g}"
                   f" / w, w = {rate:.6g} rad/s the fastest rate of the scene's linearised motion")
        raise SimulationError(f"scene {scene.describe()}: method {method!r}: {why}; use dt <= {limit:.6g} s")


__all__ = ["stability_interval", "yoshida6_interval", "fastest_rate", "stability_limit", "resolution_problem",
           "check_step", "EULER_GROWTH", "RESOLUTION_FACTOR"]
