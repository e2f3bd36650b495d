"""Inertia: the chapter's moments of inertia, products of inertia by hand, invariants, bad input.

"The chapter" is the textbook chapter on systems of particles and rigid bodies (section 5.4).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rbody import Inertia
from rbody.inertia import unit_axis
from rbody.motion import quat_normalize, quat_to_matrix

RTOL = 1e-13  # closed forms evaluated in float64: a few ulps

M, A, L = 2.5, 0.3, 1.7  # mass [kg], radius [m], length [m] used for the chapter's values


# ----- the chapter's values --------------------------------------------------------------------------

def test_hoop_about_its_axis_is_M_a2():
    """The chapter: a hoop about the axis through its centre, normal to its plane, I = M a^2."""
    hoop = Inertia.hoop(M, A, "z")
    assert hoop.moment("z") == pytest.approx(M * A**2, rel=RTOL)
    assert hoop.moment("x") == pytest.approx(M * A**2 / 2, rel=RTOL)  # perpendicular axis theorem


def test_rod_about_its_end_is_M_L2_over_3():
    """The chapter's (5.13): a rod about an axis normal to it through its end, I = M l^2 / 3."""
    rod = Inertia.rod(M, L, "z")
    for axis in ("x", "y", (1.0, 1.0, 0.0)):
        assert rod.moment(axis, through=(0.0, 0.0, L / 2)) == pytest.approx(M * L**2 / 3, rel=RTOL)
        assert rod.moment(axis, through=(0.0, 0.0, -L / 2)) == pytest.approx(M * L**2 / 3, rel=RTOL)
    assert rod.moment("z") == 0.0


def test_disc_normal_and_in_plane():
    """The chapter: a disc, M a^2 / 2 about its axis and M a^2 / 4 about a diameter."""
    disc = Inertia.disc(M, A, "z")
    assert disc.moment("z") == pytest.approx(M * A**2 / 2, rel=RTOL)
    for axis in ("x", "y", (1.0, -2.0, 0.0)):
        assert disc.moment(axis) == pytest.approx(M * A**2 / 4, rel=RTOL)


def test_disc_about_rim_point_by_parallel_axis():
    """The chapter ("The Disc Again"): normal to the plane through a rim point, I = 3/2 M a^2."""
    disc = Inertia.disc(M, A, "z")
    for angle in np.linspace(0.0, 2 * np.pi, 7):
        rim = (A * np.cos(angle), A * np.sin(angle), 0.0)
        assert disc.moment("z", through=rim) == pytest.approx(1.5 * M * A**2, rel=RTOL)


@pytest.mark.parametrize("rings", [50, 200, 800])
def test_disc_about_rim_point_by_direct_integration(rings):
    """The chapter's integral I = int rho (r^2 + a^2 - 2 a r cos(theta)) r dr dtheta = 3/2 M a^2, as a
    polar grid of point masses m_ij = rho r_i dr dtheta at ring midpoints r_i = (i + 1/2) dr.

    Tolerance, derived: the theta sum is exact (equally spaced nodes integrate 1 and cos(theta)
    exactly), the r sum is the midpoint rule, exact for int r dr (so the mass is exact) and short of
    int r^3 dr = a^4/4 by a^2 dr^2 / 8. Hence the grid's I is 3/2 M a^2 - M a^2 / (4 N^2) exactly,
    a relative deficit 1 / (6 N^2); we check that deficit to round-off, which shows convergence."""
    sectors = 64
    dr, dtheta = A / rings, 2 * np.pi / sectors
    r = (np.arange(rings) + 0.5) * dr
    theta = (np.arange(sectors) + 0.5) * dtheta
    rr, tt = np.meshgrid(r, theta, indexing="ij")
    rho = M / (np.pi * A**2)
    masses = (rho * rr * dr * dtheta).ravel()
    positions = np.stack([rr * np.cos(tt), rr * np.sin(tt), np.zeros_like(rr)], axis=-1).reshape(-1, 3)
    assert masses.sum() == pytest.approx(M, rel=1e-12)
    grid = Inertia.point_masses(masses, positions)
    rim = (A, 0.0, 0.0)
    # the chapter's way: sum m d^2 with d^2 = r^2 + a^2 - 2 a r cos(theta)
    direct = float(np.sum(masses * (rr**2 + A**2 - 2 * A * rr * np.cos(tt)).ravel()))
    expected = 1.5 * M * A**2 - M * A**2 / (4 * rings**2)
    assert direct == pytest.approx(expected, rel=1e-12)
    assert grid.moment("z", through=rim) == pytest.approx(expected, rel=1e-12)
    assert abs(grid.moment("z", through=rim) / (1.5 * M * A**2) - 1) <= 1 / (6 * rings**2) * (1 + 1e-6)


def test_sphere_and_spherical_shell():
    """The chapter: a uniform sphere, I = 2/5 M a^2; a thin spherical shell, 2/3 M a^2."""
    for axis in ("x", "y", "z", (1.0, 2.0, 3.0)):
        assert Inertia.solid_sphere(M, A).moment(axis) == pytest.approx(0.4 * M * A**2, rel=RTOL)
        assert Inertia.spherical_shell(M, A).moment(axis) == pytest.approx(2 / 3 * M * A**2, rel=RTOL)


def test_spherical_shell_from_point_masses_on_a_fibonacci_sphere():
    """2/3 M a^2 from first principles: the mean of |x|^2 - x_z^2 over a sphere is 2/3 a^2.
    N points on a Fibonacci lattice have z_k = 1 - (2k + 1)/N exactly equispaced, so sum z_k^2 / N =
    1/3 - 1/(3 N^2) exactly and I_zz = 2/3 M a^2 (1 + 1/(2 N^2))."""
    n = 2000
    k = np.arange(n)
    z = 1 - (2 * k + 1) / n
    phi = k * np.pi * (3 - np.sqrt(5))
    rho = np.sqrt(1 - z**2)
    pts = A * np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)
    shell = Inertia.point_masses(np.full(n, M / n), pts)
    assert shell.moment("z", through=(0, 0, 0)) == pytest.approx(2 / 3 * M * A**2 * (1 + 1 / (2 * n**2)), rel=1e-12)


def test_cylinder_tube_and_box_closed_forms():
    """Standard closed forms, checked as the chapter builds them: perpendicular and parallel axes."""
    c = Inertia.solid_cylinder(M, A, L, "z")
    assert np.allclose(np.diag(c.tensor), [M * (3 * A**2 + L**2) / 12] * 2 + [M * A**2 / 2], rtol=RTOL)
    t = Inertia.hollow_cylinder(M, A / 2, A, L, "z")
    s = (A / 2) ** 2 + A**2
    assert np.allclose(np.diag(t.tensor), [M * (3 * s + L**2) / 12] * 2 + [M * s / 2], rtol=RTOL)
    thin = Inertia.hollow_cylinder(M, A, A, L, "z")
    assert thin.moment("z") == pytest.approx(M * A**2, rel=RTOL)  # every point at distance a, like the hoop
    assert Inertia.hollow_cylinder(M, 0.0, A, L).tensor == pytest.approx(c.tensor, rel=RTOL)
    b = Inertia.box(M, (1.0, 2.0, 3.0))
    assert np.array_equal(b.tensor, M / 12 * np.diag([13.0, 10.0, 5.0]))


def test_perpendicular_axis_theorem_for_laminae():
    """The chapter: for a lamina in the x-y plane, I_z = I_x + I_y."""
    for lamina in (Inertia.disc(M, A, "z"), Inertia.hoop(M, A, "z"), Inertia.box(M, (0.4, 1.1, 0.0))):
        assert lamina.moment("z") == pytest.approx(lamina.moment("x") + lamina.moment("y"), rel=RTOL)
    plate = Inertia.box(M, (0.4, 1.1, 0.0))
    assert np.allclose(np.diag(plate.tensor), M / 12 * np.array([1.1**2, 0.4**2, 0.4**2 + 1.1**2]), rtol=RTOL)
    # and for any lamina: a random planar set of point masses
    rng = np.random.default_rng(5)
    xy = np.c_[rng.normal(size=(20, 2)), np.zeros(20)]
    lamina = Inertia.point_masses(rng.uniform(0.1, 2.0, 20), xy)
    assert lamina.moment("z") == pytest.approx(lamina.moment("x") + lamina.moment("y"), rel=RTOL)


def test_parallel_axis_theorem_as_in_the_chapter():
    """The chapter (5.4.3): I = I_CoM + M h^2, h the distance between the parallel axes."""
    body = Inertia.box(M, (0.3, 0.5, 0.9)).rotated(quat_normalize([0.9, 0.1, -0.3, 0.2])).translated([1, 2, 3])
    n = unit_axis((1.0, -1.0, 2.0))
    point = np.array([-0.5, 0.7, 0.1])
    d = body.com - point
    h2 = float(d @ d - (d @ n) ** 2)
    assert body.moment(n, through=point) == pytest.approx(body.moment(n) + M * h2, rel=RTOL)
    assert body.moment(n, through=point) > body.moment(n)  # the chapter's corollary


def test_moment_is_nT_I_n():
    """The chapter: the moment of inertia about the axis n is n^T I n."""
    body = Inertia.point_masses([1.0, 2.0, 3.0], [[1, 0, 0], [0, 2, 1], [1, 1, -1]])
    n = np.array([2.0, -1.0, 2.0]) / 3
    body_points = np.array([[1, 0, 0], [0, 2, 1], [1, 1, -1]], float) - body.com
    direct = sum(m * np.sum(np.cross(n, yi) ** 2) for m, yi in zip([1.0, 2.0, 3.0], body_points))
    assert body.moment(n) == pytest.approx(n @ body.tensor @ n, rel=RTOL)
    assert body.moment(n) == pytest.approx(direct, rel=RTOL)


def test_angular_momentum_and_kinetic_energy_of_rotation():
    """The chapter (5.4.4): L = I w and T = 1/2 w^T I w, from sum m y x (w x y) and 1/2 sum m |w x y|^2."""
    masses = np.array([1.0, 2.0, 0.5, 3.0])
    pts = np.array([[1.0, 0.2, 0.0], [-0.3, 1.0, 0.5], [0.0, -1.0, 2.0], [0.4, 0.4, -0.7]])
    body = Inertia.point_masses(masses, pts)
    y = pts - body.com
    omega = np.array([0.3, -1.2, 2.0])
    v = np.cross(omega, y)
    L_direct = np.sum(masses[:, None] * np.cross(y, v), axis=0)
    T_direct = 0.5 * np.sum(masses * np.sum(v * v, axis=1))
    assert np.allclose(body.angular_momentum(omega), L_direct, rtol=RTOL, atol=1e-14)
    assert np.allclose(body.tensor @ omega, L_direct, rtol=RTOL, atol=1e-14)
    assert body.kinetic_energy(omega) == pytest.approx(T_direct, rel=RTOL)
    # batches of angular velocities
    omegas = np.array([omega, 2 * omega, -omega])
    assert np.allclose(body.kinetic_energy(omegas), [T_direct, 4 * T_direct, T_direct], rtol=RTOL)
    assert np.allclose(body.angular_momentum(omegas), [L_direct, 2 * L_direct, -L_direct], rtol=RTOL)
    # L is not along w unless w is a principal axis (the chapter's remark)
    assert np.linalg.norm(np.cross(body.angular_momentum(omega), omega)) > 0.1
    moments, axes = body.principal()
    assert np.allclose(body.angular_momentum(axes[:, 0]), moments[0] * axes[:, 0], atol=1e-12)


# ----- products of inertia, by hand --------------------------------------------------------------------

def test_products_of_inertia_of_point_masses_by_hand():
    """I_ab = sum m (|x|^2 d_ab - x_a x_b): I_xy = -sum m x y, etc. Centre of mass at the origin."""
    body = Inertia.point_masses([1.0, 1.0, 2.0, 2.0], [[1, 1, 0], [-1, -1, 0], [0, 1, 1], [0, -1, -1]])
    # I_xx = 1*(1)+1*(1) + 2*(1+1)*2 = 10; I_yy = 1+1 + 2*(0+1)*2 = 6; I_zz = 2+2 + 2*1*2 = 8
    # I_xy = -(1*1*1 + 1*(-1)(-1)) = -2; I_yz = -(2*1*1 + 2*(-1)(-1)) = -4; I_xz = 0
    expected = np.array([[10.0, -2.0, 0.0], [-2.0, 6.0, -4.0], [0.0, -4.0, 8.0]])
    assert np.array_equal(body.com, np.zeros(3))
    assert np.allclose(body.tensor, expected, rtol=0, atol=1e-14)


def test_single_particle_about_the_origin_by_hand():
    """m = 1 at (1, 2, 3): about the origin [[13, -2, -3], [-2, 10, -6], [-3, -6, 5]]."""
    p = Inertia.point_masses([1.0], [[1.0, 2.0, 3.0]])
    assert np.array_equal(p.tensor, np.zeros((3, 3)))
    assert np.allclose(p.about([0, 0, 0]), [[13, -2, -3], [-2, 10, -6], [-3, -6, 5]], rtol=0, atol=1e-14)


def test_rotated_box_products_by_hand():
    """Box diag(A, B, C) turned 30 degrees about z, q = (cos 15, 0, 0, sin 15):
    R I R^T = [[3A/4 + B/4, sqrt3/4 (A - B), 0], [sqrt3/4 (A - B), A/4 + 3B/4, 0], [0, 0, C]].
    Long along x (A < B) and turned towards +y, the mass sits where x y > 0, so I_xy < 0."""
    box = Inertia.box(6.0, (3.0, 1.0, 2.0))           # A = 6 (1 + 4)/12 = 2.5, B = 6 (9 + 4)/12 = 6.5, C = 5
    Ax, By, Cz = 2.5, 6.5, 5.0
    assert np.allclose(np.diag(box.tensor), [Ax, By, Cz], rtol=RTOL)
    q = np.array([math.cos(math.radians(15)), 0.0, 0.0, math.sin(math.radians(15))])
    s3 = math.sqrt(3.0)
    expected = np.array([[0.75 * Ax + 0.25 * By, s3 / 4 * (Ax - By), 0.0],
                         [s3 / 4 * (Ax - By), 0.25 * Ax + 0.75 * By, 0.0],
                         [0.0, 0.0, Cz]])
    turned = box.rotated(q)
    assert np.allclose(turned.tensor, expected, rtol=0, atol=1e-13)
    assert turned.tensor[0, 1] < 0
    # 120 degrees about (1, 1, 1): x -> y -> z -> x, so diag(A, B, C) -> diag(C, A, B)
    q120 = np.array([0.5, 0.5, 0.5, 0.5])
    assert np.allclose(box.rotated(q120).tensor, np.diag([Cz, Ax, By]), rtol=0, atol=1e-13)
    # the same by a rotation matrix
    R = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    assert np.allclose(box.rotated(R).tensor, np.diag([Cz, Ax, By]), rtol=0, atol=1e-13)


def test_rotated_moves_the_centre_of_mass_and_translated_keeps_the_tensor():
    body = Inertia.rod(1.0, 2.0, "x").translated([1.0, 0.0, 0.0])
    turned = body.rotated(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))  # +90 about z
    assert np.allclose(turned.com, [0.0, 1.0, 0.0], atol=1e-15)
    assert np.allclose(turned.tensor, Inertia.rod(1.0, 2.0, "y").tensor, atol=1e-15)
    assert np.array_equal(body.tensor, Inertia.rod(1.0, 2.0, "x").tensor)


# ----- invariants (hypothesis) -------------------------------------------------------------------------

positive_size = st.floats(1e-2, 1e2)
masses_st = st.floats(1e-2, 1e2)
coord = st.floats(-10.0, 10.0)
vec3 = st.tuples(coord, coord, coord)
quat_st = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: sum(x * x for x in q) > 0.01)


@st.composite
def point_sets(draw, min_size=1, max_size=6):
    n = draw(st.integers(min_size, max_size))
    masses = draw(st.lists(masses_st, min_size=n, max_size=n))
    positions = draw(st.lists(vec3, min_size=n, max_size=n))
    return np.array(masses), np.array(positions, dtype=float)


@st.composite
def bodies(draw):
    """Any valid body: a primitive, turned and moved, or a set of particles."""
    kind = draw(st.sampled_from(["points", "box", "cylinder", "tube", "rod", "disc", "hoop", "sphere", "shell"]))
    m = draw(masses_st)
    if kind == "points":
        masses, positions = draw(point_sets())
        return Inertia.point_masses(masses, positions)
    a, b, c = draw(positive_size), draw(positive_size), draw(positive_size)
    axis = draw(st.sampled_from(["x", "y", "z", (1.0, 2.0, -0.5)]))
    body = {
        "box": lambda: Inertia.box(m, (a, b, c)),
        "cylinder": lambda: Inertia.solid_cylinder(m, a, b, axis),
        "tube": lambda: Inertia.hollow_cylinder(m, min(a, b), max(a, b), c, axis),
        "rod": lambda: Inertia.rod(m, a, axis),
        "disc": lambda: Inertia.disc(m, a, axis),
        "hoop": lambda: Inertia.hoop(m, a, axis),
        "sphere": lambda: Inertia.solid_sphere(m, a),
        "shell": lambda: Inertia.spherical_shell(m, a),
    }[kind]()
    return body.rotated(quat_normalize(draw(quat_st))).translated(draw(vec3))


def scale_of(tensor, mass=1.0):
    """Largest |entry| [kg m^2], floored at M (1e-12 m)^2 so that tolerances on bodies drawn at
    sub-picometre size (a particle at 1e-134 m) stay meaningful."""
    return max(float(np.max(np.abs(tensor))), mass * 1e-24)


def origin_scale(body, point=None):
    """Scale of the round-off of tensors formed from sums about the origin (or about `point`): the
    centre of mass itself carries a rounding of eps |com|, so a tensor about a point near it is
    known only to eps M |com|^2."""
    scale = scale_of(body.about(np.zeros(3)), body.mass)
    return scale if point is None else max(scale, scale_of(body.about(np.asarray(point, float)), body.mass))


@settings(max_examples=80, deadline=None)
@given(bodies(), vec3)
def test_parallel_axis_round_trip(body, point):
    """about(p) adds M (|d|^2 1 - d d^T), d = com - p; taking it off again gives the tensor back,
    and the shifted body seen from the shifted point is unchanged."""
    point = np.array(point)
    shifted = body.about(point)
    d = body.com - point
    back = shifted - body.mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    assert np.allclose(back, body.tensor, rtol=0, atol=1e-12 * origin_scale(body, point))
    offset = np.array([0.7, -1.1, 2.3])
    again = body.translated(offset).about(point + offset)
    assert np.allclose(again, shifted, rtol=0, atol=1e-12 * origin_scale(body, point))
    # the centre of mass gives the least moment about every direction (the chapter's corollary)
    for n in np.eye(3):
        assert body.moment(n, through=point) >= body.moment(n) - 1e-12 * origin_scale(body, point)


@settings(max_examples=60, deadline=None)
@given(point_sets(), vec3)
def test_about_matches_the_particle_sum(points, point):
    """For particles, about(p) is sum m (|x - p|^2 1 - (x - p)(x - p)^T) directly."""
    masses, positions = points
    body = Inertia.point_masses(masses, positions)
    y = positions - np.array(point)
    direct = np.eye(3) * np.sum(masses * np.sum(y * y, axis=1)) - (masses[:, None] * y).T @ y
    assert np.allclose(body.about(point), direct, rtol=0, atol=1e-12 * origin_scale(body, point))


@settings(max_examples=80, deadline=None)
@given(bodies(), quat_st)
def test_eigenvalues_invariant_under_rotation(body, q):
    R = quat_to_matrix(quat_normalize(q))
    before = np.linalg.eigvalsh(body.tensor)
    after = np.linalg.eigvalsh(body.rotated(R).tensor)
    assert np.allclose(after, before, rtol=0, atol=1e-12 * scale_of(body.tensor, body.mass))
    assert np.allclose(body.rotated(R).tensor, R @ body.tensor @ R.T, rtol=0, atol=1e-13 * scale_of(body.tensor, body.mass))


@settings(max_examples=80, deadline=None)
@given(point_sets(), point_sets())
def test_sum_of_point_bodies_is_the_union(first, second):
    (m1, x1), (m2, x2) = first, second
    joined = Inertia.point_masses(m1, x1) + Inertia.point_masses(m2, x2)
    union = Inertia.point_masses(np.r_[m1, m2], np.r_[x1, x2])
    assert joined.mass == pytest.approx(union.mass, rel=1e-14)
    assert np.allclose(joined.com, union.com, rtol=0, atol=1e-12 * (1 + np.max(np.abs(union.com))))
    # the tensor about the centre of mass is a difference of sums about the origin
    assert np.allclose(joined.tensor, union.tensor, rtol=0, atol=1e-12 * origin_scale(union))


@settings(max_examples=100, deadline=None)
@given(bodies())
def test_triangle_inequality_for_every_constructor(body):
    """Principal moments A <= B <= C of any physical body obey A + B >= C (equality for laminae)."""
    a, b, c = np.linalg.eigvalsh(body.tensor)
    assert a >= -1e-12 * scale_of(body.tensor, body.mass)
    assert a + b >= c - 1e-12 * scale_of(body.tensor, body.mass)


@settings(max_examples=100, deadline=None)
@given(bodies())
def test_principal_axes_are_a_proper_rotation_that_diagonalises(body):
    moments, axes = body.principal()
    assert np.all(np.diff(moments) >= 0)
    assert np.allclose(axes.T @ axes, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-12)
    assert np.allclose(axes.T @ body.tensor @ axes, np.diag(moments), rtol=0, atol=1e-12 * scale_of(body.tensor, body.mass))
    # turning the body into its principal frame leaves a diagonal tensor
    diagonal = body.rotated(axes.T).tensor
    assert np.allclose(diagonal, np.diag(moments), rtol=0, atol=1e-12 * scale_of(body.tensor, body.mass))


# ----- value semantics -------------------------------------------------------------------------------

def test_arrays_are_read_only_and_equality_is_by_value():
    body = Inertia.box(1.0, (1, 2, 3))
    with pytest.raises(ValueError):
        body.tensor[0, 0] = 5.0
    with pytest.raises(ValueError):
        body.com[0] = 5.0
    assert body == Inertia.box(1.0, (1, 2, 3))
    assert body != Inertia.box(1.0, (1, 2, 4))


# ----- bad input ----------------------------------------------------------------------------------------

NAN = float("nan")
BAD = [
    (lambda: Inertia.hoop(-1.0, 1.0), r"mass=-1\.0: must be > 0"),
    (lambda: Inertia.disc(0.0, 1.0), r"mass=0\.0: must be > 0"),
    (lambda: Inertia.solid_sphere(NAN, 1.0), r"mass=nan: every value must be finite"),
    (lambda: Inertia.rod(1.0, float("inf")), r"length=inf: every value must be finite"),
    (lambda: Inertia.solid_cylinder(1.0, 1.0, NAN), r"length=nan: every value must be finite"),
    (lambda: Inertia(np.array([1.0, 2.0]), np.zeros(3), np.eye(3)), r"mass has shape \(2,\)"),
    (lambda: Inertia.spherical_shell(1.0, -0.5), r"radius=-0\.5: must be > 0"),
    (lambda: Inertia.hoop(1.0, 0.0), r"radius=0\.0: must be > 0"),
    (lambda: Inertia.solid_cylinder(1.0, NAN, 1.0), r"radius=nan: every value must be finite"),
    (lambda: Inertia.rod(1.0, -2.0), r"length=-2\.0: must be > 0"),
    (lambda: Inertia.solid_cylinder(1.0, 1.0, 0.0), r"length=0\.0: must be > 0"),
    (lambda: Inertia.hollow_cylinder(1.0, 2.0, 1.0, 1.0), r"inner_radius=2\.0 > outer_radius=1\.0"),
    (lambda: Inertia.hollow_cylinder(1.0, -0.1, 1.0, 1.0), r"inner_radius=-0\.1: must be >= 0"),
    (lambda: Inertia.box(1.0, (1.0, -1.0, 1.0)), r"size=\[1\.0, -1\.0, 1\.0\]: side lengths must be >= 0"),
    (lambda: Inertia.box(1.0, (1.0, 0.0, 0.0)), r"at most one zero"),
    (lambda: Inertia.box(1.0, (1.0, 1.0)), r"size has shape \(2,\): expected \(3,\)"),
    (lambda: Inertia(1.0, np.zeros(3), [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), r"must be symmetric"),
    (lambda: Inertia(1.0, np.zeros(3), np.diag([-1.0, 1.0, 1.0])), r"positive semi-definite"),
    (lambda: Inertia(1.0, np.zeros(3), np.diag([1.0, 1.0, 3.0])), r"triangle inequality A \+ B >= C"),
    (lambda: Inertia(1.0, np.zeros(2), np.eye(3)), r"com has shape \(2,\): expected \(3,\)"),
    (lambda: Inertia(1.0, np.zeros(3), np.eye(2)), r"tensor has shape \(2, 2\): expected \(3, 3\)"),
    (lambda: Inertia(1.0, [0.0, NAN, 0.0], np.eye(3)), r"com=\[0\.0, nan, 0\.0\]: every value must be finite"),
    (lambda: Inertia(1.0, np.zeros(3), "eye"), r"tensor='eye': expected real numbers"),
    (lambda: Inertia.disc(1.0, 1.0, "w"), r"axis='w': expected 'x', 'y', 'z' or a 3-vector"),
    (lambda: Inertia.disc(1.0, 1.0, "X"), r"axis='X'"),
    (lambda: Inertia.hoop(1.0, 1.0, (0.0, 0.0, 0.0)), r"axis=\[0\.0, 0\.0, 0\.0\]: a direction must be non-zero"),
    (lambda: Inertia.hoop(1.0, 1.0, (1.0, 0.0)), r"axis has shape \(2,\): expected \(3,\)"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).moment("q"), r"axis='q'"),
    (lambda: Inertia.point_masses([], []), r"at least one particle"),
    (lambda: Inertia.point_masses([1.0, -1.0], [[0, 0, 0], [1, 0, 0]]), r"every particle mass must be > 0"),
    (lambda: Inertia.point_masses([1.0, 1.0], [[0, 0, 0]]), r"positions has shape \(1, 3\): expected \(2, 3\)"),
    (lambda: Inertia.point_masses(1.0, [[0, 0, 0]]), r"masses has 0 dimensions: expected 1"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).about((1.0, 2.0)), r"point has shape \(2,\)"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).rotated(np.diag([1.0, 1.0, -1.0])), r"expected a proper rotation"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).rotated(2 * np.eye(3)), r"expected a proper rotation"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).rotated(np.eye(2)), r"R has shape \(2, 2\)"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).rotated(np.zeros(4)), r"are zero .*non-zero quaternion"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).translated([NAN, 0, 0]), r"offset=\[nan, 0\.0, 0\.0\]"),
    (lambda: Inertia.box(1.0, (1, 1, 1)).kinetic_energy([1.0, NAN, 0.0]), r"omega=.*finite"),
    (lambda: Inertia.from_mesh("unused.stl", density=1.0, mass=1.0), r"give exactly one of density"),
    (lambda: Inertia.from_mesh("unused.stl"), r"give exactly one of density"),
]


@pytest.mark.parametrize("call, message", BAD, ids=[m for _, m in BAD])
def test_bad_input_raises_value_error_naming_the_problem(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_sum_with_something_else_is_a_type_error():
    with pytest.raises(TypeError):
        Inertia.box(1.0, (1, 1, 1)) + 1.0


def test_two_coincident_points_far_below_a_metre_join():
    """Two 3 kg points at y = 1.3e-139 m: com's round-off leaves the shifted tensor subnormal; the union is a point
    of 6 kg there (hypothesis found it), not a refusal."""
    x = np.array([[0.0, 1.32404823e-139, 0.0]])
    joined = Inertia.point_masses([3.0], x) + Inertia.point_masses([3.0], x)
    assert joined.mass == 6.0
    assert np.allclose(joined.com, x[0], rtol=1e-15, atol=0)
    assert np.all(joined.tensor == 0.0)


def test_particles_closer_than_float64s_normal_moments_are_a_point_mass():
    """Two unit masses 1e-157 m apart (found by hypothesis): their moments, 5e-315 kg m^2, are subnormal. The set is
    a point mass to float64, as the sum of the two point bodies is, not a body refused for its units."""
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 9.96413417e-158]])
    union = Inertia.point_masses([1.0, 1.0], x)
    joined = Inertia.point_masses([1.0], x[:1]) + Inertia.point_masses([1.0], x[1:])
    assert union.mass == joined.mass == 2.0
    assert np.array_equal(union.tensor, np.zeros((3, 3))) and np.array_equal(joined.tensor, union.tensor)
    wide = Inertia.point_masses([1.0, 1.0], [[0.0, 0.0, 0.0], [0.0, 0.0, 1e-140]])  # normal moments: kept
    assert wide.tensor[0, 0] == pytest.approx(0.5e-280, rel=1e-12)
