"""Height fields (MuJoCo's hfield) against the primitives and meshes, in the rigid limit, compiled.

A height field is MuJoCo's: a grid of nrow x ncol elevations e in [0, 1] (normalised as MuJoCo's compiler does),
in the field geom's frame vertex (r, c) at

    x = c dx - sx,   y = r dy - sy,   z = e[r, c] sz,      dx = 2 sx / (ncol - 1),  dy = 2 sy / (nrow - 1)

(size = (sx, sy, sz, base) [m]), each cell (r, c) split along its diagonal (r, c)-(r+1, c+1) into the triangles
T0 = {(r+1, c), (r, c), (r+1, c+1)} and T1 = {(r, c), (r+1, c+1), (r, c+1)}, as MuJoCo's prisms are
(engine_collision_convex.c, mjc_ConvexHField). The terrain's surface is that triangulated graph.

A geom touches such a surface at a face's interior or at a convex edge (a ridge, or the field's rim); a concave or
flat edge is touched only where its faces are (the feet of a point above a valley lie on its faces). So a geom's
candidates against the field are, for the grid vertices around it:

- faces: each triangle's plane against the geom as a plane would be (rbody.engine.contacts.geometry: a sphere's
  lowest point, a capsule's ends, a box's corners, a cylinder's rim points, a mesh's tilted supports, an ellipsoid's
  lowest point), each kept where its core point's (a sphere's or a capsule end's centre, else the point itself)
  foot on the plane lies inside the triangle (closed; the face's region) or, the core below the plane, where the
  core lies over the triangle (inside the terrain there: below a neighbour's plane beyond a ridge is not), APART
  elsewhere;
- edges: each convex edge (the next triangle's far vertex below this one's plane, or no next triangle: the rim)
  as a capsule of radius 0 against the geom (its closest point and, for a geom lying along it, the ends of the
  span: the capsule pairs' candidates), kept where the normal lies within the edge's wedge of outward normals (an
  edge's interior point) or the closest point is an end (a vertex: a peak).

Every candidate is then an exact distance of a point of the geom from a feature of the surface: the least is never
below the true distance and equals it at the touching feature. An internal prism wall never appears (MuJoCo
collides prisms, whose side walls between cells are inside the terrain; their rigid-limit normals would be
horizontal walls at every cell boundary). A point found twice (a corner over the edge two coplanar triangles share)
is APART after its first slot.

The terrain is a solid, as MuJoCo's prisms are: under the surface down to its base (z = -base), over the rectangle
[-sx, sx] x [-sy, sy]. Its sides are faces too, for a geom beside or under the field: the four walls (x = -+sx,
y = -+sy; each from the base up to the rim, the surface's boundary), the base, the walls' bottom edges and the
vertical edges at the corners. A wall's or the base's candidates are the plane's, kept where the foot lies on the
face (a wall's up to the rim's height there) or, the core point behind the face's plane, where the core lies in
the solid nearer that face than any other (a face's candidate above likewise: a corner at round-off inside a wall
is not 0.2 m under the surface); the edges' as above, their wedges between a wall's outward normal and the next
wall's or the base's. They are computed where the geom's bounding sphere reaches the wall's plane (the base's), so
that a geom over the field's middle costs nothing more.

Slots: the window of (mx + 1) x (my + 1) grid vertices from the cell under the geom's bounding circle's low corner
(mx = floor(2 radius / dx) + 2 cells along x hold any circle of that radius; the table computes them), each vertex
(r, c) owning the faces of cell (r, c) and its three edges (r, c)-(r, c+1), (r, c)-(r+1, c) and the diagonal, in
the slots of its residue (r mod (my + 1), c mod (mx + 1)): a feature keeps its slots while it stays under the geom.
The sides' slots (side_slots) follow the window's: the four walls' and the base's faces, the four bottom edges, the
four vertical edges. Height-field pairs run by the time-stepping only (their candidates change identity as the geom
moves).

The field's record in the params row: [nrow, ncol, sx, sy, sz, base, e (nrow ncol, row-major: e[r ncol + c])].
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.contacts.geometry import (APART, BOX, CAPSULE, CYLINDER, ELLIPSOID, MESH, PLANE, SPHERE,
                                            bounding_radius, collide, tangents)

HFIELD = 1  # MuJoCo's mjGEOM_HFIELD
FIELD_HEADER = 6  # nrow, ncol, sx, sy, sz, base
FIELD_KINDS = (SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH)  # the geoms a height field collides with
CONVEX_TOLERANCE = 1e-12  # an edge folds (is convex) where the far vertex is below the plane by more than this
                          # fraction of the cell's scale; flat edges are not features
WEDGE_TOLERANCE = 1e-12   # [rad]: a normal this far outside an edge's wedge still belongs to the edge
SAME = 1e-12              # [m] and for unit normals: a candidate equal to an earlier one (a point found twice)


@njit(cache=True, inline="always")
def vertex_slots(kind_b):
    """(F, E): a geom's candidates against one triangle's plane (the plane pairs' count) and against one edge (the
    capsule pairs'), for a geom of type kind_b in FIELD_KINDS."""
    if kind_b == SPHERE or kind_b == ELLIPSOID:
        face = 1
    elif kind_b == CAPSULE:
        face = 2
    elif kind_b == MESH:
        face = 9
    else:
        face = 8
    return face, (1 if (kind_b == SPHERE or kind_b == CAPSULE) else 3)


def field_slots(kind_b: int, radius: float, dx: float, dy: float) -> tuple[int, int, int]:
    """(mx, my, slots): the window of cells along x and y that holds the footprint of a geom of type kind_b whose
    bounding sphere has this radius [m] on a field of cell sizes dx, dy [m], and its candidate count."""
    mx = int(np.floor(2.0 * radius / dx)) + 2
    my = int(np.floor(2.0 * radius / dy)) + 2
    face, edge = vertex_slots(kind_b)
    return mx, my, (mx + 1) * (my + 1) * (2 * face + 3 * edge) + side_slots(kind_b)


@njit(cache=True, inline="always")
def side_slots(kind_b):
    """The slots after the window's for the field's sides and base (module docstring): each of the four walls' and
    the base's plane candidates (F each), each wall's bottom edge and each vertical corner edge (E each)."""
    face, edge = vertex_slots(kind_b)
    return 5 * face + 8 * edge


def bounding_radius_of(code: int, size) -> float:
    """The radius [m] of the sphere about a geom's centre that holds it, from its type code and size (3,) [m] as
    the constraint table holds it (geometry.bounding_radius; a mesh: its bounding box's half sizes)."""
    radius = float(bounding_radius(code, np.asarray(size, dtype=np.float64), 0))
    if not np.isfinite(radius):
        raise ValueError(f"geom type {code}: expected a sphere, capsule, ellipsoid, cylinder, box or mesh")
    return radius


def field_candidates(field, kind_b: str, pos_b, mat_b, size_b=(), *, vertices_b=None):
    """The candidate contacts of a height field (an rbody.Shape of kind "hfield", placed in the world at its pos and
    quat) and a geom, for Python callers: (dist (k,) [m], normal (k, 3) from the field to the geom, point (k, 3)
    [m]), the candidates that are contacts in this configuration (the APART slots left out). kind_b: "sphere",
    "capsule", "ellipsoid", "cylinder", "box" or "mesh"; pos_b (3,) [m]; mat_b (3, 3) its axes as columns; size_b
    as collide_pair takes it; vertices_b (V, 3) [m] a mesh's points. Raises ValueError for another kind, a shape
    that is not a height field, or a window of more than MAX_SLOTS candidates."""
    from rbody.engine.contacts.convex import pack_hull
    from rbody.engine.contacts.geometry import MAX_SLOTS, TYPE_CODES
    from rbody.motion import quat_to_matrix

    if getattr(field, "kind", None) != "hfield":
        raise ValueError(f"field={field!r}: expected an rbody.Shape of kind 'hfield'")
    code = TYPE_CODES.get(kind_b, -1)
    if code not in FIELD_KINDS:
        kinds = [kind for kind, c in TYPE_CODES.items() if c in FIELD_KINDS]
        raise ValueError(f"kind_b={kind_b!r}: a height field collides with {kinds}, not it")
    size = np.zeros(3)
    hull = np.empty(0)
    pos, mat = np.asarray(pos_b, dtype=float), np.asarray(mat_b, dtype=float)
    if code == MESH:
        if vertices_b is None:
            raise ValueError("a mesh geom needs its vertices (vertices_b)")
        points = np.asarray(vertices_b, dtype=float)
        low, high = points.min(axis=0), points.max(axis=0)
        centre = 0.5 * (low + high)
        hull, size[:] = pack_hull(points - centre), 0.5 * (high - low)
        pos = pos + mat @ centre  # the table's convention: the frame at the bounding box's centre
    else:
        given = np.atleast_1d(np.asarray(size_b, dtype=float))
        size[:given.size] = given[:3]
    heights = np.asarray(field.heights)
    dx = 2.0 * field.size[0] / (heights.shape[1] - 1)
    dy = 2.0 * field.size[1] / (heights.shape[0] - 1)
    radius = bounding_radius_of(code, size)
    mx, my, count = field_slots(code, radius, dx, dy)
    if count > MAX_SLOTS:
        raise ValueError(f"a {kind_b} of bounding radius {radius:.4g} m spans {mx} x {my} cells of {dx:.4g} x "
                         f"{dy:.4g} m: {count} candidates, more than {MAX_SLOTS}")
    dist, normal, point = np.empty(MAX_SLOTS), np.empty((MAX_SLOTS, 3)), np.empty((MAX_SLOTS, 3))
    collide_field(np.asarray(field.pos, dtype=float), quat_to_matrix(np.asarray(field.quat, dtype=float)),
                  pack_field(heights, field.size), code, pos, mat, size, hull, radius, mx, my, dist, normal, point)
    keep = np.isfinite(dist[:count])
    return dist[:count][keep].copy(), normal[:count][keep].copy(), point[:count][keep].copy()


def pack_field(heights: np.ndarray, size) -> np.ndarray:
    """The field's record (module docstring) from its elevations heights (nrow, ncol) in [0, 1] and size (sx, sy,
    sz, base) [m]."""
    heights = np.asarray(heights, dtype=float)
    return np.concatenate([[heights.shape[0], heights.shape[1], *size], heights.ravel()]).astype(float)


@njit(cache=True, inline="always")
def _grid_point(field, pf, Rf, r, c, z, out):
    """out (3,) [m]: the point over grid vertex (r, c) at height z [m] in the field's frame, in the world (the field
    at pf with axes Rf)."""
    sx, sy = field[2], field[3]
    x = c * (2.0 * sx / (int(field[1]) - 1)) - sx
    y = r * (2.0 * sy / (int(field[0]) - 1)) - sy
    for a in range(3):
        out[a] = pf[a] + Rf[a, 0] * x + Rf[a, 1] * y + Rf[a, 2] * z


@njit(cache=True, inline="always")
def _vertex(field, pf, Rf, r, c, out):
    """out (3,) [m]: grid vertex (r, c) in the world (the field at pf with axes Rf)."""
    _grid_point(field, pf, Rf, r, c, field[FIELD_HEADER + r * int(field[1]) + c] * field[4], out)


@njit(cache=True, inline="always")
def _up_normal(v0, v1, v2, Rf, n):
    """n (3,): the unit normal of the triangle (v0, v1, v2), turned to the field's +z side."""
    e1, e2, f1, f2 = v1[0] - v0[0], v1[1] - v0[1], v2[0] - v0[0], v2[1] - v0[1]
    e3, f3 = v1[2] - v0[2], v2[2] - v0[2]
    n[0], n[1], n[2] = e2 * f3 - e3 * f2, e3 * f1 - e1 * f3, e1 * f2 - e2 * f1
    length = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    if n[0] * Rf[0, 2] + n[1] * Rf[1, 2] + n[2] * Rf[2, 2] < 0.0:
        length = -length
    for a in range(3):
        n[a] /= length


@njit(cache=True)
def _triangle(field, pf, Rf, r, c, which, v0, v1, v2):
    """The vertices of triangle `which` (0: T0, 1: T1) of cell (r, c) (module docstring)."""
    if which == 0:
        _vertex(field, pf, Rf, r + 1, c, v0)
        _vertex(field, pf, Rf, r, c, v1)
        _vertex(field, pf, Rf, r + 1, c + 1, v2)
    else:
        _vertex(field, pf, Rf, r, c, v0)
        _vertex(field, pf, Rf, r + 1, c + 1, v1)
        _vertex(field, pf, Rf, r, c + 1, v2)


@njit(cache=True)
def _inside(field, pf, Rf, r, c, which, x):
    """True when the point x (3,) [m] lies over triangle `which` of cell (r, c) (its xy in the field's frame inside
    the triangle's, edges included)."""
    nrow, ncol = int(field[0]), int(field[1])
    dx, dy = 2.0 * field[2] / (ncol - 1), 2.0 * field[3] / (nrow - 1)
    lx = Rf[0, 0] * (x[0] - pf[0]) + Rf[1, 0] * (x[1] - pf[1]) + Rf[2, 0] * (x[2] - pf[2])
    ly = Rf[0, 1] * (x[0] - pf[0]) + Rf[1, 1] * (x[1] - pf[1]) + Rf[2, 1] * (x[2] - pf[2])
    u = (lx + field[2] - c * dx) / dx  # the cell's own coordinates, [0, 1] each
    v = (ly + field[3] - r * dy) / dy
    if which == 0:  # T0: 0 <= u <= v <= 1
        return u >= 0.0 and v <= 1.0 and u <= v
    return v >= 0.0 and u <= 1.0 and v <= u  # T1: 0 <= v <= u <= 1


@njit(cache=True)
def _height(field, lx, ly):
    """The surface's height [m] in the field's frame over (lx, ly) [m] (clamped to the grid's last cell): its
    cell's triangle, T0 where v >= u, interpolated."""
    nrow, ncol = int(field[0]), int(field[1])
    dx, dy = 2.0 * field[2] / (ncol - 1), 2.0 * field[3] / (nrow - 1)
    c = min(max(int(np.floor((lx + field[2]) / dx)), 0), ncol - 2)
    r = min(max(int(np.floor((ly + field[3]) / dy)), 0), nrow - 2)
    u, v = (lx + field[2] - c * dx) / dx, (ly + field[3] - r * dy) / dy
    at = FIELD_HEADER + r * ncol + c
    z00, z01, z10, z11 = field[at], field[at + 1], field[at + ncol], field[at + ncol + 1]
    if v >= u:
        return field[4] * (z00 + u * (z11 - z10) + v * (z10 - z00))
    return field[4] * (z00 + u * (z01 - z00) + v * (z11 - z01))


@njit(cache=True)
def _local(pf, Rf, x, out):
    """out (3,): the point x (3,) [m] in the field's frame."""
    for a in range(3):
        out[a] = Rf[0, a] * (x[0] - pf[0]) + Rf[1, a] * (x[1] - pf[1]) + Rf[2, a] * (x[2] - pf[2])


@njit(cache=True)
def _nearest_face(field, local, face, own):
    """True when the point (3,) in the field's frame, `own` [m] behind face `face`'s plane (its plane candidate's
    measure of it), lies within every other face of the terrain's solid (boundaries included) and no deeper behind
    any of them: the face a point inside the solid leaves by (0: the surface over it; 1 to 4: the walls x = -sx,
    x = sx, y = -sy, y = sy; 5: the base). The face's own depth is its candidate's, not recomputed, so that the two
    agree at round-off (the surface's height here and its triangle's plane there can differ in the last bit)."""
    depth = (_height(field, local[0], local[1]) - local[2], local[0] + field[2], field[2] - local[0],
             local[1] + field[3], field[3] - local[1], local[2] + field[5])
    for other in range(6):
        if other != face and (depth[other] < 0.0 or depth[other] < own):
            return False
    return True


@njit(cache=True)
def _on_side(field, side, local):
    """True when the point (3,) in the field's frame lies on side `side`'s face, read across it (0 to 3: the walls
    x = -sx, x = sx, y = -sy, y = sy, from the base up to the rim; 4: the base, under the rectangle)."""
    if side == 4:
        return abs(local[0]) <= field[2] and abs(local[1]) <= field[3]
    if local[2] < -field[5]:
        return False
    if side < 2:
        x = field[2] if side == 1 else -field[2]
        return abs(local[1]) <= field[3] and local[2] <= _height(field, x, local[1])
    y = field[3] if side == 3 else -field[3]
    return abs(local[0]) <= field[2] and local[2] <= _height(field, local[0], y)


@njit(cache=True)
def _side_normal(Rf, side, n):
    """n (3,): the outward normal of side `side` (_on_side) in the world."""
    for a in range(3):
        if side == 4:
            n[a] = -Rf[a, 2]
        else:
            n[a] = (1.0 if side % 2 == 1 else -1.0) * Rf[a, side // 2]


@njit(cache=True)
def _corner(field, pf, Rf, sign_x, sign_y, low, out):
    """out (3,) [m]: the field's corner (sign_x sx, sign_y sy) at its base (low) or on its rim (its grid vertex), in
    the world; both over the corner vertex as _vertex places it, so that the vertical edge between them ends where
    the rim's edges end, to the last bit."""
    r = int(field[0]) - 1 if sign_y > 0 else 0
    c = int(field[1]) - 1 if sign_x > 0 else 0
    if low:
        _grid_point(field, pf, Rf, r, c, -field[5], out)
    else:
        _vertex(field, pf, Rf, r, c, out)


@njit(cache=True)
def _edge_sides(field, pf, Rf, r, c, kind, n1, n2, scratch):
    """The outward normals n1, n2 (3,) of the two faces meeting at edge `kind` of vertex (r, c) (0: to (r, c+1), 1:
    to (r+1, c), 2: the diagonal to (r+1, c+1)); the field's rim stands for a missing face, its normal horizontal
    and outward. Returns True where the edge is convex (a ridge, or the rim)."""
    nrow, ncol = int(field[0]), int(field[1])
    v0, v1, v2, p, w = scratch[0:3], scratch[3:6], scratch[6:9], scratch[9:12], scratch[12:15]
    _vertex(field, pf, Rf, r, c, p)
    # the faces on either side: (cell row, cell column, triangle, far vertex row, far vertex column), or the rim
    if kind == 0:
        first = (r, c, 1, r + 1, c + 1) if r <= nrow - 2 else (-1, -1, -1, -1, -1)
        second = (r - 1, c, 0, r - 1, c) if r >= 1 else (-1, -1, -1, -1, -1)
        rim = (0.0, 1.0) if r == nrow - 1 else (0.0, -1.0)
    elif kind == 1:
        first = (r, c, 0, r + 1, c + 1) if c <= ncol - 2 else (-1, -1, -1, -1, -1)
        second = (r, c - 1, 1, r, c - 1) if c >= 1 else (-1, -1, -1, -1, -1)
        rim = (1.0, 0.0) if c == ncol - 1 else (-1.0, 0.0)
    else:
        first = (r, c, 0, r + 1, c)
        second = (r, c, 1, r, c + 1)
        rim = (0.0, 0.0)
    convex = True
    for side in range(2):
        cr, cc, tri, fr, fc = first if side == 0 else second
        out = n1 if side == 0 else n2
        if cr < 0:  # the rim: a wall along the field's edge, its normal outward
            for a in range(3):
                out[a] = Rf[a, 0] * rim[0] + Rf[a, 1] * rim[1]
            continue
        _triangle(field, pf, Rf, cr, cc, tri, v0, v1, v2)
        _up_normal(v0, v1, v2, Rf, out)
    for side in range(2):  # a ridge: each face's far vertex below the other face's plane
        cr, cc, tri, fr, fc = second if side == 0 else first
        if cr < 0:
            continue
        own = n1 if side == 0 else n2
        _vertex(field, pf, Rf, fr, fc, w)
        scale = 2.0 * field[2] / (ncol - 1) + 2.0 * field[3] / (nrow - 1) + field[4]
        if own[0] * (w[0] - p[0]) + own[1] * (w[1] - p[1]) + own[2] * (w[2] - p[2]) > -CONVEX_TOLERANCE * scale:
            convex = False
    return convex


@njit(cache=True)
def _in_wedge(n, u, n1, n2):
    """True when the unit normal n, less its part along the edge's axis u, lies between the faces' normals n1, n2
    (the edge's outward normals) within WEDGE_TOLERANCE."""
    along = n[0] * u[0] + n[1] * u[1] + n[2] * u[2]
    m0, m1, m2 = n[0] - along * u[0], n[1] - along * u[1], n[2] - along * u[2]
    s0 = n1[1] * n2[2] - n1[2] * n2[1]  # the wedge's sense, n1 x n2
    s1 = n1[2] * n2[0] - n1[0] * n2[2]
    s2 = n1[0] * n2[1] - n1[1] * n2[0]
    first = (n1[1] * m2 - n1[2] * m1) * s0 + (n1[2] * m0 - n1[0] * m2) * s1 + (n1[0] * m1 - n1[1] * m0) * s2
    second = (m1 * n2[2] - m2 * n2[1]) * s0 + (m2 * n2[0] - m0 * n2[2]) * s1 + (m0 * n2[1] - m1 * n2[0]) * s2
    scale = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2) * np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    return first >= -WEDGE_TOLERANCE * scale and second >= -WEDGE_TOLERANCE * scale


@njit(cache=True)
def _drop_repeats(dist, normal, point, count):
    """Every finite slot that repeats an earlier one (its distance, point and normal within SAME) made APART: a
    point found twice counts once. Compares the finite slots only (a window's slots are mostly APART)."""
    kept = np.empty(count, dtype=np.int64)
    n = 0
    for k in range(count):
        if dist[k] == APART:
            continue
        repeated = False
        for i in range(n):
            j = kept[i]
            if abs(dist[j] - dist[k]) > SAME:
                continue
            same = True
            for a in range(3):
                if abs(point[j, a] - point[k, a]) > SAME or abs(normal[j, a] - normal[k, a]) > SAME:
                    same = False
            if same:
                repeated = True
                break
        if repeated:
            dist[k] = APART
        else:
            kept[n] = k
            n += 1


@njit(cache=True)
def field_window(field, pf, Rf, pb, radius):
    """(r_lo, c_lo, lowest, lx, ly): the window's first cell row and column (clamped to the grid) for a geom
    centred at pb (3,) [m] with this bounding radius [m] (-1, -1 where its footprint misses the field), the geom's
    lowest height in the field's frame (its centre's less the radius) [m] and its centre's x, y there [m]."""
    nrow, ncol = int(field[0]), int(field[1])
    sx, sy = field[2], field[3]
    dx, dy = 2.0 * sx / (ncol - 1), 2.0 * sy / (nrow - 1)
    lx = Rf[0, 0] * (pb[0] - pf[0]) + Rf[1, 0] * (pb[1] - pf[1]) + Rf[2, 0] * (pb[2] - pf[2])
    ly = Rf[0, 1] * (pb[0] - pf[0]) + Rf[1, 1] * (pb[1] - pf[1]) + Rf[2, 1] * (pb[2] - pf[2])
    lz = Rf[0, 2] * (pb[0] - pf[0]) + Rf[1, 2] * (pb[1] - pf[1]) + Rf[2, 2] * (pb[2] - pf[2])
    if lx + radius < -sx or lx - radius > sx or ly + radius < -sy or ly - radius > sy:
        return -1, -1, lz - radius, lx, ly
    c_lo = min(max(int(np.floor((lx - radius + sx) / dx)), 0), ncol - 2)
    r_lo = min(max(int(np.floor((ly - radius + sy) / dy)), 0), nrow - 2)
    return r_lo, c_lo, lz - radius, lx, ly


@njit(cache=True)
def field_reach(field, pf, Rf, pb, radius):
    """A lower bound [m] on the distance between the field's surface and a geom centred at pb (3,) [m] within the
    bounding radius [m]: its lowest height above the highest vertex under its footprint (window's cells), or its
    distance beside the field's footprint (+inf where its bounding sphere misses the field's rectangle: no wall is
    within its reach; a geom beside the field below its highest vertex there has a bound <= 0, and its walls'
    candidates are computed)."""
    r_lo, c_lo, lowest, lx, ly = field_window(field, pf, Rf, pb, radius)
    return _reach(field, radius, r_lo, c_lo, lowest, lx, ly)


@njit(cache=True)
def _reach(field, radius, r_lo, c_lo, lowest, lx, ly):
    """field_reach from the window field_window gave."""
    if r_lo < 0:
        return np.inf
    nrow, ncol = int(field[0]), int(field[1])
    sx, sy = field[2], field[3]
    dx, dy = 2.0 * sx / (ncol - 1), 2.0 * sy / (nrow - 1)
    c_hi = min(int(np.floor((lx + radius + sx) / dx)) + 1, ncol - 1)
    r_hi = min(int(np.floor((ly + radius + sy) / dy)) + 1, nrow - 1)
    highest = -np.inf
    for r in range(r_lo, r_hi + 1):
        for c in range(c_lo, c_hi + 1):
            highest = max(highest, field[FIELD_HEADER + r * ncol + c])
    return lowest - highest * field[4]


@njit(cache=True)
def _edge_candidates(v0, v1, n1, n2, tb, pb, Rb, sb, hb, k0, dist, normal, point, axis, centre, t1, t2, edge, esize,
                     empty, sub_d, sub_n, sub_p):
    """Geom b's candidates against the convex edge v0-v1 (3,) [m] whose two faces' outward normals are n1, n2, into
    slots k0 on: the edge as a capsule of radius 0 (collide's capsule pairs), a candidate kept where its normal lies
    in the edge's wedge or its closest point is an end (a vertex). The other arrays are scratch."""
    length = 0.0
    for a in range(3):
        axis[a] = v1[a] - v0[a]
        length += axis[a] * axis[a]
    length = np.sqrt(length)
    for a in range(3):
        axis[a] /= length
        centre[a] = 0.5 * (v0[a] + v1[a])
    tangents(axis, t1, t2)
    for a in range(3):
        edge[a, 0], edge[a, 1], edge[a, 2] = t1[a], t2[a], axis[a]
    esize[1] = 0.5 * length
    if tb == SPHERE:  # the sphere is geom a of that pair: its normals turned
        got = collide(SPHERE, pb, Rb, sb, hb, CAPSULE, centre, edge, esize, empty, sub_d, sub_n, sub_p, -1, np.inf)
        for j in range(got):
            for a in range(3):
                sub_n[j, a] = -sub_n[j, a]
    else:
        got = collide(CAPSULE, centre, edge, esize, empty, tb, pb, Rb, sb, hb, sub_d, sub_n, sub_p, -1, np.inf)
    for j in range(got):
        if sub_d[j] == APART:
            continue
        # the edge's point: the stored point (midway) less half the distance along the normal
        t = 0.0
        for a in range(3):
            t += (sub_p[j, a] - 0.5 * sub_d[j] * sub_n[j, a] - v0[a]) * axis[a]
        interior = SAME < t < length - SAME
        if interior and not _in_wedge(sub_n[j], axis, n1, n2):
            continue
        dist[k0 + j] = sub_d[j]
        for a in range(3):
            normal[k0 + j, a], point[k0 + j, a] = sub_n[j, a], sub_p[j, a]


@njit(cache=True)
def _side_candidates(field, pf, Rf, tb, pb, Rb, sb, hb, radius, lowest, lx, ly, k0, dist, normal, point):
    """Geom b's candidates against the field's four walls and its base, their bottom edges and the vertical edges at
    its corners, into the side_slots from k0 (module docstring), each where geom b's bounding sphere (radius [m];
    lowest [m], lx, ly [m] as field_window gives them) reaches it. A face's candidate is kept where its foot lies on
    the face, or, the core point behind the face's plane, where the core lies in the terrain's solid nearer this
    face than any other (_nearest_face)."""
    F, E = vertex_slots(tb)
    reach = (lx - radius <= -field[2], lx + radius >= field[2], ly - radius <= -field[3], ly + radius >= field[3],
             lowest <= -field[5])
    if not (reach[0] or reach[1] or reach[2] or reach[3] or reach[4]):
        return
    core = sb[0] if (tb == SPHERE or tb == CAPSULE) else 0.0
    empty = np.empty(0)
    zero = np.zeros(3)
    n, t1, t2, at, local = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    n2, v0, v1, axis, centre = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    plane, edge = np.empty((3, 3)), np.empty((3, 3))
    esize = np.zeros(3)
    sub_d, sub_n, sub_p = np.empty(17), np.empty((17, 3)), np.empty((17, 3))
    for side in range(5):  # the faces: a plane each, through the side's centre (the base's: under the origin)
        if not reach[side]:
            continue
        _side_normal(Rf, side, n)
        tangents(n, t1, t2)
        for a in range(3):
            plane[a, 0], plane[a, 1], plane[a, 2] = t1[a], t2[a], n[a]
            at[a] = pf[a] + (field[5] * n[a] if side == 4 else
                             (field[2] if side < 2 else field[3]) * n[a])
        got = collide(PLANE, at, plane, zero, empty, tb, pb, Rb, sb, hb, sub_d, sub_n, sub_p, -1, np.inf)
        for j in range(got):
            if sub_d[j] == APART:
                continue
            if sub_d[j] + core < 0.0:  # the core behind the face's plane: a contact only from inside the solid
                for a in range(3):
                    v0[a] = sub_p[j, a] + (sub_d[j] + core) * sub_n[j, a]
                _local(pf, Rf, v0, local)
                if not _nearest_face(field, local, side + 1, -(sub_d[j] + core)):
                    continue
            else:
                _local(pf, Rf, sub_p[j], local)
                if not _on_side(field, side, local):
                    continue
            k = k0 + side * F + j
            dist[k] = sub_d[j]
            for a in range(3):
                normal[k, a], point[k, a] = sub_n[j, a], sub_p[j, a]
    for side in range(4):  # each wall's bottom edge: between it and the base
        if not (reach[side] and reach[4]):
            continue
        sign = 1.0 if side % 2 == 1 else -1.0
        if side < 2:
            _corner(field, pf, Rf, sign, -1.0, True, v0)
            _corner(field, pf, Rf, sign, 1.0, True, v1)
        else:
            _corner(field, pf, Rf, -1.0, sign, True, v0)
            _corner(field, pf, Rf, 1.0, sign, True, v1)
        _side_normal(Rf, side, n)
        _side_normal(Rf, 4, n2)
        _edge_candidates(v0, v1, n, n2, tb, pb, Rb, sb, hb, k0 + 5 * F + side * E, dist, normal, point, axis, centre,
                         t1, t2, edge, esize, empty, sub_d, sub_n, sub_p)
    for corner in range(4):  # the vertical edges where two walls meet, from the base to the rim
        across, along = corner % 2, 2 + corner // 2
        if not (reach[across] and reach[along]):
            continue
        sign_x, sign_y = (1.0 if across == 1 else -1.0), (1.0 if along == 3 else -1.0)
        _corner(field, pf, Rf, sign_x, sign_y, True, v0)
        _corner(field, pf, Rf, sign_x, sign_y, False, v1)
        _side_normal(Rf, across, n)
        _side_normal(Rf, along, n2)
        _edge_candidates(v0, v1, n, n2, tb, pb, Rb, sb, hb, k0 + 5 * F + 4 * E + corner * E, dist, normal, point,
                         axis, centre, t1, t2, edge, esize, empty, sub_d, sub_n, sub_p)


@njit(cache=True)
def collide_field(pf, Rf, field, tb, pb, Rb, sb, hb, radius, mx, my, dist, normal, point, beyond=np.inf):
    """The candidates of a height field (geom a: centre pf (3,) [m], axes Rf (3, 3), its record `field`) and geom b
    (type tb, pose pb, Rb, size sb, hull hb as collide takes them; radius [m] its bounding sphere's) in the window
    mx x my (module docstring) into dist, normal (from the field to the geom) and point; returns their count.
    beyond [m]: where the geom's lowest point is above the window's highest vertex by more, every slot holds that
    bound."""
    F, E = vertex_slots(tb)
    core = sb[0] if (tb == SPHERE or tb == CAPSULE) else 0.0  # the radius about a face candidate's core point
    per = 2 * F + 3 * E
    count = (mx + 1) * (my + 1) * per + side_slots(tb)
    if count > dist.shape[0]:  # the table refuses such a pair (field_slots); never written past the arrays
        return -1
    for k in range(count):
        dist[k] = APART
        for a in range(3):
            normal[k, a] = Rf[a, 2]
            point[k, a] = pb[a]
    r_lo, c_lo, lowest, lx, ly = field_window(field, pf, Rf, pb, radius)
    if r_lo < 0:  # its footprint misses the field's rectangle: nothing within its reach
        return count
    bound = _reach(field, radius, r_lo, c_lo, lowest, lx, ly)
    if bound > beyond:
        for k in range(count):
            dist[k] = bound
        return count
    nrow, ncol = int(field[0]), int(field[1])
    empty = np.empty(0)
    scratch = np.empty(15)
    v0, v1, v2 = np.empty(3), np.empty(3), np.empty(3)
    n1, n2, axis, centre, up = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    local = np.empty(3)
    plane = np.empty((3, 3))
    t1, t2 = np.empty(3), np.empty(3)
    edge = np.empty((3, 3))
    zero = np.zeros(3)
    esize = np.zeros(3)
    sub_d, sub_n, sub_p = np.empty(17), np.empty((17, 3)), np.empty((17, 3))
    for r in range(r_lo, min(r_lo + my, nrow - 1) + 1):
        for c in range(c_lo, min(c_lo + mx, ncol - 1) + 1):
            base = ((r % (my + 1)) * (mx + 1) + c % (mx + 1)) * per
            # faces: cell (r, c)'s two triangles, each plane's candidates with their foot inside it
            if r <= nrow - 2 and c <= ncol - 2 and r < r_lo + my and c < c_lo + mx:
                for which in range(2):
                    _triangle(field, pf, Rf, r, c, which, v0, v1, v2)
                    _up_normal(v0, v1, v2, Rf, up)
                    tangents(up, t1, t2)
                    for a in range(3):
                        plane[a, 0], plane[a, 1], plane[a, 2] = t1[a], t2[a], up[a]
                    got = collide(PLANE, v0, plane, zero, empty, tb, pb, Rb, sb, hb, sub_d, sub_n, sub_p, -1, np.inf)
                    for j in range(got):
                        k = base + which * F + j
                        if sub_d[j] == APART:
                            continue
                        if sub_d[j] + core < 0.0:  # the core point (a sphere's centre, a corner) below the plane:
                            for a in range(3):       # it, over the triangle (inside the terrain there), not its
                                v1[a] = sub_p[j, a] + (sub_d[j] + core) * sub_n[j, a]  # foot (beyond a ridge)
                            if not _inside(field, pf, Rf, r, c, which, v1):
                                continue
                            _local(pf, Rf, v1, local)  # and in the solid, nearer the surface than its sides
                            if not _nearest_face(field, local, 0, -(sub_d[j] + core)):
                                continue
                        elif not _inside(field, pf, Rf, r, c, which, sub_p[j]):
                            continue
                        dist[k] = sub_d[j]
                        for a in range(3):
                            normal[k, a], point[k, a] = sub_n[j, a], sub_p[j, a]
            # edges: (r, c) to (r, c+1), to (r+1, c), to (r+1, c+1), where convex
            for kind in range(3):
                r2 = r + (1 if kind >= 1 else 0)
                c2 = c + (1 if kind != 1 else 0)
                if r2 > min(r_lo + my, nrow - 1) or c2 > min(c_lo + mx, ncol - 1):
                    continue
                if not _edge_sides(field, pf, Rf, r, c, kind, n1, n2, scratch):
                    continue
                _vertex(field, pf, Rf, r, c, v0)
                _vertex(field, pf, Rf, r2, c2, v1)
                _edge_candidates(v0, v1, n1, n2, tb, pb, Rb, sb, hb, base + 2 * F + kind * E, dist, normal, point,
                                 axis, centre, t1, t2, edge, esize, empty, sub_d, sub_n, sub_p)
    _side_candidates(field, pf, Rf, tb, pb, Rb, sb, hb, radius, lowest, lx, ly, (mx + 1) * (my + 1) * per, dist,
                     normal, point)
    _drop_repeats(dist, normal, point, count)  # two coplanar faces' common edge, two edges' common end
    return count


__all__ = ["HFIELD", "FIELD_HEADER", "FIELD_KINDS", "vertex_slots", "side_slots", "field_slots", "pack_field",
           "collide_field", "field_reach", "field_candidates", "bounding_radius_of"]
