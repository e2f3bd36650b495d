"""Cylinder contacts (rbody.engine.contacts.geometry): a point's distance from a cylinder against its closed form,
the segment's closest point against dense sampling, MuJoCo's plane-cylinder and sphere-cylinder distances on random
separated poses, and cylinders in the rigid limit: thrown sliding, a cylinder rolls at 2/3 v0 from
t* = v0 / (3 mu g) (the chapter's rolling without slipping with I = m R^2 / 2); down an incline it accelerates at
(2/3) g sin(alpha); standing on its cap it stays put."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.engine.contacts.geometry import APART, collide_pair, cylinder_distance, segment_cylinder_closest
from rbody.inertia import Inertia
from rbody.motion import quat_multiply, quat_to_matrix

G = 9.81
I3 = np.eye(3)


def random_rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def about_x(angle):
    return quat_to_matrix(np.array([np.cos(angle / 2), np.sin(angle / 2), 0.0, 0.0]))


def test_point_distance_closed_form():
    """Side, cap, rim and inside, for the cylinder of radius 0.3 and half-length 0.5 along z at the origin."""
    grad = np.empty(3)
    cases = [([0.5, 0.0, 0.1], 0.2, [1, 0, 0]),                      # beside the side
             ([0.1, 0.1, 0.9], 0.4, [0, 0, 1]),                      # above the top cap
             ([0.0, 0.7, -0.8], 0.5, [0, 0.8, -0.6]),                # beyond the bottom rim: (0.4, 0.3) off it
             ([0.0, 0.25, 0.0], -0.05, [0, 1, 0]),                   # inside, nearer the side
             ([0.0, 0.0, -0.45], -0.05, [0, 0, -1])]                 # inside, nearer the bottom cap
    for x, distance, normal in cases:
        assert cylinder_distance(np.array(x, float), np.zeros(3), I3, 0.3, 0.5, grad) == pytest.approx(distance,
                                                                                                           abs=1e-15)
        np.testing.assert_allclose(grad, normal, rtol=0, atol=1e-15)


def test_segment_closest_is_the_least_distance():
    rng = np.random.default_rng(5)
    grad = np.empty(3)
    for _ in range(100):
        Rc = random_rotation(rng)
        p, u = rng.normal(size=3) * 0.8, rng.normal(size=3)
        u /= np.linalg.norm(u)
        half = rng.uniform(0.05, 0.8)
        t, lo, hi = segment_cylinder_closest(p, u, half, np.zeros(3), Rc, 0.3, 0.4)
        assert -half <= lo <= t <= hi <= half
        best = cylinder_distance(p + t * u, np.zeros(3), Rc, 0.3, 0.4, grad)
        sampled = min(cylinder_distance(p + s * u, np.zeros(3), Rc, 0.3, 0.4, grad)
                      for s in np.linspace(-half, half, 2001))
        assert best <= sampled + 1e-15
        assert sampled - best <= 2 * half / 2000  # the sampling's spacing times a slope of at most 1


def test_capsule_along_the_side_and_across_a_cap():
    """A capsule parallel to the axis, 0.5 from it, over z in [-0.2, 0.6] beside the side's [-0.4, 0.4]: distance
    0.5 - 0.3 - r at the middle of the overlap and at its lower end, its upper end (beyond the cap) farther. Lying
    across the top cap, all of it over the cap: all three at 0.15."""
    dist, normal, point = collide_pair("capsule", [0.5, 0.0, 0.2], I3, [0.05, 0.4], "cylinder", [0, 0, 0], I3,
                                       [0.3, 0.4])
    assert dist[2] == pytest.approx(0.15, abs=1e-15)
    np.testing.assert_allclose(normal[2], [-1, 0, 0], rtol=0, atol=1e-15)
    assert point[2, 2] == pytest.approx(0.5 * (-0.2 + 0.4), abs=1e-12)  # the overlap z in [-0.2, 0.4]
    assert dist[0] == pytest.approx(0.15, abs=1e-15) and dist[1] > dist[2] + 0.01
    dist, normal, point = collide_pair("capsule", [0.0, 0.0, 0.6], about_x(np.pi / 2), [0.05, 0.2], "cylinder",
                                       [0, 0, 0], I3, [0.3, 0.4])
    np.testing.assert_allclose(dist, 0.15, rtol=0, atol=1e-15)  # parallel to the cap, all of it over the cap
    np.testing.assert_allclose(normal, [[0, 0, -1.0]] * 3, rtol=0, atol=1e-15)


def test_plane_cylinder_rim_points():
    """A cylinder (R 0.3, half 0.5) tilted by 0.4 rad about x over the floor: each cap's lowest rim point at
    z_cap - R sin(0.4); standing upright its lower cap's four points at the floor."""
    R = about_x(0.4)
    centre = np.array([0.2, -0.1, 1.0])
    dist, normal, point = collide_pair("plane", [0, 0, 0], I3, (), "cylinder", centre, R, [0.3, 0.5])
    assert len(dist) == 8
    for cap, k in ((1.0, 0), (-1.0, 4)):
        z_cap = centre[2] + cap * 0.5 * R[2, 2]
        assert dist[k] == pytest.approx(z_cap - 0.3 * np.sin(0.4), abs=1e-15)
        assert dist[k + 2] == pytest.approx(z_cap + 0.3 * np.sin(0.4), abs=1e-15)   # 180 degrees: the highest
        assert dist[k + 1] == pytest.approx(z_cap, abs=1e-15)                     # 90 and 270: level with the centre
        assert dist[k + 3] == pytest.approx(z_cap, abs=1e-15)
    dist, _, point = collide_pair("plane", [0, 0, 0], I3, (), "cylinder", [0, 0, 0.5], I3, [0.3, 0.5])
    np.testing.assert_allclose(dist[4:], 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(dist[:4], 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.sort(np.linalg.norm(point[4:, :2], axis=1)), [0.3] * 4, rtol=0, atol=1e-15)


@pytest.mark.parametrize("kind_a,size_a", [("plane", ()), ("sphere", (0.2,))])
def test_against_mujoco_on_random_separated_poses(kind_a, size_a):
    mujoco = pytest.importorskip("mujoco")
    if kind_a == "plane":
        first = '<geom name="a" type="plane" size="0 0 1" margin="100" pos="0.1 -0.2 0.3" quat="0.9 0.2 -0.1 0.3"/>'
    else:
        first = '<body name="A"><freejoint/><geom name="a" type="sphere" size="0.2" margin="100"/></body>'
    xml = (f'<mujoco><worldbody>{first}<body name="B"><freejoint/><geom name="b" type="cylinder" size="0.3 0.4" '
           'margin="100"/></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    ga, gb = model.geom("a").id, model.geom("b").id
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(200):
        for j in range(model.njnt):
            adr = model.jnt_qposadr[j]
            data.qpos[adr:adr + 3] = rng.uniform(-0.8, 0.8, size=3)
            if kind_a == "plane":  # above the plane, mostly
                data.qpos[adr + 2] = rng.uniform(0.5, 1.5)
            q = rng.normal(size=4)
            data.qpos[adr + 3:adr + 7] = q / np.linalg.norm(q)
        mujoco.mj_forward(model, data)
        dist, normal, _ = collide_pair(kind_a, data.geom_xpos[ga], data.geom_xmat[ga].reshape(3, 3), size_a,
                                       "cylinder", data.geom_xpos[gb], data.geom_xmat[gb].reshape(3, 3), (0.3, 0.4))
        contacts = list(data.contact[:data.ncon])
        if not contacts:
            continue
        nearest = min(contacts, key=lambda c: c.dist)
        if nearest.dist <= 0:
            continue
        k = int(np.argmin(dist))
        assert dist[k] == pytest.approx(nearest.dist, abs=1e-12)
        sign = 1.0 if (nearest.geom1, nearest.geom2) == (ga, gb) else -1.0
        np.testing.assert_allclose(sign * normal[k], nearest.frame[:3], rtol=0, atol=1e-9)
        checked += 1
    assert checked > 50


def drum(friction, v0=0.0, alpha=0.0, r=0.2, half=0.1, upright=False):
    """A solid cylinder (1 kg) on its side (axis along y) on a floor tilted by alpha about y, or standing."""
    q_floor = (np.cos(alpha / 2), 0.0, np.sin(alpha / 2), 0.0)
    R_floor = quat_to_matrix(np.array(q_floor))
    own = np.array([1.0, 0.0, 0.0, 0.0]) if upright else np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])
    quat = tuple(quat_multiply(np.array(q_floor), own))  # lying: its axis along -y, on the slope
    height = half if upright else r
    body = Body("drum", Inertia.solid_cylinder(1.0, r, 2 * half), shapes=(Shape("c", "cylinder", (r, half)),),
                pos=tuple(R_floor[:, 2] * height), quat=quat)
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "drum"),),
                    fixed=(Shape("floor", "plane", (0, 0), quat=q_floor),),
                    contacts=(Contact("floor", "c", friction=friction),))
    return layout, R_floor


def test_drum_thrown_sliding_rolls_at_two_thirds():
    r, mu, v0, dt = 0.2, 0.3, 2.0, 1e-3
    layout, _ = drum(mu, r=r)
    run = rbody.simulate(Scene.from_layout(layout, t_end=1.0, qvel0=[v0, 0, 0, 0, 0, 0]), dt=dt)
    v, spin, z = run["drum.velocity"][:, 0], run["drum.omega"][:, 1], run["drum.com"][:, 2]
    t_star = v0 / (3 * mu * G)
    rolling = np.abs(v - r * spin) <= 1e-12
    start = run.t[np.argmax(rolling)]
    assert t_star <= start <= t_star + dt
    assert np.all(rolling[run.t >= start])
    sliding = run.t < t_star - dt
    np.testing.assert_allclose(v[sliding], v0 - mu * G * run.t[sliding], rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[run.t >= start], 2 / 3 * v0, rtol=0, atol=1e-12)
    assert np.abs(z - r).max() <= 1e-14
    assert np.abs(run["drum.com"][:, 1]).max() <= 1e-14  # no drift along its axis
    assert run["contacts"][-1] == 2                      # the two lowest rim points


def test_drum_rolls_down_an_incline_at_two_thirds_g_sin_alpha():
    alpha, r, dt = 0.2, 0.2, 1e-3
    layout, R = drum(1.0, alpha=alpha, r=r)
    run = rbody.simulate(Scene.from_layout(layout, t_end=1.0), dt=dt)
    x = (run["drum.com"] - run["drum.com"][0]) @ R[:, 0]  # along the slope (its x axis dips)
    speed = run["drum.velocity"] @ R[:, 0]
    acceleration = 2 / 3 * G * np.sin(alpha)
    # Moreau-Jean under a constant force: v_k = a k h exactly, x_k = a h^2 k (k + 1) / 2 (positions with v_{k+1})
    k = np.round(run.t / dt)
    np.testing.assert_allclose(np.abs(speed), acceleration * run.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.abs(x), acceleration * dt ** 2 * k * (k + 1) / 2, rtol=0, atol=1e-12)
    height = (run["drum.com"] @ R[:, 2])
    assert np.abs(height - r).max() <= 1e-14


def test_standing_cylinder_stays_put():
    layout, _ = drum(0.5, upright=True)
    run = rbody.simulate(Scene.from_layout(layout, t_end=1.0), dt=2e-3)
    com = run["drum.com"]
    assert np.abs(com - com[0]).max() <= 1e-13
    assert run["contacts"][-1] == 4
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G, rtol=1e-12)


def test_event_driven_scheme_refuses_cylinders():
    layout, _ = drum(0.5)
    scene = Scene.from_layout(layout, t_end=0.1)
    assert "rk4" not in scene.methods
    with pytest.raises(rbody.MethodNotApplicable, match="'floor'/'c'"):
        rbody.simulate(scene, dt=1e-3, method="rk4")


def test_apart_is_never_a_contact():
    """A capsule's end at the closest point is APART, not a second contact at the same place."""
    dist, _, _ = collide_pair("capsule", [0.0, 0.0, 1.0], I3, [0.05, 0.2], "cylinder", [0, 0, 0], I3, [0.3, 0.4])
    assert dist[0] == APART  # the lower end is the closest point
    assert dist[2] == pytest.approx(1.0 - 0.2 - 0.4 - 0.05, abs=1e-15) and dist[1] > dist[2]


@pytest.mark.parametrize("other", ["plane", "box"])
@pytest.mark.parametrize("tilt", [3e-5, 1e-3, 0.05])
def test_a_cap_nearly_flat_on_a_face_has_its_lowest_rim_point_to_round_off(other, tilt):
    """A cylinder (r 0.1, half-length 0.2) settling on its cap, tilted by `tilt` from the face's normal: its least
    rim gap is the closed form, the cap's centre's height less r sin(tilt). The direction of the lowest point, the
    normal projected onto the cap, is |w| = sin(tilt) long: computed as n - (n . axis) axis it carried an error of
    eps per entry, which lifted the point by r eps / tilt (4e-12 m at 3e-5 rad), and the projection after a step,
    aiming at 1e-13 m, stalled at 5e-13 m of overlap on that noise."""
    rng = np.random.default_rng(int(tilt * 1e6))
    face = ("plane", np.zeros(3), I3, (0.0, 0.0, 1.0)) if other == "plane" else ("box", (0, 0, -0.3), I3, (1, 1, 0.3))
    for _ in range(50):
        azimuth, spin = rng.uniform(-np.pi, np.pi, 2)
        tilt_axis = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
        q = quat_multiply(np.r_[np.cos(tilt / 2), np.sin(tilt / 2) * tilt_axis],
                          np.array([np.cos(spin / 2), 0.0, 0.0, np.sin(spin / 2)]))
        R = quat_to_matrix(q)
        gap = rng.uniform(-1e-12, 1e-12)
        centre = np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1),
                           0.2 * R[2, 2] + 0.1 * np.linalg.norm(np.cross([0, 0, 1.0], R[:, 2])) + gap])
        expected = centre[2] - 0.2 * R[2, 2] - 0.1 * np.linalg.norm(np.cross([0, 0, 1.0], R[:, 2]))
        dist, _normal, _point = collide_pair(*face, "cylinder", centre, R, (0.1, 0.2))
        assert abs(dist.min() - expected) <= 1e-16
