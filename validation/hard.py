"""The numerical-stability suite: hard cases that break naive engines, run on rbody, MuJoCo and pymunk.

    python -m validation hard [--quick] [--out DIR] [--case N ...]

Each case exposes one failure mode (issue 6): the pi collisions to many digits, the swinging rod
near the top, free rotation near the intermediate axis, needles and thin discs, rolling at the
friction limit, too large a step, meshes at bad scales, long chains, time reversal. Every case runs
on every backend that can express it and gives rows of one table:

    outcome   exact (a count exact, or an error at round-off) | error (a finite run, its error
              given) | wrong count | blew up (a non-finite or unstable state, reported as an error)
              | refused (an error before any work, or a simulator that cannot express the case)
              | not run (beyond the time budget; the estimate is in the note)
    value     the measured error or count, `measure` says which
    rbody     pass / FAIL: whether rbody met the case's requirement (rbody rows only); the other
              simulators' rows are findings, reported and never judged against a loose bound

The cases live in validation/hard_contact.py (1, 5), hard_motion.py (2, 3), hard_shapes.py (4, 7),
hard_steps.py (6, 9) and hard_chains.py (8); their figures in hard_figures.py. DIR/hard.md holds the
tables, the figures and each case's findings; the machine, the package versions and the wall time
head it.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

OUTCOMES = ("exact", "error", "wrong count", "blew up", "refused", "not run")


@dataclass(frozen=True)
class HardRow:
    """One run of one case.

    variant: what was run (parameters); backend: rbody, mujoco or pymunk; setting: method or
    integrator and step; outcome: one of OUTCOMES; value: the measured number (None when there is
    none) and measure: what it is; seconds: wall time of the run [s]; verdict: "pass"/"FAIL" for
    rbody rows, "" otherwise; note: why (an error message, an estimate, a reference value)."""

    variant: str
    backend: str
    setting: str
    outcome: str
    value: float | None
    measure: str
    seconds: float
    verdict: str = ""
    note: str = ""

    def __post_init__(self) -> None:
        if self.outcome not in OUTCOMES:
            raise ValueError(f"outcome={self.outcome!r}: expected one of {OUTCOMES}")


@dataclass
class CaseResult:
    """Everything one case reports: its rows, its figures (caption, file name), the findings in words."""

    number: int
    title: str
    requirement: str
    rows: list[HardRow] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)
    findings: list[str] = field(default_factory=list)
    seconds: float = 0.0


def timed(function: Callable, *args, **kwargs):
    """(result, seconds) of one call."""
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


def attempt(function: Callable, *args, **kwargs):
    """(result or None, error or None, seconds): a call whose failure is a result to report."""
    start = time.perf_counter()
    try:
        result = function(*args, **kwargs)
    except Exception as error:  # blow-ups and refusals of every simulator are outcomes
        return None, error, time.perf_counter() - start
    return result, None, time.perf_counter() - start


def error_outcome(error: BaseException, *, started: bool = True) -> str:
    """The outcome of a run that raised: refused (the simulator cannot express the case, the method does
    not apply, rbody refused the step before any work, or the error came before the run: started=False)
    or blew up (anything raised while or after stepping: an unstable or non-finite state, and also an
    error of another type that escaped, which the rbody verdicts then count against rbody)."""
    from rbody.errors import MethodNotApplicable, SimulationError

    if isinstance(error, (NotImplementedError, MethodNotApplicable)) or not started:
        return "refused"
    text = str(error)
    if isinstance(error, SimulationError) and ("beyond its estimated stability limit" in text
                                               or "cannot run it" in text or "no stability interval" in text):
        return "refused"
    return "blew up"


def short(error: BaseException, limit: int = 240) -> str:
    text = f"{type(error).__name__}: {error}"
    return text if len(text) <= limit else text[:limit - 3] + "..."


# ----- the cases --------------------------------------------------------------------------------------

# case number -> (module, function(quick, out) -> CaseResult)
_CASES = {1: ("hard_contact", "case_pi"), 2: ("hard_motion", "case_near_top"),
          3: ("hard_motion", "case_intermediate_axis"), 4: ("hard_shapes", "case_extreme_shapes"),
          5: ("hard_contact", "case_friction_limit"), 6: ("hard_steps", "case_large_steps"),
          7: ("hard_shapes", "case_bad_meshes"), 8: ("hard_chains", "case_long_chains"),
          9: ("hard_steps", "case_time_reversal")}
CASES = tuple(_CASES)


def case_function(number: int) -> Callable[[bool, Path], CaseResult]:
    """The function that runs hard case `number` (1..9)."""
    import importlib

    if number not in _CASES:
        raise ValueError(f"case={number!r}: the hard cases are numbered {CASES[0]}..{CASES[-1]}")
    module, name = _CASES[number]
    return getattr(importlib.import_module(f"validation.{module}"), name)


def run_cases(out: Path, *, quick: bool, cases: tuple[int, ...] = CASES) -> list[CaseResult]:
    """Run the chosen cases (numbers 1..9), writing their figures into out; progress on stderr."""
    functions = {number: case_function(number) for number in cases}
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for number in cases:
        print(f"[hard {number}] ...", end="", file=sys.stderr, flush=True)
        result, seconds = timed(functions[number], quick, out)
        result.seconds = seconds
        print(f" {result.title}: {len(result.rows)} rows, {seconds:.1f} s", file=sys.stderr, flush=True)
        results.append(result)
    return results


def run_hard(out: Path, *, quick: bool, cases: tuple[int, ...] = CASES) -> int:
    """Run the suite, print every case's table, write out/hard.md. Exit status 1 when rbody failed a
    requirement (a FAIL row), else 0."""
    started = time.perf_counter()
    results = run_cases(out, quick=quick, cases=cases)
    for result in results:
        print(f"\n== {result.number}. {result.title} ==")
        print(table(result.rows))
    path = write_markdown(out, results, quick=quick, seconds=time.perf_counter() - started)
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
             "with a clear error, and the same case is run in MuJoCo and pymunk wherever they can express it. "
             "Outcomes: exact, error (value given), wrong count, blew up, refused, not run (over the time "
             "budget). The rbody column says whether rbody met the case's requirement.", "",
             f"- command: `python -m validation hard{' --quick' if quick else ''}`",
             f"- mode: {'quick' if quick else 'full'}; wall time {seconds:.1f} s "
             f"(cases {', '.join(str(r.number) for r in results)})",
             f"- machine: {describe_machine()}",
             "- versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()),
             "- times are wall times of each run on a machine shared with other work; they include rbody's "
             "model building and MuJoCo's and pymunk's Python loops", ""]
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
    path.write_text("\n".join(parts) + "\n")
    return path


__all__ = ["HardRow", "CaseResult", "OUTCOMES", "CASES", "run_cases", "run_hard", "table", "write_markdown"]
