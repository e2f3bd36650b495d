"""Inertia.from_mesh: exact polyhedra, measured discretisation error, precision far from the origin,
thin shells, and the mesh checks.

Discretisation errors measured (unit mass; see each test): a 64-section cylinder's moment about its
axis is 1.605e-3 below M a^2 / 2 (the regular-polygon prism formula predicts (2/3) sin^2(pi/n));
an icosphere's moments are 1.44e-3 (4 subdivisions) below the sphere's, falling 4x per subdivision.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from rbody import Inertia
from rbody.motion import quat_to_matrix


def polygon_factor(n: int) -> float:
    """J / (M R^2) of a regular n-gon lamina with circumradius R about its centre: (1 + 2 cos^2(pi/n)) / 6.
    (Square: 1/3 = side^2/6 with side^2 = 2 R^2; triangle: 1/4; n -> infinity: the disc's 1/2.)"""
    return (1 + 2 * math.cos(math.pi / n) ** 2) / 6


def rel(a, b):
    return abs(a - b) / abs(b)


# ----- exact polyhedra ----------------------------------------------------------------------------------

def test_box_mesh_equals_box_primitive():
    mesh = trimesh.creation.box(extents=(0.3, 1.1, 2.7))
    for kwargs, mass in (({"mass": 4.2}, 4.2), ({"density": 7800.0}, 7800.0 * 0.3 * 1.1 * 2.7)):
        body = Inertia.from_mesh(mesh, **kwargs)
        exact = Inertia.box(mass, (0.3, 1.1, 2.7))
        assert body.mass == pytest.approx(mass, rel=1e-12)
        assert np.allclose(body.com, 0.0, atol=1e-15)
        assert np.allclose(body.tensor, exact.tensor, rtol=0, atol=1e-12 * np.max(exact.tensor))


def test_rotated_box_mesh_products_of_inertia_by_hand():
    """Sign convention I_ab = sum m (|x|^2 d_ab - x_a x_b) (a past trimesh release had the products
    of inertia with the wrong sign): a box long along x, turned 30 degrees about z towards +y, has
    its mass where x y > 0, so I_xy = sqrt3/4 (A - B) < 0, written out by hand."""
    mesh = trimesh.creation.box(extents=(3.0, 1.0, 2.0))
    q = np.array([math.cos(math.radians(15)), 0.0, 0.0, math.sin(math.radians(15))])
    transform = np.eye(4)
    transform[:3, :3] = quat_to_matrix(q)
    transform[:3, 3] = (2.0, -1.0, 0.5)
    mesh.apply_transform(transform)
    body = Inertia.from_mesh(mesh, mass=6.0)
    Ax, By, Cz = 2.5, 6.5, 5.0                    # 6 (1 + 4)/12, 6 (9 + 4)/12, 6 (9 + 1)/12
    s3 = math.sqrt(3.0)
    expected = np.array([[0.75 * Ax + 0.25 * By, s3 / 4 * (Ax - By), 0.0],
                         [s3 / 4 * (Ax - By), 0.25 * Ax + 0.75 * By, 0.0],
                         [0.0, 0.0, Cz]])
    assert np.allclose(body.tensor, expected, rtol=0, atol=1e-12)
    assert np.allclose(body.com, (2.0, -1.0, 0.5), atol=1e-14)
    # a general rotation: R I R^T of the primitive
    q2 = np.array([0.8, -0.2, 0.5, 0.26])
    q2 = q2 / np.linalg.norm(q2)
    mesh2 = trimesh.creation.box(extents=(3.0, 1.0, 2.0))
    mesh2.apply_transform(np.block([[quat_to_matrix(q2), np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]))
    assert np.allclose(Inertia.from_mesh(mesh2, mass=6.0).tensor,
                       Inertia.box(6.0, (3.0, 1.0, 2.0)).rotated(q2).tensor, rtol=0, atol=1e-12)


def test_tetrahedron_by_hand():
    """Unit right tetrahedron (0, e1, e2, e3), density 1: V = 1/6, centre (1/4, 1/4, 1/4); about the
    origin int x^2 dV = 1/60 and int x y dV = 1/120, so about the centre C_xx = 1/60 - V/16 = 1/160,
    C_xy = 1/120 - V/16 = -1/480: I_xx = 2/160 = 1/80, I_xy = +1/480."""
    mesh = trimesh.Trimesh(vertices=np.r_[np.zeros((1, 3)), np.eye(3)],
                           faces=[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], process=False)
    body = Inertia.from_mesh(mesh, density=1.0)
    assert body.mass == pytest.approx(1 / 6, rel=1e-14)
    assert np.allclose(body.com, 0.25, rtol=1e-14)
    expected = np.full((3, 3), 1 / 480) + np.eye(3) * (1 / 80 - 1 / 480)
    assert np.allclose(body.tensor, expected, rtol=1e-13, atol=0)


@pytest.mark.parametrize("sections", [8, 64, 256])
def test_cylinder_mesh_is_the_exact_polygon_prism(sections):
    """trimesh's cylinder is a regular-polygon prism with vertices on the circle: exactly
    I_axis = M a^2 k, I_across = M (a^2 k / 2 + L^2 / 12), k = (1 + 2 cos^2(pi/n)) / 6."""
    a, length, mass = 0.4, 1.3, 2.0
    body = Inertia.from_mesh(trimesh.creation.cylinder(radius=a, height=length, sections=sections), mass=mass)
    k = polygon_factor(sections)
    expected = np.diag([mass * (a**2 * k / 2 + length**2 / 12)] * 2 + [mass * a**2 * k])
    assert np.allclose(body.tensor, expected, rtol=0, atol=1e-12 * np.max(expected))


def test_cylinder_mesh_against_the_cylinder_discretisation_error():
    """Measured relative error of a 64-section cylinder (a = 0.4, L = 1.3) against M a^2/2 about its
    axis: 1.605e-3 = (2/3) sin^2(pi/64); it falls 4x each time the sections double (second order)."""
    a, length = 0.4, 1.3
    errors = []
    for n in (32, 64, 128):
        body = Inertia.from_mesh(trimesh.creation.cylinder(radius=a, height=length, sections=n), mass=1.0)
        errors.append(rel(body.tensor[2, 2], Inertia.solid_cylinder(1.0, a, length).tensor[2, 2]))
        assert errors[-1] == pytest.approx(2 / 3 * math.sin(math.pi / n) ** 2, rel=1e-9)
    assert errors[1] == pytest.approx(1.605e-3, rel=1e-3)
    assert 3.99 < errors[0] / errors[1] < 4.0 and 3.99 < errors[1] / errors[2] < 4.0


@pytest.mark.parametrize("sections", [16, 64])
def test_annulus_mesh_is_the_exact_polygon_tube(sections):
    """trimesh's annulus: two regular n-gons; with the same factor k for both,
    I_axis = M (a^2 + b^2) k and I_across = M ((a^2 + b^2) k / 2 + L^2 / 12), against the tube's
    M (a^2 + b^2)/2 (relative error (2/3) sin^2(pi/n), 1.605e-3 at n = 64)."""
    inner, outer, length, mass = 0.25, 0.6, 0.8, 3.0
    body = Inertia.from_mesh(trimesh.creation.annulus(r_min=inner, r_max=outer, height=length, sections=sections),
                             mass=mass)
    k = polygon_factor(sections)
    s = inner**2 + outer**2
    expected = np.diag([mass * (s * k / 2 + length**2 / 12)] * 2 + [mass * s * k])
    assert np.allclose(body.tensor, expected, rtol=0, atol=1e-12 * np.max(expected))
    tube = Inertia.hollow_cylinder(mass, inner, outer, length)
    assert rel(body.tensor[2, 2], tube.tensor[2, 2]) == pytest.approx(2 / 3 * math.sin(math.pi / sections) ** 2,
                                                                      rel=1e-9)


def test_icosphere_converges_to_the_sphere_at_second_order():
    """Measured (unit mass, a = 1): the icosphere's moment is below 2/5 M a^2 by 5.74e-3 (3
    subdivisions) and 1.44e-3 (4), a ratio of 3.986 (second order in the edge length); Richardson's
    (4 I_4 - I_3)/3 is within 7.0e-6 of 2/5. Icosahedral symmetry makes the tensor isotropic."""
    radius, mass = 1.0, 1.0
    moments = []
    for subdivisions in (3, 4):
        body = Inertia.from_mesh(trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius), mass=mass)
        assert np.allclose(body.tensor, body.tensor[0, 0] * np.eye(3), rtol=0, atol=1e-14)
        moments.append(body.tensor[0, 0])
    exact = Inertia.solid_sphere(mass, radius).tensor[0, 0]
    e3, e4 = rel(moments[0], exact), rel(moments[1], exact)
    assert moments[1] < exact and e4 < 1.45e-3
    assert 3.95 < e3 / e4 < 4.0
    assert rel((4 * moments[1] - moments[0]) / 3, exact) < 1e-5


# ----- precision far from the origin -----------------------------------------------------------------

@pytest.mark.parametrize("shell", [False, True])
def test_mesh_a_million_metres_away_keeps_its_tensor(shell):
    mesh = trimesh.creation.cylinder(radius=0.3, height=0.7, sections=32)
    mesh.apply_transform(np.block([[quat_to_matrix([0.9, 0.3, -0.2, 0.1]), np.zeros((3, 1))],
                                   [np.zeros((1, 3)), np.ones((1, 1))]]))
    here = Inertia.from_mesh(mesh, mass=2.0, shell=shell)
    offset = np.array([1e6 + 0.123456789, -2.3e6, 0.77e6])
    far_mesh = mesh.copy()
    far_mesh.apply_translation(offset)
    far = Inertia.from_mesh(far_mesh, mass=2.0, shell=shell)
    scale = np.max(np.abs(here.tensor))
    assert np.max(np.abs(far.tensor - here.tensor)) <= 1e-9 * scale
    assert np.allclose(far.com, here.com + offset, rtol=0, atol=1e-8)
    assert np.isclose(far.mass, here.mass, rtol=1e-15)


# ----- thin shells --------------------------------------------------------------------------------------

def test_box_shell_equals_its_six_face_plates():
    """A thin box shell of uniform areal density is six plates (laminae), each moved out from the
    centre by the parallel-axis theorem and added."""
    a, b, c = 0.5, 1.2, 2.0
    rho = 3.0                                           # kg/m^2
    plates = []
    for normal, (width, height) in ((0, (b, c)), (1, (a, c)), (2, (a, b))):
        size = np.array([a, b, c])
        size[normal] = 0.0
        half = np.array([a, b, c])[normal] / 2
        for sign in (-1, 1):
            offset = np.zeros(3)
            offset[normal] = sign * half
            plates.append(Inertia.box(rho * width * height, size).translated(offset))
    expected = sum(plates[1:], plates[0])
    body = Inertia.from_mesh(trimesh.creation.box(extents=(a, b, c)), density=rho, shell=True)
    assert body.mass == pytest.approx(rho * 2 * (a * b + b * c + a * c), rel=1e-14)
    assert np.allclose(body.tensor, expected.tensor, rtol=0, atol=1e-12 * np.max(expected.tensor))
    # a cube's shell by hand: 6 faces of mass M/6; I = 2 (M/6)(s^2/6) + 4 (M/6)(s^2/12 + s^2/4) = 5/18 M s^2
    cube = Inertia.from_mesh(trimesh.creation.box(extents=(2.0, 2.0, 2.0)), mass=1.0, shell=True)
    assert np.allclose(cube.tensor, 5 / 18 * 4.0 * np.eye(3), rtol=1e-14)


def test_icosphere_shell_approaches_the_spherical_shell():
    """Measured (unit mass, a = 1): 5.74e-3 (3 subdivisions) and 1.44e-3 (4) below 2/3 M a^2,
    ratio 3.986; Richardson's (4 I_4 - I_3)/3 is within 7.0e-6 of 2/3."""
    moments = []
    for subdivisions in (3, 4):
        body = Inertia.from_mesh(trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0),
                                 mass=1.0, shell=True)
        assert np.allclose(body.tensor, body.tensor[0, 0] * np.eye(3), rtol=0, atol=1e-14)
        moments.append(body.tensor[0, 0])
    exact = 2 / 3
    assert moments[0] < moments[1] < exact
    assert 3.95 < rel(moments[0], exact) / rel(moments[1], exact) < 4.0
    assert rel((4 * moments[1] - moments[0]) / 3, exact) < 1e-5


def test_triangle_second_moment_formula():
    """One triangle, shell: int x x^T dA = A/12 (sum v v^T + s s^T); the right triangle (0,0), (1,0),
    (0,1) has A = 1/2, int x^2 dA = 1/12, int x y dA = 1/24, centre (1/3, 1/3)."""
    mesh = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]], process=False)
    body = Inertia.from_mesh(mesh, density=1.0, shell=True)
    assert body.mass == pytest.approx(0.5, rel=1e-15)
    assert np.allclose(body.com, [1 / 3, 1 / 3, 0], rtol=1e-15)
    cxx = 1 / 12 - 0.5 / 9                              # about the centre
    cxy = 1 / 24 - 0.5 / 9
    expected = np.array([[cxx, -cxy, 0], [-cxy, cxx, 0], [0, 0, 2 * cxx]])
    assert np.allclose(body.tensor, expected, rtol=1e-13, atol=1e-16)


def test_open_mesh_is_fine_as_a_shell():
    """A box without its top face: the five remaining plates."""
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    top = np.flatnonzero(np.isclose(mesh.triangles_center[:, 2], 0.5))
    keep = np.setdiff1d(np.arange(len(mesh.faces)), top)
    open_box = trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)
    body = Inertia.from_mesh(open_box, density=1.0, shell=True)
    assert body.mass == pytest.approx(5.0, rel=1e-15)
    assert body.com[2] == pytest.approx(-0.1, rel=1e-14)  # (4 * 0 + 1 * (-1/2)) / 5


# ----- mesh hygiene ------------------------------------------------------------------------------------

def test_duplicate_vertices_and_degenerate_faces_are_harmless():
    """A box as an STL-like soup (every triangle with its own vertices, not merged), plus a face
    collapsed onto an edge and a zero-area face with three distinct collinear vertices."""
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    soup_vertices = box.vertices[box.faces].reshape(-1, 3)
    soup_faces = np.arange(len(soup_vertices)).reshape(-1, 3)
    collapsed = [[0, 0, 1]]
    soup = trimesh.Trimesh(soup_vertices, np.r_[soup_faces, collapsed], process=False)
    assert not soup.is_watertight                      # trimesh sees an open soup...
    body = Inertia.from_mesh(soup, mass=1.0)           # ...the exact duplicates are merged
    assert np.allclose(body.tensor, Inertia.box(1.0, (1.0, 2.0, 3.0)).tensor, rtol=0, atol=1e-14)
    # another triangulation of the same solid: an edge of a tetrahedron split at its midpoint
    tet = np.r_[np.zeros((1, 3)), np.eye(3)]
    mid = (tet[1] + tet[2]) / 2
    vertices = np.r_[tet, [mid]]
    faces = [[0, 4, 1], [0, 2, 4], [0, 1, 3], [0, 3, 2], [1, 4, 3], [4, 2, 3]]
    split = Inertia.from_mesh(trimesh.Trimesh(vertices, faces, process=False), density=1.0)
    whole = Inertia.from_mesh(trimesh.Trimesh(tet, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], process=False),
                              density=1.0)
    assert split.mass == pytest.approx(whole.mass, rel=1e-14)
    assert np.allclose(split.tensor, whole.tensor, rtol=1e-13)
    # zero-area face (three distinct collinear vertices) closed by its reverse: contributes nothing
    line = np.array([[5.0, 0, 0], [6.0, 0, 0], [7.0, 0, 0]])
    with_sliver = trimesh.Trimesh(np.r_[tet, line], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [4, 5, 6], [4, 6, 5]],
                                  process=False)
    assert np.allclose(Inertia.from_mesh(with_sliver, density=1.0).tensor, whole.tensor, rtol=1e-13)


def test_hollow_body_with_inward_cavity():
    """An outer box with an inner box facing inwards: a box with a cavity, M = rho (V_out - V_in)."""
    outer = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    inner = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    inner.invert()
    body = Inertia.from_mesh(trimesh.util.concatenate([outer, inner]), density=1.0)
    expected = Inertia.box(8.0, (2, 2, 2)).tensor - Inertia.box(1.0, (1, 1, 1)).tensor
    assert body.mass == pytest.approx(7.0, rel=1e-14)
    assert np.allclose(body.tensor, expected, rtol=0, atol=1e-13)
    # a ball loose in the cavity of a hollow ball (concentric icospheres: every moment scales as r^5)
    unit = Inertia.from_mesh(trimesh.creation.icosphere(subdivisions=3, radius=1.0), density=1.0)
    shells = []
    for radius, inward in ((1.0, False), (0.8, True), (0.5, False)):
        sphere = trimesh.creation.icosphere(subdivisions=3, radius=radius)
        if inward:
            sphere.invert()
        shells.append(sphere)
    rattle = Inertia.from_mesh(trimesh.util.concatenate(shells), density=1.0)
    factor = 1 - 0.8**5 + 0.5**5
    assert rattle.mass == pytest.approx(unit.mass * (1 - 0.8**3 + 0.5**3), rel=1e-13)
    assert np.allclose(rattle.tensor, factor * unit.tensor, rtol=0, atol=1e-13)
    # two separate bodies in one mesh add up
    far = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    far.apply_translation((4.0, 0.0, 0.0))
    pair = Inertia.from_mesh(trimesh.util.concatenate([outer, far]), density=1.0)
    expected_pair = Inertia.box(8.0, (2, 2, 2)) + Inertia.box(1.0, (1, 1, 1)).translated((4, 0, 0))
    assert np.allclose(pair.tensor, expected_pair.tensor, rtol=1e-13)


def test_mesh_file_path_loads(tmp_path):
    path = tmp_path / "box.stl"
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(path)
    body = Inertia.from_mesh(path, mass=2.0)
    assert np.allclose(body.tensor, Inertia.box(2.0, (1.0, 2.0, 3.0)).tensor, rtol=0, atol=1e-6)  # STL: float32
    assert np.allclose(Inertia.from_mesh(str(path), mass=2.0).tensor, body.tensor, rtol=0, atol=0)


# ----- bad meshes and bad input -------------------------------------------------------------------------

def open_box():
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    return trimesh.Trimesh(mesh.vertices, mesh.faces[2:], process=False)


def inverted_box():
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    mesh.invert()
    return mesh


def flipped_face_box():
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    faces = mesh.faces.copy()
    faces[0] = faces[0][::-1]
    return trimesh.Trimesh(mesh.vertices, faces, process=False)


def isolated_inverted_part():
    good = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    bad = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    bad.apply_translation((5.0, 0.0, 0.0))
    bad.invert()
    return trimesh.util.concatenate([good, bad])


def overlapping_parts():
    return trimesh.util.concatenate([trimesh.creation.box(extents=(2.0, 2.0, 2.0)),
                                     trimesh.creation.box(extents=(1.0, 1.0, 1.0))])


def flat_closed():
    """Two triangles back to back: closed and consistently wound, but enclosing nothing."""
    return trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 1]], process=False)


BAD_MESHES = [
    (open_box, {"density": 1.0}, r"not watertight.*shell=True.*fill_holes"),
    (inverted_box, {"density": 1.0}, r"inverted: faces point inwards.*mesh\.invert\(\)"),
    (inverted_box, {"mass": 1.0}, r"inverted"),
    (flipped_face_box, {"density": 1.0}, r"not consistently wound.*shell=True.*fix_winding"),
    (isolated_inverted_part, {"density": 1.0}, r"part 1 of 2.*inverted part.*invert"),
    (overlapping_parts, {"density": 1.0}, r"part 1 of 2.*overlapping solids count their mass twice"),
    (flat_closed, {"density": 1.0}, r"encloses no volume.*shell=True"),
    (lambda: trimesh.creation.box(), {"density": 1.0, "mass": 1.0}, r"give exactly one of density"),
    (lambda: trimesh.creation.box(), {}, r"give exactly one of density"),
    (lambda: trimesh.creation.box(), {"density": 0.0}, r"density=0\.0: must be > 0"),
    (lambda: trimesh.creation.box(), {"density": -1.0}, r"density=-1\.0: must be > 0"),
    (lambda: trimesh.creation.box(), {"mass": float("nan")}, r"mass=nan: every value must be finite"),
    (lambda: trimesh.creation.box(), {"mass": [1.0, 2.0]}, r"mass has shape \(2,\)"),
    (lambda: trimesh.creation.box(), {"mass": 1.0, "shell": "yes"}, r"shell='yes'"),
    (lambda: np.zeros((3, 3)), {"mass": 1.0}, r"expected a trimesh\.Trimesh or a path"),
    (lambda: "/nonexistent/mesh.stl", {"mass": 1.0}, r"mesh='/nonexistent/mesh\.stl': trimesh could not load it"),
    (lambda: trimesh.Trimesh(np.zeros((3, 3)), [[0, 1, 2]], process=False), {"mass": 1.0, "shell": True},
     r"only degenerate faces"),
    (lambda: trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], process=False),
     {"mass": 1.0, "shell": True}, r"zero surface area"),
    (lambda: trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 1]], process=False),
     {"mass": 1.0, "shell": True}, r"1 repeated faces"),
]


@pytest.mark.parametrize("make, kwargs, message", BAD_MESHES, ids=[m for _, _, m in BAD_MESHES])
def test_bad_mesh_raises_value_error_naming_the_problem(make, kwargs, message):
    with pytest.raises(ValueError, match=message):
        Inertia.from_mesh(make(), **kwargs)
