"""Multibody: the dynamics of any kinematic tree of rigid bodies, as model arrays and compiled algorithms.

The model (built once in numpy from a Layout) is one flat float64 row, `params`: a header, then one
record per body (parent, fixed placement in the parent, mass properties, its joints and degrees of
freedom), per joint (kind, axis, anchor, qpos/qvel addresses, ref, stiffness, springref) and per degree
of freedom (damping, armature). Every algorithm is an @njit(cache=True) free function of (params, q, v,
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
  Articulated inertias are symmetric: only their upper triangles are updated and summed (21 of 36).
- inverse dynamics and the bias forces: the recursive Newton-Euler algorithm (RNEA), gravity entering
  as an upward acceleration of the world.
- the mass matrix: the composite-rigid-body algorithm (CRBA), inertias added towards the root
  (composites in this one frame add component by component).
Passive forces are MuJoCo's: -stiffness (q - springref) - damping qvel per hinge, slide or roll, -damping
qvel per degree of freedom of a ball or free joint (stiffness on those is refused).

A ball joint's degrees of freedom are rotations about the body's final axes (MuJoCo: "assume no
subsequent rotations"), so a ball joint must be the last joint of its body; a free joint is the only
joint of a child of the world.

Cost: an evaluation of the right-hand side allocates nothing: its workspace is an array on its own stack
(stack_floats, an alloca), cut by _views into arrays over that memory (numba carrays: no reshape, no
reference counting), and each algorithm takes (params, state, workspace) and cuts its own arrays, so that
calls pass a few pointers. Only small spatial functions are inlined; each algorithm is compiled once (a
first compilation of a minute, cached on disk after it). numba's cache does not follow imports: after
editing spatial.py, delete rbody/engine/__pycache__/multibody*.nb[ci].

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
from numba import carray, njit

from rbody.engine.memory import address, stack_floats
from rbody.layout import JOINTS, WORLD, coordinate_addresses, joint_order, tree_order
from rbody.engine.spatial import (cross3, dexp_inverse, dot6, force_cross, inertia_apply, inertia_in_world,
                                  inertia_matrix, motion_cross, quat_axis_angle, quat_exp, quat_multiply,
                                  quat_rotate, quat_to_matrix, symmetric_apply)

# Joint codes, sizes and which kinds are scalar: the one joint table (rbody.layout.JOINTS), as numba constants.
HINGE, SLIDE, BALL, FREE, ROLL = (JOINTS[k].code for k in ("hinge", "slide", "ball", "free", "roll"))
KIND_CODE = {kind.name: kind.code for kind in JOINTS.values()}
NQ = {kind.code: kind.nq for kind in JOINTS.values()}
NV = {kind.code: kind.nv for kind in JOINTS.values()}
SCALAR_KINDS = tuple(kind.code for kind in JOINTS.values() if kind.scalar)  # one coordinate, displacement q - ref

# Header of the params row.
H_BODIES, H_JOINTS, H_DOFS, H_NQ, H_ROT, H_GRAVITY, H_BODY, H_JOINT, H_DOF = range(9)
HEADER = 9
# Body record: parent (-1 world), pos (3), quat (4), mass, com (3), tensor (9), first dof, dofs, first joint,
# joints.
B_PARENT, B_POS, B_QUAT, B_MASS, B_COM, B_TENSOR, B_DOF0, B_NDOF, B_JNT0, B_NJNT = 0, 1, 4, 8, 9, 12, 21, 22, 23, 24
BODY_SIZE = 25
# Joint record: kind, body, axis (3), anchor (3), qpos address, qvel address, ref, stiffness, springref,
# rotation slot (index of the joint's rotation vector phi among the ball and free joints, -1 otherwise),
# rolling radius a and rolling line l = axis x normal (3, body frame) of a roll joint (0 for the others).
J_KIND, J_BODY, J_AXIS, J_ANCHOR, J_QADR, J_DADR, J_REF, J_STIFF, J_SPRINGREF, J_ROT = 0, 1, 2, 5, 8, 9, 10, 11, 12, 13
J_RADIUS, J_LINE = 14, 15
JOINT_SIZE = 18
# Degree-of-freedom record: joint, index within the joint, starts a group (1: the velocity its bias uses
# is the body's velocity so far; 0: the same as the dof before), damping, armature, parent dof (-1 none).
D_JOINT, D_INDEX, D_GROUP, D_DAMPING, D_ARMATURE, D_PARENT = 0, 1, 2, 3, 4, 5
DOF_SIZE = 6

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


# ----- kinematics -------------------------------------------------------------------------------------------

@njit(cache=True, inline="always")
def _is_identity(p, at):
    """Whether p[at:at + 4] is the identity quaternion (1, 0, 0, 0) exactly."""
    return p[at] == 1.0 and p[at + 1] == 0.0 and p[at + 2] == 0.0 and p[at + 3] == 0.0


@njit(cache=True)
def kinematics(p, q, w):
    """World poses of every body from qpos q (nq,), as MuJoCo's mj_kinematics, into the workspace w (_views):
    xpos (nb, 3) body-frame origins [m] relative to the origin of their tree, xorigin (nb, 3) that origin (the
    world placement of the tree's root body, or its free joint's position), xquat (nb, 4), xmat (nb, 3, 3); per
    joint its world axis and anchor (nj, 3) [m] relative to the tree's origin (a roll joint's anchor after its
    slide) and a roll joint's world rolling line l (nj, 3).

    Positions relative to each tree's own origin: the spatial algebra of a tree is written about that point
    (module docstring, "Precision"), so a tree a million metres from the world origin computes as it would at it."""
    ws = _views(p, w)
    xpos, xquat, xmat, scratch, xorigin = ws.xpos, ws.xquat, ws.xmat, ws.scratch, ws.xorigin
    xaxis, xanchor, xline = ws.xaxis, ws.xanchor, ws.xline
    nb = int(p[H_BODIES])
    bo, jo = int(p[H_BODY]), int(p[H_JOINT])
    qloc, quat, previous, vec = scratch[0:4], scratch[4:8], scratch[8:12], scratch[12:15]
    for i in range(nb):
        b = bo + i * BODY_SIZE
        parent = int(p[b + B_PARENT])
        j0, nj = int(p[b + B_JNT0]), int(p[b + B_NJNT])
        if nj == 1 and int(p[jo + j0 * JOINT_SIZE + J_KIND]) == FREE:
            qa = int(p[jo + j0 * JOINT_SIZE + J_QADR])
            for a in range(3):  # a free joint's body is a child of the world: the origin of its own tree
                xorigin[i, a] = q[qa + a]
                xpos[i, a] = 0.0
                xanchor[j0, a] = 0.0
                xaxis[j0, a] = p[jo + j0 * JOINT_SIZE + J_AXIS + a]
            for a in range(4):
                quat[a] = q[qa + 3 + a]
        else:
            if parent >= 0:
                for a in range(3):
                    xorigin[i, a] = xorigin[parent, a]
                    xpos[i, a] = xpos[parent, a] + (xmat[parent, a, 0] * p[b + B_POS] + xmat[parent, a, 1]
                                                    * p[b + B_POS + 1] + xmat[parent, a, 2] * p[b + B_POS + 2])
                if _is_identity(p, b + B_QUAT):  # the common case: the body's axes are its parent's
                    for a in range(4):
                        quat[a] = xquat[parent, a]
                else:
                    quat_multiply(xquat[parent], p[b + B_QUAT:b + B_QUAT + 4], quat)
            else:  # a child of the world: the origin of its own tree
                for a in range(3):
                    xorigin[i, a] = p[b + B_POS + a]
                    xpos[i, a] = 0.0
                for a in range(4):
                    quat[a] = p[b + B_QUAT + a]
            for j in range(j0, j0 + nj):
                r = jo + j * JOINT_SIZE
                kind = int(p[r + J_KIND])
                axis = p[r + J_AXIS:r + J_AXIS + 3]
                anchor = p[r + J_ANCHOR:r + J_ANCHOR + 3]
                at_origin = anchor[0] == 0.0 and anchor[1] == 0.0 and anchor[2] == 0.0  # the common case
                quat_rotate(quat, axis, xaxis[j])
                if at_origin:
                    for a in range(3):
                        xanchor[j, a] = xpos[i, a]
                else:
                    quat_rotate(quat, anchor, xanchor[j])
                    for a in range(3):
                        xanchor[j, a] += xpos[i, a]
                qa = int(p[r + J_QADR])
                if kind == SLIDE:
                    d = q[qa] - p[r + J_REF]
                    for a in range(3):
                        xpos[i, a] += xaxis[j, a] * d
                    continue
                if kind == ROLL:  # first slide by a (q - ref) along l (anchor and body together), then turn
                    quat_rotate(quat, p[r + J_LINE:r + J_LINE + 3], xline[j])
                    d = p[r + J_RADIUS] * (q[qa] - p[r + J_REF])
                    for a in range(3):
                        xanchor[j, a] += xline[j, a] * d
                # hinge, roll or ball: turn about the anchor
                if kind == BALL:
                    norm = np.sqrt(q[qa] ** 2 + q[qa + 1] ** 2 + q[qa + 2] ** 2 + q[qa + 3] ** 2)
                    for a in range(4):
                        qloc[a] = q[qa + a] / norm
                else:
                    quat_axis_angle(axis, q[qa] - p[r + J_REF], qloc)
                for a in range(4):
                    previous[a] = quat[a]
                quat_multiply(previous, qloc, quat)
                if at_origin:  # the body frame's origin is the anchor
                    for a in range(3):
                        xpos[i, a] = xanchor[j, a]
                else:
                    quat_rotate(quat, anchor, vec)
                    for a in range(3):
                        xpos[i, a] = xanchor[j, a] - vec[a]
        norm = np.sqrt(quat[0] ** 2 + quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
        for a in range(4):
            xquat[i, a] = quat[a] / norm
        quat_to_matrix(xquat[i], xmat[i])


@njit(cache=True)
def motion_subspaces(p, w):
    """S (nv, 6): each degree of freedom's unit motion (omega; v at the world origin), world axes, as
    MuJoCo's cdof. Hinge (a; x x a) about its anchor x; slide (0; a); roll (a; x x a) + radius (0; l) (the
    hinge about the anchor after the slide, plus the slide); ball and free rotations about the body's own
    axes (columns of xmat) through the anchor; free translations along the world axes."""
    ws = _views(p, w)
    xmat, xaxis, xanchor, xline, S, axis = ws.xmat, ws.xaxis, ws.xanchor, ws.xline, ws.S, ws.scratch[0:3]
    nv = int(p[H_DOFS])
    jo, do = int(p[H_JOINT]), int(p[H_DOF])
    for d in range(nv):
        j = int(p[do + d * DOF_SIZE + D_JOINT])
        k = int(p[do + d * DOF_SIZE + D_INDEX])
        r = jo + j * JOINT_SIZE
        kind = int(p[r + J_KIND])
        body = int(p[r + J_BODY])
        for a in range(6):
            S[d, a] = 0.0
        if kind == SLIDE:
            for a in range(3):
                S[d, 3 + a] = xaxis[j, a]
            continue
        if kind == FREE and k < 3:
            S[d, 3 + k] = 1.0
            continue
        if kind == HINGE or kind == ROLL:
            for a in range(3):
                axis[a] = xaxis[j, a]
        else:
            c = k if kind == BALL else k - 3
            for a in range(3):
                axis[a] = xmat[body, a, c]
        for a in range(3):
            S[d, a] = axis[a]
        cross3(xanchor[j], axis, S[d, 3:])
        if kind == ROLL:
            radius = p[r + J_RADIUS]
            for a in range(3):
                S[d, 3 + a] += radius * xline[j, a]


@njit(cache=True)
def velocities(p, v, w):
    """vel (nb, 6): each body's spatial velocity (world axes, about the origin); bias (nv, 6): each degree of
    freedom's velocity-product acceleration S' v_d = (v_before x S) v_d (MuJoCo's cdof_dot qvel), v_before
    the body's velocity before the joint (ball and free rotations: before the whole group). A roll joint's
    hinge part moves with its slide part: + radius v_d^2 (0; l x axis) (= (radius v_d (0; l)) x (axis; x x axis))."""
    ws = _views(p, w)
    S, xaxis, xline, vel, bias, base = ws.S, ws.xaxis, ws.xline, ws.vel, ws.bias, ws.scratch[0:6]
    nb = int(p[H_BODIES])
    bo, jo, do = int(p[H_BODY]), int(p[H_JOINT]), int(p[H_DOF])
    for i in range(nb):
        b = bo + i * BODY_SIZE
        parent = int(p[b + B_PARENT])
        for a in range(6):
            vel[i, a] = vel[parent, a] if parent >= 0 else 0.0
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            if p[do + d * DOF_SIZE + D_GROUP] != 0.0:
                for a in range(6):
                    base[a] = vel[i, a]
            for a in range(6):
                bias[d, a] = 0.0
            motion_cross(base, S[d], v[d], bias[d])
            j = int(p[do + d * DOF_SIZE + D_JOINT])
            if int(p[jo + j * JOINT_SIZE + J_KIND]) == ROLL:
                scale = p[jo + j * JOINT_SIZE + J_RADIUS] * v[d] * v[d]
                bias[d, 3] += scale * (xline[j, 1] * xaxis[j, 2] - xline[j, 2] * xaxis[j, 1])
                bias[d, 4] += scale * (xline[j, 2] * xaxis[j, 0] - xline[j, 0] * xaxis[j, 2])
                bias[d, 5] += scale * (xline[j, 0] * xaxis[j, 1] - xline[j, 1] * xaxis[j, 0])
            for a in range(6):
                vel[i, a] += S[d, a] * v[d]


@njit(cache=True)
def world_inertias(p, w):
    """Each body's inertia about the world origin, world axes: h (nb, 3) = m c, Ibar (nb, 3, 3)."""
    ws = _views(p, w)
    xpos, xmat, h, Ibar = ws.xpos, ws.xmat, ws.h, ws.Ibar
    Ic = carray(address(ws.scratch, 0), (3, 3))
    nb = int(p[H_BODIES])
    bo = int(p[H_BODY])
    for i in range(nb):
        b = bo + i * BODY_SIZE
        for a in range(3):
            for c in range(3):
                Ic[a, c] = p[b + B_TENSOR + 3 * a + c]
        inertia_in_world(p[b + B_MASS], p[b + B_COM:b + B_COM + 3], Ic, xmat[i], xpos[i], h[i], Ibar[i])


@njit(cache=True)
def passive(p, q, v, out):
    """out (nv,) = MuJoCo's qfrc_passive: -stiffness (q - springref) per hinge and slide, -damping v per dof."""
    nj, nv = int(p[H_JOINTS]), int(p[H_DOFS])
    jo, do = int(p[H_JOINT]), int(p[H_DOF])
    for d in range(nv):
        out[d] = -p[do + d * DOF_SIZE + D_DAMPING] * v[d]
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        stiffness = p[r + J_STIFF]
        if stiffness != 0.0:
            out[int(p[r + J_DADR])] -= stiffness * (q[int(p[r + J_QADR])] - p[r + J_SPRINGREF])


# ----- the state of one evaluation ------------------------------------------------------------------------

STACK_FLOATS = 16384  # workspaces up to this size (128 kB, ~570 bodies) live on the stack of an evaluation
SCRATCH = 32  # floats of small temporaries (quaternions, 3- and 6-vectors) at the end of the workspace


# The arrays of one evaluation (_views): per body xpos (nb, 3) relative to its tree's origin xorigin (nb, 3), xquat (nb, 4), xmat (nb, 3, 3), spatial velocity
# vel, articulated bias force pA, acceleration acc, force (nb, 6), inertia about the origin h (nb, 3),
# Ibar (nb, 3, 3), articulated inertia IA (nb, 6, 6), mass (nb,); per joint xaxis, xanchor, xline (nj, 3); per
# dof S, bias, U (nv, 6), u (nv,), tau, pivots, zero (nv,); q (nq,); scratch (SCRATCH,).
Workspace = namedtuple("Workspace", ["xpos", "xquat", "xmat", "xaxis", "xanchor", "xline", "S", "bias", "vel", "h",
                                     "Ibar", "IA", "pA", "U", "u", "acc", "force", "mass", "q", "tau", "pivots",
                                     "zero", "scratch", "xorigin"])


# Floats of the workspace per body, joint and degree of freedom: _views cuts exactly these (a test checks it).
BODY_FLOATS = 4 * 6 + 3 * 3 + 2 * 9 + 36 + 4 + 1  # vel pA acc force; xpos h xorigin; xmat Ibar; IA; xquat; mass
JOINT_FLOATS = 3 * 3                                # xaxis xanchor xline
DOF_FLOATS = 3 * 6 + 4                              # S bias U; u tau pivots zero


@njit(cache=True)
def workspace_size(p) -> int:
    """Floats of the workspace of one evaluation (see _views)."""
    nb, nj, nv, nq = int(p[H_BODIES]), int(p[H_JOINTS]), int(p[H_DOFS]), int(p[H_NQ])
    return BODY_FLOATS * nb + JOINT_FLOATS * nj + DOF_FLOATS * nv + nq + SCRATCH


@njit(cache=True, inline="always")
def _rows(w, at, rows, columns):
    """(rows, columns) array over w[at:at + rows * columns]."""
    return carray(address(w, at), (rows, columns))


@njit(cache=True)
def _views(p, w):
    """The arrays of one evaluation, cut from one workspace w (workspace_size(p),) as arrays over its memory
    (numba carrays: no reshape, no reference count; the caller keeps w alive). Allocating each (~25 small
    arrays) would cost more than the algorithms themselves."""
    nb, nj, nv, nq = int(p[H_BODIES]), int(p[H_JOINTS]), int(p[H_DOFS]), int(p[H_NQ])
    at = 0
    S, bias, U = _rows(w, at, nv, 6), _rows(w, at + 6 * nv, nv, 6), _rows(w, at + 12 * nv, nv, 6)
    at += 18 * nv
    vel, pA = _rows(w, at, nb, 6), _rows(w, at + 6 * nb, nb, 6)
    acc, force = _rows(w, at + 12 * nb, nb, 6), _rows(w, at + 18 * nb, nb, 6)
    at += 24 * nb
    xpos, h, xorigin = _rows(w, at, nb, 3), _rows(w, at + 3 * nb, nb, 3), _rows(w, at + 6 * nb, nb, 3)
    at += 9 * nb
    xaxis, xanchor, xline = _rows(w, at, nj, 3), _rows(w, at + 3 * nj, nj, 3), _rows(w, at + 6 * nj, nj, 3)
    at += 9 * nj
    xmat, Ibar = carray(address(w, at), (nb, 3, 3)), carray(address(w, at + 9 * nb), (nb, 3, 3))
    at += 18 * nb
    IA = carray(address(w, at), (nb, 6, 6))
    at += 36 * nb
    xquat = _rows(w, at, nb, 4)
    at += 4 * nb
    u, mass = carray(address(w, at), nv), carray(address(w, at + nv), nb)
    at += nv + nb
    q, tau = carray(address(w, at), nq), carray(address(w, at + nq), nv)
    pivots, zero = carray(address(w, at + nq + nv), nv), carray(address(w, at + nq + 2 * nv), nv)
    scratch = carray(address(w, at + nq + 3 * nv), SCRATCH)
    return Workspace(xpos, xquat, xmat, xaxis, xanchor, xline, S, bias, vel, h, Ibar, IA, pA, U, u, acc, force, mass,
                     q, tau, pivots, zero, scratch, xorigin)


@njit(cache=True)
def _frames(p, q, v, w):
    """Kinematics, motion subspaces, velocities and world inertias of one state, into the workspace w."""
    kinematics(p, q, w)
    motion_subspaces(p, w)
    velocities(p, v, w)
    world_inertias(p, w)


# ----- the articulated-body algorithm ---------------------------------------------------------------------

@njit(cache=True, error_model="numpy")  # 1 / D without a zero check: D is checked, and set to inf when bad
def articulated_body(p, w, qacc):
    """ABA: qacc (nv,) from the generalised forces in the workspace's tau (nv,) (applied + passive), after
    _frames; the workspace's pivots (nv,) get the D of every degree of freedom (armature included). Returns
    the first dof whose pivot is not positive beyond PIVOT_RTOL of its scale, or -1."""
    ws = _views(p, w)
    S, bias, vel, h, Ibar, tau, pivots = ws.S, ws.bias, ws.vel, ws.h, ws.Ibar, ws.tau, ws.pivots
    IA, pA, U, u, acc, scratch = ws.IA, ws.pA, ws.U, ws.u, ws.acc, ws.scratch
    nb = int(p[H_BODIES])
    bo, do = int(p[H_BODY]), int(p[H_DOF])
    g = p[H_GRAVITY]
    tmp = scratch[0:6]
    for i in range(nb):
        mass = p[bo + i * BODY_SIZE + B_MASS]
        inertia_matrix(mass, h[i], Ibar[i], IA[i])
        inertia_apply(mass, h[i], Ibar[i], vel[i], tmp)
        for a in range(6):
            pA[i, a] = 0.0
        force_cross(vel[i], tmp, pA[i])
    bad = -1
    for i in range(nb - 1, -1, -1):
        b = bo + i * BODY_SIZE
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        Ia, pa = IA[i], pA[i]  # articulated inertia: only its upper triangle is kept (it is symmetric)
        for d in range(d0 + nd - 1, d0 - 1, -1):
            s = S[d]
            symmetric_apply(Ia, s, U[d])  # U = Ia S
            D = dot6(s, U[d]) + p[do + d * DOF_SIZE + D_ARMATURE]
            pivots[d] = D
            scale = abs(dot6(s, U[d])) + abs(p[do + d * DOF_SIZE + D_ARMATURE])
            for a in range(6):
                scale = max(scale, abs(Ia[a, a]) * (s[a] * s[a]))
            if not D > PIVOT_RTOL * scale or not D > 0.0:
                if bad < 0:
                    bad = d
                D = np.inf  # keeps the sweep finite; the caller reports the dof
            u[d] = tau[d] - dot6(s, pa)
            inv = 1.0 / D
            for a in range(6):  # Ia -= U U^T / D
                for c in range(a, 6):
                    Ia[a, c] -= U[d, a] * U[d, c] * inv
            # pa += Ia c + U u / D (Ia after the update)
            symmetric_apply(Ia, bias[d], tmp)
            for a in range(6):
                pa[a] += tmp[a] + U[d, a] * u[d] * inv
        parent = int(p[b + B_PARENT])
        if parent >= 0:
            for a in range(6):
                pA[parent, a] += pa[a]
                for c in range(a, 6):
                    IA[parent, a, c] += Ia[a, c]
    for i in range(nb):
        b = bo + i * BODY_SIZE
        parent = int(p[b + B_PARENT])
        for a in range(6):
            acc[i, a] = acc[parent, a] if parent >= 0 else 0.0
        if parent < 0:
            acc[i, 5] = g  # gravity: the world accelerates upwards
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            for a in range(6):
                acc[i, a] += bias[d, a]
            qacc[d] = (u[d] - dot6(U[d], acc[i])) / pivots[d] if d != bad else np.nan
            for a in range(6):
                acc[i, a] += S[d, a] * qacc[d]
    return bad


@njit(cache=True)
def forward_one(p, q, v, tau, qacc, pivots, w):
    """qacc (nv,) = M^-1 (tau + passive - bias) at one state, w the workspace; returns the first singular dof
    or -1 (pivots (nv,) the ABA's D)."""
    _frames(p, q, v, w)
    ws = _views(p, w)
    nv = int(p[H_DOFS])
    passive(p, q, v, ws.tau)
    for d in range(nv):
        ws.tau[d] += tau[d]
    bad = articulated_body(p, w, qacc)
    for d in range(nv):
        pivots[d] = ws.pivots[d]
    return bad


# ----- recursive Newton-Euler and composite rigid bodies -------------------------------------------------

@njit(cache=True)
def inverse_one(p, q, v, qacc, gravity_on, out, w):
    """RNEA: out (nv,) = M qacc + bias (gravity included when gravity_on), passive forces not included."""
    _frames(p, q, v, w)
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
    """CRBA: out (nv, nv) = M(q), armature on the diagonal."""
    nb, nv = int(p[H_BODIES]), int(p[H_DOFS])
    bo, do = int(p[H_BODY]), int(p[H_DOF])
    ws = _views(p, w)
    S, h, Ibar, mass, v, scratch = ws.S, ws.h, ws.Ibar, ws.mass, ws.zero, ws.scratch
    for d in range(nv):
        v[d] = 0.0
    _frames(p, q, v, w)
    for i in range(nb):
        mass[i] = p[bo + i * BODY_SIZE + B_MASS]
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
    F = scratch[0:6]
    for i in range(nb):
        b = bo + i * BODY_SIZE
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            inertia_apply(mass[i], h[i], Ibar[i], S[d], F)
            out[d, d] = dot6(S[d], F) + p[do + d * DOF_SIZE + D_ARMATURE]
            k = int(p[do + d * DOF_SIZE + D_PARENT])
            while k >= 0:
                value = dot6(S[k], F)
                out[d, k] = value
                out[k, d] = value
                k = int(p[do + k * DOF_SIZE + D_PARENT])


@njit(cache=True)
def energies_one(p, q, v, w):
    """(kinetic, potential) [J]: sum 1/2 v_i . I_i v_i; sum m g z_com + 1/2 stiffness (q - springref)^2."""
    _frames(p, q, v, w)
    ws = _views(p, w)
    vel, h, Ibar, scratch = ws.vel, ws.h, ws.Ibar, ws.scratch
    nb, nj = int(p[H_BODIES]), int(p[H_JOINTS])
    bo, jo = int(p[H_BODY]), int(p[H_JOINT])
    tmp = scratch[0:6]
    kinetic, potential = 0.0, 0.0
    for i in range(nb):
        mass = p[bo + i * BODY_SIZE + B_MASS]
        inertia_apply(mass, h[i], Ibar[i], vel[i], tmp)
        kinetic += 0.5 * dot6(vel[i], tmp)
        potential += p[H_GRAVITY] * (h[i, 2] + mass * ws.xorigin[i, 2])  # m g z_com, z in the world
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

@njit(cache=True)
def _effective_qpos(p, y, q, turn):
    """q (nq,) = qpos with every ball/free quaternion q_n replaced by q_n (x) exp(phi)."""
    nj, nq, nv = int(p[H_JOINTS]), int(p[H_NQ]), int(p[H_DOFS])
    jo = int(p[H_JOINT])
    for a in range(nq):
        q[a] = y[a]
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        slot = int(p[r + J_ROT])
        if slot < 0:
            continue
        qa = int(p[r + J_QADR]) + (3 if int(p[r + J_KIND]) == FREE else 0)
        quat_exp(y[nq + nv + 3 * slot:nq + nv + 3 * slot + 3], turn)
        quat_multiply(y[qa:qa + 4], turn, q[qa:qa + 4])


@njit(cache=True)
def tree_rhs(y, p, out):
    """y' for y = (qpos (nq), qvel (nv), phi (3 per ball/free joint)): hinge, slide and free-position
    coordinates move with qvel, quaternion entries stand still within a step, phi' = dexp^-1_phi(omega_body),
    qvel' = forward dynamics at the turned quaternions. A singular mass matrix gives NaN (the run fails)."""
    nq, nv = int(p[H_NQ]), int(p[H_DOFS])
    size = workspace_size(p)
    # the workspace on this function's stack (no allocation per evaluation), on the heap for huge trees
    w = carray(stack_floats(size), size) if size <= STACK_FLOATS else np.empty(size)
    ws = _views(p, w)
    q = ws.q
    _effective_qpos(p, y, q, ws.scratch[SCRATCH - 4:])
    _frames(p, q, y[nq:nq + nv], w)
    passive(p, q, y[nq:nq + nv], ws.tau)
    articulated_body(p, w, out[nq:nq + nv])
    coordinate_rates(p, y, out)


@njit(cache=True)
def coordinate_rates(p, y, out):
    """The qpos and phi parts of y' (tree_rhs): hinge, slide, roll and free-position coordinates move with qvel,
    quaternion entries stand still within a step, phi' = dexp^-1_phi(omega_body)."""
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
            for a in range(3):
                out[qa + a] = y[nq + da + a]
            base, da = qa + 3, da + 3
        for a in range(4):
            out[base + a] = 0.0
        slot = int(p[r + J_ROT])
        at = nq + nv + 3 * slot
        dexp_inverse(y[at:at + 3], y[nq + da:nq + da + 3], out[at:at + 3])


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


@njit(cache=True)
def tree_accel(q, p, out):
    """q'' = a(q) for trees whose mass matrix is constant and forces depend on q only (no ball or free joint:
    nq = nv): forward dynamics at zero velocity."""
    nv = int(p[H_DOFS])
    size = workspace_size(p)
    w = carray(stack_floats(size), size) if size <= STACK_FLOATS else np.empty(size)
    ws = _views(p, w)
    zero = ws.zero
    for d in range(nv):
        zero[d] = 0.0
    _frames(p, q, zero, w)
    passive(p, q, zero, ws.tau)
    articulated_body(p, w, out)


# ----- batches: one compiled loop per algorithm -----------------------------------------------------------

@njit(cache=True)
def _forward_batch(p, Q, V, T, out, pivots):
    bad = np.full(Q.shape[0], -1, dtype=np.int64)
    w = np.empty(workspace_size(p))
    for b in range(Q.shape[0]):
        bad[b] = forward_one(p, Q[b], V[b], T[b], out[b], pivots[b], w)
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
