"""Ellipsoids (rbody.engine.contacts.ellipsoid): a point's signed distance and normal against closed forms (points on
the axes, on the planes of symmetry, a sphere, spheroids), against the nearest point in 50 digits (every real root of
Eberly's sextic by mpmath, the least distance taken) for 300 points inside, outside, near the surface and near the
planes of symmetry of ellipsoids up to 1:100, against MuJoCo's mj_geomDistance for a small sphere; the support
point and a plane's distance in closed form; a segment's closest point against sampling and refinement; and, by
hypothesis, the distance's invariance under rigid motions and its unit rate along its gradient."""

import inspect

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.optimize import minimize_scalar

from rbody.engine.contacts.ellipsoid import (ellipsoid_distance, ellipsoid_support, plane_ellipsoid,
                                             segment_ellipsoid_closest)
from rbody.motion import quat_to_matrix

EPS = np.finfo(float).eps
I3 = np.eye(3)
ORIGIN = np.zeros(3)


def random_rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def distance(x, pc, Rc, s):
    grad = np.empty(3)
    d = ellipsoid_distance(np.asarray(x, float), np.asarray(pc, float), np.asarray(Rc, float), np.asarray(s, float),
                           grad)
    return d, grad


# ----- closed forms ------------------------------------------------------------------------------------------------

def test_points_on_the_axes():
    """Semi-axes (0.3, 0.5, 0.2) along x, y, z, turned and moved: outside on an axis |y_i| - s_i, along the axis; on
    the smallest axis inside, s_i - |y_i| to the pole; the centre, the smallest semi-axis to either pole; on the
    surface, 0. Inside on the longest axis (y, 0, 0) in the ellipsoid's sorted axes (e0 = 0.5 along y), near the
    centre (e0 |y| < e0^2 - e2^2), the nearest point lies off the axis, at x0 = e0^2 y / (e0^2 - e2^2): distance
    -e2 sqrt(1 - y^2 / (e0^2 - e2^2)); farther out (e0 |y| >= e0^2 - e2^2), the pole."""
    s = np.array([0.3, 0.5, 0.2])
    Rc = quat_to_matrix(np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2]))
    pc = np.array([0.4, -1.3, 2.0])
    for axis in range(3):
        for sign in (1.0, -1.0):
            for y, expected in ((s[axis] + 0.7, 0.7), (s[axis], 0.0)):
                d, grad = distance(pc + sign * y * Rc[:, axis], pc, Rc, s)
                assert d == pytest.approx(expected, abs=4 * EPS)
                np.testing.assert_allclose(grad, sign * Rc[:, axis], rtol=0, atol=4 * EPS)
    for y in (0.05, 0.15):  # on the smallest axis, inside
        d, grad = distance(pc - y * Rc[:, 2], pc, Rc, s)
        assert d == pytest.approx(y - 0.2, abs=4 * EPS)
        np.testing.assert_allclose(grad, -Rc[:, 2], rtol=0, atol=4 * EPS)
    d, grad = distance(pc, pc, Rc, s)  # the centre
    assert d == pytest.approx(-0.2, abs=4 * EPS)
    assert abs(grad @ Rc[:, 2]) == pytest.approx(1.0, abs=4 * EPS)
    e0, e2 = 0.5, 0.2
    for y in (0.0, 0.1, 0.3):  # on the longest axis near the centre: off it
        d, grad = distance(pc + y * Rc[:, 1], pc, Rc, s)
        assert d == pytest.approx(-e2 * np.sqrt(1 - y * y / (e0 * e0 - e2 * e2)), abs=4 * EPS)
        x0 = e0 * e0 * y / (e0 * e0 - e2 * e2)
        x2 = e2 * np.sqrt(1 - (x0 / e0) ** 2)
        local = np.array([0.0, x0 / e0 ** 2, x2 / e2 ** 2])
        np.testing.assert_allclose(np.abs(Rc.T @ grad), local / np.linalg.norm(local), rtol=0, atol=4 * EPS)
    for y in (0.45, 0.49):  # e0 y >= e0^2 - e2^2 = 0.21: the pole
        d, grad = distance(pc - y * Rc[:, 1], pc, Rc, s)
        assert d == pytest.approx(y - 0.5, abs=4 * EPS)
        np.testing.assert_allclose(grad, -Rc[:, 1], rtol=0, atol=4 * EPS)


def test_points_on_a_plane_of_symmetry():
    """Inside on the plane of the two longest axes, near the centre, the nearest point is off the plane, where
    t = -e2^2: x_i = e_i^2 y_i / (e_i^2 - e2^2), x2 = e2 sqrt(1 - (x0 / e0)^2 - (x1 / e1)^2) (Eberly); points on the
    other planes, on both sides, equal the same points a hair off the plane (the distance is continuous)."""
    s = np.array([0.6, 0.4, 0.1])
    y = np.array([0.12, -0.07, 0.0])
    d, grad = distance(y, ORIGIN, I3, s)
    x = np.array([s[0] ** 2 * y[0] / (s[0] ** 2 - s[2] ** 2), s[1] ** 2 * y[1] / (s[1] ** 2 - s[2] ** 2), 0.0])
    x[2] = s[2] * np.sqrt(1 - (x[0] / s[0]) ** 2 - (x[1] / s[1]) ** 2)
    assert d == pytest.approx(-np.linalg.norm(x - y), abs=4 * EPS)
    normal = x / s ** 2
    np.testing.assert_allclose(grad, normal / np.linalg.norm(normal), rtol=0, atol=4 * EPS)
    for point in ([0.0, 0.3, 0.05], [0.5, 0.0, -0.05], [0.0, 0.7, 0.3], [0.9, 0.0, -0.2], [0.3, 0.2, 0.0],
                  [0.1, 0.5, 0.0]):
        point = np.array(point)
        d, grad = distance(point, ORIGIN, I3, s)
        for axis in np.flatnonzero(point == 0.0):
            for side in (1.0, -1.0):
                nudged = point.copy()
                nudged[axis] = side * 1e-13
                d_nudged, grad_nudged = distance(nudged, ORIGIN, I3, s)
                assert abs(d - d_nudged) <= 1e-13
                np.testing.assert_allclose(grad_nudged[axis != np.arange(3)], grad[axis != np.arange(3)],
                                           rtol=0, atol=1e-10)


def test_sphere_and_spheroids():
    """All semi-axes equal: |x - c| - r along x - c. Spheroids (two equal semi-axes), whose equal pair Eberly's sort
    leaves tied: on the axis of a prolate one inside, -b sqrt(1 - y^2 / (a^2 - b^2)); on the axis of an oblate one,
    |y| - b; on its equator outside, |rho| - a along rho."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        pc, Rc, r = rng.normal(size=3), random_rotation(rng), rng.uniform(0.01, 2.0)
        x = pc + rng.normal(size=3) * r
        d, grad = distance(x, pc, Rc, [r, r, r])
        assert d == pytest.approx(np.linalg.norm(x - pc) - r, abs=4 * EPS * max(r, np.linalg.norm(x - pc)))
        np.testing.assert_allclose(grad, (x - pc) / np.linalg.norm(x - pc), rtol=0, atol=4 * EPS)
    a, b = 0.5, 0.2
    for y in (0.0, 0.1, 0.2):
        d, _ = distance([0.0, 0.0, y], ORIGIN, I3, [b, b, a])  # prolate along z
        assert d == pytest.approx(-b * np.sqrt(1 - y * y / (a * a - b * b)), abs=4 * EPS)
        d, grad = distance([0.0, y, 0.0], ORIGIN, I3, [a, b, a])  # oblate, its axis y
        assert d == pytest.approx(y - b, abs=4 * EPS)
        np.testing.assert_allclose(grad, [0, 1, 0], rtol=0, atol=4 * EPS)
    d, grad = distance([0.6, 0.0, 0.8], ORIGIN, I3, [a, b, a])  # on the equator, rho = 1
    assert d == pytest.approx(1.0 - a, abs=4 * EPS)
    np.testing.assert_allclose(grad, [0.6, 0, 0.8], rtol=0, atol=4 * EPS)


def test_support_point():
    """x = pc + R S^2 R^T d / |S R^T d|: on the surface (distance 0 to round-off), the normal there along d, and d.x
    no less than at any of 20000 points of the surface; the direction's length does not matter."""
    rng = np.random.default_rng(4)
    out, scaled = np.empty(3), np.empty(3)
    for _ in range(20):
        pc, Rc, s = rng.normal(size=3), random_rotation(rng), rng.uniform(0.01, 1.0, 3)
        d = rng.normal(size=3)
        ellipsoid_support(d, pc, Rc, s, out)
        ellipsoid_support(d * 1e-200, pc, Rc, s, scaled)
        np.testing.assert_allclose(scaled, out, rtol=0, atol=4 * EPS * np.abs(out).max())
        gap, grad = distance(out, pc, Rc, s)
        assert abs(gap) <= 8 * EPS * max(1.0, np.abs(pc).max())
        np.testing.assert_allclose(grad, d / np.linalg.norm(d), rtol=0, atol=1e-12)
        w = rng.normal(size=(20000, 3))
        surface = pc + (Rc @ (s[:, None] * (w / np.linalg.norm(w, axis=1, keepdims=True)).T)).T
        assert (surface @ d).max() <= out @ d + 1e-14
    ellipsoid_support(np.zeros(3), ORIGIN, I3, np.array([0.3, 0.2, 0.1]), out)  # d = 0: a point of the surface
    np.testing.assert_array_equal(out, [0.3, 0.0, 0.0])


def test_plane_distance():
    """Axis-aligned over the floor: the height less the vertical semi-axis, its lowest point straight below the
    centre. Turned: n.(pc - pp) - sqrt(n^T R S^2 R^T n), its point on the surface with outward normal -n, and no
    point of the surface lower."""
    point = np.empty(3)
    s = np.array([0.3, 0.2, 0.1])
    n = np.array([0.0, 0.0, 1.0])
    d = plane_ellipsoid(np.array([5.0, -2.0, 0.25]), n, np.array([0.1, 0.2, 0.5]), I3, s, point)
    assert d == pytest.approx(0.5 - 0.25 - 0.1, abs=2 * EPS)
    np.testing.assert_allclose(point, [0.1, 0.2, 0.4], rtol=0, atol=EPS)
    rng = np.random.default_rng(6)
    for _ in range(30):
        pc, Rc, s, pp = rng.normal(size=3), random_rotation(rng), rng.uniform(0.001, 0.5, 3), rng.normal(size=3)
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        d = plane_ellipsoid(pp, n, pc, Rc, s, point)
        assert d == pytest.approx(n @ (pc - pp) - np.sqrt(n @ Rc @ np.diag(s ** 2) @ Rc.T @ n), abs=8 * EPS)
        assert n @ (point - pp) == pytest.approx(d, abs=8 * EPS)
        gap, grad = distance(point, pc, Rc, s)
        assert abs(gap) <= 8 * EPS
        np.testing.assert_allclose(grad, -n, rtol=0, atol=1e-12)
        w = rng.normal(size=(5000, 3))
        surface = pc + (Rc @ (s[:, None] * (w / np.linalg.norm(w, axis=1, keepdims=True)).T)).T
        assert ((surface - pp) @ n).min() >= d - 1e-15


# ----- against the nearest point in 50 digits ----------------------------------------------------------------------

def reference(mp, x, pc, Rc, s):
    """(signed distance, normal (3,)) in mp.mpf: the point y = Rc^T (x - pc) in the ellipsoid's axes (the float
    inputs exact), every real root t of the sextic prod (t + e_i^2)^2 F(t) = 0 (mpmath.polyroots), polished by
    Newton on F, each giving a surface point x_i = e_i^2 y_i / (t + e_i^2) normal to the line from y; the nearest."""
    e = [mp.mpf(float(v)) for v in s]
    y = [sum(mp.mpf(float(Rc[k, i])) * (mp.mpf(float(x[k])) - mp.mpf(float(pc[k]))) for k in range(3))
         for i in range(3)]

    def times(a, b):
        out = [mp.mpf(0)] * (len(a) + len(b) - 1)
        for i, ai in enumerate(a):
            for j, bj in enumerate(b):
                out[i + j] += ai * bj
        return out

    square = [[ei ** 4, 2 * ei ** 2, mp.mpf(1)] for ei in e]  # (t + e_i^2)^2, ascending powers
    sextic = times(times(square[0], square[1]), square[2])
    for i in range(3):
        others = [square[j] for j in range(3) if j != i]
        term = times(*others)
        for k in range(5):
            sextic[k] -= (e[i] * y[i]) ** 2 * term[k]
    if "asc" in inspect.signature(mp.polyroots).parameters:  # mpmath >= 1.4 deprecates descending coefficients
        roots = mp.polyroots(sextic, maxsteps=400, extraprec=100, asc=True)
    else:
        roots = mp.polyroots(sextic[::-1], maxsteps=400, extraprec=100)

    def nearest(t):
        return [e[i] ** 2 * y[i] / (t + e[i] ** 2) for i in range(3)]

    def gap_of(t):
        return mp.sqrt(sum((x_i - y_i) ** 2 for x_i, y_i in zip(nearest(t), y)))

    real = [mp.re(root) for root in roots if abs(mp.im(root)) <= mp.mpf(10) ** -25 * max(e) ** 2]
    t = min(real, key=gap_of)
    try:  # polished by Newton on F in 50 digits
        t = mp.findroot(lambda t: sum((e[i] * y[i] / (t + e[i] ** 2)) ** 2 for i in range(3)) - 1, t)
    except (ValueError, ZeroDivisionError):  # a near-double root Newton cannot polish: polyroots' own
        pass
    near = nearest(t)
    gap = gap_of(t)
    if sum((y[i] / e[i]) ** 2 for i in range(3)) < 1:
        gap = -gap
    local = [near[i] / e[i] ** 2 for i in range(3)]
    length = mp.sqrt(sum(v * v for v in local))
    normal = [sum(mp.mpf(float(Rc[a, i])) * local[i] for i in range(3)) / length for a in range(3)]
    return gap, normal


def test_against_the_nearest_point_in_50_digits():
    """300 points of 5 kinds (outside, inside, within 1e-12 to 1e-2 of the surface on either side, near a plane of
    symmetry (one coordinate 1e-14 to 1e-4 of its semi-axis), near the centre) of ellipsoids with semi-axes spread
    over up to 1:100, turned and moved: the distance within 4 ulp of the scale max(s, |x - pc|, |pc|) (measured: 1.3
    ulp), the normal within 1e-12 (measured 3.7e-14; at the tip of a 1:100 ellipsoid its conditioning is the
    curvature, 1e4 / e0, times the inputs' round-off)."""
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 50
    rng = np.random.default_rng(17)
    worst_distance, worst_normal = 0.0, 0.0
    for k in range(300):
        kind = k % 5
        s = rng.permutation([1.0, 10 ** rng.uniform(-2, 0), 10 ** rng.uniform(-2, 0)]) * 10 ** rng.uniform(-1, 0.5)
        pc, Rc = rng.normal(size=3), random_rotation(rng)
        if kind == 0:
            y = rng.normal(size=3) * s.max() * 10 ** rng.uniform(0, 1.5)
        elif kind == 1:
            w = rng.normal(size=3)
            y = s * w / np.linalg.norm(w) * rng.uniform(0, 1)
        elif kind == 2:
            w = rng.normal(size=3)
            on = s * w / np.linalg.norm(w)
            normal = on / s ** 2
            y = on + normal / np.linalg.norm(normal) * s.max() * 10 ** rng.uniform(-12, -2) * rng.choice([-1, 1])
        elif kind == 3:
            y = rng.normal(size=3) * s * rng.uniform(0, 1.5)
            axis = rng.integers(3)
            y[axis] = s[axis] * 10 ** rng.uniform(-14, -4) * rng.choice([-1, 1])
        else:
            y = rng.normal(size=3) * s * 10 ** rng.uniform(-8, -1)
        x = pc + Rc @ y
        d, grad = distance(x, pc, Rc, s)
        d_ref, n_ref = reference(mp, x, pc, Rc, s)
        scale = max(s.max(), np.linalg.norm(x - pc), np.abs(pc).max())
        worst_distance = max(worst_distance, abs(d - float(d_ref)) / (EPS * scale))
        worst_normal = max(worst_normal, max(abs(grad[a] - float(n_ref[a])) for a in range(3)))
    assert worst_distance <= 4.0, worst_distance
    assert worst_normal <= 1e-12, worst_normal


# ----- against MuJoCo ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("size", [(0.3, 0.1, 0.05), (0.5, 0.05, 0.005)])
def test_against_mujoco_geom_distance(size):
    """An ellipsoid and a sphere of radius 1e-3 at 300 random separated poses: mj_geomDistance (MuJoCo's GJK, with
    ccd_tolerance 1e-12 and 1000 iterations) converges from above, so rbody's distance less the radius is never
    above it (beyond 1e-15) and within 1e-10 below it (measured: 5.7e-11 and 3.1e-11, the median 4e-16); the normal
    along MuJoCo's witness points to 1e-4 (measured 9e-6, the median 2e-8: MuJoCo's witnesses' tolerance)."""
    mujoco = pytest.importorskip("mujoco")
    radius = 1e-3
    xml = ('<mujoco><option ccd_tolerance="1e-12" ccd_iterations="1000"/><worldbody>'
           f'<body mocap="true"><geom type="ellipsoid" size="{" ".join(map(str, size))}"/></body>'
           f'<body mocap="true"><geom type="sphere" size="{radius}"/></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.opt.ccd_tolerance == 1e-12
    data = mujoco.MjData(model)
    rng = np.random.default_rng(2)
    fromto = np.zeros(6)
    below, checked = [], 0
    for _ in range(300):
        q = rng.normal(size=4)
        data.mocap_quat[0] = q / np.linalg.norm(q)
        data.mocap_pos[0] = rng.normal(size=3)
        offset = rng.normal(size=3)
        data.mocap_pos[1] = data.mocap_pos[0] + offset / np.linalg.norm(offset) * rng.uniform(0.2, 1.5) * size[0]
        mujoco.mj_forward(model, data)
        expected = mujoco.mj_geomDistance(model, data, 0, 1, 10.0, fromto)
        if expected <= 1e-6:
            continue
        d, grad = distance(data.geom_xpos[1], data.geom_xpos[0], data.geom_xmat[0].reshape(3, 3), model.geom_size[0])
        below.append(expected - (d - radius))
        direction = (fromto[3:] - fromto[:3]) / np.linalg.norm(fromto[3:] - fromto[:3])
        np.testing.assert_allclose(grad, direction, rtol=0, atol=1e-4)
        checked += 1
    assert checked >= 200
    assert min(below) >= -1e-15, min(below)
    assert max(below) <= 1e-10, max(below)
    assert np.median(below) <= 1e-14


# ----- a segment's closest point -----------------------------------------------------------------------------------

def test_segment_closest_against_sampling_and_refinement():
    """Random segments about elongated ellipsoids: the distance at t is no greater than the least of 2001 samples
    refined by Brent's method between the best sample's neighbours (to 1e-15), t inside [lo, hi] within the segment,
    outside the ellipsoid the slope at t within 1e-9 of 0 unless t is an end (where the distance falls towards it)."""
    rng = np.random.default_rng(8)
    grad = np.empty(3)
    worst, ends = 0.0, 0
    for _ in range(60):
        pc, Rc = rng.normal(size=3), random_rotation(rng)
        s = rng.permutation([0.3, 0.3 * 10 ** rng.uniform(-2, 0), 0.3 * 10 ** rng.uniform(-2, 0)])
        p, u = pc + rng.normal(size=3) * 0.3, rng.normal(size=3)
        u /= np.linalg.norm(u)
        half = rng.uniform(0.05, 0.8)
        t, lo, hi = segment_ellipsoid_closest(p, u, half, pc, Rc, s)
        assert -half <= lo <= t <= hi <= half

        def gap(tt):
            return ellipsoid_distance(p + tt * u, pc, Rc, s, grad)

        samples = np.linspace(-half, half, 2001)
        values = np.array([gap(tt) for tt in samples])
        j = int(np.argmin(values))
        refined = minimize_scalar(gap, bounds=(samples[max(j - 1, 0)], samples[min(j + 1, 2000)]), method="bounded",
                                  options={"xatol": 1e-15})
        best = min(values[j], refined.fun)
        worst = max(worst, gap(t) - best)
        outside = gap(t) > 0.0  # inside, the distance has kinks (points of several nearest points) where slopes jump
        slope = grad @ u
        if abs(t) < half and outside:
            assert abs(slope) <= 1e-9  # within 1e-12 at lo and hi; at their middle, curvature times (hi - lo) / 2
        else:
            ends += 1
            assert slope * np.sign(t) <= 0.0  # the distance still falls towards the end
    assert worst <= 1e-15, worst
    assert ends > 0


def test_segment_closed_forms():
    """Over the flat face of (1, 0.6, 0.01) at height 0.1, parallel to its long axis: the top's middle, t = -0.3 for
    the segment centred at x = 0.3; crossing the ellipsoid through its centre along z: the centre (distance -0.01);
    falling short of it: the near end."""
    s = np.array([1.0, 0.6, 0.01])
    u = np.array([1.0, 0.0, 0.0])
    t, lo, hi = segment_ellipsoid_closest(np.array([0.3, 0.0, 0.11]), u, 0.5, ORIGIN, I3, s)
    assert t == pytest.approx(-0.3, abs=1e-9) and lo <= t <= hi and hi - lo <= 1e-9
    up = np.array([0.0, 0.0, 1.0])
    t, lo, hi = segment_ellipsoid_closest(np.array([0.0, 0.0, 0.1]), up, 0.5, ORIGIN, I3, s)
    assert t == pytest.approx(-0.1, abs=1e-9)
    t, lo, hi = segment_ellipsoid_closest(np.array([0.0, 0.0, 0.6]), up, 0.5, ORIGIN, I3, s)
    assert (t, lo, hi) == (-0.5, -0.5, -0.5)


# ----- invariants (hypothesis) -------------------------------------------------------------------------------------

semi_axis = st.floats(0.01, 1.0)
coordinate = st.floats(-2.0, 2.0)
quaternion = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: sum(v * v for v in q) > 0.01)


@settings(max_examples=150, deadline=None)
@given(st.tuples(semi_axis, semi_axis, semi_axis), st.tuples(coordinate, coordinate, coordinate), quaternion,
       quaternion, st.tuples(coordinate, coordinate, coordinate))
def test_rigid_motion_leaves_the_distance(s, x, q, q_motion, shift):
    """Turning and moving ellipsoid and point together: the same distance, to 16 ulp of the scale
    |x| + |pc| + |shift| (the moved points' rounding; 6.4 ulp the worst of 40000 random cases, spheres and points at
    the origin among them), and the normal turned with them, to 1e-12 (1.2e-14 the worst; semi-axes up to 1:100)."""
    s, x, shift = np.array(s), np.array(x), np.array(shift)
    Rc = quat_to_matrix(np.array(q) / np.linalg.norm(q))
    Q = quat_to_matrix(np.array(q_motion) / np.linalg.norm(q_motion))
    pc = np.array([0.3, -0.2, 0.1])
    d, grad = distance(x, pc, Rc, s)
    d_moved, grad_moved = distance(Q @ x + shift, Q @ pc + shift, Q @ Rc, s)
    scale = max(s.max(), np.linalg.norm(x) + np.linalg.norm(pc) + np.linalg.norm(shift))  # the moved points' rounding
    assert abs(d_moved - d) <= 16 * EPS * scale
    np.testing.assert_allclose(grad_moved, Q @ grad, rtol=0, atol=1e-12)


@settings(max_examples=150, deadline=None)
@given(st.tuples(semi_axis, semi_axis, semi_axis), st.tuples(coordinate, coordinate, coordinate), quaternion,
       st.floats(0.0, 3.0))
def test_moving_along_the_normal_adds_its_length(s, x, q, step):
    """Outside, the nearest point of x + step grad is that of x: the distance grows by step exactly, to 8 ulp of
    the scale (5.2 ulp the worst of 20000 random cases), the normal unchanged to 1e-12 (6e-16 the worst)."""
    s, x = np.array(s), np.array(x)
    Rc = quat_to_matrix(np.array(q) / np.linalg.norm(q))
    d, grad = distance(x, ORIGIN, Rc, s)
    if d <= 0.0:
        return
    d_moved, grad_moved = distance(x + step * grad, ORIGIN, Rc, s)
    assert abs(d_moved - (d + step)) <= 8 * EPS * max(s.max(), np.abs(x).max() + step)
    np.testing.assert_allclose(grad_moved, grad, rtol=0, atol=1e-12)
