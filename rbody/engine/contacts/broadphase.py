"""The broad phase: which contact pairs can touch within a step, from each geom's bounding sphere found once.

The constraint table lists every pair of geoms MuJoCo's rules let collide (rbody.engine.constraints.table): one
pair record each (its first candidate's unit, its candidates, its first row, rows per candidate, its two geoms,
its margin) and one geom record per geom (its body, type, and where a unit record holds its pose and size). A
step asks of every pair whether any of its candidates can touch or close within it, by the lower bound on its gap
of contacts.kinematics.clearance: the gap between the two geoms' bounding spheres less h times a bound on the
speed at which any two of their points approach,

    reach = |c_b - c_a| - r_a - r_b - h (|v_b - v_a| + |w_a| r_a + |w_b| r_b) - margin

(a plane: the sphere's height above it in place of the distance, r_a = 0). Here each geom's centre c, its
velocity v, |w| and radius r are found once per call (geom_spheres, G geoms), and a pair's bound is then a few
operations on its two geoms' (pair_reach): the numbers clearance gives, in the same order of operations, so the
same bits. Where the spheres do not part a pair (a long box's sphere reaches far beyond it, two legs side by side
overlap theirs) and the geoms' axes may (clearance: the separating axes, or the lowest point above a plane), or for
a height field, clearance itself answers. A pair found far costs this, and no read
of its candidates' unit records: a quadruped's 7,792 candidates come in 592 pairs of 44 geoms, and a walk over
every unit record (5 MB) costs more than all of these tests.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.contacts.geometry import PLANE, bounding_radius
from rbody.engine.contacts.kinematics import _geom_centre, clearance, needs_axes, point_velocity
from rbody.engine.contacts.terrain import HFIELD
from rbody.engine.elements import block_offset
from rbody.engine.multibody import _views
from rbody.engine.constraints.table import (C_CONTACT0, C_GEOM, C_GEOMS, C_PAIR, C_PAIRS, C_ROWS, C_UNIT, G_BODY,
                                            G_POSE, G_TYPE, GEOM_SIZE, P_GEOM_A, P_GEOM_B, P_MARGIN, P_ROW, P_SLOTS,
                                            P_UNIT, P_WIDTH, PAIR_SIZE, U_GMAT_A, U_GPOS_A, U_GSIZE_A, UNIT_SIZE)

# a geom's sphere (geom_spheres): centre (3) [m], the centre's velocity (3) [m/s], |omega| [rad/s], bounding radius
# [m], a plane's outward normal (3)
S_CENTRE, S_VELOCITY, S_SPIN, S_RADIUS, S_NORMAL = 0, 3, 6, 7, 8
SPHERE_SIZE = 11
# a geom record's pose points at its position in a unit record; its axes (row-major) and size follow there
AXES_AT, SIZE_AT = U_GMAT_A - U_GPOS_A, U_GSIZE_A - U_GPOS_A


@njit(cache=True, inline="always")
def contact0(p):
    """The first contact unit (every unit before it is a limit, friction or an equality; the unit count if none)."""
    return int(p[block_offset(p) + C_CONTACT0])


@njit(cache=True, inline="always")
def contact_row0(p):
    """The first contact row (the rows of the units before the contacts are those below it)."""
    if pair_count(p) == 0:
        return int(p[block_offset(p) + C_ROWS])
    return int(p[pair_at(p, 0) + P_ROW])


@njit(cache=True, inline="always")
def pair_count(p):
    return int(p[block_offset(p) + C_PAIRS])


@njit(cache=True, inline="always")
def pair_at(p, i):
    """Offset of pair i's record in the params row."""
    return int(p[block_offset(p) + C_PAIR]) + i * PAIR_SIZE


@njit(cache=True, inline="always")
def geom_count(p):
    return int(p[block_offset(p) + C_GEOMS])


@njit(cache=True, inline="always")
def geom_at(p, i):
    """Offset of geom i's record in the params row."""
    return int(p[block_offset(p) + C_GEOM]) + i * GEOM_SIZE


@njit(cache=True, inline="always")
def pair_span(p, at):
    """(first unit, candidates, first row, rows per candidate) of the pair record at `at`: candidate j is unit
    first + j, its rows from first row + j * rows per candidate."""
    return int(p[at + P_UNIT]), int(p[at + P_SLOTS]), int(p[at + P_ROW]), int(p[at + P_WIDTH])


@njit(cache=True, inline="always")
def first_unit_at(p, at):
    """Offset of the unit record of the pair at `at`'s first candidate."""
    return int(p[block_offset(p) + C_UNIT]) + int(p[at + P_UNIT]) * UNIT_SIZE


@njit(cache=True)
def geom_spheres(p, w, h, spheres):
    """spheres (geoms, SPHERE_SIZE): every contact geom's bounding sphere after the tree's kinematics in the
    workspace w: its centre in the world, its radius (geometry.bounding_radius; +inf for a plane or a height field),
    a plane's normal (its third axis) and, for h > 0, the centre's velocity and |omega| of its body (the workspace's
    velocities; the world's: 0)."""
    ws = _views(p, w)
    for i in range(geom_count(p)):
        at = geom_at(p, i)
        body, kind, pose = int(p[at + G_BODY]), int(p[at + G_TYPE]), int(p[at + G_POSE])
        centre = spheres[i, S_CENTRE:S_CENTRE + 3]
        _geom_centre(p, w, body, pose, centre)
        spheres[i, S_RADIUS] = bounding_radius(kind, p, pose + SIZE_AT)
        if kind == PLANE:  # its normal: the geom's third axis in the world (geom_pose's, in its order)
            for a in range(3):
                if body < 0:
                    spheres[i, S_NORMAL + a] = p[pose + AXES_AT + 3 * a + 2]
                else:
                    value = 0.0
                    for e in range(3):
                        value += ws.xmat[body, a, e] * p[pose + AXES_AT + 3 * e + 2]
                    spheres[i, S_NORMAL + a] = value
        if h > 0.0:
            point_velocity(p, w, body, centre, spheres[i, S_VELOCITY:S_VELOCITY + 3])
            spin = 0.0
            if body >= 0:
                omega = ws.vel[body]
                spin = np.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2)
            spheres[i, S_SPIN] = spin


@njit(cache=True)
def pair_reach(p, w, at, h, spheres, work):
    """(reach, motion) of the pair record at `at` over the next h [s]: clearance's lower bound [m] on the gap of
    every candidate of the pair and h times its bound on their approach speed [m], from the geoms' spheres
    (geom_spheres at this h and workspace), to the bit; clearance itself where the spheres do not part a pair whose
    axes may (kinematics.needs_axes), or for a height field. work: scratch of rows.GEOMETRY_WORK floats."""
    ga, gb = int(p[at + P_GEOM_A]), int(p[at + P_GEOM_B])
    ta, tb = int(p[geom_at(p, ga) + G_TYPE]), int(p[geom_at(p, gb) + G_TYPE])
    if ta == HFIELD:
        return clearance(p, w, first_unit_at(p, at), h, work)
    a, b = spheres[ga], spheres[gb]
    radius_b = b[S_RADIUS]
    if ta == PLANE:
        radius_a = 0.0
        apart = (a[S_NORMAL] * (b[0] - a[0]) + a[S_NORMAL + 1] * (b[1] - a[1]) + a[S_NORMAL + 2] * (b[2] - a[2])) \
            - radius_b
    else:
        radius_a = a[S_RADIUS]
        apart = np.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2) - radius_a - radius_b
    motion = 0.0
    if h > 0.0:
        speed = np.sqrt((b[3] - a[3]) ** 2 + (b[4] - a[4]) ** 2 + (b[5] - a[5]) ** 2)
        if int(p[geom_at(p, ga) + G_BODY]) >= 0:
            speed += a[S_SPIN] * radius_a
        if int(p[geom_at(p, gb) + G_BODY]) >= 0:
            speed += b[S_SPIN] * radius_b
        motion = h * speed
    if apart - motion <= 1e-9 and needs_axes(ta, tb):
        return clearance(p, w, first_unit_at(p, at), h, work)  # the geoms' axes may part them
    return apart - motion - p[at + P_MARGIN], motion


__all__ = ["contact0", "contact_row0", "pair_count", "pair_at", "geom_count", "geom_at", "pair_span", "first_unit_at",
           "geom_spheres", "pair_reach", "SPHERE_SIZE"]
