"""The narrow phase of rbody's contacts: signed distance, normal and contact points of two primitive geoms, compiled.

Geoms are given as MuJoCo gives them to its collision functions (engine_collision_primitive.c): a type code (the
values of MuJoCo's mjtGeom: PLANE 0, SPHERE 2, CAPSULE 3, ELLIPSOID 4, CYLINDER 5, BOX 6, MESH 7), the world position
pos (3,) [m] of the geom's centre, its world orientation mat (3, 3) (columns: the geom's axes), its size (3,) [m] and,
for a mesh, its packed convex hull (rbody.engine.contacts.convex.pack_hull; an empty array for the others):

    plane     infinite, through pos, its normal the geom's z axis (mat[:, 2]); size unused
    sphere    radius size[0]
    capsule   radius size[0], half-length size[1] of its segment along the geom's z axis
    ellipsoid semi-axes size[0:3] along the geom's axes
    cylinder  radius size[0], half-length size[1] along the geom's z axis
    box       half sizes size[0:3] along the geom's axes
    mesh      the convex hull of its vertices (as MuJoCo collides a mesh); size: the half sizes of a box about pos,
              along the geom's axes, that holds it (the broad phase's; the constraint table centres it)

`collide` takes the pair in MuJoCo's order (type_a <= type_b; the caller swaps) and writes each candidate contact:
dist [m] (the signed distance between the surfaces along the normal, < 0 when they overlap), normal (3,) the unit
normal pointing from geom a towards geom b (MuJoCo's contact frame's first axis), and point (3,) [m] midway between
the two surfaces (MuJoCo's con.pos), or on the face where the nearest feature is flat (a plane, a box's face, a
cylinder's cap): there a contact that closes within a step will touch, and the friction rows of several such
contacts of one body (a foot's four capsule ends landing on a floor, at different heights) are then those of a
rigid motion (midway, the points' heights enter their tangential velocities through the body's turning, and no
impulses hold them all). It returns the number of candidates, which for a pair of types is fixed
(SLOTS): a plane and a capsule always give the two end spheres, a plane and a box its 8 corners, whatever their
distance, so that a contact's identity (which corner, which end) is the same at every state and its distance is a
smooth function of the configuration (the gap function of the constraint layer). The rigid limit needs no margin:
the constraint layer decides from the distance and its rate which candidates touch.

Each distance is exact (closed form, no iteration): the surfaces of these primitives are offsets of points,
segments and boxes, so the distance is the distance between the cores minus the radii, with the normal along the
line of closest approach; where the cores overlap (a sphere's centre inside a box), the normal is that of the face
of least penetration. Two boxes give 17 candidates, each corner of one against the other box (vertex-face
contacts: a box resting on a box, a stack), and the closest points of their closest pair of edges (slot 16, of
the 144 pairs whose closest points lie inside both edges, not parallel: signed along their common perpendicular, negative
where the edges crossed), APART where none cross or a corner is as
close (it holds that contact): boxes crossing edge on edge touch there. The closest points of two segments follow
Ericson's clamped solution (Real-Time Collision Detection, 5.1.9); parallel segments take the midpoint of their
overlap, so the normal is unique there too.

A capsule and a box give 3 candidates. Slot 2 is the sphere at the segment's point closest to the box
(segment_box_closest, exact; clamped to the segment, so it moves continuously from a capsule's middle across an
edge to its end on a face): where it does not touch, nothing does. Slots 0 and 1 are the end spheres, which see
an end approach a face while the closest point is elsewhere (a capsule tipping off an edge onto a face); an end
within LYING_SPAN of its half-length of the closest point is APART (+inf: never touching, never closing), so that
no contact is counted twice, nor twice nearly (two candidates a hair apart make a complementarity problem no
solver finishes). Where the capsule lies along a face (its closest points span more than LYING_SPAN of its
half-length: parallel to the face), slot 2 is the middle of that span and slots 0 and 1 its ends, so that the
capsule rests on the whole span: both ends on a face, or an end and the box's edge where it overhangs.

Cylinders. A point's signed distance from a cylinder (cylinder_distance) is closed form and convex: from its side
(rho - radius), a cap (|z| - half) or the rim (their hypotenuse). A sphere and a cylinder: 1 candidate. A capsule
and a cylinder: 3, as for a box (the segment's closest point, slot 2, found by bisection on the sign of the
distance's slope along the segment, which convexity makes monotone, to the last bit of its parameter; its ends,
slots 0 and 1, APART within LYING_SPAN of it); parallel to the side or a cap the closest point is the middle of the
parallel stretch. A plane and a cylinder: 8, each cap's rim at its point lowest towards the plane and at 90, 180
and 270 degrees from it (the rim's points along the plane's normal projected onto the caps, which is smooth in
rolling: a drum on its side touches at its two lowest rim points, and 4 more points of each rim lie a radius or a
diameter above). Standing upright (the axis within UPRIGHT of the normal) the four points of the lower cap, along
the cylinder's own axes, hold it. A cylinder and a box: 19 candidates, each an exact distance of a point of one
surface from the other geom: each cap's rim at its point closest to the box and at 90, 180 and 270 degrees from it
(slots 0-7; the closest rim point by RIM_SAMPLES samples around the rim, then the zero of the distance's slope by
false position to the last bit: the distance along a circle need not be convex), the box's 8 corners against the
cylinder (8-15), the point of the box's edges closest to the cylinder (16: exact, segment_cylinder_closest on
each edge), APART where another slot holds the same contact to 1e-12 m, and the ends of the line along which a
face lying on the side touches it (17, 18: _side_line; a crate on a log, which one point would let tip). Two
cylinders: 17, each one's rim candidates against the other (0-7, 8-15) and the closest points of their sides (16:
the axes' closest points, as two capsules, APART unless both lie within the sides, or where a rim slot holds it).
Every candidate being a point of one surface, the least distance is never below the true distance, and reaches it
(tested against MuJoCo's mj_geomDistance on random poses). These pairs run by the time-stepping only (TIME_STEPPED):
their contact points move along a rim, a curve the event-driven scheme's curvature terms do not cover.

Ellipsoids (strictly convex: one point of contact with any convex geom): with a plane, its lowest point in closed
form (plane_ellipsoid); with a sphere, the centre's exact distance (Eberly's root, rbody.engine.contacts.ellipsoid);
with a capsule, 3 as for a cylinder (the segment's closest point by bisection on the slope, its ends); with an
ellipsoid, a cylinder, a box or a mesh, their closest points (GJK, or EPA where they overlap:
rbody.engine.contacts.convex). Meshes collide by their convex hull, as MuJoCo's do: with a plane, 9 candidates, the
hull's vertex lowest towards it and its supports along -n tilted by TILT at 45 degree steps (a face lying on the
plane: its extreme vertices; exact heights); with a sphere, the centre's exact distance from the hull (its face
planes inside, its nearest point outside); with a capsule, 5 (the closest points of segment and hull, the ends, and
the ends of a face's line along the side: _side_line, as a cylinder's); with a cylinder, a box or a mesh, 17
(_patch; a cylinder's 19, its slots 17 and 18 a hull's face's line along the side, as a box's): their closest points
(slot 16) and, around that normal n, each geom's supports tilted towards the other (slots 0-7 geom b's along -n,
8-15 geom a's along +n), each point's exact signed distance from the other geom, so that a face lying on a face
rests on the extreme vertices of both; a point found twice is APART, and slot 16 where a vertex slot holds it. All
of these run by the time-stepping only: their candidates change identity with the configuration.
"""

from __future__ import annotations

import numpy as np
from numba import carray, njit

from rbody.engine.contacts.convex import (box_distance, cylinder_distance, point_signed_distance, signed_distance,
                                         support)
from rbody.engine.contacts.ellipsoid import ellipsoid_distance, plane_ellipsoid, segment_ellipsoid_closest
from rbody.engine.memory import cut, stack_floats

PLANE, SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH = 0, 2, 3, 4, 5, 6, 7
TYPE_CODES = {"plane": PLANE, "sphere": SPHERE, "capsule": CAPSULE, "ellipsoid": ELLIPSOID, "cylinder": CYLINDER,
              "box": BOX, "mesh": MESH}
# candidates per pair of type codes (type_a <= type_b): the pairs rbody computes
SLOTS = {(PLANE, SPHERE): 1, (PLANE, CAPSULE): 2, (PLANE, CYLINDER): 8, (PLANE, BOX): 8, (SPHERE, SPHERE): 1,
         (SPHERE, CAPSULE): 1, (SPHERE, CYLINDER): 1, (SPHERE, BOX): 1, (CAPSULE, CAPSULE): 1,
         (CAPSULE, CYLINDER): 3, (CAPSULE, BOX): 3, (CYLINDER, CYLINDER): 17, (CYLINDER, BOX): 19, (BOX, BOX): 17,
         # ellipsoids: strictly convex, one point of contact with any convex geom
         (PLANE, ELLIPSOID): 1, (SPHERE, ELLIPSOID): 1, (CAPSULE, ELLIPSOID): 3, (ELLIPSOID, ELLIPSOID): 1,
         (ELLIPSOID, CYLINDER): 1, (ELLIPSOID, BOX): 1, (ELLIPSOID, MESH): 1,
         # meshes (their convex hulls): a plane's lowest vertices, a patch of tilted supports against a polytope
         (PLANE, MESH): 9, (SPHERE, MESH): 1, (CAPSULE, MESH): 5, (CYLINDER, MESH): 19,
         (BOX, MESH): 17, (MESH, MESH): 17}
APART = np.inf  # the distance of a candidate that is not a contact point in this configuration (a capsule's end slots)
# pairs the event-driven scheme, which holds a contact's candidate from event to event with closed-form curvature
# terms (contacts.kinematics), does not run: candidates that are contact points in some configurations only, or
# points that move along a curve of a cylinder's rim; the time-stepping runs them
TIME_STEPPED = {(CAPSULE, BOX), (PLANE, CYLINDER), (SPHERE, CYLINDER), (CAPSULE, CYLINDER), (CYLINDER, CYLINDER),
                (CYLINDER, BOX)} | {pair for pair in SLOTS if ELLIPSOID in pair or MESH in pair}
LYING_SPAN = 1e-2  # a capsule's closest points spanning more than this fraction of its half-length: it lies along a face
UPRIGHT = 1e-12  # a cylinder whose axis is within this angle [rad] of a plane's normal stands on it
SLOPE_TOLERANCE = 1e-12  # the rate of distance along a segment [m/m] below which it runs parallel to a surface
MAX_SLOTS = 512  # a height field pair's window (rbody.engine.contacts.terrain) may hold this many; the others 17
RIM_SAMPLES = 16  # points around a rim before its closest point to a box or a cylinder is refined
PATCH = 8        # support directions tilted around a contact's normal: the corners of a face lying on another
TILT = 0.1       # their tilt's tangent: a face's extreme vertices win over vertices off it (any tilt does on a
                 # polytope's face; a small one keeps them to the face's neighbourhood on a tessellated curve)
PATCH_COS = np.cos(np.arange(PATCH) * 2.0 * np.pi / PATCH)
PATCH_SIN = np.sin(np.arange(PATCH) * 2.0 * np.pi / PATCH)


@njit(cache=True, inline="always")
def _sphere_sphere(ca, ra, cb, rb, k, dist, normal, point):
    """Contact k of a sphere (ca, ra) and a sphere (cb, rb), normal from a to b; coincident centres: +z."""
    dx, dy, dz = cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length > 0.0:
        nx, ny, nz = dx / length, dy / length, dz / length
    else:
        nx, ny, nz = 0.0, 0.0, 1.0
    d = length - ra - rb
    dist[k] = d
    normal[k, 0], normal[k, 1], normal[k, 2] = nx, ny, nz
    reach = ra + 0.5 * d
    point[k, 0], point[k, 1], point[k, 2] = ca[0] + nx * reach, ca[1] + ny * reach, ca[2] + nz * reach


@njit(cache=True, inline="always")
def _plane_point(pa, n, c, r, k, dist, normal, point):
    """Contact k of the plane (pa, normal n) and a sphere (c, r) (r = 0: a point); its point on the plane."""
    d = n[0] * (c[0] - pa[0]) + n[1] * (c[1] - pa[1]) + n[2] * (c[2] - pa[2]) - r
    dist[k] = d
    reach = r + d
    for a in range(3):
        normal[k, a] = n[a]
        point[k, a] = c[a] - n[a] * reach


@njit(cache=True)
def _point_box(c, r, pb, Rb, sb, k, dist, normal, point):
    """Contact k of a sphere (centre c, radius r; r = 0: a point) and a box (centre pb, axes Rb, half sizes sb), the
    normal from the sphere towards the box: along the line to the box's nearest point, or, with the centre inside
    the box, against the outward normal of the face of least depth."""
    l0 = Rb[0, 0] * (c[0] - pb[0]) + Rb[1, 0] * (c[1] - pb[1]) + Rb[2, 0] * (c[2] - pb[2])  # c in the box's axes
    l1 = Rb[0, 1] * (c[0] - pb[0]) + Rb[1, 1] * (c[1] - pb[1]) + Rb[2, 1] * (c[2] - pb[2])
    l2 = Rb[0, 2] * (c[0] - pb[0]) + Rb[1, 2] * (c[1] - pb[1]) + Rb[2, 2] * (c[2] - pb[2])
    o0 = l0 - min(max(l0, -sb[0]), sb[0])  # the offset from the box's nearest point
    o1 = l1 - min(max(l1, -sb[1]), sb[1])
    o2 = l2 - min(max(l2, -sb[2]), sb[2])
    outside = o0 * o0 + o1 * o1 + o2 * o2
    on_face = True  # the nearest point on a face (its point there), else on an edge or a corner (midway)
    if outside > 0.0:
        length = np.sqrt(outside)
        d = length - r
        on_face = (o0 != 0.0) + (o1 != 0.0) + (o2 != 0.0) == 1
        for a in range(3):  # from the sphere towards the box: against the outward offset
            normal[k, a] = -(Rb[a, 0] * o0 + Rb[a, 1] * o1 + Rb[a, 2] * o2) / length
    else:  # the centre inside the box (or on its surface): out through the face of least depth
        face, depth, along = 0, sb[0] - abs(l0), l0
        if sb[1] - abs(l1) < depth:
            face, depth, along = 1, sb[1] - abs(l1), l1
        if sb[2] - abs(l2) < depth:
            face, depth, along = 2, sb[2] - abs(l2), l2
        side = 1.0 if along >= 0.0 else -1.0
        d = -depth - r
        for a in range(3):
            normal[k, a] = -side * Rb[a, face]
    dist[k] = d
    reach = r + d if on_face else r + 0.5 * d
    for a in range(3):
        point[k, a] = c[a] + normal[k, a] * reach


@njit(cache=True)
def segment_closest(p1, u1, l1, p2, u2, l2):
    """(s, t): the parameters of the closest points p1 + s u1 and p2 + t u2 of two segments with centres p1, p2,
    unit directions u1, u2 and half-lengths l1, l2 (s in [-l1, l1], t in [-l2, l2]); parallel segments: the
    midpoint of their overlap (or of the gap between them)."""
    rx, ry, rz = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    b = u1[0] * u2[0] + u1[1] * u2[1] + u1[2] * u2[2]
    c = u1[0] * rx + u1[1] * ry + u1[2] * rz
    f = u2[0] * rx + u2[1] * ry + u2[2] * rz
    denom = 1.0 - b * b
    if denom > 1e-12:
        s = (b * f - c) / denom
        s = min(max(s, -l1), l1)
    else:  # parallel: the middle of the overlap of segment 1 with segment 2's projection
        centre = -c  # p2 projected on line 1, in its parameter; segment 2 spans centre -+ l2 there
        lo, hi = centre - l2, centre + l2
        lo, hi = max(lo, -l1), min(hi, l1)
        s = 0.5 * (lo + hi) if lo <= hi else (l1 if centre > 0 else -l1)
        s = min(max(s, -l1), l1)
    t = b * s + f
    if t < -l2 or t > l2:
        t = min(max(t, -l2), l2)
        s = b * t - c
        s = min(max(s, -l1), l1)
    return s, t


@njit(cache=True, inline="always")
def _box_excess(c, u, t, h):
    """The squared distance [m^2] of the point c + t u from the box [-h, h] (box coordinates)."""
    value = 0.0
    for i in range(3):
        excess = abs(c[i] + t * u[i]) - h[i]
        if excess > 0.0:
            value += excess * excess
    return value


@njit(cache=True)
def segment_box_closest(c, u, half_length, h):
    """(t, lo, hi, squared): where the segment c + t u, t in [-half_length, half_length] (box coordinates: c (3,)
    [m], u (3,) unit), comes closest to the box [-h, h] (h (3,) half sizes [m]): the parameter t of the closest point
    and the least squared distance [m^2], exact: the squared distance sum_i max(|c_i + t u_i| - h_i, 0)^2 is convex
    and quadratic between the knots where the segment crosses a face's plane, and each piece's minimum is in closed
    form. [lo, hi] (holding t): the pieces along which the distance stays the least to 1e-12 of it, whole (a segment
    lying along a face: from knot to knot, the face's edges or the segment's ends); lo = hi = t otherwise."""
    knots = np.empty(8)
    knots[0] = -half_length
    n = 1
    for i in range(3):
        if u[i] != 0.0:
            for side in (-1.0, 1.0):
                t = (side * h[i] - c[i]) / u[i]
                if -half_length < t < half_length:
                    knots[n] = t
                    n += 1
    knots[n] = half_length
    n += 1
    knots[:n].sort()
    best, at = np.inf, -half_length
    for j in range(n - 1):
        a, b = knots[j], knots[j + 1]
        if not b > a:
            continue
        middle = 0.5 * (a + b)
        quad, lin = 0.0, 0.0  # the piece's squared distance: quad t^2 + 2 lin t + const
        for i in range(3):
            x = c[i] + middle * u[i]
            if x > h[i] or x < -h[i]:
                face = h[i] if x > 0.0 else -h[i]
                quad += u[i] * u[i]
                lin += u[i] * (c[i] - face)
        t = min(max(-lin / quad, a), b) if quad > 0.0 else middle  # constant over the piece: its middle
        value = _box_excess(c, u, t, h)
        if value < best:
            best, at = value, t
    level = best * (1.0 + 1e-12)
    lo, hi = at, at
    for j in range(n - 1):  # whole pieces within the level: convexity makes them one interval about `at`
        a, b = knots[j], knots[j + 1]
        if b > a and _box_excess(c, u, a, h) <= level and _box_excess(c, u, b, h) <= level:
            lo, hi = min(lo, a), max(hi, b)
    return at, lo, hi, best


@njit(cache=True, inline="always")
def segment_in_box(pa, Ra, pb, Rb, c, u):
    """c (3,), u (3,): a capsule's centre pa and axis Ra[:, 2] in the axes of the box at pb with axes Rb (as
    segment_box_closest takes them)."""
    for e in range(3):
        c[e] = Rb[0, e] * (pa[0] - pb[0]) + Rb[1, e] * (pa[1] - pb[1]) + Rb[2, e] * (pa[2] - pb[2])
        u[e] = Rb[0, e] * Ra[0, 2] + Rb[1, e] * Ra[1, 2] + Rb[2, e] * Ra[2, 2]


@njit(cache=True)
def capsule_box_slot(c, u, half_length, h, k):
    """(t, apart): the axis parameter [m] of a capsule-box candidate k (module docstring) of the segment c + t u
    (box coordinates, as segment_box_closest takes it), and whether it is APART in this configuration."""
    closest, lo, hi, _squared = segment_box_closest(c, u, half_length, h)
    if hi - lo > LYING_SPAN * half_length:  # lying along a face: the span's middle and its ends
        return (lo if k == 0 else (hi if k == 1 else 0.5 * (lo + hi))), False
    if k == 2:
        return closest, False
    end = -half_length if k == 0 else half_length
    return end, abs(end - closest) < LYING_SPAN * half_length  # an end: not where the closest point is


@njit(cache=True)
def _point_cylinder(c, r, pc, Rc, sc, k, dist, normal, point):
    """Contact k of a sphere (centre c, radius r) and a cylinder (centre pc, axes Rc, radius sc[0], half-length
    sc[1]), the normal from the sphere towards the cylinder (against the gradient of its distance)."""
    grad = np.empty(3)
    d = cylinder_distance(c, pc, Rc, sc[0], sc[1], grad) - r
    dist[k] = d
    along = abs(grad[0] * Rc[0, 2] + grad[1] * Rc[1, 2] + grad[2] * Rc[2, 2])
    reach = r + d if along >= 1.0 - 1e-12 else r + 0.5 * d  # a cap's: its point on the cap; side, rim: midway
    for a in range(3):
        normal[k, a] = -grad[a]
        point[k, a] = c[a] - grad[a] * reach


@njit(cache=True)
def _cylinder_slope(p, u, t, pc, Rc, radius, half, x, grad):
    """d/dt of the distance of p + t u from the cylinder (nondecreasing in t: the distance is convex)."""
    for a in range(3):
        x[a] = p[a] + t * u[a]
    cylinder_distance(x, pc, Rc, radius, half, grad)
    return grad[0] * u[0] + grad[1] * u[1] + grad[2] * u[2]


@njit(cache=True)
def _slope_bracket(p, u, half_length, pc, Rc, radius, half, level, inclusive, x, grad):
    """(a, b): where along the segment the distance's slope (nondecreasing) first reaches `level` (inclusive:
    slope >= level, else slope > level), bisected to the last bit: b the first point that does, a the last that
    does not (both -half_length when the start does, both half_length when the end does not)."""
    a, b = -half_length, half_length
    start = _cylinder_slope(p, u, a, pc, Rc, radius, half, x, grad)
    if start > level or (inclusive and start == level):
        return a, a
    end = _cylinder_slope(p, u, b, pc, Rc, radius, half, x, grad)
    if not (end > level or (inclusive and end == level)):
        return b, b
    for _ in range(200):
        m = 0.5 * (a + b)
        if m <= a or m >= b:
            break
        slope = _cylinder_slope(p, u, m, pc, Rc, radius, half, x, grad)
        if slope > level or (inclusive and slope == level):
            b = m
        else:
            a = m
    return a, b


@njit(cache=True)
def segment_cylinder_closest(p, u, half_length, pc, Rc, radius, half):
    """(t, lo, hi): the parameter t of the point of the segment p + t u (t in [-half_length, half_length], u unit)
    closest to the cylinder (centre pc, axes Rc, radius, half-length half), and [lo, hi] the interval where the
    distance's slope is within SLOPE_TOLERANCE of 0 (one point, unless the segment runs parallel to the side or a
    cap); t is its middle. The distance is convex along the segment, so its slope is nondecreasing: each end of the
    interval is found by bisection on the slope's sign, to the last bit of t."""
    x, grad = np.empty(3), np.empty(3)
    _a, lo = _slope_bracket(p, u, half_length, pc, Rc, radius, half, -SLOPE_TOLERANCE, True, x, grad)
    hi, _b = _slope_bracket(p, u, half_length, pc, Rc, radius, half, SLOPE_TOLERANCE, False, x, grad)
    if hi < lo:
        lo, hi = hi, lo
    return 0.5 * (lo + hi), lo, hi


@njit(cache=True, inline="always")
def rim_frame(Rc, n, w, v):
    """w, v (3,): the directions in a cylinder's caps (axis Rc[:, 2]) of its rim candidates: w the unit direction n
    (from the other geom towards the cylinder) projected onto the caps, v = axis x w; with n within UPRIGHT of the
    axis (standing on a face), the cylinder's own x and y axes."""
    a0, a1, a2 = Rc[0, 2], Rc[1, 2], Rc[2, 2]
    c0, c1, c2 = n[1] * a2 - n[2] * a1, n[2] * a0 - n[0] * a2, n[0] * a1 - n[1] * a0  # n x axis
    w[0], w[1], w[2] = a1 * c2 - a2 * c1, a2 * c0 - a0 * c2, a0 * c1 - a1 * c0  # axis x (n x axis) = n - (n.axis) axis,
    length = np.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])  # without its cancellation: a cap tilted by t from a
    # face has |w| = sin t, and n - (n.axis) axis carries an error of eps in each entry, which tilts w by eps / t and
    # lifts the lowest rim point by r eps / t (4e-12 m at t = 3e-5 rad, a cylinder settling on its cap)
    if length > UPRIGHT:
        for a in range(3):
            w[a] /= length
    else:
        for a in range(3):
            w[a] = Rc[a, 0]
    v[0] = Rc[1, 2] * w[2] - Rc[2, 2] * w[1]
    v[1] = Rc[2, 2] * w[0] - Rc[0, 2] * w[2]
    v[2] = Rc[0, 2] * w[1] - Rc[1, 2] * w[0]


@njit(cache=True, inline="always")
def rim_point(pc, Rc, sc, w, v, k, turn, out):
    """out (3,): rim candidate k of the cylinder (centre pc, axes Rc, radius sc[0], half-length sc[1]): k = 0-3 on
    the cap at +half, 4-7 at -half, at the angle 90 (k % 4) degrees + turn [rad] from -w (the point lowest towards
    the other geom, rim_frame) towards -v."""
    cap = sc[1] if k < 4 else -sc[1]
    angle = turn + 0.5 * np.pi * (k % 4)
    cw, cv = -sc[0] * np.cos(angle), -sc[0] * np.sin(angle)
    if turn == 0.0:  # the quarter turns exactly
        j = k % 4
        cw = -sc[0] if j == 0 else (sc[0] if j == 2 else 0.0)
        cv = -sc[0] if j == 1 else (sc[0] if j == 3 else 0.0)
    for a in range(3):
        out[a] = pc[a] + cap * Rc[a, 2] + cw * w[a] + cv * v[a]


@njit(cache=True, inline="always")
def convex_distance(kind, x, pc, Rc, sc, grad):
    """The signed distance [m] of the point x (3,) from a box or a cylinder (kind, centre pc, axes Rc, size sc),
    grad (3,) its gradient (the outward normal at the nearest surface point)."""
    if kind == CYLINDER:
        return cylinder_distance(x, pc, Rc, sc[0], sc[1], grad)
    return box_distance(x, pc, Rc, sc, grad)


@njit(cache=True)
def _rim_slope(pc, Rc, sc, w, v, cap, turn, kind, po, Ro, so, x, grad):
    """d/d(turn) of the distance from the other geom (kind, po, Ro, so) of the rim point of cap `cap` (0: +half,
    4: -half) turned by `turn` from the lowest."""
    rim_point(pc, Rc, sc, w, v, cap, turn, x)
    convex_distance(kind, x, po, Ro, so, grad)
    s, c = np.sin(turn), np.cos(turn)  # d rim / d turn = r (sin w - cos v)
    slope = 0.0
    for a in range(3):
        slope += grad[a] * sc[0] * (s * w[a] - c * v[a])
    return slope


@njit(cache=True)
def rim_lowest_turn(pc, Rc, sc, w, v, cap, kind, po, Ro, so):
    """The turn [rad] from -w at which the rim of cap `cap` (0 or 4) comes closest to the other geom (a box or a
    cylinder; the distance along a circle need not be convex): the least of RIM_SAMPLES points around the rim (-w
    first, kept unless another is nearer by more than 1e-12 m: a rim lying on a face stays put), then the zero of
    the distance's slope within one sample's spacing of it, to the last bit (false position, Illinois)."""
    x, grad = np.empty(3), np.empty(3)
    best, at = np.inf, 0.0
    for i in range(RIM_SAMPLES):
        turn = 2.0 * np.pi * i / RIM_SAMPLES
        if turn > np.pi:
            turn -= 2.0 * np.pi
        rim_point(pc, Rc, sc, w, v, cap, turn, x)
        d = convex_distance(kind, x, po, Ro, so, grad)
        if d < best - 1e-12:
            best, at = d, turn
    spacing = 2.0 * np.pi / RIM_SAMPLES
    a, b = at - spacing, at + spacing
    fa = _rim_slope(pc, Rc, sc, w, v, cap, a, kind, po, Ro, so, x, grad)
    fb = _rim_slope(pc, Rc, sc, w, v, cap, b, kind, po, Ro, so, x, grad)
    if not (fa < -SLOPE_TOLERANCE and fb > SLOPE_TOLERANCE):
        return at  # no minimum within the spacing (a rim lying on a face: the slope is 0 all along)
    # the slope's zero by false position with the Illinois step (superlinear), the bracket kept
    side = 0
    for _ in range(100):
        m = (a * fb - b * fa) / (fb - fa)
        if not (a < m < b):
            m = 0.5 * (a + b)
        if m <= a or m >= b:
            break
        fm = _rim_slope(pc, Rc, sc, w, v, cap, m, kind, po, Ro, so, x, grad)
        if fm == 0.0:
            return m
        if fm < 0.0:
            a, fa = m, fm
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b, fb = m, fm
            if side == 1:
                fa *= 0.5
            side = 1
        if b - a <= 4e-16 * max(abs(a), abs(b), 1.0):
            break
    return 0.5 * (a + b) if b - a <= 4e-16 * max(abs(a), abs(b), 1.0) else m


@njit(cache=True)
def _rim_candidates(pc, Rc, sc, kind, po, Ro, so, first, flip, only, dist, normal, point, scratch):
    """Slots first to first + 7: a cylinder's (pc, Rc, sc) rim candidates against a box or a cylinder (kind, po, Ro,
    so): each cap's rim point closest to the other geom (rim_lowest_turn, from the direction of the other geom's
    distance gradient at the cylinder's centre) and those at 90, 180 and 270 degrees from it, each point's exact
    distance from the other geom. flip: the cylinder is geom b (normals turned to point from a to b)."""
    n, w, v, x = scratch[0:3], scratch[3:6], scratch[6:9], scratch[9:12]
    convex_distance(kind, pc, po, Ro, so, n)
    rim_frame(Rc, n, w, v)
    for cap in (0, 4):
        if only >= 0 and not (first + cap <= only < first + cap + 4):
            continue
        turn = rim_lowest_turn(pc, Rc, sc, w, v, cap, kind, po, Ro, so)
        for j in range(4):
            k = first + cap + j
            if only >= 0 and k != only:
                continue
            rim_point(pc, Rc, sc, w, v, cap + j, turn, x)
            if kind == BOX:
                _point_box(x, 0.0, po, Ro, so, k, dist, normal, point)
            else:
                _point_cylinder(x, 0.0, po, Ro, so, k, dist, normal, point)
            if flip:
                for a in range(3):
                    normal[k, a] = -normal[k, a]


@njit(cache=True, inline="always")
def _box_corner(pb, Rb, sb, c, out):
    """out (3,): corner c (0-7; bits: +x, +y, +z) of the box (centre pb, axes Rb, half sizes sb)."""
    x = sb[0] if c & 1 else -sb[0]
    y = sb[1] if c & 2 else -sb[1]
    z = sb[2] if c & 4 else -sb[2]
    for a in range(3):
        out[a] = pb[a] + Rb[a, 0] * x + Rb[a, 1] * y + Rb[a, 2] * z


@njit(cache=True)
def _box_edge_candidate(pc, Rc, sc, pb, Rb, sb, k, dist, normal, point, work):
    """Slot k of a cylinder (pc, Rc, sc: geom a) and a box (pb, Rb, sb: geom b): the point of the box's edges closest
    to the cylinder (each edge's by segment_cylinder_closest, exact), the normal from a to b."""
    centre, u, x, grad = work[0:3], work[3:6], work[6:9], work[9:12]
    best, best_t = np.inf, 0.0
    best_centre, best_u = np.empty(3), np.empty(3)
    for axis in range(3):  # the 4 edges along each box axis
        o1, o2 = (axis + 1) % 3, (axis + 2) % 3
        for corner in range(4):
            s1 = sb[o1] if corner & 1 else -sb[o1]
            s2 = sb[o2] if corner & 2 else -sb[o2]
            for a in range(3):
                centre[a] = pb[a] + Rb[a, o1] * s1 + Rb[a, o2] * s2
                u[a] = Rb[a, axis]
            t, _lo, _hi = segment_cylinder_closest(centre, u, sb[axis], pc, Rc, sc[0], sc[1])
            for a in range(3):
                x[a] = centre[a] + t * u[a]
            d = cylinder_distance(x, pc, Rc, sc[0], sc[1], grad)
            if d < best:
                best, best_t = d, t
                best_centre[:] = centre
                best_u[:] = u
    for a in range(3):
        x[a] = best_centre[a] + best_t * best_u[a]
    _point_cylinder(x, 0.0, pc, Rc, sc, k, dist, normal, point)
    for a in range(3):  # from the edge (b) towards the cylinder: turned to point from a to b
        normal[k, a] = -normal[k, a]


@njit(cache=True, inline="always")
def _unless_held(dist, k, count):
    """Slot k APART where another of the pair's count slots comes within 1e-12 m of its distance: that slot holds
    the same contact (a box's edge closest to a cylinder at a corner, at the rim point a rim slot found, or at an end
    of a face's line along the side), and two candidates of one contact would make the step's problem singular."""
    for j in range(count):
        if j != k and dist[j] <= dist[k] + 1e-12:
            dist[k] = APART
            return


@njit(cache=True, inline="always")
def _polytope_plane(kind, size, hull, f, m):
    """Face plane f of a box (kind BOX: 0-5, +-x, +-y, +-z; size its half sizes) or of a mesh's hull (its F face
    planes): m (3,) its unit outward normal and the returned offset d [m], inside m.x <= d, in the geom's frame."""
    if kind == BOX:
        axis, sign = f // 2, (1.0 if f % 2 == 0 else -1.0)
        m[0], m[1], m[2] = 0.0, 0.0, 0.0
        m[axis] = sign
        return size[axis]
    at = 3 + 3 * int(hull[0]) + 4 * f
    m[0], m[1], m[2] = hull[at], hull[at + 1], hull[at + 2]
    return hull[at + 3]


@njit(cache=True)
def _side_line(ta, pc, Rc, sc, kind, po, Ro, so, ho, k, dist, normal, point):
    """Slots k, k + 1 of a cylinder or a capsule (ta; pc, Rc, sc: geom a) and a polytope (kind BOX or MESH at po,
    axes Ro, size so, hull ho: geom b): a face of the polytope lying along the round geom's side touches it along a
    segment of the side's line nearest that face; these are the segment's ends, the points of the face's boundary
    over that line, each with its exact signed distance from the round geom (a point of the polytope's surface
    against the other geom), the normal the side's. The face is the polytope's separating one (the greatest of min
    over the round geom of m.x - d, m its outward normal); the line: the side's points along -m made perpendicular
    to the axis (w), at t in [-half, half] along the axis, each carried along w onto the face's plane, and kept
    inside every other face's half-space. An end within LYING_SPAN of the half-length from a rim (a capsule's end
    sphere) is APART (that rim's or end's slots hold it), and both where the span is shorter than that (a corner or
    an edge holds the contact) or the face meets the caps (no line). Returns the span's length [m] along the axis
    (0 where there is none)."""
    nf = 6 if kind == BOX else int(ho[1])
    radius, half = sc[0], sc[1]
    q, u, m, w, c = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    segment_in_box(pc, Rc, po, Ro, q, u)  # the round geom's centre and axis in the polytope's frame
    face, best = -1, -np.inf
    for f in range(nf):  # the separating face: the least m.x less d, m.x = m.q - r |m_perp| - half |m.u| on a
        d = _polytope_plane(kind, so, ho, f, m)  # cylinder, m.q - r - half |m.u| on a capsule
        along = m[0] * u[0] + m[1] * u[1] + m[2] * u[2]
        across = np.sqrt(max(1.0 - along * along, 0.0)) if ta == CYLINDER else 1.0
        gap = m[0] * q[0] + m[1] * q[1] + m[2] * q[2] - radius * across - half * abs(along) - d
        if gap > best:
            face, best = f, gap
    dist[k], dist[k + 1] = APART, APART
    d = _polytope_plane(kind, so, ho, face, m)
    along = m[0] * u[0] + m[1] * u[1] + m[2] * u[2]
    across = 0.0
    for e in range(3):
        w[e] = along * u[e] - m[e]  # the side's direction towards the face, perpendicular to the axis
        across += w[e] * w[e]
    across = np.sqrt(across)
    if across < 1e-12:  # the face meets a cap: no line
        return 0.0
    for e in range(3):
        w[e] /= across
    # the side's line q + r w + t u carried along w onto the face's plane m.x = d (m.w = -across): c + t v
    offset = (m[0] * q[0] + m[1] * q[1] + m[2] * q[2] - radius * across - d) / across
    v = np.empty(3)
    for e in range(3):
        c[e] = q[e] + (radius + offset) * w[e]
        v[e] = u[e] + along / across * w[e]
    lo, hi = -half, half
    for f in range(nf):  # the face's line inside every other face's half-space: m.(c + t v) <= d
        if f == face:
            continue
        d = _polytope_plane(kind, so, ho, f, m)
        rate = m[0] * v[0] + m[1] * v[1] + m[2] * v[2]
        room = d - (m[0] * c[0] + m[1] * c[1] + m[2] * c[2])
        if rate > 0.0:
            hi = min(hi, room / rate)
        elif rate < 0.0:
            lo = max(lo, room / rate)
        elif room < 0.0:
            return 0.0
    if not hi - lo > LYING_SPAN * half:
        return 0.0
    x, centre = np.empty(3), np.empty(3)
    for end in range(2):
        t = lo if end == 0 else hi
        if abs(t) > (1.0 - LYING_SPAN) * half:  # at a rim or a capsule's end: its slots hold it
            continue
        for a in range(3):
            x[a] = po[a] + Ro[a, 0] * (c[0] + t * v[0]) + Ro[a, 1] * (c[1] + t * v[1]) + Ro[a, 2] * (c[2] + t * v[2])
        if ta == CYLINDER:
            _point_cylinder(x, 0.0, pc, Rc, sc, k + end, dist, normal, point)
            for a in range(3):  # from the face's point (b) towards the cylinder: turned to point from a to b
                normal[k + end, a] = -normal[k + end, a]
        else:  # a capsule: the point's distance from its segment, less the radius
            along = 0.0
            for a in range(3):
                along += (x[a] - pc[a]) * Rc[a, 2]
            along = min(max(along, -half), half)
            for a in range(3):
                centre[a] = pc[a] + along * Rc[a, 2]
            _sphere_sphere(centre, radius, x, 0.0, k + end, dist, normal, point)
    return hi - lo


@njit(cache=True)
def _line_ends_hold(dist, point, k, first, last, reach):
    """A line end (slot k, k + 1 of _side_line) and another slot, first to last - 1, within reach [m] of each other
    hold one contact: the lower keeps it (the end where they tie within 1e-12 m), the other is APART."""
    for end in range(k, k + 2):
        for j in range(first, last):
            if dist[end] == APART:
                break
            if dist[j] == APART:
                continue
            near = True
            for a in range(3):
                if abs(point[j, a] - point[end, a]) > reach:
                    near = False
            if near:
                if dist[end] <= dist[j] + 1e-12:
                    dist[j] = APART
                else:
                    dist[end] = APART


@njit(cache=True, inline="always")
def _box_edge(p, R, s, e, centre, u, m1, m2):
    """Edge e (0-11) of the box (centre p, axes R, half sizes s): along axis e // 4, at the signs of bits 0 and 1 of
    e % 4 on the two other axes; centre (3,), unit direction u (3,) and the outward normals m1, m2 (3,) of its two
    faces written, its half-length returned."""
    axis = e // 4
    o1, o2 = (axis + 1) % 3, (axis + 2) % 3
    g1 = 1.0 if e & 1 else -1.0
    g2 = 1.0 if e & 2 else -1.0
    for a in range(3):
        centre[a] = p[a] + R[a, o1] * g1 * s[o1] + R[a, o2] * g2 * s[o2]
        u[a] = R[a, axis]
        m1[a], m2[a] = g1 * R[a, o1], g2 * R[a, o2]
    return s[axis]


CONE_SLACK = 1e-12  # a common perpendicular within this (a cosine) of an edge's face normals lies in its cone


@njit(cache=True)
def box_edges_closest(pa, Ra, sa, pb, Rb, sb, axes, ca, ua, cb, ub):
    """The crossing of two boxes' edges nearest to contact: of the 144 pairs of edges, one of each box, those that
    can touch edge on edge (their closest points, Ericson's, inside both edges; their common perpendicular n =
    ua x ub, oriented outward from box a at its edge, within the cone of a's two face normals there, and -n within
    b's: the separating-axis test's condition for an edge-edge axis; the others touch at a corner or a face, which
    the corner candidates hold), the one of greatest signed distance along n: the separating-axis test's
    separation along each such axis is at most the boxes' distance (and at most minus their overlap), so the
    greatest is the edges that touch first (other pairs, a far edge of one against a far edge of the other, project
    overlapping). axes (3, 3, 3): edge_axes's common perpendiculars. ca, ua (3,) and cb, ub (3,) their centres and
    directions written; returns (s, t, distance), the closest points ca + s ua and cb + t ub; distance +inf where no
    pair can."""
    best, bs, bt = -np.inf, 0.0, 0.0
    small = carray(stack_floats(168), 168)  # the vectors below, on the stack (no allocation per pair of boxes)
    c1, u1, m1, m2 = cut(small, 0, 3), cut(small, 3, 3), cut(small, 6, 3), cut(small, 9, 3)
    c2, u2, k1, k2 = cut(small, 12, (12, 3)), cut(small, 48, (12, 3)), cut(small, 84, (12, 3)), cut(small, 120, (12, 3))
    hb = cut(small, 156, 12)
    for eb in range(12):  # b's edges once, not once per edge of a
        hb[eb] = _box_edge(pb, Rb, sb, eb, c2[eb], u2[eb], k1[eb], k2[eb])
    for ea in range(12):
        ha = _box_edge(pa, Ra, sa, ea, c1, u1, m1, m2)
        for eb in range(12):
            n0, n1, n2 = axes[ea // 4, eb // 4, 0], axes[ea // 4, eb // 4, 1], axes[ea // 4, eb // 4, 2]
            if n0 == 0.0 and n1 == 0.0 and n2 == 0.0:
                continue
            if n0 * (m1[0] + m2[0]) + n1 * (m1[1] + m2[1]) + n2 * (m1[2] + m2[2]) < 0.0:
                n0, n1, n2 = -n0, -n1, -n2  # outward from a: towards its two faces' normals
            if (n0 * m1[0] + n1 * m1[1] + n2 * m1[2] < -CONE_SLACK or n0 * m2[0] + n1 * m2[1] + n2 * m2[2] < -CONE_SLACK
                    or n0 * k1[eb, 0] + n1 * k1[eb, 1] + n2 * k1[eb, 2] > CONE_SLACK
                    or n0 * k2[eb, 0] + n1 * k2[eb, 1] + n2 * k2[eb, 2] > CONE_SLACK):
                continue  # not an edge-edge axis: a face or a corner touches first
            s, t = segment_closest(c1, u1, ha, c2[eb], u2[eb], hb[eb])
            if not (abs(s) < ha and abs(t) < hb[eb]):  # beyond an edge's end: a corner's contact
                continue
            d = (n0 * (c2[eb, 0] + t * u2[eb, 0] - c1[0] - s * u1[0])
                 + n1 * (c2[eb, 1] + t * u2[eb, 1] - c1[1] - s * u1[1])
                 + n2 * (c2[eb, 2] + t * u2[eb, 2] - c1[2] - s * u1[2]))
            if d > best:
                best, bs, bt = d, s, t
                for a in range(3):
                    ca[a], ua[a], cb[a], ub[a] = c1[a], u1[a], c2[eb, a], u2[eb, a]
    return bs, bt, (best if best > -np.inf else np.inf)


@njit(cache=True)
def edge_axes(Ra, Rb, axes):
    """axes (3, 3, 3): the unit common perpendicular of box a's axis i and box b's axis j at axes[i, j] (0 where the
    two are parallel: an edge along an edge, held by the corners)."""
    for i in range(3):
        for j in range(3):
            v1, v2 = Ra[:, i], Rb[:, j]
            n0, n1, n2 = v1[1] * v2[2] - v1[2] * v2[1], v1[2] * v2[0] - v1[0] * v2[2], v1[0] * v2[1] - v1[1] * v2[0]
            length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            if length < 1e-9:
                length = np.inf
            axes[i, j, 0], axes[i, j, 1], axes[i, j, 2] = n0 / length, n1 / length, n2 / length


@njit(cache=True, inline="always")
def _axis_separation(l0, l1, l2, pa, Ra, sa, pb, Rb, sb):
    """The separation [m] of two boxes along the unit axis l: |l . (pb - pa)| less each box's half extent along l."""
    gap = abs(l0 * (pb[0] - pa[0]) + l1 * (pb[1] - pa[1]) + l2 * (pb[2] - pa[2]))
    for j in range(3):
        gap -= (abs(l0 * Ra[0, j] + l1 * Ra[1, j] + l2 * Ra[2, j]) * sa[j]
                + abs(l0 * Rb[0, j] + l1 * Rb[1, j] + l2 * Rb[2, j]) * sb[j])
    return gap


@njit(cache=True)
def _face_separation(pa, Ra, sa, pb, Rb, sb):
    """The greatest separation [m] of two boxes along their 6 face normals (the separating-axis test's face axes)."""
    best = -np.inf
    for which in range(2):
        R = Ra if which == 0 else Rb
        for i in range(3):
            best = max(best, _axis_separation(R[0, i], R[1, i], R[2, i], pa, Ra, sa, pb, Rb, sb))
    return best


EDGE_BOUND_SLACK = 1e-9  # [m] above the round-off of _edge_axes_separation and of a crossing's distance


@njit(cache=True)
def _edge_axes_separation(pa, Ra, sa, pb, Rb, sb, axes):
    """The greatest separation [m] of two boxes along the 9 cross products of their axes (the separating-axis
    test's edge axes, edge_axes's), parallel axes left out: an upper bound on the signed distance of any crossing of
    their edges (box_edges_closest: at a crossing each edge is its box's support along the axis, and the distance is
    the separation along it)."""
    best = -np.inf
    for i in range(3):
        for j in range(3):
            l0, l1, l2 = axes[i, j, 0], axes[i, j, 1], axes[i, j, 2]
            if l0 == 0.0 and l1 == 0.0 and l2 == 0.0:
                continue
            best = max(best, _axis_separation(l0, l1, l2, pa, Ra, sa, pb, Rb, sb))
    return best


@njit(cache=True)
def _box_edge_pair(pa, Ra, sa, pb, Rb, sb, k, dist, normal, point):
    """Slot k of two boxes: the crossing of their edges nearest to contact (box_edges_closest), its signed distance
    (< 0: the edges crossed, an overlap of that depth), the normal from a to b along the edges' common
    perpendicular, the point midway; APART where no two edges cross, or where a face's axis separates the boxes
    more than the edges' does (the separating-axis test: the contact is a face's)."""
    face = _face_separation(pa, Ra, sa, pb, Rb, sb)
    small = carray(stack_floats(39), 39)  # the vectors below, on the stack (no allocation per pair of boxes)
    axes = cut(small, 0, (3, 3, 3))
    edge_axes(Ra, Rb, axes)
    if _edge_axes_separation(pa, Ra, sa, pb, Rb, sb, axes) + EDGE_BOUND_SLACK < face - 1e-12:
        dist[k] = APART  # every crossing's distance is at most its axis's separation: a face's (the 144 pairs
        return           # spared where boxes rest face on face)
    ca, ua, cb, ub = cut(small, 27, 3), cut(small, 30, 3), cut(small, 33, 3), cut(small, 36, 3)
    s, t, d = box_edges_closest(pa, Ra, sa, pb, Rb, sb, axes, ca, ua, cb, ub)
    if d < face - 1e-12:
        d = APART  # a face's axis separates them more: they touch face first (a face's corners hold that)
    dist[k] = d
    if d == APART:
        return
    n0, n1, n2 = ua[1] * ub[2] - ua[2] * ub[1], ua[2] * ub[0] - ua[0] * ub[2], ua[0] * ub[1] - ua[1] * ub[0]
    length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if n0 * (ca[0] + s * ua[0] - pa[0]) + n1 * (ca[1] + s * ua[1] - pa[1]) + n2 * (ca[2] + s * ua[2] - pa[2]) < 0:
        length = -length  # outward from a (its centre behind its edge)
    normal[k, 0], normal[k, 1], normal[k, 2] = n0 / length, n1 / length, n2 / length
    for a in range(3):
        point[k, a] = 0.5 * (ca[a] + s * ua[a] + cb[a] + t * ub[a])


@njit(cache=True)
def point_distance(kind, pos, mat, size, hull, x, grad):
    """The signed distance [m] of the point x (3,) from a geom (kind, centre pos, axes mat, size; hull: a mesh's
    packed convex hull) and grad (3,) its gradient, the outward normal at the nearest surface point: closed form
    for spheres, capsules, boxes and cylinders, exact for a mesh's hull (its face planes inside, the hull's nearest
    point outside: rbody.engine.contacts.convex.point_signed_distance), Eberly's root for an ellipsoid."""
    if kind == ELLIPSOID:
        return ellipsoid_distance(x, pos, mat, size, grad)
    return point_signed_distance(kind, pos, mat, size, hull, x, grad)


@njit(cache=True)
def _point_against(x, kind, pos, mat, size, hull, own_is_b, k, dist, normal, point, grad):
    """Slot k: the point x (3,) of one geom's surface against the other geom (kind, pos, mat, size, hull): its
    exact signed distance, the normal from geom a to geom b (own_is_b: x is on geom b, so the normal is the other
    geom's outward gradient; else against it) and the point on the other geom's surface nearest to x, where x,
    closing, will touch."""
    d = point_distance(kind, pos, mat, size, hull, x, grad)
    dist[k] = d
    sign = 1.0 if own_is_b else -1.0
    for a in range(3):
        normal[k, a] = sign * grad[a]
        point[k, a] = x[a] - d * grad[a]


@njit(cache=True, inline="always")
def _same_point_as(point, k, j):
    """True when slots k and j hold the same point (to 1e-12 m)."""
    return (abs(point[j, 0] - point[k, 0]) <= 1e-12 and abs(point[j, 1] - point[k, 1]) <= 1e-12
            and abs(point[j, 2] - point[k, 2]) <= 1e-12)


@njit(cache=True, inline="always")
def _same_point(point, k, first):
    """True when slot k's point repeats one of slots first..k-1 (the same vertex found by two directions)."""
    for j in range(first, k):
        if _same_point_as(point, k, j):
            return True
    return False


@njit(cache=True, inline="always")
def _fill(dist, normal, point, k, count):
    """Every slot of count given slot k's distance, normal and point (the pair's least distance: a lower bound of
    each slot's own)."""
    for j in range(count):
        if j != k:
            dist[j] = dist[k]
            for a in range(3):
                normal[j, a], point[j, a] = normal[k, a], point[k, a]


@njit(cache=True)
def _plane_hull(pa, Ra, pb, Rb, sb, hb, dist, normal, point, beyond):
    """A plane (pa, normal Ra[:, 2]) and a mesh's hull (pb, Rb, sb, hb): slot 0 its vertex lowest towards the plane
    (the support along -n), slots 1-8 its supports along -n tilted by TILT towards the plane's own axes at 45
    degree steps (a face lying on the plane: its extreme vertices in those directions); each vertex's height above
    the plane, exact. A vertex found twice is APART where it repeats: in a later tilted slot, and in slot 0 where a
    tilted slot holds it (as _patch keeps its vertex slots over its closest points). A face landing nearly flat
    keeps each vertex in its tilted slot whichever of them is lowest; slot 0 moving from vertex to vertex as they
    trade places (0.4 degrees from flat) carried one slot's impulse and projection over to another vertex, and the
    projection after the landing stalled at 9e-9 m. Returns 9 (the lowest vertex's height beyond `beyond`: every
    slot that)."""
    direction, x = np.empty(3), np.empty(3)
    for k in range(1 + PATCH):
        for a in range(3):
            direction[a] = -Ra[a, 2]
            if k > 0:
                direction[a] += TILT * (PATCH_COS[k - 1] * Ra[a, 0] + PATCH_SIN[k - 1] * Ra[a, 1])
        support(MESH, pb, Rb, sb, hb, direction, x)
        d = Ra[0, 2] * (x[0] - pa[0]) + Ra[1, 2] * (x[1] - pa[1]) + Ra[2, 2] * (x[2] - pa[2])
        dist[k] = d
        for a in range(3):
            normal[k, a] = Ra[a, 2]
            point[k, a] = x[a] - d * Ra[a, 2]  # on the plane (one vertex, one foot: supports along -n + tilt)
        if _same_point(point, k, 1):  # a later tilted slot repeating an earlier one's
            dist[k] = APART
        if k == 0 and d > beyond:
            _fill(dist, normal, point, 0, 1 + PATCH)
            return 1 + PATCH
    for k in range(1, 1 + PATCH):  # the lowest vertex held by a tilted slot: slot 0 gives it up
        if dist[k] != APART and _same_point_as(point, k, 0):
            dist[0] = APART
            break
    return 1 + PATCH


@njit(cache=True)
def _closest_pair(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, k, dist, normal, point, n, xa, xb):
    """Slot k: the two geoms' closest points (their signed distance by GJK, or EPA where they overlap:
    rbody.engine.contacts.convex), the normal n (3,) from a to b, the point midway; xa, xb (3,) the witnesses."""
    guess = np.empty(3)
    for a in range(3):
        guess[a] = pb[a] - pa[a]
    d = signed_distance(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, guess, n, xa, xb)
    dist[k] = d
    for a in range(3):
        normal[k, a] = n[a]
        point[k, a] = 0.5 * (xa[a] + xb[a])
    return d


@njit(cache=True)
def _patch(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, dist, normal, point, beyond):
    """Two convex geoms of which one at least is a polytope (a mesh's hull; a box, a cylinder): 17 candidates, every
    one the exact signed distance of a point of one surface from the other geom. Slot 16 their closest points
    (GJK/EPA), its normal n from a to b; slots 0-7 geom b's supports along -n tilted by TILT around n at 45 degree
    steps against geom a, slots 8-15 geom a's along +n against geom b: a face lying on a face rests on both faces'
    extreme vertices (the patch), an edge on a face on its ends; against a cylinder (geom a) slots 17 and 18, the
    ends of a hull's face's line along its side (_side_line). A point found twice is APART, and slot 16 where
    another slot holds it (as close to 1e-12 m). Returns 17, or 19 with a cylinder. Closest points beyond `beyond`:
    every slot those.
    """
    count = 19 if ta == CYLINDER else 17
    n, xa, xb, t1, t2 = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    direction, x, grad = np.empty(3), np.empty(3), np.empty(3)
    if _closest_pair(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, 16, dist, normal, point, n, xa, xb) > beyond:
        _fill(dist, normal, point, 16, count)
        return count
    tangents(n, t1, t2)
    for k in range(16):
        own_is_b = k < PATCH
        sign = -1.0 if own_is_b else 1.0  # b faces a along -n, a faces b along +n
        j = k % PATCH
        for a in range(3):
            direction[a] = sign * n[a] + TILT * (PATCH_COS[j] * t1[a] + PATCH_SIN[j] * t2[a])
        if own_is_b:
            support(tb, pb, Rb, sb, hb, direction, x)
            _point_against(x, ta, pa, Ra, sa, ha, True, k, dist, normal, point, grad)
        else:
            support(ta, pa, Ra, sa, ha, direction, x)
            _point_against(x, tb, pb, Rb, sb, hb, False, k, dist, normal, point, grad)
        # the vertex itself, for the repeat test: the point stored is on the other surface, x - d grad
        if _same_support(point, dist, normal, k, 0 if own_is_b else PATCH, own_is_b):
            dist[k] = APART
    if ta == CYLINDER:  # a hull's face lying along the side: the ends of their line (17, 18)
        span = _side_line(CYLINDER, pa, Ra, sa, MESH, pb, Rb, sb, hb, 17, dist, normal, point)
        _line_ends_hold(dist, point, 17, 0, 17, LYING_SPAN * span)
    _unless_held(dist, 16, count)
    return count


@njit(cache=True, inline="always")
def _same_support(point, dist, normal, k, first, own_is_b):
    """True when slot k's support point (its stored point moved back by its distance along its normal) repeats one
    of slots first..k-1 of its group."""
    sign = 1.0 if own_is_b else -1.0  # x = point + d * (sign * normal)
    for j in range(first, k):
        if dist[j] == APART:
            continue
        same = True
        for a in range(3):
            xj = point[j, a] + dist[j] * sign * normal[j, a]
            xk = point[k, a] + dist[k] * sign * normal[k, a]
            if abs(xj - xk) > 1e-12:
                same = False
        if same:
            return True
    return False


@njit(cache=True)
def _general(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, dist, normal, point, beyond):
    """The pairs with an ellipsoid or a mesh (SLOTS). Returns their count, or -1 for a pair not computed. beyond:
    collide's."""
    n, xa, xb, grad = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    if ta == PLANE:
        if tb == ELLIPSOID:  # the ellipsoid's lowest point, closed form
            for a in range(3):
                n[a] = Ra[a, 2]
            d = plane_ellipsoid(pa, n, pb, Rb, sb, xb)
            dist[0] = d
            for a in range(3):
                normal[0, a] = n[a]
                point[0, a] = xb[a] - d * n[a]  # on the plane
            return 1
        if tb == MESH:
            return _plane_hull(pa, Ra, pb, Rb, sb, hb, dist, normal, point, beyond)
        return -1
    if ta == SPHERE:  # the centre's distance from the other geom, less the radius
        d = point_distance(tb, pb, Rb, sb, hb, pa, grad)
        dist[0] = d - sa[0]
        for a in range(3):
            normal[0, a] = -grad[a]
            point[0, a] = pa[a] - grad[a] * (sa[0] + 0.5 * dist[0])  # midway
        return 1
    if ta == CAPSULE:  # the segment's closest point (2), its ends (0, 1) APART within LYING_SPAN of it; with a
        u = Ra[:, 2]   # mesh, a face's line along the side (3, 4)
        if tb == ELLIPSOID:
            closest, _lo, _hi = segment_ellipsoid_closest(pa, u, sa[1], pb, Rb, sb)
        else:  # a mesh: the closest points of the capsule's segment and the hull
            if _closest_pair(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, 2, dist, normal, point, n, xa, xb) > beyond:
                _fill(dist, normal, point, 2, 5)
                return 5
            closest = 0.0
            for a in range(3):
                closest += (xa[a] - sa[0] * n[a] - pa[a]) * u[a]  # the segment's point: the witness less r n
            closest = min(max(closest, -sa[1]), sa[1])
        centre = np.empty(3)
        for k in range(3):
            t = closest if k == 2 else (-sa[1] if k == 0 else sa[1])
            for a in range(3):
                centre[a] = pa[a] + t * u[a]
            d = point_distance(tb, pb, Rb, sb, hb, centre, grad)
            dist[k] = d - sa[0]
            for a in range(3):
                normal[k, a] = -grad[a]
                point[k, a] = centre[a] - grad[a] * (sa[0] + 0.5 * dist[k])
            if k < 2 and abs(t - closest) < LYING_SPAN * sa[1]:
                dist[k] = APART
        if tb == ELLIPSOID:
            return 3
        span = _side_line(CAPSULE, pa, Ra, sa, MESH, pb, Rb, sb, hb, 3, dist, normal, point)
        _line_ends_hold(dist, point, 3, 0, 3, LYING_SPAN * span)
        if dist[3] <= dist[2] + 1e-12 and dist[4] <= dist[2] + 1e-12:  # the closest point along a face's line,
            dist[2] = APART  # its two ends held (where one is at an end sphere, 0, 1 or 2 holds that one)
        return 5
    if ta == ELLIPSOID:  # strictly convex: one point of contact
        _closest_pair(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, 0, dist, normal, point, n, xa, xb)
        return 1
    if tb == MESH:  # a cylinder, a box or a mesh with a mesh
        return _patch(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, dist, normal, point, beyond)
    return -1


COLLIDE_WORK = 12  # the floats of collide's scratch


@njit(cache=True, inline="always")
def answers_beyond(ta, tb):
    """Whether collide computes the pair of types ta <= tb by _general (an ellipsoid's or a mesh's pairs), which
    may answer `beyond` with the pair's least distance in every slot; the others write every slot exactly."""
    return tb == MESH or tb == ELLIPSOID or ta == ELLIPSOID


@njit(cache=True)
def collide(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, dist, normal, point, only=-1, beyond=np.inf, scratch=None):
    """The candidate contacts of geom a (type ta <= tb, centre pa (3,) [m], axes Ra (3, 3), size sa (3,) [m]; ha a
    mesh's packed convex hull, rbody.engine.contacts.convex.pack_hull, else empty) and geom b, into dist
    (MAX_SLOTS,) [m], normal (MAX_SLOTS, 3) from a to b and point (MAX_SLOTS, 3) [m]; returns their count (SLOTS of
    the pair), or -1 for a pair of types it does not compute. only >= 0: that candidate's entries alone are written
    (a contact unit is one candidate: a box pair's other 15 corners cost nothing; the pairs of an ellipsoid or a
    mesh write all of theirs). beyond [m]: a mesh's pair whose least distance is above it gives that least distance,
    normal and point for every slot (each slot's distance is at least the least: a caller asking which candidates
    come within `beyond` learns it from one distance, not 17). scratch: None, or COLLIDE_WORK floats for the small
    vectors below (a caller colliding many pairs passes it, sparing an allocation each)."""
    if answers_beyond(ta, tb):
        return _general(ta, pa, Ra, sa, ha, tb, pb, Rb, sb, hb, dist, normal, point, beyond)
    if scratch is None:
        scratch = np.empty(COLLIDE_WORK)  # the small vectors below, one allocation
    if ta == PLANE:
        n = scratch[0:3]
        for a in range(3):
            n[a] = Ra[a, 2]
        if tb == SPHERE:
            _plane_point(pa, n, pb, sb[0], 0, dist, normal, point)
            return 1
        if tb == CAPSULE:
            end = scratch[3:6]
            for k in range(2):
                if only >= 0 and k != only:
                    continue
                side = 1.0 if k == 0 else -1.0
                for a in range(3):
                    end[a] = pb[a] + side * sb[1] * Rb[a, 2]
                _plane_point(pa, n, end, sb[0], k, dist, normal, point)
            return 2
        if tb == CYLINDER:  # each cap's rim at its lowest point towards the plane and at 90, 180, 270 degrees
            w, v, rim = scratch[3:6], scratch[6:9], scratch[9:12]
            rim_frame(Rb, n, w, v)
            for k in range(8):
                if only >= 0 and k != only:
                    continue
                rim_point(pb, Rb, sb, w, v, k, 0.0, rim)
                _plane_point(pa, n, rim, 0.0, k, dist, normal, point)
            return 8
        if tb == BOX:
            corner = scratch[3:6]
            for k in range(8):
                if only >= 0 and k != only:
                    continue
                x = sb[0] if k & 1 else -sb[0]
                y = sb[1] if k & 2 else -sb[1]
                z = sb[2] if k & 4 else -sb[2]
                for a in range(3):
                    corner[a] = pb[a] + Rb[a, 0] * x + Rb[a, 1] * y + Rb[a, 2] * z
                _plane_point(pa, n, corner, 0.0, k, dist, normal, point)
            return 8
        return -1
    if ta == SPHERE:
        if tb == SPHERE:
            _sphere_sphere(pa, sa[0], pb, sb[0], 0, dist, normal, point)
            return 1
        if tb == CAPSULE:
            s = 0.0
            for a in range(3):
                s += (pa[a] - pb[a]) * Rb[a, 2]
            s = min(max(s, -sb[1]), sb[1])
            centre = scratch[0:3]
            for a in range(3):
                centre[a] = pb[a] + s * Rb[a, 2]
            _sphere_sphere(pa, sa[0], centre, sb[0], 0, dist, normal, point)
            return 1
        if tb == BOX:
            _point_box(pa, sa[0], pb, Rb, sb, 0, dist, normal, point)
            return 1
        if tb == CYLINDER:
            _point_cylinder(pa, sa[0], pb, Rb, sb, 0, dist, normal, point)
            return 1
        return -1
    if ta == BOX and tb == BOX:  # each box's corners against the other box (vertex-face contacts), the edges (16)
        if only == 16:
            only = -1  # whether a corner holds the edges' contact: every slot
        corner = scratch[0:3]
        for k in range(16):
            if only >= 0 and k != only:
                continue
            own_p, own_R, own_s = (pb, Rb, sb) if k < 8 else (pa, Ra, sa)
            other_p, other_R, other_s = (pa, Ra, sa) if k < 8 else (pb, Rb, sb)
            c = k % 8
            x = own_s[0] if c & 1 else -own_s[0]
            y = own_s[1] if c & 2 else -own_s[1]
            z = own_s[2] if c & 4 else -own_s[2]
            for a in range(3):
                corner[a] = own_p[a] + own_R[a, 0] * x + own_R[a, 1] * y + own_R[a, 2] * z
            _point_box(corner, 0.0, other_p, other_R, other_s, k, dist, normal, point)
            if k < 8:  # a corner of b: its normal points from b to a
                for a in range(3):
                    normal[k, a] = -normal[k, a]
        if only < 0:  # edges crossing: their closest points, unless a corner holds the contact
            _box_edge_pair(pa, Ra, sa, pb, Rb, sb, 16, dist, normal, point)
            _unless_held(dist, 16, 17)
        return 17
    if ta == CAPSULE and tb == BOX:  # the segment's closest point (2) and its ends, or a lying span's (0, 1)
        c, u = scratch[3:6], scratch[6:9]  # the segment in the box's axes
        segment_in_box(pa, Ra, pb, Rb, c, u)
        centre = scratch[0:3]
        for k in range(3):
            if only >= 0 and k != only:
                continue
            t, apart = capsule_box_slot(c, u, sa[1], sb, k)
            for a in range(3):
                centre[a] = pa[a] + t * Ra[a, 2]
            _point_box(centre, sa[0], pb, Rb, sb, k, dist, normal, point)
            if apart:
                dist[k] = APART
        return 3
    if ta == CAPSULE and tb == CYLINDER:  # the segment's closest point (2) and its ends (0, 1)
        u = scratch[3:6]
        for a in range(3):
            u[a] = Ra[a, 2]
        closest, _lo, _hi = segment_cylinder_closest(pa, u, sa[1], pb, Rb, sb[0], sb[1])
        centre = scratch[0:3]
        for k in range(3):
            if only >= 0 and k != only:
                continue
            t = closest if k == 2 else (-sa[1] if k == 0 else sa[1])
            for a in range(3):
                centre[a] = pa[a] + t * u[a]
            _point_cylinder(centre, sa[0], pb, Rb, sb, k, dist, normal, point)
            if k < 2 and abs(t - closest) < LYING_SPAN * sa[1]:  # that end is the closest point
                dist[k] = APART
        return 3
    if ta == CYLINDER and tb == BOX:  # the cylinder's rims (0-7), the box's corners (8-15), its nearest edge (16),
        if only >= 8:                 # a face's line along the side (17, 18)
            only = -1  # whether another slot holds a corner's, the edge's or a line end's contact: every slot
        work = np.empty(12)
        _rim_candidates(pa, Ra, sa, BOX, pb, Rb, sb, 0, False, only, dist, normal, point, work)
        corner = scratch[0:3]
        for k in range(8, 16):
            if only >= 0 and k != only:
                continue
            _box_corner(pb, Rb, sb, k - 8, corner)
            _point_cylinder(corner, 0.0, pa, Ra, sa, k, dist, normal, point)
            for a in range(3):  # from the corner (b) towards the cylinder: turned to point from a to b
                normal[k, a] = -normal[k, a]
        if only < 0:
            _box_edge_candidate(pa, Ra, sa, pb, Rb, sb, 16, dist, normal, point, work)
            span = _side_line(CYLINDER, pa, Ra, sa, BOX, pb, Rb, sb, hb, 17, dist, normal, point)
            _line_ends_hold(dist, point, 17, 8, 17, LYING_SPAN * span)  # a rim point is 1% of half off an end
            _unless_held(dist, 16, 19)
        return 19
    if ta == CYLINDER and tb == CYLINDER:  # each one's rims against the other (0-7, 8-15), the sides' (16)
        if only == 16:
            only = -1  # whether another slot holds the sides' contact: every slot
        work = np.empty(12)
        _rim_candidates(pa, Ra, sa, CYLINDER, pb, Rb, sb, 0, False, only, dist, normal, point, work)
        _rim_candidates(pb, Rb, sb, CYLINDER, pa, Ra, sa, 8, True, only, dist, normal, point, work)
        if only < 0:
            ua, ub, ca, cb = scratch[0:3], scratch[3:6], scratch[6:9], scratch[9:12]
            for a in range(3):
                ua[a], ub[a] = Ra[a, 2], Rb[a, 2]
            s, t = segment_closest(pa, ua, sa[1], pb, ub, sb[1])
            for a in range(3):
                ca[a], cb[a] = pa[a] + s * ua[a], pb[a] + t * ub[a]
            _sphere_sphere(ca, sa[0], cb, sb[0], 16, dist, normal, point)
            if not (abs(s) < sa[1] and abs(t) < sb[1]):  # not two sides: a rim is nearer, the rims' slots hold it
                dist[16] = APART
            else:
                _unless_held(dist, 16, 17)
        return 17
    if ta == CAPSULE and tb == CAPSULE:
        ua = scratch[0:3]
        ub = scratch[3:6]
        for a in range(3):
            ua[a] = Ra[a, 2]
            ub[a] = Rb[a, 2]
        s, t = segment_closest(pa, ua, sa[1], pb, ub, sb[1])
        ca = scratch[6:9]
        cb = scratch[9:12]
        for a in range(3):
            ca[a] = pa[a] + s * ua[a]
            cb[a] = pb[a] + t * ub[a]
        _sphere_sphere(ca, sa[0], cb, sb[0], 0, dist, normal, point)
        return 1
    return -1


@njit(cache=True)
def tangents(n, t1, t2):
    """t1, t2 (3,): a right-handed orthonormal frame (n, t1, t2) from the unit normal n (the contact frame; the cone
    is circular, so which pair of tangents is taken does not change the law)."""
    if abs(n[0]) < 0.6:
        ax, ay, az = 1.0, 0.0, 0.0
    else:
        ax, ay, az = 0.0, 1.0, 0.0
    dot = ax * n[0] + ay * n[1] + az * n[2]
    t1[0], t1[1], t1[2] = ax - dot * n[0], ay - dot * n[1], az - dot * n[2]
    length = np.sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2])
    for a in range(3):
        t1[a] /= length
    t2[0] = n[1] * t1[2] - n[2] * t1[1]
    t2[1] = n[2] * t1[0] - n[0] * t1[2]
    t2[2] = n[0] * t1[1] - n[1] * t1[0]


def pairs_text() -> str:
    """The pairs of geom kinds rbody computes, in words (for refusals)."""
    names = {code: kind for kind, code in TYPE_CODES.items()}
    parts = []
    for first in sorted(names):
        others = [names[b] for a, b in sorted(SLOTS) if a == first]
        if others:
            parts.append(f"{names[first]} with {', '.join(others)}")
    return "; ".join(parts)


def collide_pair(kind_a: str, pos_a, mat_a, size_a, kind_b: str, pos_b, mat_b, size_b, *, vertices_a=None,
                 vertices_b=None):
    """The candidate contacts of two geoms in any order, for Python callers: (dist (k,) [m], normal (k, 3) from geom
    a to geom b, point (k, 3) [m]). kind: one of TYPE_CODES; pos (3,) [m]; mat (3, 3) the geom's axes as columns;
    size (3,) or shorter [m] (a mesh: ignored); vertices_a, vertices_b (V, 3) [m]: a mesh's points in its frame
    (their convex hull collides). Raises ValueError for a pair rbody does not compute or a mesh without vertices."""
    codes = []
    for kind in (kind_a, kind_b):
        if kind not in TYPE_CODES:
            raise ValueError(f"geom kind {kind!r}: expected one of {tuple(TYPE_CODES)}")
        codes.append(TYPE_CODES[kind])
    ta, tb = codes
    swap = ta > tb
    hulls = []
    for kind, vertices in ((kind_a, vertices_a), (kind_b, vertices_b)):
        if kind == "mesh":
            if vertices is None:
                raise ValueError("a mesh geom needs its vertices (vertices_a or vertices_b)")
            from rbody.engine.contacts.convex import pack_hull

            hulls.append(pack_hull(np.asarray(vertices, dtype=float)))
        else:
            hulls.append(np.empty(0))
    args = [(ta, pos_a, mat_a, size_a, hulls[0]), (tb, pos_b, mat_b, size_b, hulls[1])]
    if swap:
        args.reverse()
    (t1, p1, R1, s1, h1), (t2, p2, R2, s2, h2) = args
    if (t1, t2) not in SLOTS:
        raise ValueError(f"geoms {kind_a!r} and {kind_b!r}: rbody computes contacts of {pairs_text()}, not this "
                         "pair")
    sizes = []
    for s, t, h in ((s1, t1, h1), (s2, t2, h2)):
        full = np.zeros(3)
        if t == MESH:  # a mesh's size: the half sizes of a box about its origin holding it (the table's is tight)
            full[:] = np.abs(hull_points(h)).max(axis=0)
        else:
            s = np.atleast_1d(np.asarray(s, dtype=float))
            full[:s.size] = s
        sizes.append(full)
    dist, normal, point = np.empty(MAX_SLOTS), np.empty((MAX_SLOTS, 3)), np.empty((MAX_SLOTS, 3))
    count = collide(t1, np.asarray(p1, dtype=float), np.asarray(R1, dtype=float), sizes[0], h1, t2,
                    np.asarray(p2, dtype=float), np.asarray(R2, dtype=float), sizes[1], h2, dist, normal, point)
    dist, normal, point = dist[:count].copy(), normal[:count].copy(), point[:count].copy()
    if swap:
        normal = -normal
    return dist, normal, point


def hull_points(hull: np.ndarray) -> np.ndarray:
    """(V, 3) the vertices of a packed hull (rbody.engine.contacts.convex.pack_hull), in the geom's frame [m]."""
    count = int(hull[0])
    return hull[3:3 + 3 * count].reshape(count, 3)


@njit(cache=True, inline="always")
def bounding_radius(kind, p, size_at):
    """The radius [m] of the sphere about a geom's centre that holds it, its size read at p[size_at:] (the constraint
    table's record, or a size array at 0; a mesh: its bounding box's half sizes about its origin); +inf for a plane
    or a height field."""
    if kind == SPHERE:
        return p[size_at]
    if kind == CAPSULE:
        return p[size_at] + p[size_at + 1]
    if kind == BOX:
        return np.sqrt(p[size_at] ** 2 + p[size_at + 1] ** 2 + p[size_at + 2] ** 2)
    if kind == CYLINDER:
        return np.sqrt(p[size_at] ** 2 + p[size_at + 1] ** 2)
    if kind == ELLIPSOID:
        return max(p[size_at], p[size_at + 1], p[size_at + 2])
    if kind == MESH:  # the table writes the half sizes of a mesh's bounding box about its origin as its size
        return np.sqrt(p[size_at] ** 2 + p[size_at + 1] ** 2 + p[size_at + 2] ** 2)
    return np.inf


__all__ = ["collide", "collide_pair", "bounding_radius", "point_distance", "hull_points", "MESH", "ELLIPSOID", "tangents", "segment_closest", "segment_box_closest", "capsule_box_slot", "segment_in_box", "APART", "TIME_STEPPED", "LYING_SPAN", "cylinder_distance", "segment_cylinder_closest",
           "pairs_text", "COLLIDE_WORK", "CYLINDER", "SLOTS", "MAX_SLOTS", "TYPE_CODES", "PLANE",
           "SPHERE", "CAPSULE", "BOX"]
