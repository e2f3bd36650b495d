"""Right-angle scattering of equal discs (the chapter, section 5.2) and the 2-D disc event engine."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

from rbody import simulate
from rbody.engine.events import Discs, disc_time_of_impact
from rbody.scenes import scattering

EPS = np.finfo(float).eps


def run(scene):
    """Native run sampled at an interval incommensurate with the impact time."""
    return simulate(scene, dt=scene.t_end / (60 * math.sqrt(2)), t_end=scene.t_end)


@pytest.mark.parametrize("b", [1e-3, 0.01, 0.05, 0.1, 0.15, 0.19, 0.1999])
def test_discs_leave_at_right_angles(b):
    u, r = 1.7, 0.1
    scene = scattering(b, speed=u, radius=r)
    traj = run(scene)
    assert traj.meta["event_count"] == 1
    after = traj.t > traj.events["time"][0]
    v1, v2 = traj["velocity_1"][after], traj["velocity_2"][after]
    # the chapter's v1 . v2 = 0, to round-off of the velocities' size
    np.testing.assert_allclose(np.sum(v1 * v2, axis=-1), 0.0, rtol=0, atol=4 * EPS * u * u)
    # speeds from the impact geometry, sin(phi) = b / 2r (to 40 digits: cos(asin(x)) near x = 1 is not)
    with mpmath.workdps(40):
        phi_mp = mpmath.asin(mpmath.mpf(b) / (2 * mpmath.mpf(r)))
        phi, sin, cos = float(phi_mp), float(mpmath.sin(phi_mp)), float(mpmath.cos(phi_mp))
    np.testing.assert_allclose(np.linalg.norm(v1, axis=-1), u * sin, rtol=0, atol=4 * EPS * u)
    np.testing.assert_allclose(np.linalg.norm(v2, axis=-1), u * cos, rtol=0, atol=4 * EPS * u)
    # the target leaves along the line of centres, phi below the x axis; the projectile at 90 deg to it
    np.testing.assert_allclose(np.arctan2(v2[:, 1], v2[:, 0]), -phi, rtol=0, atol=8 * EPS)
    np.testing.assert_allclose(traj["angle_between"][after], math.pi / 2, rtol=0, atol=4 * EPS / sin)
    assert scene.contact_angle == pytest.approx(phi, rel=4 * EPS)
    assert scene.speeds_after == pytest.approx((u * sin, u * cos), rel=4 * EPS)


@pytest.mark.parametrize("b", [0.0, 0.02, 0.1, 0.17, 0.25])
def test_energy_and_momentum_are_conserved(b):
    u, m = 2.0, 0.3
    traj = run(scattering(b, speed=u, mass=m))
    np.testing.assert_allclose(traj["energy"], 0.5 * m * u * u, rtol=4 * EPS)
    np.testing.assert_allclose(traj["momentum"], np.broadcast_to([m * u, 0.0], traj["momentum"].shape),
                               rtol=0, atol=4 * EPS * m * u)


def test_time_of_impact_and_contact_geometry():
    u, r, b, distance = 0.8, 0.1, 0.12, 0.9
    scene = scattering(b, speed=u, radius=r, distance=distance)
    traj = run(scene)
    # the centres are 2r apart when the projectile is sqrt((2r)^2 - b^2) behind the target along x
    t_c = (distance - math.sqrt(4 * r * r - b * b)) / u
    assert traj.events["time"][0] == pytest.approx(t_c, rel=4 * EPS)
    assert scene.impact_time == pytest.approx(t_c, rel=2 * EPS)
    # no overlap at any sample
    gap = np.linalg.norm(traj["position_2"] - traj["position_1"], axis=-1) - 2 * r
    assert np.all(gap >= -4 * EPS)


def test_head_on_impact_exchanges_the_velocities():
    traj = run(scattering(0.0, speed=1.5))
    np.testing.assert_array_equal(traj.events["velocity_1"], [[0.0, 0.0]])
    np.testing.assert_array_equal(traj.events["velocity_2"], [[1.5, 0.0]])
    np.testing.assert_array_equal(traj["angle_between"], 0.0)   # one disc at rest, always


@pytest.mark.parametrize("b", [0.2, 0.2 + 1e-12, 0.35])
def test_discs_that_miss_move_on_straight_lines(b):
    # b >= 2r: no collision (at b = 2r they graze, with no impulse)
    u = 1.0
    scene = scattering(b, speed=u, radius=0.1)
    assert not scene.collides and scene.impact_time == math.inf
    traj = run(scene)
    assert traj.meta["event_count"] == 0 and traj.events["time"].size == 0
    np.testing.assert_array_equal(traj["velocity_1"], np.broadcast_to([u, 0.0], (traj.t.size, 2)))
    np.testing.assert_array_equal(traj["velocity_2"], 0.0)
    np.testing.assert_allclose(traj["position_1"][:, 0], -scene.distance + u * traj.t, rtol=0, atol=4 * EPS)
    np.testing.assert_array_equal(traj["position_1"][:, 1], b)


@pytest.mark.parametrize("b", [0.0, 0.03, 0.11, 0.18, 0.3])
def test_native_run_matches_the_closed_form(b):
    scene = scattering(b, speed=1.3, radius=0.1, distance=0.7)
    traj = run(scene)
    exact = scene.exact(traj.t)
    for name in ("position_1", "position_2", "velocity_1", "velocity_2", "energy", "momentum"):
        scale = max(np.max(np.abs(exact[name])), 1.0)
        np.testing.assert_allclose(traj[name], exact[name], rtol=0, atol=8 * EPS * scale, err_msg=name)
    # the angle is exact where both discs move fast enough for it to be well defined
    np.testing.assert_allclose(traj["angle_between"], exact["angle_between"], rtol=0, atol=1e-14)


def test_default_start_and_duration():
    scene = scattering(0.05, speed=2.0, radius=0.1)
    assert scene.distance == pytest.approx(0.5)
    assert scene.t_end == pytest.approx(2 * 0.5 / 2.0)
    assert scene.impact_time < scene.t_end


# ----- bad input -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("b, kwargs, match", [
    (-0.01, {}, "impact_parameter"),
    (np.nan, {}, "impact_parameter"),
    (np.inf, {}, "impact_parameter"),
    ([0.1, 0.2], {}, "one number"),
    (0.1, {"radius": 0.0}, "radius"),
    (0.1, {"radius": -0.1}, "radius"),
    (0.1, {"speed": 0.0}, "speed"),
    (0.1, {"mass": -1.0}, "mass"),
    (0.1, {"mass": np.nan}, "mass"),
    (0.1, {"distance": 0.2}, "distance"),
    (0.1, {"t_end": 0.0}, "t_end"),
])
def test_bad_input(b, kwargs, match):
    with pytest.raises(ValueError, match=match):
        scattering(b, **kwargs)


# ----- what other simulators build ------------------------------------------------------------------------


def test_layout_and_observe():
    b, r, u, m = 0.07, 0.1, 1.2, 0.4
    scene = scattering(b, speed=u, mass=m, radius=r, distance=0.6)
    assert scene.applies_gravity is False
    layout = scene.layout
    assert [body.name for body in layout.bodies] == ["disc_1", "disc_2"]
    assert [body.pos for body in layout.bodies] == [(-0.6, 0.0, b), (0.0, 0.0, 0.0)]
    assert [(j.name, j.body, j.axis, j.qpos0, j.qvel0) for j in layout.joints] == [
        ("x_1", "disc_1", (1.0, 0.0, 0.0), 0.0, u), ("z_1", "disc_1", (0.0, 0.0, 1.0), 0.0, 0.0),
        ("x_2", "disc_2", (1.0, 0.0, 0.0), 0.0, 0.0), ("z_2", "disc_2", (0.0, 0.0, 1.0), 0.0, 0.0)]
    assert all(j.kind == "slide" for j in layout.joints)          # no hinge: frictionless discs do not spin
    assert [body.shapes[0].size for body in layout.bodies] == [(r,), (r,)]
    assert [body.inertia.mass for body in layout.bodies] == [m, m]
    (contact,) = layout.contacts
    assert (contact.shape_a, contact.shape_b, contact.friction, contact.restitution) == ("disc_1", "disc_2", 0.0, 1.0)
    assert layout.fixed == ()
    t = np.linspace(0, scene.t_end, 41)
    exact = scene.exact(t)
    start = {1: np.array([-0.6, b]), 2: np.zeros(2)}
    joints = {}
    for i in (1, 2):
        for a, axis in (("x", 0), ("z", 1)):
            joints[f"{a}_{i}"] = (exact[f"position_{i}"][:, axis] - start[i][axis], exact[f"velocity_{i}"][:, axis])
    seen = scene.observe(t, {}, joints)
    for name in scene.observables:
        np.testing.assert_allclose(seen[name], exact[name], rtol=0, atol=8 * EPS, err_msg=name)


# ----- the disc engine ---------------------------------------------------------------------------------------


def test_disc_time_of_impact_misses_grazes_and_recedes():
    assert disc_time_of_impact(1.0, 0.0, -1.0, 0.0, 0.2) == pytest.approx(0.8, rel=EPS)   # head on
    assert disc_time_of_impact(1.0, 0.3, -1.0, 0.0, 0.2) == np.inf                       # b > D: miss
    assert disc_time_of_impact(1.0, 0.2, -1.0, 0.0, 0.2) == np.inf                       # b = D: graze
    assert disc_time_of_impact(1.0, 0.0, 1.0, 0.0, 0.2) == np.inf                        # moving apart
    assert disc_time_of_impact(0.2, 0.0, -1.0, 0.0, 0.2) == 0.0                          # touching, closing


def test_disc_time_of_impact_against_high_precision_roots():
    rng = np.random.default_rng(7)
    for _ in range(200):
        d = rng.normal(size=2) * rng.uniform(0.3, 3)
        w = -d * rng.uniform(0.1, 2) + rng.normal(size=2) * 0.3
        D = rng.uniform(0.05, 0.25)
        tau = disc_time_of_impact(d[0], d[1], w[0], w[1], D)
        with mpmath.workdps(50):
            dm, wm = [mpmath.mpf(float(x)) for x in d], [mpmath.mpf(float(x)) for x in w]
            a = wm[0] ** 2 + wm[1] ** 2
            bh = dm[0] * wm[0] + dm[1] * wm[1]
            c = dm[0] ** 2 + dm[1] ** 2 - mpmath.mpf(D) ** 2
            disc = bh * bh - a * c
            expected = (-bh - mpmath.sqrt(disc)) / a if bh < 0 and disc > 0 else mpmath.inf
        if expected == mpmath.inf:
            assert tau == np.inf
        else:
            assert tau == pytest.approx(float(expected), rel=64 * EPS)


def test_three_discs_in_a_row_pass_the_velocity_on():
    # Newton's cradle in the plane: equal discs touching in a row, the first arriving head on; impacts
    # resolved one pair at a time leave the last disc with the whole velocity
    discs = Discs(masses=np.ones(3), radii=np.full(3, 0.1), restitution=1.0)
    pos = np.array([[-1.0, 0.0], [0.0, 0.0], [0.2, 0.0]])
    vel = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    result = discs.run(pos, vel, t_stop=5.0, record=True)
    assert result.events == 2
    np.testing.assert_allclose(result.event_arrays["time"], [0.8, 0.8], rtol=4 * EPS)
    np.testing.assert_array_equal(result.event_arrays["velocities"][-1], [[0.0, 0.0], [0.0, 0.0], [1.0, 0.0]])
