"""The work-precision sweeps of `python -m validation bench` (validation/bench/__init__.py says what is
measured): one point, one series of dt, one scene."""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from typing import Mapping

import numpy as np

import rbody
from rbody.errors import SimulationError
from rbody.trajectory import Trajectory
from validation.tolerances import energy_error, max_abs_error, max_slip
from validation.backends import ENGINES, get, supports
from validation.bench.scenes import SAMPLES, BenchScene, Series, bench_scenes

LEVELS = (1e-3, 1e-6, 1e-9, 1e-12)
COLUMNS = ("run", "scene", "backend", "method", "settings", "dt", "error", "energy_drift", "seconds_per_sim_second",
           "stepping_seconds_per_sim_second", "steps_per_second", "repeats", "failure")
REPEATS = 5
# Timed runs per point stop early once they have taken this much wall time [s] (at least one always runs).
REPEAT_BUDGET = {False: 3.0, True: 0.2}
# A point whose run is predicted (from the previous, coarser point) to take longer is not run [s].
MAX_RUN_SECONDS = {False: 60.0, True: 5.0}
# A rolling body slips when max |slip| > SLIP_FRACTION x its peak exact speed: the rolling constraint is
# then broken by more than the distance error of 1e-3 (relative) the coarsest level asks for.
SLIP_FRACTION = 1e-3


@dataclass
class Point:
    """One row of bench.csv (COLUMNS)."""

    scene: str
    backend: str
    method: str
    settings: str
    dt: float
    error: float = math.nan
    energy_drift: float = math.nan
    seconds_per_sim_second: float = math.nan
    stepping_seconds_per_sim_second: float = math.nan
    steps_per_second: float = math.nan
    repeats: int = 0
    failure: str = ""
    run: int = 1


# ----- one point --------------------------------------------------------------------------------------

class Truth:
    """The exact solution at a run's sample times, or (bench.reference) rbody's reference run on the
    same time grid, computed once per grid."""

    def __init__(self, bench: BenchScene) -> None:
        self.bench = bench
        self._cache: dict[tuple, Mapping[str, np.ndarray]] = {}

    def at(self, t: np.ndarray) -> Mapping[str, np.ndarray]:
        scene = self.bench.scene
        key = (t.size, float(t[-1]))
        if key in self._cache:
            return self._cache[key]
        if not self.bench.reference:
            self._cache[key] = scene.exact(t)
        else:
            interval = float(t[-1]) / (t.size - 1)
            run = rbody.simulate(scene, dt=interval, t_end=float(t[-1]) * (1 - 1e-13), method="reference")
            if run.t.size != t.size:
                raise RuntimeError(f"reference grid of {run.t.size} samples does not match the run's {t.size}")
            self._cache[key] = run.data
        return self._cache[key]


def _failure(bench: BenchScene, trajectory: Trajectory, truth: Mapping[str, np.ndarray], error: float) -> str:
    """Why a finished run is not a valid point ("" when it is)."""
    if not np.isfinite(error):
        return "non-finite state or error"
    if bench.counted:
        got, want = int(trajectory["collisions"][-1]), int(truth["collisions"][-1])
        if got != want:
            return f"miscount: {got} impacts, exact {want}"
    if bench.rolling:
        slip = max_slip(trajectory)
        bound = SLIP_FRACTION * float(np.max(np.abs(truth["speed"])))
        if not slip <= bound:
            return f"slips: max |slip| {slip:.3g} m/s > {bound:.3g} m/s ({SLIP_FRACTION:g} of the peak speed)"
    return ""


def _runner(series: Series):
    """The function that runs a series' points: its own runner, else its backend's run."""
    return series.runner if series.runner is not None else get(series.backend).run


def measure(bench: BenchScene, series: Series, dt: float, truth: Truth, *, quick: bool, run: int = 1) -> Point:
    """Run one point: error and energy drift from the first run, cost the minimum over the timed runs of
    meta["run_seconds"] (the stepping with the making of the observables, on every backend), and the
    stepping alone (meta["step_seconds"]) beside it."""
    scene = bench.scene
    point = Point(bench.name, series.backend, series.method, series.settings, dt, run=run)
    event_driven = series.backend == "rbody" and scene.event_driven
    save_every = 1 if event_driven else max(1, round(scene.t_end / SAMPLES / dt))
    settings = series.kwargs(dt)
    seconds: list[float] = []
    stepping: list[float] = []
    started = time.perf_counter()
    trajectory = None
    with np.errstate(all="ignore"):  # a blow-up is reported as a failure below, not as a warning
        while len(seconds) < REPEATS and (not seconds or time.perf_counter() - started < REPEAT_BUDGET[quick]):
            try:
                trial = _runner(series)(scene, dt, None, save_every=save_every, **settings)
            except SimulationError as error:  # a non-finite state, or a step refused beyond the stability limit
                point.failure = f"unstable: {_first_line(error)}"
                return point
            except (ValueError, RuntimeError, ArithmeticError) as error:  # the simulator refused the settings
                point.failure = f"error: {type(error).__name__}: {_first_line(error)}"
                return point
            seconds.append(float(trial.meta["run_seconds"]))
            stepping.append(float(trial.meta["step_seconds"]))
            if trajectory is None:
                trajectory = trial
        truth_values = truth.at(trajectory.t)
        point.error = max_abs_error(trajectory, truth_values, bench.measure)
        point.energy_drift = energy_error(trajectory, truth_values)
        point.failure = _failure(bench, trajectory, truth_values, point.error)
    simulated = float(trajectory.t[-1])
    best = min(seconds)
    point.repeats = len(seconds)
    point.seconds_per_sim_second = best / simulated
    point.stepping_seconds_per_sim_second = min(stepping) / simulated
    if event_driven:  # "steps" of an event-driven run are its impacts
        point.steps_per_second = float(trajectory.meta.get("event_count", 0)) / best if best > 0 else math.inf
    else:
        point.steps_per_second = round(simulated / dt) / best if best > 0 else math.inf
    if not np.isfinite(point.error) and not point.failure:
        point.failure = "non-finite error"
    return point


def _first_line(error: BaseException) -> str:
    return str(error).splitlines()[0][:200] if str(error) else type(error).__name__


def run_series(bench: BenchScene, series: Series, truth: Truth, *, quick: bool, run: int = 1) -> list[Point]:
    """Every dt of a series, coarse to fine, after one warm-up run at the coarsest dt (not recorded); none for a
    backend that cannot run the scene (refusals gives its row, with the reason: e.g. its package not installed)."""
    if series.runner is None and not supports(bench.scene, series.backend)[0]:
        return []
    try:
        with np.errstate(all="ignore"):
            _runner(series)(bench.scene, series.dts[0], None, **series.kwargs(series.dts[0]))
    except (ValueError, RuntimeError, ArithmeticError):
        pass  # the point itself will report it
    points: list[Point] = []
    previous: tuple[float, float] | None = None  # (dt, wall seconds of the last point)
    for dt in series.dts:
        if previous is not None and previous[1] * previous[0] / dt > MAX_RUN_SECONDS[quick]:
            predicted = previous[1] * previous[0] / dt
            points.append(Point(bench.name, series.backend, series.method, series.settings, dt, run=run,
                                failure=f"not run: predicted {predicted:.0f} s > {MAX_RUN_SECONDS[quick]:g} s"))
            continue
        start = time.perf_counter()
        point = measure(bench, series, dt, truth, quick=quick, run=run)
        wall = (time.perf_counter() - start) / max(point.repeats, 1)
        previous = (dt, wall)
        points.append(point)
    return points


def run_scene(bench: BenchScene, *, quick: bool, log=None, run: int = 1, engines=None) -> list[Point]:
    """Every series of a scene, and one row per backend that refuses it (with its reason); run: the number
    of this run of the benchmark (1, 2, ...), written in every row; engines: only these backends' series."""
    points = refusals(bench, run=run, engines=engines)
    truth = Truth(bench)
    for series in bench.series:
        if engines is not None and series.backend not in engines:
            continue
        start = time.perf_counter()
        points += run_series(bench, series, truth, quick=quick, run=run)
        if log:
            print(f"  {bench.name}: {series.backend} {series.method} [{series.settings}] "
                  f"{time.perf_counter() - start:.1f} s", file=log, flush=True)
    return points


def refusals(bench: BenchScene, *, run: int = 1, engines=None) -> list[Point]:
    """One row per backend (of `engines`, default all) that cannot run the scene, with its reason."""
    points: list[Point] = []
    for backend in engines or ENGINES:
        ok, reason = supports(bench.scene, backend)
        if not ok:
            points.append(Point(bench.name, backend, "-", "-", math.nan, run=run,
                                failure=f"refused: {_first_line(Exception(reason))}"))
    return points


def series_task(quick: bool, scene_name: str, index: int, run: int = 1) -> list[Point]:
    """Series `index` of the bench scene `scene_name`, with its own truth: one task of a run on a Dask cluster
    (validation.cluster). The scenes are built here from their names (bench_scenes), so a task carries a few
    values, not the scenes and their settings' functions; the points are those run_scene gives."""
    bench = _benches(quick)[scene_name]
    return run_series(bench, bench.series[index], Truth(bench), quick=quick, run=run)


@functools.lru_cache(maxsize=2)
def _benches(quick: bool) -> dict[str, BenchScene]:
    """The bench scenes by name, built once per process (per worker)."""
    return {bench.name: bench for bench in bench_scenes(quick)}


def read_points(path) -> list[Point]:
    """The Points of a bench.csv (validation.bench.csvfile.read_csv); a file written before the `run` and
    `stepping_seconds_per_sim_second` columns existed gives run 1 and NaN."""
    from validation.bench.csvfile import read_csv

    points = []
    for row in read_csv(path):
        values = {name: row[name] for name in COLUMNS if name in row}
        values["run"] = int(values.get("run", 1))
        values["repeats"] = int(values.get("repeats", 0))
        points.append(Point(**values))
    return points
