"""The speed-against-error benchmark: its quick mode end to end, and the helpers it rests on."""

import math

import numpy as np
import pytest

from validation.bench.csvfile import read_csv
from validation.bench.growth import exponent
from validation.bench.scenes import sweep
from validation.bench.sweep import COLUMNS


@pytest.mark.crosssim
def test_quick_bench_writes_every_point_and_no_silent_nan(tmp_path):
    from validation.__main__ import main

    assert main(["bench", "--quick", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "bench.csv").read_text()
    comments = [line for line in text.splitlines() if line.startswith("#")]
    assert any(line.startswith("# machine: ") for line in comments)
    assert any("mujoco" in line and "pymunk" in line for line in comments if line.startswith("# versions: "))
    header = next(line for line in text.splitlines() if not line.startswith("#"))
    assert tuple(header.split(",")) == COLUMNS
    rows = read_csv(tmp_path / "bench.csv")
    assert {r["backend"] for r in rows} == {"rbody", "mujoco", "pymunk"}
    for row in rows:
        if math.isnan(row["error"]):  # a NaN error only with the reason for it
            assert row["failure"], row
        if not row["failure"]:
            assert row["error"] >= 0 and row["seconds_per_sim_second"] > 0 and row["repeats"] >= 1, row
    # pymunk cannot express free rotation: a row says so rather than no row
    assert any(r["scene"] == "free_rotation" and r["backend"] == "pymunk" and r["failure"].startswith("refused")
               for r in rows)
    summary = (tmp_path / "summary.md").read_text()
    assert "## swinging_rod" in summary and "| error <= |" in summary and "## Goals" in summary
    assert "machine: " in summary and "versions: " in summary
    assert (tmp_path / "wp_swinging_rod.png").stat().st_size > 10_000


def test_sweep_is_coarse_to_fine_on_a_common_sampling_grid():
    sample = 0.01
    dts = sweep(0.1, 1e-5, 7, sample)
    assert len(dts) == 7 and all(a > b for a, b in zip(dts, dts[1:]))
    for dt in dts:  # a whole number of steps per sample, or of samples per step
        ratio = sample / dt if dt <= sample else dt / sample
        assert abs(ratio - round(ratio)) < 1e-9


def test_exponent_recovers_a_power_law():
    x = np.array([2.0, 4.0, 8.0, 16.0, 32.0])
    assert exponent(x, 3e-6 * x**2.5) == pytest.approx(2.5, rel=1e-12)
    assert math.isnan(exponent([1.0], [1.0]))
