"""The acceleration-level terms J' v of a contact's rows: the gap's second derivative and the rolling point's, compiled.

The event-driven scheme (rbody.engine.constraints.events) holds a touching contact by J qacc + J' v = 0 on its
normal row (the gap stays 0) and, while it sticks, on its tangent rows (no slip). J' v is the part of the rows'
time derivative that does not multiply qacc. The material points' accelerations at the contact point (what a
connect row would use) are not it: the contact point moves over both surfaces, and the normal turns with them.

Each candidate of rbody.engine.contacts.geometry is, at any configuration, one of two shapes of gap:

- PLANE: a plane fixed in body P (outward unit normal m, turning with P) and a point x fixed in body Q (a sphere's
  centre, a capsule's end, a box's corner) with radius rho: g = m . (x - o) - rho, o a material point of P on the
  plane. With o taken at the foot of x (x - o = m (g + rho)):

      g'' = m . (a_Q(x) - a_P(o)) + 2 (w_P x m) . (v_Q(x) - v_P(o)) - (g + rho) |w_P - (w_P . m) m|^2

  (a_X(y): the acceleration of body X's material point at y with qacc = 0; a fixed plane gives m . a_Q(x): the
  centre's, not the contact point's). Plane-sphere, plane-capsule, plane-box, and a box's face against a point.
- CORES: two core points x_A = c_A + s u_A, x_B = c_B + t u_B (a sphere's centre or a capsule's end: fixed; a
  capsule's segment or a box's edge: the closest point, sliding along the axis u while its parameter is inside the
  segment), radii summing to rho: d = x_B - x_A, g = |d| - rho, n = d / |d|. The parameters' rates s', t' follow from the closest-point
  conditions d . u_A = 0, d . u_B = 0 differentiated, d' = (v_B(x_B) - v_A(x_A)) + t' u_B - s' u_A, and

      g'' = n . (a_B(x_B) - a_A(x_A)) + 2 t' n . (w_B x u_B) - 2 s' n . (w_A x u_A) + |d'_perp|^2 / |d|

  (|d'_perp|^2 / |d| the curvature term of sphere on sphere). Sphere-sphere, sphere-capsule, capsule-capsule, a
  point against a box's edge or corner. Parallel segments (both parameters inside, the closest pair not unique)
  take the least-norm rates. A capsule against a box is a capsule's point against the box's face (PLANE), edge or
  corner (CORES): an end (fixed), or the segment's closest point (sliding along its axis).

The tangent rows of a sticking contact: with e a tangent, p the contact point and p' its velocity (from the shapes
above: the foot point on the plane or x_A + n (r_A + g / 2)), d/dt e . (v_B(p) - v_A(p)) without qacc is
e . (a_B(p) - a_A(p) + w_B x (p' - v_B(p)) - w_A x (p' - v_A(p))) + e' . (v_B(p) - v_A(p)); the last term is
dropped: it multiplies the slip velocity, which is 0 (to round-off) wherever these rows are held.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.contacts.geometry import (BOX, CAPSULE, CYLINDER, ELLIPSOID, PLANE, SPHERE, bounding_radius,
                                            box_edges_closest, capsule_box_slot, edge_axes, segment_closest,
                                            segment_in_box)
from rbody.engine.contacts.rows import field_at, geom_pose
from rbody.engine.contacts.terrain import HFIELD, field_reach
from rbody.engine.multibody import _views
from rbody.engine.constraints.table import (U_BODY1, U_BODY2, U_DOF, U_GMAT_A, U_GMAT_B, U_GPOS_A, U_GPOS_B,
                                            U_GSIZE_A, U_GSIZE_B, U_GTYPE_A, U_GTYPE_B, U_HULL_A, U_MARGIN)

SHAPE_PLANE, SHAPE_CORES = 0, 1
TIGHTEN_BELOW = 1e-9  # [m] a broad-phase bound at most this is tightened by the geoms' axes (the callers part pairs
# above TOUCH_TOLERANCE, 1e-10 m, or above 0)


@njit(cache=True)
def _point_against_box(c, r, pbox, Rbox, sbox, x, u, slide, m):
    """The shape of the gap of a point c (radius r) against a box: returns 0 for a face (m its outward normal, x[1]
    a point of its plane), 1 for an edge (x[1] its point nearest to c, u[1] its axis, slide[1] = 1), 2 for a corner
    (x[1] the corner); x[0] = c in every case."""
    local = np.empty(3)
    for i in range(3):
        local[i] = Rbox[0, i] * (c[0] - pbox[0]) + Rbox[1, i] * (c[1] - pbox[1]) + Rbox[2, i] * (c[2] - pbox[2])
    nearest = np.empty(3)
    clamped = 0
    last_free = 0
    for i in range(3):
        nearest[i] = min(max(local[i], -sbox[i]), sbox[i])
        if local[i] != nearest[i]:
            clamped += 1
        else:
            last_free = i
    for a in range(3):
        x[0, a] = c[a]
    face = -1
    if clamped == 0:  # inside: the face of least depth
        face, depth = 0, sbox[0] - abs(local[0])
        for i in range(1, 3):
            if sbox[i] - abs(local[i]) < depth:
                face, depth = i, sbox[i] - abs(local[i])
    elif clamped == 1:
        for i in range(3):
            if local[i] != nearest[i]:
                face = i
    if face >= 0:
        side = 1.0 if local[face] >= 0.0 else -1.0
        for a in range(3):
            m[a] = side * Rbox[a, face]
            x[1, a] = pbox[a] + side * sbox[face] * Rbox[a, face]
        return 0
    for a in range(3):
        x[1, a] = pbox[a] + Rbox[a, 0] * nearest[0] + Rbox[a, 1] * nearest[1] + Rbox[a, 2] * nearest[2]
    if clamped == 2:
        for a in range(3):
            u[1, a] = Rbox[a, last_free]
        slide[1] = 1.0
        return 1
    return 2


@njit(cache=True)
def contact_shape(ta, pa, Ra, sa, tb, pb, Rb, sb, k, x, u, slide, m, radius):
    """The shape of candidate k's gap of geoms a and b (as collide takes them; module docstring). Returns
    (shape, plane_on). SHAPE_PLANE: the plane on geom a (plane_on 0) or b (1), m (3,) its outward normal, x[0] a
    point of the plane, x[1] the point on the other geom, radius[1] that point's radius. SHAPE_CORES: x (2, 3) the
    core points on geoms a and b, u (2, 3) their axes, slide (2,) 1 where the point slides along its axis, radius
    (2,) the radii of a and b."""
    for i in range(2):
        slide[i] = 0.0
        radius[i] = 0.0
        for a in range(3):
            u[i, a] = 0.0
    if ta == PLANE:
        for a in range(3):
            m[a] = Ra[a, 2]
        if tb == SPHERE:
            for a in range(3):
                x[1, a] = pb[a]
            radius[1] = sb[0]
        elif tb == CAPSULE:
            side = 1.0 if k == 0 else -1.0
            for a in range(3):
                x[1, a] = pb[a] + side * sb[1] * Rb[a, 2]
            radius[1] = sb[0]
        else:  # box corner k
            cx = sb[0] if k & 1 else -sb[0]
            cy = sb[1] if k & 2 else -sb[1]
            cz = sb[2] if k & 4 else -sb[2]
            for a in range(3):
                x[1, a] = pb[a] + Rb[a, 0] * cx + Rb[a, 1] * cy + Rb[a, 2] * cz
        for a in range(3):
            x[0, a] = pa[a]
        return SHAPE_PLANE, 0
    if ta == SPHERE and tb == SPHERE:
        for a in range(3):
            x[0, a], x[1, a] = pa[a], pb[a]
        radius[0], radius[1] = sa[0], sb[0]
        return SHAPE_CORES, 0
    if ta == SPHERE and tb == CAPSULE:
        s = 0.0
        for a in range(3):
            s += (pa[a] - pb[a]) * Rb[a, 2]
        if abs(s) < sb[1]:
            slide[1] = 1.0
        s = min(max(s, -sb[1]), sb[1])
        for a in range(3):
            x[0, a] = pa[a]
            x[1, a] = pb[a] + s * Rb[a, 2]
            u[1, a] = Rb[a, 2]
        radius[0], radius[1] = sa[0], sb[0]
        return SHAPE_CORES, 0
    if ta == CAPSULE and tb == CAPSULE:
        ua, ub = np.empty(3), np.empty(3)
        for a in range(3):
            ua[a], ub[a] = Ra[a, 2], Rb[a, 2]
        s, t = segment_closest(pa, ua, sa[1], pb, ub, sb[1])
        slide[0] = 1.0 if abs(s) < sa[1] else 0.0
        slide[1] = 1.0 if abs(t) < sb[1] else 0.0
        for a in range(3):
            x[0, a], x[1, a] = pa[a] + s * ua[a], pb[a] + t * ub[a]
            u[0, a], u[1, a] = ua[a], ub[a]
        radius[0], radius[1] = sa[0], sb[0]
        return SHAPE_CORES, 0
    if ta == BOX and tb == BOX and k == 16:  # two edges crossing: two core segments of radius 0
        ea, eb = np.empty(3), np.empty(3)
        axes = np.empty((3, 3, 3))
        edge_axes(Ra, Rb, axes)
        s, t, _d = box_edges_closest(pa, Ra, sa, pb, Rb, sb, axes, x[0], ea, x[1], eb)
        slide[0], slide[1] = 1.0, 1.0  # inside both edges (box_edges_closest)
        for a in range(3):
            x[0, a] += s * ea[a]
            x[1, a] += t * eb[a]
            u[0, a], u[1, a] = ea[a], eb[a]
        return SHAPE_CORES, 0
    # a point (sphere centre, capsule's end or closest point, box corner) against a box: the point on geom a
    # (sphere, capsule; box-box k >= 8) or b
    xs, us, ss = np.empty((2, 3)), np.zeros((2, 3)), np.zeros(2)
    c = np.empty(3)
    sliding = False  # the point slides along geom a's axis (a capsule's closest point, inside its segment)
    if ta == SPHERE:
        point_on, r = 0, sa[0]
        for a in range(3):
            c[a] = pa[a]
        case = _point_against_box(c, r, pb, Rb, sb, xs, us, ss, m)
    elif ta == CAPSULE:  # a point of the segment: the closest (slot 2) or a lying span's end (geometry.collide)
        point_on, r = 0, sa[0]
        local, axis = np.empty(3), np.empty(3)
        segment_in_box(pa, Ra, pb, Rb, local, axis)
        t, _apart = capsule_box_slot(local, axis, sa[1], sb, k)
        sliding = -sa[1] < t < sa[1]
        for a in range(3):
            c[a] = pa[a] + t * Ra[a, 2]
        case = _point_against_box(c, r, pb, Rb, sb, xs, us, ss, m)
    else:
        own_p, own_R, own_s = (pb, Rb, sb) if k < 8 else (pa, Ra, sa)
        other_p, other_R, other_s = (pa, Ra, sa) if k < 8 else (pb, Rb, sb)
        point_on, r = (1 if k < 8 else 0), 0.0
        j = k % 8
        cx = own_s[0] if j & 1 else -own_s[0]
        cy = own_s[1] if j & 2 else -own_s[1]
        cz = own_s[2] if j & 4 else -own_s[2]
        for a in range(3):
            c[a] = own_p[a] + own_R[a, 0] * cx + own_R[a, 1] * cy + own_R[a, 2] * cz
        case = _point_against_box(c, r, other_p, other_R, other_s, xs, us, ss, m)
    box_on = 1 - point_on
    if case == 0:  # a face of the box: the plane on the box's geom
        for a in range(3):
            x[0, a], x[1, a] = xs[1, a], xs[0, a]
        radius[1] = r
        return SHAPE_PLANE, box_on
    for a in range(3):
        x[point_on, a], x[box_on, a] = xs[0, a], xs[1, a]
        u[box_on, a] = us[1, a]
        if sliding:
            u[point_on, a] = Ra[a, 2]
    slide[box_on] = ss[1]
    slide[point_on] = 1.0 if sliding else 0.0
    radius[point_on] = r
    return SHAPE_CORES, 0


@njit(cache=True, inline="always")
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, inline="always")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, inline="always")
def point_velocity(p, w, body, x, velocity):
    """velocity (3,) [m/s] of the world point x (3,) fixed on `body` (-1: the world, at rest), v_O + omega x r with r
    from the origin of the body's tree, from the workspace's body velocities (world axes)."""
    if body < 0:
        for a in range(3):
            velocity[a] = 0.0
        return
    ws = _views(p, w)
    vel = ws.vel[body]
    r0, r1, r2 = x[0] - ws.xorigin[body, 0], x[1] - ws.xorigin[body, 1], x[2] - ws.xorigin[body, 2]
    velocity[0] = vel[3] + vel[1] * r2 - vel[2] * r1
    velocity[1] = vel[4] + vel[2] * r0 - vel[0] * r2
    velocity[2] = vel[5] + vel[0] * r1 - vel[1] * r0


@njit(cache=True, inline="always")
def _geom_centre(p, w, body, pos_at, pos):
    """pos (3,) [m]: a geom's centre in the world (geom_pose without its axes)."""
    if body < 0:
        for a in range(3):
            pos[a] = p[pos_at + a]
        return
    ws = _views(p, w)
    for a in range(3):
        pos[a] = (ws.xorigin[body, a] + ws.xpos[body, a] + ws.xmat[body, a, 0] * p[pos_at]
                  + ws.xmat[body, a, 1] * p[pos_at + 1] + ws.xmat[body, a, 2] * p[pos_at + 2])


@njit(cache=True, inline="always")
def _support_radius(kind, R, size, l0, l1, l2):
    """Half the extent [m] of a geom (axes R, size) along the unit axis l: its projection onto l is its centre's
    -+ this."""
    if kind == SPHERE:
        return size[0]
    along = abs(l0 * R[0, 2] + l1 * R[1, 2] + l2 * R[2, 2])
    if kind == CAPSULE:
        return along * size[1] + size[0]
    if kind == CYLINDER:
        return along * size[1] + size[0] * np.sqrt(max(0.0, 1.0 - along * along))
    if kind == ELLIPSOID:  # |S R^T l|
        e0 = (l0 * R[0, 0] + l1 * R[1, 0] + l2 * R[2, 0]) * size[0]
        e1 = (l0 * R[0, 1] + l1 * R[1, 1] + l2 * R[2, 1]) * size[1]
        return np.sqrt(e0 * e0 + e1 * e1 + (along * size[2]) ** 2)
    # a box, or a mesh by its bounding box (the table's size: its half sizes about the geom's origin)
    return (abs(l0 * R[0, 0] + l1 * R[1, 0] + l2 * R[2, 0]) * size[0]
            + abs(l0 * R[0, 1] + l1 * R[1, 1] + l2 * R[2, 1]) * size[1] + along * size[2])


@njit(cache=True, inline="always")
def _axis_gap(ta, pa, Ra, sa, tb, pb, Rb, sb, l0, l1, l2):
    """The gap [m] between the projections of two geoms onto the unit axis l: at most their distance."""
    return (abs(l0 * (pb[0] - pa[0]) + l1 * (pb[1] - pa[1]) + l2 * (pb[2] - pa[2]))
            - _support_radius(ta, Ra, sa, l0, l1, l2) - _support_radius(tb, Rb, sb, l0, l1, l2))


@njit(cache=True)
def separating_gap(ta, pa, Ra, sa, tb, pb, Rb, sb):
    """A lower bound [m] on the distance of two convex geoms (not planes or height fields; a mesh by the bounding
    box its size gives) by the separating-axis test: along any unit axis the two project onto intervals, and the
    gap between them is at most their distance. The axes: the line of centres, each geom's own three (a box's face
    normals, a capsule's or cylinder's axis and two across it, an ellipsoid's), and the nine cross products of one
    geom's axes with the other's (two boxes edge to edge: with the faces', the whole test of two oriented boxes;
    two capsules askew: their common normal). A sphere's axes are any: it adds the line of centres only."""
    dx, dy, dz = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
    apart = np.sqrt(dx * dx + dy * dy + dz * dz)
    best = -np.inf
    if apart > 0.0:
        best = _axis_gap(ta, pa, Ra, sa, tb, pb, Rb, sb, dx / apart, dy / apart, dz / apart)
    for which in range(2):
        kind, R = (ta, Ra) if which == 0 else (tb, Rb)
        if kind == SPHERE:
            continue
        for i in range(3):
            best = max(best, _axis_gap(ta, pa, Ra, sa, tb, pb, Rb, sb, R[0, i], R[1, i], R[2, i]))
    if ta == SPHERE or tb == SPHERE:
        return best
    for i in range(3):
        for j in range(3):
            l0 = Ra[1, i] * Rb[2, j] - Ra[2, i] * Rb[1, j]
            l1 = Ra[2, i] * Rb[0, j] - Ra[0, i] * Rb[2, j]
            l2 = Ra[0, i] * Rb[1, j] - Ra[1, i] * Rb[0, j]
            size = np.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
            if size > 1e-6:  # (parallel axes: the faces' own test holds that direction)
                best = max(best, _axis_gap(ta, pa, Ra, sa, tb, pb, Rb, sb, l0 / size, l1 / size, l2 / size))
    return best


@njit(cache=True, inline="always")
def _round(kind):
    """Whether a geom is a sphere, a capsule or a cylinder: a core (a point or its axis segment) and a radius."""
    return kind == SPHERE or kind == CAPSULE or kind == CYLINDER


@njit(cache=True)
def core_gap(ta, pa, Ra, sa, tb, pb, Rb, sb):
    """A lower bound [m] on the distance of two round geoms (spheres, capsules, cylinders: _round): the distance
    between their cores (a sphere's centre, the segment of a capsule's or a cylinder's axis of its half-length
    size[1]) less their radii size[0]. Exact for spheres and capsules (their surfaces are the points within a radius
    of the core); a cylinder lies within the capsule of its radius and half-length, whose gap this is. Where the
    separating axes fail (a capsule beside a cylinder's rim, askew: no axis of the two nor their cross products
    parts them, though they are centimetres apart), the cores' closest points do."""
    la = 0.0 if ta == SPHERE else sa[1]
    lb = 0.0 if tb == SPHERE else sb[1]
    s, t = segment_closest(pa, Ra[:, 2], la, pb, Rb[:, 2], lb)
    d0 = pb[0] + t * Rb[0, 2] - pa[0] - s * Ra[0, 2]
    d1 = pb[1] + t * Rb[1, 2] - pa[1] - s * Ra[1, 2]
    d2 = pb[2] + t * Rb[2, 2] - pa[2] - s * Ra[2, 2]
    return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - sa[0] - sb[0]


@njit(cache=True, inline="always")
def needs_axes(ta, tb):
    """Whether a pair's bounding spheres can be tightened by their axes (clearance): a plane with anything but a
    sphere (its lowest point), two geoms not both spheres (round ones by their cores, core_gap; any by the separating
    axes); not a height field's."""
    if ta == PLANE:
        return tb != SPHERE
    return ta != HFIELD and not (ta == SPHERE and tb == SPHERE)


@njit(cache=True)
def clearance(p, w, u, h, work):
    """A lower bound [m] on the gap of every candidate of the contact unit at u over the next h [s] (the broad
    phase): the gap between the two geoms' bounding spheres (a plane and a sphere: the sphere's height above it),
    less h times a bound on the speed at which any point of one approaches any point of the other, |v_b - v_a| at
    the centres plus |omega| times each radius (the workspace's body velocities; h = 0: the gap bound alone). Where
    that, less the margin, is not above TIGHTEN_BELOW and the geoms' axes may part them (needs_axes: a long box's
    bounding sphere reaches far beyond it, two legs side by side overlap theirs), if larger: above a plane the
    height of the geom's lowest point; two spheres, capsules or cylinders their cores' gap (core_gap: two capsules'
    distance), and with a cylinder, if that leaves them within reach, the separating axes' gap; any other pair the
    separating axes' gap. Less the pair's margin, as its gaps are.
    > TOUCH_TOLERANCE: no candidate of the pair touches or closes within h, and its distance need not be computed.
    Returns (that bound, motion, gap): motion [m] h times the bound on the approach speed, gap [m] that bound before the
    motion and the margin are taken off (the bound on the gap itself). work: scratch of GEOMETRY_WORK floats
    (contact_geometry's)."""
    pa, pb = work[0:3], work[3:6]
    body_a, body_b = int(p[u + U_BODY1]), int(p[u + U_BODY2])
    ta, tb = int(p[u + U_GTYPE_A]), int(p[u + U_GTYPE_B])
    radius_b = bounding_radius(tb, p, u + U_GSIZE_B)
    if ta == HFIELD:  # world-fixed: geom b's height above the highest vertex under its footprint, widened by the
        Ra = work[6:15].reshape((3, 3))  # step's motion (its lowest point falls and moves sideways at most that)
        geom_pose(p, w, body_a, u + U_GPOS_A, u + U_GMAT_A, pa, Ra)
        _geom_centre(p, w, body_b, u + U_GPOS_B, pb)
        motion = 0.0
        if h > 0.0:
            vb = work[27:30]
            point_velocity(p, w, body_b, pb, vb)
            ws = _views(p, w)
            omega = ws.vel[body_b]
            motion = h * (np.sqrt(vb[0] ** 2 + vb[1] ** 2 + vb[2] ** 2)
                          + np.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2) * radius_b)
        reach = field_reach(field_at(p, int(p[u + U_HULL_A])), pa, Ra, pb, radius_b + motion)
        return reach - p[u + U_MARGIN], motion, reach + motion
    if ta == PLANE:
        Ra = work[6:15].reshape((3, 3))
        geom_pose(p, w, body_a, u + U_GPOS_A, u + U_GMAT_A, pa, Ra)
        _geom_centre(p, w, body_b, u + U_GPOS_B, pb)
        radius_a = 0.0
        apart = (Ra[0, 2] * (pb[0] - pa[0]) + Ra[1, 2] * (pb[1] - pa[1]) + Ra[2, 2] * (pb[2] - pa[2])) - radius_b
    else:
        _geom_centre(p, w, body_a, u + U_GPOS_A, pa)
        _geom_centre(p, w, body_b, u + U_GPOS_B, pb)
        radius_a = bounding_radius(ta, p, u + U_GSIZE_A)
        apart = np.sqrt((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2 + (pb[2] - pa[2]) ** 2) - radius_a - radius_b
    motion = 0.0  # h times the bound on the approach speed
    if h > 0.0:
        va, vb = work[24:27], work[27:30]
        point_velocity(p, w, body_a, pa, va)
        point_velocity(p, w, body_b, pb, vb)
        speed = np.sqrt((vb[0] - va[0]) ** 2 + (vb[1] - va[1]) ** 2 + (vb[2] - va[2]) ** 2)
        ws = _views(p, w)
        for body, radius in ((body_a, radius_a), (body_b, radius_b)):
            if body >= 0:
                omega = ws.vel[body]
                speed += np.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2) * radius
        motion = h * speed
    margin = p[u + U_MARGIN]
    if apart - motion - margin <= TIGHTEN_BELOW and needs_axes(ta, tb):  # loose spheres (a long box, legs side by side)
        Rb = work[15:24].reshape((3, 3))
        geom_pose(p, w, body_b, u + U_GPOS_B, u + U_GMAT_B, pb, Rb)
        sb = p[u + U_GSIZE_B:u + U_GSIZE_B + 3]
        Ra = work[6:15].reshape((3, 3))  # (a plane's: its pose above)
        if ta == PLANE:  # b's lowest point along the plane's normal: the gap itself (a mesh: its bounding box's)
            apart = max(apart, Ra[0, 2] * (pb[0] - pa[0]) + Ra[1, 2] * (pb[1] - pa[1]) + Ra[2, 2] * (pb[2] - pa[2])
                        - _support_radius(tb, Rb, sb, Ra[0, 2], Ra[1, 2], Ra[2, 2]))
        else:  # round geoms: their cores' gap (two capsules: their distance); else, or if that leaves them
            geom_pose(p, w, body_a, u + U_GPOS_A, u + U_GMAT_A, pa, Ra)  # within reach with a cylinder, the
            sa = p[u + U_GSIZE_A:u + U_GSIZE_A + 3]  # separating axes' gap
            cores = _round(ta) and _round(tb)
            if cores:
                apart = max(apart, core_gap(ta, pa, Ra, sa, tb, pb, Rb, sb))
            if not cores or ((ta == CYLINDER or tb == CYLINDER) and apart - motion - margin <= TIGHTEN_BELOW):
                apart = max(apart, separating_gap(ta, pa, Ra, sa, tb, pb, Rb, sb))
    return apart - motion - margin, motion, apart


@njit(cache=True)
def body_motion(p, w, acc, body, x, velocity, acceleration, omega, alpha):
    """At the world point x (3,) fixed on `body` (-1: the world): its velocity, its acceleration with qacc = 0
    (a_O + alpha x r + omega x v), the body's angular velocity and its angular acceleration with qacc = 0."""
    if body < 0:
        for a in range(3):
            velocity[a] = acceleration[a] = omega[a] = alpha[a] = 0.0
        return
    ws = _views(p, w)
    vel = ws.vel[body]
    r = np.empty(3)
    for a in range(3):
        r[a] = x[a] - ws.xorigin[body, a]
        omega[a] = vel[a]
        alpha[a] = acc[body, a]
    point_velocity(p, w, body, x, velocity)
    A = acc[body]
    acceleration[0] = A[3] + A[1] * r[2] - A[2] * r[1] + vel[1] * velocity[2] - vel[2] * velocity[1]
    acceleration[1] = A[4] + A[2] * r[0] - A[0] * r[2] + vel[2] * velocity[0] - vel[0] * velocity[2]
    acceleration[2] = A[5] + A[0] * r[1] - A[1] * r[0] + vel[0] * velocity[1] - vel[1] * velocity[0]


@njit(cache=True)
def contact_bias(p, w, acc, uo, g, frame, r, jdot, row):
    """jdot[row:row + r] = J' v of the contact unit at uo (module docstring): the gap's second derivative without
    qacc on the normal row, and on the tangent rows (frame[1], frame[2]) the rolling point's term; g [m] its gap
    (the distance less the pair's margin), frame (3, 3) its normal and tangents (rows), after the tree's kinematics
    and velocities (workspace w) and acc (nb, 6) its bias accelerations."""
    g = g + p[uo + U_MARGIN]  # the surfaces' distance: the curvature terms are the geometry's
    pa, pb = np.empty(3), np.empty(3)
    Ra, Rb = np.empty((3, 3)), np.empty((3, 3))
    bodies = (int(p[uo + U_BODY1]), int(p[uo + U_BODY2]))
    geom_pose(p, w, bodies[0], uo + U_GPOS_A, uo + U_GMAT_A, pa, Ra)
    geom_pose(p, w, bodies[1], uo + U_GPOS_B, uo + U_GMAT_B, pb, Rb)
    x, u = np.empty((2, 3)), np.empty((2, 3))
    slide, radius, m = np.empty(2), np.empty(2), np.empty(3)
    shape, plane_on = contact_shape(int(p[uo + U_GTYPE_A]), pa, Ra, p[uo + U_GSIZE_A:uo + U_GSIZE_A + 3],
                                    int(p[uo + U_GTYPE_B]), pb, Rb, p[uo + U_GSIZE_B:uo + U_GSIZE_B + 3],
                                    int(p[uo + U_DOF]), x, u, slide, m, radius)
    vel, accel, om, al = np.empty((2, 3)), np.empty((2, 3)), np.empty((2, 3)), np.empty((2, 3))
    tmp, tmp2 = np.empty(3), np.empty(3)
    point, pdot = np.empty(3), np.empty(3)
    normal = frame[0]
    if shape == SHAPE_PLANE:
        P, Q = bodies[plane_on], bodies[1 - plane_on]
        rho = radius[1]
        foot = np.empty(3)
        for a in range(3):
            foot[a] = x[1, a] - m[a] * (g + rho)
        body_motion(p, w, acc, P, foot, vel[0], accel[0], om[0], al[0])
        body_motion(p, w, acc, Q, x[1], vel[1], accel[1], om[1], al[1])
        _cross(om[0], m, tmp)  # m' = w_P x m
        dv = np.empty(3)
        for a in range(3):
            dv[a] = vel[1, a] - vel[0, a]
        wm = _dot(om[0], m)
        perp = _dot(om[0], om[0]) - wm * wm
        gdd = (m[0] * (accel[1, 0] - accel[0, 0]) + m[1] * (accel[1, 1] - accel[0, 1])
               + m[2] * (accel[1, 2] - accel[0, 2]) + 2.0 * _dot(tmp, dv) - (g + rho) * perp)
        gd = _dot(m, dv)  # v_P(x) and v_P(foot) differ by w_P x m (g + rho), normal to m
        for a in range(3):  # the contact point on the plane (geometry: a face's contact point), the foot
            point[a] = foot[a]
            pdot[a] = vel[1, a] - tmp[a] * (rho + g) - m[a] * gd
    else:
        for i in range(2):
            body_motion(p, w, acc, bodies[i], x[i], vel[i], accel[i], om[i], al[i])
        d, dv = np.empty(3), np.empty(3)
        for a in range(3):
            d[a] = x[1, a] - x[0, a]
            dv[a] = vel[1, a] - vel[0, a]
        length = np.sqrt(_dot(d, d))
        n = np.empty(3)
        for a in range(3):
            n[a] = d[a] / length if length > 0.0 else normal[a]
        turn_a, turn_b = np.empty(3), np.empty(3)
        _cross(om[0], u[0], turn_a)
        _cross(om[1], u[1], turn_b)
        ca = -_dot(dv, u[0]) - _dot(d, turn_a)  # eq. A: -s' + t' b = ca
        cb = -_dot(dv, u[1]) - _dot(d, turn_b)  # eq. B: -s' b + t' = cb
        b = _dot(u[0], u[1])
        sd, td = 0.0, 0.0
        if slide[0] != 0.0 and slide[1] != 0.0:
            det = b * b - 1.0
            if abs(det) > 1e-12:
                sd = (ca - b * cb) / det
                td = (b * ca - cb) / det
            else:  # parallel: least-norm rates of the (consistent) pair of equations
                A2 = np.array([[-1.0, b], [-b, 1.0]])
                rhs = np.array([ca, cb])
                sol = np.linalg.lstsq(A2, rhs, 1e-12)[0]
                sd, td = sol[0], sol[1]
        elif slide[0] != 0.0:
            sd = -ca
        elif slide[1] != 0.0:
            td = cb
        dd = np.empty(3)
        for a in range(3):
            dd[a] = dv[a] + td * u[1, a] - sd * u[0, a]
        gd = _dot(n, dd)
        gdd = (n[0] * (accel[1, 0] - accel[0, 0]) + n[1] * (accel[1, 1] - accel[0, 1])
               + n[2] * (accel[1, 2] - accel[0, 2]) + 2.0 * td * _dot(n, turn_b) - 2.0 * sd * _dot(n, turn_a))
        if length > 0.0:
            gdd += (_dot(dd, dd) - gd * gd) / length
        reach = radius[0] + 0.5 * g
        for a in range(3):
            point[a] = x[0, a] + n[a] * reach
            ndot = (dd[a] - n[a] * gd) / length if length > 0.0 else 0.0
            pdot[a] = vel[0, a] + sd * u[0, a] + ndot * reach + n[a] * 0.5 * gd
    jdot[row] = gdd
    if r == 1:
        return
    # tangent rows: e . (a_B(p) - a_A(p) + w_B x (p' - v_B(p)) - w_A x (p' - v_A(p)))
    total = np.zeros(3)
    for i in range(2):
        body_motion(p, w, acc, bodies[i], point, vel[i], accel[i], om[i], al[i])
        sign = 1.0 if i == 1 else -1.0
        for a in range(3):
            tmp[a] = pdot[a] - vel[i, a]
        _cross(om[i], tmp, tmp2)
        for a in range(3):
            total[a] += sign * (accel[i, a] + tmp2[a])
    for e in range(1, r):
        jdot[row + e] = frame[e, 0] * total[0] + frame[e, 1] * total[1] + frame[e, 2] * total[2]


__all__ = ["contact_shape", "contact_bias", "body_motion", "point_velocity", "clearance", "separating_gap", "core_gap",
           "needs_axes", "bounding_radius", "SHAPE_PLANE", "SHAPE_CORES"]
