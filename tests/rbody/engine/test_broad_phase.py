"""The broad phase's lower bounds (rbody.engine.contacts.kinematics): the separating-axis gap along a box's face
normals never exceeds the distance the narrow phase computes, on random poses of every pair with a box; and it
parts a long box from its neighbour where their bounding spheres overlap."""

import numpy as np

from rbody.engine.contacts.geometry import TYPE_CODES, collide_pair
from rbody.engine.contacts.kinematics import axes_gap
from rbody.motion import quat_to_matrix

SIZES = {"sphere": (0.2, 0.0, 0.0), "capsule": (0.1, 0.3, 0.0), "box": (0.1, 0.4, 0.2)}


def rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def test_axes_gap_is_a_lower_bound_of_the_distance():
    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(2000):
        kind = str(rng.choice(list(SIZES)))
        pairs = sorted([(TYPE_CODES[kind], kind), (TYPE_CODES["box"], "box")])
        (ta, ka), (tb, kb) = pairs
        pa, pb = rng.normal(size=3) * 0.5, rng.normal(size=3) * 0.5
        Ra, Rb = rotation(rng), rotation(rng)
        sa, sb = np.array(SIZES[ka]), np.array(SIZES[kb])
        bound = axes_gap(ta, pa, Ra, sa, tb, pb, Rb, sb)
        dist, _, _ = collide_pair(ka, pa, Ra, sa, kb, pb, Rb, sb)
        nearest = np.min(dist[np.isfinite(dist)])
        assert bound <= nearest + 1e-15
        checked += nearest > 0
    assert checked > 500


def test_axes_gap_parts_long_boxes_side_by_side():
    """Two 0.2 x 0.02 x 0.02 boxes side by side 5 mm apart: their bounding spheres overlap by 0.19 m; along the
    normal of their facing sides the gap is the 5 mm."""
    I3 = np.eye(3)
    half = np.array([0.1, 0.01, 0.01])
    pa, pb = np.zeros(3), np.array([0.0, 0.025, 0.0])
    spheres = np.linalg.norm(pb - pa) - 2 * np.linalg.norm(half)
    assert spheres < -0.15
    bound = axes_gap(TYPE_CODES["box"], pa, I3, half, TYPE_CODES["box"], pb, I3, half)
    assert abs(bound - 0.005) <= 1e-15
