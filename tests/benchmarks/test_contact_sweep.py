"""benchmarks/contact_sweep.py: its measures on closed-form samples, its choice of the cheapest run per error level,
and (slow) its --quick run end to end: the table, the points and the figure, rbody in the rigid limit."""

import csv
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "contact_sweep.py"
spec = importlib.util.spec_from_file_location("contact_sweep", SCRIPT)
sweep = importlib.util.module_from_spec(spec)
sys.modules["contact_sweep"] = sweep  # dataclasses look their module up there
spec.loader.exec_module(sweep)


def sphere_samples(dt, rolls=True):
    """The closed form of the thrown sphere sampled every dt: sliding at v0 - mu g t, spinning up at 5 mu g t/(2 r),
    rolling at 5/7 v0 from t* (or, when rolls is False, skidding on at v0 without spin: no friction)."""
    t = np.arange(0.0, 1.0 + dt / 2, dt)
    mu, g, v0, r = sweep.MU_SPHERE, sweep.G, sweep.V0, sweep.RADIUS
    t_star = 2 * v0 / (7 * mu * g)
    v = np.where(t < t_star, v0 - mu * g * t, 5 / 7 * v0) if rolls else np.full_like(t, v0)
    w = np.where(t < t_star, 5 * mu * g * t / (2 * r), 5 / 7 * v0 / r) if rolls else np.zeros_like(t)
    qpos = np.zeros((t.size, 7))
    qpos[:, 2] = r
    zeros = np.zeros_like(t)
    return {"t": t, "qpos": qpos, "v": np.stack([v, zeros, zeros], 1), "w": np.stack([zeros, w, zeros], 1)}


@pytest.mark.parametrize("dt", [1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1])  # the sweep's steps (0.1: two sliding samples)
def test_sphere_measures_read_the_closed_form_as_exact_and_a_skid_as_never_rolling(dt):
    # the closed form sampled every dt: the slip is linear in t up to t*, the line through the last two sliding
    # samples finds the threshold whatever dt (a line across the kink at t*, to the first rolling sample, read it
    # 7.6e-4 s late at dt = 3e-3 and 5.6e-3 s at 1e-2)
    exact = sweep.sphere_measures(sphere_samples(dt))
    assert exact["speed"] <= 1e-15 and exact["sink"] == 0.0
    assert exact["t_star"] <= 1e-12
    skid = sweep.sphere_measures(sphere_samples(dt, rolls=False))
    assert math.isinf(skid["t_star"]) and skid["speed"] == pytest.approx(2 / 7 * sweep.V0)


def test_sphere_measures_read_a_slip_that_stalls_before_it_drops_across_the_drop():
    # a soft contact's slip may hold still between samples, then fall below the threshold: no line through the two
    # equal samples (it would never reach the threshold), the line across the drop instead
    run = sphere_samples(1e-2)
    t = run["t"]
    stall = (t > 0.1) & (t < 0.25)
    run["v"][stall, 0] = run["v"][np.flatnonzero(stall)[0], 0]
    run["w"][stall, 1] = run["w"][np.flatnonzero(stall)[0], 1]
    k = np.flatnonzero(t >= 0.25)[0]
    slip0 = run["v"][k - 1, 0] - sweep.RADIUS * run["w"][k - 1, 1]
    crossing = t[k - 1] + (t[k] - t[k - 1]) * (slip0 - sweep.SLIP_THRESHOLD) / slip0  # rolling at t[k]: slip 0
    measured = sweep.sphere_measures(run)
    exact = (sweep.V0 - sweep.SLIP_THRESHOLD) / (3.5 * sweep.MU_SPHERE * sweep.G)
    assert measured["t_star"] == pytest.approx(abs(crossing - exact), rel=1e-12)


def test_stack_and_incline_measures_see_sinking_and_drift():
    qpos = np.zeros((3, 14))
    qpos[:, 2], qpos[:, 9] = 0.05, 0.15
    qpos[2, 9] -= 2e-4                      # the upper box sinks 0.2 mm
    qpos[1, 0] += 3e-5                      # the lower one drifts 0.03 mm and comes back
    measured = sweep.stack_measures({"qpos": qpos})
    assert measured["sink"] == pytest.approx(2e-4) and measured["drift"] == pytest.approx(3e-5)
    assert measured["rest"] == measured["sink"]
    assert sweep.incline_measures({"qpos": qpos})["creep"] == pytest.approx(3e-5)


def row(engine, cost, error, dt=1e-3, failure=""):
    return sweep.Row("sphere", engine, "f", f"{engine} {cost}", dt, {"speed": error}, cost, 0.0, 1, failure)


def test_cheapest_run_per_level_and_the_rows_below_mujocos_floor():
    rows = [row("mujoco", 1.0, 1e-3), row("mujoco", 5.0, 1e-4), row("mujoco", 0.1, 1e-5, failure="non-finite state"),
            row("rbody", 2.0, 1e-14), row("rbody", 0.5, 2e-3)]
    assert sweep.cheapest(rows, "sphere", "speed", "mujoco", 1e-3).cost == 1.0
    assert sweep.cheapest(rows, "sphere", "speed", "mujoco", 1e-4).cost == 5.0
    assert sweep.cheapest(rows, "sphere", "speed", "mujoco", 1e-5) is None      # the failed run does not count
    assert sweep.cheapest(rows, "sphere", "speed", "rbody", 1e-2).cost == 0.5
    assert sweep.floor_of(rows, "sphere", "speed", "mujoco").errors["speed"] == 1e-4
    lines = [line for line in sweep.level_table(rows) if line.startswith("| sphere: speed")]
    assert [line.split("|")[2].strip() for line in lines] == [
        "0.01", "0.001", "0.0001", "1e-05 and below: below MuJoCo's floor (0.0001)"]
    assert lines[1].split("|")[7].strip() == "2"                                 # rbody 2.0 s/s against 1.0


def test_a_time_constant_below_two_steps_runs_once_as_mujoco_runs_it():
    # MuJoCo runs any time constant below 2 dt as 2 dt: at dt = 0.03 both of (0.02, 0.002) are that run, so only
    # the larger is run, labelled with what it ran at; at 0.01 tc 0.02 is its own run (2 dt) and 0.002 is its run
    grid = (0.02, 0.002)
    assert sweep.clamped_duplicate(0.02, 0.03, grid) is None
    assert sweep.clamped_duplicate(0.002, 0.03, grid) == 0.02
    assert sweep.clamped_duplicate(0.02, 0.01, grid) is None
    assert sweep.clamped_duplicate(0.002, 0.01, grid) == 0.02
    assert sweep.clamped_duplicate(0.002, 1e-3, grid) is None     # 2 dt = 0.002: its own run
    assert sweep.clamped_duplicate(0.002, 3e-4, grid) is None
    setting = sweep.MujocoSetting(timeconst=0.02)
    assert setting.label_at(0.01) == setting.label
    assert setting.label_at(0.1).endswith("(run as 2 dt = 0.2)")
    case = sweep.CASES[0]
    row = sweep.mujoco_point(case, None, None, sweep.MujocoSetting(timeconst=0.002), 0.1, 1.0, 1, grid)
    assert row.failure.startswith("not run: the run of tc 0.02") and not row.errors   # refused before any run


@pytest.mark.parametrize("seconds, repeats, calls", [
    (1e-3, 3, 30),      # a short run: repeated until SHORT_REPEATS (30 ms in all, under SHORT_SECONDS)
    (4e-3, 3, 13),      # until its calls add up to SHORT_SECONDS (0.05 s: 13 of 4 ms)
    (0.1, 3, 3),        # a long one: the repeats asked for
    (1e-3, 1, 1),       # one timed run asked for (--quick): one
    (1.5, 3, 2),        # the budget (2 s) spent after two
])
def test_short_runs_are_repeated_until_they_add_up(seconds, repeats, calls):
    """Both engines' points are timed by repeat(): a run of a millisecond, whose minimum over three calls moves with
    the machine's load, is repeated until its calls add up to SHORT_SECONDS (at most SHORT_REPEATS)."""
    made = []

    def run():
        made.append(len(made))
        return seconds, "result"
    timed, first = sweep.repeat(run, repeats)
    assert len(timed) == len(made) == calls
    assert first == ("result",)


@pytest.mark.slow
def test_quick_run_prints_the_tables_and_writes_points_and_figure(tmp_path, capsys):
    """About 10 s once numba's cache is warm (minutes on the first run: compilation)."""
    figure, points = tmp_path / "sweep.png", tmp_path / "points.csv"
    assert sweep.main(["--quick", "--figure", str(figure), "--csv", str(points)]) == 0
    out = capsys.readouterr().out
    assert "machine" in out and "mujoco" in out and "rbody / MuJoCo" in out
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader(points.open()))
    primary = {"sphere": "speed", "incline": "creep", "stack": "rest"}
    for scene, measure in primary.items():
        # (a finer point may be skipped as predicted too long on a loaded machine: "not run", with its reason)
        ours = [r for r in rows if r["scene"] == scene and r["engine"] == "rbody" and r["family"] == "moreau"
                and not r["failure"].startswith("not run")]
        theirs = [r for r in rows if r["scene"] == scene and r["engine"] == "mujoco" and not r["failure"]]
        assert ours and theirs
        assert all(float(r[measure]) <= 1e-12 for r in ours)          # the rigid limit: round-off
        # MuJoCo's soft contacts: every setting of the quick grid misses the closed form by more than 1e-6
        assert min(float(r[measure]) for r in theirs) > 1e-6
    assert "humanoid figure standing" in out and "gripper holding a box" in out


def test_the_figure_stands_on_its_soles_and_the_pads_touch_the_box_at_qpos0():
    """The two models of the cost section start in contact, not above or inside: MuJoCo's own distances at qpos0."""
    import mujoco

    figure = mujoco.MjModel.from_xml_string(sweep.humanoid_xml())
    data = mujoco.MjData(figure)
    mujoco.mj_forward(figure, data)
    assert (figure.nbody, figure.nv) == (13, 24)                # world + 12 bodies; a free root and 18 hinges
    soles = [i for i in range(figure.ngeom) if figure.geom(i).name.startswith("sole_")]
    lowest = [data.geom_xpos[i][2] - figure.geom_size[i][0] for i in soles]   # capsules lying flat
    np.testing.assert_allclose(lowest, 0.0, rtol=0, atol=1e-12)
    # every other geom clear of the floor by its bounding sphere (the shins' lowest points are 5.5 cm up)
    others = [data.geom_xpos[i][2] - figure.geom_rbound[i] for i in range(1, figure.ngeom) if i not in soles]
    assert min(others) > 0.05
    gripper = mujoco.MjModel.from_xml_string(sweep.gripper_xml())
    data = mujoco.MjData(gripper)
    mujoco.mj_forward(gripper, data)
    box = gripper.geom("object").id
    for pad in ("pad_left", "pad_right"):
        distance = mujoco.mj_geomDistance(gripper, data, gripper.geom(pad).id, box, 0.01, None)
        assert abs(distance) <= 1e-12
