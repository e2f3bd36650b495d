"""How well a step resolves the fastest motion of a scene: the accuracy threshold of each method, and the check.

Stability (rbody.engine.stability) says whether a run stays bounded; it does not say whether it is right. A
method stepping an oscillation y' = i w y at h w just inside its stability interval is bounded and wrong: rk4 at
a quarter of its limit (h w = 0.71) loses 1.6 % of the energy per period, and in a run of many periods all of it.

The measure. The fastest linear mode of a scene has angular frequency w (the rate the stability check finds).
One step of a method maps the oscillator's state (q, p) by a 2 x 2 matrix M(h w) (the exact flow: a rotation by
h w); after one period 2 pi / w, i.e. s = 2 pi / (h w) steps, the exact state is back where it started, and the
method's is M^s (a real power, through the eigenvalues). The period error is e(h w) = ||M^s - I||_2: the error
after one period, relative to the amplitude, counting amplitude (euler, rk4) and phase (all) alike.

The threshold of a method is the h w at which e = ACCURACY_TOLERANCE (1 %), found by bisection (from below, in
its stability interval) on its own step matrix:
    euler 0.00317, symplectic_euler 0.186, verlet 0.195, rk4 0.662, yoshida6 0.865, gauss6: none (e stays
    below 1 % up to its stability interval 2.32), splitting: verlet's (a second-order symmetric splitting),
    moreau, mujoco_euler, implicitfast and implicit: symplectic_euler's (their motion on an undamped oscillation),
    reference: none (adaptive, to rtol 1e-13).
Runge-Kutta methods (euler, rk4, gauss6) from their tableaux: R(z) = 1 + z b^T (I - z A)^-1 1 at z = i h w;
the symplectic ones (symplectic_euler, verlet and yoshida6, a composition of verlet steps) from their kicks and
drifts on q'' = -w^2 q. simulate warns (rbody.errors.AccuracyWarning) when dt w exceeds the threshold, with
both figures and the step that meets it; tests/rbody/engine/test_accuracy.py measures the period error of the
compiled methods on a stiff joint spring on both sides of each threshold.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from rbody.engine import integrators
from rbody.engine.methods import method as method_record

ACCURACY_TOLERANCE = 0.01  # error over one period of the fastest mode, relative to its amplitude
# Methods whose accuracy is another method's: a scene's splitting is second order and symmetric (verlet's).
# Moreau-Jean time-stepping (rbody.engine.constraints.stepping) moves a tree between impulses as symplectic Euler:
# v += h a(q, v), then q += h v.
# MuJoCo's integrators (rbody.engine.mujoco_steps) are semi-implicit Euler on an undamped oscillation (their implicit
# velocity terms only damp), and the rate they are checked against is the stiffness's.
SAME_AS = {"splitting": "verlet", "moreau": "symplectic_euler", "mujoco_euler": "symplectic_euler",
           "implicitfast": "symplectic_euler", "implicit": "symplectic_euler"}


def step_matrix(method: str, x: float) -> np.ndarray:
    """(2, 2) one step of `method` at h w = x on the oscillator q' = w p, p' = -w q, in (q, p)."""
    if method in ("euler", "rk4", "gauss6"):
        A, b = _tableau(method)
        z = -1j * x  # q + i p turns as exp(-i w t)
        stages = np.linalg.solve(np.eye(len(b)) - z * A, np.ones(len(b)))
        r = 1.0 + z * complex(b @ stages)
        return np.array([[r.real, -r.imag], [r.imag, r.real]])
    weights = {"symplectic_euler": None, "verlet": np.ones(1), "yoshida6": integrators.YOSHIDA6}[method]
    if weights is None:  # v += h a(q); q += h v
        return np.array([[1.0, x], [0.0, 1.0]]) @ np.array([[1.0, 0.0], [-x, 1.0]])
    matrix = np.eye(2)
    for w in weights:  # kick-drift-kick
        kick = np.array([[1.0, 0.0], [-0.5 * w * x, 1.0]])
        matrix = kick @ np.array([[1.0, w * x], [0.0, 1.0]]) @ kick @ matrix
    return matrix


def _tableau(method: str) -> tuple[np.ndarray, np.ndarray]:
    if method == "euler":
        return np.zeros((1, 1)), np.ones(1)
    if method == "rk4":
        A = np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]])
        return A, np.array([1, 2, 2, 1]) / 6.0
    return integrators.GAUSS6_A, integrators.GAUSS6_B


def period_error(method: str, x: float) -> float:
    """e(x) = ||M(x)^(2 pi / x) - I||_2: the method's error after one period of an oscillation stepped at h w = x,
    relative to its amplitude (module docstring)."""
    matrix = step_matrix(SAME_AS.get(method, method), x)
    values, vectors = np.linalg.eig(matrix)
    power = vectors @ np.diag(np.exp((2.0 * math.pi / x) * np.log(values.astype(complex)))) @ np.linalg.inv(vectors)
    return float(np.linalg.norm(power.real - np.eye(2), 2))


@lru_cache(maxsize=None)
def accuracy_threshold(method: str) -> float:
    """h w above which `method` carries one period of the fastest mode with more than ACCURACY_TOLERANCE error
    (module docstring); inf where no step inside the stability interval does (gauss6, reference)."""
    interval = method_record(method).interval  # ValueError for an unknown method
    if method == "reference" or interval == math.inf:
        return math.inf
    top = interval if interval > 0 else 1.0  # euler: no interval; its error passes 1 % long before h w = 1
    top *= 1.0 - 1e-9                          # inside the interval (at its edge the eigenvalues meet)
    if period_error(method, top) <= ACCURACY_TOLERANCE:
        return math.inf
    low, high = 0.0, top
    for _ in range(100):
        middle = 0.5 * (low + high)
        if period_error(method, middle) <= ACCURACY_TOLERANCE:
            low = middle
        else:
            high = middle
        if high - low <= 1e-12 * high:
            break
    return low


def accuracy_problem(method: str, dt: float, rate: float) -> str | None:
    """Why a run of `method` at step dt [s] resolves the fastest mode (rate w [1/s]) poorly (str), or None."""
    threshold = accuracy_threshold(method)
    if not rate > 0 or threshold == math.inf or dt * rate <= threshold:
        return None
    return (f"dt * w = {dt * rate:.3g} (dt={dt:g} s, w = {rate:.6g} rad/s the fastest rate of the scene's linearised "
            f"motion) is beyond {method}'s accuracy threshold {threshold:.3g}: one period of that mode is carried "
            f"with {period_error(method, dt * rate):.2g} error (relative to its amplitude; {ACCURACY_TOLERANCE:.0%} "
            f"at the threshold). Use dt <= {threshold / rate:.3g} s, a method of higher order, or ask simulate for "
            "an error estimate (error_estimate=True)")


__all__ = ["ACCURACY_TOLERANCE", "accuracy_threshold", "accuracy_problem", "period_error", "step_matrix"]
