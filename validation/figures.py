"""Which figures the report draws, from the runs of the main command."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from validation import report


def make_figures(runs: dict, out: Path) -> list[tuple[str, str]]:
    """runs: case name -> (case, {backend: Trajectory}). Returns (caption, file name) pairs; a case no backend ran
    (e.g. the peers alone on a scene they refuse) has no figure."""
    runs = {name: (case, by_backend) for name, (case, by_backend) in runs.items() if by_backend}
    figures = []
    if "rolling_race" in runs:
        case, by_backend = runs["rolling_race"]
        t = np.linspace(0.0, case.scene.t_end, 400)
        exact = dict(case.scene.exact(t), t=t)
        figures.append(("The rolling race: distance against time, exact and each engine",
                        report.figure_race(by_backend, exact, case.scene.labels, out)))
    if "swinging_rod" in runs:
        case, by_backend = runs["swinging_rod"]
        figures.append(("The swinging rod: angle and energy error against time",
                        report.figure_pendulum(by_backend, case.scene.exact, out, "swinging_rod.png",
                                               "The swinging rod (theta0 = 1 rad)")))
    counts: dict[str, dict[int, int]] = {}
    for name, (case, by_backend) in runs.items():
        if name.startswith("pi_collisions"):
            for backend, run in by_backend.items():
                counts.setdefault(backend, {})[case.scene.digits] = int(run["collisions"][-1])
    if counts:
        figures.append(("Collision counts: leading digits of pi right, per backend", report.figure_pi(counts, out)))
    if "free_rotation" in runs:
        _case, by_backend = runs["free_rotation"]
        figures.append(("Free rotation: drift of the energy and of |L|", report.figure_rotation(by_backend, out)))
    if "stacked_balls" in runs:
        case, by_backend = runs["stacked_balls"]
        figures.append(("Stacked balls: heights against time, exact and each engine",
                        report.figure_series(by_backend, case.scene.exact, "small_height", {"small": ""},
                                             "small ball height [m]", "Stacked balls (M = 1 kg, m = 0.05 kg, "
                                             "gap 0.02 m)", out, "stacked_balls.png")))
    if "two_body" in runs:
        case, by_backend = runs["two_body"]
        figures.append(("The two-body problem: orbits, exact and each engine",
                        report.figure_orbit(by_backend, case.scene.exact, out)))
    if "rocket" in runs:
        case, by_backend = runs["rocket"]
        figures.append(("The rocket with drag: speed against time, exact and each engine",
                        report.figure_series(by_backend, case.scene.exact, "speed", {"": ""}, "speed [m/s]",
                                             "Rocket: burning to dry mass, then coasting", out, "rocket.png")))
    return figures
