"""The chapter's bouncing balls (section 5.2.1) and the line engine with gravity along the line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbody import simulate
from rbody.engine.events import Line, exact_line, time_to_close
from rbody.scenes import stacked_balls

EPS = np.finfo(float).eps
G = 9.81


def chapter_ratio(M: float, m: float) -> float:
    """v/u = (3M - m)/(M + m), the chapter's result."""
    return (3 * M - m) / (M + m)


def run(scene, t_end=None):
    """Native run sampled at an interval incommensurate with the impact times (a sample at an impact
    time is ambiguous to round-off: before or after)."""
    t_end = scene.t_end if t_end is None else t_end
    return simulate(scene, dt=t_end / (100 * math.sqrt(2)), t_end=t_end)


# ----- the chapter's numbers -----------------------------------------------------------------------


@pytest.mark.parametrize("M, m", [(1.0, 0.01), (10.0, 1.0), (2.0, 1.0), (1.5, 1.0), (0.6, 0.057)])
def test_rebound_speed_is_the_chapter_formula(M, m):
    h = 1.3
    scene = stacked_balls(M, m, drop_height=h)
    traj = run(scene)
    u = math.sqrt(2 * G * h)
    kind, time = traj.events["kind"], traj.events["time"]
    # the chapter's sequence: the large ball meets the floor, then at once the small ball
    assert kind[:2].tolist() == [1, 0]
    assert time[0] == time[1] == pytest.approx(math.sqrt(2 * h / G), rel=4 * EPS)
    np.testing.assert_allclose(traj.events["small_velocity"][0], -u, rtol=4 * EPS)   # still falling at u
    np.testing.assert_allclose(traj.events["large_velocity"][0], u, rtol=4 * EPS)    # reversed by the floor
    v, V = traj.events["small_velocity"][1], traj.events["large_velocity"][1]
    assert v / u == pytest.approx(chapter_ratio(M, m), rel=8 * EPS, abs=0)
    assert V / u == pytest.approx((M - 3 * m) / (M + m), rel=0, abs=8 * EPS)
    assert scene.speed_ratio == pytest.approx(chapter_ratio(M, m), rel=EPS)
    assert scene.rebound_velocity == pytest.approx(chapter_ratio(M, m) * u, rel=4 * EPS)


@pytest.mark.parametrize("M, m", [(1.0, 0.01), (10.0, 1.0), (2.0, 1.0), (3.0, 1.0), (1.0, 1.0)])
def test_small_ball_rises_v_over_u_squared_as_high(M, m):
    h, R = 0.8, 0.1
    scene = stacked_balls(M, m, drop_height=h, radius_large=R)
    assert scene.t_end == scene.top_time == pytest.approx(math.sqrt(2 * h / G) * (1 + chapter_ratio(M, m)), rel=4 * EPS)
    traj = simulate(scene, dt=scene.t_end / 64)   # the last sample is at the top (to round-off)
    # the small ball's bottom met the large ball's top at 2R above the floor
    rise = traj["small_height"][-1] - 2 * R
    assert rise / h == pytest.approx(chapter_ratio(M, m) ** 2, rel=1e-14)
    assert scene.height_ratio == pytest.approx(chapter_ratio(M, m) ** 2, rel=2 * EPS)
    assert traj["small_velocity"][-1] == pytest.approx(0.0, abs=1e-13)


def test_heavy_large_ball_gives_nearly_three_times_the_speed_and_nine_times_the_height():
    h = 1.0
    scene = stacked_balls(1000.0, 1.0, drop_height=h)
    traj = simulate(scene, dt=scene.t_end / 32)
    u = math.sqrt(2 * G * h)
    v = traj.events["small_velocity"][1]
    rise = traj["small_height"][-1] - 2 * scene.radius_large
    # 3 - v/u = 4m/(M + m) and 9 - (v/u)^2 = (3 + v/u) 4m/(M + m): both small for M >> m
    assert 3 - v / u == pytest.approx(4 / 1001, rel=1e-13)
    assert 2.99 < v / u < 3.0
    assert 8.97 < rise / h < 9.0
    assert 9 - rise / h == pytest.approx((3 + v / u) * 4 / 1001, rel=1e-11)


def test_three_to_one_leaves_the_large_ball_at_rest_on_the_floor():
    # M = 3m: V = 0, v = 2u; the floor holds the large ball, which must not bounce on it at zero speed
    h = 1.0
    scene = stacked_balls(3.0, 1.0, drop_height=h)
    traj = run(scene)
    after = traj.t > math.sqrt(2 * h / G)
    np.testing.assert_array_equal(traj["large_velocity"][after], 0.0)
    np.testing.assert_array_equal(traj["large_height"][after], 0.0)
    assert traj.meta["event_count"] == 2
    assert scene.top_height - 2 * scene.radius_large == pytest.approx(4 * h, rel=4 * EPS)


def test_equal_masses_leave_together_at_the_impact_speed():
    # M = m: V = -u (then reversed at once by the floor), v = u: the two rise together, as high as they fell
    h = 0.5
    scene = stacked_balls(1.0, 1.0, drop_height=h)
    traj = run(scene)
    assert traj.events["kind"].tolist() == [1, 0, 1]
    u = math.sqrt(2 * G * h)
    np.testing.assert_allclose(traj.events["small_velocity"][1:], [u, u], rtol=4 * EPS)
    np.testing.assert_allclose(traj.events["large_velocity"][1:], [-u, u], rtol=4 * EPS)
    after = traj.t > traj.events["time"][0]
    np.testing.assert_allclose(traj["small_height"][after] - traj["large_height"][after], 2 * scene.radius_large,
                               rtol=0, atol=8 * EPS)


# ----- against the closed form ------------------------------------------------------------------------


@pytest.mark.parametrize("M, m, gap", [(10.0, 1.0, 0.0), (1.0, 0.01, 0.0), (2.0, 1.0, 0.0), (1.5, 1.0, 0.0),
                                       (1.0, 0.1, 1e-3), (1.0, 1.0, 0.01), (5.0, 1.0, 0.3)])
def test_native_run_matches_the_closed_form(M, m, gap):
    scene = stacked_balls(M, m, drop_height=1.0, gap=gap)
    traj = run(scene)
    assert traj.t[-1] <= scene.exact_until
    exact = scene.exact(traj.t)
    u, top, energy = scene.impact_speed, scene.top_height, scene.energy
    for name, scale in (("small_velocity", u), ("large_velocity", u), ("small_height", top),
                        ("large_height", top), ("energy", energy)):
        np.testing.assert_allclose(traj[name], exact[name], rtol=0, atol=64 * EPS * scale, err_msg=name)


def test_gap_delays_the_impact_and_lowers_the_rebound():
    # gap d: the balls close at 2u after the floor impact, meet tau = d/(2u) later, each slowed by g tau
    h, d, M, m = 1.0, 0.01, 4.0, 1.0
    scene = stacked_balls(M, m, drop_height=h, gap=d)
    traj = run(scene)
    u = math.sqrt(2 * G * h)
    tau = d / (2 * u)
    assert traj.events["kind"][:2].tolist() == [1, 0]
    assert traj.events["time"][1] - traj.events["time"][0] == pytest.approx(tau, rel=1e-12)
    assert traj.events["small_velocity"][1] == pytest.approx(chapter_ratio(M, m) * u - G * tau, rel=1e-14)
    assert traj.events["large_velocity"][1] == pytest.approx((M - 3 * m) / (M + m) * u - G * tau, rel=1e-14)


def test_energy_is_conserved_through_many_bounces():
    # M = 2m: V < 0, the large ball bounces on the floor again and again before the small ball falls back
    scene = stacked_balls(2.0, 1.0, drop_height=1.0, t_end=3.0)
    traj = run(scene)
    assert traj.meta["event_count"] > 6
    np.testing.assert_allclose(traj["energy"], scene.energy, rtol=16 * EPS)
    # and nothing passes through the floor or the other ball
    assert np.all(traj["large_height"] >= 0)
    assert np.all(traj["small_height"] - traj["large_height"] >= 2 * scene.radius_large * (1 - 4 * EPS))


def test_second_ball_ball_impact_ends_the_closed_form():
    scene = stacked_balls(2.0, 1.0, drop_height=1.0, t_end=3.0)
    until = scene.exact_until
    traj = simulate(scene, dt=0.01, t_end=until * (1 + 1e-9))
    ball = traj.events["kind"] == 0
    assert traj.events["time"][ball][1] == pytest.approx(until, rel=1e-13)
    with pytest.raises(ValueError, match="second ball-ball impact"):
        scene.exact([until * (1 + 1e-9)])


def test_lighter_large_ball_needs_a_duration():
    with pytest.raises(ValueError, match="give t_end"):
        stacked_balls(0.5, 1.0, drop_height=1.0)
    scene = stacked_balls(0.5, 1.0, drop_height=1.0, t_end=1.0)
    assert scene.exact_until == pytest.approx(math.sqrt(2 / G), rel=4 * EPS)


# ----- bad input ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("args, kwargs, match", [
    ((-1.0, 0.1), {}, "large_mass"),
    ((1.0, -0.1), {}, "small_mass"),
    ((0.0, 0.1), {}, "large_mass"),
    ((np.nan, 0.1), {}, "large_mass"),
    ((1.0, 0.1), {"drop_height": 0.0}, "drop_height"),
    ((1.0, 0.1), {"drop_height": -1.0}, "drop_height"),
    ((1.0, 0.1), {"drop_height": np.inf}, "drop_height"),
    ((1.0, 0.1), {"radius_large": 0.0}, "radius_large"),
    ((1.0, 0.1), {"radius_small": -0.01}, "radius_small"),
    ((1.0, 0.1), {"gap": -1e-3}, "gap"),
    ((1.0, 0.1), {"gap": 8.0}, "gap"),
    ((1.0, 0.1), {"gravity": 0.0}, "gravity"),
    (([1.0, 2.0], 0.1), {}, "one number"),
    ((1.0, 0.1), {"t_end": -1.0}, "t_end"),
])
def test_bad_input(args, kwargs, match):
    kwargs = {"drop_height": 1.0, **kwargs}
    with pytest.raises(ValueError, match=match):
        stacked_balls(*args, **kwargs)


# ----- what other simulators build ----------------------------------------------------------------------


def test_layout_and_observe():
    h, R, r, d = 1.0, 0.1, 0.02, 0.005
    scene = stacked_balls(10.0, 1.0, drop_height=h, radius_large=R, radius_small=r, gap=d)
    layout = scene.layout
    assert [b.name for b in layout.bodies] == ["large", "small"]
    assert [b.pos for b in layout.bodies] == [(0.0, 0.0, h + R), (0.0, 0.0, h + 2 * R + d + r)]
    assert [(j.name, j.kind, j.axis, j.qpos0, j.qvel0) for j in layout.joints] == [
        ("z_large", "slide", (0.0, 0.0, 1.0), 0.0, 0.0), ("z_small", "slide", (0.0, 0.0, 1.0), 0.0, 0.0)]
    assert [b.shapes[0].size for b in layout.bodies] == [(R,), (r,)]
    assert layout.bodies[0].inertia.mass == 10.0
    (floor,) = layout.fixed
    assert floor.kind == "plane" and floor.pos == (0.0, 0.0, 0.0)
    assert {(c.shape_a, c.shape_b) for c in layout.contacts} == {("floor", "large"), ("large", "small")}
    assert all(c.restitution == 1.0 and c.friction == 0.0 for c in layout.contacts)
    t = np.linspace(0, scene.t_end, 77)
    exact = scene.exact(t)
    start = scene.start_heights
    joints = {"z_large": (exact["large_height"] - start[0], exact["large_velocity"]),
              "z_small": (exact["small_height"] - start[1], exact["small_velocity"])}
    seen = scene.observe(t, {}, joints)
    for name in scene.observables:
        scale = np.max(np.abs(exact[name]))
        np.testing.assert_allclose(seen[name], exact[name], rtol=0, atol=8 * EPS * scale, err_msg=name)


# ----- the line engine with gravity ----------------------------------------------------------------------


def test_ball_bouncing_on_a_floor():
    # one ball, bottom at h: floor impacts at sqrt(2h/g) (1 + 2k), at speed sqrt(2 g h), for ever
    h, r = 2.0, 0.1
    line = Line(np.array([1.0]), np.array([r]), 1.0, wall_lo=0.0, acceleration=-G)
    result = line.run(np.array([h + r]), np.array([0.0]), t_stop=10.0, record=True)
    t0 = math.sqrt(2 * h / G)
    k = np.arange(result.events)
    assert result.events == int((10.0 / t0 + 1) // 2)
    np.testing.assert_allclose(result.event_arrays["time"], t0 * (1 + 2 * k), rtol=1e-14)
    np.testing.assert_allclose(result.event_arrays["velocities"][:, 0], math.sqrt(2 * G * h), rtol=1e-14)


def test_ball_thrown_up_to_a_ceiling():
    # acceleration -g, ball moving up at w toward a wall a distance s above: s = w t - g t^2/2
    w, s = 5.0, 1.0
    line = Line(np.array([1.0]), np.array([0.0]), 1.0, wall_hi=s, acceleration=-G)
    result = line.run(np.array([0.0]), np.array([w]), t_stop=5.0, record=True)
    t_hit = (w - math.sqrt(w * w - 2 * G * s)) / G
    assert result.event_arrays["time"][0] == pytest.approx(t_hit, rel=1e-14)
    assert result.event_arrays["velocities"][0, 0] == pytest.approx(-(w - G * t_hit), rel=1e-14)
    # too slow to reach it: no impact
    assert line.run(np.array([0.0]), np.array([4.0]), t_stop=5.0).events == 0


@pytest.mark.parametrize("gap, c, accel", [(1.0, 0.0, -G), (1.0, 3.0, -G), (1.0, -3.0, -G), (0.0, -3.0, -G),
                                           (1.0, 3.0, 2.0), (1e-9, 1e-3, -G), (1e6, 1e-8, -1e-3)])
def test_time_to_close_is_the_first_closing_root(gap, c, accel):
    import mpmath

    tau = time_to_close(gap, c, accel)
    # roots of gap - c tau + accel tau^2 / 2 to 50 digits; the closing one has a slope <= 0 there
    with mpmath.workdps(50):
        roots = mpmath.polyroots([mpmath.mpf(accel) / 2, -mpmath.mpf(c), mpmath.mpf(gap)], extraprec=100)
        closing = [float(x.real) for x in roots if abs(x.imag) == 0 and x.real >= 0 and -c + accel * x.real <= 0]
    assert tau == pytest.approx(min(closing), rel=4 * EPS)


def test_time_to_close_never_when_the_gap_turns_first():
    assert time_to_close(1.0, 1.0, 2.0) == np.inf          # decelerates to rest before it closes
    assert time_to_close(1.0, -1.0, 2.0) == np.inf         # moving apart and pushed apart
    assert time_to_close(np.inf, 1.0, -G) == np.inf        # no wall
    assert time_to_close(1.0, -1.0, 0.0) == np.inf         # free motion, moving apart


def test_rational_twin_refuses_acceleration():
    line = Line(np.array([1.0]), np.array([0.1]), 1.0, wall_lo=0.0, acceleration=-G)
    with pytest.raises(ValueError, match="acceleration"):
        exact_line(line, [1.0], [0.0], [1.0])
