"""Regression baselines: each backend's metrics at the main command's default settings.

validation/baselines/<mode>/<backend>.json (mode "full" or "quick": the quick cases are shorter runs,
so they have baselines of their own) holds {"versions": {...}, "metrics": {"case/metric": value}}.
A metric regresses when it gets worse than its baseline by more than MARGIN (a relative factor,
with an absolute floor for values at round-off level), or when a collision count changes at all.
"""

from __future__ import annotations

import json
import platform
from pathlib import Path
from typing import Iterable

import numpy as np

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
    return {"mujoco": mujoco.__version__, "pymunk": pymunk.version, "numpy": np.__version__,
            "numba": numba.__version__, "python": platform.python_version()}


def load(backend: str, directory: Path = BASELINE_DIR / "full") -> dict:
    path = directory / f"{backend}.json"
    if not path.exists():
        return {"versions": {}, "metrics": {}}
    return json.loads(path.read_text())


def save(rows: Iterable, directory: Path = BASELINE_DIR / "full") -> list[Path]:
    """Write one file per backend from the measured rows (values only; refused/failed rows skipped)."""
    by_backend: dict[str, dict[str, float]] = {}
    for row in rows:
        if row.value is not None:
            by_backend.setdefault(row.backend, {})[f"{row.case}/{row.metric}"] = float(row.value)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for backend, metrics in sorted(by_backend.items()):
        path = directory / f"{backend}.json"
        path.write_text(json.dumps({"versions": versions(), "metrics": dict(sorted(metrics.items()))},
                                   indent=1) + "\n")
        written.append(path)
    return written


def regressions(rows: Iterable, directory: Path = BASELINE_DIR / "full") -> list[str]:
    """Messages for every row that is worse than its recorded baseline."""
    found = []
    cache: dict[str, dict] = {}
    for row in rows:
        if row.value is None:
            continue
        recorded = cache.setdefault(row.backend, load(row.backend, directory))["metrics"]
        key = f"{row.case}/{row.metric}"
        if key not in recorded:
            continue
        base = recorded[key]
        if row.metric in EXACT_METRICS:
            worse = row.value != base
        else:
            worse = abs(row.value) > abs(base) * RELATIVE_MARGIN + ABSOLUTE_MARGIN
        if worse:
            found.append(f"{row.backend} {key}: {row.value:.3g} against baseline {base:.3g}")
    return found
