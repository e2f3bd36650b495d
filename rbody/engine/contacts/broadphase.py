"""The broad phase: which contact pairs can touch within a step, from each geom's bounding sphere found once.

The constraint table lists every pair of geoms MuJoCo's rules let collide (rbody.engine.constraints.table): one
pair record each (its first candidate's unit, its candidates, its first row, rows per candidate, its two geoms,
its margin) and one geom record per geom (its body, type, and where a unit record holds its pose and size). A
step asks of every pair whether any of its candidates can touch or close within it, by the lower bound on its gap
of contacts.kinematics.clearance: the gap between the two geoms' bounding spheres less h times a bound on the
speed at which any two of their points approach,

    reach = |c_b - c_a| - r_a - r_b - h (|v_b - v_a| + |w_a| r_a + |w_b| r_b) - margin

(a plane: the sphere's height above it in place of the distance, r_a = 0). Here each geom's centre c, its
velocity v, |w| r and radius r are found once per call (geom_spheres, G geoms), and every pair's bound is then a
few operations on two rows of them in one loop (pair_reaches): the numbers clearance gives, in the same order of
operations, so the same bits. Where the spheres, less the margin, do not part a pair (a long box's sphere reaches
far beyond it, two legs side by side overlap theirs, a quadruped's thigh passes its trunk within the margins) and
the geoms' axes may (clearance: the cores of round geoms, the separating axes, the lowest point above a plane), or
for a height field, clearance itself answers. A pair found far costs this, and no read of its candidates' unit
records: a quadruped's 7,792 candidates come in 592 pairs of 44 geoms, and a walk over every unit record (5 MB)
costs more than all of these tests.

A caller that keeps memory from call to call (the time-stepping: kept_size) also keeps a neighbour list, Verlet's
list of molecular dynamics: the pairs whose spheres, less the margin, were within NEIGHBOUR_SKIN when it was built,
and each geom's centre then. While no two geoms have moved together by more than the skin, only those pairs are
bounded (pair_reaches): a standing quadruped's 4 of 636.

The list also keeps, for each pair whose spheres did not part it, the gap clearance found between its geoms and
where: geom b's pose in geom a's frame (the gap depends on that alone). Any point of b has moved in a's frame by at
most |t - t0| + r_b |Q - Q0|_F since (t, Q: that pose, r_b: b's bounding radius), so

    gap >= gap0 - |t - t0| - r_b |Q - Q0|_F,

which, less the step's motion and the margin, answers for the pair where it is above TIGHTEN_BELOW: a pose and a
product of two rotations, not the separating axes of two meshes (a humanoid standing: 41 pairs of limbs whose
spheres overlap, 0.5 us each by their axes).
"""

from __future__ import annotations

import numpy as np
from numba import carray, njit

from rbody.engine.contacts.geometry import PLANE, bounding_radius
from rbody.engine.contacts.kinematics import TIGHTEN_BELOW, clearance, needs_axes
from rbody.engine.contacts.rows import GEOMETRY_WORK, kept_geometry_size
from rbody.engine.contacts.terrain import HFIELD
from rbody.engine.elements import block_offset
from rbody.engine.memory import cut, keep_alive, stack_floats
from rbody.engine.multibody import H_NQ, STACK_FLOATS, _views
from rbody.engine.constraints.table import (C_CONTACT0, C_GEOM, C_GEOMS, C_PAIR, C_PAIRS, C_ROWS, C_UNIT, C_UNITS,
                                            G_BODY, G_POSE, G_TYPE, GEOM_SIZE, P_GEOM_A, P_GEOM_B, P_MARGIN, P_ROW,
                                            P_SLOTS, P_UNIT, P_WIDTH, PAIR_SIZE, U_GMAT_A, U_GPOS_A, U_GSIZE_A,
                                            U_MARGIN, UNIT_SIZE)

# a geom's sphere (geom_spheres): centre (3) [m], the centre's velocity (3) [m/s], |omega| r [m/s] (0 for a plane or
# the world's), bounding radius r [m], a plane's outward normal (3), its type (geometry's codes)
S_CENTRE, S_VELOCITY, S_SWEEP, S_RADIUS, S_NORMAL, S_KIND = 0, 3, 6, 7, 8, 11
SPHERE_SIZE = 12
# the neighbour list (pair_reaches): 1 where built, the listed pairs' count, each geom's centre (3) where it was
# built, the listed pairs' indices
N_BUILT, N_COUNT, N_CENTRES = 0, 1, 2
# after them, each pair's tightened gap (_tightened): 1 where found, the gap's lower bound [m] clearance found (no
# motion, no margin), and where: geom b's centre (3) and axes (3, 3, row-major) in geom a's frame
T_FOUND, T_GAP, T_SHIFT, T_TURN = 0, 1, 2, 5
TIGHT_SIZE = 14
# a geom's axes within one call of pair_reaches (3, 3, row-major), then 1 where found
AXES_FOUND = 9
AXES_SIZE = 10
NEIGHBOUR_SKIN = 0.02  # [m] a pair is listed where its spheres, less its margin, are this close
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
    geoms = geom_at(p, 0)
    for i in range(geom_count(p)):  # (geom i's record from the first's: geom_at's chain of reads from the header,
        at = geoms + i * GEOM_SIZE  # redone each pass, since a store to the spheres may alias p, cost as much)
        body, kind, pose = int(p[at + G_BODY]), int(p[at + G_TYPE]), int(p[at + G_POSE])
        # Its centre, kinematics._geom_centre's sum, and below its velocity, point_velocity's, written here on the
        # workspace's arrays: those helpers given p and w cost numba's reference counts of both per geom, inlined or
        # not (the inliner binds each argument to a new variable), more than the sphere's arithmetic.
        for a in range(3):
            if body < 0:
                spheres[i, S_CENTRE + a] = p[pose + a]
            else:
                spheres[i, S_CENTRE + a] = (ws.xorigin[body, a] + ws.xpos[body, a] + ws.xmat[body, a, 0] * p[pose]
                                            + ws.xmat[body, a, 1] * p[pose + 1] + ws.xmat[body, a, 2] * p[pose + 2])
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
        spheres[i, S_KIND] = kind
        if h > 0.0:  # v_O + omega x r, r from the origin of the body's tree; the fastest any of its points moves
            sweep = 0.0  # about its centre: |omega| r
            if body < 0:
                for a in range(3):
                    spheres[i, S_VELOCITY + a] = 0.0
            else:
                r0 = spheres[i, S_CENTRE] - ws.xorigin[body, 0]
                r1 = spheres[i, S_CENTRE + 1] - ws.xorigin[body, 1]
                r2 = spheres[i, S_CENTRE + 2] - ws.xorigin[body, 2]
                spheres[i, S_VELOCITY] = ws.vel[body, 3] + ws.vel[body, 1] * r2 - ws.vel[body, 2] * r1
                spheres[i, S_VELOCITY + 1] = ws.vel[body, 4] + ws.vel[body, 2] * r0 - ws.vel[body, 0] * r2
                spheres[i, S_VELOCITY + 2] = ws.vel[body, 5] + ws.vel[body, 0] * r1 - ws.vel[body, 1] * r0
                if kind != PLANE and kind != HFIELD:  # (their radius: inf)
                    sweep = np.sqrt(ws.vel[body, 0] ** 2 + ws.vel[body, 1] ** 2 + ws.vel[body, 2] ** 2) * \
                        spheres[i, S_RADIUS]
            spheres[i, S_SWEEP] = sweep


@njit(cache=True)
def neighbours_size(p):
    """The length of the neighbour list (pair_reaches): whether it holds one, its count, each geom's centre (3) [m]
    where it was built, the listed pairs' indices, then each pair's tightened gap (TIGHT_SIZE)."""
    return _tight_at(p) + TIGHT_SIZE * pair_count(p)


@njit(cache=True)
def kept_size(p):
    """The length of what a step keeps for the next (stepping.moreau_step's end_geometry): the contacts' geometry
    (rows.kept_geometry_size), then the broad phase's neighbour list (neighbours_size). Both hold for the geoms of p
    as they were: a caller that changes a geom's size, pose or margin in p starts from a new one (zeros)."""
    return _neighbours_from(p) + neighbours_size(p)


@njit(cache=True, inline="always")
def kept_neighbours(p, kept):
    """The neighbour list within a step's kept memory (kept_size): a view of its tail; empty where kept holds the
    geometry only (pair_reaches then bounds every pair)."""
    start = _neighbours_from(p)
    if kept.shape[0] < start + neighbours_size(p):
        return kept[:0]
    return kept[start:start + neighbours_size(p)]


@njit(cache=True)
def _list_holds(p, spheres, h, neighbours):
    """The largest sum, over two geoms, of the distance each centre has moved since the neighbour list was built
    and h times the fastest any of its points moves (|v| + |omega| r), where that sum is within NEIGHBOUR_SKIN less
    twice TIGHTEN_BELOW: the list then holds every pair whose bound can be at most TIGHTEN_BELOW. A negative value
    where it does not (or none was built). Planes and height fields are left out: a pair with one that moves is
    always listed, and one on the world does not move."""
    if neighbours.shape[0] == 0 or neighbours[N_BUILT] != 1.0:
        return -1.0
    first, second = 0.0, 0.0
    for i in range(geom_count(p)):
        kind = int(spheres[i, S_KIND])
        if kind == PLANE or kind == HFIELD:
            continue
        c = N_CENTRES + 3 * i
        moved = np.sqrt((spheres[i, 0] - neighbours[c]) ** 2 + (spheres[i, 1] - neighbours[c + 1]) ** 2
                        + (spheres[i, 2] - neighbours[c + 2]) ** 2)
        if h > 0.0:
            moved += h * (np.sqrt(spheres[i, 3] ** 2 + spheres[i, 4] ** 2 + spheres[i, 5] ** 2)
                          + spheres[i, S_SWEEP])
        if not moved <= NEIGHBOUR_SKIN:  # (a NaN too)
            return -1.0
        if moved > first:
            first, second = moved, first
        elif moved > second:
            second = moved
    if first + second > NEIGHBOUR_SKIN - 2.0 * TIGHTEN_BELOW:
        return -1.0
    return first + second


@njit(cache=True)
def pair_reaches(p, w, h, reach, motion, neighbours):
    """reach, motion (pairs,): for every pair over the next h [s], clearance's lower bound [m] on the gap of each of
    its candidates and h times its bound on their approach speed [m], to the bit, from the geoms' spheres
    (geom_spheres, after the tree's kinematics in the workspace w, its velocities for h > 0); clearance itself where
    the spheres' bound less the margin is at most kinematics.TIGHTEN_BELOW and the geoms' axes may part the pair
    (kinematics.needs_axes), or for a height field. One loop over the pair records reading two rows of the spheres
    each (5 ns a pair; a call per pair costs seven times that).

    neighbours (neighbours_size(p),), kept by the caller from call to call, or empty: the pairs whose spheres, less
    the margin, were within NEIGHBOUR_SKIN where it was built (and every pair with a height field or a moving plane).
    Where no two geoms have moved, with h times their speeds, more than the skin less twice TIGHTEN_BELOW since
    (_list_holds), only the listed pairs are bounded, to the same bits; every other pair's bound is above
    TIGHTEN_BELOW, and it is given the lower bound NEIGHBOUR_SKIN - TIGHTEN_BELOW less that sum of moves (motion 0).
    Otherwise every pair is bounded and the list built again. A quadruped standing lists 4 to 33 of its 559 to 697
    pairs. With the list, a pair clearance would tighten is bounded from the gap it found before where that holds
    above TIGHTEN_BELOW (_tightened): a lower bound then, not clearance's bits; every caller reads a bound above
    TIGHTEN_BELOW as apart (its candidates neither touch nor close within the step), as it reads clearance's."""
    size = geom_count(p) * SPHERE_SIZE  # (on the stack where small)
    owned = carray(stack_floats(size), size) if size <= STACK_FLOATS else np.empty(size)
    spheres = cut(owned, 0, (geom_count(p), SPHERE_SIZE))
    geom_spheres(p, w, h, spheres)
    xmat = _views(p, w).xmat  # the tightened gaps' poses: each geom's axes, found where first needed (AXES_FOUND)
    axes = carray(stack_floats(geom_count(p) * AXES_SIZE), (geom_count(p), AXES_SIZE)) if \
        geom_count(p) * AXES_SIZE <= STACK_FLOATS else np.empty((geom_count(p), AXES_SIZE))
    axes[:, AXES_FOUND] = 0.0
    work = carray(stack_floats(GEOMETRY_WORK), GEOMETRY_WORK)  # clearance's scratch (not 30 kB from the heap)
    pairs = pair_at(p, 0)
    moves = _list_holds(p, spheres, h, neighbours)
    build = moves < 0.0 and neighbours.shape[0] > 0
    count = pair_count(p)
    if moves >= 0.0:
        reach[:] = NEIGHBOUR_SKIN - TIGHTEN_BELOW - moves
        motion[:] = 0.0
        count = int(neighbours[N_COUNT])
    first_listed, listed = _listed_at(p), 0
    for k in range(count):
        i = int(neighbours[first_listed + k]) if moves >= 0.0 else k
        at = pairs + i * PAIR_SIZE  # (pair i's record from the first's: pair_at's chain of reads from the header,
        a, b = int(p[at + P_GEOM_A]), int(p[at + P_GEOM_B])  # redone each pass since a store to reach may alias p)
        ta, tb = int(spheres[a, S_KIND]), int(spheres[b, S_KIND])
        if ta == HFIELD:
            reach[i], motion[i], _gap = clearance(p, w, first_unit_at(p, at), h, work)
            apart = -np.inf
        else:
            if ta == PLANE:
                apart = (spheres[a, S_NORMAL] * (spheres[b, 0] - spheres[a, 0])
                         + spheres[a, S_NORMAL + 1] * (spheres[b, 1] - spheres[a, 1])
                         + spheres[a, S_NORMAL + 2] * (spheres[b, 2] - spheres[a, 2])) - spheres[b, S_RADIUS]
            else:
                apart = (np.sqrt((spheres[b, 0] - spheres[a, 0]) ** 2 + (spheres[b, 1] - spheres[a, 1]) ** 2
                                 + (spheres[b, 2] - spheres[a, 2]) ** 2) - spheres[a, S_RADIUS] - spheres[b, S_RADIUS])
            moved = 0.0
            if h > 0.0:
                moved = h * (np.sqrt((spheres[b, 3] - spheres[a, 3]) ** 2 + (spheres[b, 4] - spheres[a, 4]) ** 2
                                     + (spheres[b, 5] - spheres[a, 5]) ** 2) + spheres[a, S_SWEEP] + spheres[b, S_SWEEP])
            if apart - moved - p[at + P_MARGIN] <= TIGHTEN_BELOW and needs_axes(ta, tb):  # the axes may part them
                reach[i], motion[i] = _tightened(p, w, first_unit_at(p, at), h, spheres, xmat, axes, a, b, moved,
                                                 neighbours, i, work)
            else:
                reach[i], motion[i] = apart - moved - p[at + P_MARGIN], moved
        if build and (apart - p[at + P_MARGIN] <= NEIGHBOUR_SKIN or _moving_plane(p, ta, a)):
            neighbours[first_listed + listed] = i
            listed += 1
    if build:
        neighbours[N_BUILT], neighbours[N_COUNT] = 1.0, listed
        for i in range(geom_count(p)):
            for e in range(3):
                neighbours[N_CENTRES + 3 * i + e] = spheres[i, e]
    keep_alive(owned)  # read through a view only


@njit(cache=True, inline="always")
def _neighbours_from(p):
    """Where the neighbour list starts in a step's kept memory: after the kept geometry (rows.kept_geometry_size)."""
    return kept_geometry_size(int(p[H_NQ]), int(p[block_offset(p) + C_UNITS]), pair_count(p))


@njit(cache=True, inline="always")
def _listed_at(p):
    """Where the neighbour list's pair indices start (after each geom's centre)."""
    return N_CENTRES + 3 * geom_count(p)


@njit(cache=True, inline="always")
def _tight_at(p):
    """Where the pairs' tightened gaps start in the neighbour list (after the listed pairs' indices)."""
    return _listed_at(p) + pair_count(p)


@njit(cache=True)
def _tightened(p, w, u, h, spheres, xmat, axes, a, b, moved, neighbours, i, work):
    """clearance's (bound, motion) for pair i (its first unit at u, its geoms a and b: rows of geom_spheres's
    spheres) whose spheres do not part it, moved [m]: h times its spheres' bound on the approach speed; xmat (bodies,
    3, 3): the bodies' axes (the workspace's); axes (geoms, AXES_SIZE): the geoms' axes where found this call. From
    the gap it found before and geom b's pose in geom a's frame then (module docstring), kept in the neighbour list,
    where that leaves the bound above TIGHTEN_BELOW; else from clearance, whose gap and pose are then kept. An empty
    list keeps nothing: clearance alone."""
    if neighbours.shape[0] == 0:
        reach, motion, _gap = clearance(p, w, u, h, work)
        return reach, motion
    for geom in (a, b):
        if axes[geom, AXES_FOUND] == 0.0:
            _geom_axes(p, xmat, geom, axes[geom])
            axes[geom, AXES_FOUND] = 1.0
    Ra, Rb = axes[a], axes[b]  # the geoms' axes (row-major)
    shift, turn = work[30:33], work[33:42]  # b's centre and axes in a's frame: Ra^T (pb - pa), Ra^T Rb (row-major)
    for x in range(3):
        shift[x] = 0.0
        for y in range(3):
            shift[x] += Ra[3 * y + x] * (spheres[b, S_CENTRE + y] - spheres[a, S_CENTRE + y])
        for z in range(3):
            turn[3 * x + z] = Ra[x] * Rb[z] + Ra[3 + x] * Rb[3 + z] + Ra[6 + x] * Rb[6 + z]
    t = _tight_at(p) + TIGHT_SIZE * i
    margin = p[u + U_MARGIN]
    if neighbours[t + T_FOUND] == 1.0:
        shifted, turned = 0.0, 0.0
        for x in range(3):
            shifted += (shift[x] - neighbours[t + T_SHIFT + x]) ** 2
        for x in range(9):
            turned += (turn[x] - neighbours[t + T_TURN + x]) ** 2
        bound = neighbours[t + T_GAP] - (np.sqrt(shifted) + spheres[b, S_RADIUS] * np.sqrt(turned)) - moved - margin
        if bound > TIGHTEN_BELOW:
            return bound, moved
    reach, motion, gap = clearance(p, w, u, h, work)
    neighbours[t + T_FOUND], neighbours[t + T_GAP] = 1.0, gap
    for x in range(3):
        neighbours[t + T_SHIFT + x] = shift[x]
    for x in range(9):
        neighbours[t + T_TURN + x] = turn[x]
    return reach, motion


@njit(cache=True, inline="always")
def _geom_axes(p, xmat, geom, R):
    """R[:9] geom's axes in the world, row-major: its body's axes (xmat) times its own (rows.geom_pose's
    product)."""
    at = geom_at(p, geom)
    body, pose = int(p[at + G_BODY]), int(p[at + G_POSE])
    for x in range(3):
        for z in range(3):
            if body < 0:
                R[3 * x + z] = p[pose + AXES_AT + 3 * x + z]
            else:
                R[3 * x + z] = (xmat[body, x, 0] * p[pose + AXES_AT + z] + xmat[body, x, 1] * p[pose + AXES_AT + 3 + z]
                                + xmat[body, x, 2] * p[pose + AXES_AT + 6 + z])


@njit(cache=True, inline="always")
def _moving_plane(p, kind, geom):
    """Whether a pair's first geom (a plane or height field sorts first) is a plane on a body: its pairs' bounds
    turn with the body, which its centre's move does not bound."""
    return kind == PLANE and int(p[geom_at(p, geom) + G_BODY]) >= 0


__all__ = ["contact0", "contact_row0", "pair_count", "pair_at", "geom_count", "geom_at", "pair_span", "first_unit_at",
           "geom_spheres", "pair_reaches", "neighbours_size", "kept_size", "kept_neighbours", "SPHERE_SIZE",
           "NEIGHBOUR_SKIN"]
