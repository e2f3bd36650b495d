"""A time-stepping run's record of its impulses (rbody.engine.constraints.stepping: _record, StepForces): each
saved sample's nonzero impulses, kept as (row, value) pairs after the last sample's."""

import numpy as np

from rbody.engine.constraints.stepping import StepForces, _record


def test_a_run_records_each_samples_nonzero_impulses_in_row_order():
    """stepping._record appends a sample's nonzero impulses after the last sample's, growing its arrays as far as
    they must (here from 4 slots past several doublings at once), and StepForces reads every sample back as it was.
    It reads P on the step's problem rows alone (a row in the problem may push nothing: not recorded)."""
    rng = np.random.default_rng(3)
    samples = [np.where(rng.random(500) < fraction, rng.normal(size=500), 0.0) for fraction in (0.0, 0.01, 0.3, 0.05)]
    starts = np.zeros(len(samples) + 1, dtype=np.int64)
    rows, values, used = np.empty(4, dtype=np.int64), np.empty(4), 0
    for s, P in enumerate(samples):
        in_problem = np.flatnonzero((P != 0.0) | (rng.random(500) < 0.1))  # ascending, as the step lists them
        problem_rows = np.concatenate([[in_problem.size], in_problem, np.zeros(500 - in_problem.size)]).astype(np.int64)
        rows, values, used = _record(P, problem_rows, s, starts, rows, values, used)
    assert used == sum(int(np.count_nonzero(P)) for P in samples) > 4
    forces = StepForces(starts, rows[:used], values[:used], 500, dt=0.5)
    for s, P in enumerate(samples):
        kept = rows[starts[s]:starts[s + 1]]
        assert np.array_equal(kept, np.flatnonzero(P))  # in row order
        assert np.array_equal(forces.dense()[s], P / 0.5)
