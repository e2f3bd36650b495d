"""Speed against error: the work-precision benchmark of rbody, MuJoCo and pymunk.

    python -m validation bench [--scene NAME ...] [--quick] [--out DIR]

For every scene of validation/bench/scenes.py, every backend that can run it and each of its
methods or settings, a sweep of dt; at each point

    error  = max over the run of |x(t) - x*(t)| of the scene's main observable (compare.max_abs_error),
             x* the exact solution (the chain: rbody's DOP853 reference run at rtol 1e-13)
    drift  = compare.energy_error: max |E - E*| / max |E*|
    cost   = seconds of stepping per simulated second: meta["step_seconds"] / simulated time, after one
             warm-up run per series, the minimum of up to REPEATS runs (fewer when a run is long: the
             `repeats` column says how many)

A run that blows up or is refused as beyond the stability limit (SimulationError: "unstable"), miscounts
impacts or slips is a row with its `failure` reason, never dropped. What each backend's step_seconds holds: rbody the whole simulate call
after its kernels are compiled (stepping and the observables); MuJoCo the mujoco.rollout calls alone;
pymunk the space.step calls alone (so MuJoCo's and pymunk's translation of states into observables is
free here and rbody's is not).

Outputs in DIR: bench.csv (every point; machine and versions in '#' lines), wp_<scene>.png (work-
precision and energy panels), batch.csv and growth.csv (validation.bench.batch, bench.growth), their
figures, and summary.md (validation.bench.report).

The modules, each importing only those above it: scenes (the scenes and their series), csvfile (the
CSV files and their '#' header), sweep (one point, one series, one scene), report (figures, summary),
batch and growth (the batch and growth measurements), run (the command).
"""
