"""The README's tables from a benchmark run and a hard-case run, and their copy into docs/.

    python -m validation.bench.tables --bench report/bench [--bench DIR2 ...] [--hard report/hard]
                                      [--readme README.md] [--docs docs]

- the ratio table (how many times cheaper rbody is than the best other column, per scene and level:
  the median over the runs and its range, as summary.md) replaces the README's lines between
  <!-- bench-ratios:start --> and <!-- bench-ratios:end -->; several --bench folders are merged as
  successive runs (their `run` numbers renumbered);
- the goals of summary.md's "## Goals" section (of the first --bench folder) replace the lines between
  <!-- bench-goals:start --> and <!-- bench-goals:end -->;
- with --peers DIR (a run of the peers beside the others, e.g. `python -m validation bench --out DIR`), the cost
  of rbody, of the best of MuJoCo and pymunk, of Pinocchio and of Bullet at each error level replaces the lines
  between <!-- bench-peers:start --> and <!-- bench-peers:end -->;
- the digits of pi each engine counts exactly (hard case 1's finding "Digits right ...") replace the
  lines between <!-- hard-pi:start --> and <!-- hard-pi:end -->;
- with --docs, the run's files (bench.csv, batch.csv, growth.csv, summary.md, the figures; hard.md and
  its figures) are copied into docs/bench/ and docs/hard/, and the two work-precision figures the README
  shows into docs/figures/.
Every file is written to a temporary name in its folder and renamed into place.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import shutil
import sys
from pathlib import Path

from rbody.files import atomic_path, write_atomic
from validation.bench.report import GOAL_RATIO, LEVELS, NAMES, cheapest, column, level_table
from validation.bench.sweep import Point, read_points

README_FIGURES = ("wp_swinging_rod.png", "wp_rolling_race.png")


def merged_points(folders: list[Path]) -> list[Point]:
    """The points of every folder's bench.csv, the runs of the second folder numbered after the first's."""
    points: list[Point] = []
    offset = 0
    for folder in folders:
        path = Path(folder) / "bench.csv"
        if not path.is_file():
            raise ValueError(f"--bench {folder}: no bench.csv there (run `python -m validation bench --out {folder}`)")
        mine = read_points(path)
        points += [dataclasses.replace(p, run=p.run + offset) for p in mine]
        offset = max((p.run for p in points), default=offset)
    return points


def ratio_table(points: list[Point]) -> str:
    """Markdown: per scene (in the order of the CSV) and level, rbody's standing as summary.md gives it."""
    scenes = list(dict.fromkeys(p.scene for p in points))
    runs = sorted({p.run for p in points})
    lines = [f"| scene | error <= {LEVELS[0]:.0e} | " + " | ".join(f"{level:.0e}" for level in LEVELS[1:]) + " |",
             "|---|" + "---|" * len(LEVELS)]
    for scene in scenes:
        mine = [p for p in points if p.scene == scene]
        columns = ["rbody"] + [c for c in ("mujoco", "mujoco reduced", "pymunk", "pinocchio", "bullet")
                               if any(column(p) == c and not math.isnan(p.dt) for p in mine)]
        _table, standing = level_table(mine, scene, columns)
        cells = []
        for s in standing:
            if s["ratio"] == math.inf:
                cells.append("only rbody")
            elif s["ratio"] == 0.0:
                cells.append("rbody never")
            elif not s["ratios"]:
                cells.append("none" if s["rival"] is None and s["rbody"] is None else "in some runs only")
            else:
                finite = sorted(s["ratios"])
                text = f"{s['ratio']:.3g}x" + (f" ({finite[0]:.3g}..{finite[-1]:.3g})" if len(finite) > 1 else "")
                cells.append(f"**{text}**" if s["ratio"] < GOAL_RATIO else text)
        lines.append(f"| {scene} | " + " | ".join(cells) + " |")
    note = (f"Median over {len(runs)} runs (min..max over the runs); " if len(runs) > 1 else "One run; ")
    note += ("bold: under the 10x goal; \"only rbody\": no other column reaches the level anywhere in its sweep "
             "(MuJoCo and pymunk at every setting swept, MuJoCo also on rbody's reduction where there is one).")
    return "\n".join(lines + ["", note])


PEER_LEVELS = LEVELS[:3]


def peer_table(points: list[Point]) -> str:
    """Markdown: per scene and error level that some engine reaches, the least cost [wall s per simulated s] of
    rbody, of the best of MuJoCo (its contact model or rbody's reduction) and pymunk, of Pinocchio and of Bullet,
    each read off its work-precision curves (report.cheapest; Bullet's solver setting named where it is not the
    default); "never": swept, not reached; "-": the engine does not express the scene."""
    scenes = list(dict.fromkeys(p.scene for p in points))
    lines = ["| scene | error <= | rbody | best of MuJoCo, pymunk | Pinocchio | Bullet |", "|---|---|---|---|---|---|"]

    def cell(scene: str, keys: tuple[str, ...], level: float) -> str:
        swept = any(column(p) in keys and p.scene == scene and not math.isnan(p.dt) for p in points)
        if not swept:
            return "-"
        readings = [r for key in keys if (r := cheapest(points, scene, key, level)) is not None]
        if not readings:
            return "never"
        best = min(readings, key=lambda r: r.seconds_per_sim_second)
        label = NAMES.get(column(best), best.backend) if len(keys) > 1 else ""
        setting = "" if best.settings in ("default",) or best.settings.startswith("exact") else best.settings
        detail = ", ".join(x for x in (label, best.method, setting,
                                       f"dt {best.dt:.2g}") if x)
        return f"{best.seconds_per_sim_second:.2g} ({detail})"

    for scene in scenes:
        for level in PEER_LEVELS:
            cells = [cell(scene, ("rbody",), level), cell(scene, ("mujoco", "mujoco reduced", "pymunk"), level),
                     cell(scene, ("pinocchio",), level), cell(scene, ("bullet",), level)]
            if all(c in ("-", "never") for c in cells):
                continue
            lines.append(f"| {scene} | {level:.0e} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def goals_lines(summary_md: Path) -> str:
    """The list under summary.md's '## Goals' heading."""
    text = Path(summary_md).read_text()
    if "\n## Goals\n" not in text:
        raise ValueError(f"{summary_md}: no '## Goals' section")
    goals = text.split("\n## Goals\n", 1)[1].split("\n## ", 1)[0]
    return goals.strip()


def pi_digits_line(hard_md: Path) -> str:
    """Hard case 1's finding 'Digits right (largest N with the exact count): ...' and each peer's coarsest
    exact step, from hard.md."""
    text = Path(hard_md).read_text()
    found = re.search(r"^- (Digits right \(largest N with the exact count\):[^\n]*)$", text, re.M)
    if found is None:
        raise ValueError(f"{hard_md}: no 'Digits right' finding of hard case 1 (run `python -m validation hard`)")
    steps = re.findall(r"^- ((?:mujoco|pymunk), digits \d+: coarsest exact step [^\n]*)$", text, re.M)
    return "\n".join([found.group(1)] + [f"- {line}" for line in steps])


def replace_block(text: str, name: str, body: str) -> str:
    """text with the lines between <!-- name:start --> and <!-- name:end --> replaced by body."""
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    if text.count(start) != 1 or text.count(end) != 1 or text.index(start) > text.index(end):
        raise ValueError(f"README: expected one {start} ... {end} block")
    head, rest = text.split(start)
    _old, tail = rest.split(end)
    return f"{head}{start}\n{body}\n{end}{tail}"


def _copy(source: Path, target: Path) -> None:
    with atomic_path(target) as temporary:
        shutil.copyfile(source, temporary)


def _copy_run(folder: Path, into: Path, patterns: tuple[str, ...]) -> list[Path]:
    into.mkdir(parents=True, exist_ok=True)
    copied = []
    for pattern in patterns:
        for source in sorted(folder.glob(pattern)):
            _copy(source, into / source.name)
            copied.append(into / source.name)
    return copied


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m validation.bench.tables", description=__doc__.split("\n\n")[0])
    parser.add_argument("--bench", type=Path, action="append", metavar="DIR",
                        help="a benchmark output folder (repeatable: merged as successive runs)")
    parser.add_argument("--peers", type=Path, metavar="DIR",
                        help="a benchmark output folder with the peers' series: the bench-peers table")
    parser.add_argument("--hard", type=Path, metavar="DIR", help="the hard-case output folder (holds hard.md)")
    parser.add_argument("--readme", type=Path, default=Path("README.md"))
    parser.add_argument("--docs", type=Path, help="copy the runs into DOCS/bench, DOCS/hard, DOCS/figures")
    args = parser.parse_args(argv)
    if not args.bench and args.peers is None:
        parser.error("give --bench DIR, --peers DIR or both")
    readme = args.readme.read_text()
    if args.peers is not None:
        readme = replace_block(readme, "bench-peers", peer_table(merged_points([args.peers])))
        if args.docs is not None:
            copied = _copy_run(args.peers, args.docs / "bench-peers", ("*.csv", "*.png", "summary.md"))
            print(f"{len(copied)} files copied into {args.docs / 'bench-peers'}", file=sys.stderr)
        if not args.bench:
            write_atomic(args.readme, readme)
            print(f"{args.readme}: the peers' table rewritten", file=sys.stderr)
            return 0
    points = merged_points(args.bench)
    readme = replace_block(readme, "bench-ratios", ratio_table(points))
    readme = replace_block(readme, "bench-goals", goals_lines(args.bench[0] / "summary.md"))
    if args.hard is not None:
        readme = replace_block(readme, "hard-pi", pi_digits_line(args.hard / "hard.md"))
    write_atomic(args.readme, readme)
    print(f"{args.readme}: tables rewritten", file=sys.stderr)
    if args.docs is not None:
        if len(args.bench) == 1:
            copied = _copy_run(args.bench[0], args.docs / "bench", ("*.csv", "*.png", "summary.md"))
            (args.docs / "figures").mkdir(parents=True, exist_ok=True)
            for name in README_FIGURES:
                if (args.bench[0] / name).is_file():
                    _copy(args.bench[0] / name, args.docs / "figures" / name)
        else:  # several runs: the merged CSV (summary.md of each run stays in its folder)
            from validation.bench.csvfile import write_csv
            from validation.bench.sweep import COLUMNS

            (args.docs / "bench").mkdir(parents=True, exist_ok=True)
            copied = [write_csv(args.docs / "bench" / "bench.csv", (dataclasses.asdict(p) for p in points), COLUMNS,
                                [f"merged from {', '.join(map(str, args.bench))}"])]
        if args.hard is not None:
            copied += _copy_run(args.hard, args.docs / "hard", ("hard.md", "hard_*.png"))
        print(f"{len(copied)} files copied into {args.docs}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
