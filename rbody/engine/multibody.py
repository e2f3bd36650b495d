"""Multibody: the dynamics of any kinematic tree of rigid bodies, as model arrays and compiled algorithms.

The model (built once in numpy from a Layout) is one flat float64 row, `params`: a header, then one
record per body (parent, fixed placement in the parent, mass properties, its joints and degrees of
freedom), per joint (kind, axis, anchor, qpos/qvel addresses, ref, stiffness, springref) and per degree
of freedom (damping, armature), each record declared once below as a rbody.engine.schema.Record (TREE_HEADER,
BODY, JOINT, DOF), from which its offsets follow. Every algorithm is an @njit(cache=True) free function of (params, q, v,
...): a new model is new numbers in the same row, never new compiled code, and the same row is what the
integrators hand to the right-hand side of a TreeScene (rbody.scene).

Coordinates are MuJoCo's for the same model: bodies depth first from the world, joints in the order a
body lists them; hinge, slide and roll: one coordinate, displacement q - ref; ball: qpos a unit quaternion
(w, x, y, z), qvel the body-frame angular velocity; free: qpos the world position of the body frame's
origin and its quaternion, qvel that origin's world velocity then the body-frame angular velocity.
Several joints on one body compose in the order given, as MJCF composes them; a body without joints is
welded to its parent (no degree of freedom: its inertia simply adds to what its parent carries).
A roll joint (a round body of radius a rolling without slipping on a line) is a slide by a (q - ref)
along l = axis x normal followed by a hinge by q - ref about the axis through the anchor: one coordinate,
the contact point anchor - a normal at rest.

Algorithms (Featherstone, Rigid Body Dynamics Algorithms, 2008), all with spatial vectors
(rbody.engine.spatial) written in one frame, the world's axes about the origin of the body's tree ("ground
coordinates", RBDA sec. 7.3 remark; "Precision" below): a joint's motion subspace S is then a world-frame 6-vector computed
from the body's pose exactly as MuJoCo computes its cdof, several joints on one body are a chain of
massless virtual links with no transform between them, and nothing is ever moved between body frames:

- forward dynamics: the articulated-body algorithm (ABA), three passes, cost linear in the number of
  degrees of freedom. Chosen over the composite-rigid-body algorithm and a dense Cholesky (cubic in n)
  because the goal is long chains and big batches; for the tree's sparsity it needs no factorisation.
  Armature adds to the pivot D of its degree of freedom, which is exactly (M + diag(armature)) qdd.
  Articulated inertias are symmetric: only their upper triangles are updated and summed (21 of 36). The
  inward sweep is a chain of dependent eliminations; each one's rank-one update is left pending and applied
  while the next pivot is formed, and a body hands its inertia to its parent in registers where the parent
  comes next (_sweeps).
- inverse dynamics and the bias forces: the recursive Newton-Euler algorithm (RNEA), gravity entering
  as an upward acceleration of the world.
- the mass matrix: the composite-rigid-body algorithm (CRBA), inertias added towards the root
  (composites in this one frame add component by component).
Passive forces are MuJoCo's: -stiffness (q - springref) - damping qvel per hinge, slide or roll, -damping
qvel per degree of freedom of a ball or free joint (stiffness on those is refused).

A ball joint's degrees of freedom are rotations about the body's final axes (MuJoCo: "assume no
subsequent rotations"), so a ball joint must be the last joint of its body; a free joint is the only
joint of a child of the world.

Cost: an evaluation of the right-hand side allocates nothing: its workspace lives on its own stack
(stack_floats, an alloca) and every algorithm reads it, the model row and the state through raw pointers by
index (Offsets: where each workspace array starts; numba's array indexing would test every index for a negative
value), in two compiled functions shared by every entry point: _outward (pose, motion subspaces, velocities,
world inertia and the ABA's start, body after body in one pass) and _sweeps (the ABA's inward and outward
sweeps). Sums of products fuse into fused multiply-adds (FMA), which shortens the chains of dependent
operations. _views still cuts the workspace into named arrays for the other algorithms and for callers.
The same source compiles for one state (float64 pointers) and for eight side by side
(rbody.engine.simd.LanePointer: each workspace entry then holds eight lanes): tree_rhs_lanes steps a batch of a
tree without ball or free joints eight elements per instruction, each lane with tree_rhs's bits. The cosines
and sines of every hinge's half angle are formed first by a polynomial that LLVM vectorises
(rbody.engine.spatial.sin_cos). Measured by benchmarks/engine_core_speed.py against MuJoCo and Pinocchio.
numba's cache does not follow imports: after editing spatial.py, simd.py or memory.py, delete
rbody/engine/__pycache__/multibody*.nb[ci].

Precision: spatial quantities about a point lose digits in proportion to a body's distance from it
(|x| / size of the tree), so each tree (the bodies below one child of the world) is written about its own
origin: the world placement of its root body, or its free joint's position (kinematics: xorigin). The trees of
a model never exchange a force, so each tree's algebra may use its own point; only the outputs that need world
coordinates (centres of mass, potential energy) add the origin back. A tree a million metres from the world
origin then computes as it does at it (MuJoCo works about each tree's centre of mass, to the same effect).
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import carray, cfunc, njit

from rbody.engine import pointers
from rbody.engine.memory import address, data, keep_alive, stack_floats
from rbody.engine.schema import FLOAT, INT, Record
from rbody.layout import JOINTS, WORLD, coordinate_addresses, joint_order, tree_order
from rbody.engine.simd import (WIDTH, choose, equals, lane_pointer, maximum_of, number, positive_beyond,
                               sines_and_cosines as _sines_and_cosines)
from rbody.engine.spatial import dexp_inverse3, dot6, force_cross, inertia_apply, quat_exp, quat_multiply

# Joint codes, sizes and which kinds are scalar: the one joint table (rbody.layout.JOINTS), as numba constants.
HINGE, SLIDE, BALL, FREE, ROLL = (JOINTS[k].code for k in ("hinge", "slide", "ball", "free", "roll"))
KIND_CODE = {kind.name: kind.code for kind in JOINTS.values()}
NQ = {kind.code: kind.nq for kind in JOINTS.values()}
NV = {kind.code: kind.nv for kind in JOINTS.values()}
SCALAR_KINDS = tuple(kind.code for kind in JOINTS.values() if kind.scalar)  # one coordinate, displacement q - ref

# The params row (rbody.engine.schema): a header, then one record per body, joint and degree of freedom.
TREE_HEADER = Record("tree header", [
    ("bodies", 1, INT, "number of bodies nb"),
    ("joints", 1, INT, "number of joints nj"),
    ("dofs", 1, INT, "degrees of freedom nv"),
    ("nq", 1, INT, "position coordinates nq"),
    ("rotations", 1, INT, "ball and free joints (rotation vectors phi in the state)"),
    ("gravity", 1, FLOAT, "g [m/s^2], along -z"),
    ("body", 1, INT, "where the body records start"),
    ("joint", 1, INT, "where the joint records start"),
    ("dof", 1, INT, "where the degree-of-freedom records start"),
])
H_BODIES, H_JOINTS, H_DOFS, H_NQ, H_ROT, H_GRAVITY, H_BODY, H_JOINT, H_DOF = TREE_HEADER.offsets()
HEADER = TREE_HEADER.size
BODY = Record("body", [
    ("parent", 1, INT, "parent body (-1: the world)"),
    ("pos", 3, FLOAT, "placement in the parent's frame [m]"),
    ("quat", 4, FLOAT, "orientation in the parent's frame (w, x, y, z)"),
    ("mass", 1, FLOAT, "[kg]"),
    ("com", 3, FLOAT, "centre of mass, body frame [m]"),
    ("tensor", 9, FLOAT, "inertia tensor about the centre of mass, body axes [kg m^2]"),
    ("dof0", 1, INT, "first degree of freedom"),
    ("ndof", 1, INT, "degrees of freedom of its joints"),
    ("jnt0", 1, INT, "first joint"),
    ("njnt", 1, INT, "joints"),
])
B_PARENT, B_POS, B_QUAT, B_MASS, B_COM, B_TENSOR, B_DOF0, B_NDOF, B_JNT0, B_NJNT = BODY.offsets()
BODY_SIZE = BODY.size
JOINT = Record("joint", [
    ("kind", 1, INT, "joint code (rbody.layout.JOINTS)"),
    ("body", 1, INT, "the body it moves"),
    ("axis", 3, FLOAT, "unit axis, body frame (hinge, slide, roll)"),
    ("anchor", 3, FLOAT, "anchor, body frame [m]"),
    ("qadr", 1, INT, "qpos address"),
    ("dadr", 1, INT, "qvel address"),
    ("ref", 1, FLOAT, "reference coordinate [rad | m]"),
    ("stiffness", 1, FLOAT, "spring stiffness [N m/rad | N/m]"),
    ("springref", 1, FLOAT, "spring rest coordinate [rad | m]"),
    ("rotation", 1, INT, "slot of its rotation vector phi among ball and free joints (-1: none)"),
    ("radius", 1, FLOAT, "rolling radius a of a roll joint [m] (0 for the others)"),
    ("line", 3, FLOAT, "rolling line l = axis x normal of a roll joint, body frame"),
])
(J_KIND, J_BODY, J_AXIS, J_ANCHOR, J_QADR, J_DADR, J_REF, J_STIFF, J_SPRINGREF, J_ROT, J_RADIUS,
 J_LINE) = JOINT.offsets()
JOINT_SIZE = JOINT.size
DOF = Record("degree of freedom", [
    ("joint", 1, INT, "its joint"),
    ("index", 1, INT, "index within the joint"),
    ("group", 1, INT, "1: starts a group (the velocity its bias uses is the body's velocity so far); 0: as the "
                      "dof before"),
    ("damping", 1, FLOAT, "viscous damping [N m s/rad | N s/m]"),
    ("armature", 1, FLOAT, "armature inertia added to M's diagonal [kg m^2 | kg]"),
    ("parent", 1, INT, "parent degree of freedom (-1: none)"),
])
D_JOINT, D_INDEX, D_GROUP, D_DAMPING, D_ARMATURE, D_PARENT = DOF.offsets()
DOF_SIZE = DOF.size

# The 3-D algorithms let LLVM fuse a product and a sum into one rounding (fused multiply-add): fewer
# instructions and a shorter chain of dependent ones, and results at least as accurate.
FMA = {"contract"}

PIVOT_RTOL = 1e-12  # a pivot D of the ABA below this fraction of its scale leaves M singular
NEARLY_SINGULAR = 1e-6  # a pivot below this fraction of its value at the start: the mass matrix is (nearly) singular
PATH_SAMPLES = 97       # states sampled on the failing step's path, up to 1.5 dt from its start


# ----- the model row --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TreeArrays:
    """The model in numpy, before packing: bodies in MuJoCo order, joints, degrees of freedom."""

    names: tuple[str, ...]          # bodies, MuJoCo order
    joint_names: tuple[str, ...]    # joints, MuJoCo order
    joint_kinds: tuple[str, ...]
    row: np.ndarray                 # (p,) the params row
    nq: int
    nv: int
    nrot: int
    qposadr: np.ndarray             # (joints,)
    dofadr: np.ndarray              # (joints,)
    dof_body: np.ndarray            # (nv,) body index of every degree of freedom
    dof_joint: np.ndarray           # (nv,)


def body_offset(p, i):
    return int(p[H_BODY]) + i * BODY_SIZE


# ----- the state of one evaluation ------------------------------------------------------------------------

STACK_FLOATS = 16384  # workspaces up to this size (128 kB, ~570 bodies) live on the stack of an evaluation
SCRATCH = 32  # floats of small temporaries (quaternions, 3- and 6-vectors) at the end of the workspace


# The arrays of one evaluation (_views): per body xpos (nb, 3) relative to its tree's origin xorigin (nb, 3), xquat
# (nb, 4), xmat (nb, 3, 3), spatial velocity vel, articulated bias force pA, acceleration acc, force (nb, 6),
# inertia about the origin h (nb, 3), Ibar (nb, 3, 3), articulated inertia IA (nb, 6, 6; its upper triangle),
# mass (nb,); per joint xaxis, xanchor, xline (nj, 3), half (2, nj): cos and sin of half the angle q - ref of
# each hinge and roll joint (0 for the others); per dof S, bias, U (nv, 6), u (nv,), tau, pivots, zero (nv,);
# q (nq,); scratch (SCRATCH,). After the articulated-body algorithm IA and pA hold Featherstone's I^A and
# p^A of each body (its subtree's, before its own joints are eliminated).
Workspace = namedtuple("Workspace", ["xpos", "xquat", "xmat", "xaxis", "xanchor", "xline", "S", "bias", "vel", "h",
                                     "Ibar", "IA", "pA", "U", "u", "acc", "force", "mass", "q", "tau", "pivots",
                                     "zero", "scratch", "xorigin", "half"])
# Where each of those arrays starts in the workspace (a float index): _offsets, read by _views and by the
# algorithms, which index the workspace directly (w[o.xpos + 3 * i + a] is xpos[i, a]).
Offsets = namedtuple("Offsets", ["S", "bias", "U", "vel", "pA", "acc", "force", "xpos", "h", "xorigin", "xaxis",
                                 "xanchor", "xline", "xmat", "Ibar", "IA", "xquat", "u", "mass", "q", "tau", "pivots",
                                 "zero", "scratch", "half"])


# Floats of the workspace per body, joint and degree of freedom: _views cuts exactly these (a test checks it).
BODY_FLOATS = 4 * 6 + 3 * 3 + 2 * 9 + 36 + 4 + 1  # vel pA acc force; xpos h xorigin; xmat Ibar; IA; xquat; mass
JOINT_FLOATS = 3 * 3 + 2                            # xaxis xanchor xline; half
DOF_FLOATS = 3 * 6 + 4                              # S bias U; u tau pivots zero


@njit(cache=True)
def workspace_size(p) -> int:
    """Floats of the workspace of one evaluation (see _views)."""
    nb, nj, nv, nq = int(p[H_BODIES]), int(p[H_JOINTS]), int(p[H_DOFS]), int(p[H_NQ])
    return BODY_FLOATS * nb + JOINT_FLOATS * nj + DOF_FLOATS * nv + nq + SCRATCH


@njit(cache=True, inline="always")
def _offsets(p):
    """The start of every array of the workspace (Offsets), in the order _views cuts them."""
    nb, nj, nv, nq = int(p[H_BODIES]), int(p[H_JOINTS]), int(p[H_DOFS]), int(p[H_NQ])
    at = 18 * nv
    S, bias, U = 0, 6 * nv, 12 * nv
    vel, pA, acc, force = at, at + 6 * nb, at + 12 * nb, at + 18 * nb
    at += 24 * nb
    xpos, h, xorigin = at, at + 3 * nb, at + 6 * nb
    at += 9 * nb
    xaxis, xanchor, xline, half = at, at + 3 * nj, at + 6 * nj, at + 9 * nj
    at += 11 * nj
    xmat, Ibar = at, at + 9 * nb
    at += 18 * nb
    IA = at
    at += 36 * nb
    xquat = at
    at += 4 * nb
    u, mass = at, at + nv
    at += nv + nb
    return Offsets(S, bias, U, vel, pA, acc, force, xpos, h, xorigin, xaxis, xanchor, xline, xmat, Ibar, IA, xquat, u,
                   mass, at, at + nq, at + nq + nv, at + nq + 2 * nv, at + nq + 3 * nv, half)


@njit(cache=True, inline="always")
def _rows(w, at, rows, columns):
    """(rows, columns) array over w[at:at + rows * columns]."""
    return carray(address(w, at), (rows, columns))


@njit(cache=True)
def _views(p, w):
    """The arrays of one evaluation, cut from one workspace w (workspace_size(p),) as arrays over its memory
    (numba carrays: no reshape, no reference count; the caller keeps w alive)."""
    nb, nj, nv, nq = int(p[H_BODIES]), int(p[H_JOINTS]), int(p[H_DOFS]), int(p[H_NQ])
    o = _offsets(p)
    return Workspace(_rows(w, o.xpos, nb, 3), _rows(w, o.xquat, nb, 4), carray(address(w, o.xmat), (nb, 3, 3)),
                     _rows(w, o.xaxis, nj, 3), _rows(w, o.xanchor, nj, 3), _rows(w, o.xline, nj, 3),
                     _rows(w, o.S, nv, 6), _rows(w, o.bias, nv, 6), _rows(w, o.vel, nb, 6), _rows(w, o.h, nb, 3),
                     carray(address(w, o.Ibar), (nb, 3, 3)), carray(address(w, o.IA), (nb, 6, 6)),
                     _rows(w, o.pA, nb, 6), _rows(w, o.U, nv, 6), carray(address(w, o.u), nv),
                     _rows(w, o.acc, nb, 6), _rows(w, o.force, nb, 6), carray(address(w, o.mass), nb),
                     carray(address(w, o.q), nq), carray(address(w, o.tau), nv), carray(address(w, o.pivots), nv),
                     carray(address(w, o.zero), nv), carray(address(w, o.scratch), SCRATCH),
                     _rows(w, o.xorigin, nb, 3), _rows(w, o.half, 2, nj))


# ----- one body at a time: the outward pass's steps -------------------------------------------------------
# Each step reads and writes the workspace by index (Offsets), its small vectors held in local variables; the
# algorithms below run them body after body in one loop (one pass over the tree's memory), and kinematics,
# motion_subspaces, velocities and world_inertias each run one of them over all bodies.

@njit(cache=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    """a (x) b for quaternions given by their components (w, x, y, z)."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True, inline="always")
def _qrot(q0, q1, q2, q3, v0, v1, v2):
    """R(q) v: v + 2 w (u x v) + 2 u x (u x v), u = (q1, q2, q3)."""
    t0 = 2.0 * (q2 * v2 - q3 * v1)
    t1 = 2.0 * (q3 * v0 - q1 * v2)
    t2 = 2.0 * (q1 * v1 - q2 * v0)
    return v0 + q0 * t0 + q2 * t2 - q3 * t1, v1 + q0 * t1 + q3 * t0 - q1 * t2, v2 + q0 * t2 + q1 * t1 - q2 * t0


@njit(cache=True, inline="always")
def _half_angles(p, q, qo, w, o):
    """half (2, nj): cos and sin of (q - ref) / 2 of every hinge and roll joint, 1 and 0 for the others: first the
    angles, then their cosines and sines in a loop without a call, which LLVM vectorises (rbody.engine.spatial.sin_cos;
    np.sin and np.cos when an angle is beyond its range)."""
    nj, jo = int(p[H_JOINTS]), int(p[H_JOINT])
    c, s = o.half, o.half + nj
    largest = number(w, 0.0)
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        kind = int(p[r + J_KIND])
        x = 0.5 * (q[qo + int(p[r + J_QADR])] - p[r + J_REF]) if kind == HINGE or kind == ROLL else number(w, 0.0)
        w[s + j] = x
        largest = maximum_of(largest, abs(x))
    _sines_and_cosines(w, s, c, nj, largest)


@njit(cache=True, fastmath=FMA)
def _free_pose(p, q, qo, w, o, i, j):
    """Body i moved by its free joint j (_pose): its origin and axes, the joint's axis and anchor; returns the body's
    quaternion (w, x, y, z) made unit."""
    r = int(p[H_JOINT]) + j * JOINT_SIZE
    qa = qo + int(p[r + J_QADR])
    xp, xo = o.xpos + 3 * i, o.xorigin + 3 * i
    for a in range(3):  # a free joint's body is a child of the world: the origin of its own tree
        w[xo + a] = q[qa + a]
        w[xp + a] = 0.0
        w[o.xanchor + 3 * j + a] = 0.0
        w[o.xaxis + 3 * j + a] = p[r + J_AXIS + a]
    q0, q1, q2, q3 = q[qa + 3], q[qa + 4], q[qa + 5], q[qa + 6]
    norm = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return q0 / norm, q1 / norm, q2 / norm, q3 / norm


@njit(cache=True, fastmath=FMA)
def _other_joint(p, q, qo, w, o, j, x0, x1, x2, q0, q1, q2, q3):
    """A slide, roll or ball joint j of a body whose frame is at x (relative to its tree's origin) with quaternion q
    so far (_pose): the joint's axis, anchor and rolling line into the workspace; returns the body's (x, q) after
    the joint. A separate function: the pose of hinges, the common joint, is written out where it is used."""
    r = int(p[H_JOINT]) + j * JOINT_SIZE
    kind = int(p[r + J_KIND])
    n0, n1, n2 = p[r + J_ANCHOR], p[r + J_ANCHOR + 1], p[r + J_ANCHOR + 2]
    a0, a1, a2 = _qrot(q0, q1, q2, q3, p[r + J_AXIS], p[r + J_AXIS + 1], p[r + J_AXIS + 2])
    ja, jx = o.xaxis + 3 * j, o.xanchor + 3 * j
    w[ja], w[ja + 1], w[ja + 2] = a0, a1, a2
    c0, c1, c2 = _qrot(q0, q1, q2, q3, n0, n1, n2)
    c0, c1, c2 = c0 + x0, c1 + x1, c2 + x2
    qa = qo + int(p[r + J_QADR])
    if kind == SLIDE:
        w[jx], w[jx + 1], w[jx + 2] = c0, c1, c2
        d = q[qa] - p[r + J_REF]
        return x0 + a0 * d, x1 + a1 * d, x2 + a2 * d, q0, q1, q2, q3
    if kind == ROLL:  # first slide by a (q - ref) along l (anchor and body together), then turn
        l0, l1, l2 = _qrot(q0, q1, q2, q3, p[r + J_LINE], p[r + J_LINE + 1], p[r + J_LINE + 2])
        jl = o.xline + 3 * j
        w[jl], w[jl + 1], w[jl + 2] = l0, l1, l2
        d = p[r + J_RADIUS] * (q[qa] - p[r + J_REF])
        c0, c1, c2 = c0 + l0 * d, c1 + l1 * d, c2 + l2 * d
        sine = w[o.half + int(p[H_JOINTS]) + j]
        t0, t1, t2, t3 = w[o.half + j], sine * p[r + J_AXIS], sine * p[r + J_AXIS + 1], sine * p[r + J_AXIS + 2]
    else:  # ball
        t0, t1, t2, t3 = q[qa], q[qa + 1], q[qa + 2], q[qa + 3]
        norm = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2 + t3 * t3)
        t0, t1, t2, t3 = t0 / norm, t1 / norm, t2 / norm, t3 / norm
    w[jx], w[jx + 1], w[jx + 2] = c0, c1, c2
    q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, t0, t1, t2, t3)  # turn about the anchor
    n0, n1, n2 = _qrot(q0, q1, q2, q3, n0, n1, n2)
    return c0 - n0, c1 - n1, c2 - n2, q0, q1, q2, q3


@njit(cache=True, inline="always")
def _pose(p, q, qo, w, o, i):
    """Body i's pose, as MuJoCo's mj_kinematics (kinematics() gives the meaning of each array), its parent's
    already placed: xorigin, xpos, xquat, xmat of the body; xaxis, xanchor, xline of its joints. q[qo + a] is
    qpos[a]."""
    b = int(p[H_BODY]) + i * BODY_SIZE
    jo, nj_all = int(p[H_JOINT]), int(p[H_JOINTS])
    parent = int(p[b + B_PARENT])
    j0, nj = int(p[b + B_JNT0]), int(p[b + B_NJNT])
    xp, xo = o.xpos + 3 * i, o.xorigin + 3 * i
    if nj == 1 and int(p[jo + j0 * JOINT_SIZE + J_KIND]) == FREE:
        q0, q1, q2, q3 = _free_pose(p, q, qo, w, o, i, j0)
    else:
        if parent >= 0:
            pp, pq, pm = o.xpos + 3 * parent, o.xquat + 4 * parent, o.xmat + 9 * parent
            l0, l1, l2 = p[b + B_POS], p[b + B_POS + 1], p[b + B_POS + 2]
            for a in range(3):
                w[xo + a] = w[o.xorigin + 3 * parent + a]
            x0 = w[pp] + (w[pm] * l0 + w[pm + 1] * l1 + w[pm + 2] * l2)
            x1 = w[pp + 1] + (w[pm + 3] * l0 + w[pm + 4] * l1 + w[pm + 5] * l2)
            x2 = w[pp + 2] + (w[pm + 6] * l0 + w[pm + 7] * l1 + w[pm + 8] * l2)
            q0, q1, q2, q3 = w[pq], w[pq + 1], w[pq + 2], w[pq + 3]
            if not (p[b + B_QUAT] == 1.0 and p[b + B_QUAT + 1] == 0.0 and p[b + B_QUAT + 2] == 0.0
                    and p[b + B_QUAT + 3] == 0.0):  # else the common case: the body's axes are its parent's
                q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, p[b + B_QUAT], p[b + B_QUAT + 1], p[b + B_QUAT + 2],
                                       p[b + B_QUAT + 3])
        else:  # a child of the world: the origin of its own tree
            for a in range(3):
                w[xo + a] = p[b + B_POS + a]
            x0 = x1 = x2 = number(w, 0.0)
            q0, q1 = number(w, p[b + B_QUAT]), number(w, p[b + B_QUAT + 1])
            q2, q3 = number(w, p[b + B_QUAT + 2]), number(w, p[b + B_QUAT + 3])
        for j in range(j0, j0 + nj):
            r = jo + j * JOINT_SIZE
            if int(p[r + J_KIND]) != HINGE:
                x0, x1, x2, q0, q1, q2, q3 = _other_joint(p, q, qo, w, o, j, x0, x1, x2, q0, q1, q2, q3)
                continue
            # a hinge: turn about the anchor, by the cosine and sine of half its angle (_half_angles)
            e0, e1, e2 = p[r + J_AXIS], p[r + J_AXIS + 1], p[r + J_AXIS + 2]
            n0, n1, n2 = p[r + J_ANCHOR], p[r + J_ANCHOR + 1], p[r + J_ANCHOR + 2]
            at_origin = n0 == 0.0 and n1 == 0.0 and n2 == 0.0  # the common case
            a0, a1, a2 = _qrot(q0, q1, q2, q3, e0, e1, e2)
            ja, jx = o.xaxis + 3 * j, o.xanchor + 3 * j
            w[ja], w[ja + 1], w[ja + 2] = a0, a1, a2
            if at_origin:
                c0, c1, c2 = x0, x1, x2
            else:
                c0, c1, c2 = _qrot(q0, q1, q2, q3, n0, n1, n2)
                c0, c1, c2 = c0 + x0, c1 + x1, c2 + x2
            w[jx], w[jx + 1], w[jx + 2] = c0, c1, c2
            sine = w[o.half + nj_all + j]
            q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, w[o.half + j], sine * e0, sine * e1, sine * e2)
            if at_origin:  # the body frame's origin is the anchor
                x0, x1, x2 = c0, c1, c2
            else:
                n0, n1, n2 = _qrot(q0, q1, q2, q3, n0, n1, n2)
                x0, x1, x2 = c0 - n0, c1 - n1, c2 - n2
        # a product of unit quaternions is unit to round-off, |q|^2 = 1 + e: one Newton step for 1/|q|,
        # (3 - |q|^2) / 2 = 1 - e/2, leaves an error of order e^2 (no square root, no division)
        scale = 1.5 - 0.5 * (q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 * scale, q1 * scale, q2 * scale, q3 * scale
        w[xp], w[xp + 1], w[xp + 2] = x0, x1, x2
    xq, xm = o.xquat + 4 * i, o.xmat + 9 * i
    w[xq], w[xq + 1], w[xq + 2], w[xq + 3] = q0, q1, q2, q3
    w[xm] = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
    w[xm + 1] = 2.0 * (q1 * q2 - q0 * q3)
    w[xm + 2] = 2.0 * (q1 * q3 + q0 * q2)
    w[xm + 3] = 2.0 * (q1 * q2 + q0 * q3)
    w[xm + 4] = 1.0 - 2.0 * (q1 * q1 + q3 * q3)
    w[xm + 5] = 2.0 * (q2 * q3 - q0 * q1)
    w[xm + 6] = 2.0 * (q1 * q3 - q0 * q2)
    w[xm + 7] = 2.0 * (q2 * q3 + q0 * q1)
    w[xm + 8] = 1.0 - 2.0 * (q1 * q1 + q2 * q2)


@njit(cache=True, fastmath=FMA)
def _other_subspace(p, w, o, i, d):
    """S of degree of freedom d of body i when its joint is not a hinge (_subspaces)."""
    j = int(p[int(p[H_DOF]) + d * DOF_SIZE + D_JOINT])
    k = int(p[int(p[H_DOF]) + d * DOF_SIZE + D_INDEX])
    r = int(p[H_JOINT]) + j * JOINT_SIZE
    kind = int(p[r + J_KIND])
    s = o.S + 6 * d
    if kind == SLIDE:
        w[s], w[s + 1], w[s + 2] = 0.0, 0.0, 0.0
        w[s + 3], w[s + 4], w[s + 5] = w[o.xaxis + 3 * j], w[o.xaxis + 3 * j + 1], w[o.xaxis + 3 * j + 2]
        return
    if kind == FREE and k < 3:
        for a in range(6):
            w[s + a] = 0.0
        w[s + 3 + k] = 1.0
        return
    if kind == ROLL:
        a0, a1, a2 = w[o.xaxis + 3 * j], w[o.xaxis + 3 * j + 1], w[o.xaxis + 3 * j + 2]
    else:  # a rotation of a ball or free joint: about the body's own axis k
        c = k if kind == BALL else k - 3
        xm = o.xmat + 9 * i
        a0, a1, a2 = w[xm + c], w[xm + 3 + c], w[xm + 6 + c]
    x0, x1, x2 = w[o.xanchor + 3 * j], w[o.xanchor + 3 * j + 1], w[o.xanchor + 3 * j + 2]
    w[s], w[s + 1], w[s + 2] = a0, a1, a2
    w[s + 3] = x1 * a2 - x2 * a1
    w[s + 4] = x2 * a0 - x0 * a2
    w[s + 5] = x0 * a1 - x1 * a0
    if kind == ROLL:
        radius = p[r + J_RADIUS]
        for a in range(3):
            w[s + 3 + a] += radius * w[o.xline + 3 * j + a]


@njit(cache=True, inline="always")
def _subspaces(p, w, o, i):
    """S of body i's degrees of freedom (motion_subspaces gives the meaning), after its pose."""
    b = int(p[H_BODY]) + i * BODY_SIZE
    jo, do = int(p[H_JOINT]), int(p[H_DOF])
    d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
    for d in range(d0, d0 + nd):
        j = int(p[do + d * DOF_SIZE + D_JOINT])
        if int(p[jo + j * JOINT_SIZE + J_KIND]) != HINGE:
            _other_subspace(p, w, o, i, d)
            continue
        s, ja, jx = o.S + 6 * d, o.xaxis + 3 * j, o.xanchor + 3 * j  # a hinge: (a; x x a)
        a0, a1, a2 = w[ja], w[ja + 1], w[ja + 2]
        x0, x1, x2 = w[jx], w[jx + 1], w[jx + 2]
        w[s], w[s + 1], w[s + 2] = a0, a1, a2
        w[s + 3] = x1 * a2 - x2 * a1
        w[s + 4] = x2 * a0 - x0 * a2
        w[s + 5] = x0 * a1 - x1 * a0


@njit(cache=True, fastmath=FMA)
def _roll_bias(p, w, o, d, qd):
    """The velocity product of a roll joint's degree of freedom d gains radius qd^2 (0; l x axis) (velocities)."""
    j = int(p[int(p[H_DOF]) + d * DOF_SIZE + D_JOINT])
    scale = p[int(p[H_JOINT]) + j * JOINT_SIZE + J_RADIUS] * qd * qd
    l0, l1, l2 = w[o.xline + 3 * j], w[o.xline + 3 * j + 1], w[o.xline + 3 * j + 2]
    a0, a1, a2 = w[o.xaxis + 3 * j], w[o.xaxis + 3 * j + 1], w[o.xaxis + 3 * j + 2]
    c = o.bias + 6 * d
    w[c + 3] += scale * (l1 * a2 - l2 * a1)
    w[c + 4] += scale * (l2 * a0 - l0 * a2)
    w[c + 5] += scale * (l0 * a1 - l1 * a0)


@njit(cache=True, inline="always")
def _motion(p, v, vo, w, o, i):
    """vel of body i and the velocity products (bias) of its degrees of freedom (velocities gives the meaning),
    after its motion subspaces and its parent's velocity; v[vo + d] is qvel[d]."""
    b = int(p[H_BODY]) + i * BODY_SIZE
    jo, do = int(p[H_JOINT]), int(p[H_DOF])
    parent = int(p[b + B_PARENT])
    if parent >= 0:
        pv = o.vel + 6 * parent
        w0, w1, w2, v0, v1, v2 = w[pv], w[pv + 1], w[pv + 2], w[pv + 3], w[pv + 4], w[pv + 5]
    else:
        w0 = w1 = w2 = v0 = v1 = v2 = number(w, 0.0)
    b0, b1, b2, b3, b4, b5 = w0, w1, w2, v0, v1, v2
    d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
    for d in range(d0, d0 + nd):
        if p[do + d * DOF_SIZE + D_GROUP] != 0.0:  # the velocity before this joint (or group of rotations)
            b0, b1, b2, b3, b4, b5 = w0, w1, w2, v0, v1, v2
        s = o.S + 6 * d
        s0, s1, s2, s3, s4, s5 = w[s], w[s + 1], w[s + 2], w[s + 3], w[s + 4], w[s + 5]
        qd = v[vo + d]
        c = o.bias + 6 * d  # (base x S) qd
        w[c] = (b1 * s2 - b2 * s1) * qd
        w[c + 1] = (b2 * s0 - b0 * s2) * qd
        w[c + 2] = (b0 * s1 - b1 * s0) * qd
        w[c + 3] = (b1 * s5 - b2 * s4 + b4 * s2 - b5 * s1) * qd
        w[c + 4] = (b2 * s3 - b0 * s5 + b5 * s0 - b3 * s2) * qd
        w[c + 5] = (b0 * s4 - b1 * s3 + b3 * s1 - b4 * s0) * qd
        if int(p[jo + int(p[do + d * DOF_SIZE + D_JOINT]) * JOINT_SIZE + J_KIND]) == ROLL:
            _roll_bias(p, w, o, d, qd)
        w0, w1, w2 = w0 + s0 * qd, w1 + s1 * qd, w2 + s2 * qd
        v0, v1, v2 = v0 + s3 * qd, v1 + s4 * qd, v2 + s5 * qd
    e = o.vel + 6 * i
    w[e], w[e + 1], w[e + 2], w[e + 3], w[e + 4], w[e + 5] = w0, w1, w2, v0, v1, v2


@njit(cache=True, inline="always")
def _inertia(p, w, o, i):
    """h and Ibar of body i (world_inertias gives the meaning), after its pose; returns them as numbers too:
    (mass, h0, h1, h2, I00, I01, I02, I11, I12, I22)."""
    b = int(p[H_BODY]) + i * BODY_SIZE
    m = p[b + B_MASS]
    xm, xp = o.xmat + 9 * i, o.xpos + 3 * i
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = (w[xm], w[xm + 1], w[xm + 2], w[xm + 3], w[xm + 4], w[xm + 5],
                                                   w[xm + 6], w[xm + 7], w[xm + 8])
    k0, k1, k2 = p[b + B_COM], p[b + B_COM + 1], p[b + B_COM + 2]
    c0 = (R00 * k0 + R01 * k1 + R02 * k2) + w[xp]
    c1 = (R10 * k0 + R11 * k1 + R12 * k2) + w[xp + 1]
    c2 = (R20 * k0 + R21 * k1 + R22 * k2) + w[xp + 2]
    t = b + B_TENSOR
    C00, C01, C02, C11, C12, C22 = p[t], p[t + 1], p[t + 2], p[t + 4], p[t + 5], p[t + 8]
    # R Ic R^T: first Ic R^T (columns: Ic times each row of R), then the rows of R against it
    m00 = C00 * R00 + C01 * R01 + C02 * R02
    m10 = C01 * R00 + C11 * R01 + C12 * R02
    m20 = C02 * R00 + C12 * R01 + C22 * R02
    m01 = C00 * R10 + C01 * R11 + C02 * R12
    m11 = C01 * R10 + C11 * R11 + C12 * R12
    m21 = C02 * R10 + C12 * R11 + C22 * R12
    m02 = C00 * R20 + C01 * R21 + C02 * R22
    m12 = C01 * R20 + C11 * R21 + C12 * R22
    m22 = C02 * R20 + C12 * R21 + C22 * R22
    mc0, mc1, mc2 = m * c0, m * c1, m * c2
    square = c0 * c0 + c1 * c1 + c2 * c2
    I00 = (R00 * m00 + R01 * m10 + R02 * m20) + (m * square - mc0 * c0)
    I01 = (R00 * m01 + R01 * m11 + R02 * m21) - mc0 * c1
    I02 = (R00 * m02 + R01 * m12 + R02 * m22) - mc0 * c2
    I11 = (R10 * m01 + R11 * m11 + R12 * m21) + (m * square - mc1 * c1)
    I12 = (R10 * m02 + R11 * m12 + R12 * m22) - mc1 * c2
    I22 = (R20 * m02 + R21 * m12 + R22 * m22) + (m * square - mc2 * c2)
    h, ib = o.h + 3 * i, o.Ibar + 9 * i
    w[h], w[h + 1], w[h + 2] = mc0, mc1, mc2
    w[ib], w[ib + 1], w[ib + 2] = I00, I01, I02
    w[ib + 3], w[ib + 4], w[ib + 5] = I01, I11, I12
    w[ib + 6], w[ib + 7], w[ib + 8] = I02, I12, I22
    return m, mc0, mc1, mc2, I00, I01, I02, I11, I12, I22


@njit(cache=True, inline="always")
def _articulated_start(w, o, i, m, h0, h1, h2, I00, I01, I02, I11, I12, I22):
    """The articulated-body algorithm's start at body i: IA = its rigid inertia (upper triangle, the matrix
    [[Ibar, [h]x], [[h]x^T, m 1]]) and pA = v x* (I v), after its velocity."""
    e = o.vel + 6 * i
    w0, w1, w2, v0, v1, v2 = w[e], w[e + 1], w[e + 2], w[e + 3], w[e + 4], w[e + 5]
    n0 = (I00 * w0 + I01 * w1 + I02 * w2) + (h1 * v2 - h2 * v1)
    n1 = (I01 * w0 + I11 * w1 + I12 * w2) + (h2 * v0 - h0 * v2)
    n2 = (I02 * w0 + I12 * w1 + I22 * w2) + (h0 * v1 - h1 * v0)
    f0 = m * v0 - (h1 * w2 - h2 * w1)
    f1 = m * v1 - (h2 * w0 - h0 * w2)
    f2 = m * v2 - (h0 * w1 - h1 * w0)
    pa = o.pA + 6 * i
    w[pa] = (w1 * n2 - w2 * n1) + (v1 * f2 - v2 * f1)
    w[pa + 1] = (w2 * n0 - w0 * n2) + (v2 * f0 - v0 * f2)
    w[pa + 2] = (w0 * n1 - w1 * n0) + (v0 * f1 - v1 * f0)
    w[pa + 3] = w1 * f2 - w2 * f1
    w[pa + 4] = w2 * f0 - w0 * f2
    w[pa + 5] = w0 * f1 - w1 * f0
    a = o.IA + 36 * i
    w[a], w[a + 1], w[a + 2], w[a + 3], w[a + 4], w[a + 5] = I00, I01, I02, 0.0, -h2, h1
    w[a + 7], w[a + 8], w[a + 9], w[a + 10], w[a + 11] = I11, I12, h2, 0.0, -h0
    w[a + 14], w[a + 15], w[a + 16], w[a + 17] = I22, -h1, h0, 0.0
    w[a + 21], w[a + 22], w[a + 23] = m, 0.0, 0.0
    w[a + 28], w[a + 29] = m, 0.0
    w[a + 35] = m


# ----- the outward pass as separate algorithms --------------------------------------------------------------

@njit(cache=True, fastmath=FMA)
def kinematics(p, q, w):
    """World poses of every body from qpos q (nq,), as MuJoCo's mj_kinematics, into the workspace w (_views):
    xpos (nb, 3) body-frame origins [m] relative to the origin of their tree, xorigin (nb, 3) that origin (the
    world placement of the tree's root body, or its free joint's position), xquat (nb, 4), xmat (nb, 3, 3); per
    joint its world axis and anchor (nj, 3) [m] relative to the tree's origin (a roll joint's anchor after its
    slide) and a roll joint's world rolling line l (nj, 3).

    Positions relative to each tree's own origin: the spatial algebra of a tree is written about that point
    (module docstring, "Precision"), so a tree a million metres from the world origin computes as it would at it."""
    o = _offsets(p)
    pp, qq, ww = address(p, 0), address(q, 0), address(w, 0)
    _half_angles(pp, qq, 0, ww, o)
    for i in range(int(p[H_BODIES])):
        _pose(pp, qq, 0, ww, o, i)


@njit(cache=True, fastmath=FMA)
def motion_subspaces(p, w):
    """S (nv, 6): each degree of freedom's unit motion (omega; v at the origin of its tree), world axes, as
    MuJoCo's cdof. Hinge (a; x x a) about its anchor x; slide (0; a); roll (a; x x a) + radius (0; l) (the
    hinge about the anchor after the slide, plus the slide); ball and free rotations about the body's own
    axes (columns of xmat) through the anchor; free translations along the world axes. After kinematics."""
    o = _offsets(p)
    pp, ww = address(p, 0), address(w, 0)
    for i in range(int(p[H_BODIES])):
        _subspaces(pp, ww, o, i)


@njit(cache=True, fastmath=FMA)
def velocities(p, v, w):
    """vel (nb, 6): each body's spatial velocity (world axes, about the origin of its tree); bias (nv, 6): each
    degree of freedom's velocity-product acceleration S' v_d = (v_before x S) v_d (MuJoCo's cdof_dot qvel),
    v_before the body's velocity before the joint (ball and free rotations: before the whole group). A roll
    joint's hinge part moves with its slide part: + radius v_d^2 (0; l x axis) (= (radius v_d (0; l)) x
    (axis; x x axis)). After motion_subspaces."""
    o = _offsets(p)
    pp, vv, ww = address(p, 0), address(v, 0), address(w, 0)
    for i in range(int(p[H_BODIES])):
        _motion(pp, vv, 0, ww, o, i)


@njit(cache=True, fastmath=FMA)
def world_inertias(p, w):
    """Each body's inertia about the origin of its tree, world axes: h (nb, 3) = m c, Ibar (nb, 3, 3). After
    kinematics."""
    o = _offsets(p)
    pp, ww = address(p, 0), address(w, 0)
    for i in range(int(p[H_BODIES])):
        _inertia(pp, ww, o, i)


@njit(cache=True, fastmath=FMA)
def passive(p, q, v, out):
    """out (nv,) = MuJoCo's qfrc_passive: -stiffness (q - springref) per hinge and slide, -damping v per dof."""
    _passive(address(p, 0), address(q, 0), 0, address(v, 0), 0, address(out, 0), 0)


@njit(cache=True, inline="always")
def _passive(p, q, qo, v, vo, out, to):
    """out[to + d] = qfrc_passive[d] (passive), q[qo + a] = qpos[a], v[vo + d] = qvel[d]."""
    nj, nv = int(p[H_JOINTS]), int(p[H_DOFS])
    jo, do = int(p[H_JOINT]), int(p[H_DOF])
    for d in range(nv):
        out[to + d] = -p[do + d * DOF_SIZE + D_DAMPING] * v[vo + d]
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        stiffness = p[r + J_STIFF]
        if stiffness != 0.0:
            out[to + int(p[r + J_DADR])] -= stiffness * (q[qo + int(p[r + J_QADR])] - p[r + J_SPRINGREF])


# An offset of 0 typed as a plain integer: a literal 0 argument would compile _outward and _sweeps a second
# time, for Literal[int](0).
AT_START = np.int64(0)


@njit(cache=True, fastmath=FMA)
def _outward(p, q, qo, v, vo, w, o):
    """The outward pass of one state, body after body: kinematics, motion subspaces, velocities, world inertias
    and the start of the articulated-body algorithm (IA, pA) into the workspace."""
    _half_angles(p, q, qo, w, o)
    for i in range(int(p[H_BODIES])):
        _pose(p, q, qo, w, o, i)
        _subspaces(p, w, o, i)
        _motion(p, v, vo, w, o, i)
        m, h0, h1, h2, I00, I01, I02, I11, I12, I22 = _inertia(p, w, o, i)
        _articulated_start(w, o, i, m, h0, h1, h2, I00, I01, I02, I11, I12, I22)


@njit(cache=True, fastmath=FMA)
def _frames(p, q, v, w):
    """Kinematics, motion subspaces, velocities and world inertias of one state, into the workspace w, with the
    articulated-body algorithm's start (IA, pA)."""
    _outward(address(p, 0), address(q, 0), AT_START, address(v, 0), AT_START, address(w, 0), _offsets(p))


# ----- the articulated-body algorithm ---------------------------------------------------------------------

@njit(cache=True, fastmath=FMA, error_model="numpy")  # 1 / D without a zero check: D is checked, set to inf when bad
def _sweeps(p, w, o, qacc, ao):
    """The articulated-body algorithm's inward and outward sweeps (Featherstone, RBDA, table 7.1) from the
    outward pass's S, bias, IA, pA and the generalised forces tau: qacc[ao + d] for each dof; into the workspace
    IA and pA of each body (I^A, p^A: its subtree's, before its own joints are eliminated), pivots D, U, u and
    acc. Returns the first dof whose pivot is not positive beyond PIVOT_RTOL of its scale, or -1 (a float; with
    lanes, rbody.engine.simd.LanePointer, one per lane); its qacc is NaN.

    The inward sweep is a chain of dependent steps from the leaves to the root: eliminating a degree of freedom
    needs its pivot D = S . Ia S, hence the articulated inertia Ia left by the previous elimination, Ia - U U^T / D,
    hence that elimination's division. Two things keep the chain short. Each elimination's rank-one update is
    left pending: the next one forms Ia S = A S - U (U . S) / D from the inertia A without it, which was ready one
    step earlier, and applies the update (to all 21 numbers) meanwhile. And a body's articulated inertia and
    bias force stay in local variables, handed in them to the next body when that is the parent (a body's first
    child, in the tree's depth-first order; every body of a chain); other parents gather theirs in the workspace.
    Every sum of six products is added as a balanced tree."""
    nb = int(p[H_BODIES])
    bo = int(p[H_BODY])
    do = int(p[H_DOF])
    # A (upper triangle a..), the bias force P, and the pending elimination (q = U, qinv = 1 / D) live across
    # bodies when one hands over to its parent (carry); numbers, or lanes (rbody.engine.simd.number)
    zero = number(w, 0.0)
    a00 = a01 = a02 = a03 = a04 = a05 = a11 = a12 = a13 = a14 = a15 = a22 = a23 = a24 = a25 = zero
    a33 = a34 = a35 = a44 = a45 = a55 = P0 = P1 = P2 = P3 = P4 = P5 = zero
    q0 = q1 = q2 = q3 = q4 = q5 = qinv = zero
    bad = number(w, -1.0)  # the first dof whose pivot is not positive, or -1
    carry = False
    pending = False
    for i in range(nb - 1, -1, -1):
        b = bo + i * BODY_SIZE
        d0 = int(p[b + B_DOF0])
        nd = int(p[b + B_NDOF])
        parent = int(p[b + B_PARENT])
        e = o.IA + 36 * i
        f = o.pA + 6 * i
        if carry:  # the child handed over: add the body's own (and its other children's) inertia and force
            a00 = a00 + w[e]
            a01 = a01 + w[e + 1]
            a02 = a02 + w[e + 2]
            a03 = a03 + w[e + 3]
            a04 = a04 + w[e + 4]
            a05 = a05 + w[e + 5]
            a11 = a11 + w[e + 7]
            a12 = a12 + w[e + 8]
            a13 = a13 + w[e + 9]
            a14 = a14 + w[e + 10]
            a15 = a15 + w[e + 11]
            a22 = a22 + w[e + 14]
            a23 = a23 + w[e + 15]
            a24 = a24 + w[e + 16]
            a25 = a25 + w[e + 17]
            a33 = a33 + w[e + 21]
            a34 = a34 + w[e + 22]
            a35 = a35 + w[e + 23]
            a44 = a44 + w[e + 28]
            a45 = a45 + w[e + 29]
            a55 = a55 + w[e + 35]
            P0 = P0 + w[f]
            P1 = P1 + w[f + 1]
            P2 = P2 + w[f + 2]
            P3 = P3 + w[f + 3]
            P4 = P4 + w[f + 4]
            P5 = P5 + w[f + 5]
        else:
            a00 = w[e]
            a01 = w[e + 1]
            a02 = w[e + 2]
            a03 = w[e + 3]
            a04 = w[e + 4]
            a05 = w[e + 5]
            a11 = w[e + 7]
            a12 = w[e + 8]
            a13 = w[e + 9]
            a14 = w[e + 10]
            a15 = w[e + 11]
            a22 = w[e + 14]
            a23 = w[e + 15]
            a24 = w[e + 16]
            a25 = w[e + 17]
            a33 = w[e + 21]
            a34 = w[e + 22]
            a35 = w[e + 23]
            a44 = w[e + 28]
            a45 = w[e + 29]
            a55 = w[e + 35]
            P0 = w[f]
            P1 = w[f + 1]
            P2 = w[f + 2]
            P3 = w[f + 3]
            P4 = w[f + 4]
            P5 = w[f + 5]
            pending = False
        w[f] = P0
        w[f + 1] = P1
        w[f + 2] = P2
        w[f + 3] = P3
        w[f + 4] = P4
        w[f + 5] = P5
        stored = False
        for d in range(d0 + nd - 1, d0 - 2, -1):
            s = o.S + 6 * d
            if d >= d0:  # Y = A S with A before the pending elimination
                s0 = w[s]
                s1 = w[s + 1]
                s2 = w[s + 2]
                s3 = w[s + 3]
                s4 = w[s + 4]
                s5 = w[s + 5]
                Y0 = ((a00 * s0 + a01 * s1) + (a02 * s2 + a03 * s3)) + (a04 * s4 + a05 * s5)
                Y1 = ((a01 * s0 + a11 * s1) + (a12 * s2 + a13 * s3)) + (a14 * s4 + a15 * s5)
                Y2 = ((a02 * s0 + a12 * s1) + (a22 * s2 + a23 * s3)) + (a24 * s4 + a25 * s5)
                Y3 = ((a03 * s0 + a13 * s1) + (a23 * s2 + a33 * s3)) + (a34 * s4 + a35 * s5)
                Y4 = ((a04 * s0 + a14 * s1) + (a24 * s2 + a34 * s3)) + (a44 * s4 + a45 * s5)
                Y5 = ((a05 * s0 + a15 * s1) + (a25 * s2 + a35 * s3)) + (a45 * s4 + a55 * s5)
                sU = ((s0 * Y0 + s1 * Y1) + (s2 * Y2 + s3 * Y3)) + (s4 * Y4 + s5 * Y5)
            if pending:  # apply it: A -= q q^T / D_q
                g0 = q0 * qinv
                g1 = q1 * qinv
                g2 = q2 * qinv
                g3 = q3 * qinv
                g4 = q4 * qinv
                g5 = q5 * qinv
                a00 = a00 - g0 * q0
                a01 = a01 - g0 * q1
                a02 = a02 - g0 * q2
                a03 = a03 - g0 * q3
                a04 = a04 - g0 * q4
                a05 = a05 - g0 * q5
                a11 = a11 - g1 * q1
                a12 = a12 - g1 * q2
                a13 = a13 - g1 * q3
                a14 = a14 - g1 * q4
                a15 = a15 - g1 * q5
                a22 = a22 - g2 * q2
                a23 = a23 - g2 * q3
                a24 = a24 - g2 * q4
                a25 = a25 - g2 * q5
                a33 = a33 - g3 * q3
                a34 = a34 - g3 * q4
                a35 = a35 - g3 * q5
                a44 = a44 - g4 * q4
                a45 = a45 - g4 * q5
                a55 = a55 - g5 * q5
            if not stored:  # I^A of the body: its children's eliminations applied, none of its own
                w[e] = a00
                w[e + 1] = a01
                w[e + 2] = a02
                w[e + 3] = a03
                w[e + 4] = a04
                w[e + 5] = a05
                w[e + 7] = a11
                w[e + 8] = a12
                w[e + 9] = a13
                w[e + 10] = a14
                w[e + 11] = a15
                w[e + 14] = a22
                w[e + 15] = a23
                w[e + 16] = a24
                w[e + 17] = a25
                w[e + 21] = a33
                w[e + 22] = a34
                w[e + 23] = a35
                w[e + 28] = a44
                w[e + 29] = a45
                w[e + 35] = a55
                stored = True
            if d < d0:
                pending = False
                break
            # U = Ia S: Y less the pending elimination's part, q (q . S) / D_q
            U0 = Y0
            U1 = Y1
            U2 = Y2
            U3 = Y3
            U4 = Y4
            U5 = Y5
            if pending:
                k = ((q0 * s0 + q1 * s1) + (q2 * s2 + q3 * s3)) + (q4 * s4 + q5 * s5)
                t = k * qinv
                U0 = Y0 - q0 * t
                U1 = Y1 - q1 * t
                U2 = Y2 - q2 * t
                U3 = Y3 - q3 * t
                U4 = Y4 - q4 * t
                U5 = Y5 - q5 * t
                sU = sU - k * t
            armature = p[do + d * DOF_SIZE + D_ARMATURE]
            D = sU + armature
            w[o.pivots + d] = D
            # the pivot's scale: |S . Ia S| + armature + sum_a Ia[a, a] S_a^2 (the diagonal of Ia is not negative).
            # Each term in kg m^2 for a rotation, kg for a translation: a body of tiny moments and finite mass
            # (rotational entries 1e-12 of the translational ones) keeps its rotations' pivots on their own scale
            # (a scale of trace(Ia) |S|^2 would add its mass to its moments and refuse it; tests/rbody/engine/
            # test_precision.py)
            scale = (abs(sU) + armature) + ((a00 * (s0 * s0) + a11 * (s1 * s1)) + (a22 * (s2 * s2) + a33 * (s3 * s3))
                                            + (a44 * (s4 * s4) + a55 * (s5 * s5)))
            good = positive_beyond(D, PIVOT_RTOL * scale)
            bad = choose(good, bad, choose(positive_beyond(-bad, 0.0), float(d), bad))
            D = choose(good, D, np.inf)  # inf keeps the sweep finite; the caller reports the dof
            ud = w[o.tau + d] - (((s0 * P0 + s1 * P1) + (s2 * P2 + s3 * P3)) + (s4 * P4 + s5 * P5))
            w[o.u + d] = ud
            g = o.U + 6 * d
            w[g] = U0
            w[g + 1] = U1
            w[g + 2] = U2
            w[g + 3] = U3
            w[g + 4] = U4
            w[g + 5] = U5
            inv = 1.0 / D
            # pa += Ia' c + U u / D with Ia' = Ia - U U^T / D: Ia c + U (u - U . c) / D
            c = o.bias + 6 * d
            k0 = w[c]
            k1 = w[c + 1]
            k2 = w[c + 2]
            k3 = w[c + 3]
            k4 = w[c + 4]
            k5 = w[c + 5]
            r = (ud - (((U0 * k0 + U1 * k1) + (U2 * k2 + U3 * k3)) + (U4 * k4 + U5 * k5))) * inv
            P0 += ((a00 * k0 + a01 * k1) + (a02 * k2 + a03 * k3)) + (a04 * k4 + a05 * k5) + U0 * r
            P1 += ((a01 * k0 + a11 * k1) + (a12 * k2 + a13 * k3)) + (a14 * k4 + a15 * k5) + U1 * r
            P2 += ((a02 * k0 + a12 * k1) + (a22 * k2 + a23 * k3)) + (a24 * k4 + a25 * k5) + U2 * r
            P3 += ((a03 * k0 + a13 * k1) + (a23 * k2 + a33 * k3)) + (a34 * k4 + a35 * k5) + U3 * r
            P4 += ((a04 * k0 + a14 * k1) + (a24 * k2 + a34 * k3)) + (a44 * k4 + a45 * k5) + U4 * r
            P5 += ((a05 * k0 + a15 * k1) + (a25 * k2 + a35 * k3)) + (a45 * k4 + a55 * k5) + U5 * r
            pending = True
            q0 = U0
            q1 = U1
            q2 = U2
            q3 = U3
            q4 = U4
            q5 = U5
            qinv = inv
        carry = parent >= 0 and parent == i - 1  # hand over in local variables, the last elimination pending
        if parent >= 0 and not carry:  # the parent gathers the body's Ia and pa in the workspace
            if pending:
                g0 = q0 * qinv
                g1 = q1 * qinv
                g2 = q2 * qinv
                g3 = q3 * qinv
                g4 = q4 * qinv
                g5 = q5 * qinv
                a00 = a00 - g0 * q0
                a01 = a01 - g0 * q1
                a02 = a02 - g0 * q2
                a03 = a03 - g0 * q3
                a04 = a04 - g0 * q4
                a05 = a05 - g0 * q5
                a11 = a11 - g1 * q1
                a12 = a12 - g1 * q2
                a13 = a13 - g1 * q3
                a14 = a14 - g1 * q4
                a15 = a15 - g1 * q5
                a22 = a22 - g2 * q2
                a23 = a23 - g2 * q3
                a24 = a24 - g2 * q4
                a25 = a25 - g2 * q5
                a33 = a33 - g3 * q3
                a34 = a34 - g3 * q4
                a35 = a35 - g3 * q5
                a44 = a44 - g4 * q4
                a45 = a45 - g4 * q5
                a55 = a55 - g5 * q5
            e = o.IA + 36 * parent
            w[e] += a00
            w[e + 1] += a01
            w[e + 2] += a02
            w[e + 3] += a03
            w[e + 4] += a04
            w[e + 5] += a05
            w[e + 7] += a11
            w[e + 8] += a12
            w[e + 9] += a13
            w[e + 10] += a14
            w[e + 11] += a15
            w[e + 14] += a22
            w[e + 15] += a23
            w[e + 16] += a24
            w[e + 17] += a25
            w[e + 21] += a33
            w[e + 22] += a34
            w[e + 23] += a35
            w[e + 28] += a44
            w[e + 29] += a45
            w[e + 35] += a55
            f = o.pA + 6 * parent
            w[f] += P0
            w[f + 1] += P1
            w[f + 2] += P2
            w[f + 3] += P3
            w[f + 4] += P4
            w[f + 5] += P5
    g = p[H_GRAVITY]
    for i in range(nb):
        b = bo + i * BODY_SIZE
        parent = int(p[b + B_PARENT])
        if parent >= 0:
            e = o.acc + 6 * parent
            x0 = w[e]
            x1 = w[e + 1]
            x2 = w[e + 2]
            x3 = w[e + 3]
            x4 = w[e + 4]
            x5 = w[e + 5]
        else:  # gravity: the world accelerates upwards
            x0 = zero
            x1 = zero
            x2 = zero
            x3 = zero
            x4 = zero
            x5 = number(w, g)
        d0 = int(p[b + B_DOF0])
        nd = int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            c = o.bias + 6 * d
            x0 = x0 + w[c]
            x1 = x1 + w[c + 1]
            x2 = x2 + w[c + 2]
            x3 = x3 + w[c + 3]
            x4 = x4 + w[c + 4]
            x5 = x5 + w[c + 5]
            e = o.U + 6 * d
            inv = 1.0 / w[o.pivots + d]  # ready long before it is needed, unlike a division at the end
            qdd = (w[o.u + d] - (((w[e] * x0 + w[e + 1] * x1) + (w[e + 2] * x2 + w[e + 3] * x3))
                                 + (w[e + 4] * x4 + w[e + 5] * x5))) * inv
            qdd = choose(equals(bad, float(d)), np.nan, qdd)
            qacc[ao + d] = qdd
            s = o.S + 6 * d
            x0 = x0 + w[s] * qdd
            x1 = x1 + w[s + 1] * qdd
            x2 = x2 + w[s + 2] * qdd
            x3 = x3 + w[s + 3] * qdd
            x4 = x4 + w[s + 4] * qdd
            x5 = x5 + w[s + 5] * qdd
        e = o.acc + 6 * i
        w[e] = x0
        w[e + 1] = x1
        w[e + 2] = x2
        w[e + 3] = x3
        w[e + 4] = x4
        w[e + 5] = x5
    return bad


@njit(cache=True, fastmath=FMA, error_model="numpy")  # 1 / D without a zero check: D is checked, and set to inf when bad
def articulated_body(p, w, qacc):
    """ABA: qacc (nv,) from the generalised forces in the workspace's tau (nv,) (applied + passive), after
    kinematics, motion_subspaces, velocities and world_inertias; the workspace's pivots (nv,) get the D of every
    degree of freedom (armature included). Returns the first dof whose pivot is not positive beyond PIVOT_RTOL
    of its scale, or -1."""
    o = _offsets(p)
    pp, ww = address(p, 0), address(w, 0)
    for i in range(int(p[H_BODIES])):
        b = int(p[H_BODY]) + i * BODY_SIZE
        h, ib = o.h + 3 * i, o.Ibar + 9 * i
        _articulated_start(ww, o, i, p[b + B_MASS], w[h], w[h + 1], w[h + 2], w[ib], w[ib + 1], w[ib + 2],
                           w[ib + 4], w[ib + 5], w[ib + 8])
    return int(_sweeps(pp, ww, o, address(qacc, 0), AT_START))


@njit(cache=True, fastmath=FMA, error_model="numpy")
def forward_one(p, q, v, tau, qacc, pivots, w):
    """qacc (nv,) = M^-1 (tau + passive - bias) at one state, w the workspace; returns the first singular dof
    or -1 (pivots (nv,) the ABA's D)."""
    o = _offsets(p)
    nv = int(p[H_DOFS])
    pp, qq, vv, ww = address(p, 0), address(q, 0), address(v, 0), address(w, 0)
    _outward(pp, qq, AT_START, vv, AT_START, ww, o)
    _passive(pp, qq, 0, vv, 0, ww, o.tau)
    for d in range(nv):
        w[o.tau + d] += tau[d]
    bad = int(_sweeps(pp, ww, o, address(qacc, 0), AT_START))
    for d in range(nv):
        pivots[d] = w[o.pivots + d]
    return bad


# ----- recursive Newton-Euler and composite rigid bodies -------------------------------------------------

@njit(cache=True)
def inverse_one(p, q, v, qacc, gravity_on, out, w):
    """RNEA: out (nv,) = M qacc + bias (gravity included when gravity_on), passive forces not included; the frames
    at (q, v) left in the workspace w."""
    _frames(p, q, v, w)
    inverse_at_frames(p, qacc, gravity_on, out, w)


@njit(cache=True)
def inverse_at_frames(p, qacc, gravity_on, out, w):
    """inverse_one from the frames _frames left in the workspace w (at the state's q and v): out (nv,) = M qacc +
    bias; w's acc and force are written, its frames read only."""
    ws = _views(p, w)
    S, bias, vel, h, Ibar, acc, force, scratch = ws.S, ws.bias, ws.vel, ws.h, ws.Ibar, ws.acc, ws.force, ws.scratch
    nb = int(p[H_BODIES])
    bo, do = int(p[H_BODY]), int(p[H_DOF])
    tmp = scratch[0:6]
    for i in range(nb):
        b = bo + i * BODY_SIZE
        parent = int(p[b + B_PARENT])
        for a in range(6):
            acc[i, a] = acc[parent, a] if parent >= 0 else 0.0
        if parent < 0 and gravity_on:
            acc[i, 5] = p[H_GRAVITY]
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            for a in range(6):
                acc[i, a] += bias[d, a] + S[d, a] * qacc[d]
        mass = p[b + B_MASS]
        inertia_apply(mass, h[i], Ibar[i], acc[i], force[i])
        inertia_apply(mass, h[i], Ibar[i], vel[i], tmp)
        force_cross(vel[i], tmp, force[i])
    for i in range(nb - 1, -1, -1):
        b = bo + i * BODY_SIZE
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            out[d] = dot6(S[d], force[i]) + p[do + d * DOF_SIZE + D_ARMATURE] * qacc[d]  # armature: M's diagonal
        parent = int(p[b + B_PARENT])
        if parent >= 0:
            for a in range(6):
                force[parent, a] += force[i, a]


@njit(cache=True)
def mass_matrix_one(p, q, out, w):
    """CRBA: out (nv, nv) = M(q), armature on the diagonal; the frames at (q, qvel 0) left in the workspace w."""
    zero = _views(p, w).zero
    for d in range(zero.shape[0]):
        zero[d] = 0.0
    _frames(p, q, zero, w)
    mass_matrix_at_frames(p, w, out)


@njit(cache=True)
def mass_matrix_at_frames(p, w, out):
    """CRBA from the frames _frames left in the workspace w (at any qvel: M reads the positions only): out (nv, nv)
    = M, armature on the diagonal. w is read only: the composite inertias (each body's with its subtree's) are
    summed in their own buffer, so that the bodies' own inertias stay for the force elements and the RNEA."""
    nb, nv = int(p[H_BODIES]), int(p[H_DOFS])
    bo, do = int(p[H_BODY]), int(p[H_DOF])
    ws = _views(p, w)
    S, scratch = ws.S, ws.scratch
    size = 13 * nb  # mass, h (3), Ibar (3, 3) per body (one buffer, on the stack where small)
    owned = carray(stack_floats(size), size) if size <= STACK_FLOATS else np.empty(size)
    mass = carray(address(owned, 0), nb)
    h = carray(address(owned, nb), (nb, 3))
    Ibar = carray(address(owned, 4 * nb), (nb, 3, 3))
    for i in range(nb):
        mass[i] = p[bo + i * BODY_SIZE + B_MASS]
        for a in range(3):
            h[i, a] = ws.h[i, a]
            for c in range(3):
                Ibar[i, a, c] = ws.Ibar[i, a, c]
    for i in range(nb - 1, -1, -1):  # composite inertias: add each body's to its parent's
        parent = int(p[bo + i * BODY_SIZE + B_PARENT])
        if parent >= 0:
            mass[parent] += mass[i]
            for a in range(3):
                h[parent, a] += h[i, a]
                for c in range(3):
                    Ibar[parent, a, c] += Ibar[i, a, c]
    for a in range(nv):
        for c in range(nv):
            out[a, c] = 0.0
    parents = np.empty(nv, dtype=np.int64)  # the dofs' parents as integers: a walk up the tree reads each once
    for d in range(nv):                      # (read from p, each step of the walk waits on a float's conversion)
        parents[d] = int(p[do + d * DOF_SIZE + D_PARENT])
    F = scratch[0:6]
    for i in range(nb):
        b = bo + i * BODY_SIZE
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            inertia_apply(mass[i], h[i], Ibar[i], S[d], F)
            out[d, d] = dot6(S[d], F) + p[do + d * DOF_SIZE + D_ARMATURE]
            k = parents[d]
            while k >= 0:
                value = dot6(S[k], F)
                out[d, k] = value
                out[k, d] = value
                k = parents[k]
    keep_alive(owned)  # read through views only


@njit(cache=True)
def energies_one(p, q, v, w):
    """(kinetic, potential) [J]: sum 1/2 v_i . I_i v_i + sum 1/2 armature_d qvel_d^2 (the rotors armature stands
    for: 1/2 qvel' M qvel with M MuJoCo's qM, which the dynamics integrate); sum m g z_com + 1/2 stiffness
    (q - springref)^2."""
    _frames(p, q, v, w)
    ws = _views(p, w)
    vel, h, Ibar, scratch = ws.vel, ws.h, ws.Ibar, ws.scratch
    nb, nj = int(p[H_BODIES]), int(p[H_JOINTS])
    bo, jo = int(p[H_BODY]), int(p[H_JOINT])
    do, nv = int(p[H_DOF]), int(p[H_DOFS])
    tmp = scratch[0:6]
    kinetic, potential = 0.0, 0.0
    for i in range(nb):
        mass = p[bo + i * BODY_SIZE + B_MASS]
        inertia_apply(mass, h[i], Ibar[i], vel[i], tmp)
        kinetic += 0.5 * dot6(vel[i], tmp)
        potential += p[H_GRAVITY] * (h[i, 2] + mass * ws.xorigin[i, 2])  # m g z_com, z in the world
    for d in range(nv):
        kinetic += 0.5 * p[do + d * DOF_SIZE + D_ARMATURE] * v[d] * v[d]
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        x = q[int(p[r + J_QADR])] - p[r + J_SPRINGREF]
        potential += 0.5 * p[r + J_STIFF] * x * x
    return kinetic, potential


@njit(cache=True)
def body_states_one(p, q, v, com, quat, velocity, omega, w):
    """World centre of mass (nb, 3) [m], orientation (nb, 4), centre-of-mass velocity (nb, 3) [m/s] and
    angular velocity (nb, 3) [rad/s] of every body."""
    _frames(p, q, v, w)
    ws = _views(p, w)
    xquat, vel, h, xorigin, c = ws.xquat, ws.vel, ws.h, ws.xorigin, ws.scratch[0:3]
    nb = int(p[H_BODIES])
    bo = int(p[H_BODY])
    for i in range(nb):
        mass = p[bo + i * BODY_SIZE + B_MASS]
        for a in range(3):
            c[a] = h[i, a] / mass  # the com relative to the tree's origin
            com[i, a] = xorigin[i, a] + c[a]
            omega[i, a] = vel[i, a]
        for a in range(4):
            quat[i, a] = xquat[i, a]
        # velocity of the point at the com: v_O + omega x c
        velocity[i, 0] = vel[i, 3] + vel[i, 1] * c[2] - vel[i, 2] * c[1]
        velocity[i, 1] = vel[i, 4] + vel[i, 2] * c[0] - vel[i, 0] * c[2]
        velocity[i, 2] = vel[i, 5] + vel[i, 0] * c[1] - vel[i, 1] * c[0]


# ----- the native state of a TreeScene: y = (qpos, qvel, phi) ---------------------------------------------

@njit(cache=True, inline="always")
def _effective_qpos(p, y, w, at):
    """w[at + a] = qpos[a] with every ball/free quaternion q_n replaced by q_n (x) exp(phi), y = (qpos, qvel, phi)."""
    nj, nq, nv = int(p[H_JOINTS]), int(p[H_NQ]), int(p[H_DOFS])
    jo = int(p[H_JOINT])
    for a in range(nq):
        w[at + a] = y[a]
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        slot = int(p[r + J_ROT])
        if slot < 0:
            continue
        qa = int(p[r + J_QADR]) + (3 if int(p[r + J_KIND]) == FREE else 0)
        f = nq + nv + 3 * slot
        f0, f1, f2 = y[f], y[f + 1], y[f + 2]
        angle = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)  # exp(phi), as quat_exp
        scale = 0.5 - angle * angle / 48.0 if angle < 1e-4 else np.sin(0.5 * angle) / angle
        t0, t1, t2, t3 = _qmul(y[qa], y[qa + 1], y[qa + 2], y[qa + 3], np.cos(0.5 * angle), scale * f0, scale * f1,
                               scale * f2)
        w[at + qa], w[at + qa + 1], w[at + qa + 2], w[at + qa + 3] = t0, t1, t2, t3


@njit(cache=True, fastmath=FMA, error_model="numpy")  # 1 / D without a zero check (articulated_body)
def tree_rhs(y, p, out):
    """y' for y = (qpos (nq), qvel (nv), phi (3 per ball/free joint)): hinge, slide and free-position
    coordinates move with qvel, quaternion entries stand still within a step, phi' = dexp^-1_phi(omega_body),
    qvel' = forward dynamics at the turned quaternions. A singular mass matrix gives NaN (the run fails)."""
    nq = int(p[H_NQ])
    size = workspace_size(p)
    # the workspace on this function's stack (no allocation per evaluation), on the heap for huge trees
    w = carray(stack_floats(size), size) if size <= STACK_FLOATS else np.empty(size)
    o = _offsets(p)
    pp, yy, ww = address(p, 0), address(y, 0), address(w, 0)
    if int(p[H_ROT]) > 0:
        _effective_qpos(pp, yy, ww, o.q)
        q, qo = ww, o.q
    else:
        q, qo = yy, 0
    _outward(pp, q, qo, yy, nq, ww, o)
    _passive(pp, q, qo, yy, nq, ww, o.tau)
    _sweeps(pp, ww, o, address(out, 0), nq)
    _coordinate_rates(pp, yy, address(out, 0))
    keep_alive(w)  # the workspace was read through ww only: on the heap, it must outlive the passes


@njit(cache=True, inline="always")
def _coordinate_rates(p, y, out):
    """The qpos and phi parts of y' (tree_rhs), y and out read and written by index (arrays or pointers): hinge,
    slide, roll and free-position coordinates move with qvel, quaternion entries stand still within a step,
    phi' = dexp^-1_phi(omega_body). Entries of y and out past phi are not touched."""
    nj, nq, nv = int(p[H_JOINTS]), int(p[H_NQ]), int(p[H_DOFS])
    jo = int(p[H_JOINT])
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        kind = int(p[r + J_KIND])
        qa, da = int(p[r + J_QADR]), int(p[r + J_DADR])
        if kind == HINGE or kind == SLIDE or kind == ROLL:
            out[qa] = y[nq + da]
            continue
        base = qa
        if kind == FREE:
            out[qa], out[qa + 1], out[qa + 2] = y[nq + da], y[nq + da + 1], y[nq + da + 2]
            base, da = qa + 3, da + 3
        out[base], out[base + 1], out[base + 2], out[base + 3] = 0.0, 0.0, 0.0, 0.0
        at = nq + nv + 3 * int(p[r + J_ROT])
        out[at], out[at + 1], out[at + 2] = dexp_inverse3(y[at], y[at + 1], y[at + 2], y[nq + da], y[nq + da + 1],
                                                          y[nq + da + 2])


@njit(cache=True, fastmath=FMA)
def coordinate_rates(p, y, out):
    """The qpos and phi parts of y' (y, out (n,) with n >= nq + nv + 3 nrot), as tree_rhs forms them (the same
    code, so a caller that forms qvel' its own way, e.g. the constraint layer, moves the coordinates as tree_rhs
    does): hinge, slide, roll and free-position coordinates move with qvel, quaternion entries stand still within a
    step, phi' = dexp^-1_phi(omega_body). out's qvel part and entries past phi are not touched."""
    _coordinate_rates(address(p, 0), address(y, 0), address(out, 0))


# Trees without ball or free joints in lanes: WIDTH states side by side (rbody.engine.simd), each lane with
# tree_rhs's bits.
LANES = WIDTH


@njit(cache=True, fastmath=FMA, error_model="numpy")  # 1 / D without a zero check (articulated_body)
def tree_rhs_lanes(y, p, out):
    """tree_rhs for LANES states side by side of a tree without ball or free joints (runs_in_lanes): y and out
    (2 nv LANES,) structures of arrays (entry k of state l at k LANES + l). The same compiled passes as tree_rhs,
    over rbody.engine.simd.LanePointer: each lane does tree_rhs's operations, and gets its bits."""
    nj, nq = int(p[H_JOINTS]), int(p[H_NQ])
    jo = int(p[H_JOINT])
    size = workspace_size(p) * LANES
    heap = np.empty(size if size > STACK_FLOATS else 1)  # huge trees: the workspace on the heap
    w = lane_pointer(stack_floats(size) if size <= STACK_FLOATS else address(heap, 0))
    o = _offsets(p)
    pp, yy, oo = address(p, 0), lane_pointer(address(y, 0)), lane_pointer(address(out, 0))
    _outward(pp, yy, AT_START, yy, nq, w, o)
    _passive(pp, yy, AT_START, yy, nq, w, o.tau)
    _sweeps(pp, w, o, oo, nq)
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        oo[int(pp[r + J_QADR])] = yy[nq + int(pp[r + J_DADR])]
    keep_alive(heap)  # read through w only: on the heap, it must outlive the passes


def runs_in_lanes(multibody) -> bool:
    """Whether tree_rhs_lanes runs the tree: no ball or free joint (their rotation vectors phi and the step's
    finish, tree_finish, are not written for lanes)."""
    return multibody.nrot == 0


@njit(cache=True)
def tree_finish(y, p):
    """After a step: fold every phi into its quaternion, q <- q (x) exp(phi), and set phi = 0."""
    nj, nq, nv = int(p[H_JOINTS]), int(p[H_NQ]), int(p[H_DOFS])
    jo = int(p[H_JOINT])
    w = np.empty(8)
    turn, old = w[0:4], w[4:8]
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        slot = int(p[r + J_ROT])
        if slot < 0:
            continue
        qa = int(p[r + J_QADR]) + (3 if int(p[r + J_KIND]) == FREE else 0)
        at = nq + nv + 3 * slot
        quat_exp(y[at:at + 3], turn)
        for a in range(4):
            old[a] = y[qa + a]
        quat_multiply(old, turn, y[qa:qa + 4])
        for a in range(3):
            y[at + a] = 0.0


@njit(cache=True, fastmath=FMA, error_model="numpy")  # 1 / D without a zero check (articulated_body)
def tree_accel(q, p, out):
    """q'' = a(q) for trees whose mass matrix is constant and forces depend on q only (no ball or free joint:
    nq = nv): forward dynamics at zero velocity."""
    nv = int(p[H_DOFS])
    size = workspace_size(p)
    w = carray(stack_floats(size), size) if size <= STACK_FLOATS else np.empty(size)
    o = _offsets(p)
    pp, qq, ww = address(p, 0), address(q, 0), address(w, 0)
    for d in range(nv):
        w[o.zero + d] = 0.0
    _outward(pp, qq, AT_START, ww, o.zero, ww, o)
    _passive(pp, qq, 0, ww, o.zero, ww, o.tau)
    _sweeps(pp, ww, o, address(out, 0), AT_START)
    keep_alive(w)  # the passes read the workspace through ww only


# ----- the kernels as C function pointers, kept in numba's disk cache (rbody.engine.pointers) --------------

def _tree_rhs_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def tree_rhs_c(y, p, out, n, m):
        tree_rhs(carray(y, n), carray(p, m), carray(out, n))
    return tree_rhs_c


def _tree_accel_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def tree_accel_c(q, p, out, n, m):
        tree_accel(carray(q, n), carray(p, m), carray(out, n))
    return tree_accel_c


def _tree_finish_pointer():
    @cfunc(pointers.FINISH_SIGNATURE, cache=True)
    def tree_finish_c(y, p, n, m):
        tree_finish(carray(y, n), carray(p, m))
    return tree_finish_c


def _tree_rhs_lanes_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def tree_rhs_lanes_c(y, p, out, n, m):
        tree_rhs_lanes(carray(y, n * LANES), carray(p, m), carray(out, n * LANES))
    return tree_rhs_lanes_c


pointers.register(tree_rhs, "rhs", _tree_rhs_pointer)
pointers.register(tree_rhs_lanes, "lanes", _tree_rhs_lanes_pointer)
pointers.register(tree_accel, "rhs", _tree_accel_pointer)
pointers.register(tree_finish, "finish", _tree_finish_pointer)


# ----- batches: one compiled loop per algorithm -----------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _forward_batch(p, Q, V, T, out, pivots):
    """forward_one over rows of Q, V, T (C arrays), written out here: the two compiled passes it calls are the ones
    tree_rhs calls, so that a new model's first run compiles no other copy of them."""
    count, nq, nv = Q.shape[0], int(p[H_NQ]), int(p[H_DOFS])
    bad = np.empty(count, dtype=np.int64)
    w = np.empty(workspace_size(p))
    o = _offsets(p)
    pp, ww, qq, vv, tt, aa, pv = address(p, 0), address(w, 0), data(Q), data(V), data(T), data(out), data(pivots)
    for b in range(count):
        _outward(pp, qq, b * nq, vv, b * nv, ww, o)
        _passive(pp, qq, b * nq, vv, b * nv, ww, o.tau)
        for d in range(nv):
            ww[o.tau + d] += tt[b * nv + d]
        bad[b] = int(_sweeps(pp, ww, o, aa, b * nv))
        for d in range(nv):
            pv[b * nv + d] = ww[o.pivots + d]
    keep_alive(w)  # read through ww only: it must outlive the loop
    return bad


@njit(cache=True)
def _inverse_batch(p, Q, V, A, gravity_on, out):
    w = np.empty(workspace_size(p))
    for b in range(Q.shape[0]):
        inverse_one(p, Q[b], V[b], A[b], gravity_on, out[b], w)


@njit(cache=True)
def _mass_matrix_batch(p, Q, out):
    w = np.empty(workspace_size(p))
    for b in range(Q.shape[0]):
        mass_matrix_one(p, Q[b], out[b], w)


@njit(cache=True)
def _passive_batch(p, Q, V, out):
    for b in range(Q.shape[0]):
        passive(p, Q[b], V[b], out[b])


@njit(cache=True)
def _energies_batch(p, Q, V, out):
    w = np.empty(workspace_size(p))
    for b in range(Q.shape[0]):
        out[b, 0], out[b, 1] = energies_one(p, Q[b], V[b], w)


@njit(cache=True)
def _body_states_batch(p, Q, V, com, quat, velocity, omega):
    w = np.empty(workspace_size(p))
    for b in range(Q.shape[0]):
        body_states_one(p, Q[b], V[b], com[b], quat[b], velocity[b], omega[b], w)


# ----- building the model from a Layout -------------------------------------------------------------------

def _number(value, what: str) -> float:
    array = np.asarray(value, dtype=np.float64)
    if array.shape != () or not np.isfinite(array):
        raise ValueError(f"{what}={value!r}: expected one finite number")
    return float(array)


def _vector(value, what: str, size: int) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what}={value!r}: expected {size} finite numbers") from None
    if array.size != size or not np.all(np.isfinite(array)):
        raise ValueError(f"{what}={value!r}: expected {size} finite numbers")
    return array


def initial_coordinates(layout, order, joints) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's qpos (nq,) and qvel (nv,) from the joints' qpos0/qvel0 (rbody.layout.Joint conventions)."""
    from rbody.motion import quat_to_matrix as rotation_of

    bodies = {body.name: body for body in order}
    qpos, qvel = [], []
    for joint in joints:
        what = f"joint {joint.name!r}"
        if joint.kind in ("hinge", "slide", "roll"):
            qpos.append(_number(joint.qpos0, f"{what}: qpos0"))
            qvel.append(_number(joint.qvel0, f"{what}: qvel0"))
        elif joint.kind == "ball":
            quat = (np.array([1.0, 0.0, 0.0, 0.0]) if np.size(joint.qpos0) == 1 and float(np.asarray(joint.qpos0)) == 0
                    else _vector(joint.qpos0, f"{what}: qpos0 (a quaternion w, x, y, z)", 4))
            norm = np.linalg.norm(quat)
            if norm == 0:
                raise ValueError(f"{what}: qpos0={joint.qpos0!r} is a zero quaternion")
            qpos.extend((quat / norm).tolist())
            omega = (np.zeros(3) if np.size(joint.qvel0) == 1 and float(np.asarray(joint.qvel0)) == 0
                     else _vector(joint.qvel0, f"{what}: qvel0 (body-frame angular velocity)", 3))
            qvel.extend(omega.tolist())
        else:  # free: the body's pose; qvel0 = (v of the body-frame origin, omega), world frame
            body = bodies[joint.body]
            quat = _vector(body.quat, f"body {body.name!r}: quat", 4)
            quat = quat / np.linalg.norm(quat)
            velocity = (np.zeros(6) if np.size(joint.qvel0) == 1 and float(np.asarray(joint.qvel0)) == 0
                        else _vector(joint.qvel0, f"{what}: qvel0 (v, omega), world frame", 6))
            qpos.extend(list(_vector(body.pos, f"body {body.name!r}: pos", 3)) + quat.tolist())
            qvel.extend(velocity[:3].tolist() + (rotation_of(quat).T @ velocity[3:]).tolist())
    return np.array(qpos, dtype=np.float64), np.array(qvel, dtype=np.float64)


def build_tree(layout, gravity: float) -> tuple[TreeArrays, np.ndarray, np.ndarray]:
    """The params row of `layout` and its initial qpos, qvel; ValueError for what cannot be a tree."""
    from rbody.motion import quat_normalize

    gravity = _number(gravity, "gravity")
    order = tree_order(layout)
    index = {body.name: i for i, body in enumerate(order)}
    joint_names = set()
    for joint in layout.joints:
        if joint.name in joint_names:
            raise ValueError(f"two joints are called {joint.name!r}: joint names must be unique")
        joint_names.add(joint.name)
        if joint.body not in index:
            raise ValueError(f"joint {joint.name!r}: body={joint.body!r} is not a body of the layout")
        if joint.kind not in KIND_CODE:
            raise ValueError(f"joint {joint.name!r}: kind={joint.kind!r}, expected one of {tuple(KIND_CODE)}")
        for field in ("damping", "stiffness", "springref", "armature", "ref"):
            value = _number(getattr(joint, field, 0.0), f"joint {joint.name!r}: {field}")
            if field in ("damping", "stiffness", "armature") and value < 0:
                raise ValueError(f"joint {joint.name!r}: {field}={value!r} must be >= 0")
        if joint.kind in ("ball", "free") and getattr(joint, "stiffness", 0.0) != 0:
            raise ValueError(f"joint {joint.name!r}: stiffness={joint.stiffness!r} on a {joint.kind} joint is not "
                             "modelled (MuJoCo's quaternion spring); use stiffness only on hinge and slide joints")
        _vector(joint.axis, f"joint {joint.name!r}: axis", 3)
        _vector(joint.anchor, f"joint {joint.name!r}: anchor", 3)
    joints = list(joint_order(layout))
    for body in order:
        own = [j for j in joints if j.body == body.name]
        kinds = [j.kind for j in own]
        if "free" in kinds:
            if body.parent != WORLD:
                raise ValueError(f"joint {own[kinds.index('free')].name!r}: a free joint on body {body.name!r}, "
                                 f"whose parent is {body.parent!r}: a free joint belongs to a child of the world")
            if len(own) > 1:
                raise ValueError(f"body {body.name!r} has a free joint and {len(own) - 1} other joint(s): a free "
                                 "joint must be its body's only joint")
        if "ball" in kinds[:-1]:
            raise ValueError(f"joint {own[kinds.index('ball')].name!r}: a ball joint must be the last joint of body "
                             f"{body.name!r} (its rotations are about the body's final axes)")
        for b_field, size in (("pos", 3), ("quat", 4)):
            _vector(getattr(body, b_field), f"body {body.name!r}: {b_field}", size)

    nb, nj = len(order), len(joints)
    qposadr, dofadr, nq, nv = coordinate_addresses(tuple(joints))
    rotslot, nrot = [], 0
    for joint in joints:
        rotslot.append(nrot if joint.kind in ("ball", "free") else -1)
        nrot += joint.kind in ("ball", "free")
    body_offset_ = HEADER
    joint_offset = body_offset_ + nb * BODY_SIZE
    dof_offset = joint_offset + nj * JOINT_SIZE
    row = np.zeros(dof_offset + nv * DOF_SIZE)
    row[[H_BODIES, H_JOINTS, H_DOFS, H_NQ, H_ROT, H_GRAVITY, H_BODY, H_JOINT, H_DOF]] = (
        nb, nj, nv, nq, nrot, gravity, body_offset_, joint_offset, dof_offset)
    dof_body = np.empty(nv, dtype=np.int64)
    dof_joint = np.empty(nv, dtype=np.int64)
    last_dof = {}  # body name -> its last dof, or its nearest moving ancestor's
    j = 0
    for i, body in enumerate(order):
        b = body_offset_ + i * BODY_SIZE
        row[b + B_PARENT] = index[body.parent] if body.parent in index else -1
        row[b + B_POS:b + B_POS + 3] = _vector(body.pos, f"body {body.name!r}: pos", 3)
        row[b + B_QUAT:b + B_QUAT + 4] = quat_normalize(_vector(body.quat, f"body {body.name!r}: quat", 4))
        row[b + B_MASS] = body.inertia.mass
        row[b + B_COM:b + B_COM + 3] = body.inertia.com
        row[b + B_TENSOR:b + B_TENSOR + 9] = np.asarray(body.inertia.tensor).reshape(-1)
        own = [jt for jt in joints if jt.body == body.name]
        row[b + B_JNT0], row[b + B_NJNT] = j, len(own)
        row[b + B_DOF0] = dofadr[j] if own else 0
        row[b + B_NDOF] = sum(NV[KIND_CODE[jt.kind]] for jt in own)
        parent_dof = last_dof.get(body.parent, -1)
        for joint in own:
            code = KIND_CODE[joint.kind]
            r = joint_offset + j * JOINT_SIZE
            row[r + J_KIND], row[r + J_BODY] = code, i
            axis = _vector(joint.axis, f"joint {joint.name!r}: axis", 3)
            row[r + J_AXIS:r + J_AXIS + 3] = axis / np.linalg.norm(axis) if code in SCALAR_KINDS else (0, 0, 1)
            row[r + J_ANCHOR:r + J_ANCHOR + 3] = (_vector(joint.anchor, "anchor", 3) if code != FREE else 0.0)
            row[r + J_QADR], row[r + J_DADR] = qposadr[j], dofadr[j]
            row[r + J_REF] = getattr(joint, "ref", 0.0) if code in SCALAR_KINDS else 0.0
            if code == ROLL:  # the rolling line l = axis x normal (rbody.layout.Joint.line)
                row[r + J_RADIUS] = _number(joint.radius, f"joint {joint.name!r}: radius")
                row[r + J_LINE:r + J_LINE + 3] = joint.line
            row[r + J_STIFF] = getattr(joint, "stiffness", 0.0)
            row[r + J_SPRINGREF] = getattr(joint, "springref", 0.0)
            row[r + J_ROT] = rotslot[j]
            for k in range(NV[code]):
                d = dofadr[j] + k
                o = dof_offset + d * DOF_SIZE
                row[o + D_JOINT], row[o + D_INDEX] = j, k
                row[o + D_GROUP] = 1.0 if (code in SCALAR_KINDS or k in (0, 3)) else 0.0
                row[o + D_DAMPING] = getattr(joint, "damping", 0.0)
                row[o + D_ARMATURE] = getattr(joint, "armature", 0.0)
                row[o + D_PARENT] = parent_dof
                parent_dof = d
                dof_body[d], dof_joint[d] = i, j
            j += 1
        last_dof[body.name] = parent_dof
    TREE_HEADER.check(row, 0, 1)
    BODY.check(row, body_offset_, nb)
    JOINT.check(row, joint_offset, nj)
    DOF.check(row, dof_offset, nv)
    row.setflags(write=False)
    arrays = TreeArrays(names=tuple(b.name for b in order), joint_names=tuple(jt.name for jt in joints),
                        joint_kinds=tuple(jt.kind for jt in joints), row=row, nq=nq, nv=nv, nrot=nrot,
                        qposadr=np.array(qposadr, dtype=np.int64), dofadr=np.array(dofadr, dtype=np.int64),
                        dof_body=dof_body, dof_joint=dof_joint)
    qpos0, qvel0 = initial_coordinates(layout, order, joints)
    return arrays, qpos0, qvel0


class Multibody:
    """The dynamics of the kinematic tree of a Layout (module docstring).

    Multibody(layout, *, gravity=9.81 [m/s^2] along -z). Attributes: nq, nv (MuJoCo's sizes), qpos0 (nq,),
    qvel0 (nv,) from the joints, body_names (MuJoCo order), joint_names, params (the model row).
    Every method accepts leading batch axes on its state arguments: q (..., nq), v (..., nv).
    Raises ValueError, before any work, for a layout that is not a tree rbody can run (module docstring)
    and for a mass matrix singular at qpos0 (naming the body and joint).
    """

    def __init__(self, layout, *, gravity: float = 9.81) -> None:
        arrays, qpos0, qvel0 = build_tree(layout, gravity)
        self.layout = layout
        self.gravity = float(gravity)
        self.arrays = arrays
        self.params = arrays.row
        # a writable copy for the kernels: the same array type as the rows the integrators pass (a read-only
        # array is another numba type, which would compile every algorithm a second time)
        self._kernel_params = np.array(arrays.row)
        self.nq, self.nv, self.nrot = arrays.nq, arrays.nv, arrays.nrot
        self.body_names, self.joint_names = arrays.names, arrays.joint_names
        qpos0.setflags(write=False)
        qvel0.setflags(write=False)
        self.qpos0, self.qvel0 = qpos0, qvel0
        self.check_pivots(qpos0)  # a tree with no degree of freedom (nq = nv = 0, as MuJoCo compiles it) is a model too

    # ----- arguments ---------------------------------------------------------------------------------

    def _state(self, value, size: int, what: str) -> np.ndarray:
        array = np.asarray(value, dtype=np.float64)
        if array.ndim == 0 or array.shape[-1] != size:
            raise ValueError(f"{what} has shape {array.shape}: expected (..., {size})")
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{what} holds NaN or inf: expected finite numbers")
        return array

    def _batch(self, *pairs) -> tuple[tuple[int, ...], list[np.ndarray]]:
        arrays = [self._state(value, size, what) for value, size, what in pairs]
        shape = np.broadcast_shapes(*(a.shape[:-1] for a in arrays))
        # writable C arrays, as the integrators pass: a read-only state (a broadcast view) is another numba type,
        # which would compile every algorithm a second time (seconds on a first run); the count explicit: a tree
        # with nothing that moves has nq = 0
        count = int(np.prod(shape)) if shape else 1
        flat = [np.require(np.broadcast_to(a, shape + a.shape[-1:]).reshape(count, a.shape[-1]), np.float64, ["C", "W"])
                for a in arrays]
        return shape, flat

    def pivots(self, q) -> tuple[np.ndarray, np.ndarray]:
        """(pivots (B, nv), bad (B,)): the ABA's pivot D of every degree of freedom at each q (..., nq) flattened
        to B states, armature included, and the first dof of each state whose pivot is not positive (-1: none)."""
        _, (Q,) = self._batch((q, self.nq, "q"))
        count = Q.shape[0]
        out, pivots = np.empty((count, self.nv)), np.empty((count, self.nv))
        zeros = np.zeros((count, self.nv))
        bad = _forward_batch(self._kernel_params, Q, zeros, zeros, out, pivots)
        return pivots, bad

    def check_pivots(self, q) -> None:
        """Raise ValueError naming the body and joint when M(q) is singular (an ABA pivot <= 0)."""
        _, bad = self.pivots(q)
        if np.any(bad >= 0):
            d = int(bad[bad >= 0][0])
            body = self.body_names[self.arrays.dof_body[d]]
            joint = self.joint_names[self.arrays.dof_joint[d]]
            raise ValueError(
                f"the mass matrix is singular: body {body!r} gives its joint {joint!r} (degree of freedom {d}) no "
                "inertia (the joint moves nothing with mass or moment about its axis: e.g. a point mass turning "
                "about an axis through it, or a massless end); give the body inertia about that joint, armature, "
                "or remove the joint")

    def diagnosis(self):
        """diagnose(y, y0, dt) -> str for a NativeModel whose states start with this tree's (qpos (nq), qvel (nv)):
        at the last finite state y of a failed run started from y0, the body and joint whose mass-matrix pivot
        vanishes there (the ValueError of check_pivots) or on the path of the failing step, the hinge, slide and
        roll coordinates moved on at their rates for up to 1.5 dt (where a stage of the step may have met a
        singular configuration that no whole step reached); "" when neither."""
        nq = self.nq
        moving = [(int(qa), int(da)) for kind, qa, da in zip(self.arrays.joint_kinds, self.arrays.qposadr,
                                                             self.arrays.dofadr) if JOINTS[kind].scalar]

        def diagnose(y: np.ndarray, y0: np.ndarray, dt: float) -> str:
            y, y0 = np.asarray(y, dtype=np.float64), np.asarray(y0, dtype=np.float64)
            try:
                self.check_pivots(y[:nq])
            except ValueError as error:
                return str(error)
            fraction = np.linspace(0.0, 1.5, PATH_SAMPLES)
            path = np.repeat(y[None, :nq], PATH_SAMPLES, axis=0)
            for qa, da in moving:
                path[:, qa] += fraction * dt * y[nq + da]
            ratio = self.pivots(path)[0] / self.pivots(y0[:nq])[0]
            where, d = np.unravel_index(int(np.argmin(ratio)), ratio.shape)
            if not ratio[where, d] < NEARLY_SINGULAR:
                return ""
            body = self.body_names[self.arrays.dof_body[d]]
            joint = self.joint_names[self.arrays.dof_joint[d]]
            return (f"the mass matrix became singular: body {body!r} gives its joint {joint!r} (degree of freedom "
                    f"{d}) no inertia about {fraction[where]:.2g} dt after the last finite state (its pivot falls to "
                    f"{ratio[where, d]:.2g} of its value at the start: the joints' axes line up there, or the joint "
                    "moves nothing with mass); give the body inertia about that joint or armature, or other joints (a "
                    "ball joint has no singular configuration)")
        return diagnose

    # ----- the algorithms ----------------------------------------------------------------------------

    def mass_matrix(self, q) -> np.ndarray:
        """M (..., nv, nv) [kg, kg m, kg m^2] at q (..., nq), armature on the diagonal (MuJoCo's mj_fullM)."""
        shape, (Q,) = self._batch((q, self.nq, "q"))
        out = np.empty((Q.shape[0], self.nv, self.nv))
        _mass_matrix_batch(self._kernel_params, Q, out)
        return out.reshape(shape + (self.nv, self.nv))

    def bias_forces(self, q, v) -> np.ndarray:
        """(..., nv) gravity, Coriolis and centrifugal generalised forces (MuJoCo's qfrc_bias)."""
        shape, (Q, V) = self._batch((q, self.nq, "q"), (v, self.nv, "v"))
        out = np.empty((Q.shape[0], self.nv))
        _inverse_batch(self._kernel_params, Q, V, np.zeros_like(V), True, out)
        return out.reshape(shape + (self.nv,))

    def passive_forces(self, q, v) -> np.ndarray:
        """(..., nv) springs and dampers (MuJoCo's qfrc_passive)."""
        shape, (Q, V) = self._batch((q, self.nq, "q"), (v, self.nv, "v"))
        out = np.empty((Q.shape[0], self.nv))
        _passive_batch(self._kernel_params, Q, V, out)
        return out.reshape(shape + (self.nv,))

    def forward_dynamics(self, q, v, tau=None) -> np.ndarray:
        """qacc (..., nv) = M^-1 (tau + passive - bias) by the articulated-body algorithm (MuJoCo's qacc with
        constraints off); tau (..., nv) applied generalised forces, default 0. Raises ValueError where M is
        singular."""
        tau = np.zeros(self.nv) if tau is None else tau
        shape, (Q, V, T) = self._batch((q, self.nq, "q"), (v, self.nv, "v"), (tau, self.nv, "tau"))
        out, pivots = np.empty((Q.shape[0], self.nv)), np.empty((Q.shape[0], self.nv))
        bad = _forward_batch(self._kernel_params, Q, V, T, out, pivots)
        if np.any(bad >= 0):
            self.check_pivots(Q[int(np.argmax(bad >= 0))])
        return out.reshape(shape + (self.nv,))

    def inverse_dynamics(self, q, v, a) -> np.ndarray:
        """tau (..., nv) with forward_dynamics(q, v, tau) = a: M a + bias - passive (RNEA)."""
        shape, (Q, V, A) = self._batch((q, self.nq, "q"), (v, self.nv, "v"), (a, self.nv, "a"))
        out = np.empty((Q.shape[0], self.nv))
        _inverse_batch(self._kernel_params, Q, V, A, True, out)
        passive_ = np.empty_like(out)
        _passive_batch(self._kernel_params, Q, V, passive_)
        return (out - passive_).reshape(shape + (self.nv,))

    def _energies(self, q, v) -> tuple[tuple[int, ...], np.ndarray]:
        shape, (Q, V) = self._batch((q, self.nq, "q"), (v, self.nv, "v"))
        out = np.empty((Q.shape[0], 2))
        _energies_batch(self._kernel_params, Q, V, out)
        return shape, out

    def kinetic_energy(self, q, v) -> np.ndarray:
        """(...) 1/2 sum over bodies of m |v_com|^2 + omega . Ic omega [J] (armature not included)."""
        shape, out = self._energies(q, v)
        return out[:, 0].reshape(shape)

    def potential_energy(self, q) -> np.ndarray:
        """(...) sum m g z_com + 1/2 stiffness (q - springref)^2 over the springs [J]."""
        q = self._state(q, self.nq, "q")
        shape, out = self._energies(q, np.zeros(q.shape[:-1] + (self.nv,)))
        return out[:, 1].reshape(shape)

    def body_states(self, q, v) -> dict[str, np.ndarray]:
        """World com (..., nb, 3) [m], quat (..., nb, 4), com velocity (..., nb, 3) [m/s], omega (..., nb, 3)
        [rad/s], bodies in body_names order."""
        shape, (Q, V) = self._batch((q, self.nq, "q"), (v, self.nv, "v"))
        nb = len(self.body_names)
        com, quat = np.empty((Q.shape[0], nb, 3)), np.empty((Q.shape[0], nb, 4))
        velocity, omega = np.empty((Q.shape[0], nb, 3)), np.empty((Q.shape[0], nb, 3))
        _body_states_batch(self._kernel_params, Q, V, com, quat, velocity, omega)
        return {"com": com.reshape(shape + (nb, 3)), "quat": quat.reshape(shape + (nb, 4)),
                "velocity": velocity.reshape(shape + (nb, 3)), "omega": omega.reshape(shape + (nb, 3))}

    def body_poses(self, q) -> tuple[np.ndarray, np.ndarray]:
        """(com (..., nb, 3) [m], quat (..., nb, 4)) of every body, world frame, body_names order."""
        q = self._state(q, self.nq, "q")
        states = self.body_states(q, np.zeros(q.shape[:-1] + (self.nv,)))
        return states["com"], states["quat"]

    def __repr__(self) -> str:
        return (f"Multibody({len(self.body_names)} bodies, joints "
                f"{', '.join(f'{n}:{k}' for n, k in zip(self.joint_names, self.arrays.joint_kinds))}; nq={self.nq}, "
                f"nv={self.nv})")
