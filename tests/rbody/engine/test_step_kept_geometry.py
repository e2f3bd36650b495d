"""The time-stepping finds each touching pair's candidates once a step: a step's end finds them for its projection
(dynamics.state_gaps) and keeps them (contacts.broadphase.kept_size); the next step starts at that configuration
and reads them instead of finding them again. Reading them must change nothing: the runs below, each step given
the kept geometry or an empty one, agree to the bit, over pairs whose candidates are always exact (boxes) and pairs
that may answer with a bound (an ellipsoid's, a mesh's). Each step also lists its problem's rows, ascending, and
sets its impulses on those rows only (the next step clears P there and nowhere else)."""

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import rbody
from rbody import Scene, from_mjcf
from rbody.engine import multibody as mb
from rbody.engine.constraints.stepping import (EXACT_ROWS, MODES, PGS_SWEEPS, STEP_TOLERANCE, MoreauRun,
                                               moreau_step, step_arena)
from rbody.engine.contacts.broadphase import kept_size
from rbody.engine.contacts.rows import kept_for

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
    """(states (steps + 1, n), whether each step started at the kept configuration): moreau_step by hand, the kept
    geometry carried from step to step (keep) or a fresh empty one given to every step."""
    prepared = rbody.prepare(scene, dt=dt, method="moreau")
    model = prepared.model
    run = MoreauRun(model.constraints, np.asarray(model.params)[0], "test")
    p, y = run.p, np.array(np.asarray(model.y0)[0], dtype=np.float64)
    rows = model.constraints.rows
    P, problem_rows = np.zeros(rows), np.zeros(rows + 1, dtype=np.int64)
    size = kept_size(p)
    kept = np.zeros(size)
    arena = step_arena(p)
    states, read = [y.copy()], []
    nq = int(p[mb.H_NQ])
    for _ in range(steps):
        if not keep:
            kept = np.zeros(size)
        read.append(kept_for(kept, y[:nq].copy()))
        status, _residual, m = moreau_step(p, y, dt, P, EXACT_ROWS, PGS_SWEEPS, STEP_TOLERANCE, problem_rows,
                                           MODES["moreau"], kept, *arena)
        assert status == 0
        listed = problem_rows[1:1 + problem_rows[0]]  # the step's problem: its rows, ascending, and P set on them only
        assert problem_rows[0] == m and np.all(np.diff(listed) > 0)
        assert set(np.flatnonzero(P)) <= set(listed.tolist())
        states.append(y.copy())
    return np.array(states), np.array(read)


@pytest.mark.parametrize("name", ["stack", "shapes"])
def test_the_kept_geometry_changes_no_bit(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # AccuracyWarning of the step
        scene = (Scene.from_layout(stack_layout(), t_end=1.0) if name == "stack"
                 else from_mjcf(ROLLING_SHAPES, t_end=1.0))
        kept, read = step_run(scene, 2e-3, 300, keep=True)
        fresh, never = step_run(scene, 2e-3, 300, keep=False)
    assert not never.any()
    assert read[1:].mean() > 0.5          # the later steps mostly start where the last one's end found its pairs
    assert np.array_equal(kept, fresh)    # and reading them gives the same bits as finding them again
    assert np.all(np.isfinite(kept))

