"""Speed against error: the work-precision benchmark of rbody, MuJoCo and pymunk.

    python -m validation bench [--scene NAME ...] [--quick] [--out DIR]

For every scene of validation/bench_scenes.py, every backend that can run it and each of its
methods or settings, a sweep of dt; at each point

    error  = max over the run of |x(t) - x*(t)| of the scene's main observable (compare.max_abs_error),
             x* the exact solution (the chain: rbody's DOP853 reference run at rtol 1e-13)
    drift  = compare.energy_error: max |E - E*| / max |E*|
    cost   = seconds of stepping per simulated second: meta["step_seconds"] / simulated time, after one
             warm-up run per series, the minimum of up to REPEATS runs (fewer when a run is long: the
             `repeats` column says how many)

A run that blows up or is refused as beyond the stability limit (SimulationError: "unstable"), miscounts
impacts or slips is a row with its `failure` reason, never dropped. What each backend's step_seconds holds: rbody the whole simulate call
after its kernels are compiled (stepping and the observables); MuJoCo the mujoco.rollout calls alone;
pymunk the space.step calls alone (so MuJoCo's and pymunk's translation of states into observables is
free here and rbody's is not).

Outputs in DIR: bench.csv (every point; machine and versions in '#' lines), wp_<scene>.png (work-
precision and energy panels), batch.csv and growth.csv (validation.bench_batch, bench_growth), their
figures, and summary.md (validation.bench_report).
"""

from __future__ import annotations

import csv
import math
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

import rbody
from rbody.errors import SimulationError
from rbody.trajectory import Trajectory
from validation import compare
from validation.backends import BACKENDS, get, supports
from validation.bench_scenes import SAMPLES, BenchScene, Series, bench_scenes

LEVELS = (1e-3, 1e-6, 1e-9, 1e-12)
COLUMNS = ("scene", "backend", "method", "settings", "dt", "error", "energy_drift", "seconds_per_sim_second",
           "steps_per_second", "repeats", "failure")
REPEATS = 5
# Timed runs per point stop early once they have taken this much wall time [s] (at least one always runs).
REPEAT_BUDGET = {False: 3.0, True: 0.2}
# A point whose run is predicted (from the previous, coarser point) to take longer is not run [s].
MAX_RUN_SECONDS = {False: 60.0, True: 5.0}
# A rolling body slips when max |slip| > SLIP_FRACTION x its peak exact speed: the rolling constraint is
# then broken by more than the distance error of 1e-3 (relative) the coarsest level asks for.
SLIP_FRACTION = 1e-3
EXTRA_WORK = ("batch", "growth")
# --quick without --scene: the scenes that exercise every kind of truth and failure (the compound pendulum
# and the race repeat the rod and the disc), so that the smoke test stays under 2 minutes.
QUICK_DEFAULT = ("swinging_rod", "rolling_disc", "line_collisions", "pi_collisions", "free_rotation",
                 "pendulum_chain") + EXTRA_WORK


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
    steps_per_second: float = math.nan
    repeats: int = 0
    failure: str = ""


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
        slip = compare.max_slip(trajectory)
        bound = SLIP_FRACTION * float(np.max(np.abs(truth["speed"])))
        if not slip <= bound:
            return f"slips: max |slip| {slip:.3g} m/s > {bound:.3g} m/s ({SLIP_FRACTION:g} of the peak speed)"
    return ""


def measure(bench: BenchScene, series: Series, dt: float, truth: Truth, *, quick: bool) -> Point:
    """Run one point: error and energy drift from the first run, cost the minimum over the timed runs."""
    scene = bench.scene
    point = Point(bench.name, series.backend, series.method, series.settings, dt)
    event_driven = series.backend == "rbody" and scene.event_driven
    save_every = 1 if event_driven else max(1, round(scene.t_end / SAMPLES / dt))
    settings = series.kwargs(dt)
    seconds: list[float] = []
    started = time.perf_counter()
    trajectory = None
    with np.errstate(all="ignore"):  # a blow-up is reported as a failure below, not as a warning
        while len(seconds) < REPEATS and (not seconds or time.perf_counter() - started < REPEAT_BUDGET[quick]):
            try:
                run = get(series.backend).run(scene, dt, None, save_every=save_every, **settings)
            except SimulationError as error:  # a non-finite state, or a step refused beyond the stability limit
                point.failure = f"unstable: {_first_line(error)}"
                return point
            except (ValueError, RuntimeError, ArithmeticError) as error:  # the simulator refused the settings
                point.failure = f"error: {type(error).__name__}: {_first_line(error)}"
                return point
            seconds.append(float(run.meta["step_seconds"]))
            if trajectory is None:
                trajectory = run
        truth_values = truth.at(trajectory.t)
        point.error = compare.max_abs_error(trajectory, truth_values, bench.measure)
        point.energy_drift = compare.energy_error(trajectory, truth_values)
        point.failure = _failure(bench, trajectory, truth_values, point.error)
    simulated = float(trajectory.t[-1])
    best = min(seconds)
    point.repeats = len(seconds)
    point.seconds_per_sim_second = best / simulated
    if event_driven:  # "steps" of an event-driven run are its impacts
        point.steps_per_second = float(trajectory.meta.get("event_count", 0)) / best if best > 0 else math.inf
    else:
        point.steps_per_second = round(simulated / dt) / best if best > 0 else math.inf
    if not np.isfinite(point.error) and not point.failure:
        point.failure = "non-finite error"
    return point


def _first_line(error: BaseException) -> str:
    return str(error).splitlines()[0][:200] if str(error) else type(error).__name__


def run_series(bench: BenchScene, series: Series, truth: Truth, *, quick: bool) -> list[Point]:
    """Every dt of a series, coarse to fine, after one warm-up run at the coarsest dt (not recorded)."""
    try:
        with np.errstate(all="ignore"):
            get(series.backend).run(bench.scene, series.dts[0], None, **series.kwargs(series.dts[0]))
    except (ValueError, RuntimeError, ArithmeticError):
        pass  # the point itself will report it
    points: list[Point] = []
    previous: tuple[float, float] | None = None  # (dt, wall seconds of the last point)
    for dt in series.dts:
        if previous is not None and previous[1] * previous[0] / dt > MAX_RUN_SECONDS[quick]:
            predicted = previous[1] * previous[0] / dt
            points.append(Point(bench.name, series.backend, series.method, series.settings, dt,
                                failure=f"not run: predicted {predicted:.0f} s > {MAX_RUN_SECONDS[quick]:g} s"))
            continue
        start = time.perf_counter()
        point = measure(bench, series, dt, truth, quick=quick)
        wall = (time.perf_counter() - start) / max(point.repeats, 1)
        previous = (dt, wall)
        points.append(point)
    return points


def run_scene(bench: BenchScene, *, quick: bool, log=None) -> list[Point]:
    """Every series of a scene, and one row per backend that refuses it (with its reason)."""
    points: list[Point] = []
    for backend in BACKENDS:
        ok, reason = supports(bench.scene, backend)
        if not ok:
            points.append(Point(bench.name, backend, "-", "-", math.nan,
                                failure=f"refused: {_first_line(Exception(reason))}"))
    truth = Truth(bench)
    for series in bench.series:
        start = time.perf_counter()
        points += run_series(bench, series, truth, quick=quick)
        if log:
            print(f"  {bench.name}: {series.backend} {series.method} [{series.settings}] "
                  f"{time.perf_counter() - start:.1f} s", file=log, flush=True)
    return points


# ----- the CSV ------------------------------------------------------------------------------------------

def header_lines(quick: bool) -> list[str]:
    """Machine, versions and mode: the '#' lines at the top of every CSV of the benchmark."""
    from validation.baselines import versions
    from validation.machine import describe_machine

    return [f"machine: {describe_machine()}",
            "versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()),
            f"mode: {'quick' if quick else 'full'}; load average at start: {_load()}",
            "error: max abs error of the scene's main observable over the run [its unit]; energy_drift: "
            "max |E - E*| / max |E*|; seconds_per_sim_second: min over `repeats` timed runs; event-driven "
            "rows count impacts as steps"]


def _load() -> str:
    try:
        with open("/proc/loadavg") as f:
            return " ".join(f.read().split()[:3])
    except OSError:
        return "unknown"


def write_csv(path: Path, rows: Iterable[Mapping], columns: tuple[str, ...], header: list[str]) -> Path:
    with open(path, "w", newline="") as f:
        for line in header:
            f.write(f"# {line}\n")
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(row[k]) for k in columns})
    return path


def _cell(value) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    return str(value)


def read_csv(path: Path) -> list[dict]:
    """Rows of a benchmark CSV (the '#' lines skipped), numbers as floats."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    for row in rows:
        for key, value in row.items():
            try:
                row[key] = float(value) if key not in ("scene", "backend", "method", "settings", "failure") else value
            except ValueError:
                pass
    return rows


# ----- the command --------------------------------------------------------------------------------------

def run_bench(out: Path, *, names: Iterable[str] | None = None, quick: bool = False, log=sys.stderr) -> Path:
    """Run the benchmark into folder `out` and return the path of summary.md.

    names: scene names of bench_scenes() and/or "batch", "growth" (default: all of them; quick: QUICK_DEFAULT).
    """
    from validation import bench_batch, bench_growth, bench_report

    benches = bench_scenes(quick)
    known = [b.name for b in benches] + list(EXTRA_WORK)
    names = list(names) if names else list(QUICK_DEFAULT if quick else known)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"--scene {', '.join(unknown)}: expected one of {', '.join(known)}")
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    header = header_lines(quick)
    points: list[Point] = []
    for bench in benches:
        if bench.name in names:
            print(f"[bench] {bench.name} ({bench.scene.describe()})", file=log, flush=True)
            points += run_scene(bench, quick=quick, log=log)
    csv_path = write_csv(out / "bench.csv", (asdict(p) for p in points), COLUMNS, header)
    figures = [bench_report.plot_scene(points, b, out) for b in benches if b.name in names]
    batch = bench_batch.run_batch(out, quick=quick, header=header, log=log) if "batch" in names else None
    growth = (bench_growth.run_growth(out, quick=quick, header=header, batch=batch, log=log)
              if "growth" in names else None)
    wall = time.perf_counter() - started
    path = bench_report.write_summary(out, points, [b for b in benches if b.name in names], figures, batch, growth,
                                      header, quick=quick, seconds=wall)
    print(f"[bench] {csv_path}\n[bench] {path} ({wall:.0f} s)", file=log)
    return path


def main(args) -> int:
    """Entry of `python -m validation bench` (args: scene, quick, out)."""
    path = run_bench(args.out, names=args.scene, quick=args.quick)
    print(path.read_text())
    return 0
