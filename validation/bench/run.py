"""The command `python -m validation bench`: every chosen scene's sweeps, the batch and growth
measurements, the CSVs, the figures and summary.md."""

from __future__ import annotations

import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Iterable

from validation.bench import batch, growth, report
from validation.bench.csvfile import header_lines, write_csv
from validation.bench.scenes import bench_scenes
from validation.bench.sweep import COLUMNS, Point, refusals, run_scene, series_task
from validation.cluster import run_tasks

EXTRA_WORK = ("batch", "growth")
# --quick without --scene: the scenes that exercise every kind of truth and failure (the compound pendulum
# and the race repeat the rod and the disc), so that the smoke test stays under 2 minutes.
QUICK_DEFAULT = ("swinging_rod", "rolling_disc", "line_collisions", "pi_collisions", "free_rotation",
                 "pendulum_chain") + EXTRA_WORK


def run_bench(out: Path, *, names: Iterable[str] | None = None, quick: bool = False, log=sys.stderr,
              client=None) -> Path:
    """Run the benchmark into folder `out` and return the path of summary.md.

    names: scene names of bench_scenes() and/or "batch", "growth" (default: all of them; quick: QUICK_DEFAULT).
    client: a dask.distributed.Client, or None: each series (backend x method x setting, its sweep of dt) is
    then one timed task on its cluster, one at a time per worker (validation.cluster); the batch and growth
    measurements, which use every core, run here afterwards, with the cluster idle. bench.csv is the same.
    """
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
    if client is None:
        for bench in benches:
            if bench.name in names:
                print(f"[bench] {bench.name} ({bench.scene.describe()})", file=log, flush=True)
                points += run_scene(bench, quick=quick, log=log)
    else:
        points = _sweeps_on_cluster(client, [b for b in benches if b.name in names], quick=quick, log=log)
    csv_path = write_csv(out / "bench.csv", (asdict(p) for p in points), COLUMNS, header)
    figures = [report.plot_scene(points, b, out) for b in benches if b.name in names]
    batch_result = batch.run_batch(out, quick=quick, header=header, log=log) if "batch" in names else None
    growth_result = (growth.run_growth(out, quick=quick, header=header, batch=batch_result, log=log)
                     if "growth" in names else None)
    wall = time.perf_counter() - started
    path = report.write_summary(out, points, [b for b in benches if b.name in names], figures, batch_result,
                                growth_result, header, quick=quick, seconds=wall)
    print(f"[bench] {csv_path}\n[bench] {path} ({wall:.0f} s)", file=log)
    return path


def _sweeps_on_cluster(client, benches: list, *, quick: bool, log) -> list[Point]:
    """The points of run_scene for every bench scene, in the same order, each series a timed task."""
    tasks = [(f"{bench.name} {series.backend} {series.method} [{series.settings}]", series_task,
              (quick, bench.name, index)) for bench in benches for index, series in enumerate(bench.series)]
    results = iter(run_tasks(client, tasks, what="bench", timed=True, log=log))
    points: list[Point] = []
    for bench in benches:
        points += refusals(bench)
        for _ in bench.series:
            points += next(results)
    return points


def main(args) -> int:
    """Entry of `python -m validation bench` (args: scene, quick, out, workers, scheduler)."""
    from validation.cluster import connect

    with connect(args.scheduler, args.workers) as client:
        path = run_bench(args.out, names=args.scene, quick=args.quick, client=client)
    print(path.read_text())
    return 0
