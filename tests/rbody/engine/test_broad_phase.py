"""The broad phase's lower bounds (rbody.engine.contacts.kinematics): the separating-axis gap never exceeds the
distance the narrow phase computes, on random poses of every pair of convex primitives; it parts a long box from
its neighbour, two boxes edge to edge and two legs side by side where their bounding spheres overlap; above a plane
it is the height of the geom's lowest point."""

import numpy as np

from rbody.engine.contacts.geometry import TYPE_CODES, collide_pair
from rbody.engine.contacts.kinematics import _support_radius, core_gap, separating_gap
from rbody.motion import quat_to_matrix

SIZES = {"sphere": (0.2, 0.0, 0.0), "capsule": (0.1, 0.3, 0.0), "box": (0.1, 0.4, 0.2), "cylinder": (0.15, 0.25, 0.0),
         "ellipsoid": (0.1, 0.3, 0.2)}


def rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def test_the_separating_gap_is_a_lower_bound_of_the_distance():
    rng = np.random.default_rng(2)
    checked, parted = 0, 0
    kinds = list(SIZES)
    for _ in range(3000):
        ka, kb = sorted(rng.choice(kinds, size=2), key=lambda kind: TYPE_CODES[str(kind)])
        ka, kb = str(ka), str(kb)
        if ka == "ellipsoid" and kb == "ellipsoid":
            continue
        pa, pb = rng.normal(size=3) * 0.5, rng.normal(size=3) * 0.5
        Ra, Rb = rotation(rng), rotation(rng)
        sa, sb = np.array(SIZES[ka]), np.array(SIZES[kb])
        bound = separating_gap(TYPE_CODES[ka], pa, Ra, sa, TYPE_CODES[kb], pb, Rb, sb)
        dist, _, _ = collide_pair(ka, pa, Ra, sa, kb, pb, Rb, sb)
        nearest = np.min(dist[np.isfinite(dist)])
        assert bound <= nearest + 1e-12, (ka, kb, bound, nearest)
        checked += nearest > 0
        spheres = np.linalg.norm(pb - pa) - np.linalg.norm(sa) - np.linalg.norm(sb)
        parted += bound > 0 and spheres < 0  # apart by their axes, not by (roughly) their spheres
    assert checked > 1000
    assert parted > 100


def test_the_separating_gap_parts_long_boxes_side_by_side():
    """Two 0.2 x 0.02 x 0.02 boxes side by side 5 mm apart: their bounding spheres overlap by 0.19 m; along the
    normal of their facing sides the gap is the 5 mm."""
    I3 = np.eye(3)
    half = np.array([0.1, 0.01, 0.01])
    pa, pb = np.zeros(3), np.array([0.0, 0.025, 0.0])
    spheres = np.linalg.norm(pb - pa) - 2 * np.linalg.norm(half)
    assert spheres < -0.15
    bound = separating_gap(TYPE_CODES["box"], pa, I3, half, TYPE_CODES["box"], pb, I3, half)
    assert abs(bound - 0.005) <= 1e-15


def test_the_separating_gap_parts_two_legs_side_by_side():
    """Two capsules of radius 0.02 and half length 0.1, parallel along z and 0.05 m apart between their axes (two
    shins): their bounding spheres overlap by 0.19 m; across their axes the gap is 0.05 - 0.04 = 0.01 m, exactly."""
    I3 = np.eye(3)
    size = np.array([0.02, 0.1, 0.0])
    pa, pb = np.zeros(3), np.array([0.03, 0.04, 0.0])
    code = TYPE_CODES["capsule"]
    bound = separating_gap(code, pa, I3, size, code, pb, I3, size)
    assert abs(bound - 0.01) <= 1e-15  # along the line of centres (their common normal)
    tilted = rotation(np.random.default_rng(5))
    dist, _, _ = collide_pair("capsule", pa, I3, size, "capsule", pb, tilted, size)
    assert separating_gap(code, pa, I3, size, code, pb, tilted, size) <= dist.min() + 1e-15


def test_the_separating_gap_parts_boxes_edge_to_edge():
    """Two unit cubes turned 45 degrees about crossed axes, their edges 0.1 m apart along z: no face normal nor the
    line of centres parts them by the full 0.1, the cross product of the two edges does, exactly."""
    half = np.full(3, 0.5)
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    Ra = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])  # about y: an edge along y at its top, z = 1/sqrt(2)
    Rb = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])  # about x: an edge along x at its bottom
    gap = 0.1
    pb = np.array([0.0, 0.0, 2 * 0.5 * np.sqrt(2) + gap])
    code = TYPE_CODES["box"]
    bound = separating_gap(code, np.zeros(3), Ra, half, code, pb, Rb, half)
    assert abs(bound - gap) <= 1e-14
    dist, _, _ = collide_pair("box", np.zeros(3), Ra, half, "box", pb, Rb, half)
    assert abs(dist.min() - gap) <= 1e-12


def test_above_a_plane_the_bound_is_the_lowest_point():
    """A capsule tilted 60 degrees from the vertical above the floor: its lowest point's height, 0.3 - (0.4 cos 60 +
    0.05) = 0.05 m, where its bounding sphere (0.45 m) reaches below the floor."""
    c, s = np.cos(np.pi / 3), np.sin(np.pi / 3)
    R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    size = np.array([0.05, 0.4, 0.0])
    centre = np.array([0.1, -0.2, 0.3])
    n = np.array([0.0, 0.0, 1.0])
    lowest = centre[2] - _support_radius(TYPE_CODES["capsule"], R, size, *n)
    dist, _, _ = collide_pair("plane", np.zeros(3), np.eye(3), np.array([0.0, 0.0, 0.0]), "capsule", centre, R, size)
    np.testing.assert_allclose(lowest, dist.min(), rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(lowest, 0.05, rtol=0.0, atol=1e-15)
    assert centre[2] - 0.45 < 0.0  # the sphere reaches the floor, the capsule does not


def test_the_cores_gap_is_the_distance_of_capsules_and_a_bound_with_cylinders():
    """On random poses: the cores' gap (the distance between a sphere's centre or a capsule's or cylinder's axis
    segment less the radii) is the narrow phase's distance for spheres and capsules, to round-off, and at most it
    with a cylinder (inside the capsule of its radius and half-length); it parts pairs the separating axes leave
    touching (a sphere beside a capsule's end, off its axis)."""
    rng = np.random.default_rng(4)
    round_kinds = ("sphere", "capsule", "cylinder")
    parted = 0
    for _ in range(3000):
        ka, kb = sorted(rng.choice(round_kinds, size=2), key=lambda kind: TYPE_CODES[str(kind)])
        ka, kb = str(ka), str(kb)
        pa, pb = rng.normal(size=3) * 0.5, rng.normal(size=3) * 0.5
        Ra, Rb = rotation(rng), rotation(rng)
        sa, sb = np.array(SIZES[ka]), np.array(SIZES[kb])
        ta, tb = TYPE_CODES[ka], TYPE_CODES[kb]
        bound = core_gap(ta, pa, Ra, sa, tb, pb, Rb, sb)
        dist, _, _ = collide_pair(ka, pa, Ra, sa, kb, pb, Rb, sb)
        nearest = np.min(dist[np.isfinite(dist)])
        if "cylinder" in (ka, kb):
            assert bound <= nearest + 1e-12, (ka, kb, bound, nearest)
        else:
            assert abs(bound - nearest) <= 1e-12, (ka, kb, bound, nearest)
        parted += bound > 0.0 and separating_gap(ta, pa, Ra, sa, tb, pb, Rb, sb) <= 0.0
    assert parted >= 5, parted


def test_the_cores_gap_parts_capsules_end_to_end_askew():
    """Capsules of radius 0.1 and half-length 0.3, one along x at the origin, the other along z at (0.4, 0.2, 0.4):
    their nearest points are the ends (0.3, 0, 0) and (0.4, 0.2, 0.1), sqrt(0.06) - 0.2 = 0.0449 m apart; no axis of
    either nor a cross product of two parts them (along y: 0.2 - 0.1 - 0.1 = 0)."""
    code = TYPE_CODES["capsule"]
    size = np.array([0.1, 0.3, 0.0])
    along_x = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    pb = np.array([0.4, 0.2, 0.4])
    expected = np.sqrt(0.06) - 0.2
    assert abs(core_gap(code, np.zeros(3), along_x, size, code, pb, np.eye(3), size) - expected) <= 1e-15
    assert separating_gap(code, np.zeros(3), along_x, size, code, pb, np.eye(3), size) <= 1e-15
    dist, _, _ = collide_pair("capsule", np.zeros(3), along_x, size, "capsule", pb, np.eye(3), size)
    assert abs(dist.min() - expected) <= 1e-15
