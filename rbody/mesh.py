"""Mass properties of a triangle mesh, as a solid of uniform density or as a thin uniform shell.

Solid. A closed, consistently wound surface bounds a volume; with the origin at any point O, each
face (a, b, c) spans the signed tetrahedron (O, a, b, c) of volume V_t = a . (b x c) / 6, and the
signed tetrahedra add up to the enclosed solid (the divergence theorem).  For a tetrahedron with
one vertex at the origin

    int x dV     = V_t (a + b + c) / 4,
    int x x^T dV = V_t / 20 (a a^T + b b^T + c c^T + s s^T),   s = a + b + c,

exactly.  Thin shell. For a triangle of area A

    int x dA     = A (a + b + c) / 3,
    int x x^T dA = A / 12 (a a^T + b b^T + c c^T + s s^T).

From the second moment C = int x x^T dm about the centre of mass, the chapter's tensor is
I_ab = sum m (|x|^2 d_ab - x_a x_b) = tr(C) d_ab - C_ab: products of inertia carry the minus sign.

Precision: the vertices are first moved by their mean, so the sums are formed with coordinates of
the size of the body, not of its distance from the origin; the second moment is then shifted to
the centre of mass exactly (C_com = C - m d d^T).  A mesh a million metres from the origin gives
the tensor it gives at the origin, to the rounding of its own vertex coordinates.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numba import njit

from rbody.checks import finite_array, positive

# Signed volume below this fraction of the summed |tetrahedron volumes| is round-off: no volume.
_ZERO_VOLUME_RTOL = 1e-10
# Query points per mesh component for the winding-number check.
_QUERIES_PER_COMPONENT = 3


def mass_properties(mesh: Any, *, density: float | None = None, mass: float | None = None,
                    shell: bool = False) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass properties of a triangle mesh: mass, centre of mass and tensor about it (rbody.Inertia.from_mesh
    wraps them in an Inertia).

    mesh:    trimesh.Trimesh (or trimesh.Scene, whose geometry is joined), or a path trimesh can
             load; vertices in the frame the body is given in [m]
    density: uniform density, kg/m^3 for a solid, kg/m^2 for a shell (shell=True) [kg/m^3 | kg/m^2]
    mass:    total mass instead of a density [kg]; give exactly one of density and mass
    shell:   False: the solid the closed surface bounds. True: a thin surface of uniform areal
             density (any mesh, open or closed, wound either way)

    Returns (mass [kg], com (3,) in the mesh's frame [m], tensor (3,3) about com [kg m^2]).

    A solid needs a closed (watertight), consistently wound surface with outward faces; otherwise
    ValueError says which and how to repair it. Exactly repeated vertices are merged and faces
    collapsed onto an edge (a repeated vertex index) are dropped: neither changes the body.
    Zero-area faces with three distinct vertices contribute nothing and are kept. A mesh of several
    closed parts may contain cavities (inward-facing inner surfaces); an inside-out part or parts
    that overlap are errors, found from the winding number of the other parts (only parts whose
    bounding boxes overlap are compared; parts are faces joined across edges that two faces share,
    so a body touching another at a corner is still a part of its own). A surface that intersects
    itself (a fold, or parts that cross) is an error, found by an exact test of every pair of faces
    whose bounding boxes overlap (an edge of one passing strictly through the other; coplanar
    overlaps are not seen). A mesh with more than MAX_FACE_PAIRS such pairs (about 5e6: a
    cylinder of ~700 sections, whose cap triangles all meet at the centre) is refused rather than
    left unchecked; a shell (shell=True) is not checked.
    """
    if (density is None) == (mass is None):
        raise ValueError(
            f"density={density!r}, mass={mass!r}: give exactly one of density "
            "[kg/m^3, or kg/m^2 for shell=True] and mass [kg]")
    if density is not None:
        density = positive(finite_array(density, "density", shape=()), "density")
    if mass is not None:
        mass = positive(finite_array(mass, "mass", shape=()), "mass")
    if not isinstance(shell, (bool, np.bool_)):
        raise ValueError(f"shell={shell!r}: expected True (thin surface) or False (solid)")

    vertices, faces = _clean(*_load(mesh))
    # In units of the body's size s about its vertex mean: the integrals (up to s^5) neither overflow nor
    # underflow for a body 1e-100 or 1e100 m across; the results are scaled back once, per unit mass.
    centre = vertices.mean(axis=0)
    size = float(np.max(np.abs(vertices - centre)))
    if size == 0.0:
        raise ValueError("mesh has all its vertices at one point: it has no area or volume")
    local = (vertices - centre) / size
    if shell:
        measure, first, second = _shell_moments(local, faces)
    else:
        measure, first, second = _solid_moments(local, faces)

    # Uniform density rho: m = rho * measure s^k (k = 3 solid, 2 shell); the moments per unit mass do not
    # depend on rho.
    if density is not None:
        with np.errstate(over="raise", under="ignore"):
            try:
                total = density * measure * size ** (2 if shell else 3)
            except FloatingPointError:
                raise ValueError(f"density={density!r} over a body {size:.3g} m across: the mass overflows float64") from None
        if not total > 0:
            raise ValueError(f"density={density!r} over a body {size:.3g} m across: the mass underflows to 0 in float64")
    else:
        total = mass
    offset = first / measure                            # centre of mass relative to the vertex mean [s]
    per_mass = second / measure - np.outer(offset, offset)
    per_mass = 0.5 * (per_mass + per_mass.T) * size**2  # int x x^T dm / m about the centre of mass [m^2]
    tensor = total * (np.trace(per_mass) * np.eye(3) - per_mass)
    return float(total), centre + offset * size, tensor


# ----- input ---------------------------------------------------------------------------------------

def _load(mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) vertices [m] and (F, 3) integer faces of a Trimesh, a Scene or a mesh file."""
    import trimesh

    if isinstance(mesh, (str, os.PathLike)):
        try:
            mesh = trimesh.load_mesh(os.fspath(mesh))
        except Exception as error:  # trimesh raises many types for unreadable files
            raise ValueError(f"mesh={os.fspath(mesh)!r}: trimesh could not load it ({error})") from None
    elif isinstance(mesh, trimesh.Scene):
        mesh = mesh.to_mesh()
    if not isinstance(mesh, trimesh.Trimesh):
        raise ValueError(f"mesh={type(mesh).__name__}: expected a trimesh.Trimesh or a path to a mesh file")
    vertices = finite_array(mesh.vertices, "mesh.vertices", ndim=2)
    faces = np.asarray(mesh.faces)
    if vertices.shape[1:] != (3,):
        raise ValueError(f"mesh.vertices has shape {vertices.shape}: expected (n, 3)")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.dtype.kind not in "iu":
        raise ValueError(f"mesh.faces has shape {faces.shape} and dtype {faces.dtype}: "
                         "expected (n, 3) vertex indices of triangles")
    if faces.shape[0] == 0:
        raise ValueError("mesh has no faces: an empty mesh has no mass")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ValueError(f"mesh.faces index vertices outside 0..{len(vertices) - 1}")
    return vertices, faces.astype(np.int64)


def _clean(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Only the vertices the faces use, exact duplicates merged; faces with a repeated index dropped."""
    unique, inverse = np.unique(vertices[faces.ravel()], axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3)
    collapsed = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    faces = faces[~collapsed]
    if faces.shape[0] == 0:
        raise ValueError("mesh has only degenerate faces (each repeats a vertex): it has no area or volume")
    return unique, faces


# ----- integrals -----------------------------------------------------------------------------------

def _corners(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, ...]:
    """Corners a, b, c (F, 3) of every face, measured from the vertex mean [m]."""
    local = vertices - vertices.mean(axis=0)
    return local[faces[:, 0]], local[faces[:, 1]], local[faces[:, 2]]


def _second_moment(weights: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(3,3) sum_t w_t (a a^T + b b^T + c c^T + s s^T), s = a + b + c."""
    s = a + b + c
    return sum(np.einsum("t,ti,tj->ij", weights, p, p) for p in (a, b, c, s))


def _solid_moments(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Volume V [m^3], int x dV (3,) [m^4] and int x x^T dV (3,3) [m^5] about the vertex mean."""
    _check_closed(faces, len(vertices))
    a, b, c = _corners(vertices, faces)
    six_volumes = np.einsum("ti,ti->t", a, np.cross(b, c))   # 6 V_t = a . (b x c)
    volume = float(six_volumes.sum()) / 6.0
    scale = float(np.abs(six_volumes).sum()) / 6.0
    if abs(volume) <= _ZERO_VOLUME_RTOL * scale:
        raise ValueError(f"mesh encloses no volume (signed volume {volume:.3g} m^3): "
                         "use shell=True for a surface")
    if volume < 0:
        raise ValueError(f"mesh is inverted: faces point inwards (signed volume {volume:.6g} m^3); "
                         "use mesh.invert() to turn them outwards")
    _check_parts(vertices, faces, six_volumes)
    _check_self_intersection(vertices, faces)
    first = six_volumes @ (a + b + c) / 24.0                  # V_t s / 4
    second = _second_moment(six_volumes / 120.0, a, b, c)      # V_t / 20
    return volume, first, second


def _shell_moments(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Area A [m^2], int x dA (3,) [m^3] and int x x^T dA (3,3) [m^4] about the vertex mean."""
    keys = np.unique(np.sort(faces, axis=1), axis=0, return_counts=True)[1]
    repeated = int(np.sum(keys - 1))
    if repeated:
        raise ValueError(
            f"mesh has {repeated} repeated faces (the same three vertices, e.g. a double-sided "
            "surface): a thin shell would count their area twice; remove them first "
            "(mesh.update_faces(mesh.unique_faces()))")
    a, b, c = _corners(vertices, faces)
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    area = float(areas.sum())
    if area <= 0:
        raise ValueError("mesh has zero surface area: a shell needs non-degenerate faces")
    first = areas @ (a + b + c) / 3.0
    second = _second_moment(areas / 12.0, a, b, c)
    return area, first, second


# ----- checks of a solid ---------------------------------------------------------------------------

def _check_closed(faces: np.ndarray, n_vertices: int) -> None:
    """Raise ValueError unless every edge is met an even number of times, as often i->j as j->i."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    undirected = np.sort(directed, axis=1)
    counts = np.unique(undirected[:, 0] * n_vertices + undirected[:, 1], return_counts=True)[1]
    odd = int(np.sum(counts % 2 == 1))
    if odd:
        raise ValueError(
            f"mesh is not watertight: {odd} edges border an odd number of faces (holes or an open "
            "boundary), so it bounds no solid. Use shell=True for a thin surface, or repair it "
            "(mesh.merge_vertices(), mesh.fill_holes() or trimesh.repair.fill_holes(mesh))")
    forward = np.sort(directed[:, 0] * n_vertices + directed[:, 1])
    backward = np.sort(directed[:, 1] * n_vertices + directed[:, 0])
    if not np.array_equal(forward, backward):
        mismatched = int(np.sum(forward != backward))
        raise ValueError(
            f"mesh is not consistently wound: about {mismatched} edges are run the same way by the "
            "faces on both sides, so the faces do not all point outwards. Use shell=True for a "
            "thin surface, or repair it (trimesh.repair.fix_winding(mesh), then check mesh.volume > 0)")


def _check_parts(vertices: np.ndarray, faces: np.ndarray, six_volumes: np.ndarray) -> None:
    """Each closed part must see uniform density 0 or 1 on both of its sides.

    With w the winding number of the other parts at a point of part k: a part facing outwards
    (V_k > 0) must lie outside all other material (w = 0); a cavity (V_k < 0) must lie inside
    material (w = 1). An isolated part must therefore face outwards.
    """
    n_parts, label = _parts(faces, len(vertices))
    if n_parts == 1:
        return
    volumes = np.bincount(label, weights=six_volumes, minlength=n_parts) / 6.0
    spans = np.bincount(label, weights=np.abs(six_volumes), minlength=n_parts) / 6.0
    corner = vertices[faces]                                        # (F, 3 corners, 3)
    low = np.full((n_parts, 3), np.inf)
    high = np.full((n_parts, 3), -np.inf)
    np.minimum.at(low, label, corner.min(axis=1))
    np.maximum.at(high, label, corner.max(axis=1))
    pad = 1e-9 * float(np.max(high.max(axis=0) - low.min(axis=0)))
    areas = np.linalg.norm(np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0]), axis=1)
    order = np.argsort(label, kind="stable")                       # faces grouped by part
    bounds = np.searchsorted(label[order], np.arange(n_parts + 1))
    faces_of = [order[bounds[k]:bounds[k + 1]] for k in range(n_parts)]
    for k in range(n_parts):
        if abs(volumes[k]) <= _ZERO_VOLUME_RTOL * spans[k]:
            continue  # a part enclosing nothing (e.g. a face closed by its reverse) has no mass
        expected = 0.0 if volumes[k] > 0 else 1.0
        overlap = np.all((low[k] <= high + pad) & (low <= high[k] + pad), axis=1)
        overlap[k] = False
        others = np.flatnonzero(overlap)
        if others.size == 0:
            winding = 0.0
        else:
            own = faces_of[k]
            picks = own[np.argsort(areas[own])[::-1][:_QUERIES_PER_COMPONENT]]
            points = corner[picks].mean(axis=1)
            neighbours = np.concatenate([faces_of[j] for j in others])
            winding = float(np.median(_winding_number(points, corner[neighbours])))
        if abs(winding - expected) > 0.25:
            role = "faces outwards" if volumes[k] > 0 else "faces inwards (a cavity)"
            fix = ("an inverted part: use mesh.invert() on it" if volumes[k] < 0 and winding < 0.5
                   else "overlapping solids count their mass twice (join them with a boolean union)"
                   if volumes[k] > 0 else "a cavity facing inwards must lie inside the material")
            raise ValueError(
                f"mesh part {k} of {n_parts} ({len(faces_of[k])} faces, signed volume "
                f"{volumes[k]:.6g} m^3) {role} but the winding number of the other parts there is "
                f"{winding:.3g}, not {expected:g}: {fix}")


def _parts(faces: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """(number of parts, (F,) part of each face): faces joined across the edges they share two by two
    (one face running the edge each way), not across a vertex or an edge where more faces meet, so that
    a body touching another at one corner or along one edge is still a part of its own."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_faces = len(faces)
    undirected = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    key = undirected[:, 0] * n_vertices + undirected[:, 1]
    owner = np.repeat(np.arange(n_faces), 3)
    order = np.argsort(key, kind="stable")
    key, owner = key[order], owner[order]
    _, start, count = np.unique(key, return_index=True, return_counts=True)
    manifold = start[count == 2]                   # edges met by exactly two faces
    graph = coo_matrix((np.ones(len(manifold)), (owner[manifold], owner[manifold + 1])), shape=(n_faces, n_faces))
    return connected_components(graph, directed=False)


# Self-intersection test: meshes up to this many candidate pairs of faces (bounding boxes that overlap)
# are checked exactly; a larger one is refused (rbody cannot then say that its surface does not cross itself).
MAX_FACE_PAIRS = 5_000_000  # ~2 s of numpy (a 512-section cylinder: 1.5 s; an 81920-face icosphere: 2.6 s)
_ORIENT_RTOL = 1e-12  # an orientation below this fraction of |edge|^3 is a touch, not a crossing


def _check_self_intersection(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Raise ValueError when two faces of the surface cross (a surface that folds through itself, or parts that
    overlap): their volumes would be counted twice or with the wrong sign. Two faces cross when an edge of one
    passes through the inside of the other, both strictly (a touch along a face, an edge or at a point is not
    a crossing); edges at a vertex the faces share are not tested (they meet there), and faces sharing an
    edge, or of zero area, are skipped. Coplanar faces that overlap are not found."""
    # In units of the mesh's size about its centre: the test is scale-free, and areas of a body 1e-100 m across
    # do not underflow.
    local = vertices - vertices.mean(axis=0)
    size = float(np.max(np.abs(local)))
    if size == 0:
        return
    corner = (local / size)[faces]                                      # (F, 3, 3)
    areas = np.linalg.norm(np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0]), axis=1)
    keep = np.flatnonzero(areas > 1e-14 * max(float(areas.max()), np.finfo(float).tiny))
    if keep.size < 2:
        return
    first, second = _candidate_pairs(corner[keep])
    first, second = keep[first], keep[second]
    # Faces that cross each have corners strictly on both sides of the other's plane: most pairs (neighbours
    # on a convex patch, coplanar fans) fail this cheap test and are not tested edge by edge.
    normal = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), np.finfo(float).tiny)
    size = np.max(corner.max(axis=1) - corner.min(axis=1), axis=1)
    straddle = _straddles(corner[second], normal[first], corner[first, 0], size[first] + size[second])
    straddle &= _straddles(corner[first], normal[second], corner[second, 0], size[first] + size[second])
    first, second = first[straddle], second[straddle]
    for lo in range(0, len(first), 1_000_000):
        i, j = first[lo:lo + 1_000_000], second[lo:lo + 1_000_000]
        crossing = _faces_cross(corner[i], corner[j], faces[i], faces[j])
        if np.any(crossing):
            k = int(np.argmax(crossing))
            raise ValueError(
                f"mesh surface intersects itself: faces {int(i[k])} and {int(j[k])} cross (at least "
                f"{int(crossing.sum())} pairs of faces do), so parts of the solid overlap or the surface folds "
                "through itself and some volume would count twice or with the wrong sign; join overlapping parts "
                "with a boolean union (trimesh's mesh.union) or repair the surface")


def _candidate_pairs(corner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs i < j of faces (F, 3, 3) whose bounding boxes overlap, in numpy: each face is entered in the cells
    of a uniform grid (cell size the median extent of a face) that its box covers, and faces sharing a cell are
    paired. ValueError beyond MAX_FACE_PAIRS pairs (the exact test would take minutes)."""
    low, high = corner.min(axis=1), corner.max(axis=1)
    pad = 1e-9 * float(np.max(high.max(axis=0) - low.min(axis=0)))
    low, high = low - pad, high + pad
    # Cell size: the median width of a face (sqrt(2 area)), so that long slivers (a cylinder's caps and sides)
    # fall in many small cells rather than all faces in a few large ones; doubled while the entries are too many.
    width = np.sqrt(np.linalg.norm(np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0]), axis=1))
    cell = max(float(np.median(width)), 1e-9 * float(np.max(high - low)), np.finfo(float).tiny)
    origin = low.min(axis=0)
    while True:
        first_cell = np.floor((low - origin) / cell).astype(np.int64)
        last_cell = np.floor((high - origin) / cell).astype(np.int64)
        span = last_cell - first_cell + 1                               # (F, 3) cells along each axis
        per_face = np.prod(span.astype(np.float64), axis=1)
        if per_face.sum() <= 8 * len(corner) + 1_000_000:
            break
        cell *= 2.0
    per_face = per_face.astype(np.int64)
    face = np.repeat(np.arange(len(corner)), per_face)
    local = np.arange(len(face)) - np.repeat(np.cumsum(per_face) - per_face, per_face)
    sy, sz = span[face, 1], span[face, 2]
    offset = np.stack([local // (sy * sz), (local // sz) % sy, local % sz], axis=1)
    index = first_cell[face] + offset
    size = last_cell.max(axis=0) + 1
    key = (index[:, 0] * size[1] + index[:, 1]) * size[2] + index[:, 2]
    order = np.argsort(key, kind="stable")
    key, face, index = key[order], face[order], index[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    count = np.diff(np.r_[start, len(key)])
    total = float(np.sum(count * (count - 1) / 2))
    if total > MAX_FACE_PAIRS:
        _refuse_pairs(len(corner), total)
    position = np.arange(len(face))
    later = np.repeat(start + count, count) - position - 1              # entries after each one in its cell
    first = np.repeat(position, later)
    second = first + 1 + (np.arange(int(later.sum())) - np.repeat(np.cumsum(later) - later, later))
    i, j = face[first], face[second]
    # A pair is kept in one cell only, the one holding the lowest corner of the overlap of its boxes.
    home = np.floor((np.maximum(low[i], low[j]) - origin) / cell).astype(np.int64)
    keep = np.all(home == index[first], axis=1) & np.all((low[i] <= high[j]) & (low[j] <= high[i]), axis=1)
    i, j = i[keep], j[keep]
    return np.minimum(i, j), np.maximum(i, j)


def _straddles(tri: np.ndarray, normal: np.ndarray, point: np.ndarray, size: np.ndarray) -> np.ndarray:
    """(N,) triangle tri (N, 3, 3) has corners strictly on both sides of the plane (normal, point) (N, 3)."""
    distance = np.einsum("nki,ni->nk", tri - point[:, None, :], normal)
    tolerance = (_ORIENT_RTOL * size)[:, None]
    return np.any(distance > tolerance, axis=1) & np.any(distance < -tolerance, axis=1)


def _refuse_pairs(n_faces: int, pairs: float) -> None:
    raise ValueError(
        f"mesh has {n_faces} faces with about {pairs:.3g} pairs of faces close enough to cross, beyond "
        f"{MAX_FACE_PAIRS:.0e}: rbody cannot check in reasonable time that the surface does not intersect itself; "
        "simplify the mesh (mesh.simplify_quadric_decimation) or give it in parts")


def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N,) sign (-1, 0, 1) of the volume (b - a) . ((c - a) x (d - a)); 0 within _ORIENT_RTOL of the size."""
    u, v, w = b - a, c - a, d - a
    volume = np.einsum("ni,ni->n", u, np.cross(v, w))
    size = np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1) * np.linalg.norm(w, axis=1)
    return np.where(np.abs(volume) > _ORIENT_RTOL * size, np.sign(volume), 0.0)


def _edge_crosses(p: np.ndarray, q: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(N,) segment p q (N, 3) passes strictly through the inside of triangle tri (N, 3, 3)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    sides = _orient(a, b, c, p) * _orient(a, b, c, q)
    s1, s2, s3 = _orient(p, q, a, b), _orient(p, q, b, c), _orient(p, q, c, a)
    return (sides < 0) & (s1 != 0) & (s1 == s2) & (s2 == s3)


def _faces_cross(tri_i: np.ndarray, tri_j: np.ndarray, face_i: np.ndarray, face_j: np.ndarray) -> np.ndarray:
    """(N,) triangles tri_i and tri_j (N, 3, 3) cross, edges from a vertex they share not tested (see above)."""
    in_j = np.any(face_i[:, :, None] == face_j[:, None, :], axis=2)     # (N, 3): vertex of i also in j
    in_i = np.any(face_j[:, :, None] == face_i[:, None, :], axis=2)
    shared = in_j.sum(axis=1)
    crossing = np.zeros(len(tri_i), dtype=bool)
    for (tri_a, tri_b, free) in ((tri_i, tri_j, ~in_j), (tri_j, tri_i, ~in_i)):
        for k in range(3):
            m = (k + 1) % 3
            usable = free[:, k] & free[:, m] & (shared < 2)
            if np.any(usable):
                idx = np.flatnonzero(usable)
                crossing[idx] |= _edge_crosses(tri_a[idx, k], tri_a[idx, m], tri_b[idx])
    return crossing


def _winding_number(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(Q,) winding number at points (Q, 3) of the closed triangles (F, 3, 3): sum Omega / 4 pi,
    with the solid angle of each triangle from Van Oosterom and Strackee,
    tan(Omega / 2) = a.(b x c) / (|a||b||c| + (a.b)|c| + (b.c)|a| + (c.a)|b|). Compiled: a point against
    every triangle with no temporaries (the overlap check of two meshes of 10^4 faces on a 16^3 grid takes about a
    second, not half a minute)."""
    total = np.zeros(len(points))
    if len(points) and len(triangles):
        _winding_kernel(np.ascontiguousarray(points, dtype=np.float64),
                        np.ascontiguousarray(triangles, dtype=np.float64), total)
    return total


@njit(cache=True)
def _winding_kernel(points, triangles, total):
    for q in range(points.shape[0]):
        px, py, pz = points[q, 0], points[q, 1], points[q, 2]
        angle = 0.0
        for f in range(triangles.shape[0]):
            ax, ay, az = triangles[f, 0, 0] - px, triangles[f, 0, 1] - py, triangles[f, 0, 2] - pz
            bx, by, bz = triangles[f, 1, 0] - px, triangles[f, 1, 1] - py, triangles[f, 1, 2] - pz
            cx, cy, cz = triangles[f, 2, 0] - px, triangles[f, 2, 1] - py, triangles[f, 2, 2] - pz
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            lc = np.sqrt(cx * cx + cy * cy + cz * cz)
            # summed from +0.0 as numpy's einsum sums: a point on a triangle's plane then has numerator +0, and
            # atan2(+0, -|x|) = +pi, so a point on a face counts as inside that face's solid
            numerator = 0.0 + ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
            denominator = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la
                           + (cx * ax + cy * ay + cz * az) * lb)
            angle += 2.0 * np.arctan2(numerator, denominator)
        total[q] = angle / (4 * np.pi)
