"""Where a contact unit's geoms are, and its candidate contact, from the tree's workspace, compiled.

A contact unit of the constraint table (rbody.engine.constraints.table: CONTACT, CONTACT1) names two geoms by
their type codes, their bodies (-1: the world) and their poses in their bodies' frames; after the tree's
kinematics (rbody.engine.multibody: xorigin, xpos, xmat) each geom's world pose is its body's pose composed with
its own, and the unit's candidate (its slot among the pair's candidates, rbody.engine.contacts.geometry) gives
the gap function g (the signed distance less the pair's margin, U_MARGIN: MuJoCo's inflation of the surfaces), the
normal n (from geom a to geom b) and the contact point.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.contacts.geometry import (BOX, COLLIDE_WORK, MAX_SLOTS, MESH, PLANE, answers_beyond, bounding_radius,
                                           collide)
from rbody.engine.contacts.terrain import FIELD_HEADER, HFIELD, collide_field
from rbody.engine.multibody import _views
from rbody.engine.constraints.table import (U_BODY1, U_BODY2, U_DOF, U_GMAT_A, U_GMAT_B, U_GPOS_A, U_GPOS_B,
                                            U_GSIZE_A, U_GSIZE_B, U_GTYPE_A, U_GTYPE_B, U_HULL_A, U_HULL_B,
                                            U_MARGIN, U_WINDOW)


@njit(cache=True)
def geom_pose(p, w, body, pos_at, mat_at, pos, mat):
    """pos (3,) [m] and mat (3, 3) of a geom in the world: body's frame (world coordinates, its tree's origin
    added) composed with the geom's pose read at pos_at, mat_at in the params row p (the world's: as read)."""
    if body < 0:
        for a in range(3):
            pos[a] = p[pos_at + a]
            for c in range(3):
                mat[a, c] = p[mat_at + 3 * a + c]
        return
    ws = _views(p, w)
    for a in range(3):
        acc = ws.xorigin[body, a] + ws.xpos[body, a]
        for c in range(3):
            acc += ws.xmat[body, a, c] * p[pos_at + c]
        pos[a] = acc
        for c in range(3):
            value = 0.0
            for e in range(3):
                value += ws.xmat[body, a, e] * p[mat_at + 3 * e + c]
            mat[a, c] = value
    return


GEOMETRY_WORK = 24 + 7 * MAX_SLOTS + COLLIDE_WORK  # the floats contact_geometry's scratch holds


@njit(cache=True, inline="always")
def hull_at(p, at):
    """The packed convex hull (rbody.engine.contacts.convex.pack_hull) whose record starts at `at` in the params row
    p, a view; at < 0 (not a mesh): an empty view. Its length: 3 + 3 V + 4 F + (V + 1) + A."""
    if at < 0:
        return p[0:0]
    V, F, A = int(p[at]), int(p[at + 1]), int(p[at + 2])
    return p[at:at + 3 + 3 * V + 4 * F + V + 1 + A]


@njit(cache=True, inline="always")
def field_at(p, at):
    """The height field record (rbody.engine.contacts.terrain.pack_field) whose record starts at `at` in the params
    row p, a view."""
    return p[at:at + FIELD_HEADER + int(p[at]) * int(p[at + 1])]


@njit(cache=True)
def _candidates(p, w, u, work, only, beyond=np.inf):
    """collide on the contact unit at u's pair of geoms, posed after the tree's kinematics, into work (GEOMETRY_WORK
    floats: the poses, then gaps work[24:24 + MAX_SLOTS] (the distances less the pair's margin), normals and
    points, then collide's scratch); only: one slot, or -1 for all; beyond [m]: a pair whose least gap exceeds it
    may give that least gap for every slot (collide)."""
    pa, pb = work[0:3], work[3:6]
    Ra, Rb = work[6:15].reshape((3, 3)), work[15:24].reshape((3, 3))
    geom_pose(p, w, int(p[u + U_BODY1]), u + U_GPOS_A, u + U_GMAT_A, pa, Ra)
    geom_pose(p, w, int(p[u + U_BODY2]), u + U_GPOS_B, u + U_GMAT_B, pb, Rb)
    dist = work[24:24 + MAX_SLOTS]
    normals = work[24 + MAX_SLOTS:24 + 4 * MAX_SLOTS].reshape((MAX_SLOTS, 3))
    points = work[24 + 4 * MAX_SLOTS:24 + 7 * MAX_SLOTS].reshape((MAX_SLOTS, 3))
    if int(p[u + U_GTYPE_A]) == HFIELD:  # a height field's window (every slot at once)
        count = collide_field(pa, Ra, field_at(p, int(p[u + U_HULL_A])), int(p[u + U_GTYPE_B]), pb, Rb,
                              p[u + U_GSIZE_B:u + U_GSIZE_B + 3], hull_at(p, int(p[u + U_HULL_B])),
                              p[u + U_WINDOW + 2], int(p[u + U_WINDOW]), int(p[u + U_WINDOW + 1]), dist, normals,
                              points, beyond + p[u + U_MARGIN])
    else:
        count = collide(int(p[u + U_GTYPE_A]), pa, Ra, p[u + U_GSIZE_A:u + U_GSIZE_A + 3],
                        hull_at(p, int(p[u + U_HULL_A])), int(p[u + U_GTYPE_B]), pb, Rb,
                        p[u + U_GSIZE_B:u + U_GSIZE_B + 3], hull_at(p, int(p[u + U_HULL_B])), dist, normals, points,
                        only, beyond + p[u + U_MARGIN], work[24 + 7 * MAX_SLOTS:GEOMETRY_WORK])
    margin = p[u + U_MARGIN]
    if margin != 0.0:
        for k in range(count):
            if only < 0 or k == only:
                dist[k] -= margin  # APART (+inf) stays APART
    return count


@njit(cache=True)
def pair_candidates(p, w, u, work, beyond=np.inf):
    """Every candidate of the contact unit at u's pair of geoms at once (the unit's slot aside) into work (GEOMETRY_WORK
    floats): distances work[24:24 + MAX_SLOTS], normals and points after them (as contact_geometry lays them out);
    returns their count. For a caller that reads all of a pair's candidates: the geoms' poses once. beyond [m]:
    where the pair's least gap is above it, every slot may hold that least gap (a lower bound of its own) instead
    of its own, the pairs whose candidates cost most (a mesh's) then computing one distance: for a caller that
    only asks which candidates come within `beyond`."""
    return _candidates(p, w, u, work, -1, beyond)


@njit(cache=True, inline="always")
def exact_within(p, u, count, work, beyond):
    """Whether pair_candidates(p, w, u, work, beyond), which returned count, wrote every candidate exactly: a pair of
    primitives always does; a pair with a mesh, an ellipsoid or a height field only where its least gap is within
    beyond (else its slots may hold that least gap, a bound)."""
    ta, tb = int(p[u + U_GTYPE_A]), int(p[u + U_GTYPE_B])
    if not (ta == HFIELD or answers_beyond(ta, tb)):  # a field's window answers it as _general does
        return True
    for k in range(count):
        if work[24 + k] <= beyond:
            return True
    return False


@njit(cache=True, inline="always")
def candidate(work, k, normal, point):
    """Slot k's gap [m] (returned), normal (3,) and point (3,) from work as _candidates lays them out."""
    for a in range(3):
        normal[a] = work[24 + MAX_SLOTS + 3 * k + a]
        point[a] = work[24 + 4 * MAX_SLOTS + 3 * k + a]
    return work[24 + k]


KEPT = 8  # the floats kept for a contact unit: whether exact (1) or not (0), its gap, normal (3) and point (3)
POSED = 24  # the floats kept for a contact pair: its geoms' poses where its candidates were found (_candidates' order:
            # position a, position b, axes a, axes b)
KEPT_MOTION = np.finfo(np.float64).eps  # a flat-faced pair moved by less than this times its geoms' reach from the
                                        # origin (|centre| + bounding radius, summed) reads its kept candidates


@njit(cache=True)
def kept_geometry_size(nq, units, pairs):
    """The length of a kept geometry: whether it holds one (1) or not (0), the configuration q (nq,) it was found at,
    KEPT floats for each of the table's units (the contact units' candidates; the others unused), then POSED floats
    for each contact pair (its geoms' poses where they were found). A step's end finds every touching pair's
    candidates (its projection's gaps); the next step starts at that configuration and would find them again: it
    reads them here instead, where q has the same bits. The next step's end reads them too where a flat-faced pair
    has moved by less than the round-off of its geoms' poses since (moved_within_round_off): a pair at rest moves by
    round-off every step."""
    return _poses_at(nq, units, pairs)


@njit(cache=True, inline="always")
def keep_geometry(kept, nq, k, exact, gap, normal, point):
    """Keep unit k's candidate: its gap [m], normal (3,) and point (3,) [m], exact or not (a bound, or not found)."""
    at = 1 + nq + KEPT * k
    kept[at] = 1.0 if exact else 0.0
    kept[at + 1] = gap
    for a in range(3):
        kept[at + 2 + a] = normal[a]
        kept[at + 5 + a] = point[a]


@njit(cache=True, inline="always")
def forget_geometry(kept, nq, k):
    """Mark unit k's candidate not kept (a pair's first unit: the step reads a pair's candidates from kept only
    where its first is exact, rbody.engine.constraints.stepping.near_contacts)."""
    kept[1 + nq + KEPT * k] = 0.0


@njit(cache=True, inline="always")
def kept_for(kept, q):
    """Whether kept holds a geometry found at the configuration q (nq,), to the bit."""
    if kept[0] == 0.0:
        return False
    for a in range(q.shape[0]):
        if kept[1 + a] != q[a]:
            return False
    return True


@njit(cache=True, inline="always")
def kept_exact(kept, nq, k):
    """Whether unit k's kept candidate is exact."""
    return kept[1 + nq + KEPT * k] != 0.0


@njit(cache=True, inline="always")
def kept_candidate(kept, nq, k, normal, point):
    """Unit k's kept gap [m] (returned), normal (3,) and point (3,)."""
    at = 1 + nq + KEPT * k
    for a in range(3):
        normal[a] = kept[at + 2 + a]
        point[a] = kept[at + 5 + a]
    return kept[at + 1]


@njit(cache=True, inline="always")
def _poses_at(nq, units, i):
    """Where contact pair i's kept poses start (kept_geometry_size's layout; units: the table's unit count)."""
    return 1 + nq + KEPT * units + POSED * i


@njit(cache=True, inline="always")
def keep_poses(kept, nq, units, i, work):
    """Keep contact pair i's geoms' poses, work[:POSED] as pair_candidates left them (the poses it found the pair's
    candidates at); units: the table's unit count."""
    at = _poses_at(nq, units, i)
    for a in range(POSED):
        kept[at + a] = work[a]


@njit(cache=True, inline="always")
def _flat_faced(kind):
    """Whether a geom's surface is flat faces only (a plane, a box, a mesh's convex hull)."""
    return kind == PLANE or kind == BOX or kind == MESH


@njit(cache=True)
def moved_within_round_off(p, w, u, kept, nq, units, i, now):
    """Whether contact pair i, its first unit's record at u, has moved since its kept poses (keep_poses) by less than
    the round-off of the poses themselves, after the tree's kinematics in the workspace w; now: POSED floats of
    scratch (the poses now). Every point of a geom at most r from its centre c (r: geometry.bounding_radius) moves
    by at most |c' - c| + r ||R' - R||_F (R its axes: ||(R' - R) x|| <= ||R' - R||_2 |x|); the pair's two such
    moves, summed, must be within KEPT_MOTION (eps) times the reach of its geoms from the origin, |c| + r each,
    the scale of the round-off the poses carry. A plane's radius is infinite: its axes must not have turned at all,
    and it adds nothing to the scale (a floor on the world does not move).

    Flat-faced pairs only (planes, boxes, meshes: _flat_faced): their candidates are corners and clipped edges, and a
    body rocking on them pivots on its corners. Where a geom is round, its point of contact rolls over it as the body
    rocks, and that roll, at the first order of the rocking, is what holds a body balanced on a round surface: read
    from a kept geometry, a cube resting on a lying cylinder's top line lost it, its angular velocity growing from
    2e-16 to 1.5e-14 rad/s in 1 s (found again every step it stays at 2e-16: tests/rbody/engine/
    test_cylinder_box_pairs.py)."""
    if not (_flat_faced(int(p[u + U_GTYPE_A])) and _flat_faced(int(p[u + U_GTYPE_B]))):
        return False
    at = _poses_at(nq, units, i)
    geom_pose(p, w, int(p[u + U_BODY1]), u + U_GPOS_A, u + U_GMAT_A, now[0:3], now[6:15].reshape((3, 3)))
    geom_pose(p, w, int(p[u + U_BODY2]), u + U_GPOS_B, u + U_GMAT_B, now[3:6], now[15:24].reshape((3, 3)))
    moved, scale = 0.0, 0.0
    for side in range(2):
        centre, axes = 3 * side, 6 + 9 * side
        size_at = u + U_GSIZE_A if side == 0 else u + U_GSIZE_B
        radius = bounding_radius(int(p[u + U_GTYPE_A if side == 0 else u + U_GTYPE_B]), p, size_at)
        shift, turn, reach = 0.0, 0.0, 0.0
        for a in range(3):
            shift += (now[centre + a] - kept[at + centre + a]) ** 2
            reach += now[centre + a] ** 2
        for a in range(9):
            turn += (now[axes + a] - kept[at + axes + a]) ** 2
        moved += np.sqrt(shift)
        if turn > 0.0:
            moved += radius * np.sqrt(turn)  # (+inf for a plane that turned)
        if radius < np.inf:
            scale += np.sqrt(reach) + radius
    return moved <= KEPT_MOTION * scale


@njit(cache=True)
def contact_geometry(p, w, u, normal, point, work=None):
    """The gap g [m] of the contact unit whose record starts at u (returned), its normal (3,) from geom a to geom b
    and its point (3,) [m, world], after the tree's kinematics in the workspace w. work: None, or scratch of
    GEOMETRY_WORK floats a caller looping over many units passes to spare the allocations."""
    if work is None:
        work = np.empty(GEOMETRY_WORK)
    k = int(p[u + U_DOF])
    _candidates(p, w, u, work, k)
    return candidate(work, k, normal, point)


__all__ = ["geom_pose", "contact_geometry", "pair_candidates", "candidate", "exact_within", "hull_at", "field_at",
           "GEOMETRY_WORK", "KEPT", "POSED", "KEPT_MOTION", "kept_geometry_size", "keep_poses",
           "moved_within_round_off", "keep_geometry", "forget_geometry", "kept_for", "kept_exact",
           "kept_candidate"]
