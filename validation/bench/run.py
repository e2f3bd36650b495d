"""The command `python -m validation bench`: every chosen scene's sweeps, the batch and growth
measurements, the CSVs, the figures and summary.md."""

from __future__ import annotations

import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Iterable

from rbody.files import replaced_folder
from validation.bench import batch, growth, report
from validation.bench.csvfile import header_lines, write_csv
from validation.bench.scenes import bench_scenes
from validation.bench.sweep import COLUMNS, Point, refusals, run_scene, series_task
from validation.cluster import run_tasks

EXTRA_WORK = ("batch", "growth")
# --quick without --scene: the scenes that exercise every kind of truth and failure (the compound pendulum
# and the race repeat the rod and the disc), so that the smoke test stays under 2 minutes.
QUICK_DEFAULT = ("swinging_rod", "rolling_disc", "line_collisions", "pi_collisions", "free_rotation",
                 "pendulum_chain", "chain_general") + EXTRA_WORK


def run_bench(out: Path, *, names: Iterable[str] | None = None, quick: bool = False, repeat: int = 1,
              log=sys.stderr, client=None, engines: Iterable[str] | None = None) -> Path:
    """Run the benchmark into folder `out` and return the path of summary.md.

    names: scene names of bench_scenes() and/or "batch", "growth" (default: all of them; quick: QUICK_DEFAULT).
    repeat: how many times every sweep is run (the `run` column of bench.csv); the summary gives each
    ratio's median and its range over the runs. Batch and growth are measured once.
    engines: only these backends' series (default: every engine's; e.g. the peers alone, beside a full run);
    client: a dask.distributed.Client, or None: each series (backend x method x setting, its sweep of dt) of
    each run is then one timed task on its cluster, one at a time per worker (validation.cluster); the batch
    and growth measurements, which use every core, run here afterwards, with the cluster idle. bench.csv
    holds the same points either way (timings aside).
    """
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise ValueError(f"repeat={repeat!r}: expected a whole number >= 1")
    from validation.backends import ENGINES

    engines = tuple(engines) if engines else None
    if engines is not None and (not engines or any(e not in ENGINES for e in engines)):
        raise ValueError(f"engines={list(engines)}: expected engines among {', '.join(ENGINES)}")
    benches = bench_scenes(quick)
    known = [b.name for b in benches] + list(EXTRA_WORK)
    names = list(names) if names else list(QUICK_DEFAULT if quick else known)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"--scene {', '.join(unknown)}: expected one of {', '.join(known)}")
    started = time.perf_counter()
    header = header_lines(quick)
    points: list[Point] = []
    with replaced_folder(out) as staging:  # the CSVs, figures and summary all new, or all as they were
        if client is None:
            for run in range(1, repeat + 1):
                for bench in benches:
                    if bench.name in names:
                        print(f"[bench] run {run} of {repeat}: {bench.name} ({bench.scene.describe()})", file=log,
                              flush=True)
                        points += run_scene(bench, quick=quick, log=log, run=run, engines=engines)
        else:
            points = _sweeps_on_cluster(client, [b for b in benches if b.name in names], quick=quick, repeat=repeat,
                                        log=log, engines=engines)
        csv_name = write_csv(staging / "bench.csv", (asdict(p) for p in points), COLUMNS, header).name
        figures = [report.plot_scene(points, b, staging) for b in benches if b.name in names]
        batch_result = batch.run_batch(staging, quick=quick, header=header, log=log) if "batch" in names else None
        growth_result = (growth.run_growth(staging, quick=quick, header=header, batch=batch_result, log=log)
                         if "growth" in names else None)
        wall = time.perf_counter() - started
        name = report.write_summary(staging, points, [b for b in benches if b.name in names], figures,
                                    batch_result, growth_result, header, quick=quick, seconds=wall).name
    path = out / name
    print(f"[bench] {out / csv_name}\n[bench] {path} ({wall:.0f} s)", file=log)
    return path


def _sweeps_on_cluster(client, benches: list, *, quick: bool, repeat: int, log, engines=None) -> list[Point]:
    """The points of run_scene for every run and bench scene, in the same order, each series a timed task."""
    def chosen(bench):
        return [(index, series) for index, series in enumerate(bench.series)
                if engines is None or series.backend in engines]

    tasks = [(f"run {run}: {bench.name} {series.backend} {series.method} [{series.settings}]", series_task,
              (quick, bench.name, index, run))
             for run in range(1, repeat + 1) for bench in benches for index, series in chosen(bench)]
    results = iter(run_tasks(client, tasks, what="bench", timed=True, log=log))
    points: list[Point] = []
    for run in range(1, repeat + 1):
        for bench in benches:
            points += refusals(bench, run=run, engines=engines)
            for _ in chosen(bench):
                points += next(results)
    return points


def main(args) -> int:
    """Entry of `python -m validation bench` (args: scene, quick, out, repeat, workers, scheduler)."""
    from validation.cluster import connect

    with connect(getattr(args, "scheduler", None), getattr(args, "workers", None)) as client:
        path = run_bench(args.out, names=args.scene, quick=args.quick, repeat=getattr(args, "repeat", 1),
                         client=client, engines=getattr(args, "engine", None))
    print(path.read_text())
    return 0
