"""The time-stepping finds each touching pair's candidates at most once a step: a step's end finds them for its
projection (dynamics.state_gaps) and keeps them with the geoms' poses (contacts.broadphase.kept_size); the next
step starts at that configuration and reads them instead of finding them again, and its end reads them too where
a flat-faced pair has moved by less than its poses' round-off (rows.moved_within_round_off: a body at rest moves
by round-off each step; a round geom's pair is found again, since its point of contact rolls as a body rocks).
Reading them must change nothing beyond round-off: the runs below, each step given the kept geometry or an empty
one, agree to round-off, over pairs whose candidates are always exact (boxes) and pairs that
may answer with a bound (an ellipsoid's, a mesh's). Each step also lists its problem's rows, ascending, and
sets its impulses on those rows only (the next step clears P there and nowhere else)."""

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import rbody
from rbody import Scene, from_mjcf
from rbody.engine import multibody as mb
from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.jacobians import row_count, unit_count
from rbody.engine.constraints.stepping import (EXACT_ROWS, FLAGGED_GAP, MODES, PGS_SWEEPS, STEP_TOLERANCE,
                                               MoreauRun, moreau_step, step_arena)
from rbody.engine.contacts.broadphase import kept_size, pair_at, pair_count, pair_span
from rbody.engine.contacts.rows import KEPT, KEPT_MOTION, POSED, kept_for, kept_geometry_size

sys.path.insert(0, str(Path(__file__).parent))
from test_contact_closed_forms import stack_layout  # noqa: E402

ROLLING_SHAPES = """
<mujoco>
  <asset>
    <mesh name="wedge" vertex="0 0 0  0.2 0 0  0 0.15 0  0 0 0.1  0.2 0 0.1  0 0.15 0.1"/>
  </asset>
  <worldbody>
    <geom type="plane" size="2 2 0.1" friction="0.6"/>
    <body pos="0 0 0.2" euler="20 10 5">
      <freejoint/>
      <geom type="ellipsoid" size="0.1 0.06 0.04" mass="1" friction="0.6"/>
    </body>
    <body pos="0.5 0 0.15" euler="20 10 5">
      <freejoint/>
      <geom type="mesh" mesh="wedge" mass="1" friction="0.6"/>
    </body>
    <body pos="-0.5 0 0.12">
      <freejoint/>
      <geom type="box" size="0.1 0.08 0.05" mass="1" friction="0.6"/>
    </body>
  </worldbody>
</mujoco>
"""


def step_run(scene: Scene, dt: float, steps: int, keep: bool):
    """(states (steps + 1, n), whether each step started at the kept configuration, whether each step's end left
    every pair's kept poses as they were: it read every near pair's kept candidates, or found one again at poses
    with the same bits, as a round geom held exactly still is): moreau_step by hand, the kept geometry carried from
    step to step (keep) or a fresh empty one given to every step."""
    prepared = rbody.prepare(scene, dt=dt, method="moreau")
    model = prepared.model
    run = MoreauRun(model.constraints, np.asarray(model.params)[0], "test")
    p, y = run.p, np.array(np.asarray(model.y0)[0], dtype=np.float64)
    rows = model.constraints.rows
    P, problem_rows = np.zeros(rows), np.zeros(rows + 1, dtype=np.int64)
    size = kept_size(p)
    kept = np.zeros(size)
    arena = step_arena(p)
    states, read, ends = [y.copy()], [], []
    nq = int(p[mb.H_NQ])
    for _ in range(steps):
        if not keep:
            kept = np.zeros(size)
        read.append(kept_for(kept, y[:nq].copy()))
        poses = _poses(p, kept).copy()
        status, _residual, m = moreau_step(p, y, dt, P, EXACT_ROWS, PGS_SWEEPS, STEP_TOLERANCE, problem_rows,
                                           MODES["moreau"], kept, *arena)
        assert status == 0
        listed = problem_rows[1:1 + problem_rows[0]]  # the step's problem: its rows, ascending, and P set on them only
        assert problem_rows[0] == m and np.all(np.diff(listed) > 0)
        assert set(np.flatnonzero(P)) <= set(listed.tolist())
        states.append(y.copy())
        ends.append(kept_for(kept, y[:nq].copy()) and np.array_equal(poses, _poses(p, kept)))
    return np.array(states), np.array(read), np.array(ends)


def _poses(p: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """The kept memory's poses of every contact pair (rows.keep_poses): unchanged by a step whose end read every
    near pair's kept candidates and found none again."""
    start = kept_geometry_size(int(p[mb.H_NQ]), unit_count(p), 0)
    return kept[start:kept_geometry_size(int(p[mb.H_NQ]), unit_count(p), pair_count(p))]


@pytest.mark.parametrize("name", ["stack", "shapes"])
def test_the_kept_geometry_changes_nothing_beyond_round_off(name):
    """Reading the kept geometry, at the next step's start (the same configuration) and at its end (the pair moved
    by less than its poses' round-off), leaves the run within round-off of one that finds every pair again."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # AccuracyWarning of the step
        scene = (Scene.from_layout(stack_layout(), t_end=1.0) if name == "stack"
                 else from_mjcf(ROLLING_SHAPES, t_end=1.0))
        kept, read, ends = step_run(scene, 2e-3, 300, keep=True)
        fresh, never, _ = step_run(scene, 2e-3, 300, keep=False)
    assert not never.any()
    assert read[1:].mean() > 0.5          # the later steps mostly start where the last one's end found its pairs
    assert np.all(np.isfinite(kept))
    if name == "stack":
        assert ends[-100:].mean() > 0.9   # at rest, the ends read every pair found before
        assert np.abs(kept - fresh).max() <= 1e-14  # metre-scale coordinates (measured 1.5e-15 over 500 steps)
        return
    # The wedge (the mesh, qpos 7:14, qvel 27:33) lands 0.4 degrees from flat: which of its corners touches first is
    # decided at round-off, and its place of rest with it (among runs that find every pair each step, one raised by
    # one unit in the last place of its start's height rests 2.1e-7 m from the other, its velocity 1.1e-3 m/s apart
    # on the way). The runs must agree to round-off on the other two bodies and both rest the wedge on its base.
    wedge = np.r_[7:14, 27:33]
    others = np.setdiff1d(np.arange(21 + 18), wedge)  # the qpos and qvel of the ellipsoid and the box
    assert ends[-30:].mean() > 0.9
    assert np.abs(kept[:, others] - fresh[:, others]).max() <= 1e-14
    for run in (kept, fresh):
        height, tilt, velocity = run[-1, 9], run[-1, 11:13], run[-1, 27:33]
        assert abs(height) <= 1e-14 and np.abs(tilt).max() <= 1e-14 and np.abs(velocity).max() <= 1e-14
    assert np.abs(kept[-1, wedge] - fresh[-1, wedge]).max() <= 1e-5


def stack_at_rest():
    """(params p, state y, kept memory) of the five-box stack after 50 steps of 2 ms, stepped by hand."""
    return stepped(Scene.from_layout(stack_layout(), t_end=1.0), 50)


def stepped(scene: Scene, steps: int):
    """(params p, state y, kept memory) of scene after `steps` steps of 2 ms, moreau_step by hand."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prepared = rbody.prepare(scene, dt=2e-3, method="moreau")
    run = MoreauRun(prepared.model.constraints, np.asarray(prepared.model.params)[0], "test")
    p, y = run.p, np.array(np.asarray(prepared.model.y0)[0], dtype=np.float64)
    rows = row_count(p)
    P, problem_rows = np.zeros(rows), np.zeros(rows + 1, dtype=np.int64)
    kept, arena = np.zeros(kept_size(p)), step_arena(p)
    for _ in range(steps):
        moreau_step(p, y, 2e-3, P, EXACT_ROWS, PGS_SWEEPS, STEP_TOLERANCE, problem_rows, MODES["moreau"], kept, *arena)
    return p, y, kept


@pytest.mark.parametrize("lowered", [1, 2, 4, 6])
def test_a_kept_gap_is_within_its_poses_round_off_of_the_gap_found_again(lowered):
    """The stack at rest, its top box lowered by `lowered` units in the last place of its height (5.6e-17 m each):
    within its pair's bound, eps times its geoms' reach from the origin (1.2 m: 2.7e-16 m), the end reads the kept
    gaps (every pair found just before the move), which then differ from the gaps found again by the move and no
    more; beyond it (six units) the pair is found again and its gaps are the fresh ones."""
    p, y, _kept = stack_at_rest()
    rows = row_count(p)
    kept = np.zeros(kept_size(p))
    dyn.state_gaps(p, y, np.zeros(rows), FLAGGED_GAP, kept)  # every near pair found at this state
    top = 7 * 4 + 2  # the top box's height in qpos
    move = lowered * np.spacing(y[top])
    y[top] -= move
    reading = kept.copy()
    read_gaps, found_gaps = np.zeros(rows), np.zeros(rows)
    dyn.state_gaps(p, y, read_gaps, FLAGGED_GAP, reading)
    dyn.state_gaps(p, y, found_gaps, FLAGGED_GAP)
    top_rows = _pair_rows(p, pair_count(p) - 1)  # the last pair: the top two boxes
    touching = top_rows[np.abs(found_gaps[top_rows]) <= 1e-15]  # (its other slots: corners apart, or none)
    bound = KEPT_MOTION * 1.2  # a pair's bound here, about (and each pair's kept gaps lag by at most their own)
    for i in range(pair_count(p) - 1):  # the pairs below, not moved: within their bound of the gaps found again
        rows_i = _pair_rows(p, i)
        finite = rows_i[np.isfinite(found_gaps[rows_i])]
        assert np.abs(read_gaps[finite] - found_gaps[finite]).max() <= bound
    apart = np.abs(read_gaps[touching] - found_gaps[touching])
    assert len(touching) >= 4
    if move <= bound:
        assert np.array_equal(_poses(p, reading), _poses(p, kept))  # nothing found again
        assert 0.0 < apart.max() <= move + bound  # the kept gaps lag the move
    else:
        assert not np.array_equal(_poses(p, reading), _poses(p, kept))
        assert apart.max() == 0.0


@pytest.mark.parametrize("shift, found_again", [(2, 0), (2000, 1)])
def test_a_pair_moved_beyond_its_poses_round_off_is_found_again(shift, found_again):
    """The stack at rest, its top box moved sideways by `shift` units in the last place of its x (0.04 m): two
    (1.4e-17 m, within eps times its pair's reach from the origin, about 1.4 m) leaves every pair read from the kept
    memory; two thousand (1.4e-14 m) finds the top pair again, and only it. (Raised instead, the top pair would part:
    its separating axes' bound then answers it.)"""
    p, y, kept = stack_at_rest()
    rows = row_count(p)
    dyn.state_gaps(p, y, np.zeros(rows), FLAGGED_GAP, kept)  # every near pair found or read at this state
    top = 7 * 4  # the top box's x in qpos (five free joints)
    y[top] += shift * np.spacing(y[top])
    reading = kept.copy()
    dyn.state_gaps(p, y, np.zeros(rows), FLAGGED_GAP, reading)
    before, after = _poses(p, kept).reshape(-1, POSED), _poses(p, reading).reshape(-1, POSED)
    changed = [i for i in range(pair_count(p)) if not np.array_equal(before[i], after[i])]
    assert len(changed) == found_again
    if changed:  # the top pair, posed again where its top box was raised (its last finding at most eps apart)
        np.testing.assert_allclose(np.abs(after[changed[0]] - before[changed[0]]).max(), 2000 * np.spacing(0.04),
                                   rtol=0.01)


def test_only_flat_faced_pairs_are_read_at_a_steps_end():
    """A sphere and a box resting on the floor, the kept memory's gaps overwritten with 0.5 m where the end's gaps
    were just found: at the same state the box's pair (flat faces: its corners) reads them, the sphere's pair is
    found again (its point of contact would roll as it rocks: rows.moved_within_round_off)."""
    shapes = """
    <mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
      <body pos="0 0 0.1"><freejoint/><geom type="sphere" size="0.1" mass="1"/></body>
      <body pos="0.5 0 0.05"><freejoint/><geom type="box" size="0.1 0.1 0.05" mass="1"/></body>
    </worldbody></mujoco>"""
    p, y, kept = stepped(from_mjcf(shapes, t_end=1.0), 20)
    rows, nq, units = row_count(p), int(p[mb.H_NQ]), unit_count(p)
    found = np.zeros(rows)
    dyn.state_gaps(p, y, found, FLAGGED_GAP, kept)
    kept[1 + nq + 1:1 + nq + KEPT * units:KEPT] = 0.5  # every unit's kept gap
    gaps = np.zeros(rows)
    dyn.state_gaps(p, y, gaps, FLAGGED_GAP, kept)
    sphere_rows, box_rows = _pair_rows(p, 0), _pair_rows(p, 1)
    assert np.abs(found[sphere_rows]).min() <= 1e-15 and np.abs(found[box_rows]).min() <= 1e-15  # both rest
    assert np.all(gaps[box_rows] == 0.5)                   # the box's corners read from the kept memory
    assert np.array_equal(gaps[sphere_rows], found[sphere_rows])  # the sphere's point found again


def _pair_rows(p: np.ndarray, i: int) -> np.ndarray:
    """Contact pair i's candidates' normal rows (broadphase.pair_span)."""
    first, slots, row0, width = pair_span(p, pair_at(p, i))
    return row0 + width * np.arange(slots)
