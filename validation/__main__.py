"""python -m validation [run] | export | bench | hard | compare MODEL — see `python -m validation --help`."""

from __future__ import annotations

import argparse
import errno
import sys
import time
from pathlib import Path

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m validation",
        usage="%(prog)s [run | export | bench | hard | compare MODEL] [options]",
        description="Run rbody's scenes in rbody, MuJoCo, pymunk, Pinocchio and Bullet and compare each with the exact solution.",
        epilog="Exit status: 0 all measures within their baselines; 1 a regression (a measure worse than its "
               "baseline); 2 a problem with the inputs, found before the run where it can be (a bad argument, "
               "--out not writable, a broken baseline file) or after it (a measure with no baseline: run "
               "--update-baselines).")
    commands = parser.add_subparsers(dest="command")
    run = commands.add_parser(
        "run", prog="python -m validation run", usage="%(prog)s [options]",
        help="every scene in every backend (the default command)")
    for p in (parser, run):
        p.add_argument("--out", type=Path, default=Path("report"), help="report folder (default: report/)")
        p.add_argument("--quick", action="store_true", help="short runs (a smoke test)")
        p.add_argument("--update-baselines", action="store_true",
                       help="rewrite validation/baselines/ from this run")
        p.add_argument("--backend", action="append", choices=("rbody", "mujoco", "pymunk", "pinocchio", "bullet"),
                       help="only these backends (repeatable; default: all five)")
    export = commands.add_parser(
        "export", prog="python -m validation export", usage="%(prog)s [options]",
        help="write the MJCF of every scene into models/")
    export.add_argument("--out", type=Path, default=MODELS_DIR, help="folder (default: models/)")
    bench = commands.add_parser(
        "bench", prog="python -m validation bench", usage="%(prog)s [options]",
        help="speed against error: work-precision sweeps (validation/bench/)")
    bench.add_argument("--scene", action="append", metavar="NAME",
                       help="only this scene, or 'batch' or 'growth' (repeatable; default: all)")
    bench.add_argument("--quick", action="store_true", help="short sweeps, under 2 minutes (the test suite's)")
    bench.add_argument("--out", type=Path, default=Path("report/bench"), help="folder (default: report/bench/)")
    bench.add_argument("--engine", action="append", choices=("rbody", "mujoco", "pymunk", "pinocchio", "bullet"),
                       help="only this engine's series (repeatable; default: every engine's)")
    bench.add_argument("--repeat", type=int, default=1, metavar="N",
                       help="run every sweep N times; the summary gives each ratio with its range (default: 1)")
    hard = commands.add_parser(
        "hard", prog="python -m validation hard", usage="%(prog)s [options]",
        help="numerical stability on hard cases (validation/hard/): DIR/hard.md")
    hard.add_argument("--quick", action="store_true", help="short runs, under 2 minutes")
    hard.add_argument("--out", type=Path, default=Path("report"), help="report folder (default: report/)")
    hard.add_argument("--case", action="append", type=int, metavar="N", help="only case N of 1..10 (repeatable)")
    compare = commands.add_parser(
        "compare", prog="python -m validation compare", usage="%(prog)s MODEL [options]",
        help="one model in every engine that can express it: where they diverge (validation/comparison.py)")
    compare.add_argument("model", help="an MJCF file, a URDF file, or 'module:name' / 'file.py:name' naming an rbody "
                                       "Scene")
    compare.add_argument("--t-end", type=float, metavar="S", help="duration [s] (default: the model's)")
    compare.add_argument("--no-constraints", action="store_true",
                         help="a URDF's limits, friction and mimics recorded, not applied (as Pinocchio's aba runs it)")
    compare.add_argument("--dt", type=float, metavar="S", help="time step [s] (default: the model's timestep, else 1e-3)")
    compare.add_argument("--method", metavar="M", help="rbody's method (default: an MJCF file's own integrator, "
                         "else rk4 where it applies)")
    compare.add_argument("--engines", default=None,
                         help="comma-separated engines of rbody,mujoco,pymunk,pinocchio,bullet, or 'all' (default: "
                              "rbody,mujoco,pymunk; every engine for a URDF file)")
    compare.add_argument("--out", type=Path, default=Path("report/compare"), help="folder (default: report/compare/)")
    compare.add_argument("--baseline", type=Path, metavar="DIR", help="check the divergences against this folder")
    compare.add_argument("--update-baseline", action="store_true", help="record this run's divergences in --baseline")
    compare.add_argument("--animate", action="store_true",
                         help="also write the animation of every engine's run, side by side, into the report "
                              "(DIR/<model>_motion.gif, rbody.animate)")
    compare.add_argument("--keyframe", metavar="K", help="MJCF file: start from this keyframe (index or name)")
    compare.add_argument("--qpos0", metavar='"Q ..."', help="MJCF file: initial qpos, numbers separated by spaces")
    compare.add_argument("--qvel0", metavar='"V ..."', help="MJCF file: initial qvel, numbers separated by spaces")
    compare.add_argument("--ctrl", metavar="FILE.npy|module:function",
                         help="MJCF file: the controls of every engine, an array (nu,) or (n_steps, nu), or a "
                              "function ctrl(t, qpos, qvel) -> (nu,)")
    compare.add_argument("--overlapping-geoms", action="store_true",
                         help="MJCF file: let rbody sum overlapping geoms' masses as MuJoCo does")
    for p in (parser, run, bench, hard, compare):
        _cluster_options(p)
    return parser


def _cluster_options(parser: argparse.ArgumentParser) -> None:
    """--workers N | --scheduler ADDRESS: the independent runs as tasks on a Dask cluster (validation/cluster.py)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, metavar="N",
                       help="run on a local Dask cluster of N worker processes, one thread each")
    group.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on the Dask cluster whose scheduler is at ADDRESS (e.g. tcp://host:8786)")


# Exit status (documented in --help and the README)
OK, REGRESSION, INPUT_PROBLEM = 0, 1, 2


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status (OK, REGRESSION, INPUT_PROBLEM)."""
    from rbody.files import UnwritableFolder, check_writable_folder
    from validation.baselines import BaselineError
    from validation.cluster import ClusterUnavailable

    args = _parser().parse_args(argv)
    try:
        if "\0" in str(args.out):
            raise InputProblem(f"--out {str(args.out)!r}: a path cannot hold a NUL character")
        check_writable_folder(args.out)  # before any work: a run of minutes must not end in a traceback
        return _command(args)
    except (BaselineError, UnwritableFolder, InputProblem, ClusterUnavailable) as error:
        print(f"error: {error}", file=sys.stderr)
        return INPUT_PROBLEM
    except OSError as error:
        if error.errno not in _WRITE_ERRORS:
            raise
        print(f"error: cannot write the results: {error}", file=sys.stderr)
        return INPUT_PROBLEM


# A folder made read-only during the run, a full disk or quota, a read-only file system.
_WRITE_ERRORS = (errno.EACCES, errno.EPERM, errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.ENAMETOOLONG)


class InputProblem(ValueError):
    """A command-line value the command cannot use (named in the message), found before any work."""


def _check_choices(args) -> None:
    """--scene of bench and --case of hard, checked before any work (InputProblem)."""
    if args.command == "bench" and args.scene:
        from validation.bench.run import EXTRA_WORK
        from validation.bench.scenes import bench_scenes

        known = [b.name for b in bench_scenes(args.quick)] + list(EXTRA_WORK)
        unknown = [name for name in args.scene if name not in known]
        if unknown:
            raise InputProblem(f"--scene {', '.join(unknown)}: expected one of {', '.join(known)}")
    if args.command == "hard" and args.case:
        from validation.hard.suite import CASES

        unknown = [str(n) for n in args.case if n not in CASES]
        if unknown:
            raise InputProblem(f"--case {', '.join(unknown)}: expected case numbers {CASES[0]}..{CASES[-1]}")


def _command(args) -> int:
    _check_choices(args)
    if args.command == "export":
        from validation.export import export_models
        for path in export_models(args.out):
            print(path)
        return 0
    if args.command == "bench":
        from validation.bench.run import main as bench_main
        return bench_main(args)
    if args.command == "compare":
        from validation.comparison import main as compare_main
        return compare_main(args)
    from validation.cluster import connect
    if args.command == "hard":
        from validation.hard.suite import CASES, run_hard
        with connect(args.scheduler, args.workers) as client:
            return run_hard(args.out, quick=args.quick, cases=tuple(args.case) if args.case else CASES,
                            client=client)
    with connect(args.scheduler, args.workers) as client:
        return run_all(args.out, quick=args.quick, update=args.update_baselines,
                       backends=tuple(args.backend) if args.backend else None, client=client)


def run_all(out: Path, *, quick: bool, update: bool, backends: tuple[str, ...] | None, client=None) -> int:
    """Run every case, print the table, write the report; exit 1 on a regression against baselines, 2 on a
    measure without a baseline (BaselineError, before any run, for a broken baseline file).
    Each (case, backend) is one task (validation.cluster.run_tasks): here in order, or on the cluster of
    `client` (a dask.distributed.Client); the rows and report are the same either way."""
    from rbody.files import replaced_folder
    from validation import baselines, report
    from validation.animations import chapter_animations
    from validation.backends import BACKENDS, ENGINES
    from validation.cases import default_cases
    from validation.cluster import run_tasks
    from validation.evaluate import evaluate
    from validation.figures import make_figures

    directory = baselines.mode_dir(quick)
    if not update:  # read and checked before the run; --update-baselines rewrites them without reading them
        baselines.check(directory, backends or ENGINES)
    started = time.perf_counter()
    cases = default_cases(quick)
    chosen = backends or ENGINES
    tasks = [(f"{case.name} {backend}", evaluate, (case, (backend,))) for case in cases for backend in chosen]
    results = iter(run_tasks(client, tasks, what="validation"))
    rows, runs = [], {}
    for case in cases:
        runs[case.name] = (case, {})
        for _ in chosen:  # one backend's rows and run, in the order of `chosen`
            case_rows, case_runs = next(results)
            rows += case_rows
            runs[case.name][1].update(case_runs)
    print(report.table(rows))
    found, missing = [], []
    if update:
        for path in baselines.save(rows, directory):
            print(f"baseline written: {path}", file=sys.stderr)
    else:
        found, missing = baselines.compare(rows, directory)
    header = _header(quick, time.perf_counter() - started)
    with replaced_folder(out) as staging:  # the report and its figures: all old or all new
        figures = make_figures(runs, staging)
        animations = chapter_animations(staging, runs, engines=tuple(e for e in chosen if e in BACKENDS), quick=quick,
                                        say=lambda line: print(f"animation: {line}", file=sys.stderr, flush=True))
        report.write(staging, rows, figures, header, found + missing, animations)
    print(f"\nreport: {out / 'report.md'}", file=sys.stderr)
    for message in found:
        print(f"REGRESSION {message}", file=sys.stderr)
    for message in missing:
        print(f"MISSING {message}", file=sys.stderr)
    return REGRESSION if found else INPUT_PROBLEM if missing else OK


def _header(quick: bool, seconds: float) -> str:
    from validation.baselines import versions
    from validation.machine import describe_machine
    lines = ["# rbody validation report", "",
             "Each textbook scene run in rbody, MuJoCo, pymunk, Pinocchio and Bullet (where each can express it) at the default settings of "
             "validation/cases.py, compared with the scene's exact solution.", "",
             f"- mode: {'quick' if quick else 'full'}; wall time {seconds:.1f} s",
             f"- machine: {describe_machine()}",
             "- versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()), ""]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
