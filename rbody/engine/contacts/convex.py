"""The signed distance of two convex geoms, compiled: support functions, GJK for separated geoms, EPA for
overlapping ones, and the signed distance of a point from one geom.

Geoms are given as MuJoCo gives them to its convex collision (engine_collision_convex.c): a type code (the values
of MuJoCo's mjtGeom: SPHERE 2, CAPSULE 3, ELLIPSOID 4, CYLINDER 5, BOX 6, MESH 7), the world position pos (3,) [m]
of the geom's centre, its world orientation mat (3, 3) (columns: the geom's axes), its size (3,) [m] and, for a
mesh, its packed convex hull (pack_hull; an empty array for the other kinds):

    sphere     radius size[0]
    capsule    radius size[0], half-length size[1] of its segment along the geom's z axis
    ellipsoid  semi-axes size[0:3] along the geom's axes
    cylinder   radius size[0], half-length size[1] along the geom's z axis
    box        half sizes size[0:3] along the geom's axes
    mesh       the convex hull of its vertices (given in the geom's frame), size unused

The support function (`support`) of each kind is closed form: a sphere's centre plus r d/|d|, a capsule's end on
the side of d plus r d/|d|, an ellipsoid's diag(s^2) d / |diag(s) d| (local frame), a cylinder's cap on the side
of d and its rim's point r d_xy/|d_xy|, a box's corner sign(d) s. A mesh's is found by hill climbing on the hull's
edge graph (from a vertex, move to the neighbour farthest along d until none is farther: on a convex polytope a
vertex no neighbour improves on is a global maximum, the simplex method's optimality), started from the best of
the hull's SEEDS first vertices (pack_hull puts the extremes along the axes and the cube's diagonals there) or from
a hint (the last support vertex); hulls of at most BRUTE_FORCE vertices are searched whole.

`signed_distance` works on the Minkowski difference C = A - B of the two geoms, whose support along d is
s_A(d) - s_B(-d): the geoms are separated by the distance of the origin from C, and overlap when C holds the
origin, by the distance of the origin from C's boundary (the penetration depth: the shortest translation of B that
separates them is along the outward normal of C's boundary point nearest the origin). Spheres and capsules enter as
their cores, a point and a segment, with their radii subtracted at the end (C's offset by r_a + r_b: its signed
distance from the origin is that of the cores' difference less r_a + r_b, exactly, on both sides of contact), so
they are polytopes like boxes and meshes. Closed forms come first: two spheres or capsules (C is flat, no inside
for EPA) by the closest points of two segments (the interior candidate by cross products, which stay exact however
nearly parallel the segments are, and the 4 ends with the other's clamped projection; the normal their common
perpendicular where they cross inside, normal to a segment whose point is inside it, else the line between the
points; where the cores meet, the direction between the centres across the segments, else the guess, else +z); a
sphere and a box or a cylinder by the centre's closed-form signed distance (point_signed_distance) less the radius.

GJK (Gilbert, Johnson and Keerthi) keeps a simplex of up to 4 points of C and its point v nearest the origin, from
the signed-volumes sub-algorithm (Montanari, Petrinic and Barbieri, ACM ToG 2017: the origin's barycentric
coordinates in the simplex by signed volumes and areas, computed relative to a vertex so that only the simplex's
own size enters the round-off, and the nearest face or edge where one is not positive). Where the nearest point is
inside a segment or a triangle, v itself is the origin's projection on its line or plane, not the weights'
combination: the weights of a thin triangle (two support points of a curved surface close together and a far one:
GJK's simplex near a rim or a cylinder's side) carry a round-off that the combination turns into v's direction,
while the plane's normal, from the triangle's two shortest edges, is exact to round-off in them; a triangle is a
sliver (plane ill-conditioned, its edges taken instead) when its largest angle's sine is below 1e-6. Each step adds
the support point w along -v. |v| is an upper bound on the distance and -n.s_C(n) a lower bound for any unit n (C
lies beyond the plane through s_C(n) normal to n); with n = -v/|v| it is v.w/|v|, and the duality gap
|v| - v.w/|v| ends the iteration:

  - polytope pairs (points, segments, boxes, meshes: the support point is a vertex, named by its index): when w is
    already in the simplex (in exact arithmetic v is then the answer: the support points are finitely many vertices
    and |v| strictly decreases), or the gap is within round-off (ROUNDOFF times the largest coordinate met).
  - curved pairs (an ellipsoid or a cylinder): when the gap is <= CURVED_TOLERANCE * max(1, size scale) [m] (the
    size scale: the largest size of the two geoms; for a mesh the distance of its first hull vertex from its
    origin), or GJK_ITERATIONS steps have run (status ITERATION_LIMIT).

Where a step does not decrease |v| (to round-off) before the gap closes: on a curved surface |v| converges
quadratically faster than its direction, so up to STALL_STEPS such steps are taken (v still turns); the candidate
normals of _certify are tried (v's direction made normal to the simplex's edge, the simplex triangle's normal, a
cylinder's axis near a cap contact, whose support points are rim points and whose triangles turn into slivers, and
the normal made perpendicular to a cylinder's axis near a side contact), and the best certificate may close the
gap; else the next support point is taken along that best normal (near a side contact, the other rim's point at
the current angle, which -v's direction, tilted along the axis by round-off, never reaches), and after STALL_STEPS
GJK starts again from the last support point with a fresh simplex (a sliver's nearest point, or a triangle across
a polytope's nearly coplanar faces, is blurred by round-off), up to GJK_RESTARTS times, and then reports STALLED
with its gap; a gap larger than |v| (the sign of the distance undecided: a thin tetrahedron's signed volumes lose
theirs to round-off) goes to EPA instead, as does a curved pair's |v| within the curved tolerance. The same
candidates pick the final normal: the one whose
certificate -n.s_C(n) is largest, so that the reported gap (|v| less it) bounds the distance and the normal
together. A gap g leaves the normal of a curved pair free by about sqrt(2 g / rho) (rho: the curvature radius of C
where it is nearest the origin, at least the distance), about 1e-6 rad for g = 1e-12 m; for polytope pairs the
normal is a face's, exact to round-off.

When the simplex comes to hold the origin (a tetrahedron with four positive coordinates, or |v| within round-off of
0), the geoms overlap or touch (or, where GJK hands over an undecided sign, lie apart by less than its gap: P below
may then miss the origin by that little, its nearest face one the origin lies outside, of negative offset, and the
least offset is still the depth, negative: a distance), and EPA (the expanding polytope algorithm, van den Bergen)
takes the simplex, grown to a tetrahedron by support points across it where it is smaller, as a polytope P inside C
holding the origin. Its face nearest the origin gives a lower bound on the depth (P lies inside C), the support
along that face's normal an upper bound for that normal (C lies behind the plane through it); the support point is
added to P (the faces it sees removed, the horizon's edges joined to it) until the two meet: within round-off or on
a repeated vertex for polytope pairs, within the curved tolerance otherwise. P lives in fixed arrays, EPA_VERTICES
vertices and EPA_FACES = 2 EPA_VERTICES faces (a closed triangulated surface of V vertices has 2V - 4 faces);
running out is status EPA_CAPACITY, with the result of the last nearest face (a depth that is a lower bound, the gap
reported): deep overlaps about a symmetry (coincident ellipsoids: a ring or a sphere of equally deep directions)
need more vertices than a curved minimum does. For a curved pair EPA's face normal is its support points' plane,
tilted by their round-off over the face's size (5e-13 rad for an ellipsoid touching a box's face): _certify's
flat-face candidates replace it where they certify more (GJK hands a curved pair within its tolerance of touching
to EPA, so a resting ellipsoid's every step ends here).

The result: the signed distance [m] (the distance when separated, minus the depth when overlapping), the unit normal
from geom a towards geom b (the outward normal of C at its boundary point nearest the origin: B moved along it
separates, or moves further away, at unit rate), and the witness points xa, xb on the two surfaces (the barycentric
combination of the final simplex's or face's support points; where the projection falls outside the nearest face,
the coplanar face holding it), xb - xa = dist * normal exactly (a remainder across the normal, round-off or, where a
curved pair's normal was turned from v's direction by theta for a better certificate, |dist| theta, is moved onto
the witness freer to move along the surface, _freedom: an edge's or a face's, or a cylinder's side or cap, rather
than a rim's or a curved surface's, rather than a vertex's; split between two as free). A curved surface (an
ellipsoid, a cylinder's rim) against a face whose normal the result is exactly (a box's face, a mesh's face plane, a
cylinder's cap or side: _certify's candidates) touches at its own support point along the normal, exact, and the
face's witness lies the distance along the normal from it (_place_witnesses), where the combination of support
points spread about the contact would put the point, a torque arm, off by up to sqrt(2 gap rho); on a flat face (not
a cylinder's side, curved about its axis) that distance is the two support points' gap along the normal, exact to
round-off, where |v| or EPA's offset is within the tolerance of it. The optional `info` (INFO,) array
receives the status (CONVERGED 0, ITERATION_LIMIT 1, EPA_CAPACITY 2, STALLED 3: the gap still open after the
restarts, or EPA unable to grow its polytope, BAD_INPUT 4: a mesh without a hull, NaN returned), the iterations of
GJK and of EPA, the final duality gap [m] (0 for the closed forms), and the hint vertices of the two geoms (read as
the hill climbs' starts when >= 0, written with the last support vertices: a caller that keeps info from step to
step warm starts both meshes).

`point_signed_distance` is closed form for spheres, capsules, boxes and cylinders, the largest excess over the face
planes inside a mesh (exact: the nearest boundary point of an inner point is on the nearest face plane), and the
routine above (a point as a sphere of radius 0) outside a mesh and for an ellipsoid.

Kernels are numba-compiled (njit, cache=True) over float64 arrays; GJK's state is a few small arrays allocated once
per call, EPA's polytope fixed arrays allocated once per call that needs it; nothing is allocated per iteration. The
leaf kernels (supports, signed volumes, planes, the closed forms), which allocate nothing, are compiled without
numba's reference counting (_nrt=False): a call that passes arrays otherwise increments and decrements each one's
count, atomically, and those 8 to 10 atomic operations were two thirds of a separated box pair's time.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.core.cpu import CPUTargetOptions

# numba's private option that compiles a kernel without reference counting (module docstring); where a numba
# release drops it, the leaf kernels compile as every other kernel does (slower, the same results)
LEAF = {"_nrt": False} if hasattr(CPUTargetOptions, "_nrt") else {}

SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH = 2, 3, 4, 5, 6, 7

CONVERGED, ITERATION_LIMIT, EPA_CAPACITY, STALLED, BAD_INPUT = 0, 1, 2, 3, 4
STATUS_TEXT = {CONVERGED: "converged", ITERATION_LIMIT: "iteration limit", EPA_CAPACITY: "EPA out of capacity",
               STALLED: "stalled in round-off", BAD_INPUT: "bad input (a mesh without a hull)"}
INFO = 6  # info entries: status, GJK iterations, EPA iterations, gap [m], hint vertex of a, of b

GJK_ITERATIONS = 500  # a guard: polytope pairs end in far fewer steps, curved ones in tens
STALL_STEPS = 16  # GJK steps in a row that keep |v| to round-off (turning it) before a restart
GJK_RESTARTS = 2  # fresh simplices from the last support point after a stall, before STALLED
EPA_VERTICES = 256  # EPA's polytope capacity (vertices), each iteration adds one
EPA_FACES = 2 * EPA_VERTICES  # a closed triangulated surface of V vertices has 2V - 4 faces
CURVED_TOLERANCE = 1e-12  # duality gap [m] per metre of size scale (at least 1 m) for curved pairs
EPS = 2.220446049250313e-16
ROUNDOFF = 16.0 * EPS  # round-off of a support point's coordinate, relative to the largest coordinate met
SEEDS = 14  # a mesh's cold hill climb starts from the best of its first SEEDS hull vertices
BRUTE_FORCE = 16  # hulls of at most this many vertices are searched whole


# ------------------------------------------------------------------------------------------------ support

@njit(cache=True, **LEAF)
def _mesh_support(hull, l0, l1, l2, hint):
    """The index of the hull vertex farthest along the local direction (l0, l1, l2): brute force for at most
    BRUTE_FORCE vertices, else steepest hill climbing on the edge graph from `hint` (< 0: the best seed)."""
    nv = int(hull[0])
    nf = int(hull[1])
    start = 3 + 3 * nv + 4 * nf  # the adjacency starts; the neighbours follow them
    nbr = start + nv + 1
    if nv <= BRUTE_FORCE:
        best, value = 0, -np.inf
        for i in range(nv):
            s = l0 * hull[3 + 3 * i] + l1 * hull[4 + 3 * i] + l2 * hull[5 + 3 * i]
            if s > value:
                best, value = i, s
        return best
    if hint < 0 or hint >= nv:
        best, value = 0, -np.inf
        for i in range(min(SEEDS, nv)):
            s = l0 * hull[3 + 3 * i] + l1 * hull[4 + 3 * i] + l2 * hull[5 + 3 * i]
            if s > value:
                best, value = i, s
    else:
        best = hint
        value = l0 * hull[3 + 3 * best] + l1 * hull[4 + 3 * best] + l2 * hull[5 + 3 * best]
    while True:  # strictly increasing: ends at a vertex no neighbour improves on, a global maximum
        at = best
        for k in range(int(hull[start + at]), int(hull[start + at + 1])):
            j = int(hull[nbr + k])
            s = l0 * hull[3 + 3 * j] + l1 * hull[4 + 3 * j] + l2 * hull[5 + 3 * j]
            if s > value:
                best, value = j, s
        if best == at:
            return best


@njit(cache=True, **LEAF)
def _support(kind, pos, mat, size, hull, d0, d1, d2, core, hint):
    """(x, y, z, index): the world point [m] of the geom (its core when `core`: a sphere's centre, a capsule's
    segment) farthest along the world direction (d0, d1, d2), and the feature's index (a mesh's vertex, a box's
    corner, a capsule's end 0 (+z) or 1, a sphere's centre 0; -1 for a curved surface's point)."""
    l0 = mat[0, 0] * d0 + mat[1, 0] * d1 + mat[2, 0] * d2  # the direction in the geom's axes
    l1 = mat[0, 1] * d0 + mat[1, 1] * d1 + mat[2, 1] * d2
    l2 = mat[0, 2] * d0 + mat[1, 2] * d1 + mat[2, 2] * d2
    x, y, z, index = 0.0, 0.0, 0.0, -1
    radius = 0.0
    if kind == SPHERE:
        index = 0
        radius = size[0]
    elif kind == CAPSULE:
        z = size[1] if l2 >= 0.0 else -size[1]
        index = 0 if l2 >= 0.0 else 1
        radius = size[0]
    elif kind == ELLIPSOID:  # diag(s^2) l / |diag(s) l|: where the outward normal diag(s^-2) x is along l
        q0, q1, q2 = size[0] * l0, size[1] * l1, size[2] * l2
        norm = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
        if norm > 0.0:
            x, y, z = size[0] * q0 / norm, size[1] * q1 / norm, size[2] * q2 / norm
        else:
            x = size[0]
    elif kind == CYLINDER:  # the cap on the side of l, its rim's point along l's radial part
        rho = np.sqrt(l0 * l0 + l1 * l1)
        if rho > 0.0:
            x, y = size[0] * l0 / rho, size[0] * l1 / rho
        z = size[1] if l2 >= 0.0 else -size[1]
    elif kind == BOX:
        x = size[0] if l0 >= 0.0 else -size[0]
        y = size[1] if l1 >= 0.0 else -size[1]
        z = size[2] if l2 >= 0.0 else -size[2]
        index = (1 if l0 >= 0.0 else 0) + (2 if l1 >= 0.0 else 0) + (4 if l2 >= 0.0 else 0)
    elif kind == MESH:
        index = _mesh_support(hull, l0, l1, l2, hint)
        x, y, z = hull[3 + 3 * index], hull[4 + 3 * index], hull[5 + 3 * index]
    w0 = pos[0] + mat[0, 0] * x + mat[0, 1] * y + mat[0, 2] * z
    w1 = pos[1] + mat[1, 0] * x + mat[1, 1] * y + mat[1, 2] * z
    w2 = pos[2] + mat[2, 0] * x + mat[2, 1] * y + mat[2, 2] * z
    if radius > 0.0 and not core:
        norm = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if norm > 0.0:
            w0 += radius * d0 / norm
            w1 += radius * d1 / norm
            w2 += radius * d2 / norm
        index = -1
    return w0, w1, w2, index


@njit(cache=True)
def support(kind, pos, mat, size, hull, d, out, hint=-1):
    """out (3,) [m]: the world point of the geom (kind, centre pos (3,) [m], axes mat (3, 3), size (3,) [m], hull:
    pack_hull's array for a mesh) farthest along the world direction d (3,) (any length > 0). Returns the feature's
    index: a mesh's hull vertex, a box's corner (bits +x, +y, +z), -1 for a point of a curved surface. hint: a mesh's
    hill climb starts there (>= 0; a previous call's answer), else at the best of the hull's seeds."""
    out[0], out[1], out[2], index = _support(kind, pos, mat, size, hull, d[0], d[1], d[2], False, hint)
    return index


@njit(cache=True, **LEAF)
def _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, d0, d1, d2, hints, rows, ids, k):
    """rows[k] (9,): the support point w = a - b of C = A - B along (d0, d1, d2) (rows[k, 0:3]), with a
    (rows[k, 3:6]) the point of A's core farthest along d and b (rows[k, 6:9]) B's along -d; ids[k] their feature
    indices; hints updated. Returns the largest absolute coordinate of a and b (the round-off scale)."""
    a0, a1, a2, ia = _support(ka, pa, Ra, sa, ha, d0, d1, d2, True, hints[0])
    b0, b1, b2, ib = _support(kb, pb, Rb, sb, hb, -d0, -d1, -d2, True, hints[1])
    if ka == MESH:
        hints[0] = ia
    if kb == MESH:
        hints[1] = ib
    ids[k, 0], ids[k, 1] = ia, ib
    rows[k, 0], rows[k, 1], rows[k, 2] = a0 - b0, a1 - b1, a2 - b2
    rows[k, 3], rows[k, 4], rows[k, 5] = a0, a1, a2
    rows[k, 6], rows[k, 7], rows[k, 8] = b0, b1, b2
    return max(abs(a0), abs(a1), abs(a2), abs(b0), abs(b1), abs(b2))


# ------------------------------------------------------------------------------------------------ signed volumes

@njit(cache=True, **LEAF)
def _s1d(s, i, j):
    """(l_i, l_j): the barycentric coordinates of the point of the segment s[i] s[j] nearest the origin (the
    origin's projection on the line, mu = -s_i.e / e.e along e = s_j - s_i, clamped to the segment)."""
    e0, e1, e2 = s[j, 0] - s[i, 0], s[j, 1] - s[i, 1], s[j, 2] - s[i, 2]
    ee = e0 * e0 + e1 * e1 + e2 * e2
    if not ee > 0.0:
        return 1.0, 0.0
    mu = -(s[i, 0] * e0 + s[i, 1] * e1 + s[i, 2] * e2) / ee
    if mu <= 0.0:
        return 1.0, 0.0
    if mu >= 1.0:
        return 0.0, 1.0
    return 1.0 - mu, mu


@njit(cache=True, **LEAF)
def _norm2_of(s, i, li, j, lj, k, lk):
    """|l_i s_i + l_j s_j + l_k s_k|^2."""
    x = li * s[i, 0] + lj * s[j, 0] + lk * s[k, 0]
    y = li * s[i, 1] + lj * s[j, 1] + lk * s[k, 1]
    z = li * s[i, 2] + lj * s[j, 2] + lk * s[k, 2]
    return x * x + y * y + z * z


@njit(cache=True, **LEAF)
def _triangle_normal(s, i, j, k):
    """(n0, n1, n2, sliver): the triangle's normal n = (s_j - s_i) x (s_k - s_i) (|n| twice its area), computed
    from the two edges at the vertex opposite the longest edge: the two shortest, the least round-off (a triangle
    with one short edge, two support points of a curved surface close together, keeps a normal exact to round-off
    in the short edge, where the long edges' product would lose it to cancellation); and whether the triangle is a
    sliver, its largest angle's sine below 1e-6 (three points nearly on a line: the plane is ill-conditioned)."""
    jk = (s[k, 0] - s[j, 0]) ** 2 + (s[k, 1] - s[j, 1]) ** 2 + (s[k, 2] - s[j, 2]) ** 2  # opposite i
    ki = (s[i, 0] - s[k, 0]) ** 2 + (s[i, 1] - s[k, 1]) ** 2 + (s[i, 2] - s[k, 2]) ** 2  # opposite j
    ij = (s[j, 0] - s[i, 0]) ** 2 + (s[j, 1] - s[i, 1]) ** 2 + (s[j, 2] - s[i, 2]) ** 2  # opposite k
    if jk >= ki and jk >= ij:  # (s_j - s_i) x (s_k - s_i) = (s_k - s_j) x (s_i - s_j) = (s_i - s_k) x (s_j - s_k)
        o, p, q, pp, qq = i, j, k, ij, ki
    elif ki >= ij:
        o, p, q, pp, qq = j, k, i, jk, ij
    else:
        o, p, q, pp, qq = k, i, j, ki, jk
    a0, a1, a2 = s[p, 0] - s[o, 0], s[p, 1] - s[o, 1], s[p, 2] - s[o, 2]
    b0, b1, b2 = s[q, 0] - s[o, 0], s[q, 1] - s[o, 1], s[q, 2] - s[o, 2]
    n0 = a1 * b2 - a2 * b1
    n1 = a2 * b0 - a0 * b2
    n2 = a0 * b1 - a1 * b0
    return n0, n1, n2, not n0 * n0 + n1 * n1 + n2 * n2 > 1e-12 * pp * qq


@njit(cache=True, **LEAF)
def _s2d(s, i, j, k):
    """(l_i, l_j, l_k, squared distance): the point of the triangle s[i] s[j] s[k] nearest the origin. The
    origin's projection p = (n.s_i / n.n) n on the plane (n: _triangle_normal) and its barycentric coordinates as
    signed areas, n.((s_k - s_j) x (p - s_j)) / n.n and cyclic (each from an edge and a difference of nearby points:
    only the triangle's size enters the round-off, and a thin triangle's short edge is used as it is, not as the
    difference of two long ones); all positive: p; else the nearest point of the edges opposite a coordinate <= 0
    (all three edges when the triangle is a sliver, whose plane is ill-conditioned)."""
    n0, n1, n2, sliver = _triangle_normal(s, i, j, k)
    nn = n0 * n0 + n1 * n1 + n2 * n2
    li, lj, lk = -1.0, -1.0, -1.0
    best, bi, bj, bk = np.inf, 1.0, 0.0, 0.0
    if nn > 0.0:
        t = (n0 * s[i, 0] + n1 * s[i, 1] + n2 * s[i, 2]) / nn
        p0, p1, p2 = t * n0, t * n1, t * n2
        li = _edge_area(s, j, k, n0, n1, n2, p0, p1, p2) / nn
        lj = _edge_area(s, k, i, n0, n1, n2, p0, p1, p2) / nn
        lk = _edge_area(s, i, j, n0, n1, n2, p0, p1, p2) / nn
        if li > 0.0 and lj > 0.0 and lk > 0.0:
            total = li + lj + lk
            li, lj, lk = li / total, lj / total, lk / total
            if not sliver:
                return li, lj, lk, _norm2_of(s, i, li, j, lj, k, lk)
            best, bi, bj, bk = _norm2_of(s, i, li, j, lj, k, lk), li, lj, lk
    else:
        sliver = True
    if sliver or li <= 0.0:
        x, y = _s1d(s, j, k)
        d = _norm2_of(s, i, 0.0, j, x, k, y)
        if d < best:
            best, bi, bj, bk = d, 0.0, x, y
    if sliver or lj <= 0.0:
        x, y = _s1d(s, i, k)
        d = _norm2_of(s, i, x, j, 0.0, k, y)
        if d < best:
            best, bi, bj, bk = d, x, 0.0, y
    if sliver or lk <= 0.0:
        x, y = _s1d(s, i, j)
        d = _norm2_of(s, i, x, j, y, k, 0.0)
        if d < best:
            best, bi, bj, bk = d, x, y, 0.0
    return bi, bj, bk, best


@njit(cache=True, **LEAF)
def _edge_area(s, j, k, n0, n1, n2, p0, p1, p2):
    """n.((s_k - s_j) x (p - s_j)): twice the signed area of the triangle s_j s_k p (times |n|), the weight of the
    vertex opposite the edge s_j s_k."""
    e0, e1, e2 = s[k, 0] - s[j, 0], s[k, 1] - s[j, 1], s[k, 2] - s[j, 2]
    q0, q1, q2 = p0 - s[j, 0], p1 - s[j, 1], p2 - s[j, 2]
    return n0 * (e1 * q2 - e2 * q1) + n1 * (e2 * q0 - e0 * q2) + n2 * (e0 * q1 - e1 * q0)


@njit(cache=True, **LEAF)
def _nearest_point(s, n):
    """(x, y, z): the point of the simplex s[0:n] (n <= 3) nearest the origin, where it lies inside the simplex
    (every weight positive): the origin's projection on the segment's line or the triangle's plane, whose direction
    is exact to round-off in the simplex's edges, where the weights' combination would carry their round-off (a thin
    triangle's: the curved pair's normal turned by it); a sliver's, by its weights, is left to the caller (NaN)."""
    if n == 1:
        return s[0, 0], s[0, 1], s[0, 2]
    if n == 2:
        e0, e1, e2 = s[1, 0] - s[0, 0], s[1, 1] - s[0, 1], s[1, 2] - s[0, 2]
        mu = -(s[0, 0] * e0 + s[0, 1] * e1 + s[0, 2] * e2) / (e0 * e0 + e1 * e1 + e2 * e2)
        return s[0, 0] + mu * e0, s[0, 1] + mu * e1, s[0, 2] + mu * e2
    n0, n1, n2, sliver = _triangle_normal(s, 0, 1, 2)
    if sliver:
        return np.nan, np.nan, np.nan
    t = (n0 * s[0, 0] + n1 * s[0, 1] + n2 * s[0, 2]) / (n0 * n0 + n1 * n1 + n2 * n2)
    return t * n0, t * n1, t * n2


@njit(cache=True, **LEAF)
def _det(a0, a1, a2, b0, b1, b2, c0, c1, c2):
    """det[a, b, c] = a . (b x c)."""
    return a0 * (b1 * c2 - b2 * c1) + a1 * (b2 * c0 - b0 * c2) + a2 * (b0 * c1 - b1 * c0)


@njit(cache=True, **LEAF)
def _s3d(s, lam):
    """lam (4,): the barycentric coordinates of the point of the tetrahedron s[0:4] nearest the origin; returns
    True when that is the origin itself, inside (all four signed volumes of the origin with a face, relative to
    the tetrahedron's, positive), else the nearest point of the faces opposite a coordinate <= 0 (all four when the
    tetrahedron is flat to 1e-10 of its edges' product)."""
    e10, e11, e12 = s[1, 0] - s[0, 0], s[1, 1] - s[0, 1], s[1, 2] - s[0, 2]
    e20, e21, e22 = s[2, 0] - s[0, 0], s[2, 1] - s[0, 1], s[2, 2] - s[0, 2]
    e30, e31, e32 = s[3, 0] - s[0, 0], s[3, 1] - s[0, 1], s[3, 2] - s[0, 2]
    vol = _det(e10, e11, e12, e20, e21, e22, e30, e31, e32)
    size = np.sqrt((e10 * e10 + e11 * e11 + e12 * e12) * (e20 * e20 + e21 * e21 + e22 * e22)
                   * (e30 * e30 + e31 * e31 + e32 * e32))
    flat = not abs(vol) > 1e-10 * size
    c0 = c1 = c2 = c3 = -1.0
    if not flat:
        # the origin replacing vertex i: det of the edges from the origin's place, over the volume
        f10, f11, f12 = s[2, 0] - s[1, 0], s[2, 1] - s[1, 1], s[2, 2] - s[1, 2]
        f20, f21, f22 = s[3, 0] - s[1, 0], s[3, 1] - s[1, 1], s[3, 2] - s[1, 2]
        c0 = _det(s[1, 0], s[1, 1], s[1, 2], f10, f11, f12, f20, f21, f22) / vol
        c1 = _det(-s[0, 0], -s[0, 1], -s[0, 2], e20, e21, e22, e30, e31, e32) / vol
        c2 = _det(e10, e11, e12, -s[0, 0], -s[0, 1], -s[0, 2], e30, e31, e32) / vol
        c3 = _det(e10, e11, e12, e20, e21, e22, -s[0, 0], -s[0, 1], -s[0, 2]) / vol
        if c0 > 0.0 and c1 > 0.0 and c2 > 0.0 and c3 > 0.0:
            total = c0 + c1 + c2 + c3
            lam[0], lam[1], lam[2], lam[3] = c0 / total, c1 / total, c2 / total, c3 / total
            return True
    best = np.inf
    for i in range(4):
        ci = c0 if i == 0 else (c1 if i == 1 else (c2 if i == 2 else c3))
        if not (flat or ci <= 0.0):
            continue
        a, b, d = (i + 1) % 4, (i + 2) % 4, (i + 3) % 4
        x, y, z, dist = _s2d(s, a, b, d)
        if dist < best:
            best = dist
            lam[i], lam[a], lam[b], lam[d] = 0.0, x, y, z
    return False


# ------------------------------------------------------------------------------------------------ EPA

@njit(cache=True, **LEAF)
def _face_plane(vert, fv, planes, f):
    """planes[f] = (n, d): the unit normal of face f (vertices fv[f], counter-clockwise seen from outside;
    _triangle_normal's) and its offset (the mean of n.v over its vertices); returns False for a face of no area."""
    i, j, k = fv[f, 0], fv[f, 1], fv[f, 2]
    n0, n1, n2, _sliver = _triangle_normal(vert, i, j, k)
    length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not length > 0.0:
        return False
    n0, n1, n2 = n0 / length, n1 / length, n2 / length
    d = 0.0
    for v in (i, j, k):
        d += n0 * vert[v, 0] + n1 * vert[v, 1] + n2 * vert[v, 2]
    planes[f, 0], planes[f, 1], planes[f, 2], planes[f, 3] = n0, n1, n2, d / 3.0
    return True


@njit(cache=True, **LEAF)
def _face_weights(vert, fv, f, n0, n1, n2, p0, p1, p2):
    """(l0, l1, l2): the barycentric coordinates of the point p (in face f's plane, unit normal n) in face f, as
    signed areas n.((v_k - v_j) x (p - v_j)) (_edge_area) over their sum (thirds for a face of no area)."""
    l0 = l1 = l2 = 0.0
    for m in range(3):
        area = _edge_area(vert, fv[f, (m + 1) % 3], fv[f, (m + 2) % 3], n0, n1, n2, p0, p1, p2)
        if m == 0:
            l0 = area
        elif m == 1:
            l1 = area
        else:
            l2 = area
    total = l0 + l1 + l2
    if total == 0.0:
        return 1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0
    return l0 / total, l1 / total, l2 / total


@njit(cache=True, **LEAF)
def _face_result(vert, vid, fv, planes, state, high, f, floor, normal, xa, xb, ids):
    """normal, xa, xb (3,): face f's normal and the witness points of the origin's projection d n on it (its
    barycentric coordinates applied to the vertices' A and B points), ids[0:3] the features of the face they come
    from (for _place_witnesses, once EPA ends); returns the depth d. Where the projection falls outside f (a tie:
    P's faces coplanar on a flat face of C, two boxes face to face), the witnesses are taken from the coplanar live
    face (within `floor`) that holds it, so that they lie on the surfaces."""
    n0, n1, n2, d = planes[f, 0], planes[f, 1], planes[f, 2], planes[f, 3]
    p0, p1, p2 = d * n0, d * n1, d * n2
    l0, l1, l2 = _face_weights(vert, fv, f, n0, n1, n2, p0, p1, p2)
    face = f
    worst = min(l0, l1, l2)
    if worst < -1e-12:
        for g in range(high):
            if g == f or state[g] != 1 or abs(planes[g, 3] - d) > floor \
                    or planes[g, 0] * n0 + planes[g, 1] * n1 + planes[g, 2] * n2 < 1.0 - 1e-12:
                continue
            m0, m1, m2 = _face_weights(vert, fv, g, n0, n1, n2, p0, p1, p2)
            if min(m0, m1, m2) > worst:
                worst, face, l0, l1, l2 = min(m0, m1, m2), g, m0, m1, m2
    for a in range(3):
        xa[a] = 0.0
        xb[a] = 0.0
    for m in range(3):
        v = fv[face, m]
        weight = l0 if m == 0 else (l1 if m == 1 else l2)
        for a in range(3):
            xa[a] += weight * vert[v, 3 + a]
            xb[a] += weight * vert[v, 6 + a]
    normal[0], normal[1], normal[2] = n0, n1, n2
    for m in range(3):
        ids[m, 0], ids[m, 1] = vid[fv[face, m], 0], vid[fv[face, m], 1]
    return d


@njit(cache=True)
def _grow_simplex(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, vert, vid, n, hints, floor):
    """Grows the simplex vert[0:n] (n < 4, holding the origin within round-off) to a tetrahedron with support
    points across it: the farthest from the first vertex along the 6 axis directions, from the segment's line
    along 4 directions perpendicular to it, from the triangle's plane along its normal on the origin's side (the
    other when C is flat on that side). Returns the largest coordinate met, or -1 when C is flat (no point of C
    more than `floor` off the simplex)."""
    big = 0.0
    tmp = np.empty((2, 9))
    tid = np.empty((2, 2), np.int64)
    while n < 4:
        best, found = floor, False
        if n == 1:
            for axis in range(6):
                sign = 1.0 if axis < 3 else -1.0
                d0 = sign if axis % 3 == 0 else 0.0
                d1 = sign if axis % 3 == 1 else 0.0
                d2 = sign if axis % 3 == 2 else 0.0
                big = max(big, _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, d0, d1, d2, hints, tmp, tid, 0))
                dist = np.sqrt((tmp[0, 0] - vert[0, 0]) ** 2 + (tmp[0, 1] - vert[0, 1]) ** 2
                               + (tmp[0, 2] - vert[0, 2]) ** 2)
                if dist > best:
                    best, found = dist, True
                    tmp[1, :] = tmp[0, :]
                    tid[1, :] = tid[0, :]
        elif n == 2:
            e0, e1, e2 = vert[1, 0] - vert[0, 0], vert[1, 1] - vert[0, 1], vert[1, 2] - vert[0, 2]
            length = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            e0, e1, e2 = e0 / length, e1 / length, e2 / length
            # a unit vector across the segment: e crossed with the axis least along it
            if abs(e0) <= abs(e1) and abs(e0) <= abs(e2):
                u0, u1, u2 = 0.0, e2, -e1
            elif abs(e1) <= abs(e2):
                u0, u1, u2 = -e2, 0.0, e0
            else:
                u0, u1, u2 = e1, -e0, 0.0
            length = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
            u0, u1, u2 = u0 / length, u1 / length, u2 / length
            w0, w1, w2 = e1 * u2 - e2 * u1, e2 * u0 - e0 * u2, e0 * u1 - e1 * u0
            for m in range(4):
                sign = 1.0 if m < 2 else -1.0
                if m % 2 == 0:
                    d0, d1, d2 = sign * u0, sign * u1, sign * u2
                else:
                    d0, d1, d2 = sign * w0, sign * w1, sign * w2
                big = max(big, _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, d0, d1, d2, hints, tmp, tid, 0))
                r0, r1, r2 = tmp[0, 0] - vert[0, 0], tmp[0, 1] - vert[0, 1], tmp[0, 2] - vert[0, 2]
                along = r0 * e0 + r1 * e1 + r2 * e2
                dist = np.sqrt(max(r0 * r0 + r1 * r1 + r2 * r2 - along * along, 0.0))
                if dist > best:
                    best, found = dist, True
                    tmp[1, :] = tmp[0, :]
                    tid[1, :] = tid[0, :]
        else:
            a0, a1, a2 = vert[1, 0] - vert[0, 0], vert[1, 1] - vert[0, 1], vert[1, 2] - vert[0, 2]
            b0, b1, b2 = vert[2, 0] - vert[0, 0], vert[2, 1] - vert[0, 1], vert[2, 2] - vert[0, 2]
            n0, n1, n2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
            length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            if not length > 0.0:
                return -1.0
            n0, n1, n2 = n0 / length, n1 / length, n2 / length
            side = -(n0 * vert[0, 0] + n1 * vert[0, 1] + n2 * vert[0, 2])  # the origin's height
            first = 1.0 if side >= 0.0 else -1.0
            for sign in (first, -first):
                big = max(big, _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, sign * n0, sign * n1,
                                          sign * n2, hints, tmp, tid, 0))
                height = sign * (n0 * (tmp[0, 0] - vert[0, 0]) + n1 * (tmp[0, 1] - vert[0, 1])
                                 + n2 * (tmp[0, 2] - vert[0, 2]))
                if height > floor:
                    best, found = height, True
                    tmp[1, :] = tmp[0, :]
                    tid[1, :] = tid[0, :]
                    break
        if not found:
            return -1.0
        vert[n, :] = tmp[1, :]
        vid[n, :] = tid[1, :]
        n += 1
    return big


@njit(cache=True)
def _epa(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, simp, ids, n, tol, polytope, big, hints, normal, xa, xb, out):
    """The penetration depth [m] of the cores (C = A - B holding the origin), from GJK's final simplex simp[0:n]
    (rows w, a, b; ids their features): normal, xa, xb (3,) as signed_distance's for the cores, the witnesses the
    last face's weights' combinations, its features in ids[0:3] (untouched where NaN is returned); out (3,): status,
    iterations, duality gap [m]. Returns NaN when no polytope can be built (C flat about the origin)."""
    nv_max, nf_max = EPA_VERTICES, EPA_FACES
    vert = np.empty((nv_max + 1, 9))  # the last row: the candidate support point when P is full
    vid = np.empty((nv_max + 1, 2), np.int64)
    for i in range(n):
        vert[i, :] = simp[i, :]
        vid[i, :] = ids[i, :]
    out[0], out[1], out[2] = CONVERGED, 0.0, 0.0
    floor = ROUNDOFF * big
    if n < 4:
        grown = _grow_simplex(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, vert, vid, n, hints, floor)
        if grown < 0.0:
            return np.nan
        big = max(big, grown)
    # orient the tetrahedron: vertex 3 on the side of (v1 - v0) x (v2 - v0)
    vol = _det(vert[1, 0] - vert[0, 0], vert[1, 1] - vert[0, 1], vert[1, 2] - vert[0, 2],
               vert[2, 0] - vert[0, 0], vert[2, 1] - vert[0, 1], vert[2, 2] - vert[0, 2],
               vert[3, 0] - vert[0, 0], vert[3, 1] - vert[0, 1], vert[3, 2] - vert[0, 2])
    if vol == 0.0:
        return np.nan
    if vol < 0.0:
        for a in range(9):
            vert[1, a], vert[2, a] = vert[2, a], vert[1, a]
        for a in range(2):
            vid[1, a], vid[2, a] = vid[2, a], vid[1, a]
    fv = np.empty((nf_max, 3), np.int64)  # face vertices, counter-clockwise seen from outside
    adj = np.empty((nf_max, 3), np.int64)  # the face across edge m (fv[m] -> fv[m + 1])
    planes = np.empty((nf_max, 4))
    state = np.empty(nf_max, np.int64)  # 0 free, 1 live, 2 seen from the new vertex (faces below `high`)
    free = np.empty(nf_max, np.int64)
    horizon = np.empty((nf_max, 3), np.int64)  # u, v (the edge as in the removed face), the face across
    stack = np.empty(nf_max, np.int64)
    starts = np.empty(nv_max + 1, np.int64)  # the new face whose horizon edge starts at a vertex (-1: none)
    ends = np.empty(nv_max + 1, np.int64)  # ... ends at it
    for i in range(4):
        starts[i], ends[i] = -1, -1
    tetra = ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3))
    links = ((2, 3, 1), (0, 3, 2), (1, 3, 0), (0, 2, 1))
    for f in range(4):
        for m in range(3):
            fv[f, m] = tetra[f][m]
            adj[f, m] = links[f][m]
        if not _face_plane(vert, fv, planes, f):
            return np.nan
        state[f] = 1
    high, nfree, nv = 4, 0, 4
    depth = 0.0
    for iteration in range(nv_max + 1):
        out[1] = iteration
        closest, lower = -1, np.inf
        for f in range(high):
            if state[f] == 1 and planes[f, 3] < lower:
                closest, lower = f, planes[f, 3]
        depth = _face_result(vert, vid, fv, planes, state, high, closest, floor, normal, xa, xb, ids)
        n0, n1, n2 = planes[closest, 0], planes[closest, 1], planes[closest, 2]
        big = max(big, _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, n0, n1, n2, hints, vert, vid, nv))
        floor = ROUNDOFF * big
        height = n0 * vert[nv, 0] + n1 * vert[nv, 1] + n2 * vert[nv, 2]  # C's support along the normal: an upper bound
        # the face's own certificate, depth in [lower, height], so that its normal is the one certified (a
        # smaller support along another direction bounds the depth, not this normal)
        out[2] = max(height - lower, 0.0)
        if height - lower <= max(tol, floor):
            return depth
        if polytope:  # a vertex already in P: no progress is possible
            for i in range(nv):
                if vid[i, 0] == vid[nv, 0] and vid[i, 1] == vid[nv, 1]:
                    return depth
        if nv == nv_max:
            out[0] = EPA_CAPACITY
            return depth
        # the faces the new point sees (a connected cap from the closest face), and the horizon around them
        state[closest] = 2
        stack[0] = closest
        top, nh, nseen = 1, 0, 1
        broken = False
        while top > 0:
            top -= 1
            f = stack[top]
            for m in range(3):
                g = adj[f, m]
                if state[g] == 2:
                    continue
                if planes[g, 0] * vert[nv, 0] + planes[g, 1] * vert[nv, 1] + planes[g, 2] * vert[nv, 2] \
                        - planes[g, 3] > floor:
                    state[g] = 2
                    stack[top] = g
                    top += 1
                    nseen += 1
                else:
                    if nh == nf_max:
                        broken = True
                        break
                    horizon[nh, 0], horizon[nh, 1], horizon[nh, 2] = fv[f, m], fv[f, (m + 1) % 3], g
                    nh += 1
            if broken:
                break
        # the horizon must be one loop: each vertex starts one edge and ends one
        if not broken:
            for h in range(nh):
                u, v = horizon[h, 0], horizon[h, 1]
                if starts[u] != -1 or ends[v] != -1:
                    broken = True
                starts[u] = h
                ends[v] = h
            for h in range(nh):
                starts[horizon[h, 0]] = -1
                ends[horizon[h, 1]] = -1
        full = nh == nf_max or nh > nseen + nfree + (nf_max - high)
        if broken or full:
            for f in range(high):
                if state[f] == 2:
                    state[f] = 1
            out[0] = EPA_CAPACITY if full else STALLED
            return depth
        # commit: the new vertex (row nv), the seen faces freed, a face on each horizon edge
        for f in range(high):
            if state[f] == 2:
                state[f] = 0
                free[nfree] = f
                nfree += 1
        for h in range(nh):
            if nfree > 0:
                nfree -= 1
                f = free[nfree]
            else:
                f = high
                high += 1
            u, v, g = horizon[h, 0], horizon[h, 1], horizon[h, 2]
            fv[f, 0], fv[f, 1], fv[f, 2] = u, v, nv
            state[f] = 1
            adj[f, 0] = g
            for m in range(3):  # the neighbour's edge v -> u now borders the new face
                if adj[g, m] >= 0 and fv[g, m] == v and fv[g, (m + 1) % 3] == u:
                    adj[g, m] = f
            starts[u] = f
            ends[v] = f
            horizon[h, 2] = f  # reused: the new face of this edge
        degenerate = False
        for h in range(nh):
            f = horizon[h, 2]
            u, v = horizon[h, 0], horizon[h, 1]
            adj[f, 1] = starts[v]  # edge v -> w borders the new face starting at v (its edge w -> v)
            adj[f, 2] = ends[u]  # edge w -> u borders the new face ending at u (its edge u -> w)
            if not _face_plane(vert, fv, planes, f):
                degenerate = True
        for h in range(nh):
            starts[horizon[h, 0]] = -1
            ends[horizon[h, 1]] = -1
        starts[nv], ends[nv] = -1, -1  # the new vertex's: on no horizon yet
        nv += 1
        if degenerate:  # a new face of no area (the new point on a horizon edge's line): keep the last result
            out[0] = STALLED
            return depth
    out[0] = ITERATION_LIMIT
    return depth


# ------------------------------------------------------------------------------------------------ GJK

@njit(cache=True, **LEAF)
def _size_scale(kind, size, hull):
    """A geom's size [m] for the curved tolerance: its largest size, a mesh's first hull vertex's distance from
    its origin."""
    if kind == MESH:
        return np.sqrt(hull[3] * hull[3] + hull[4] * hull[4] + hull[5] * hull[5])
    if kind == SPHERE:
        return size[0]
    if kind == CAPSULE or kind == CYLINDER:
        return max(size[0], size[1])
    return max(size[0], size[1], size[2])


@njit(cache=True)
def _flat_normal(ka, pa, Ra, kb, pb, Rb, g0, g1, g2, normal):
    """normal (3,): the direction chosen where two cores without an inside (points, segments) cross: the common
    perpendicular of two crossing segments (towards b), else the first of pb - pa, the guess, x, y, z with a part
    across the segments."""
    ua = np.zeros(3)
    ub = np.zeros(3)
    if ka == CAPSULE:
        ua[0], ua[1], ua[2] = Ra[0, 2], Ra[1, 2], Ra[2, 2]
    if kb == CAPSULE:
        ub[0], ub[1], ub[2] = Rb[0, 2], Rb[1, 2], Rb[2, 2]
    c0, c1, c2 = ua[1] * ub[2] - ua[2] * ub[1], ua[2] * ub[0] - ua[0] * ub[2], ua[0] * ub[1] - ua[1] * ub[0]
    length = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if length > 1e-12:
        sign = 1.0 if c0 * (pb[0] - pa[0]) + c1 * (pb[1] - pa[1]) + c2 * (pb[2] - pa[2]) >= 0.0 else -1.0
        normal[0], normal[1], normal[2] = sign * c0 / length, sign * c1 / length, sign * c2 / length
        return
    # ub orthogonalised against ua (parallel segments: one direction to remove)
    dot = ua[0] * ub[0] + ua[1] * ub[1] + ua[2] * ub[2]
    for a in range(3):
        ub[a] -= dot * ua[a]
    length = np.sqrt(ub[0] * ub[0] + ub[1] * ub[1] + ub[2] * ub[2])
    if length > 1e-12:
        for a in range(3):
            ub[a] /= length
    else:
        ub[:] = 0.0
    for candidate in range(5):
        if candidate == 0:
            c0, c1, c2 = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
        elif candidate == 1:
            c0, c1, c2 = g0, g1, g2
        else:
            c0, c1, c2 = (1.0 if candidate == 2 else 0.0), (1.0 if candidate == 3 else 0.0), \
                (1.0 if candidate == 4 else 0.0)
        size = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        for u in (ua, ub):
            dot = c0 * u[0] + c1 * u[1] + c2 * u[2]
            c0, c1, c2 = c0 - dot * u[0], c1 - dot * u[1], c2 - dot * u[2]
        length = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        if length > 1e-9 * size and length > 0.0:
            normal[0], normal[1], normal[2] = c0 / length, c1 / length, c2 / length
            return
    normal[0], normal[1], normal[2] = 0.0, 0.0, 1.0


@njit(cache=True, **LEAF)
def _segment_pair(p, u, l1, q, w, l2):
    """(s, t, interior): the parameters of the closest points p + s u and q + t w of two segments (centres p, q,
    unit directions u, w, half-lengths l1, l2 >= 0), and whether both are inside their segments at the lines'
    common perpendicular. That candidate is solved with the cross product n = u x w, s = ((q - p) x w).n / n.n,
    t = ((q - p) x u).n / n.n, whose round-off along nearly parallel segments moves both points alike (Ericson's
    1 - (u.w)^2 loses every digit below an angle of 1e-8); then the 4 ends, each with the other's clamped
    projection, and the least of them all."""
    r0, r1, r2 = q[0] - p[0], q[1] - p[1], q[2] - p[2]
    n0, n1, n2 = u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]
    nn = n0 * n0 + n1 * n1 + n2 * n2
    best, bs, bt, interior = np.inf, 0.0, 0.0, False
    if nn > 0.0:
        s = ((r1 * w[2] - r2 * w[1]) * n0 + (r2 * w[0] - r0 * w[2]) * n1 + (r0 * w[1] - r1 * w[0]) * n2) / nn
        t = ((r1 * u[2] - r2 * u[1]) * n0 + (r2 * u[0] - r0 * u[2]) * n1 + (r0 * u[1] - r1 * u[0]) * n2) / nn
        if abs(s) <= l1 and abs(t) <= l2:
            d0, d1, d2 = s * u[0] - t * w[0] - r0, s * u[1] - t * w[1] - r1, s * u[2] - t * w[2] - r2
            best, bs, bt, interior = d0 * d0 + d1 * d1 + d2 * d2, s, t, True
    for k in range(4):
        if k < 2:  # an end of the first, the second's point nearest it
            s = l1 if k == 0 else -l1
            t = min(max(s * (u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) - (r0 * w[0] + r1 * w[1] + r2 * w[2]), -l2),
                    l2)
        else:
            t = l2 if k == 2 else -l2
            s = min(max(t * (u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) + (r0 * u[0] + r1 * u[1] + r2 * u[2]), -l1),
                    l1)
        d0, d1, d2 = s * u[0] - t * w[0] - r0, s * u[1] - t * w[1] - r1, s * u[2] - t * w[2] - r2
        dd = d0 * d0 + d1 * d1 + d2 * d2
        if dd < best:
            best, bs, bt, interior = dd, s, t, False
    return bs, bt, interior


@njit(cache=True)
def _cores_closed_form(ka, pa, Ra, sa, kb, pb, Rb, sb, g0, g1, g2, normal, xa, xb):
    """The signed distance of two spheres or capsules: their cores' closest points (_segment_pair; a sphere a
    segment of length 0) less the radii. The normal: the common perpendicular where two segments cross inside
    (exact as a cross product, however near the cores come), else the line between the closest points, else
    (cores meeting at an end) _flat_normal."""
    u = np.zeros(3)
    w = np.zeros(3)
    la = sa[1] if ka == CAPSULE else 0.0
    lb = sb[1] if kb == CAPSULE else 0.0
    for a in range(3):
        u[a] = Ra[a, 2] if ka == CAPSULE else 0.0
        w[a] = Rb[a, 2] if kb == CAPSULE else 0.0
    s, t, interior = _segment_pair(pa, u, la, pb, w, lb)
    c0, c1, c2 = u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]
    length = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if not (interior and length > 0.0):
        # one alternating pass: the second's point nearest the first's, then the first's nearest that (parallel
        # segments tie along their overlap, to round-off, and a tie at two ends is not the nearest pair)
        t = min(max((pa[0] + s * u[0] - pb[0]) * w[0] + (pa[1] + s * u[1] - pb[1]) * w[1]
                    + (pa[2] + s * u[2] - pb[2]) * w[2], -lb), lb)
        s = min(max((pb[0] + t * w[0] - pa[0]) * u[0] + (pb[1] + t * w[1] - pa[1]) * u[1]
                    + (pb[2] + t * w[2] - pa[2]) * u[2], -la), la)
    for a in range(3):
        xa[a] = pa[a] + s * u[a]
        xb[a] = pb[a] + t * w[a]
    d0, d1, d2 = xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]
    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if interior and length > 0.0:
        side = c0 * d0 + c1 * d1 + c2 * d2
        if side == 0.0:
            side = c0 * (pb[0] - pa[0]) + c1 * (pb[1] - pa[1]) + c2 * (pb[2] - pa[2])
        if side < 0.0:
            length = -length
        normal[0], normal[1], normal[2] = c0 / length, c1 / length, c2 / length
    elif dist > ROUNDOFF * (max(abs(pa[0]), abs(pa[1]), abs(pa[2]), abs(pb[0]), abs(pb[1]), abs(pb[2])) + la + lb):
        # the line between the points, normal to a segment where its point is inside it (optimality: the part
        # along it is round-off, which the segment's length would turn into a wrong certificate)
        e0, e1, e2 = d0, d1, d2
        if abs(s) < la:
            along = e0 * u[0] + e1 * u[1] + e2 * u[2]
            e0, e1, e2 = e0 - along * u[0], e1 - along * u[1], e2 - along * u[2]
        if abs(t) < lb:
            q0, q1, q2 = w[0], w[1], w[2]
            if abs(s) < la:  # w across u
                along = q0 * u[0] + q1 * u[1] + q2 * u[2]
                q0, q1, q2 = q0 - along * u[0], q1 - along * u[1], q2 - along * u[2]
            qq = q0 * q0 + q1 * q1 + q2 * q2
            if qq > 1e-20:
                along = (e0 * q0 + e1 * q1 + e2 * q2) / qq
                e0, e1, e2 = e0 - along * q0, e1 - along * q1, e2 - along * q2
        size = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if size > 0.5 * dist:
            normal[0], normal[1], normal[2] = e0 / size, e1 / size, e2 / size
        else:
            normal[0], normal[1], normal[2] = d0 / dist, d1 / dist, d2 / dist
    else:  # the cores meet (within round-off, whose direction is noise)
        _flat_normal(ka, pa, Ra, kb, pb, Rb, g0, g1, g2, normal)
    for a in range(3):  # xb - xa = dist * normal (the segments' crossing: their difference is along the normal)
        middle = 0.5 * (xa[a] + xb[a])
        xa[a] = middle - 0.5 * dist * normal[a] + sa[0] * normal[a]
        xb[a] = middle + 0.5 * dist * normal[a] - sb[0] * normal[a]
    return dist - sa[0] - sb[0]


@njit(cache=True, **LEAF)
def _sphere_closed_form(c, r, kind, p, R, s, flip, normal, xa, xb):
    """The signed distance of a sphere (centre c, radius r) and a box or a cylinder (kind, p, R, s): the centre's
    closed-form signed distance phi and gradient g (the outward normal at the geom's nearest surface point) less r.
    The normal from the sphere to the geom is -g (+g when flip: the geom is a); the witnesses c - phi g on the geom,
    c - r g on the sphere."""
    if kind == BOX:
        phi = box_distance(c, p, R, s, normal)
    else:
        phi = cylinder_distance(c, p, R, s[0], s[1], normal)
    for a in range(3):
        g = normal[a]
        on_geom, on_sphere = c[a] - phi * g, c[a] - r * g
        if flip:
            xa[a], xb[a], normal[a] = on_geom, on_sphere, g
        else:
            xa[a], xb[a], normal[a] = on_sphere, on_geom, -g
    return phi - r


@njit(cache=True, **LEAF)
def _mesh_face(hull, axes, d0, d1, d2, least):
    """The index of the hull's face plane whose outward normal is nearest the world direction (d0, d1, d2) (unit),
    where its cosine is at least `least`; -1 where none is. Every face is read (F of them)."""
    nv, nf = int(hull[0]), int(hull[1])
    l0 = axes[0, 0] * d0 + axes[1, 0] * d1 + axes[2, 0] * d2
    l1 = axes[0, 1] * d0 + axes[1, 1] * d1 + axes[2, 1] * d2
    l2 = axes[0, 2] * d0 + axes[1, 2] * d1 + axes[2, 2] * d2
    best, face = least, -1
    for f in range(nf):
        k = 3 + 3 * nv + 4 * f
        cosine = hull[k] * l0 + hull[k + 1] * l1 + hull[k + 2] * l2
        if cosine >= best:
            best, face = cosine, f
    return face


@njit(cache=True, **LEAF)
def _face_axis(hull, axes, face):
    """(x, y, z): the world outward normal of the hull's face plane `face`."""
    k = 3 + 3 * int(hull[0]) + 4 * face
    m0, m1, m2 = hull[k], hull[k + 1], hull[k + 2]
    return (axes[0, 0] * m0 + axes[0, 1] * m1 + axes[0, 2] * m2, axes[1, 0] * m0 + axes[1, 1] * m1 + axes[1, 2] * m2,
            axes[2, 0] * m0 + axes[2, 1] * m1 + axes[2, 2] * m2)


@njit(cache=True, **LEAF)
def _certify(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, simp, ids, n, n0, n1, n2, hints, normal, big, row):
    """(bound, big): the normal of separated cores, written to normal (3,), and the lower bound on their distance
    it certifies, -n.s_C(n) (C lies beyond the plane through s_C(n) normal to n: true for any unit n). Candidates:
    v's direction (n0, n1, n2), made normal to the simplex's edge when v is inside one (v's part along it is
    round-off); the simplex triangle's normal when v is inside one (exact to round-off in the triangle's size on a
    flat face of C, where v's direction is off by round-off over the distance); a cylinder's axis when the normal
    is within 0.1 rad of it (a cap's face: its support points are rim points, whose triangles turn into slivers),
    and the normal made perpendicular to the axis when it is within 0.1 rad of that (the side's: along the axis
    the side is straight, and a normal tilted along it by theta certifies theta times the half-length less); a
    box's face axis within 0.1 rad of the normal (a face on a curved surface: C is curved there, by the other
    geom, and no other candidate is the face's normal exactly), and against an ellipsoid or a cylinder a mesh's
    face plane nearest the normal, within 0.1 rad (every face read: the polytope pairs, whose triangle normal is
    already the face's, do not pay for it).
    The one certifying most wins. simp[row] is the scratch for the support points."""
    normal[0], normal[1], normal[2] = n0, n1, n2
    if n == 2:
        e0, e1, e2 = simp[1, 0] - simp[0, 0], simp[1, 1] - simp[0, 1], simp[1, 2] - simp[0, 2]
        ee = e0 * e0 + e1 * e1 + e2 * e2
        if ee > 0.0:
            along = (n0 * e0 + n1 * e1 + n2 * e2) / ee
            t0, t1, t2 = n0 - along * e0, n1 - along * e1, n2 - along * e2
            length = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            if length > 0.5:
                normal[0], normal[1], normal[2] = t0 / length, t1 / length, t2 / length
    big = max(big, _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, normal[0], normal[1], normal[2], hints, simp,
                              ids, row))
    bound = -(normal[0] * simp[row, 0] + normal[1] * simp[row, 1] + normal[2] * simp[row, 2])
    for candidate in range(9):
        b0, b1, b2 = normal[0], normal[1], normal[2]
        c0, c1, c2 = b0, b1, b2
        if candidate == 0:
            if n != 3:
                continue
            c0, c1, c2, _sliver = _triangle_normal(simp, 0, 1, 2)
        elif candidate >= 7:  # a mesh's face plane against a curved geom, the one nearest the normal, within 0.1 rad
            kind, axes, hull, other = (ka, Ra, ha, kb) if candidate == 7 else (kb, Rb, hb, ka)
            if kind != MESH or not (other == ELLIPSOID or other == CYLINDER):
                continue
            sign = 1.0 if candidate == 7 else -1.0  # a's outward normal at the contact is +n, b's -n
            face = _mesh_face(hull, axes, sign * b0, sign * b1, sign * b2, 0.995)
            if face < 0:
                continue
            c0, c1, c2 = _face_axis(hull, axes, face)
        elif candidate >= 5:  # a box's face axis, the one nearest the normal, within 0.1 rad of it
            kind, axes = (ka, Ra) if candidate == 5 else (kb, Rb)
            if kind != BOX:
                continue
            best = 0.0
            for i in range(3):
                along = axes[0, i] * b0 + axes[1, i] * b1 + axes[2, i] * b2
                if abs(along) > abs(best):
                    best, c0, c1, c2 = along, axes[0, i], axes[1, i], axes[2, i]
            if abs(best) < 0.995:
                continue
        else:
            kind, axes = (ka, Ra) if candidate % 2 == 1 else (kb, Rb)
            if kind != CYLINDER:
                continue
            c0, c1, c2 = axes[0, 2], axes[1, 2], axes[2, 2]
            along = c0 * b0 + c1 * b1 + c2 * b2
            if candidate <= 2:  # the cap's normal, the axis
                if abs(along) < 0.995:
                    continue
            else:  # the side's: the normal less its part along the axis
                if abs(along) > 0.1:
                    continue
                c0, c1, c2 = b0 - along * c0, b1 - along * c1, b2 - along * c2
        length = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        if not length > 0.0:
            continue
        if c0 * b0 + c1 * b1 + c2 * b2 < 0.0:
            length = -length
        c0, c1, c2 = c0 / length, c1 / length, c2 / length
        big = max(big, _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, c0, c1, c2, hints, simp, ids, row))
        other = -(c0 * simp[row, 0] + c1 * simp[row, 1] + c2 * simp[row, 2])
        if other > bound:
            bound = other
            normal[0], normal[1], normal[2] = c0, c1, c2
    return bound, big


@njit(cache=True, **LEAF)
def _freedom(kind, axes, normal, ids, r0, r1, r2, n, side):
    """How freely a witness on `side` (0: a, 1: b) may move across the normal and stay on its surface, from the
    simplex's features (rows r0, r1, r2 of ids, the first n) and, for a cylinder, the normal against its axis:
    0 on a polytope's vertex (every point the same feature: any move leaves the surface at once); 1 on a curved
    surface (a smooth one is left only to second order; a cylinder's rim is a curved edge, left at once across it,
    and is ranked here with the smooth ones); 2 on a polytope's edge or face (two features or more) or a cylinder's
    side or cap (the normal within 1e-9 of perpendicular or parallel to its axis): flat along the move."""
    if kind == CYLINDER:
        along = abs(normal[0] * axes[0, 2] + normal[1] * axes[1, 2] + normal[2] * axes[2, 2])
        return 2 if (along < 1e-9 or along > 1.0 - 1e-9) else 1
    first = ids[r0, side]
    if first < 0:
        return 1
    for i in range(1, n):
        other = ids[r1 if i == 1 else r2, side]
        if other < 0:
            return 1
        if other != first:
            return 2
    return 0


@njit(cache=True, **LEAF)
def _face_normal(kind, axes, hull, sign, normal):
    """True where the normal is a flat face's of the geom to round-off (1e-12): a box's face axis, a mesh's face
    plane's (sign * normal its outward one), a cylinder's axis (its cap) or a direction perpendicular to it (its side),
    as _certify's candidates make them."""
    if kind == MESH:
        return _mesh_face(hull, axes, sign * normal[0], sign * normal[1], sign * normal[2], 1.0 - 1e-12) >= 0
    if kind == BOX:
        for i in range(3):
            if abs(normal[0] * axes[0, i] + normal[1] * axes[1, i] + normal[2] * axes[2, i]) > 1.0 - 1e-12:
                return True
    elif kind == CYLINDER:
        along = abs(normal[0] * axes[0, 2] + normal[1] * axes[1, 2] + normal[2] * axes[2, 2])
        return along < 1e-12 or along > 1.0 - 1e-12
    return False


@njit(cache=True, **LEAF)
def _within(kind, pos, axes, size, hull, x0, x1, x2):
    """True where the point (x0, x1, x2) lies in the box's, the cylinder's or the mesh's hull's solid, to round-off
    of its size."""
    d0, d1, d2 = x0 - pos[0], x1 - pos[1], x2 - pos[2]
    l0 = axes[0, 0] * d0 + axes[1, 0] * d1 + axes[2, 0] * d2
    l1 = axes[0, 1] * d0 + axes[1, 1] * d1 + axes[2, 1] * d2
    l2 = axes[0, 2] * d0 + axes[1, 2] * d1 + axes[2, 2] * d2
    slack = 1.0 + 1e-12
    if kind == MESH:  # inside every face plane, n.x <= d, to 1e-12 of the plane's offset (at least 1e-12 m)
        nv = int(hull[0])
        for f in range(int(hull[1])):
            k = 3 + 3 * nv + 4 * f
            if hull[k] * l0 + hull[k + 1] * l1 + hull[k + 2] * l2 > hull[k + 3] + 1e-12 * max(1.0, abs(hull[k + 3])):
                return False
        return True
    if kind == BOX:
        return abs(l0) <= size[0] * slack and abs(l1) <= size[1] * slack and abs(l2) <= size[2] * slack
    return l0 * l0 + l1 * l1 <= (size[0] * slack) ** 2 and abs(l2) <= size[1] * slack


@njit(cache=True, **LEAF)
def _place_witnesses(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, ids, r0, r1, r2, n, dist, normal, xa, xb):
    """xa, xb (3,): the witnesses, the weights' combinations, made to satisfy xb - xa = dist * normal exactly (the
    simplex's or face's features: rows r0, r1, r2 of ids, the first n). Where one geom is curved at the contact
    (an ellipsoid, a cylinder's rim) and the other flat there (a polytope's edge or face, a cylinder's side or
    cap: _freedom) with the normal its face's exactly (_face_normal: a box's or a mesh's face, a cylinder's side
    or cap), the curved one's witness is its support point along the normal, the point of its surface with that
    normal, and the flat one's lies dist along the normal from it (where that is on the face, not beyond its
    edge: _within): the weights' combination of support points spread about the contact (sqrt(2 gap rho), 1e-6 m
    for a gap of 1e-12 m) puts a torque arm off by as much; there the distance is the two support points' gap
    along the normal, n.(x_b - x_a), exact (the face's plane separates them by it, and they are that far apart),
    where GJK's |v| and EPA's face offset bound it within the tolerance. Else the residual across the normal
    (round-off, or |dist| theta where the normal was turned by theta for a better certificate) moves the freer
    witness, both as free: half each. Returns the distance [m]."""
    fa = _freedom(ka, Ra, normal, ids, r0, r1, r2, n, 0)
    fb = _freedom(kb, Rb, normal, ids, r0, r1, r2, n, 1)
    curved_b = fa == 2 and fb == 1 and _face_normal(ka, Ra, ha, 1.0, normal)
    if curved_b or (fb == 2 and fa == 1 and _face_normal(kb, Rb, hb, -1.0, normal)):
        # the two support points, a's along n and b's along -n: their gap along n is the distance where the face
        # is flat (a box's, a mesh's, a cylinder's cap); a cylinder's side is curved around its axis, and a normal
        # turned about it within the tolerance's freedom certifies less than the distance: there dist is kept
        kind, axes = (ka, Ra) if curved_b else (kb, Rb)
        along = normal[0] * axes[0, 2] + normal[1] * axes[1, 2] + normal[2] * axes[2, 2]
        side = kind == CYLINDER and abs(along) < 0.5
        exact = dist
        if curved_b:  # b's support point is its contact, a's witness the distance back along n
            x0, x1, x2, _index = _support(kb, pb, Rb, sb, hb, -normal[0], -normal[1], -normal[2], True, -1)
            if not side:
                f0, f1, f2, _index = _support(ka, pa, Ra, sa, ha, normal[0], normal[1], normal[2], True, -1)
                exact = normal[0] * (x0 - f0) + normal[1] * (x1 - f1) + normal[2] * (x2 - f2)
            f0, f1, f2 = x0 - exact * normal[0], x1 - exact * normal[1], x2 - exact * normal[2]
            inside = _within(ka, pa, Ra, sa, ha, f0, f1, f2)
        else:
            f0, f1, f2, _index = _support(ka, pa, Ra, sa, ha, normal[0], normal[1], normal[2], True, -1)
            if not side:
                x0, x1, x2, _index = _support(kb, pb, Rb, sb, hb, -normal[0], -normal[1], -normal[2], True, -1)
                exact = normal[0] * (x0 - f0) + normal[1] * (x1 - f1) + normal[2] * (x2 - f2)
            x0, x1, x2 = f0 + exact * normal[0], f1 + exact * normal[1], f2 + exact * normal[2]
            inside = _within(kb, pb, Rb, sb, hb, x0, x1, x2)
        if inside:  # else the curved point is beyond the face's edge: the contact is at that edge
            xa[0], xa[1], xa[2] = f0, f1, f2
            xb[0], xb[1], xb[2] = x0, x1, x2
            return exact
    share = 0.5 if fa == fb else (1.0 if fa > fb else 0.0)  # the part a's witness takes
    for a in range(3):
        residual = xb[a] - xa[a] - dist * normal[a]
        xa[a] += share * residual
        xb[a] -= (1.0 - share) * residual
    return dist


@njit(cache=True)
def _signed_distance(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, guess, normal, xa, xb, out):
    """signed_distance's work; out (INFO,) its info."""
    out[0], out[1], out[2], out[3] = CONVERGED, 0.0, 0.0, 0.0
    if (ka == MESH and (ha.size < 3 or ha[0] < 4)) or (kb == MESH and (hb.size < 3 or hb[0] < 4)):
        out[0] = BAD_INPUT
        for a in range(3):
            normal[a], xa[a], xb[a] = np.nan, np.nan, np.nan
        return np.nan
    hints = np.empty(2, np.int64)  # the meshes' hill climbs start here (-1: from the seeds)
    hints[0] = int(out[4]) if (ka == MESH and 0.0 <= out[4] < ha[0]) else -1
    hints[1] = int(out[5]) if (kb == MESH and 0.0 <= out[5] < hb[0]) else -1
    ra = sa[0] if (ka == SPHERE or ka == CAPSULE) else 0.0  # the radii about the cores
    rb = sb[0] if (kb == SPHERE or kb == CAPSULE) else 0.0
    flat_a = ka == SPHERE or ka == CAPSULE
    flat_b = kb == SPHERE or kb == CAPSULE
    polytope = (flat_a or ka == BOX or ka == MESH) and (flat_b or kb == BOX or kb == MESH)
    tol = 0.0 if polytope else CURVED_TOLERANCE * max(1.0, _size_scale(ka, sa, ha), _size_scale(kb, sb, hb))
    # the first direction: the guess, else from a towards b, else +x
    g0, g1, g2 = guess[0], guess[1], guess[2]
    if not g0 * g0 + g1 * g1 + g2 * g2 > 0.0:
        g0, g1, g2 = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
        if not g0 * g0 + g1 * g1 + g2 * g2 > 0.0:
            g0, g1, g2 = 1.0, 0.0, 0.0
    if flat_a and flat_b:  # two points or segments: their closest points in closed form
        return _cores_closed_form(ka, pa, Ra, sa, kb, pb, Rb, sb, g0, g1, g2, normal, xa, xb)
    if ka == SPHERE and (kb == BOX or kb == CYLINDER):  # a point's closed-form distance, less the radius
        return _sphere_closed_form(pa, sa[0], kb, pb, Rb, sb, False, normal, xa, xb)
    if kb == SPHERE and (ka == BOX or ka == CYLINDER):
        return _sphere_closed_form(pb, sb[0], ka, pa, Ra, sa, True, normal, xa, xb)
    # rows 0-3: the simplex's points (w, a, b), row 4: the last support point (a restart's start), rows 5-8: the
    # simplex before a step (restored when the step makes things worse), row 9: _certify's; lam[0:4] the weights,
    # lam[4:8] those before the step
    simp = np.empty((10, 9))
    ids = np.empty((10, 2), np.int64)
    lam = np.zeros(8)
    big = _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, g0, g1, g2, hints, simp, ids, 0)
    n = 1
    lam[0] = 1.0
    v0, v1, v2 = simp[0, 0], simp[0, 1], simp[0, 2]
    contact = False
    status = ITERATION_LIMIT
    gap = np.inf
    iterations = 0
    stalls = 0
    restarts = 0
    steer = False
    for iteration in range(GJK_ITERATIONS):
        iterations = iteration + 1
        vv = v0 * v0 + v1 * v1 + v2 * v2
        floor = ROUNDOFF * big
        if vv <= max(floor, tol) ** 2:  # the origin on the simplex within round-off (or the tolerance): touching
            contact = True
            status = CONVERGED
            break
        norm = np.sqrt(vv)
        if steer:  # after a stall: along the normal that certified most
            d0, d1, d2 = normal[0], normal[1], normal[2]
            steer = False
        else:
            d0, d1, d2 = -v0 / norm, -v1 / norm, -v2 / norm
        big = max(big, _minkowski(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, d0, d1, d2, hints, simp, ids, n))
        floor = ROUNDOFF * big
        # C lies beyond the plane through w normal to d: -d.w a lower bound on the distance
        lower = -(d0 * simp[n, 0] + d1 * simp[n, 1] + d2 * simp[n, 2])
        gap = norm - lower
        if gap <= max(tol, floor):
            status = CONVERGED
            break
        if polytope:
            repeated = False
            for i in range(n):
                if ids[i, 0] == ids[n, 0] and ids[i, 1] == ids[n, 1]:
                    repeated = True
            if repeated:  # w already in the simplex: v is the nearest point of C
                status = CONVERGED
                break
        for i in range(n):
            for a in range(9):
                simp[5 + i, a] = simp[i, a]
            ids[5 + i, 0], ids[5 + i, 1] = ids[i, 0], ids[i, 1]
            lam[4 + i] = lam[i]
        if n < 4:  # w kept in row 4 (a restart's start)
            for a in range(9):
                simp[4, a] = simp[n, a]
            ids[4, 0], ids[4, 1] = ids[n, 0], ids[n, 1]
        count = n
        n += 1
        for i in range(4):
            lam[i] = 0.0
        if n == 2:
            lam[0], lam[1] = _s1d(simp, 0, 1)
        elif n == 3:
            lam[0], lam[1], lam[2], _d = _s2d(simp, 0, 1, 2)
        else:
            if _s3d(simp, lam):
                contact = True
                status = CONVERGED
                break
        m = 0  # drop the points of zero weight
        for i in range(n):
            if lam[i] > 0.0:
                if m != i:
                    for a in range(9):
                        simp[m, a] = simp[i, a]
                    ids[m, 0], ids[m, 1] = ids[i, 0], ids[i, 1]
                    lam[m] = lam[i]
                m += 1
        for i in range(m, 4):
            lam[i] = 0.0
        n = m
        u0, u1, u2 = _nearest_point(simp, n)
        if u0 != u0:  # a sliver: its weights' combination
            u0 = u1 = u2 = 0.0
            for i in range(n):
                u0 += lam[i] * simp[i, 0]
                u1 += lam[i] * simp[i, 1]
                u2 += lam[i] * simp[i, 2]
        uu = u0 * u0 + u1 * u1 + u2 * u2
        # no progress in |v|: on a curved surface |v| converges quadratically faster than its direction (which
        # the gap measures), so a step that keeps |v| to round-off may still turn v: STALL_STEPS of them in a row
        # are taken; then, if the gap is still open, the simplex has become a sliver (or, between a polytope's
        # nearly coplanar faces, a triangle) whose nearest point round-off blurs, and GJK starts again from the
        # last support point with a fresh simplex, GJK_RESTARTS times; else the last simplex is the answer
        level = not uu > vv * (1.0 + 4.0 * EPS)
        stalls = stalls + 1 if not uu < vv else 0
        if level and stalls >= 1 and not gap <= max(tol, floor):
            # a step without progress: another normal may close the gap already (a flat face's, a cap's), else the
            # next support point is taken along the best of them
            un = np.sqrt(uu)
            bound, big = _certify(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, simp, ids, n, -u0 / un, -u1 / un, -u2 / un,
                                  hints, normal, big, 9)
            if un - bound <= max(tol, floor):
                v0, v1, v2 = u0, u1, u2
                gap = un - bound
                status = CONVERGED
                break
            steer = True  # the next support point along that normal (a cylinder side's: from the other rim)
        if not (level and stalls <= STALL_STEPS):
            if not level:  # worse: back to the last simplex
                n = count
                for i in range(n):
                    for a in range(9):
                        simp[i, a] = simp[5 + i, a]
                    ids[i, 0], ids[i, 1] = ids[5 + i, 0], ids[5 + i, 1]
                    lam[i] = lam[4 + i]
                for i in range(n, 4):
                    lam[i] = 0.0
                u0, u1, u2, uu = v0, v1, v2, vv
            if not gap <= max(tol, floor):  # another normal may close the gap (a flat face's, a cap's)
                un = np.sqrt(uu)
                bound, big = _certify(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, simp, ids, n, -u0 / un, -u1 / un,
                                      -u2 / un, hints, normal, big, 9)
                gap = min(gap, un - bound)
            if restarts < GJK_RESTARTS and not gap <= max(tol, floor):
                restarts += 1
                stalls = 0
                steer = False
                n = 1
                for a in range(9):
                    simp[0, a] = simp[4, a]
                ids[0, 0], ids[0, 1] = ids[4, 0], ids[4, 1]
                lam[0], lam[1], lam[2], lam[3] = 1.0, 0.0, 0.0, 0.0
                v0, v1, v2 = simp[0, 0], simp[0, 1], simp[0, 2]
                continue
            v0, v1, v2 = u0, u1, u2
            status = CONVERGED if gap <= max(tol, floor) else STALLED
            contact = status == STALLED and uu <= gap * gap  # the gap spans 0: EPA decides the sign
            break
        v0, v1, v2 = u0, u1, u2
    out[1] = iterations
    out[3] = max(gap, 0.0) if gap < np.inf else 0.0
    dist = np.nan
    if contact:
        epa_out = np.empty(3)
        depth = _epa(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, simp, ids, n, tol, polytope, big, hints, normal, xa,
                     xb, epa_out)
        if depth == depth:  # not NaN: EPA built its polytope; its last face's witnesses placed once
            dist = -depth
            faces = ka == BOX or ka == MESH or ka == CYLINDER or kb == BOX or kb == MESH or kb == CYLINDER
            if faces and not polytope:  # a flat face's normal that certifies more than EPA's face (whose normal
                # is its support points' plane, off by their round-off over its size) is the normal
                _bound, big = _certify(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, simp, ids, 1, normal[0], normal[1],
                                       normal[2], hints, normal, big, 9)
            dist = _place_witnesses(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, ids, 0, 1, 2, 3, dist, normal, xa, xb)
            status = int(epa_out[0])
            out[2] = epa_out[1]
            out[3] = epa_out[2]
    if dist != dist:  # separated, or cores without an inside: GJK's nearest point
        for a in range(3):
            xa[a] = 0.0
            xb[a] = 0.0
            for i in range(n):
                xa[a] += lam[i] * simp[i, 3 + a]
                xb[a] += lam[i] * simp[i, 6 + a]
        w0, w1, w2 = v0, v1, v2  # v = xa - xb to round-off in the weights
        dist = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        if dist > ROUNDOFF * big:
            bound, big = _certify(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, simp, ids, n, -w0 / dist, -w1 / dist,
                                  -w2 / dist, hints, normal, big, 9)
            gap = max(dist - bound, 0.0)
            out[3] = gap
            if status == STALLED and gap <= max(tol, ROUNDOFF * big):
                status = CONVERGED
            dist = _place_witnesses(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, ids, 0, 1, 2, n, dist, normal, xa, xb)
        else:  # EPA failed on a touching pair: the guess
            length = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
            normal[0], normal[1], normal[2] = g0 / length, g1 / length, g2 / length
            if status == CONVERGED:
                status = STALLED
    out[0] = status
    out[4], out[5] = hints[0], hints[1]
    for a in range(3):  # the radii: the surfaces lie r along the normal from the cores' witnesses
        xa[a] += ra * normal[a]
        xb[a] -= rb * normal[a]
    return dist - ra - rb


@njit(cache=True)
def signed_distance(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, guess, normal, xa, xb, info=None):
    """The signed distance [m] of geom a (type ka, centre pa (3,) [m], axes Ra (3, 3), size sa (3,) [m], hull ha
    (pack_hull's; np.empty(0) unless a mesh)) and geom b (kb, pb, Rb, sb, hb): the distance of the sets when
    separated, minus the penetration depth (the shortest translation separating them) when overlapping.
    guess (3,): a first direction from a towards b (the last step's normal; zero: pb - pa). normal (3,): the unit
    normal from a towards b (moving b along it separates them at unit rate). xa, xb (3,) [m]: the witness points on
    the surfaces, xb - xa = dist * normal. info (INFO,) optional: status (CONVERGED 0 ...), GJK and EPA iterations,
    the final duality gap [m], and the mesh hint vertices (read when >= 0, written back). NaN for BAD_INPUT."""
    if info is None:
        work = np.empty(INFO)
        work[4], work[5] = -1.0, -1.0
        return _signed_distance(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, guess, normal, xa, xb, work)
    return _signed_distance(ka, pa, Ra, sa, ha, kb, pb, Rb, sb, hb, guess, normal, xa, xb, info)


# ------------------------------------------------------------------------------------------------ a point

@njit(cache=True, **LEAF)
def box_distance(x, pb, Rb, sb, grad):
    """The signed distance [m] of the point x (3,) from the box (centre pb, axes Rb, half sizes sb) and its gradient
    grad (3,): outside, along the offset from the box's nearest point; inside, the outward normal of the face of
    least depth."""
    l0 = Rb[0, 0] * (x[0] - pb[0]) + Rb[1, 0] * (x[1] - pb[1]) + Rb[2, 0] * (x[2] - pb[2])
    l1 = Rb[0, 1] * (x[0] - pb[0]) + Rb[1, 1] * (x[1] - pb[1]) + Rb[2, 1] * (x[2] - pb[2])
    l2 = Rb[0, 2] * (x[0] - pb[0]) + Rb[1, 2] * (x[1] - pb[1]) + Rb[2, 2] * (x[2] - pb[2])
    o0 = l0 - min(max(l0, -sb[0]), sb[0])
    o1 = l1 - min(max(l1, -sb[1]), sb[1])
    o2 = l2 - min(max(l2, -sb[2]), sb[2])
    outside = o0 * o0 + o1 * o1 + o2 * o2
    if outside > 0.0:
        length = np.sqrt(outside)
        for a in range(3):
            grad[a] = (Rb[a, 0] * o0 + Rb[a, 1] * o1 + Rb[a, 2] * o2) / length
        return length
    face, depth, along = 0, sb[0] - abs(l0), l0
    if sb[1] - abs(l1) < depth:
        face, depth, along = 1, sb[1] - abs(l1), l1
    if sb[2] - abs(l2) < depth:
        face, depth, along = 2, sb[2] - abs(l2), l2
    side = 1.0 if along >= 0.0 else -1.0
    for a in range(3):
        grad[a] = side * Rb[a, face]
    return -depth


@njit(cache=True, **LEAF)
def cylinder_distance(x, pc, Rc, radius, half, grad):
    """The signed distance [m] of the point x (3,) from the cylinder of centre pc (3,), axis Rc[:, 2], radius and
    half-length half [m], and its gradient grad (3,): the outward normal at the nearest point of the surface (the
    rim's, a cap's or the side's; inside: the nearer of cap and side). Convex in x: max(d_r, d_z) inside,
    |(d_r, d_z)_+| outside, d_r = rho - radius, d_z = |z| - half."""
    d0, d1, d2 = x[0] - pc[0], x[1] - pc[1], x[2] - pc[2]
    z = d0 * Rc[0, 2] + d1 * Rc[1, 2] + d2 * Rc[2, 2]
    r0, r1, r2 = d0 - z * Rc[0, 2], d1 - z * Rc[1, 2], d2 - z * Rc[2, 2]
    rho = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if rho > 0.0:
        e0, e1, e2 = r0 / rho, r1 / rho, r2 / rho
    else:  # on the axis: any radial direction
        e0, e1, e2 = Rc[0, 0], Rc[1, 0], Rc[2, 0]
    side = 1.0 if z >= 0.0 else -1.0
    dr, dz = rho - radius, abs(z) - half
    if dr > 0.0 and dz > 0.0:  # beyond the rim
        length = np.sqrt(dr * dr + dz * dz)
        grad[0] = (dr * e0 + dz * side * Rc[0, 2]) / length
        grad[1] = (dr * e1 + dz * side * Rc[1, 2]) / length
        grad[2] = (dr * e2 + dz * side * Rc[2, 2]) / length
        return length
    if dz > dr:  # a cap's
        for a in range(3):
            grad[a] = side * Rc[a, 2]
        return dz
    grad[0], grad[1], grad[2] = e0, e1, e2  # the side's
    return dr


@njit(cache=True)
def point_signed_distance(kind, pos, mat, size, hull, x, grad):
    """The signed distance [m] of the point x (3,) [m] from the geom (kind, centre pos (3,) [m], axes mat (3, 3),
    size (3,) [m], hull: pack_hull's for a mesh), negative inside; grad (3,): the outward unit normal at the
    nearest surface point. Closed form for spheres, capsules, boxes and cylinders; a mesh's inside is the largest
    excess over its face planes (exact), its outside and an ellipsoid by signed_distance (the point a sphere of
    radius 0). NaN for a mesh without a hull."""
    if kind == SPHERE or kind == CAPSULE:
        c0, c1, c2 = pos[0], pos[1], pos[2]
        if kind == CAPSULE:  # the segment's point nearest x
            t = (x[0] - pos[0]) * mat[0, 2] + (x[1] - pos[1]) * mat[1, 2] + (x[2] - pos[2]) * mat[2, 2]
            t = min(max(t, -size[1]), size[1])
            c0, c1, c2 = c0 + t * mat[0, 2], c1 + t * mat[1, 2], c2 + t * mat[2, 2]
        d0, d1, d2 = x[0] - c0, x[1] - c1, x[2] - c2
        length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if length > 0.0:
            grad[0], grad[1], grad[2] = d0 / length, d1 / length, d2 / length
        else:  # on the core: any direction across it
            grad[0], grad[1], grad[2] = mat[0, 0], mat[1, 0], mat[2, 0]
        return length - size[0]
    if kind == BOX:
        return box_distance(x, pos, mat, size, grad)
    if kind == CYLINDER:
        return cylinder_distance(x, pos, mat, size[0], size[1], grad)
    if kind == MESH:
        if hull.size < 3 or hull[0] < 4:
            grad[0], grad[1], grad[2] = np.nan, np.nan, np.nan
            return np.nan
        nv, nf = int(hull[0]), int(hull[1])
        l0 = mat[0, 0] * (x[0] - pos[0]) + mat[1, 0] * (x[1] - pos[1]) + mat[2, 0] * (x[2] - pos[2])
        l1 = mat[0, 1] * (x[0] - pos[0]) + mat[1, 1] * (x[1] - pos[1]) + mat[2, 1] * (x[2] - pos[2])
        l2 = mat[0, 2] * (x[0] - pos[0]) + mat[1, 2] * (x[1] - pos[1]) + mat[2, 2] * (x[2] - pos[2])
        best, face = -np.inf, 0
        for f in range(nf):
            p = 3 + 3 * nv + 4 * f
            excess = hull[p] * l0 + hull[p + 1] * l1 + hull[p + 2] * l2 - hull[p + 3]
            if excess > best:
                best, face = excess, f
        if best <= 0.0:  # inside: the nearest face plane holds the nearest boundary point
            p = 3 + 3 * nv + 4 * face
            for a in range(3):
                grad[a] = mat[a, 0] * hull[p] + mat[a, 1] * hull[p + 1] + mat[a, 2] * hull[p + 2]
            return best
    point = np.zeros(3)  # the point as a sphere of radius 0 (geom a), the geom as b
    axes = np.eye(3)
    normal = np.empty(3)
    xa = np.empty(3)
    xb = np.empty(3)
    guess = np.empty(3)
    for a in range(3):
        guess[a] = pos[a] - x[a]
    dist = signed_distance(SPHERE, x, axes, point, np.empty(0), kind, pos, mat, size, hull, guess, normal, xa, xb)
    for a in range(3):  # the normal points from the point to the geom; the outward normal is its opposite
        grad[a] = -normal[a]
    return dist


# ------------------------------------------------------------------------------------------------ hulls

_SEED_DIRECTIONS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
                             [1, 1, 1], [-1, -1, -1], [1, -1, -1], [-1, 1, 1], [-1, 1, -1], [1, -1, 1],
                             [-1, -1, 1], [1, 1, -1]], dtype=float)


def pack_hull(vertices) -> np.ndarray:
    """The convex hull of the points vertices (N, 3) [m] (in the geom's frame), packed into one float64 array:
    [V, F, A, the V hull vertices (3V), the F face planes (4F: unit outward n and d, inside n.x <= d; coplanar
    hull triangles merged, one plane per facet), V + 1 adjacency starts (offsets into the neighbour block), the A
    neighbour indices (the hull triangulation's edge graph, which holds the hull's edges)]. The first vertices are
    the extremes along the axes and the cube's diagonals (the hill climb's seeds). Raises ValueError for fewer than
    4 points, non-finite values, or a flat (zero-volume) cloud."""
    from scipy.spatial import ConvexHull, QhullError

    points = np.asarray(vertices, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"hull: vertices of shape {points.shape}: expected (N, 3)")
    if len(points) < 4:
        raise ValueError(f"hull: {len(points)} points: a convex hull needs at least 4")
    if not np.all(np.isfinite(points)):
        raise ValueError("hull: non-finite vertex coordinates (nan or inf)")
    centred = points - points.mean(axis=0)
    extent = np.abs(centred).max()
    if extent == 0.0 or np.linalg.svd(centred / extent, compute_uv=False)[2] <= 1e-12 * np.sqrt(len(points)):
        raise ValueError("hull: the points are flat (zero volume): they lie on a plane, a line or a point")
    try:
        hull = ConvexHull(points)
    except QhullError as error:
        raise ValueError(f"hull: the points are flat (zero volume) for qhull: {str(error).splitlines()[0]}") \
            from None
    # the vertices: the seeds first, then the others in qhull's order
    order = list(dict.fromkeys(int(i) for i in np.argmax(points[hull.vertices] @ _SEED_DIRECTIONS.T, axis=0)))
    order = [int(hull.vertices[i]) for i in order]
    order += [int(i) for i in hull.vertices if int(i) not in set(order)]
    index = {old: new for new, old in enumerate(order)}
    verts = points[order]
    # facets: neighbouring triangles with qhull's same plane (its triangulated facets share their hyperplane)
    triangles = hull.simplices
    parent = list(range(len(triangles)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for t, neighbours in enumerate(hull.neighbors):
        for u in neighbours:
            if np.array_equal(hull.equations[t], hull.equations[u]):
                parent[root(t)] = root(int(u))
    groups: dict[int, list[int]] = {}
    for t in range(len(triangles)):
        groups.setdefault(root(t), []).append(t)
    planes = []
    for members in groups.values():
        # the facet's normal: its triangles' area vectors summed (oriented by qhull's outward normal), unit; d
        # the largest n.v over its vertices, so that every vertex is inside
        total = np.zeros(3)
        corners = set()
        for t in members:
            a, b, c = points[triangles[t]]
            area = np.cross(b - a, c - a)
            if area @ hull.equations[t, :3] < 0:
                area = -area
            total += area
            corners.update(int(i) for i in triangles[t])
        normal = total / np.linalg.norm(total)
        planes.append([*normal, max(float(normal @ points[i]) for i in corners)])
    # the edge graph
    neighbours: list[set[int]] = [set() for _ in order]
    for tri in triangles:
        for m in range(3):
            a, b = index[int(tri[m])], index[int(tri[(m + 1) % 3])]
            neighbours[a].add(b)
            neighbours[b].add(a)
    starts = np.zeros(len(order) + 1)
    starts[1:] = np.cumsum([len(s) for s in neighbours])
    flat = [float(j) for s in neighbours for j in sorted(s)]
    return np.concatenate([[len(order), len(planes), len(flat)], verts.ravel(), np.asarray(planes).ravel(), starts,
                           flat]).astype(float)


def hull_vertices(hull) -> np.ndarray:
    """(V, 3) [m]: the hull's vertices, in the geom's frame."""
    nv = int(hull[0])
    return np.asarray(hull[3:3 + 3 * nv]).reshape(nv, 3).copy()


def hull_planes(hull) -> np.ndarray:
    """(F, 4): the hull's face planes (unit outward n, d [m]; inside n.x <= d)."""
    nv, nf = int(hull[0]), int(hull[1])
    return np.asarray(hull[3 + 3 * nv:3 + 3 * nv + 4 * nf]).reshape(nf, 4).copy()


def hull_neighbours(hull) -> list[np.ndarray]:
    """The hull's edge graph: the neighbour indices of each vertex."""
    nv, nf = int(hull[0]), int(hull[1])
    start = 3 + 3 * nv + 4 * nf
    offsets = hull[start:start + nv + 1].astype(int)
    block = hull[start + nv + 1:].astype(int)
    return [block[offsets[i]:offsets[i + 1]] for i in range(nv)]


__all__ = ["SPHERE", "CAPSULE", "ELLIPSOID", "CYLINDER", "BOX", "MESH", "CONVERGED", "ITERATION_LIMIT",
           "EPA_CAPACITY", "STALLED", "BAD_INPUT", "STATUS_TEXT", "INFO", "GJK_ITERATIONS", "EPA_VERTICES",
           "EPA_FACES", "CURVED_TOLERANCE", "support", "signed_distance", "point_signed_distance", "pack_hull",
           "hull_vertices", "hull_planes", "hull_neighbours"]
