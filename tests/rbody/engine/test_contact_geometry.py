"""The narrow phase (rbody.engine.contacts.geometry) against closed forms and against MuJoCo's collision functions
(mj_collision) on random poses: distances and normals to round-off for every pair rbody computes."""

import numpy as np
import pytest

from rbody.engine.contacts.geometry import collide_pair, segment_closest
from rbody.motion import quat_to_matrix

I3 = np.eye(3)


def rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def test_plane_sphere_closed_form():
    # a tilted plane through the origin, a sphere of radius 0.3 whose centre is 1.0 along its normal
    R = quat_to_matrix(np.array([np.cos(0.2), np.sin(0.2), 0.0, 0.0]))
    n = R[:, 2]
    dist, normal, point = collide_pair("plane", [0, 0, 0], R, (), "sphere", 1.0 * n + 5 * R[:, 0], I3, [0.3])
    assert dist[0] == pytest.approx(0.7, abs=1e-15)
    np.testing.assert_allclose(normal[0], n, rtol=0, atol=1e-15)
    np.testing.assert_allclose(point[0], 5 * R[:, 0], rtol=0, atol=1e-14)  # on the plane: where it will touch


def test_plane_box_gives_its_corners():
    # a unit box turned by 30 degrees about z, resting 0.1 above the floor: 4 corners at 0.1, 4 at 1.1
    R = quat_to_matrix(np.array([np.cos(np.pi / 12), 0, 0, np.sin(np.pi / 12)]))
    dist, normal, point = collide_pair("plane", [0, 0, 0], I3, (), "box", [1.0, 2.0, 0.6], R, [0.5, 0.5, 0.5])
    assert len(dist) == 8
    np.testing.assert_allclose(np.sort(dist), [0.1] * 4 + [1.1] * 4, rtol=0, atol=1e-15)
    np.testing.assert_allclose(normal, np.tile([0, 0, 1.0], (8, 1)))
    low = point[dist < 0.5]
    np.testing.assert_allclose(low[:, 2], 0.0, rtol=0, atol=1e-15)  # on the floor, below the corner
    np.testing.assert_allclose(np.linalg.norm(low[:, :2] - [1, 2], axis=1), np.sqrt(0.5), rtol=0, atol=1e-15)


def test_swapped_order_flips_the_normal():
    d1, n1, _ = collide_pair("sphere", [0, 0, 0], I3, [0.5], "capsule", [2, 0, 0], I3, [0.25, 1.0])
    d2, n2, _ = collide_pair("capsule", [2, 0, 0], I3, [0.25, 1.0], "sphere", [0, 0, 0], I3, [0.5])
    assert d1[0] == pytest.approx(1.25, abs=1e-15) and d2[0] == d1[0]
    np.testing.assert_array_equal(n1, -n2)
    np.testing.assert_allclose(n1[0], [1, 0, 0])


def test_sphere_inside_box_leaves_by_the_nearest_face():
    dist, normal, _ = collide_pair("sphere", [0.3, 0.1, 0.0], I3, [0.1], "box", [0, 0, 0], I3, [0.5, 1.0, 2.0])
    assert dist[0] == pytest.approx(-0.2 - 0.1, abs=1e-15)
    np.testing.assert_allclose(normal[0], [-1, 0, 0])  # from the sphere towards the box: the box is on -x


def test_capsules_crossed_and_parallel():
    # crossed at right angles, 1 apart: distance 1 - radii, normal along the common perpendicular
    Rx = quat_to_matrix(np.array([np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0]))  # z axis turned onto x
    dist, normal, point = collide_pair("capsule", [0, 0, 0], I3, [0.1, 1.0], "capsule", [0, 0.3, 1.0], Rx,
                                       [0.2, 1.0])
    # closest points: (0, 0, 1) on the first segment's end and (0, 0.3, 1) on the second: distance 0.3
    assert dist[0] == pytest.approx(0.3 - 0.1 - 0.2, abs=1e-15)
    np.testing.assert_allclose(normal[0], [0, 1, 0], rtol=0, atol=1e-15)
    # parallel, overlapping over z in [0.5, 1]: the normal is still the perpendicular, the point in the overlap
    dist, normal, point = collide_pair("capsule", [0, 0, 0], I3, [0.1, 1.0], "capsule", [0.5, 0, 1.5], I3,
                                       [0.1, 1.0])
    assert dist[0] == pytest.approx(0.3, abs=1e-15)
    np.testing.assert_allclose(normal[0], [1, 0, 0], rtol=0, atol=1e-15)
    assert 0.5 <= point[0, 2] <= 1.0


def test_segment_closest_against_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(200):
        p1, p2 = rng.normal(size=3), rng.normal(size=3)
        u1, u2 = rng.normal(size=3), rng.normal(size=3)
        u1 /= np.linalg.norm(u1)
        u2 /= np.linalg.norm(u2)
        l1, l2 = rng.uniform(0.1, 2, size=2)
        s, t = segment_closest(p1, u1, l1, p2, u2, l2)
        best = np.linalg.norm(p1 + s * u1 - p2 - t * u2)
        grid = np.linspace(-1, 1, 401)
        S, T = np.meshgrid(grid * l1, grid * l2)
        brute = np.linalg.norm(p1 + S[..., None] * u1 - p2 - T[..., None] * u2, axis=-1).min()
        assert best <= brute + 1e-12


# ----- against MuJoCo's mj_collision -------------------------------------------------------------------

def _geom(name, kind, size):
    return f'<geom name="{name}" type="{kind}" size="{" ".join(map(str, size))}" margin="100"/>'


PAIRS = [("plane", (0, 0, 1), "sphere", (0.3,)), ("plane", (0, 0, 1), "capsule", (0.2, 0.5)),
         ("plane", (0, 0, 1), "box", (0.3, 0.4, 0.5)), ("sphere", (0.3,), "sphere", (0.5,)),
         ("sphere", (0.3,), "capsule", (0.2, 0.6)), ("capsule", (0.1, 0.4), "capsule", (0.2, 0.6)),
         ("sphere", (0.3,), "box", (0.3, 0.4, 0.5))]


@pytest.mark.parametrize("kind_a,size_a,kind_b,size_b", PAIRS)
def test_against_mujoco_on_random_poses(kind_a, size_a, kind_b, size_b):
    mujoco = pytest.importorskip("mujoco")
    rng = np.random.default_rng(7)
    if kind_a == "plane":
        first = '<geom name="a" type="plane" size="0 0 1" margin="100" pos="0.1 -0.2 0.3" quat="0.9 0.2 -0.1 0.3"/>'
    else:
        first = f'<body name="A"><freejoint/>{_geom("a", kind_a, size_a)}</body>'
    xml = (f'<mujoco><worldbody>{first}<body name="B"><freejoint/>{_geom("b", kind_b, size_b)}</body>'
           '</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    ga, gb = model.geom("a").id, model.geom("b").id
    checked = 0
    for trial in range(40):
        for j in range(model.njnt):
            adr = model.jnt_qposadr[j]
            data.qpos[adr:adr + 3] = rng.uniform(-0.8, 0.8, size=3)
            q = rng.normal(size=4)
            data.qpos[adr + 3:adr + 7] = q / np.linalg.norm(q)
        mujoco.mj_forward(model, data)
        dist, normal, _ = collide_pair(kind_a, data.geom_xpos[ga], data.geom_xmat[ga].reshape(3, 3), size_a,
                                       kind_b, data.geom_xpos[gb], data.geom_xmat[gb].reshape(3, 3), size_b)
        for c in data.contact[:data.ncon]:
            sign = 1.0 if (c.geom1, c.geom2) == (ga, gb) else -1.0
            k = int(np.argmin(np.abs(dist - c.dist)))
            assert dist[k] == pytest.approx(c.dist, abs=1e-12), (trial, dist, c.dist)
            if kind_b != "box" or kind_a != "sphere" or dist[k] > -0.05:  # deep inside a box MuJoCo's face choice
                np.testing.assert_allclose(sign * normal[k], c.frame[:3], rtol=0, atol=1e-9)
            checked += 1
    assert checked >= 40


def test_box_on_box_corners():
    # a 0.2-wide box centred on a 0.4-wide one, 0.01 above its top face: its 4 lower corners at 0.01, normal +z
    dist, normal, point = collide_pair("box", [0, 0, 0], I3, [0.2, 0.2, 0.1], "box", [0.05, 0, 0.16], I3,
                                       [0.1, 0.1, 0.05])
    assert len(dist) == 17  # 8 + 8 corners and the edges' crossing
    lower = dist[:8][[0, 1, 2, 3]]                            # corners of b with z = -half
    np.testing.assert_allclose(lower, 0.01, rtol=0, atol=1e-15)
    np.testing.assert_allclose(normal[[0, 1, 2, 3]], np.tile([0, 0, 1.0], (4, 1)), rtol=0, atol=1e-15)
    assert np.all(dist[4:8] > 0.1) and np.all(dist[8:16] > 0.01)  # the rest are farther away
    assert dist[16] == np.inf  # no edges cross: a face on a face
