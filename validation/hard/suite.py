"""The hard-case suite of `python -m validation hard` (validation/hard/__init__.py says what it runs):
the case table, the command, and the tables and report hard.md."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

from rbody.files import replaced_folder, write_atomic
from validation.hard import chains, contact, motion, rigid_contacts, shapes, steps
from validation.hard.rows import CaseResult, HardRow, timed

# ----- the cases --------------------------------------------------------------------------------------

# case number -> function(quick, out) -> CaseResult
_CASES = {1: contact.case_pi, 2: motion.case_near_top, 3: motion.case_intermediate_axis,
          4: shapes.case_extreme_shapes, 5: contact.case_friction_limit, 6: steps.case_large_steps,
          7: shapes.case_bad_meshes, 8: chains.case_long_chains, 9: steps.case_time_reversal,
          10: rigid_contacts.case_rigid_contacts}
CASES = tuple(_CASES)


def case_function(number: int) -> Callable[[bool, Path], CaseResult]:
    """The function that runs hard case `number` (one of CASES: 1..10)."""
    if number not in _CASES:
        raise ValueError(f"case={number!r}: the hard cases are numbered {CASES[0]}..{CASES[-1]}")
    return _CASES[number]


def run_cases(out: Path, *, quick: bool, cases: tuple[int, ...] = CASES, client=None) -> list[CaseResult]:
    """Run the chosen cases (numbers of CASES), then write their figures into out; progress on stderr.

    Each case is one task (validation.cluster.run_tasks): here in order (client None) or on the Dask cluster
    of `client`. A case draws its figures in a folder of its own (a worker need not share a file system with
    the report); they are written into `out` once every case has run."""
    from validation.cluster import run_tasks

    for number in cases:
        case_function(number)  # an unknown case number: refused before any work
    tasks = [(f"case {number}", case_task, (number, quick)) for number in cases]
    done = run_tasks(client, tasks, what="hard")
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for result, files in done:
        for name, data in files.items():
            write_atomic(out / name, data)
        print(f"[hard {result.number}] {result.title}: {len(result.rows)} rows, {result.seconds:.1f} s",
              file=sys.stderr, flush=True)
        results.append(result)
    return results


def case_task(number: int, quick: bool) -> tuple[CaseResult, dict[str, bytes]]:
    """Hard case `number` run in a temporary folder: its result and the files it drew there (name -> bytes).
    One task of run_cases, here or on a Dask worker."""
    with tempfile.TemporaryDirectory(prefix=f"rbody-hard-{number}-") as folder:
        result, seconds = timed(case_function(number), quick, Path(folder))
        result.seconds = seconds
        files = {path.name: path.read_bytes() for path in sorted(Path(folder).iterdir()) if path.is_file()}
    return result, files


def run_hard(out: Path, *, quick: bool, cases: tuple[int, ...] = CASES, client=None) -> int:
    """Run the suite, print every case's table, write out/hard.md. Exit status 1 when rbody failed a
    requirement (a FAIL row), else 0. client: a dask.distributed.Client to run the cases on, or None."""
    started = time.perf_counter()
    with replaced_folder(out) as staging:  # hard.md and its figures all new, or all as they were
        results = run_cases(staging, quick=quick, cases=cases, client=client)
        for result in results:
            print(f"\n== {result.number}. {result.title} ==")
            print(table(result.rows))
        path = out / write_markdown(staging, results, quick=quick, seconds=time.perf_counter() - started).name
    print(f"\nreport: {path}", file=sys.stderr)
    failed = [(r.number, row) for r in results for row in r.rows if row.verdict == "FAIL"]
    for number, row in failed:
        print(f"rbody FAIL in case {number}: {row.variant} [{row.setting}]: {row.note}", file=sys.stderr)
    return 1 if failed else 0


# ----- tables and the report ------------------------------------------------------------------------

HEADER = ("variant", "backend", "setting", "outcome", "value", "measure", "time [s]", "rbody")


def format_value(value: float | None) -> str:
    if value is None:
        return "-"
    if float(value).is_integer() and abs(value) < 1e15:
        return str(int(value))
    return f"{value:.3g}"


def _cells(row: HardRow) -> tuple[str, ...]:
    return (row.variant, row.backend, row.setting, row.outcome, format_value(row.value), row.measure,
            f"{row.seconds:.2f}", row.verdict or "")


def table(rows: list[HardRow], *, markdown: bool = False) -> str:
    """The rows as a text table (or Markdown): variant, backend, setting, outcome, value, measure, time, rbody."""
    lines = [_cells(r) for r in rows]
    if markdown:
        out = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
        out += ["| " + " | ".join(cell.replace("|", "/") for cell in line) + " |" for line in lines]
        return "\n".join(out)
    widths = [max([len(h)] + [len(line[k]) for line in lines]) for k, h in enumerate(HEADER)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    rule = fmt.format(*("-" * w for w in widths))
    return "\n".join([fmt.format(*HEADER), rule] + [fmt.format(*line) for line in lines])


def _notes(rows: list[HardRow]) -> list[str]:
    seen, out = set(), []
    for row in rows:
        if row.note and (row.backend, row.variant, row.note) not in seen:
            seen.add((row.backend, row.variant, row.note))
            out.append(f"- {row.variant} / {row.backend} [{row.setting}]: {row.note}")
    return out


def write_markdown(out: Path, results: list[CaseResult], *, quick: bool, seconds: float) -> Path:
    """out/hard.md: the header (mode, machine, versions, wall time), then per case its requirement,
    table, findings, figures and the notes of its rows."""
    from validation.baselines import versions
    from validation.machine import describe_machine

    parts = ["# Numerical stability on hard cases", "",
             "Each case is built to expose one failure mode; rbody must come through it correctly or refuse "
             "with a clear error, and the same case is run in MuJoCo, pymunk, Pinocchio and Bullet wherever they can express it. "
             "Outcomes: exact, error (value given), wrong count, blew up, refused, not run (over the time "
             "budget). The rbody column says whether rbody met the case's requirement.", "",
             f"- command: `python -m validation hard{' --quick' if quick else ''}`",
             f"- mode: {'quick' if quick else 'full'}; wall time {seconds:.1f} s "
             f"(cases {', '.join(str(r.number) for r in results)})",
             f"- machine: {describe_machine()}",
             "- versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()),
             "- times are wall times of each run on a machine shared with other work; they include rbody's "
             "model building and MuJoCo's and pymunk's Python loops, except in case 1, where MuJoCo's and "
             "pymunk's are their stepping alone (the measure of the search's budget)", ""]
    summary = [(r.number, r.title, sum(row.verdict == "pass" for row in r.rows),
                sum(row.verdict == "FAIL" for row in r.rows), r.seconds) for r in results]
    parts += ["| case | title | rbody pass | rbody FAIL | time [s] |", "|---|---|---|---|---|"]
    parts += [f"| {n} | {t} | {p} | {f} | {s:.1f} |" for n, t, p, f, s in summary] + [""]
    for result in results:
        parts += [f"## {result.number}. {result.title}", "", f"Requirement: {result.requirement}", "",
                  table(result.rows, markdown=True), ""]
        if result.findings:
            parts += ["Findings:", ""] + [f"- {line}" for line in result.findings] + [""]
        for caption, name in result.figures:
            parts += [f"![{caption}]({name})", "", f"*{caption}*", ""]
        notes = _notes(result.rows)
        if notes:
            parts += ["<details><summary>notes</summary>", ""] + notes + ["", "</details>", ""]
    path = out / "hard.md"
    write_atomic(path, "\n".join(parts) + "\n")
    return path


__all__ = ["CASES", "case_function", "run_cases", "run_hard", "table", "write_markdown"]
