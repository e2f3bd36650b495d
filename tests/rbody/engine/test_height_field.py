"""Height fields in the rigid limit (rbody.engine.contacts.terrain): a geom's candidates are exact distances from the
triangulated surface's faces and convex edges (against a brute-force distance on a random field), no internal
walls between cells (a box on a planar ramp of many cells sees only the ramp's normal), and closed forms through
the whole engine: a sphere thrown sliding on a flat field rolls from t* = 2 v0 / (7 mu g) at 5/7 v0 (the chapter's
slide-to-roll transition), a sphere rests in a V valley at r / cos(alpha) above its floor, a block on a ramp of
many cells sticks at mu = tan(alpha) (1 + 1e-6) and slides across the cells' edges and diagonals as the
time-stepping's closed form at mu = tan(alpha) / 2, a sphere rolls down it at 5/7 g sin(alpha); MJCF height fields
load, export to MuJoCo with the same surface, and bad input is refused."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.engine.contacts.terrain import field_candidates
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix

G = 9.81
I3 = np.eye(3)


def field(heights, size, pos=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0)):
    return Shape("ground", "hfield", size, pos=pos, quat=quat, heights=np.asarray(heights))


def ramp(alpha, n=21, half=3.0):
    """A plane rising along +x at angle alpha, as a field of n x n vertices over [-half, half]^2."""
    rise = 2 * half * np.tan(alpha)
    return field(np.tile(np.linspace(0.0, 1.0, n), (n, 1)), (half, half, rise, 0.1))


def surface_distance(point, shape):
    """Brute force: the distance [m] of point (3,) from the field's triangulated surface (every triangle's closest
    point, Ericson's region tests), signed by the side (below the surface: negative)."""
    heights = np.asarray(shape.heights)
    nrow, ncol = heights.shape
    sx, sy, sz, _ = shape.size
    x, y = np.linspace(-sx, sx, ncol), np.linspace(-sy, sy, nrow)
    V = lambda r, c: np.array([x[c], y[r], sz * heights[r, c]])  # noqa: E731
    best = np.inf
    for r in range(nrow - 1):
        for c in range(ncol - 1):
            for tri in ((V(r + 1, c), V(r, c), V(r + 1, c + 1)), (V(r, c), V(r + 1, c + 1), V(r, c + 1))):
                best = min(best, np.linalg.norm(point - closest_on_triangle(point, *tri)))
    return -best if point[2] < surface_height(point, shape) else best


def surface_height(point, shape):
    """The height [m] of the field's surface, in its frame, under point (x, y, ...): its cell's triangle (T0 above
    the diagonal (r, c)-(r+1, c+1), T1 below), interpolated."""
    heights = np.asarray(shape.heights)
    nrow, ncol = heights.shape
    sx, sy, sz, _ = shape.size
    x, y = np.linspace(-sx, sx, ncol), np.linspace(-sy, sy, nrow)
    c = min(int((point[0] + sx) / (x[1] - x[0])), ncol - 2)
    r = min(int((point[1] + sy) / (y[1] - y[0])), nrow - 2)
    u, v = (point[0] - x[c]) / (x[1] - x[0]), (point[1] - y[r]) / (y[1] - y[0])
    z00, z01, z10, z11 = sz * heights[r, c], sz * heights[r, c + 1], sz * heights[r + 1, c], sz * heights[r + 1, c + 1]
    return z00 + u * (z11 - z10) + v * (z10 - z00) if v >= u else z00 + u * (z01 - z00) + v * (z11 - z01)


def closest_on_triangle(p, a, b, c):
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0 and d2 <= 0:
        return a
    bp = p - b
    d3, d4 = ab @ bp, ac @ bp
    if d3 >= 0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return a + d1 / (d1 - d3) * ab
    cp = p - c
    d5, d6 = ab @ cp, ac @ cp
    if d6 >= 0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return a + d2 / (d2 - d6) * ac
    va = d3 * d6 - d5 * d4
    if va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
        return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)
    denom = 1.0 / (va + vb + vc)
    return a + ab * vb * denom + ac * vc * denom


def test_a_sphere_over_a_random_field_is_its_exact_distance_from_the_surface():
    rng = np.random.default_rng(3)
    shape = field(rng.uniform(0, 1, size=(9, 9)), (1.0, 1.0, 0.3, 0.1))
    checked = 0
    for _ in range(200):
        centre = np.array([*rng.uniform(-0.8, 0.8, 2), 0.0])
        r = rng.uniform(0.02, 0.12)
        centre[2] = 0.3 + rng.uniform(-0.25, 0.1)
        truth = surface_distance(centre, shape)
        if truth <= r * 0.01:  # keep to spheres above the surface
            continue
        dist, normal, point = field_candidates(shape, "sphere", centre, I3, (r,))
        assert np.all(dist >= truth - r - 1e-14)  # never below the true distance
        np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, rtol=0, atol=1e-14)
        if truth <= r:  # touching or overlapping: the nearest surface point is under the sphere, in its window
            assert dist.min() == pytest.approx(truth - r, abs=1e-14)
            checked += 1
    assert checked > 30


def solid_boundary(shape):
    """The triangles (T, 3, 3) [m] of the terrain solid's closed boundary in the field's frame: the surface's, each
    wall's two per rim segment (from the rim down to the base), the base's two."""
    heights = np.asarray(shape.heights)
    nrow, ncol = heights.shape
    sx, sy, sz, base = shape.size
    x, y = np.linspace(-sx, sx, ncol), np.linspace(-sy, sy, nrow)
    V = lambda r, c: np.array([x[c], y[r], sz * heights[r, c]])  # noqa: E731
    B = lambda r, c: np.array([x[c], y[r], -base])  # noqa: E731
    triangles = []
    for r in range(nrow - 1):
        for c in range(ncol - 1):
            triangles += [(V(r + 1, c), V(r, c), V(r + 1, c + 1)), (V(r, c), V(r + 1, c + 1), V(r, c + 1))]
    rims = [[(r, 0) for r in range(nrow)], [(r, ncol - 1) for r in range(nrow)], [(0, c) for c in range(ncol)],
            [(nrow - 1, c) for c in range(ncol)]]
    for rim in rims:
        for (r0, c0), (r1, c1) in zip(rim[:-1], rim[1:]):
            triangles += [(V(r0, c0), V(r1, c1), B(r1, c1)), (V(r0, c0), B(r1, c1), B(r0, c0))]
    triangles += [(B(0, 0), B(0, ncol - 1), B(nrow - 1, ncol - 1)), (B(0, 0), B(nrow - 1, ncol - 1), B(nrow - 1, 0))]
    return np.array(triangles)


def solid_distance(point, shape):
    """Brute force: the distance [m] of point (3,) outside the terrain's solid from it (every boundary triangle's
    closest point); None for a point inside the solid."""
    sx, sy, _, base = shape.size
    if abs(point[0]) <= sx and abs(point[1]) <= sy and -base <= point[2] <= surface_height(point, shape):
        return None
    return min(np.linalg.norm(point - closest_on_triangle(point, *tri)) for tri in solid_boundary(shape))


def test_a_sphere_beside_or_under_a_field_is_its_exact_distance_from_the_solid():
    """The terrain is a solid (MuJoCo's prisms, from the surface down to the base): a sphere beside the field, below
    its rim, or under its base meets its walls, their edges and its base at their exact distance, never below it."""
    rng = np.random.default_rng(5)
    shape = field(rng.uniform(0, 1, size=(7, 7)), (1.0, 0.8, 0.3, 0.1))
    checked = {"wall": 0, "base": 0}
    for _ in range(1000):
        r = rng.uniform(0.02, 0.12)
        centre = np.array([rng.uniform(-1.2, 1.2), rng.uniform(-1.0, 1.0), rng.uniform(-0.3, 0.35)])
        if abs(centre[0]) <= 1.0 and abs(centre[1]) <= 0.8 and centre[2] >= -0.1:
            continue  # over the rectangle above the base: the surface's test above
        truth = solid_distance(centre, shape)
        if truth is None or truth <= r * 0.01:
            continue
        dist, normal, _ = field_candidates(shape, "sphere", centre, I3, (r,))
        assert np.all(dist >= truth - r - 1e-14)  # never below the true distance
        np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, rtol=0, atol=1e-14)
        if truth <= r:  # touching or overlapping: the solid's nearest point is within the sphere's reach
            assert dist.size and dist.min() == pytest.approx(truth - r, abs=1e-14)
            checked["base" if centre[2] < -0.1 else "wall"] += 1
    assert checked["wall"] > 40 and checked["base"] > 10


def test_a_box_beside_a_wall_touches_it_by_its_four_corners():
    # a plateau 0.3 m high on a base 0.1 m deep; a 0.2 m cube 1 mm from its +x wall, below the rim: the cube's four
    # corners facing the wall, at 1 mm, the wall's outward normal
    plateau = field(np.ones((5, 5)), (1.0, 1.0, 0.3, 0.1))
    dist, normal, point = field_candidates(plateau, "box", [1.0 + 0.1 + 1e-3, 0.3, 0.05], I3, (0.1, 0.1, 0.1))
    close = dist < 0.05
    assert close.sum() == 4
    np.testing.assert_allclose(dist[close], 1e-3, rtol=0, atol=1e-15)
    np.testing.assert_allclose(normal[close], np.tile([1.0, 0, 0], (4, 1)), rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.sort(point[close, 2]), [-0.05, -0.05, 0.15, 0.15], rtol=0, atol=1e-15)
    # lifted above the rim it clears the wall and meets the rim's edge instead: the wall is only below the rim
    dist, normal, _ = field_candidates(plateau, "box", [1.0 + 0.1 + 1e-3, 0.3, 0.3 + 0.1 + 1e-3], I3,
                                       (0.1, 0.1, 0.1))
    assert dist.min() == pytest.approx(np.sqrt(2) * 1e-3, abs=1e-15)  # the box's lower edge from the rim's edge


def test_a_corner_edge_ends_at_the_rim_vertex_to_the_last_bit():
    # 0.45 m half-wide on 7 columns: the grid's last x, 6 * (0.9 / 6) - 0.45, is 0.4499999999999999, not 0.45. The
    # vertical edge at each corner runs from the base to the rim's corner vertex as the rim's own edges place it
    # (their common end is where _drop_repeats matches their candidates), and straight down from it
    from rbody.engine.contacts.terrain import _corner, _vertex, pack_field
    heights = np.random.default_rng(5).uniform(0.2, 1.0, (5, 7))
    record = pack_field(heights, (0.45, 0.3, 0.2, 0.1))
    for pf, Rf in ((np.zeros(3), I3), (np.array([0.1, -0.2, 0.3]), quat_to_matrix(np.array([0.9, 0.1, -0.3, 0.2])))):
        top, bottom, vertex = np.empty(3), np.empty(3), np.empty(3)
        for sign_x, sign_y in ((-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)):
            r, c = (4 if sign_y > 0 else 0), (6 if sign_x > 0 else 0)
            _vertex(record, pf, Rf, r, c, vertex)
            _corner(record, pf, Rf, sign_x, sign_y, False, top)
            _corner(record, pf, Rf, sign_x, sign_y, True, bottom)
            assert np.array_equal(top, vertex)
            drop = Rf.T @ (top - bottom)
            np.testing.assert_allclose(drop, [0.0, 0.0, 0.2 * heights[r, c] + 0.1], rtol=0, atol=1e-15)
            if pf @ pf == 0.0:  # the field's own frame: the edge is vertical to the last bit
                assert bottom[0] == top[0] and bottom[1] == top[1]


def test_a_sphere_in_a_valley_touches_both_faces_and_on_a_ridge_its_edge():
    xs = np.linspace(-3, 3, 21)
    valley = field(np.tile(np.abs(xs) / 3, (21, 1)), (3.0, 3.0, 3.0, 0.1))  # faces at 45 degrees
    r = 0.1
    dist, normal, _ = field_candidates(valley, "sphere", [0.0, 0.05, r * np.sqrt(2)], I3, (r,))
    np.testing.assert_allclose(dist, 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.sort(normal[:, 0]), [-np.sqrt(0.5), np.sqrt(0.5)], rtol=0, atol=1e-15)
    ridge = field(np.tile(1 - np.abs(xs) / 3, (21, 1)), (3.0, 3.0, 3.0, 0.1))
    dist, normal, _ = field_candidates(ridge, "sphere", [0.0, 0.05, 3.0 + r + 0.01], I3, (r,))
    assert dist.min() == pytest.approx(0.01, abs=1e-15)
    np.testing.assert_allclose(normal[np.argmin(dist)], [0, 0, 1], rtol=0, atol=1e-15)
    # a box lying across the ridge rests on the ridge line: the span's ends and middle, normals up
    dist, normal, point = field_candidates(ridge, "box", [0.0, 0.05, 3.11], I3, (0.1, 0.1, 0.1))
    touching = dist <= 0.01 + 1e-15
    assert touching.sum() >= 3 and dist.min() == pytest.approx(0.01, abs=1e-15)
    np.testing.assert_allclose(normal[touching], np.tile([0, 0, 1], (touching.sum(), 1)), rtol=0, atol=1e-14)
    assert np.ptp(point[touching, 1]) == pytest.approx(0.2, abs=1e-12)  # from one end of the box to the other


def test_no_wall_between_cells_a_box_on_a_ramp_sees_only_the_ramp():
    alpha = 0.3
    shape = ramp(alpha)
    tilt = quat_to_matrix(np.array([np.cos(alpha / 2), 0.0, -np.sin(alpha / 2), 0.0]))
    n = tilt[:, 2]
    for x0 in (0.0, 0.15, 0.3, 0.449, 1.0):  # over cell edges, diagonals and interiors (cells 0.3 m)
        surface = np.array([x0, 0.3 * x0, 3.0 * np.tan(alpha) + x0 * np.tan(alpha)])
        dist, normal, _ = field_candidates(shape, "box", surface + (0.1 + 1e-3) * n, tilt, (0.1, 0.1, 0.1))
        close = dist < 0.05
        assert close.sum() == 4  # the four lower corners, each once
        np.testing.assert_allclose(dist[close], 1e-3, rtol=0, atol=1e-14)
        np.testing.assert_allclose(normal[close], np.tile(n, (4, 1)), rtol=0, atol=1e-14)


def simulate_on(shape_field, body_shape, inertia, pos, quat=(1.0, 0.0, 0.0, 0.0), friction=0.5, qvel=None,
                t_end=1.0, dt=2e-3):
    body = Body("body", inertia, shapes=(body_shape,), pos=tuple(pos), quat=tuple(quat))
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "body"),), fixed=(shape_field,),
                    contacts=(Contact(shape_field.name, body_shape.name, friction=friction),))
    return rbody.simulate(Scene.from_layout(layout, t_end=t_end, qvel0=qvel), dt=dt)


def test_a_sphere_thrown_sliding_on_a_field_rolls_at_five_sevenths():
    r, mu, v0, dt = 0.1, 0.5, 2.0, 2e-3
    flat = field(np.full((21, 21), 0.5), (3.0, 3.0, 1.0, 0.1))
    run = simulate_on(flat, Shape("s", "sphere", (r,)), Inertia.solid_sphere(1.0, r), (0.0, 0.0, 0.5 + r),
                      friction=mu, qvel=[v0, 0, 0, 0, 0, 0], t_end=0.6, dt=dt)
    v, spin, z = run["body.velocity"][:, 0], run["body.omega"][:, 1], run["body.com"][:, 2]
    t_star = 2 * v0 / (7 * mu * G)
    start = run.t[np.argmax(np.abs(v - r * spin) <= 1e-12)]
    assert t_star <= start <= t_star + dt
    np.testing.assert_allclose(v[run.t >= start], 5 / 7 * v0, rtol=0, atol=1e-12)
    assert np.abs(z - (0.5 + r)).max() <= 1e-14  # across cells' edges and diagonals: no bump


def test_a_sphere_rests_in_a_valley_at_the_closed_form_height():
    xs = np.linspace(-3, 3, 21)
    valley = field(np.tile(np.abs(xs) / 3, (21, 1)), (3.0, 3.0, 3.0, 0.1))
    r = 0.1
    run = simulate_on(valley, Shape("s", "sphere", (r,)), Inertia.solid_sphere(1.0, r), (0.0, 0.05, r * np.sqrt(2) + 0.05),
                      t_end=1.0)
    end = run["body.com"][-1]
    assert end[2] == pytest.approx(r * np.sqrt(2), abs=1e-13)  # r / cos(45 degrees) above the valley's floor
    assert abs(end[0]) <= 1e-13


def test_a_sphere_sliding_into_a_fields_wall_stops_at_it():
    """A sphere sliding on a frictionless floor (restitution 0) into the side of a plateau field standing on that
    floor: it stops at the wall at once, its centre r from it, and stays there, never into the terrain (before the
    field's sides were faces it slid under the plateau's rim into the solid)."""
    r, v0 = 0.1, 1.0
    floor = Shape("floor", "plane", (0.0, 0.0))
    plateau = field(np.ones((5, 5)), (1.0, 1.0, 0.3, 0.1), pos=(2.0, 0.0, 0.1))  # its base on the floor
    ball = Shape("s", "sphere", (r,))
    body = Body("body", Inertia.solid_sphere(1.0, r), shapes=(ball,), pos=(0.0, 0.0, r))
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "body"),), fixed=(floor, plateau),
                    contacts=(Contact("floor", "s", friction=0.0), Contact("ground", "s", friction=0.0)))
    run = rbody.simulate(Scene.from_layout(layout, t_end=1.5, qvel0=[v0, 0, 0, 0, 0, 0]), dt=2e-3)
    x, z = run["body.com"][:, 0], run["body.com"][:, 2]
    wall = 2.0 - 1.0 - r
    assert x.max() <= wall + 1e-12                      # never into the wall
    hit = run.t >= (wall - 0.0) / v0 + 2e-3             # a step after it reaches the wall
    np.testing.assert_allclose(x[hit], wall, rtol=0, atol=1e-12)
    assert np.abs(run["body.velocity"][hit]).max() <= 1e-12
    assert np.abs(z - r).max() <= 1e-14                 # on the floor throughout


@pytest.mark.parametrize("ratio", [1 + 1e-6, 0.5])
def test_a_block_on_a_ramp_of_many_cells_sticks_or_slides_exactly(ratio):
    alpha, dt, t_end = 0.3, 1e-2, 1.5
    mu = np.tan(alpha) * ratio
    tilt = (np.cos(alpha / 2), 0.0, -np.sin(alpha / 2), 0.0)
    n = quat_to_matrix(np.array(tilt))[:, 2]
    surface = np.array([1.0, 0.1, 3.0 * np.tan(alpha) + np.tan(alpha)])
    run = simulate_on(ramp(alpha), Shape("b", "box", (0.1, 0.1, 0.1)), Inertia.box(1.0, (0.2, 0.2, 0.2)),
                      surface + 0.1 * n, quat=tilt, friction=mu, t_end=t_end, dt=dt)
    moved = np.linalg.norm(run["body.com"] - run["body.com"][0], axis=1)
    if ratio > 1:
        assert moved.max() <= 1e-13
    else:  # down the ramp across 5 cells' edges and diagonals, as on a plane
        a = G * (np.sin(alpha) - mu * np.cos(alpha))
        assert moved[-1] > 1.5
        np.testing.assert_allclose(moved, a * run.t * (run.t + dt) / 2, rtol=0, atol=1e-12)


def test_a_sphere_rolls_down_a_ramp_of_many_cells_at_five_sevenths_g_sin_alpha():
    alpha, r, dt = 0.2, 0.1, 2e-3
    n = np.array([-np.sin(alpha), 0.0, np.cos(alpha)])
    surface = np.array([2.0, 0.0, 3.0 * np.tan(alpha) + 2.0 * np.tan(alpha)])
    run = simulate_on(ramp(alpha), Shape("s", "sphere", (r,)), Inertia.solid_sphere(1.0, r), surface + r * n,
                      friction=0.5, t_end=1.5, dt=dt)
    moved = np.linalg.norm(run["body.com"] - run["body.com"][0], axis=1)
    a = 5 / 7 * G * np.sin(alpha)
    assert moved[-1] > 1.5
    np.testing.assert_allclose(moved, a * run.t * (run.t + dt) / 2, rtol=0, atol=1e-12)
    height = (run["body.com"] - surface) @ n  # its centre r above the ramp throughout
    np.testing.assert_allclose(height, r, rtol=0, atol=1e-13)


FIELD_MJCF = """<mujoco>
  <asset>
    <hfield name="bumps" nrow="3" ncol="4" size="1.5 1 0.4 0.1" elevation="2 3 2 1  3 5 3 1  1 2 1 1"/>
  </asset>
  <worldbody>
    <geom name="ground" type="hfield" hfield="bumps" pos="0.1 0 -0.05"/>
    <body name="ball" pos="0.2 0.1 0.8">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.1" mass="1"/>
    </body>
  </worldbody>
</mujoco>"""


def assert_surface_is_mujocos(mujoco, path, ground):
    """A ray cast straight down onto the field of the model at path, in MuJoCo, meets rbody's triangles' height
    (the field's shape `ground`, placed without rotation), to MuJoCo's single precision, at points over every
    quarter of the field."""
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ball = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "ball")
    sx, sy = ground.size[:2]
    for u, v in ((-0.8, -0.7), (-0.27, 0.8), (0.33, -0.3), (0.87, 0.6), (0.0, -0.9), (0.0, 0.9)):
        x, y = u * sx, v * sy
        start = np.array([ground.pos[0] + x, ground.pos[1] + y, 5.0])
        distance = mujoco.mj_ray(model, data, start, np.array([0.0, 0.0, -1.0]), None, 1, ball, np.zeros(1, np.int32))
        assert abs((5.0 - distance) - (ground.pos[2] + surface_height((x, y), ground))) <= 1e-6 * ground.size[2]


def test_an_mjcf_height_field_loads_runs_and_exports_to_mujoco(tmp_path):
    mujoco = pytest.importorskip("mujoco")
    path = tmp_path / "field.xml"
    path.write_text(FIELD_MJCF)
    scene = rbody.from_mjcf(path)
    ground = next(s for s in scene.layout.fixed if s.name == "ground")
    heights = np.asarray(ground.heights)
    # elevation lists its rows from y = +1 down, as MuJoCo's compiler reads them: row 0 (y = -1) is its last
    np.testing.assert_allclose(heights, (np.array([[1, 2, 1, 1], [3, 5, 3, 1], [2, 3, 2, 1]]) - 1) / 4, rtol=0, atol=0)
    assert ground.pos == (0.1, 0.0, -0.05)
    assert_surface_is_mujocos(mujoco, path, ground)
    run = rbody.simulate(scene, dt=2e-3, t_end=0.6, progress=False)
    # it lands on the bump and rolls off it: never into the surface, on it from the landing
    gaps = np.array([field_candidates(ground, "sphere", centre, I3, (0.1,))[0].min()
                     for centre in run["ball.com"][::10]])
    assert gaps.min() >= -1e-12
    landed = np.argmax(gaps <= 1e-12)
    assert 0 < landed and np.abs(gaps[landed:]).max() <= 1e-12
    exported = rbody.to_mjcf(scene)
    model = mujoco.MjModel.from_xml_string(exported)
    data = np.asarray(model.hfield_data).reshape(3, 4)
    low = heights.min()
    np.testing.assert_allclose(low * ground.size[2] + data * model.hfield_size[0, 2], heights * ground.size[2],
                               rtol=0, atol=1e-7)  # MuJoCo's single precision


# FIELD_MJCF's scene on a field read from a file in meshdir
FILE_MJCF = FIELD_MJCF.replace("<mujoco>", '<mujoco>\n  <compiler meshdir="terrain"/>').replace(
    '<hfield name="bumps" nrow="3" ncol="4" size="1.5 1 0.4 0.1" elevation="2 3 2 1  3 5 3 1  1 2 1 1"/>',
    '<hfield name="bumps" file="{file}" size="1.5 1 0.4 0.1"/>')


@pytest.mark.parametrize("kind", ["png", "bin"])
def test_a_height_field_from_a_file_is_read_as_mujoco_reads_it(tmp_path, kind):
    """A <hfield file=...> in meshdir, a PNG (its rows from its top at y = +size[1], its grey levels) or MuJoCo's
    binary (int32 nrow, ncol, float32 elevations from y = -size[1]), neither symmetric: rbody's heights are MuJoCo's
    hfield_data to the bit, its surface MuJoCo's, and a ball dropped on it lands without entering it."""
    mujoco = pytest.importorskip("mujoco")
    rows = np.array([[0, 40, 80, 120, 90], [30, 200, 250, 60, 20], [10, 70, 150, 100, 0], [0, 0, 60, 30, 10]])
    (tmp_path / "terrain").mkdir()
    if kind == "png":
        import matplotlib.image

        matplotlib.image.imsave(tmp_path / "terrain" / "field.png", rows.astype(np.uint8), cmap="gray", vmin=0,
                                vmax=255)
    else:
        with open(tmp_path / "terrain" / "field.bin", "wb") as out:
            np.array(rows.shape, dtype=np.int32).tofile(out)
            rows.astype(np.float32).tofile(out)
    path = tmp_path / "field.xml"
    path.write_text(FILE_MJCF.format(file=f"field.{kind}"))
    scene = rbody.from_mjcf(path)
    ground = next(s for s in scene.layout.fixed if s.name == "ground")
    model = mujoco.MjModel.from_xml_path(str(path))
    np.testing.assert_array_equal(np.asarray(ground.heights), np.asarray(model.hfield_data).reshape(rows.shape))
    # the row at y = -1: the binary's first, the PNG's last (its top row lies at +y)
    np.testing.assert_allclose(np.asarray(ground.heights)[0], rows[0 if kind == "bin" else -1] / rows.max(),
                               rtol=0, atol=1e-6)
    assert_surface_is_mujocos(mujoco, path, ground)
    run = rbody.simulate(scene, dt=2e-3, t_end=0.5, progress=False)
    gaps = np.array([field_candidates(ground, "sphere", centre, I3, (0.1,))[0].min() for centre in run["ball.com"]])
    assert gaps.min() >= -1e-12 and gaps[-1] <= 1e-12  # it lands, never into the surface


def test_bad_height_fields_are_refused(tmp_path):
    with pytest.raises(ValueError, match="expected 4 positive numbers"):
        Shape("g", "hfield", (1.0, 1.0, 0.5), heights=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="in \\[0, 1\\]"):
        Shape("g", "hfield", (1.0, 1.0, 0.5, 0.1), heights=np.full((3, 3), 2.0))
    with pytest.raises(ValueError, match="each >= 2"):
        Shape("g", "hfield", (1.0, 1.0, 0.5, 0.1), heights=np.zeros((1, 3)))
    with pytest.raises(ValueError, match="only a hfield shape"):
        Shape("g", "box", (1.0, 1.0, 0.5), heights=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="world-fixed terrain"):
        Body("b", Inertia.solid_sphere(1.0, 0.1), shapes=(field(np.zeros((3, 3)), (1, 1, 1, 1)),))
    fine = field(np.zeros((201, 201)), (1.0, 1.0, 0.1, 0.1))  # cells of 1 cm under a 0.5 m box: too many slots
    body = Body("body", Inertia.box(1.0, (1, 1, 1)), shapes=(Shape("b", "box", (0.5, 0.5, 0.5)),), pos=(0, 0, 1))
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "body"),), fixed=(fine,),
                    contacts=(Contact("ground", "b"),))
    with pytest.raises(ValueError, match="spans up to .* cells of height field 'ground'"):
        rbody.simulate(Scene.from_layout(layout, t_end=0.01), dt=1e-3)
    (tmp_path / "broken.png").write_bytes(b"not a PNG")
    for text, match in (('file="terrain.png" size="1 1 1 1"', "height field file .*terrain.png' does not exist"),
                        ('file="broken.png" size="1 1 1 1"', "broken.png': MuJoCo's compiler cannot read it"),
                        ('file="broken.png" size="1 1 1 1" elevation="1 2 3 4"', "give one of them"),
                        ('nrow="3" ncol="3" size="1 1 1 1" elevation="1 2"', "must match nrow\\*ncol"),
                        ('nrow="3" ncol="3" size="1 1 0 1"', "4 sizes > 0")):
        path = tmp_path / "bad.xml"
        path.write_text(f'<mujoco><asset><hfield name="f" {text}/></asset><worldbody>'
                        '<geom type="hfield" hfield="f"/></worldbody></mujoco>')
        with pytest.raises(rbody.mjcf.MJCFError, match=match):
            rbody.from_mjcf(path)
