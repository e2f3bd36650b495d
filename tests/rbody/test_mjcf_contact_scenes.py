"""The chapter's contact scenes written as MJCF contact models (walls and floors as planes, spheres on slide
joints) and run by the general engine's event-driven contacts (method "rk4"), against the built-in scenes' exact
kernels (rbody.scenes: pi collisions, Newton's cradle as line collisions, the stacked balls); and the rolling race
(a disc, a hoop and a sphere free on a tilted plane) by the time-stepping, against the race's exact solution."""

import math

import numpy as np
import pytest

import rbody
from rbody.scenes.collisions import line_collisions, pi_collisions
from rbody.scenes.rolling import rolling_race
from rbody.scenes.stacked_balls import stacked_balls

WALL = '<geom name="wall" type="plane" size="0 0 1" quat="0.7071067811865476 0 0.7071067811865476 0"/>'  # normal +x


def line_model(masses, positions, radius, wall=True, restitution=1.0):
    """Balls on slide joints along x, frictionless contacts (condim 1), a wall at x = 0 facing +x."""
    balls = "".join(
        f'<body name="b{i}" pos="{x!r} 0 0"><joint name="x{i}" type="slide" axis="1 0 0"/>'
        f'<geom name="g{i}" type="sphere" size="{radius!r}" mass="{m!r}"/></body>'
        for i, (m, x) in enumerate(zip(masses, positions)))
    return (f'<mujoco model="line"><default><geom condim="1"/></default>'
            f'<custom><numeric name="rbody.contact_restitution" data="{restitution!r}"/></custom>'
            f'<worldbody>{WALL if wall else ""}{balls}</worldbody></mujoco>')


@pytest.mark.parametrize("digits", [1, 2, pytest.param(3, marks=pytest.mark.slow)])
def test_pi_collisions_as_mjcf_count_the_digits_of_pi(digits):
    """Two spheres and a wall (Galperin): floor(pi 10^N) impacts, and the final velocities of the exact kernel."""
    exact = pi_collisions(digits)
    light, heavy = exact.masses
    xml = line_model([light, heavy], list(exact.positions), exact.radius)
    scene = rbody.from_mjcf(xml, t_end=exact.t_end, qvel0=list(exact.velocities))
    run = rbody.simulate(scene, dt=exact.t_end / (200 * 10 ** (digits - 1)), method="rk4")
    impacts = int((run.events["what"] == "impact").sum())
    assert impacts == math.floor(math.pi * 10**digits) == exact.expected_collisions
    reference = rbody.simulate(exact, dt=exact.t_end / (200 * 10 ** (digits - 1)))
    np.testing.assert_allclose(run["qvel"][-1], reference["velocities"][-1],
                               rtol=0, atol=1e-9 * exact.speed * 10**digits)
    total = run["energy"] + run["dissipated"]
    np.testing.assert_allclose(total, total[0], rtol=1e-12)


def test_newtons_cradle_as_mjcf_impacts_sequentially():
    """A striker onto four touching balls: the impulse passes ball to ball (sequential impacts at one instant) and
    the last ball leaves with the striker's speed, as the exact line-collision kernel says (a simultaneous Newton
    law would spread the momentum over all four)."""
    radius, v0 = 0.05, 1.0
    positions = [0.5, 1.0, 1.1, 1.2, 1.3]
    masses = [1.0] * 5
    xml = line_model(masses, positions, radius, wall=False)
    scene = rbody.from_mjcf(xml, t_end=1.0, qvel0=[v0, 0, 0, 0, 0])
    run = rbody.simulate(scene, dt=1e-2, method="rk4")
    exact = rbody.simulate(line_collisions(masses, positions, [v0, 0, 0, 0, 0], radii=radius, walls=(-10.0,),
                                           t_end=1.0), dt=1e-2)
    np.testing.assert_allclose(run["qvel"][-1], [0, 0, 0, 0, v0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(run["qvel"], exact["velocities"], rtol=0, atol=1e-12)
    impacts = run.events["time"][run.events["what"] == "impact"]
    assert len(impacts) == 4
    np.testing.assert_allclose(impacts, 0.4, rtol=0, atol=1e-12)   # the striker meets ball 1 at t = 0.4 s


def test_stacked_balls_as_mjcf_against_the_chapter():
    """A small ball resting on a large one, dropped onto a floor, elastic: the small ball leaves at
    (3M - m)/(M + m) times the impact speed (the chapter), and follows the exact kernel's heights."""
    M, m, h, R, r = 1.0, 0.1, 1.0, 0.1, 0.02
    exact = stacked_balls(M, m, drop_height=h, radius_large=R, radius_small=r)
    xml = (f'<mujoco model="stacked"><default><geom condim="1"/></default>'
           f'<custom><numeric name="rbody.contact_restitution" data="1"/></custom><worldbody>'
           f'<geom name="floor" type="plane" size="0 0 1"/>'
           f'<body name="large" pos="0 0 {h + R!r}"><joint name="zl" type="slide" axis="0 0 1"/>'
           f'<geom name="gl" type="sphere" size="{R!r}" mass="{M!r}"/></body>'
           f'<body name="small" pos="0 0 {h + 2 * R + r!r}"><joint name="zs" type="slide" axis="0 0 1"/>'
           f'<geom name="gs" type="sphere" size="{r!r}" mass="{m!r}"/></body></worldbody></mujoco>')
    t_end = exact.t_end
    scene = rbody.from_mjcf(xml, t_end=t_end)
    run = rbody.simulate(scene, dt=t_end / 100, method="rk4")
    reference = rbody.simulate(exact, dt=t_end / 100)
    u = math.sqrt(2 * 9.81 * h)
    after = run.t > math.sqrt(2 * h / 9.81) + 1e-9
    v_small = run["qvel"][:, 1]
    first = np.argmax(after)
    np.testing.assert_allclose(v_small[first] + 9.81 * (run.t[first] - math.sqrt(2 * h / 9.81)),
                               u * (3 * M - m) / (M + m), rtol=1e-12)
    np.testing.assert_allclose(v_small, reference["small_velocity"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(run["qpos"][:, 1] + h + 2 * R, reference["small_height"], rtol=0, atol=1e-9)


def race_model(incline, radius, half_length, slots):
    """The chapter's race as an MJCF contact model: a plane tilted by `incline` about y (its x axis dipping), and a
    disc (a solid cylinder), a hoop (a cylinder geom with a thin-walled cylinder's <inertial>) and a solid sphere, 1
    kg each, free, resting on it side by side (y = slots), the cylinders' axes across the slope. The bodies collide
    with the plane only (contype 2, conaffinity 1)."""
    from rbody.motion import quat_multiply, quat_to_matrix

    q_floor = np.array([np.cos(incline / 2), 0.0, np.sin(incline / 2), 0.0])
    R = quat_to_matrix(q_floor)
    across = quat_multiply(q_floor, np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]))  # axis along y

    def at(y):
        return " ".join(repr(float(v)) for v in R @ np.array([0.0, y, radius]))

    def quat(q):
        return " ".join(repr(float(v)) for v in q)

    hoop_axis, hoop_diameter = radius ** 2, radius ** 2 / 2 + (2 * half_length) ** 2 / 12
    bodies = (f'<body name="disc" pos="{at(slots[0])}" quat="{quat(across)}"><freejoint/>'
              f'<geom name="disc" type="cylinder" size="{radius!r} {half_length!r}" mass="1"/></body>'
              f'<body name="hoop" pos="{at(slots[1])}" quat="{quat(across)}"><freejoint/>'
              f'<inertial pos="0 0 0" mass="1" diaginertia="{hoop_diameter!r} {hoop_diameter!r} {hoop_axis!r}"/>'
              f'<geom name="hoop" type="cylinder" size="{radius!r} {half_length!r}"/></body>'
              f'<body name="ball" pos="{at(slots[2])}"><freejoint/>'
              f'<geom name="ball" type="sphere" size="{radius!r}" mass="1"/></body>')
    return (f'<mujoco model="race"><default><geom contype="2" conaffinity="1" friction="1"/></default><worldbody>'
            f'<geom name="slope" type="plane" size="0 0 1" quat="{quat(q_floor)}" contype="1" conaffinity="1"/>'
            f'{bodies}</worldbody></mujoco>'), R


def test_rolling_race_as_mjcf_against_the_chapter():
    """Released together, each rolls without slipping at x'' = g sin(alpha) / (1 + k): the sphere (k = 2/5) first,
    the disc (1/2), the hoop (1) last, as the built-in race's exact solution. The time-stepping's discrete motion
    under a constant force is exact: speed a t at every step, to round-off; the rolling bodies' heights stay their
    radius."""
    incline, radius, dt = 0.25, 0.1, 1e-3
    xml, R = race_model(incline, radius, 0.05, (-0.5, 0.0, 0.5))
    scene = rbody.from_mjcf(xml, t_end=1.0)
    run = rbody.simulate(scene, dt=dt)
    race = rolling_race(("solid_sphere", "disc", "hollow_cylinder"), radius=radius, incline=incline, length=1.0)
    down = R[:, 0] if R[2, 0] < 0 else -R[:, 0]  # along the slope, the way it descends
    for name, a in zip(("ball", "disc", "hoop"), race.acceleration):
        speed = run[f"{name}.velocity"] @ down
        np.testing.assert_allclose(speed, a * run.t, rtol=0, atol=1e-12)
        height = (run[f"{name}.com"] - run[f"{name}.com"][0]) @ R[:, 2]
        assert np.abs(height).max() <= 1e-14
    np.testing.assert_allclose(race.acceleration, [G_RACE * np.sin(incline) / (1 + k) for k in (0.4, 0.5, 1.0)],
                               rtol=1e-15)
    order = np.argsort([-(run[f"{name}.com"][-1] @ down) for name in ("ball", "disc", "hoop")])
    assert list(order) == [0, 1, 2]   # the sphere ahead, then the disc, then the hoop


G_RACE = 9.81
