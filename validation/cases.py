"""The main command's cases: each scene at documented default settings, with its metrics.

Time steps: 1e-3 s for every time-stepped backend (a common, honest default); rbody's
event-driven scenes use dt only for sampling. Settings per backend are the ones DESIGN.md and the
backend modules document as right for the scene (elastic contacts, elliptic cones for rolling).
"""

from __future__ import annotations

import numpy as np

import rbody
from rbody import scenes
from validation.evaluate import Case

DT = 1e-3


def pendulum_cases(quick: bool) -> list[Case]:
    t_end = 2.0 if quick else 10.0
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=t_end)
    disc = rbody.Inertia.disc(2.0, 0.25, "y")
    compound = scenes.compound_pendulum(disc, pivot=(0.25, 0.0, 0.0), theta0=2.0, t_end=t_end,
                                        shapes=(rbody.Shape("disc", "cylinder", (0.25, 0.01),
                                                            quat=(np.sqrt(0.5), np.sqrt(0.5), 0, 0)),))
    metrics = ("max_abs_error", "final_relative_error", "energy_error")
    settings = {"rbody": {"method": "rk4"}, "mujoco": {"integrator": "RK4"}}
    return [Case("swinging_rod", "pendulum", rod, {b: DT for b in ("rbody", "mujoco", "pymunk")}, metrics, settings),
            Case("compound_pendulum", "pendulum", compound, {b: DT for b in ("rbody", "mujoco", "pymunk")},
                 metrics, settings)]


ALL = ("rbody", "mujoco", "pymunk")


def rolling_cases(quick: bool) -> list[Case]:
    """Each body rolling on a 0.5 rad incline, the disc sliding (friction below mu_min), the race."""
    t_end = 0.5 if quick else 1.0
    bodies = ("disc",) if quick else ("disc", "hollow_cylinder", "solid_sphere", "spherical_shell")
    cases = []
    for body in bodies:
        scene = scenes.rolling(body, radius=0.1, incline=0.5, friction=1.0, t_end=t_end)
        cases.append(Case(f"rolling_{body}", "rolling", scene, {b: DT for b in ALL},
                          ("max_abs_error", "final_relative_error", "energy_error", "max_slip")))
    sliding = scenes.rolling("disc", radius=0.1, incline=0.5, friction=0.05, t_end=t_end)
    cases.append(Case("sliding_disc", "rolling", sliding, {b: DT for b in ALL},
                      ("max_abs_error", "final_relative_error", "energy_error")))
    race = scenes.rolling_race(("disc", "hollow_cylinder", "solid_sphere", "spherical_shell"), radius=0.1,
                               incline=0.3, length=0.5 if quick else 2.0)
    cases.append(Case("rolling_race", "race", race, {b: DT for b in ALL}, ("arrival_error", "max_abs_error")))
    return cases


def default_cases(quick: bool = False) -> list[Case]:
    """Every case of the main command; quick keeps each one short (the CLI test and CI)."""
    return pendulum_cases(quick) + rolling_cases(quick)
