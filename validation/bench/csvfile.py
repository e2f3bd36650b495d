"""The benchmark's CSV files: the '#' header (machine, versions, mode), writing and reading rows."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Iterable, Mapping

from rbody.files import atomic_open


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
    with atomic_open(path, "w", newline="") as f:  # a temporary name, renamed into place
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
