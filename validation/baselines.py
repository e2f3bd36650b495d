"""Regression baselines: each backend's metrics at the main command's default settings.

validation/baselines/<mode>/<backend>.json (mode "full" or "quick": the quick cases are shorter runs,
so they have baselines of their own) holds {"versions": {...}, "metrics": {"case/metric": value}}.
A metric regresses when it gets worse than its baseline by more than MARGIN (a relative factor,
with an absolute floor for values at round-off level), or when a collision count changes at all.

The files are read and checked before any run (check): a file that is not JSON, or not of that shape,
raises BaselineError naming the file, what is wrong and the command that rewrites it. A metric
without a baseline (no file, or no entry) is reported as such ("no baseline for ...") and is not a
pass. save() writes the new files into a staging folder that replaces the baseline folder whole at the end
(rbody.files.replaced_folder: a killed update leaves the old baselines or the new ones, never a mix), and never
reads the old files, so that --update-baselines repairs a broken file. Temporaries an interrupted write left in
the folder (hidden names: rbody.files.is_temporary) are never read as baselines, and an update removes them.
"""

from __future__ import annotations

import json
import math
import os
import platform
from pathlib import Path
from typing import Iterable

import numpy as np

from rbody.files import remove_stale_temporaries, replaced_folder, write_atomic

BASELINE_DIR = Path(__file__).parent / "baselines"


def mode_dir(quick: bool) -> Path:
    """Where the baselines of the quick or the full mode live."""
    return BASELINE_DIR / ("quick" if quick else "full")

# Worse means: |value| > |baseline| * RELATIVE_MARGIN + ABSOLUTE_MARGIN. Round-off-level errors move by
# small factors between CPUs and library builds; a real regression moves them by orders of magnitude.
RELATIVE_MARGIN = 2.0
ABSOLUTE_MARGIN = 1e-13
EXACT_METRICS = ("count_error", "pi_digits")  # integers: any change is a regression


def versions() -> dict[str, str]:
    import mujoco
    import numba
    import pymunk
    found = {"mujoco": mujoco.__version__, "pymunk": pymunk.version, "numpy": np.__version__,
             "numba": numba.__version__, "python": platform.python_version()}
    try:
        import pinocchio

        found["pinocchio"] = pinocchio.__version__
    except ImportError:
        pass
    try:
        from importlib.metadata import version

        found["pybullet"] = version("pybullet")
    except Exception:  # not installed
        pass
    return found


class BaselineError(ValueError):
    """A baseline file that cannot be used: the message names the file, the problem and the repair."""


def repair_command(directory: str | os.PathLike) -> str:
    """The command that rewrites the baselines in `directory`."""
    directory = Path(directory)
    if directory.resolve() == mode_dir(True).resolve():
        return "python -m validation --quick --update-baselines"
    if directory.resolve() == mode_dir(False).resolve():
        return "python -m validation --update-baselines"
    return f"python -m validation [--quick] --update-baselines (baselines in {str(directory)!r})"


def read(path: str | os.PathLike) -> dict:
    """The baseline file at `path`, checked: {"versions": {name: text}, "metrics": {"case/metric": number}}.
    BaselineError (a ValueError) naming the file, the problem and the repairing command otherwise."""
    path = Path(path)

    def broken(problem: str) -> BaselineError:
        return BaselineError(f"baseline file {str(path)!r} {problem}; rewrite it with `{repair_command(path.parent)}`")

    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise broken("is not UTF-8 text") from None
    except OSError as error:
        raise broken(f"cannot be read ({error.strerror or error})") from None
    if not text.strip():
        raise broken("is empty (an interrupted write?)")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise broken(f"is not valid JSON ({error.msg} at line {error.lineno}, column {error.colno})") from None
    if not isinstance(data, dict):
        raise broken(f"holds a JSON {type(data).__name__}, expected an object with 'versions' and 'metrics'")
    metrics = data.get("metrics")
    if not isinstance(metrics, dict):
        raise broken(f"has 'metrics' of type {type(metrics).__name__}, expected an object of 'case/metric': number")
    for key, value in metrics.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise broken(f"has metric {key!r} = {value!r}, expected a finite number")
    versions_ = data.get("versions", {})
    if not isinstance(versions_, dict):
        raise broken(f"has 'versions' of type {type(versions_).__name__}, expected an object")
    return {"versions": versions_, "metrics": {key: float(value) for key, value in metrics.items()}}


def load(backend: str, directory: str | os.PathLike = BASELINE_DIR / "full") -> dict | None:
    """The checked baseline of `backend` in `directory` (read), or None when there is no file."""
    path = Path(directory) / f"{backend}.json"
    if not path.exists():
        return None
    return read(path)


def check(directory: str | os.PathLike, backends: Iterable[str]) -> None:
    """Read and check every baseline file of `backends` in `directory` before any run (BaselineError on the
    first broken one; missing files are not an error here, they are reported after the run)."""
    for backend in backends:
        load(backend, directory)


def save(rows: Iterable, directory: str | os.PathLike = BASELINE_DIR / "full",
         keep: dict[str, dict[str, float]] | None = None) -> list[Path]:
    """Write one file per backend from the measured rows (values only; refused/failed rows skipped), all at once:
    into a staging folder that then replaces `directory` whole (rbody.files.replaced_folder; files of backends not
    written are kept). keep: backend -> metrics to write beside the rows' (another model's entries in a compare
    baseline). The old files are not read here (so that a broken one is repaired); stale temporaries are removed."""
    directory = Path(directory)
    by_backend: dict[str, dict[str, float]] = {backend: dict(metrics) for backend, metrics in (keep or {}).items()}
    for row in rows:
        if row.value is not None:
            by_backend.setdefault(row.backend, {})[f"{row.case}/{row.metric}"] = float(row.value)
    directory.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(directory)
    names = []
    with replaced_folder(directory) as staging:
        for backend, metrics in sorted(by_backend.items()):
            write_atomic(staging / f"{backend}.json",
                         json.dumps({"versions": versions(), "metrics": dict(sorted(metrics.items()))}, indent=1) + "\n")
            names.append(f"{backend}.json")
    return [directory / name for name in names]


def compare(rows: Iterable, directory: str | os.PathLike = BASELINE_DIR / "full") -> tuple[list[str], list[str]]:
    """(regressions, missing): a message for every row worse than its recorded baseline, and one for every
    measured row that has no baseline ("no baseline for ...: run ..."). BaselineError for a broken file."""
    directory = Path(directory)
    found, missing = [], []
    cache: dict[str, dict | None] = {}
    for row in rows:
        if row.value is None:
            continue
        if row.backend not in cache:
            cache[row.backend] = load(row.backend, directory)
        key = f"{row.case}/{row.metric}"
        recorded = cache[row.backend]
        if recorded is None or key not in recorded["metrics"]:
            where = "no file " + str(directory / f"{row.backend}.json") if recorded is None else "no entry"
            missing.append(f"no baseline for {row.backend} {key} ({where}): run `{repair_command(directory)}`")
            continue
        base = recorded["metrics"][key]
        if row.metric in EXACT_METRICS:
            worse = row.value != base
        else:
            worse = abs(row.value) > abs(base) * RELATIVE_MARGIN + ABSOLUTE_MARGIN
        if worse:
            found.append(f"{row.backend} {key}: {row.value:.3g} against baseline {base:.3g}")
    return found, missing


def regressions(rows: Iterable, directory: str | os.PathLike = BASELINE_DIR / "full") -> list[str]:
    """Messages for every row that is worse than its recorded baseline, and for every row without one
    (a missing baseline is not a pass). directory: str or Path."""
    found, missing = compare(rows, directory)
    return found + missing
