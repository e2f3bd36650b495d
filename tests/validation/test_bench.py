"""The speed-against-error benchmark: its quick mode end to end, and the helpers it rests on."""

import math

import numpy as np
import pytest

from validation.bench.csvfile import read_csv
from validation.bench.growth import exponent
from validation.bench.report import column, curve_cost, level_table
from validation.bench.scenes import REDUCED_LABEL, sweep
from validation.bench.sweep import COLUMNS, Point, read_points
from validation.bench.tables import replace_block


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
    from rbody import scenes
    from validation.backends import PEERS, supports

    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0)
    installed = {peer for peer in PEERS if supports(rod, peer)[0]}
    assert {r["backend"] for r in rows} == {"rbody", "mujoco", "pymunk"} | installed  # the peers where installed
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
    # the same work on every side: the cost with the observables, and the stepping alone beside it; rbody's and
    # pymunk's cost holds their stepping (MuJoCo's is its other rollout, the one with sensors)
    for row in rows:
        if not row["failure"]:
            assert row["stepping_seconds_per_sim_second"] > 0, row
            if row["backend"] in ("rbody", "pymunk"):
                assert row["seconds_per_sim_second"] >= row["stepping_seconds_per_sim_second"], row
    # MuJoCo on rbody's rolling reduction, in its own column, exact to round-off at RK4
    reduced = [r for r in rows if r["scene"] == "rolling_disc" and r["settings"].startswith(REDUCED_LABEL)]
    assert reduced and min(r["error"] for r in reduced if not r["failure"]) < 1e-12
    assert "MuJoCo on rbody's reduction" in summary and "median" in summary
    # the general engine's chain, and MuJoCo with contacts and constraints disabled on it
    assert any(r["scene"] == "chain_general" and r["backend"] == "rbody" and not r["failure"] for r in rows)


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


def _point(dt, error, cost, failure="", method="rk4", backend="rbody", settings="default", run=1):
    return Point("s", backend, method, settings, dt, error=error, seconds_per_sim_second=cost, failure=failure,
                 run=run)


def test_curve_cost_interpolates_in_log_log_between_neighbours():
    """error = dt^4, cost = 1e-3 / dt: at level 1e-8 the curve crosses between dt = 1e-2 (1e-8: passes) ... so
    take points at dt 0.1 and 0.01 (errors 1e-4, 1e-8) and ask for 1e-6: log-linear gives dt = 10^-1.5 and
    cost 1e-3 / 10^-1.5 exactly, cheaper than the grid point that passes (dt = 0.01, cost 0.1)."""
    rows = [_point(0.1, 1e-4, 1e-2), _point(0.01, 1e-8, 1e-1)]
    reading = curve_cost(rows, 1e-6)
    assert reading.interpolated and reading.dt == pytest.approx(10**-1.5, rel=1e-12)
    assert reading.seconds_per_sim_second == pytest.approx(1e-3 * 10**1.5, rel=1e-12)
    assert curve_cost(rows, 1e-9) is None                     # no extrapolation past the finest point
    assert curve_cost(rows, 1e-3).seconds_per_sim_second == 1e-2  # the coarsest point passes as measured
    broken = [_point(0.1, 1e-4, 1e-2), _point(0.01, 1e-8, 1e-1, failure="slips: ..."), _point(0.001, 1e-12, 1.0)]
    assert curve_cost(broken, 1e-6).seconds_per_sim_second == 1.0  # a failure breaks the curve


def test_level_table_gives_each_ratio_with_its_range_over_runs():
    points = []
    for run, scale in ((1, 1.0), (2, 2.0), (3, 1.5)):  # MuJoCo 10x, 20x, 15x rbody's cost in the three runs
        points += [_point(0.1, 1e-8, 1e-3, run=run),
                   _point(0.1, 1e-8, 1e-2 * scale, backend="mujoco", method="RK4", run=run)]
    table, standing = level_table(points, "s", ["rbody", "mujoco"])
    first = standing[0]
    assert sorted(first["ratios"]) == pytest.approx([10.0, 15.0, 20.0]) and first["ratio"] == pytest.approx(15.0)
    assert "15x (10..20)" in table
    reduced = _point(0.1, 1e-8, 1e-3 * 2, backend="mujoco", method="RK4", settings=REDUCED_LABEL + "slide")
    assert column(reduced) == "mujoco reduced"
    _table, standing = level_table(points + [reduced], "s", ["rbody", "mujoco", "mujoco reduced"])
    assert standing[0]["ratios"][0] == pytest.approx(2.0)  # run 1: the reduction is the best other column


def test_tables_replace_only_the_marked_block():
    text = "a\n<!-- x:start -->\nold\n<!-- x:end -->\nb\n"
    assert replace_block(text, "x", "new") == "a\n<!-- x:start -->\nnew\n<!-- x:end -->\nb\n"
    with pytest.raises(ValueError, match="y:start"):
        replace_block(text, "y", "new")


def test_read_points_round_trips_bench_csv(tmp_path):
    from dataclasses import asdict

    from validation.bench.csvfile import write_csv

    points = [_point(0.1, 1e-8, 1e-3, run=2), _point(math.nan, math.nan, math.nan, failure="refused: 2-D", run=2)]
    path = write_csv(tmp_path / "bench.csv", (asdict(p) for p in points), COLUMNS, ["machine: test"])
    back = read_points(path)
    for name, value in asdict(points[0]).items():  # every field back, NaN as NaN
        got = getattr(back[0], name)
        assert got == value or (isinstance(value, float) and math.isnan(value) and math.isnan(got)), name
    assert back[1].failure == "refused: 2-D" and back[1].run == 2 and isinstance(back[1].repeats, int)


@pytest.mark.crosssim
def test_bench_of_one_engine_sweeps_its_settings_and_dt(tmp_path):
    """--engine bullet: Bullet's series alone (the others not run); on contacts each solver setting is a series of
    its own; on the rod its semi-implicit Euler is first order (the error falls with dt)."""
    pytest.importorskip("pybullet")
    from validation.bench.run import run_bench

    import io

    run_bench(tmp_path, names=["swinging_rod", "rolling_disc"], quick=True, engines=("bullet",), log=io.StringIO())
    rows = read_csv(tmp_path / "bench.csv")
    assert {r["backend"] for r in rows} == {"bullet"}
    rod = sorted((r for r in rows if r["scene"] == "swinging_rod" and not r["failure"]), key=lambda r: -r["dt"])
    assert len(rod) >= 5
    slope = math.log(rod[0]["error"] / rod[-1]["error"]) / math.log(rod[0]["dt"] / rod[-1]["dt"])
    assert 0.8 < slope < 1.2  # first order
    settings = {r["settings"] for r in rows if r["scene"] == "rolling_disc"}
    assert any("solver_iterations" in s for s in settings)


def test_peer_table_reads_each_engine_off_its_curve():
    """The README's peers table: a column per engine, its least cost at each level it reaches on its curve, '-'
    for an engine that does not express the scene, 'never' for one swept that does not reach the level."""
    from validation.bench.tables import peer_table

    def curve(backend, settings, costs_errors):
        return [Point("rod", backend, "m", settings, dt, error=e, seconds_per_sim_second=c)
                for dt, (c, e) in zip((1e-1, 1e-2, 1e-3), costs_errors)]

    points = (curve("rbody", "default", [(1e-5, 1e-4), (1e-4, 1e-8), (1e-3, 1e-12)])
              + curve("mujoco", "default", [(1e-4, 1e-3), (1e-3, 1e-7), (1e-2, 1e-11)])
              + curve("bullet", "solver_iterations=50", [(1e-3, 1e-2), (1e-2, 1e-3), (1e-1, 1e-4)]))
    table = peer_table(points)
    row = next(line for line in table.splitlines() if line.startswith("| rod | 1e-03 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2].startswith("1e-05") and cells[3].startswith("0.0001 (MuJoCo") and cells[4] == "-"
    assert cells[5].startswith("0.01 (m, solver_iterations=50")
    row = next(line for line in table.splitlines() if line.startswith("| rod | 1e-06 |"))
    assert row.rstrip().endswith("| never |")  # Bullet swept, never at 1e-6
