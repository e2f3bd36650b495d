"""Speed against error: the work-precision benchmark of rbody, MuJoCo and pymunk.

    python -m validation bench [--scene NAME ...] [--quick] [--repeat N] [--out DIR]

For every scene of validation/bench/scenes.py, every backend that can run it and each of its
methods or settings, a sweep of dt; at each point

    error  = max over the run of |x(t) - x*(t)| of the scene's main observable (compare.max_abs_error),
             x* the exact solution (the chains: rbody's DOP853 reference run at rtol 1e-13)
    drift  = compare.energy_error: max |E - E*| / max |E*|
    cost   = seconds per simulated second of the same work on every side, meta["run_seconds"]: what
             turns the initial state into the scene's observables at the saved times. rbody: the whole
             simulate call after its kernels are compiled (model, stability check, stepping, every
             observable); MuJoCo: the rollout of the model with the sensors that record the observed
             quantities, the contact onsets and scene.observe; pymunk: the space.step loop with the reads
             of every saved body state and scene.observe. Model compilation is charged to no one. After one
             warm-up run per series, the minimum of up to REPEATS runs (fewer when a run is long: the
             `repeats` column says how many); the stepping alone (meta["step_seconds"]) is a column beside it.

Why this and not stepping alone everywhere: a user of rbody pays the whole call, and rbody's
observables are not deferred; charging the peers their own extraction makes both sides do the same work
without changing the engine.

A run that blows up or is refused as beyond the stability limit (SimulationError: "unstable"), miscounts
impacts or slips is a row with its `failure` reason, never dropped. The summary reads each level's cost
off every series' work-precision curve (interpolated in log-log between neighbouring valid points,
validation.bench.report.curve_cost); --repeat N runs every sweep N times (the `run` column) and gives
each ratio's median and range over the runs.

Outputs in DIR: bench.csv (every point; machine and versions in '#' lines), wp_<scene>.png (work-
precision and energy panels), batch.csv and growth.csv (validation.bench.batch, bench.growth), their
figures, and summary.md (validation.bench.report). validation.bench.tables writes the README's tables
from these files.

The modules, each importing only those above it: scenes (the scenes and their series; reduced, MuJoCo on
rbody's rolling reduction, is imported by it where used), csvfile (the CSV files and their '#' header),
sweep (one point, one series, one scene), report (figures, summary), batch and growth (the batch and
growth measurements), run (the command), tables (the README's tables).
"""
