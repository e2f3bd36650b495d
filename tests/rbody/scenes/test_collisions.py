"""Exact impacts on a line and the chapter's pi-counting balls (section 5.2.2)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from rbody import Trajectory, simulate
from rbody.engine.events import Line, exact_line
from rbody.errors import SimulationError
from rbody.scenes import line_collisions, pi_collisions

EPS = np.finfo(float).eps
# floor(pi 10^N) for N = 0..8 from the decimal digits of pi, 3.14159265358979...
PI_DIGITS = "314159265"


def floor_pi(n: int) -> int:
    return int(PI_DIGITS[: n + 1])


def ball_ball(traj: Trajectory) -> np.ndarray:
    return traj.events["kind"] == 0


# ----- hand-computed impacts ------------------------------------------------------------------------


def test_equal_masses_exchange_velocities():
    scene = line_collisions([1.0, 1.0], [0.0, 1.0], [1.0, 0.0], walls=())
    traj = simulate(scene, dt=0.25)
    # gap 1 m closed at 1 m/s: one impact at t = 1 s, after which ball 0 rests and ball 1 moves at 1 m/s.
    np.testing.assert_array_equal(traj.events["time"], [1.0])
    np.testing.assert_array_equal(traj.events["velocities"], [[0.0, 1.0]])
    assert traj.events["kind"].tolist() == [0] and traj.events["i"].tolist() == [0]
    assert traj.events["j"].tolist() == [1]
    assert scene.t_end == pytest.approx(1.1)       # 1.1 x the last impact time
    np.testing.assert_allclose(traj["positions"][-1], [1.0, 1.0 + (traj.t[-1] - 1.0)], rtol=0, atol=4 * EPS)
    assert traj["collisions"].tolist() == [0, 0, 0, 0, 0, 1]   # a sample at t = 1 shows the motion before


def test_unequal_masses_textbook_formulas():
    # m1 = 1, m2 = 3, v = (2, 0): v1' = (m1 - m2)/(m1 + m2) v = -1, v2' = 2 m1/(m1 + m2) v = 1.
    scene = line_collisions([1.0, 3.0], [0.0, 0.5], [2.0, 0.0], walls=())
    traj = simulate(scene, dt=0.05)
    np.testing.assert_array_equal(traj.events["time"], [0.25])
    np.testing.assert_allclose(traj.events["velocities"], [[-1.0, 1.0]], rtol=0, atol=2 * EPS)


def test_ball_onto_wall_reverses():
    scene = line_collisions([2.0], [1.0], [-0.5], radii=0.25, walls=(0.0,), t_end=2.0)
    traj = simulate(scene, dt=0.5)
    # contact when x - r = 0: t = (1 - 0.25) / 0.5 = 1.5 s, then x = 0.25 + 0.5 (t - 1.5).
    np.testing.assert_array_equal(traj.events["time"], [1.5])
    assert traj.events["kind"].tolist() == [1] and traj.events["j"].tolist() == [-1]
    np.testing.assert_array_equal(traj["velocities"][:, 0], [-0.5, -0.5, -0.5, -0.5, 0.5])
    np.testing.assert_array_equal(traj["positions"][:, 0], [1.0, 0.75, 0.5, 0.25, 0.5])
    # a wall on the right
    right = line_collisions([1.0], [1.0], [1.0], walls=(3.0,), t_end=3.0)
    traj = simulate(right, dt=1.0)
    np.testing.assert_array_equal(traj.events["time"], [2.0])
    np.testing.assert_array_equal(traj["positions"][:, 0], [1.0, 2.0, 3.0, 2.0])


@pytest.mark.parametrize("e", [0.0, 0.3, 0.5, 0.9])
def test_restitution_loses_the_exact_fraction(e):
    # Two balls: the kinetic energy of the centre of mass is kept, that of the relative motion
    # (1/2 mu v_rel^2) is multiplied by e^2.
    m1, m2, v1 = 1.0, 3.0, 2.0
    scene = line_collisions([m1, m2], [0.0, 1.0], [v1, 0.0], walls=(), restitution=e)
    traj = simulate(scene, dt=0.1)
    energy0 = 0.5 * m1 * v1**2
    cm = 0.5 * (m1 * v1) ** 2 / (m1 + m2)
    assert traj["energy"][-1] == pytest.approx(cm + e**2 * (energy0 - cm), rel=8 * EPS)
    v_after = traj.events["velocities"][0]
    assert v_after[1] - v_after[0] == pytest.approx(e * v1, rel=8 * EPS, abs=8 * EPS)   # Newton's rule
    # a wall: the speed is multiplied by e, the energy by e^2
    wall = line_collisions([1.0], [1.0], [-1.0], walls=(0.0,), restitution=e, t_end=2.0)
    traj = simulate(wall, dt=0.5)
    assert traj["energy"][-1] == pytest.approx(e**2 * 0.5, rel=2 * EPS, abs=0)


def test_newtons_cradle_with_radii():
    # Ball 0 hits the touching pair 1-2 (radius 0.05 m, 0.6 - 0.5 rounds to 0.1 - 1 ulp: touching):
    # the impulse goes through, ball 2 leaves with the velocity, 0 and 1 rest.
    scene = line_collisions([1.0, 1.0, 1.0], [0.0, 0.5, 0.6], [1.0, 0.0, 0.0], radii=0.05, walls=(), t_end=1.0)
    traj = simulate(scene, dt=0.1)
    np.testing.assert_allclose(traj.events["time"], [0.4, 0.4], rtol=4 * EPS)
    assert traj.events["i"].tolist() == [0, 1]
    np.testing.assert_array_equal(traj["velocities"][-1], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(traj["positions"][-1], [0.4, 0.5, 0.6 + (traj.t[-1] - 0.4)], rtol=0, atol=8 * EPS)
    assert traj["energy"][-1] == pytest.approx(0.5, rel=4 * EPS)


# ----- the compiled loop against its twin in exact rational arithmetic ----------------------------


@pytest.mark.parametrize("seed", range(8))
def test_compiled_events_match_the_exact_rational_run(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 5))
    masses = rng.uniform(0.2, 5.0, n)
    radii = rng.uniform(0.0, 0.1, n)
    x = np.cumsum(rng.uniform(0.3, 1.0, n))
    v = rng.uniform(-2.0, 2.0, n)
    walls = [(0.0,), (0.0, x[-1] + 1.0), (x[-1] + 1.0,), ()][seed % 4]   # left, both, right, none
    if not walls:
        v = np.sort(v)[::-1]      # converging, so that there are impacts
    e = 1.0 if seed < 4 else 0.8
    scene = line_collisions(masses, x, v, radii=radii, walls=walls, restitution=e, t_end=4.0)
    traj = simulate(scene, dt=0.01)
    exact = scene.exact(traj.t)
    ev = exact_line(scene.line, x, v, traj.t)["events"]
    count = traj.events["time"].size
    assert count == ev["time"].size and count > 0
    np.testing.assert_array_equal(traj.events["i"], np.where(ev["gap"] == 0, 0, ev["gap"] - 1))
    # one rounding per impact in each gap and velocity, scale 4 s, 4 m, 10 m/s
    tol = 8 * (count + 1) * EPS
    np.testing.assert_allclose(traj.events["time"], ev["time"], rtol=0, atol=tol * 4)
    np.testing.assert_allclose(traj.events["velocities"], ev["velocities"], rtol=0, atol=tol * 10)
    np.testing.assert_allclose(traj["positions"], exact["positions"], rtol=0, atol=tol * 10)
    np.testing.assert_array_equal(traj["collisions"], exact["collisions"])


# ----- invariants --------------------------------------------------------------------------------


def test_energy_conserved_to_round_off_when_elastic():
    rng = np.random.default_rng(7)
    scene = line_collisions(rng.uniform(0.5, 2, 4), [1.0, 2.0, 3.0, 4.0], rng.uniform(-1, 1, 4), radii=0.1,
                            walls=(0.0, 5.0), t_end=40.0)
    traj = simulate(scene, dt=0.01)
    count = traj.meta["event_count"]
    assert count > 50   # the test means something only with many impacts
    energy = traj["energy"]
    assert np.max(np.abs(energy / energy[0] - 1)) <= 4 * count * EPS   # one rounding per impact
    for digits in (2, 3):
        pi = pi_collisions(digits)
        traj = simulate(pi, dt=pi.t_end / 300)
        energy = traj["energy"]
        assert np.max(np.abs(energy / energy[0] - 1)) <= traj.meta["event_count"] * EPS


@pytest.mark.parametrize("convention", ["galperin", "chapter"])
def test_momentum_conserved_in_ball_ball_impacts(convention):
    scene = pi_collisions(3, convention=convention)
    traj = simulate(scene, dt=scene.t_end / 100)
    m = np.array(scene.masses)
    before = np.vstack([np.array(scene.velocities)[None], traj.events["velocities"][:-1]])
    after = traj.events["velocities"]
    p_before, p_after = before @ m, after @ m
    scale = np.abs(before) @ m
    bb = ball_ball(traj)
    np.testing.assert_array_less(np.abs(p_after - p_before)[bb], 4 * EPS * scale[bb])
    # a wall takes momentum: the light ball's is reversed
    wall = ~bb
    np.testing.assert_array_equal(after[wall, scene.light], -before[wall, scene.light])


def test_no_penetration_at_samples_and_impacts():
    for scene in (pi_collisions(3, radius=0.0), pi_collisions(3, convention="chapter", radius=0.0)):
        traj = simulate(scene, dt=scene.t_end / 2000)
        x = traj["positions"]
        # radius 0: positions in order and inside the wall exactly (the engine integrates gaps >= 0)
        assert np.all(np.diff(x, axis=1) >= 0)
        inside = x - scene.walls[0]
        assert np.all(inside >= 0) if scene.convention == "galperin" else np.all(inside <= 0)
        # at each impact: the state sampled at the impact times
        at = scene.line.run(np.array(scene.positions), np.array(scene.velocities), t_stop=traj.t[-1],
                            sample_t=traj.events["time"])
        x = scene.line.positions(at.samples["gaps"], at.samples["x0"])
        assert np.all(np.diff(x, axis=1) >= 0) and np.all(at.samples["gaps"] >= 0)
    scene = pi_collisions(3)   # radii 0.05: surface gaps >= 0 to the round-off of x + r
    traj = simulate(scene, dt=scene.t_end / 2000)
    gaps = np.diff(traj["positions"], axis=1)[:, 0] - 2 * scene.radius
    assert np.all(gaps >= -4 * EPS * 2.0)


def test_dt_only_changes_the_sampling():
    scene = pi_collisions(2)
    coarse, fine = simulate(scene, dt=0.1), simulate(scene, dt=0.05)
    for name in ("time", "kind", "i", "j", "velocities"):
        np.testing.assert_array_equal(coarse.events[name], fine.events[name])
    # 0.05 = 0.1 / 2 exactly: every coarse sample time is a fine one, with the same state
    common = slice(0, None, 2)
    np.testing.assert_array_equal(fine.t[common][: coarse.t.size], coarse.t)
    for name in ("positions", "velocities", "collisions"):
        np.testing.assert_array_equal(fine[name][common][: coarse.t.size], coarse[name])
    np.testing.assert_array_equal(coarse.t, np.arange(coarse.t.size) * 0.1)
    assert coarse.t[-1] >= scene.t_end > coarse.t[-2]


# ----- the digits of pi -----------------------------------------------------------------------------


@pytest.mark.parametrize("digits", range(7))
def test_galperin_count_is_floor_pi_10n(digits):
    scene = pi_collisions(digits)
    assert scene.expected_collisions == floor_pi(digits)
    assert scene.exact_counts["total"] == floor_pi(digits)
    assert scene.count() == floor_pi(digits)
    assert scene.counts()["done"]


@pytest.mark.parametrize("digits", range(7))
def test_chapter_count_p_minus_one_is_floor_pi_10n(digits):
    scene = pi_collisions(digits, convention="chapter")
    assert scene.masses[0] == 16 * 100.0**digits * scene.masses[1]
    assert scene.expected_collisions - 1 == floor_pi(digits)
    assert scene.count() == scene.expected_collisions


def test_galperin_digits_7_fast_and_exact():
    start = time.perf_counter()
    scene = pi_collisions(7)
    elapsed = time.perf_counter() - start
    assert scene.count() == floor_pi(7)
    assert elapsed < 20.0, f"{elapsed:.1f} s for 31 415 926 impacts"


@pytest.mark.slow
def test_chapter_digits_7_and_galperin_8():
    assert pi_collisions(7, convention="chapter").count() == floor_pi(7) + 1
    assert pi_collisions(8).count() == floor_pi(8)


def test_small_speed_keeps_the_count():
    # heavy speed 10^-N: the light ball stays near 1 m/s, the count does not change
    scene = pi_collisions(3, speed=1e-3)
    assert scene.count() == floor_pi(3)
    traj = simulate(scene, dt=scene.t_end / 100)
    assert np.max(np.abs(traj["v"])) <= 1.0 + 1e-12


def _matrix_power_velocities(x: float, u0: float, count: int) -> np.ndarray:
    """(count, 2): A^n (u0, 0) for n = 1..count, the chapter's matrix applied n times."""
    A = np.array([[1 - x, -2 * x], [2, 1 - x]]) / (1 + x)
    out, state = np.empty((count, 2)), np.array([u0, 0.0])
    for n in range(count):
        state = A @ state
        out[n] = state
    return out


@pytest.mark.parametrize("convention", ["galperin", "chapter"])
@pytest.mark.parametrize("digits", [1, 2, 3])
def test_velocities_follow_the_chapter_closed_form(digits, convention):
    scene = pi_collisions(digits, convention=convention)
    traj = simulate(scene, dt=scene.t_end / 50)
    bb = ball_ball(traj)
    u_sim, v_sim = traj.events["u"][bb], traj.events["v"][bb]
    count = u_sim.size
    assert count == scene.exact_counts["ball"]
    x = scene.mass_ratio
    u0 = scene.velocities[scene.heavy]
    powers = _matrix_power_velocities(x, u0, count)
    u_closed, v_closed = scene.exact_velocities(np.arange(1, count + 1))
    scale = abs(u0) / math.sqrt(x)           # the light ball's largest speed
    tol = 4 * np.arange(1, count + 1) * EPS * scale   # one rounding per impact, accumulated
    np.testing.assert_array_less(np.abs(u_closed - powers[:, 0]), tol)
    np.testing.assert_array_less(np.abs(v_closed - powers[:, 1]), tol)
    np.testing.assert_array_less(np.abs(u_sim - u_closed), tol)
    np.testing.assert_array_less(np.abs(v_sim - v_closed), tol)
    # the chapter's frame: v_n is the light ball's velocity towards the wall, > 0 until n theta > pi
    towards_wall = 1.0 if convention == "chapter" else -1.0
    theta = 2 * math.atan(math.sqrt(x))
    n = np.arange(1, count + 1)
    assert np.all(towards_wall * v_sim[n * theta < np.pi - 1e-9] > 0)
    # the heavy ball turns round at the p-th impact: cos(p theta) < 0 first
    turn = int(np.argmax(u_sim * u0 < 0)) + 1
    assert turn == scene.exact_counts["turn"] == scene.counts()["turn"]
    assert np.cos(turn * theta) < 0 < np.cos((turn - 1) * theta)


@pytest.mark.parametrize("convention", ["galperin", "chapter"])
def test_sampled_motion_matches_the_unfolded_billiard(convention):
    scene = pi_collisions(2, convention=convention)
    traj = simulate(scene, dt=scene.t_end / 400)
    exact = scene.exact(traj.t)
    count = traj.meta["event_count"]
    tol = 8 * count * EPS
    np.testing.assert_array_equal(traj["collisions"], exact["collisions"])
    np.testing.assert_array_equal(traj["ball_collisions"], exact["ball_collisions"])
    np.testing.assert_allclose(traj["positions"], exact["positions"], rtol=0, atol=tol * 2.0)     # 2 m
    np.testing.assert_allclose(traj["v"], exact["v"], rtol=0, atol=tol * 100.0)                   # 100 m/s
    np.testing.assert_allclose(traj["u"], exact["u"], rtol=0, atol=tol)
    assert traj["collisions"][-1] == scene.exact_counts["total"]


def test_closed_form_velocities_checks_n():
    scene = pi_collisions(1)
    for bad in (-1, 1.5, [0, 17]):
        with pytest.raises(ValueError, match="n="):
            scene.exact_velocities(bad)


# ----- what other simulators build ----------------------------------------------------------------


def test_layout_and_observe():
    scene = pi_collisions(2)
    layout = scene.layout
    assert [b.name for b in layout.bodies] == ["ball_0", "ball_1"]
    assert [j.name for j in layout.joints] == ["x_0", "x_1"]
    assert all(j.kind == "slide" and j.axis == (1.0, 0.0, 0.0) and j.qpos0 == 0.0 for j in layout.joints)
    assert [j.qvel0 for j in layout.joints] == [0.0, -1.0]
    assert [b.pos[0] for b in layout.bodies] == [1.0, 2.0]
    heavy = layout.bodies[1].inertia
    assert heavy.mass == 100.0**2 and heavy.tensor[0, 0] == pytest.approx(0.4 * 1e4 * 0.05**2)
    (wall,) = layout.fixed
    assert wall.kind == "box" and wall.pos[0] + wall.size[0] == 0.0     # the face at the wall
    pairs = {(c.shape_a, c.shape_b) for c in layout.contacts}
    assert pairs == {("ball_0", "ball_1"), ("wall_lo", "ball_0")}
    assert all(c.friction == 0 and c.restitution == 1 for c in layout.contacts)
    # observe from joint histories made from the exact motion
    t = np.linspace(0, scene.t_end, 50)
    exact = scene.exact(t)
    joints = {f"x_{i}": (exact["positions"][:, i] - scene.positions[i], exact["velocities"][:, i]) for i in range(2)}
    seen = scene.observe(t, {}, joints)
    for name in ("positions", "velocities", "energy", "u", "v"):
        np.testing.assert_allclose(seen[name], exact[name], rtol=1e-15, atol=1e-15)


def test_layout_gives_point_balls_a_radius_and_keeps_the_gaps():
    scene = line_collisions([1.0, 2.0], [1.0, 1.5], [0.0, 0.0], walls=(0.0, 3.0), t_end=1.0)
    layout = scene.layout
    x = [b.pos[0] for b in layout.bodies]
    r = [b.shapes[0].size[0] for b in layout.bodies]
    assert r == [0.05, 0.05]
    lo, hi = layout.fixed
    gaps = [x[0] - r[0] - (lo.pos[0] + lo.size[0]), x[1] - r[1] - x[0] - r[0], hi.pos[0] - hi.size[0] - x[1] - r[1]]
    np.testing.assert_allclose(gaps, [1.0, 0.5, 1.5], rtol=0, atol=4 * EPS * 3)


# ----- bad input ------------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, match", [
    ({"masses": [1.0, -1.0]}, "masses"),
    ({"masses": [1.0, np.nan]}, "masses"),
    ({"positions": [1.0, np.nan]}, "positions"),
    ({"velocities": [np.inf, 0.0]}, "velocities"),
    ({"positions": [1.0, 1.05], "radii": 0.05}, "balls 0 and 1 overlap"),
    ({"positions": [2.0, 1.0]}, "balls 0 and 1 are not in order"),
    ({"positions": [-1.0, 1.0]}, "wall at 0.0 m lies between balls 0 and 1"),
    ({"positions": [1.0, 2.0], "walls": (1.5,)}, "wall at 1.5 m lies between balls 0 and 1"),
    ({"positions": [0.05, 1.0], "radii": 0.1}, "ball 0 .* on or through the wall"),
    ({"restitution": 1.5}, "restitution"),
    ({"restitution": -0.1}, "restitution"),
    ({"radii": [0.1, -0.1]}, "radii"),
    ({"walls": (0.0, 3.0)}, "walls on both sides"),
    ({"masses": [1.0, 1.0, 1.0]}, "positions has shape"),
    ({"max_events": 0}, "max_events"),
])
def test_bad_line_input(kwargs, match):
    args = {"masses": [1.0, 2.0], "positions": [1.0, 2.0], "velocities": [0.0, -1.0]}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        line_collisions(args.pop("masses"), args.pop("positions"), args.pop("velocities"), **args)


@pytest.mark.parametrize("kwargs, match", [
    ({"digits": -1}, "digits"),
    ({"digits": 2.5}, "digits"),
    ({"digits": True}, "digits"),
    ({"digits": "3"}, "digits"),
    ({"digits": 12}, "digits"),
    ({"digits": 1, "convention": "feynman"}, "convention"),
    ({"digits": 1, "light_mass": 0.0}, "light_mass"),
    ({"digits": 1, "speed": np.nan}, "speed"),
    ({"digits": 1, "radius": 0.5}, "radius"),
])
def test_bad_pi_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        pi_collisions(**kwargs)


def test_too_many_impacts_is_a_simulation_error():
    # e = 0.5: the light ball is crushed between the heavy ball and the wall, infinitely many
    # impacts before a finite time (inelastic collapse)
    with pytest.raises(SimulationError, match="max_events=10000"):
        line_collisions([1.0, 100.0], [1.0, 2.0], [0.0, -1.0], restitution=0.5, max_events=10_000)


def test_exact_rational_run_refuses_long_runs():
    scene = pi_collisions(1)
    line = Line(np.array(scene.masses), np.array(scene.line.radii), 1.0, 0.0)
    with pytest.raises(ValueError, match="max_events=5"):
        exact_line(line, np.array(scene.positions), np.array(scene.velocities), [scene.t_end], max_events=5)
