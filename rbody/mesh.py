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

from rbody._checks import finite_array, positive
from rbody.inertia import Inertia

# Signed volume below this fraction of the summed |tetrahedron volumes| is round-off: no volume.
_ZERO_VOLUME_RTOL = 1e-10
# Query points per mesh component for the winding-number check, and the chunk of point-face pairs.
_QUERIES_PER_COMPONENT = 3
_PAIRS_PER_CHUNK = 1_000_000


def inertia_from_mesh(mesh: Any, *, density: float | None = None, mass: float | None = None,
                      shell: bool = False) -> Inertia:
    """Mass properties of a triangle mesh: mass, centre of mass and tensor about it.

    mesh:    trimesh.Trimesh (or trimesh.Scene, whose geometry is joined), or a path trimesh can
             load; vertices in the frame the body is given in [m]
    density: uniform density, kg/m^3 for a solid, kg/m^2 for a shell (shell=True) [kg/m^3 | kg/m^2]
    mass:    total mass instead of a density [kg]; give exactly one of density and mass
    shell:   False: the solid the closed surface bounds. True: a thin surface of uniform areal
             density (any mesh, open or closed, wound either way)

    Returns an Inertia with com (3,) in the mesh's frame [m] and tensor (3,3) about it [kg m^2].

    A solid needs a closed (watertight), consistently wound surface with outward faces; otherwise
    ValueError says which and how to repair it. Exactly repeated vertices are merged and faces
    collapsed onto an edge (a repeated vertex index) are dropped: neither changes the body.
    Zero-area faces with three distinct vertices contribute nothing and are kept. A mesh of several
    closed parts may contain cavities (inward-facing inner surfaces); an inside-out part or parts
    that overlap are errors, found from the winding number of the other parts (only parts whose
    bounding boxes overlap are compared).
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
    if shell:
        measure, first, second = _shell_moments(vertices, faces)
    else:
        measure, first, second = _solid_moments(vertices, faces)

    # Uniform density rho: m = rho * measure, and every moment scales with rho.
    rho = density if density is not None else mass / measure
    total = rho * measure
    offset = first / measure                            # centre of mass relative to the vertex mean
    second_com = second - measure * np.outer(offset, offset)
    second_com = rho * 0.5 * (second_com + second_com.T)
    tensor = np.trace(second_com) * np.eye(3) - second_com
    return Inertia(total, vertices.mean(axis=0) + offset, tensor)


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
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(vertices)
    edges = faces[:, [0, 1, 1, 2]].reshape(-1, 2)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    n_parts, vertex_label = connected_components(graph, directed=False)
    if n_parts == 1:
        return
    label = vertex_label[faces[:, 0]]
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


def _winding_number(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(Q,) winding number at points (Q, 3) of the closed triangles (F, 3, 3): sum Omega / 4 pi,
    with the solid angle of each triangle from Van Oosterom and Strackee,
    tan(Omega / 2) = a.(b x c) / (|a||b||c| + (a.b)|c| + (b.c)|a| + (c.a)|b|)."""
    total = np.zeros(len(points))
    chunk = max(1, _PAIRS_PER_CHUNK // max(1, len(triangles)))
    for start in range(0, len(points), chunk):
        rel = triangles[None, :, :, :] - points[start:start + chunk, None, None, :]   # (q, F, 3, 3)
        a, b, c = rel[:, :, 0], rel[:, :, 1], rel[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        numerator = np.einsum("qfi,qfi->qf", a, np.cross(b, c))
        denominator = (la * lb * lc + np.einsum("qfi,qfi->qf", a, b) * lc
                       + np.einsum("qfi,qfi->qf", b, c) * la + np.einsum("qfi,qfi->qf", c, a) * lb)
        total[start:start + chunk] = np.sum(2.0 * np.arctan2(numerator, denominator), axis=1) / (4 * np.pi)
    return total
