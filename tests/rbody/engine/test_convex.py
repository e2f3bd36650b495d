"""The convex narrow phase (rbody.engine.contacts.convex): GJK and EPA on support functions, against closed forms
(spheres, a sphere and a box, two boxes by the separating-axis theorem, parallel capsules, a box on a mesh's face, a
point and a cube mesh, a point and an ellipsoid by root finding), against MuJoCo's mj_geomDistance on random
separated poses of every pair of sphere, capsule, ellipsoid, cylinder, box and mesh, and invariants (hypothesis):
swapping the geoms, moving b along the normal, the witness points on the surfaces."""

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings, strategies as st

from rbody.engine.contacts.convex import (BAD_INPUT, BOX, CAPSULE, CONVERGED, CURVED_TOLERANCE, CYLINDER,
                                          ELLIPSOID, EPA_CAPACITY, INFO, MESH, SPHERE, hull_neighbours, hull_planes,
                                          hull_vertices, pack_hull, point_signed_distance, signed_distance, support)

I3 = np.eye(3)
NONE = np.empty(0)
KINDS = {"sphere": SPHERE, "capsule": CAPSULE, "ellipsoid": ELLIPSOID, "cylinder": CYLINDER, "box": BOX,
         "mesh": MESH}
POLYTOPES = {SPHERE, CAPSULE, BOX, MESH}  # GJK's polytope pairs: cores with vertices
CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)


def rotation(rng):
    """A uniformly random rotation matrix."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def turn_about(axis, angle):
    """The rotation by angle [rad] about the unit axis (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def geom(kind, pos, mat=I3, size=(0, 0, 0), hull=NONE):
    full = np.zeros(3)
    size = np.atleast_1d(np.asarray(size, dtype=float))
    full[:size.size] = size
    return KINDS[kind] if isinstance(kind, str) else kind, np.asarray(pos, float), np.asarray(mat, float), full, hull


def distance(a, b, guess=(0.0, 0.0, 0.0)):
    """(dist, normal, xa, xb, info) of geoms a and b (each geom()'s tuple)."""
    normal, xa, xb = np.empty(3), np.empty(3), np.empty(3)
    info = np.zeros(INFO)
    info[4:] = -1
    d = signed_distance(*a, *b, np.asarray(guess, float), normal, xa, xb, info)
    return d, normal, xa, xb, info


def certified(a, b, m):
    """-m.(s_A(m) - s_B(-m)) for the unit direction m: never above the signed distance (a lower bound on the
    distance when separated; minus an upper bound on the depth when overlapping), equal to it for the true normal."""
    sa, sb = np.empty(3), np.empty(3)
    support(*a, np.asarray(m, float), sa)
    support(*b, -np.asarray(m, float), sb)
    return -float(np.dot(m, sa - sb))


def on_surface(g, x):
    return point_signed_distance(*g, np.asarray(x, float), np.empty(3))


# ----- closed forms ------------------------------------------------------------------------------------------------

GAPS = [1e-3, 1e-6, 1e-9, -1e-9, -1e-6, -1e-3]


@pytest.mark.parametrize("gap", GAPS + [0.3, -0.05])
def test_sphere_sphere(gap):
    # radii 0.5 and 0.25 along a tilted direction: dist = |c| - 0.75
    u = np.array([1.0, 2.0, -2.0]) / 3.0
    a, b = geom("sphere", [0.1, 0.2, 0.3], size=[0.5]), geom("sphere", np.array([0.1, 0.2, 0.3]) + (0.75 + gap) * u,
                                                                size=[0.25])
    d, n, xa, xb, info = distance(a, b)
    assert d == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n, u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(xa, a[1] + 0.5 * u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(xb - xa, d * n, rtol=0, atol=1e-15)
    assert info[0] == CONVERGED and info[1] <= 2


@pytest.mark.parametrize("gap", GAPS)
def test_sphere_box_face_edge_and_inside(gap):
    box = geom("box", [0, 0, 0], size=[1.0, 0.5, 0.25])
    # above the +y face
    d, n, _, _, _ = distance(geom("sphere", [0.3, 0.5 + 0.2 + gap, 0.1], size=[0.2]), box)
    assert d == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n, [0, -1, 0], rtol=0, atol=1e-15)
    # off the edge x = 1, z = 0.25 along the diagonal of the two faces
    u = np.array([1.0, 0.0, 1.0]) / np.sqrt(2)
    d, n, _, _, _ = distance(box, geom("sphere", np.array([1.0, 0.1, 0.25]) + (0.2 + gap) * u, size=[0.2]))
    assert d == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n, u, rtol=0, atol=1e-12)
    # the centre inside, 0.01 from the +x face: out through it, depth 0.01 + r
    d, n, xa, xb, info = distance(geom("sphere", [0.99, 0.1, 0.05], size=[0.2]), box)
    assert d == pytest.approx(-0.21, abs=1e-15)
    np.testing.assert_allclose(n, [-1, 0, 0], rtol=0, atol=1e-15)  # b (the box) moves towards -x to let the sphere out
    np.testing.assert_allclose(xb, [1.0, 0.1, 0.05], rtol=0, atol=1e-15)
    assert info[0] == CONVERGED


def sat_depth(pa, Ra, sa, pb, Rb, sb):
    """The penetration depth of two overlapping boxes and its axis, by the separating-axis theorem: the least
    overlap over the 15 axes (face normals and edge crossings), each exact."""
    axes = [Ra[:, i] for i in range(3)] + [Rb[:, i] for i in range(3)]
    for i, j in itertools.product(range(3), range(3)):
        c = np.cross(Ra[:, i], Rb[:, j])
        if np.linalg.norm(c) > 1e-9:
            axes.append(c / np.linalg.norm(c))
    overlaps, directions = [], []
    for u in axes:
        ra = np.sum(sa * np.abs(Ra.T @ u))
        rb = np.sum(sb * np.abs(Rb.T @ u))
        t = float(np.dot(pb - pa, u))
        overlaps.append(ra + rb - abs(t))
        directions.append(u * (1.0 if t >= 0 else -1.0))
    order = np.argsort(overlaps)
    return overlaps[order[0]], directions[order[0]], overlaps[order[1]]


@pytest.mark.parametrize("gap", GAPS)
def test_box_box_axis_aligned(gap):
    # b beside a along x, offset in y and z so that the faces overlap partly (face-face contact)
    a = geom("box", [0.2, -0.1, 0.3], size=[0.5, 0.4, 0.3])
    b = geom("box", [0.2 + 0.5 + 0.25 + gap, 0.1, 0.45], size=[0.25, 0.35, 0.2])
    d, n, xa, xb, info = distance(a, b)
    assert d == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n, [1, 0, 0], rtol=0, atol=1e-15)
    assert xa[0] == pytest.approx(0.7, abs=1e-15) and xb[0] == pytest.approx(0.7 + gap, abs=1e-15)
    assert info[0] == CONVERGED and info[3] <= 1e-15
    # swapped: the normal flips, the distance stays
    d2, n2, _, _, _ = distance(b, a)
    assert d2 == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n2, [-1, 0, 0], rtol=0, atol=1e-15)


def test_box_box_rotated_overlap_by_the_separating_axis_theorem():
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(100):
        Ra, Rb = rotation(rng), rotation(rng)
        sa, sb = rng.uniform(0.1, 0.5, 3), rng.uniform(0.1, 0.5, 3)
        pb = rng.normal(size=3) * 0.2
        depth, axis, second = sat_depth(np.zeros(3), Ra, sa, pb, Rb, sb)
        if depth <= 0:
            continue
        a, b = geom("box", np.zeros(3), Ra, sa), geom("box", pb, Rb, sb)
        d, n, xa, xb, info = distance(a, b)
        worst = max(worst, abs(d + depth))
        assert info[0] == CONVERGED
        if second > depth + 1e-9:  # a unique least axis: the normal
            np.testing.assert_allclose(n, axis, rtol=0, atol=1e-13)
        assert certified(a, b, n) == pytest.approx(d, abs=1e-14)  # the normal certifies the depth
        np.testing.assert_allclose(xb - xa, d * n, rtol=0, atol=1e-14)
    assert worst <= 1e-14


@pytest.mark.parametrize("gap", GAPS)
def test_capsules_parallel(gap):
    # two parallel capsules along z, radii 0.1 and 0.2, axes 0.3 + gap apart along y, overlapping in z
    a = geom("capsule", [0, 0, 0], size=[0.1, 0.5])
    b = geom("capsule", [0, 0.3 + gap, 0.4], size=[0.2, 0.3])
    d, n, xa, xb, info = distance(a, b)
    assert d == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n, [0, 1, 0], rtol=0, atol=1e-15)
    assert xa[1] == pytest.approx(0.1, abs=1e-15) and 0.1 - 1e-15 <= xa[2] <= 0.5 + 1e-15
    # end to end along the axis
    b = geom("capsule", [0, 0, 0.5 + 0.1 + 0.3 + 0.2 + gap], size=[0.2, 0.3])
    d, n, _, _, _ = distance(a, b)
    assert d == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n, [0, 0, 1], rtol=0, atol=1e-15)


@pytest.mark.parametrize("gap", GAPS)
def test_box_face_on_a_mesh_face(gap):
    # a mesh: a random convex cloud with a flat top face z = 0.2 (a square of 4 points), turned and moved; a box
    # resting on that face, turned about its normal, gap above it
    rng = np.random.default_rng(3)
    cloud = np.vstack([rng.normal(size=(40, 3)) * 0.1 - [0, 0, 0.15],
                       [[-0.3, -0.3, 0.2], [0.3, -0.3, 0.2], [0.3, 0.3, 0.2], [-0.3, 0.3, 0.2]]])
    cloud[:, 2] = np.minimum(cloud[:, 2], 0.2)
    hull = pack_hull(cloud)
    R = rotation(rng)
    p = np.array([0.5, -0.25, 1.0])
    mesh = geom("mesh", p, R, hull=hull)
    top = R[:, 2]
    Rbox = R @ turn_about([0, 0, 1], 0.4)
    box = geom("box", p + (0.2 + 0.1 + gap) * top + 0.05 * R[:, 0], Rbox, [0.15, 0.1, 0.1])
    d, n, xa, xb, info = distance(mesh, box)
    assert d == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n, top, rtol=0, atol=1e-14)
    assert info[0] == CONVERGED
    d2, n2, _, _, _ = distance(box, mesh)
    assert d2 == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(n2, -top, rtol=0, atol=1e-14)


def test_point_and_a_unit_cube_mesh():
    hull = pack_hull(0.5 * CUBE)
    cube = geom("mesh", [0, 0, 0], hull=hull)
    grad = np.empty(3)
    # inside: the nearest face plane
    assert point_signed_distance(*cube, np.array([0.1, 0.2, 0.45]), grad) == pytest.approx(-0.05, abs=1e-15)
    np.testing.assert_allclose(grad, [0, 0, 1], rtol=0, atol=1e-15)
    assert point_signed_distance(*cube, np.zeros(3), grad) == -0.5
    # outside a face, an edge, a corner
    assert point_signed_distance(*cube, np.array([0.7, 0.1, -0.2]), grad) == pytest.approx(0.2, abs=1e-15)
    np.testing.assert_allclose(grad, [1, 0, 0], rtol=0, atol=1e-15)
    assert point_signed_distance(*cube, np.array([0.8, 0.9, 0.1]), grad) == pytest.approx(0.5, abs=1e-15)
    np.testing.assert_allclose(grad, [0.6, 0.8, 0], rtol=0, atol=1e-15)
    x = np.array([0.5, 0.5, 0.5]) + np.array([1.0, 2.0, 2.0]) / 3.0 * 0.3
    assert point_signed_distance(*cube, x, grad) == pytest.approx(0.3, abs=1e-15)
    np.testing.assert_allclose(grad, [1 / 3, 2 / 3, 2 / 3], rtol=0, atol=1e-15)
    # turned and moved: the same distances in its frame
    R, p = turn_about([0, 0, 1], 0.3), np.array([1.0, 2.0, 3.0])
    turned = geom("mesh", p, R, hull=hull)
    assert point_signed_distance(*turned, p + R @ [0.7, 0.1, -0.2], grad) == pytest.approx(0.2, abs=1e-15)
    np.testing.assert_allclose(grad, R[:, 0], rtol=0, atol=1e-15)


def test_point_and_the_closed_forms():
    grad = np.empty(3)
    R = turn_about(np.array([1.0, 2.0, 2.0]) / 3.0, 0.7)
    p = np.array([0.3, -0.2, 0.1])
    cases = [("sphere", [0.5], [0.9, 0, 0], 0.4, [1, 0, 0]), ("sphere", [0.5], [0.1, 0, 0], -0.4, [1, 0, 0]),
             ("capsule", [0.2, 0.5], [0.3, 0, 0.6], 0.1 * np.sqrt(10) - 0.2, [0.3, 0, 0.1]),
             ("capsule", [0.2, 0.5], [0.05, 0, 0.2], -0.15, [1, 0, 0]),
             ("box", [0.5, 0.4, 0.3], [0.1, 0.45, 0], 0.05, [0, 1, 0]),
             ("box", [0.5, 0.4, 0.3], [0.1, 0.35, 0], -0.05, [0, 1, 0]),
             ("cylinder", [0.3, 0.2], [0.0, 0.4, 0.3], np.hypot(0.1, 0.1), [1, 0, 1]),
             ("cylinder", [0.3, 0.2], [0.0, 0.25, 0.1], -0.05, [1, 0, 0])]
    for kind, size, local, expected, direction in cases:
        g = geom(kind, p, R, size)
        d = point_signed_distance(*g, p + R @ np.asarray(local, float), grad)
        assert d == pytest.approx(expected, abs=1e-15), kind
        u = np.asarray(direction, float)
        if kind == "cylinder":
            u = np.array([0.0, 1.0, 1.0]) if expected > 0 else np.array([0.0, 1.0, 0.0])
        np.testing.assert_allclose(grad, R @ (u / np.linalg.norm(u)), rtol=0, atol=1e-15, err_msg=kind)


def point_ellipsoid_reference(x, s):
    """The distance of the point x (outside) from the ellipsoid of semi-axes s and the unit outward normal at the
    nearest point: x_i = s_i^2 p_i / (t + s_i^2) with t > 0 the root of sum (s_i p_i / (t + s_i^2))^2 = 1, which
    decreases in t, by bisection to the last bit."""
    lo, hi = 0.0, float(np.linalg.norm(x) * np.max(s)) + 1.0
    f = lambda t: np.sum((s * x / (t + s * s)) ** 2) - 1.0
    while True:
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
    y = s * s * x / (lo + s * s)
    offset = x - y
    return np.linalg.norm(offset), offset / np.linalg.norm(offset)


def test_sphere_and_ellipsoid_against_root_finding():
    """A curved pair: the distance to the duality gap (<= CURVED_TOLERANCE m), the normal to the bound the gap puts
    on it (|n - n*| <= sqrt(2 gap / d) for a point's distance d from C, about 1e-6)."""
    rng = np.random.default_rng(5)
    s = np.array([0.15, 0.1, 0.07])
    worst_d = worst_n = 0.0
    for _ in range(100):
        R = rotation(rng)
        u = rng.normal(size=3)
        c = u / np.linalg.norm(u) * rng.uniform(0.2, 0.6)
        d, n, xa, xb, info = distance(geom("sphere", c, size=[0.12]), geom("ellipsoid", np.zeros(3), R, s))
        ref, normal = point_ellipsoid_reference(R.T @ c, s)
        assert info[0] == CONVERGED and info[3] <= CURVED_TOLERANCE
        assert ref - 0.12 <= d + 1e-15 <= ref - 0.12 + info[3] + 2e-15  # the gap brackets the truth
        worst_d = max(worst_d, abs(d - (ref - 0.12)))
        worst_n = max(worst_n, np.linalg.norm(n + R @ normal))
    assert worst_d <= 1e-12
    assert worst_n <= 1e-5


def test_point_and_cylinder_by_gjk_and_epa_against_the_closed_form():
    """A capsule of zero length (GJK on its core point, EPA inside) against a cylinder, separated and overlapping,
    against the closed form (which a sphere takes): the distance within the duality gap, the normal within its
    bound (sqrt(2 gap / rho) for a point rho from the axis inside: 1e-4 here)."""
    rng = np.random.default_rng(9)
    s = np.array([0.1, 0.12, 0.0])
    grad = np.empty(3)
    worst, worst_n, capacity = 0.0, 0.0, 0
    for _ in range(200):
        R = rotation(rng)
        c = rng.normal(size=3) * 0.15
        d, n, xa, xb, info = distance(geom("capsule", c, size=[0.05, 0.0]), geom("cylinder", np.zeros(3), R, s))
        ref = point_signed_distance(CYLINDER, np.zeros(3), R, s, NONE, c, grad) - 0.05
        assert info[0] in (CONVERGED, EPA_CAPACITY)
        capacity += info[0] == EPA_CAPACITY  # a point near the axis: a ring of equal depths, EPA runs out
        assert ref - 1e-15 <= d <= ref + info[3] + 1e-15  # EPA's depth is a lower bound, GJK's distance an upper
        worst = max(worst, abs(d - ref))
        if info[0] == CONVERGED:
            worst_n = max(worst_n, np.linalg.norm(n + grad))
        # the sphere takes the closed form: exact
        d2, n2, xa2, xb2, info2 = distance(geom("sphere", c, size=[0.05]), geom("cylinder", np.zeros(3), R, s))
        assert d2 == ref and info2[1] == 0
        np.testing.assert_allclose(n2, -grad, rtol=0, atol=1e-15)
        np.testing.assert_allclose(xb2 - xa2, d2 * n2, rtol=0, atol=1e-15)
    assert worst <= 1e-12
    assert worst_n <= 1e-4
    assert capacity <= 10


def test_capsule_box_overlap_by_the_separating_axis_theorem():
    """A capsule's segment through a box: the cores' depth is the least overlap over the box's 3 face normals
    and the 3 crossings of the segment with its edges, plus the radius."""
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(200):
        Ra, Rb = rotation(rng), rotation(rng)
        sb = rng.uniform(0.1, 0.4, 3)
        pa = rng.normal(size=3) * 0.1
        r, h = 0.05, 0.3
        u = Ra[:, 2]
        axes = [Rb[:, i] for i in range(3)] + [np.cross(u, Rb[:, i]) / np.linalg.norm(np.cross(u, Rb[:, i]))
                                               for i in range(3)]
        depth = min(np.sum(sb * np.abs(Rb.T @ m)) + h * abs(u @ m) - abs(pa @ m) for m in axes)
        if depth <= 0:
            continue
        checked += 1
        d, n, xa, xb, info = distance(geom("capsule", pa, Ra, [r, h]), geom("box", np.zeros(3), Rb, sb))
        assert d == pytest.approx(-depth - r, abs=1e-14)
        assert info[0] == CONVERGED
    assert checked > 50


# ----- against MuJoCo ----------------------------------------------------------------------------------------------

SIZES = {"sphere": (0.12,), "capsule": (0.08, 0.15), "ellipsoid": (0.15, 0.1, 0.07), "cylinder": (0.1, 0.12),
         "box": (0.1, 0.07, 0.13)}
# Measured on 150 random separated poses per pair (seeds below, distances > 0.02 m), |ours - MuJoCo|: polytope
# pairs and the closed forms 0 to 7e-16 m (both exact to round-off: MuJoCo's GJK has no tolerance for boxes and
# meshes and stops on stagnation), so 1e-14; curved pairs 9e-13 to 1.5e-10 m: MuJoCo's GJK stops when |v| changes by
# less than 1e-15 between steps, before its duality gap closes (its distance can even fall 2e-13 below the truth,
# its witness point 5e-13 outside an ellipsoid, where ours run to a gap of 4e-17 brackets the truth), ours is within
# its gap (<= 1e-12) of the truth, so 5e-10. Normals (MuJoCo's witness direction): polytopes 2.5e-15, so 1e-11;
# curved pairs up to 1.8e-5: a duality gap g leaves the direction free by about sqrt(2 g / rho) on each side, so 1e-4.
DIST_TOL = {True: 1e-14, False: 5e-10}
NORMAL_TOL = {True: 1e-11, False: 1e-4}


def mujoco_pair(mujoco, kind_a, kind_b, rng):
    def geom_xml(name, kind, mesh):
        if kind == "mesh":
            return f'<geom name="{name}" type="mesh" mesh="{mesh}"/>'
        return f'<geom name="{name}" type="{kind}" size="{" ".join(map(repr, SIZES[kind]))}"/>'

    assets = ""
    for mesh in ("ma", "mb"):  # a random convex cloud, exact in float32 (MuJoCo keeps mesh vertices as floats)
        cloud = (rng.normal(size=(40, 3)) * [0.12, 0.09, 0.07]).astype(np.float32).astype(float)
        assets += f'<mesh name="{mesh}" vertex="{" ".join(repr(float(x)) for x in cloud.ravel())}"/>'
    xml = (f'<mujoco><option ccd_tolerance="1e-14" ccd_iterations="1000"/><asset>{assets}</asset><worldbody>'
           f'<body mocap="true">{geom_xml("a", kind_a, "ma")}</body>'
           f'<body mocap="true">{geom_xml("b", kind_b, "mb")}</body></worldbody></mujoco>')
    return mujoco.MjModel.from_xml_string(xml)


def mujoco_geom(model, data, g, hulls):
    """Our description of MuJoCo's geom g: its world frame (a mesh's geom frame is MuJoCo's mesh frame, in which
    model.mesh_vert holds its vertices) and the hull of its vertices."""
    kind = int(model.geom_type[g])
    hull = NONE
    if kind == MESH:
        if g not in hulls:
            mesh = model.geom_dataid[g]
            start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
            hulls[g] = pack_hull(model.mesh_vert[start:start + count].astype(float))
        hull = hulls[g]
    return kind, data.geom_xpos[g].copy(), data.geom_xmat[g].reshape(3, 3).copy(), model.geom_size[g].copy(), hull


@pytest.mark.parametrize("kind_a,kind_b", list(itertools.combinations_with_replacement(list(KINDS), 2)))
def test_against_mujoco_on_random_separated_poses(kind_a, kind_b):
    mujoco = pytest.importorskip("mujoco")
    rng = np.random.default_rng(list(KINDS).index(kind_a) * 10 + list(KINDS).index(kind_b))
    model = mujoco_pair(mujoco, kind_a, kind_b, rng)
    data = mujoco.MjData(model)
    # exact: polytope pairs, and a sphere with a cylinder (the centre's closed-form distance)
    exact = KINDS[kind_a] in POLYTOPES and KINDS[kind_b] in POLYTOPES or {kind_a, kind_b} == {"sphere", "cylinder"}
    hulls = {}
    fromto = np.zeros(6)
    checked, worst_d, worst_n = 0, 0.0, 0.0
    for _ in range(150):
        qa, qb = rng.normal(size=4), rng.normal(size=4)
        data.mocap_quat[0], data.mocap_quat[1] = qa / np.linalg.norm(qa), qb / np.linalg.norm(qb)
        offset = rng.normal(size=3)
        data.mocap_pos[1] = offset / np.linalg.norm(offset) * rng.uniform(0.25, 0.6)
        mujoco.mj_forward(model, data)
        reference = mujoco.mj_geomDistance(model, data, 0, 1, 10.0, fromto)
        if not reference > 0.02:
            continue
        a, b = mujoco_geom(model, data, 0, hulls), mujoco_geom(model, data, 1, hulls)
        d, n, xa, xb, info = distance(a, b)
        assert info[0] == CONVERGED
        direction = (fromto[3:] - fromto[:3]) / np.linalg.norm(fromto[3:] - fromto[:3])
        worst_d = max(worst_d, abs(d - reference))
        worst_n = max(worst_n, np.linalg.norm(n - direction))
        checked += 1
    assert checked >= 60
    assert worst_d <= DIST_TOL[exact]
    assert worst_n <= NORMAL_TOL[exact]


@pytest.mark.parametrize("kind_a,kind_b", [("sphere", "box"), ("sphere", "mesh"), ("capsule", "mesh"),
                                           ("box", "box"), ("box", "mesh"), ("mesh", "mesh")])
def test_against_mujoco_on_random_overlapping_polytopes(kind_a, kind_b):
    """EPA on polytope pairs against MuJoCo's EPA (exact for them): depths to round-off."""
    mujoco = pytest.importorskip("mujoco")
    rng = np.random.default_rng(100 + list(KINDS).index(kind_a) * 10 + list(KINDS).index(kind_b))
    model = mujoco_pair(mujoco, kind_a, kind_b, rng)
    data = mujoco.MjData(model)
    hulls = {}
    fromto = np.zeros(6)
    checked, worst_d, worst_n = 0, 0.0, 0.0
    for _ in range(100):
        qa, qb = rng.normal(size=4), rng.normal(size=4)
        data.mocap_quat[0], data.mocap_quat[1] = qa / np.linalg.norm(qa), qb / np.linalg.norm(qb)
        data.mocap_pos[1] = rng.normal(size=3) * 0.05
        mujoco.mj_forward(model, data)
        reference = mujoco.mj_geomDistance(model, data, 0, 1, 10.0, fromto)
        if not reference < -1e-3:
            continue
        a, b = mujoco_geom(model, data, 0, hulls), mujoco_geom(model, data, 1, hulls)
        d, n, xa, xb, info = distance(a, b)
        assert info[0] == CONVERGED
        direction = (fromto[:3] - fromto[3:]) / np.linalg.norm(fromto[3:] - fromto[:3])
        worst_d = max(worst_d, abs(d - reference))
        worst_n = max(worst_n, np.linalg.norm(n - direction))
        checked += 1
    assert checked > 50
    assert worst_d <= 1e-14
    assert worst_n <= 1e-11


# ----- invariants --------------------------------------------------------------------------------------------------

HULL = pack_hull(np.random.default_rng(17).normal(size=(30, 3)) * [0.12, 0.1, 0.08])
SHAPES = [geom("sphere", np.zeros(3), size=[0.1]), geom("capsule", np.zeros(3), size=[0.06, 0.12]),
          geom("ellipsoid", np.zeros(3), size=[0.12, 0.08, 0.05]), geom("cylinder", np.zeros(3), size=[0.08, 0.1]),
          geom("box", np.zeros(3), size=[0.1, 0.06, 0.08]), geom("mesh", np.zeros(3), hull=HULL)]


def posed(shape, quaternion, pos):
    q = np.asarray(quaternion, float)
    R = rotation(np.random.default_rng(0)) if not np.linalg.norm(q) > 1e-3 else None
    if R is None:
        w, x, y, z = q / np.linalg.norm(q)
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return shape[0], np.asarray(pos, float), R, shape[3], shape[4]


def tolerance(a, b, *infos):
    """The distance's accuracy: round-off for polytope pairs, the duality gaps for curved ones."""
    if a[0] in POLYTOPES and b[0] in POLYTOPES:
        return 1e-14
    return max(CURVED_TOLERANCE, *(info[3] for info in infos)) + 1e-14


quaternions = st.lists(st.floats(-1, 1), min_size=4, max_size=4)
offsets = st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 5), st.integers(0, 5), quaternions, quaternions, offsets)
def test_invariants(i, j, qa, qb, offset):
    a = posed(SHAPES[i], qa, [0.01, -0.02, 0.03])
    b = posed(SHAPES[j], qb, np.array([0.01, -0.02, 0.03]) + offset)
    d, n, xa, xb, info = distance(a, b)
    assert info[0] in (CONVERGED, EPA_CAPACITY)
    assume(info[0] == CONVERGED)  # EPA_CAPACITY: deep curved overlaps (coincident ellipsoids), test_status_reports
    tol = tolerance(a, b, info)
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(xb - xa, d * n, rtol=0, atol=1e-13)
    # the normal certifies the distance (-n.s_C(n) reaches it: n is a true normal to the tolerance)
    assert d - tol - 1e-13 <= certified(a, b, n) <= d + 1e-13
    # swapped: the same distance, a normal as good (its opposite certifies the first order's)
    d2, n2, _, _, info2 = distance(b, a)
    assume(info2[0] == CONVERGED)
    tol = tolerance(a, b, info, info2)
    assert d2 == pytest.approx(d, abs=tol)
    assert certified(a, b, -n2) >= d - info[3] - info2[3] - 1e-13  # c(-n2) >= d2 - gap2 >= truth - gap2
    # the witness points on the surfaces: the cores' barycentric combinations, within the gap; for a curved pair
    # also moved across the normal by |d| theta / 2 where a normal turned by theta from v's direction certified more
    # (theta <= 1e-8 on these sizes)
    slack = 0.0 if a[0] in POLYTOPES and b[0] in POLYTOPES else 1e-8 * abs(d)
    assert on_surface(a, xa) == pytest.approx(0.0, abs=tol + slack + 1e-13)
    assert on_surface(b, xb) == pytest.approx(0.0, abs=tol + slack + 1e-13)
    # b moved along the normal by t: the distance grows by t (overlapping or not)
    for t in (0.02, abs(d) + 0.01):
        moved = (b[0], b[1] + t * n, b[2], b[3], b[4])
        d3, _, _, _, info3 = distance(a, moved, guess=n)
        assert d3 == pytest.approx(d + t, abs=tolerance(a, b, info, info3) + 1e-13)


# ----- supports and hulls ------------------------------------------------------------------------------------------

def test_supports_in_closed_form():
    rng = np.random.default_rng(2)
    R, p = rotation(rng), np.array([0.3, -0.1, 0.2])
    out = np.empty(3)
    for _ in range(20):
        d = rng.normal(size=3)
        local = R.T @ d
        assert support(BOX, p, R, np.array([0.1, 0.2, 0.3]), NONE, d, out) >= 0
        np.testing.assert_allclose(out, p + R @ (np.sign(local) * [0.1, 0.2, 0.3]), rtol=0, atol=1e-15)
        support(SPHERE, p, R, np.array([0.2, 0, 0]), NONE, d, out)
        np.testing.assert_allclose(out, p + 0.2 * d / np.linalg.norm(d), rtol=0, atol=1e-15)
        s = np.array([0.3, 0.2, 0.1])
        assert support(ELLIPSOID, p, R, s, NONE, d, out) == -1
        y = R.T @ (out - p)
        assert np.sum((y / s) ** 2) == pytest.approx(1.0, abs=1e-14)  # on the surface
        normal = y / s ** 2  # the outward normal there is along d
        np.testing.assert_allclose(normal / np.linalg.norm(normal), local / np.linalg.norm(local), rtol=0, atol=1e-14)
        support(CYLINDER, p, R, np.array([0.2, 0.3, 0]), NONE, d, out)
        y = R.T @ (out - p)
        assert np.hypot(y[0], y[1]) == pytest.approx(0.2, abs=1e-15) and abs(y[2]) == pytest.approx(0.3, abs=1e-15)
        support(CAPSULE, p, R, np.array([0.1, 0.3, 0]), NONE, d, out)
        np.testing.assert_allclose(out, p + np.sign(local[2]) * 0.3 * R[:, 2] + 0.1 * d / np.linalg.norm(d),
                                   rtol=0, atol=1e-15)


def test_mesh_support_by_hill_climbing_is_the_brute_force_maximum():
    rng = np.random.default_rng(4)
    points = rng.normal(size=(2500, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    hull = pack_hull(points * [0.2, 0.15, 0.1])
    vertices = hull_vertices(hull)
    assert len(vertices) == 2500
    out = np.empty(3)
    hint = -1
    for _ in range(300):
        d = rng.normal(size=3)
        index = support(MESH, np.zeros(3), I3, np.zeros(3), hull, d, out, hint)
        assert vertices[index] @ d >= np.max(vertices @ d) - 1e-15  # the maximum (to the dot products' rounding)
        np.testing.assert_array_equal(out, vertices[index])
        hint = index if rng.uniform() < 0.5 else -1  # warm and cold starts


def test_pack_hull_merges_coplanar_triangles_and_keeps_the_edge_graph():
    R = rotation(np.random.default_rng(1))
    cloud = np.vstack([CUBE * [0.5, 0.3, 0.2], [[0.0, 0.0, 0.0], [0.1, 0.1, 0.05]]])  # 2 inner points
    hull = pack_hull(cloud @ R.T)
    assert hull[:2].tolist() == [8, 6]
    planes = hull_planes(hull)
    local = np.sort(np.abs(planes[:, :3] @ R), axis=0)  # each axis is the normal of two faces, on both sides
    np.testing.assert_allclose(local, [[0, 0, 0]] * 4 + [[1, 1, 1]] * 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.sort(planes[:, 3]), [0.2, 0.2, 0.3, 0.3, 0.5, 0.5], rtol=0, atol=1e-15)
    vertices = hull_vertices(hull)
    assert np.all(vertices @ planes[:, :3].T <= planes[:, 3] + 1e-15)
    for i, neighbours in enumerate(hull_neighbours(hull)):
        local = (vertices[neighbours] - vertices[i]) @ R
        on_edges = np.sum(np.count_nonzero(np.abs(local) > 1e-12, axis=1) == 1)
        assert on_edges == 3  # the cube's 3 edges from each corner (and the faces' diagonals, triangulated)


@pytest.mark.parametrize("points,message", [
    (CUBE[:3], "at least 4"),
    (np.vstack([CUBE[:7], [[np.nan, 0, 0]]]), "non-finite"),
    (np.vstack([CUBE[:7], [[np.inf, 0, 0]]]), "non-finite"),
    (CUBE * [1, 1, 0], "flat"),
    (np.outer(np.linspace(0, 1, 6), [1, 2, 3]), "flat"),
    (np.zeros((5, 3)), "flat"),
    (np.zeros((5, 2)), "shape"),
])
def test_pack_hull_refusals(points, message):
    with pytest.raises(ValueError, match=message):
        pack_hull(points)


# Two poses test_invariants' random search found (a CI run of 2026-11-30): the hull's edge leaning on the cylinder's
# rim nearly along it. The simplex held a thin triangle, two rim points 1e-8 m apart and a far one: its nearest point
# as the weights' combination carried their round-off along the edge (the normal turned 5e-8 rad, the rim's witness
# put 3.3e-11 m off it by the residual's half), and its angle test took it for a sliver (the second pose stalled at a
# gap of 3.8e-10 m). The nearest point as the projection on the plane, the normal from the short edge, and the
# residual moved onto the edge's witness mend both.
RIM_POSES = [([0.0625, -1.0, 0.0, 0.0], [0.0, 0.5, -0.6875, 0.65625], [0.298828125, 0.02114966644957228, 0.15625]),
             ([0.0625, -1.0, 0.0, 0.0], [0.0, 0.5, -0.6875, 0.65625], [0.298828125, 0.01953125, 0.15625])]


@pytest.mark.parametrize("qa, qb, offset", RIM_POSES)
def test_a_hull_on_a_cylinders_rim_converges_with_its_witness_on_the_rim(qa, qb, offset):
    a = posed(SHAPES[5], qa, [0.01, -0.02, 0.03])
    b = posed(SHAPES[3], qb, np.array([0.01, -0.02, 0.03]) + offset)
    d, n, xa, xb, info = distance(a, b)
    assert info[0] == CONVERGED and info[3] <= CURVED_TOLERANCE
    tol = tolerance(a, b, info)
    assert d - tol - 1e-13 <= certified(a, b, n) <= d + 1e-13
    assert on_surface(a, xa) == pytest.approx(0.0, abs=tol + 1e-13)
    assert on_surface(b, xb) == pytest.approx(0.0, abs=tol + 1e-13)


@pytest.mark.parametrize("flat", ["box", "mesh", "cylinder cap", "cylinder side"])
def test_an_ellipsoid_on_a_face_touches_at_its_point_with_the_faces_normal(flat):
    # an ellipsoid (turned at random) just above a box's or a mesh box's top face, a cylinder's cap, or the top line
    # of a cylinder lying along y: the contact point is the ellipsoid's point whose normal is the result's,
    # x = c - R diag(s^2) R^T n / |diag(s) R^T n|, to round-off, and for a face (the box's, the mesh's, the cap) that
    # normal is the face's exactly; the combination of GJK's support points, spread about the
    # contact by sqrt(2 gap rho), put it up to 1e-6 m away, a torque arm off by as much. (The side is curved around
    # its axis: there the normal is exact along the axis and within the tolerance's freedom around it.) Half the
    # poses lie within the curved tolerance of touching, 1e-16 to 1e-12 m apart or overlapping, where GJK hands
    # over to EPA: EPA's face normal, its support points' plane, was tilted up to 5.5e-13 and the distance 1.5e-13
    # m off (an ellipsoid resting on a mesh cube crept by it); the face's normal and the support points' gap along
    # it, the distance to round-off, are taken there too.
    rng = np.random.default_rng(8)
    s, up = np.array([0.12, 0.08, 0.05]), np.array([0.0, 0.0, 1.0])
    for i in range(40):
        R = rotation(rng)
        lowest = R @ (s ** 2 * (R.T @ up)) / np.linalg.norm(s * (R.T @ up))  # from the lowest point to the centre
        gap = 10.0 ** rng.uniform(-12, -4) if i % 2 else rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-16, -12)
        if flat == "cylinder side":
            face = geom("cylinder", [0.0, 0.0, -0.3], turn_about([1.0, 0.0, 0.0], np.pi / 2), [0.3, 0.2])
            centre = np.array([lowest[0], rng.uniform(-0.1, 0.1), lowest[2] + gap])  # the lowest point over x = 0
        else:
            face = {"box": geom("box", [0.0, 0.0, -0.1], I3, [0.3, 0.3, 0.1]),
                    "mesh": geom("mesh", [0.0, 0.0, -0.1], I3, hull=pack_hull(CUBE * [0.3, 0.3, 0.1])),
                    "cylinder cap": geom("cylinder", [0.0, 0.0, -0.1], I3, [0.3, 0.1])}[flat]
            centre = np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), lowest[2] + gap])
        ellipsoid = geom("ellipsoid", centre, R, s)
        d, n, xa, xb, info = distance(face, ellipsoid)
        assert info[0] == CONVERGED
        if flat == "cylinder side":
            assert d == pytest.approx(gap, abs=1e-12)
            assert abs(n[1]) <= 1e-15 and np.linalg.norm(n - up) <= 1e-5
        else:  # the face's normal: the distance is exact
            assert d == pytest.approx(gap, rel=0, abs=1e-16)
            np.testing.assert_allclose(n, up, rtol=0, atol=1e-15)
        point = centre - R @ (s ** 2 * (R.T @ n)) / np.linalg.norm(s * (R.T @ n))
        np.testing.assert_allclose(xb, point, rtol=0, atol=2e-16)
        np.testing.assert_allclose(xa, xb - d * n, rtol=0, atol=2e-16)
        # the distance's own error; on the side, a normal turned by theta about the axis also moves the witness off
        # the side by about (R + rho) theta^2 / 2 (R = 0.3, the ellipsoid's curvature radius rho <= 0.12^2 / 0.05)
        turned = 0.3 * float(np.linalg.norm(n - up)) ** 2 if flat == "cylinder side" else 0.0
        assert on_surface(face, xa) == pytest.approx(0.0, abs=abs(d - gap) + turned + 1e-14)


def touching(rng, i, j, target):
    """Shapes i and j in random poses, b moved along a random direction until their signed distance is `target`
    (bisection to round-off)."""
    qa, qb = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    a = posed(SHAPES[i], qa, [0.01, -0.02, 0.03])
    lo, hi = 0.0, 0.6
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if distance(a, posed(SHAPES[j], qb, np.array([0.01, -0.02, 0.03]) + mid * u))[0] < target:
            lo = mid
        else:
            hi = mid
    return a, posed(SHAPES[j], qb, np.array([0.01, -0.02, 0.03]) + hi * u)


CURVED_PAIRS = [(i, j) for i in range(6) for j in range(6) if {i, j} & {2, 3} and {i, j} != {0, 3}]


@pytest.mark.parametrize("i, j", CURVED_PAIRS)
def test_curved_pairs_touching_converge(i, j):
    # every pair with an ellipsoid or a cylinder (but the sphere and the cylinder: closed form), 24 random poses each
    # brought to touching, from 1e-15 m to 1e-9 m apart or overlapping: GJK ends within the curved tolerance
    # (converged, not stalled), its normal certifies the distance, the witnesses lie on the surfaces. Before the
    # thin triangles were mended (the nearest point as a projection, the normal from the shortest edges, steering
    # along the best normal after a stall, EPA where the gap spans 0), 13% of such poses stalled, a few with a gap
    # of 0.4 m (a normal pointing anywhere).
    rng = np.random.default_rng(100 * i + j)
    for k in range(24):
        target = 10.0 ** rng.uniform(-15, -9) * (1.0 if k % 4 else -1.0)
        a, b = touching(rng, i, j, target)
        d, n, xa, xb, info = distance(a, b)
        assert info[0] == CONVERGED, (k, info)
        tol = tolerance(a, b, info)
        assert info[3] <= CURVED_TOLERANCE
        assert d - tol - 1e-13 <= certified(a, b, n) <= d + 1e-13
        np.testing.assert_allclose(xb - xa, d * n, rtol=0, atol=1e-13)
        assert on_surface(a, xa) == pytest.approx(0.0, abs=tol + 1e-13)
        assert on_surface(b, xb) == pytest.approx(0.0, abs=tol + 1e-13)


def test_status_reports():
    # a mesh without a hull: BAD_INPUT, NaN
    d, n, _, _, info = distance(geom("mesh", np.zeros(3)), geom("sphere", [1, 0, 0], size=[0.1]))
    assert np.isnan(d) and np.all(np.isnan(n)) and info[0] == BAD_INPUT
    # two coincident ellipsoids: the deepest, most symmetric overlap; EPA runs out of vertices before the gap
    # closes, says so, and its depth is within the gap it reports
    e = geom("ellipsoid", np.zeros(3), size=[0.5, 0.4, 0.3])
    d, n, _, _, info = distance(e, e)
    assert info[0] == EPA_CAPACITY and info[3] > CURVED_TOLERANCE
    assert -0.6 - 1e-15 <= d <= -0.6 + info[3]
    # polytope pairs end in a few steps
    d, n, _, _, info = distance(geom("box", np.zeros(3), rotation(np.random.default_rng(0)), [0.1, 0.2, 0.3]),
                                geom("mesh", [0.5, 0.1, 0.0], hull=HULL))
    assert info[0] == CONVERGED and info[1] <= 10 and info[2] == 0
