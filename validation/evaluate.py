"""Run a case in each backend and measure it against the exact solution.

A Case is one scene at documented default settings, with the metrics that judge it. `evaluate`
runs it in every backend that can express it and returns one Row per (backend, metric), plus the
trajectories for the report's figures. Backends that refuse a scene give a row that says why;
backends that fail (blow up, raise) give a row that says how: nothing is dropped.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

import rbody
from rbody.trajectory import Trajectory
from validation.tolerances import (energy_error, final_relative_error, max_abs_error, max_slip, pi_digits_right,
                                tolerance)
from validation.backends import BACKENDS, get


@dataclass(frozen=True)
class Case:
    """One scene of the main command.

    name:      row label (also the baseline key)
    family:    key into validation.tolerances.TOLERANCES
    scene:     the scene to run (unbatched)
    dt:        backend -> time step [s]
    settings:  backend -> keyword settings for its run()
    metrics:   names of the measures in METRICS
    reference: for a scene with no closed form, the trajectory every backend is compared with is a
               tight native run with this method (else scene.exact)
    skipped:   backend -> why the main command does not run it on this case (a refused row with the reason)
    """

    name: str
    family: str
    scene: Any
    dt: Mapping[str, float]
    metrics: tuple[str, ...]
    settings: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    reference: str | None = None
    reference_dt: float | None = None
    skipped: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Row:
    """One measured value: verdict is "ok", "FINDING" (outside tolerance), "refused" or "failed";
    seconds is the wall time of the stepping."""

    case: str
    backend: str
    metric: str
    value: float | None
    tolerance: float | None
    verdict: str
    seconds: float
    note: str = ""


def _truth(case: Case, trajectory: Trajectory) -> Mapping[str, np.ndarray]:
    if case.reference is None:
        return case.scene.exact(trajectory.t)
    reference = rbody.simulate(case.scene, dt=case.reference_dt or case.dt["rbody"], method=case.reference)
    return _resample(reference, trajectory.t)


def _resample(reference: Trajectory, t: np.ndarray) -> dict[str, np.ndarray]:
    """Reference observables at times t (linear interpolation; the reference is sampled finely)."""
    out = {}
    for name in reference.observables:
        values = reference[name].reshape(reference.t.size, -1)
        columns = [np.interp(t, reference.t, values[:, k]) for k in range(values.shape[1])]
        out[name] = np.stack(columns, axis=-1).reshape((t.size,) + reference[name].shape[1:])
    return out


def _measure(metric: str, case: Case, trajectory: Trajectory, truth: Mapping[str, np.ndarray]) -> float:
    main = case.scene.main_observable
    if metric == "max_abs_error":
        return max_abs_error(trajectory, truth, main)
    if metric == "final_relative_error":
        return final_relative_error(trajectory, truth, main)
    if metric == "energy_error":
        return energy_error(trajectory, truth)
    if metric == "max_slip":
        return max_slip(trajectory)
    if metric == "count_error":
        return float(int(trajectory["collisions"][-1]) - int(case.scene.expected_collisions))
    if metric == "pi_digits":
        return float(pi_digits_right(int(trajectory["collisions"][-1]), case.scene.digits))
    if metric == "arrival_error":
        return float(np.max(np.abs(trajectory["arrival_time"] - truth["arrival_time"])
                            / truth["arrival_time"]))
    raise ValueError(f"metric={metric!r}: not a known measure")


def evaluate(case: Case, backends: tuple[str, ...] = BACKENDS) -> tuple[list[Row], dict[str, Trajectory]]:
    """Rows for every (backend, metric) of `case`, and the trajectories that were produced."""
    rows: list[Row] = []
    runs: dict[str, Trajectory] = {}
    for backend in backends:
        if backend in case.skipped:
            rows.append(Row(case.name, backend, "-", None, None, "refused", 0.0, case.skipped[backend]))
            continue
        try:
            module = get(backend)  # NotImplementedError: the engine's package is not installed
            module.check(case.scene)
        except NotImplementedError as reason:
            rows.append(Row(case.name, backend, "-", None, None, "refused", 0.0, str(reason)))
            continue
        start = time.perf_counter()
        try:
            trajectory = module.run(case.scene, case.dt[backend], None, **case.settings.get(backend, {}))
        except Exception as error:  # a blow-up or a simulator error is a result to report
            rows.append(Row(case.name, backend, "-", None, None, "failed", time.perf_counter() - start,
                            f"{type(error).__name__}: {error}"))
            continue
        # The stepping alone where the backend measured it (no compile, no model building).
        seconds = float(trajectory.meta.get("step_seconds", time.perf_counter() - start))
        runs[backend] = trajectory
        # The exact observables only where a metric compares with them (a count needs none).
        needs_truth = any(metric not in ("count_error", "pi_digits", "max_slip") for metric in case.metrics)
        truth = _truth(case, trajectory) if needs_truth else {}
        for metric in case.metrics:
            value = _measure(metric, case, trajectory, truth)
            bound = tolerance(case.family, backend, metric)
            if metric == "pi_digits":
                verdict = "ok" if value == case.scene.digits + 1 else "FINDING"
            elif bound is None:
                verdict = "-"
            else:
                verdict = "ok" if abs(value) <= bound.value else "FINDING"
            rows.append(Row(case.name, backend, metric, value, None if bound is None else bound.value,
                            verdict, seconds, "" if bound is None else bound.reason))
    return rows, runs
