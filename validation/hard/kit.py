"""What every time-stepped hard case measures: a backend's run timed by its own stepping, rbody's verdict
against its stability estimate, drift envelopes, zero crossings and periods, bounded energy, and the
coarsest step that passes (a search by bisection under a budget of stepping time)."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

import rbody
import validation
from rbody import stability
from validation.hard.rows import attempt

EPS = float(np.finfo(np.float64).eps)


def run_backend(scene, backend: str, dt: float, **settings):
    """(trajectory or None, error or None, seconds): validation.run, timed by the backend's own stepping
    time where it reports one."""
    trajectory, error, seconds = attempt(validation.run, scene, backend, dt=dt, **settings)
    if trajectory is not None:
        seconds = float(trajectory.meta.get("step_seconds", seconds))
    return trajectory, error, seconds


def refusal_expected(scene, method: str, dt: float, t_end: float | None = None) -> str | None:
    """rbody's own estimate (rbody.stability.check_step): the message with which rbody should refuse
    this run, or None when it should run it."""
    try:
        stability.check_step(scene, method, dt, t_end)
    except rbody.SimulationError as error:
        return str(error)
    return None


def rbody_verdict(scene, method: str, dt: float, t_end: float | None, outcome: str, wrong: str = "") -> tuple[str, str]:
    """(verdict, reason) of an rbody run: refused is right when rbody's estimate refuses it (and a
    refusal inside the estimate is a false alarm); a returned run is a FAIL when the estimate says it
    should have been refused, or when `wrong` says it is qualitatively wrong."""
    expected = refusal_expected(scene, method, dt, t_end)
    if outcome in ("refused", "blew up"):
        if expected is None:
            return "FAIL", "rbody stopped a run inside its own stability estimate (a false alarm)"
        return ("pass", "") if outcome == "refused" else ("FAIL", "rbody ran into the failure instead of refusing "
                                                          f"before the first step: {expected}")
    if expected is not None:
        return "FAIL", f"rbody returned a run it should refuse: {expected}"
    if wrong:
        return "FAIL", wrong
    return "pass", ""


def envelope(x: np.ndarray, y: np.ndarray, bins: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """Max of |y| over log-spaced bins of x > 0: a drift curve small enough to draw."""
    x, y = np.asarray(x, float), np.abs(np.asarray(y, float))
    keep = x > 0
    x, y = x[keep], y[keep]
    if x.size == 0:
        return x, y
    edges = np.geomspace(x[0], x[-1] * (1 + 1e-12), bins + 1)
    index = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    top = np.full(bins, -1.0)
    np.maximum.at(top, index, y)
    centres = np.sqrt(edges[:-1] * edges[1:])
    used = top >= 0
    return centres[used], top[used]


def upward_crossings(t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Times where q crosses 0 upwards, from samples of q and q' = v: the cubic Hermite interpolant on
    each bracketing interval, solved by Newton's method from the linear guess."""
    i = np.flatnonzero((q[:-1] < 0) & (q[1:] >= 0))
    if i.size == 0:
        return np.empty(0)
    h = t[i + 1] - t[i]
    q0, q1, d0, d1 = q[i], q[i + 1], v[i] * h, v[i + 1] * h
    s = -q0 / (q1 - q0)
    for _ in range(8):
        s2, s3 = s * s, s * s * s
        p = (2 * s3 - 3 * s2 + 1) * q0 + (s3 - 2 * s2 + s) * d0 + (-2 * s3 + 3 * s2) * q1 + (s3 - s2) * d1
        dp = (6 * s2 - 6 * s) * q0 + (3 * s2 - 4 * s + 1) * d0 + (-6 * s2 + 6 * s) * q1 + (3 * s2 - 2 * s) * d1
        s = np.clip(s - p / np.where(dp == 0, 1.0, dp), 0.0, 1.0)
    return t[i] + s * h


def mean_period(t: np.ndarray, q: np.ndarray, v: np.ndarray) -> tuple[float, int]:
    """Mean interval between upward zero crossings of q [s] (nan with fewer than two) and their count."""
    crossings = upward_crossings(t, q, v)
    if crossings.size < 2:
        return float("nan"), int(crossings.size)
    return float((crossings[-1] - crossings[0]) / (crossings.size - 1)), int(crossings.size)


def energy_bounded(energy: np.ndarray, steps: int) -> bool:
    """The energy error over the whole run stays within twice that of its first quarter (plus the round-off
    random walk, 8 eps sqrt(steps) |E0|): bounded, not drifting (a linear drift gives 4 times)."""
    error = np.abs(energy - energy[0])
    quarter = max(2, energy.size // 4)
    allowance = 8 * EPS * math.sqrt(max(steps, 1)) * abs(energy[0])
    return float(np.max(error)) <= 2.0 * float(np.max(error[:quarter])) + allowance


def coarsest_step(passes: Callable[[float], tuple[bool, float]], coarse: float, t_end: float, budget: float,
                  cost_per_step: float, *, factor: float = 10.0, resolution: float = 2.0
                  ) -> tuple[float | None, list[tuple[float, bool, float]]]:
    """The coarsest time step at which `passes` holds, found by the same rule for every engine: from `coarse`
    [s] down by `factor` until a run passes, the finest step tried being the one whose run is predicted to
    take `budget` seconds of stepping; then bisection in log dt between the last failing and the first passing
    step until they are within `resolution` of each other.

    passes(dt) -> (passed, seconds of stepping); a run of t_end [s] takes ceil(t_end / dt) steps, predicted at
    cost_per_step [s] (then measured, from runs of at least 10^4 steps). Returns (the coarsest passing dt or
    None when none passed within the budget, every trial as (dt, passed, seconds) in the order run)."""
    if not (coarse > 0 and t_end > 0 and budget > 0 and cost_per_step > 0 and factor > 1 and resolution > 1):
        raise ValueError(f"coarse={coarse!r}, t_end={t_end!r}, budget={budget!r}, cost_per_step={cost_per_step!r}, "
                         f"factor={factor!r}, resolution={resolution!r}: expected positive values, factor and "
                         "resolution > 1")
    trials: list[tuple[float, bool, float]] = []
    cost = cost_per_step

    def trial(dt: float) -> bool:
        nonlocal cost
        passed, seconds = passes(dt)
        steps = math.ceil(t_end / dt * (1 - 1e-12))
        if steps >= 10_000 and seconds > 0:
            cost = seconds / steps
        trials.append((dt, passed, seconds))
        return passed

    dt, failing, at_budget = coarse, None, False
    while not trial(dt):
        failing = dt
        finest = t_end * cost / budget  # the step whose run takes the budget
        if at_budget or finest >= dt * (1 - 1e-9):  # the run at the budget failed too, or no finer step fits
            return None, trials
        at_budget = dt / factor <= finest
        dt = max(dt / factor, finest)
    passing = dt
    while failing is not None and failing / passing > resolution:
        middle = math.sqrt(failing * passing)
        if trial(middle):
            passing = middle
        else:
            failing = middle
    return passing, trials
