"""The main command's cases: each scene at documented default settings, with its metrics.

Time steps: 1e-3 s for every time-stepped backend (a common, honest default), the peers Pinocchio and Bullet
included (each runs the scenes it can express: Pinocchio the contact-free trees, Bullet the trees and the
contacts); rbody's event-driven scenes use dt only for sampling. Settings per backend are the ones DESIGN.md and the
backend modules document as right for the scene (elastic contacts, elliptic cones for rolling).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

import rbody
from rbody import scenes
from validation.backends import ENGINES
from validation.evaluate import Case

DT = 1e-3
ALL = ENGINES   # rbody, MuJoCo, pymunk and the peers Pinocchio and Bullet
# Bullet's pi runs beyond this many steps are not run by the main command: each is a Python loop over
# stepSimulation and a contact query (about 30 us a step here), and Bullet misses the count from N = 0 on (a sphere
# meeting a static box stops dead: tests/validation/test_peers.py); N = 3 would take ~1e6 steps, N = 4 ~8e6.
BULLET_PI_STEPS = 300_000


def pendulum_cases(quick: bool) -> list[Case]:
    t_end = 2.0 if quick else 10.0
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=t_end)
    disc = rbody.Inertia.disc(2.0, 0.25, "y")
    compound = scenes.compound_pendulum(disc, pivot=(0.25, 0.0, 0.0), theta0=2.0, t_end=t_end,
                                        shapes=(rbody.Shape("disc", "cylinder", (0.25, 0.01),
                                                            quat=(np.sqrt(0.5), np.sqrt(0.5), 0, 0)),))
    metrics = ("max_abs_error", "final_relative_error", "energy_error")
    settings = {"rbody": {"method": "rk4"}, "mujoco": {"integrator": "RK4"}, "pinocchio": {"method": "rk4"}}
    return [Case("swinging_rod", "pendulum", rod, {b: DT for b in ALL}, metrics, settings),
            Case("compound_pendulum", "pendulum", compound, {b: DT for b in ALL}, metrics, settings)]


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


def chain_cases(quick: bool) -> list[Case]:
    """The double rod pendulum: no closed form, so every backend is compared with DOP853 at rtol 1e-13."""
    chain = scenes.pendulum_chain(2, theta0=(1.0, 0.5), t_end=2.0 if quick else 5.0)
    return [Case("double_pendulum", "chain", chain, {b: DT for b in ALL}, ("max_abs_error", "energy_error"),
                 {"rbody": {"method": "rk4"}, "mujoco": {"integrator": "RK4"}, "pinocchio": {"method": "rk4"}},
                 reference="reference")]


def collision_cases(quick: bool) -> list[Case]:
    """Newton's cradle (three balls, elastic) and the pi collisions.

    The pi scenes give the heavy ball a speed of 10^-N, which keeps the light ball near 1 m/s where a
    1 ms step resolves its flight, and a spacing of 0.3 m, so that the run (about 3 spacing / speed)
    stays short enough to step at dt = 1e-3.
    """
    cradle = scenes.line_collisions((1.0, 1.0, 1.0), (0.0, 0.5, 0.7), (1.0, 0.0, 0.0), radii=0.1,
                                    walls=(), t_end=1.0)
    cases = [Case("newtons_cradle", "collisions", cradle, {b: DT for b in ALL}, ("max_abs_error", "energy_error"))]
    for digits in range(3 if quick else 5):
        scene = scenes.pi_collisions(digits, speed=10.0**-digits, spacing=0.3, radius=0.05)
        # rbody's dt only samples the trajectory: a thousand samples of the whole run.
        # The others count contact onsets at every step; they keep about a thousand samples of the run.
        keep = {"save_every": max(1, int(scene.t_end / DT / 1000))}
        steps = scene.t_end / DT
        skipped = {} if steps <= BULLET_PI_STEPS else {
            "bullet": f"not run by the main command: {steps:.2g} steps of pybullet's Python loop (~{steps * 3e-5:.0f} s); "
                      "Bullet misses the count from N = 0 on (a sphere stops dead at a static wall)"}
        cases.append(Case(f"pi_collisions_{digits}", "pi", scene, {"rbody": scene.t_end / 1000, "mujoco": DT,
                                                                  "pymunk": DT, "pinocchio": DT, "bullet": DT},
                          ("count_error", "pi_digits"), {"mujoco": keep, "pymunk": keep, "bullet": keep},
                          skipped=skipped))
    return cases


def rotation_cases(quick: bool) -> list[Case]:
    """A body with principal moments 1, 2, 3 kg m^2 spun near its intermediate axis (tennis racket)."""
    body = rbody.Inertia(2.0, np.zeros(3), np.diag([1.0, 2.0, 3.0]))
    scene = scenes.free_rotation(body, omega0=(0.05, 2.0, 0.05), t_end=4.0 if quick else 20.0)
    return [Case("free_rotation", "free_rotation", scene, {b: DT for b in ALL},
                 ("max_abs_error", "energy_error"), {"rbody": {"method": "rk4"}, "mujoco": {"integrator": "RK4"},
                                                     "pinocchio": {"method": "rk4"}})]


def stacked_balls_case(quick: bool) -> list[Case]:
    """M = 1 kg under m = 0.05 kg, dropped from 1 m, with a gap of 0.02 m between the balls, for every
    backend; the exact solution includes the gap. Finding: with gap 0 (the chapter's touching balls)
    MuJoCo and pymunk resolve the floor and ball-ball contacts together in one step and lose the kick
    that sends the small ball up (v/u) ^ 2 as high; the gap lets the large ball's bounce come first."""
    del quick  # the run already ends where the small ball tops out (about 1.7 s)
    scene = scenes.stacked_balls(1.0, 0.05, drop_height=1.0, gap=0.02)
    return [Case("stacked_balls", "stacked_balls", scene, {b: DT for b in ALL},
                 ("max_abs_error", "energy_error"))]


def scattering_case(quick: bool) -> list[Case]:
    """Equal discs, impact parameter = radius (a 30 degree contact angle), elastic and frictionless."""
    del quick  # 1 s at 1 m/s
    scene = scenes.scattering(0.1, radius=0.1)
    return [Case("scattering", "scattering", scene, {b: DT for b in ALL}, ("max_abs_error", "energy_error"))]


def variable_mass_cases(quick: bool) -> list[Case]:
    """The rocket with linear drag burning from 100 kg to its 40 kg dry mass in 6 s, then coasting; the
    avalanche on a 0.5 rad slope. MuJoCo and pymunk set the mass before every step and apply the force
    along the slide (validation.backends): first order in dt."""
    rocket = scenes.rocket(100.0, burn_rate=10.0, exhaust_speed=50.0, dry_mass=40.0, drag=2.0,
                           t_end=4.0 if quick else 8.0)
    avalanche = scenes.avalanche(0.5, t_end=1.0 if quick else 3.0)
    metrics = ("max_abs_error", "final_relative_error")
    return [Case("rocket", "variable_mass", rocket, {b: DT for b in ALL}, metrics),
            Case("avalanche", "variable_mass", avalanche, {b: DT for b in ALL}, metrics)]


def two_body_case(quick: bool) -> list[Case]:
    """m1 = 1, m2 = 2, G = 1, a bound orbit of eccentricity 0.3 (period 6.19 s), two periods (one quick).
    MuJoCo and pymunk apply the pair force every step (validation.backends)."""
    scene = scenes.two_body(1.0, 2.0, separation=(1.0, 0.0, 0.0), relative_velocity=(0.0, 0.0, np.sqrt(3.9)),
                            t_end=1.0)
    scene = replace(scene, t_end=(1 if quick else 2) * scene.period)
    return [Case("two_body", "two_body", scene, {b: DT for b in ALL}, ("max_abs_error", "energy_error"),
                 {"rbody": {"method": "rk4"}, "mujoco": {"integrator": "RK4"}})]


def particles_case(quick: bool) -> list[Case]:
    """Ten particles with central pair forces: rbody only (MuJoCo and pymunk refuse a scene with no
    layout: no body touches or is jointed to another)."""
    scene = scenes.particles(10, seed=1, forces="central", t_end=1.0 if quick else 5.0)
    return [Case("particles", "particles", scene, {b: DT for b in ALL}, ("energy_error",),
                 {"rbody": {"method": "rk4"}})]


def default_cases(quick: bool = False) -> list[Case]:
    """Every case of the main command; quick keeps each one short (the CLI test and CI)."""
    return (pendulum_cases(quick) + chain_cases(quick) + rolling_cases(quick) + collision_cases(quick)
            + rotation_cases(quick) + stacked_balls_case(quick) + scattering_case(quick)
            + variable_mass_cases(quick) + two_body_case(quick) + particles_case(quick))
