"""The planar fast path of the multibody engine: trees whose bodies all move in one plane.

Most of the chapter's scenes (the swinging rod, the compound pendulum, the pendulum chain, rolling) are
planar trees: every hinge axis parallel to one unit normal n, every slide perpendicular to n. Their
motion is a planar rigid motion of every body, and the articulated-body algorithm (Featherstone,
RBDA 2008, ch. 7) then runs in 3-component spatial vectors and 3x3 inertias instead of 6 and 6x6.

Plane coordinates: an orthonormal right-handed frame (e1, e2, n) of the world; e2 is the in-plane
direction of world up z when n is not vertical (e2 = z when n is horizontal). Everything is written in
the world's axes about the origin of each tree (its root body's placement) projected on the plane ("ground coordinates", as
rbody.engine.multibody):

    motion  m = (omega, vx, vy): angular velocity about n, velocity of the body point at the origin
    force   f = (tau, fx, fy):   moment about n through the origin, in-plane force
    m1 x m2  = (0, omega2 v1y - omega1 v2y, omega1 v2x - omega2 v1x)
    m x* f   = (vx fy - vy fx, -omega fy, omega fx)
    inertia  [[m |c|^2 + I_n, -hy, hx], [-hy, m, 0], [hx, 0, m]],  h = m c (c the com in the plane)

Why this is exact, the same generalised dynamics as the 3-D engine. Every joint's motion subspace lies in
the planar subalgebra {(omega n; v), v perpendicular to n} of spatial motions, so the mass matrix
S_i . I S_j sees only the block of each body's spatial inertia on that subalgebra: its mass, the in-plane
part of its com and its moment I_n = n . I_c n about the axis n through the com (constant: rotations
about n fix n). The velocity-product forces S . (v x* I v) see only the in-plane components of I v (the
dual action of a planar motion maps the annihilator of the subalgebra into itself). So the products of
inertia I_xn, I_yn and a com offset along n load the joints (moments about in-plane axes, forces along n)
but never enter the equations of motion. Likewise only the in-plane part of gravity does work on a planar
motion: the plane need not be vertical (a tilted n sees g projected on the plane); a horizontal plane
(n vertical) feels no gravity at all.

The model row (built in numpy from the 3-D row, rbody.engine.multibody): a header, then one node per
degree of freedom, depth first (the 3-D engine's order: node d is qpos[d] and qvel[d]; a node's parent
node comes before it). Several joints on one body are a chain of nodes, the inertia of the body on the
last; a welded body's inertia is merged into the node that carries it (welded to the world: dropped).
A node holds its joint (kind, sign of its axis along n, anchor or direction at the reference pose, in
plane coordinates), its passive terms and the merged inertia (mass, com at the reference pose, I_n).
Each body's pose is a planar rigid displacement G = (angle, t) from its reference pose (all q = ref),
composed node by node: G_d = G_parent o J_d(q_d - ref), with
    hinge about anchor a, sign s:  J = (s x, a - R(s x) a)
    slide along d:                 J = (0, d x)
    roll (radius r, line l):       J = (s x, a - R(s x) a + r x l)   (slide r x along l, then turn about a)
and the world motion subspaces follow: hinge (s, s Ay, -s Ax) at the current anchor A = G_parent(a);
slide (0, R(angle_parent) d); roll (s, s Cy + r Ly, -s Cx + r Lx) with C = G_parent(a + r x l) the centre
and L = R(angle_parent) l, whose velocity-product term has, beside (v_parent x S) q', the part of S
turning with q itself: (0, s r Ly, -s r Lx) q'^2 (the slide's subspace crossed with the hinge's).

Kernels: rhs(y, p, out) and accel(q, p, out), the integrators' signatures, over a row p of this module's
layout. An evaluation allocates nothing: its workspace (WORK = 32 floats a node) is a stack buffer
(stack_floats, an LLVM alloca freed on return), read and written by flat index, and each kernel is one
inlined call, so that numba keeps no reference counting of its arrays.

Ground coordinates rather than each node's own frame (where a node's inertia and subspace are constants
and only the parent-to-node transform moves): measured in one run (benchmarks/planar_speed.py setting), the
own-frame ABA was 12% faster on the one-hinge rod but 8% slower at 8 links and 13% at 32, its backward pass
carrying a 3x3 congruence per node where ground coordinates add inertias as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import carray, cfunc, njit

from rbody.engine import multibody as mb
from rbody.engine import pointers
from rbody.engine.memory import address, stack_floats
from rbody.engine.schema import FLOAT, INT, Record
from rbody.engine.simd import (WIDTH, greater, lane, lanes, largest_abs, load, maximum, sin_cos as sin_cos_lanes, splat,
                               store, where)
from rbody.engine.spatial import REDUCED_RANGE, sin_cos

PLANAR_HINGE, PLANAR_SLIDE, PLANAR_ROLL = 0, 1, 2
PLANAR_KINDS = {mb.HINGE: PLANAR_HINGE, mb.SLIDE: PLANAR_SLIDE, mb.ROLL: PLANAR_ROLL}  # the 3-D engine's codes
PARALLEL_TOL = 1e-12  # |a x n| of a hinge axis, |d . n| of a slide direction: beyond this, not planar
PIVOT_RTOL = mb.PIVOT_RTOL

# The planar row (rbody.engine.schema): a header, then one record per node (degree of freedom).
PLANAR_HEADER = Record("planar header", [
    ("nodes", 1, INT, "nodes (= nq = nv)"),
    ("gravity", 2, FLOAT, "in-plane gravity as an upward acceleration of the world [m/s^2]"),
])
P_NODES, P_GX = PLANAR_HEADER.offsets()
P_GY = P_GX + 1
HEADER = PLANAR_HEADER.size
NODE = Record("planar node", [
    ("parent", 1, INT, "parent node (-1: the world)"),
    ("kind", 1, INT, "PLANAR_HINGE, PLANAR_SLIDE or PLANAR_ROLL"),
    ("sign", 1, FLOAT, "sign s of the axis along the plane's normal n"),
    ("point", 2, FLOAT, "hinge and roll: anchor [m]; slide: unit direction (reference pose)"),
    ("ref", 1, FLOAT, "reference coordinate [rad | m]"),
    ("stiffness", 1, FLOAT, "[N m/rad | N/m]"),
    ("springref", 1, FLOAT, "[rad | m]"),
    ("damping", 1, FLOAT, "[N m s/rad | N s/m]"),
    ("armature", 1, FLOAT, "[kg m^2 | kg]"),
    ("mass", 1, FLOAT, "mass the node carries [kg]"),
    ("com", 2, FLOAT, "its centre of mass at the reference pose [m]"),
    ("moment", 1, FLOAT, "I_n about that centre [kg m^2]"),
    ("radius", 1, FLOAT, "roll radius [m]"),
    ("line", 2, FLOAT, "roll line at the reference pose"),
])
(N_PARENT, N_KIND, N_SIGN, N_POINT, N_REF, N_STIFF, N_SPRINGREF, N_DAMPING, N_ARMATURE, N_MASS, N_COM, N_MOMENT,
 N_RADIUS, N_LINE) = NODE.offsets()
NODE_SIZE = NODE.size
# Workspace of a node (one evaluation).
NODE_WORK = Record("planar node workspace", [
    ("cos", 1, FLOAT, "cos of the node's absolute angle"), ("sin", 1, FLOAT, "its sine"),
    ("angle", 1, FLOAT, "the absolute angle of its frame G [rad]"), ("t", 2, FLOAT, "the origin of G [m]"),
    ("S", 3, FLOAT, "motion subspace"), ("v", 3, FLOAT, "velocity"), ("c", 3, FLOAT, "velocity product"),
    ("inertia", 6, FLOAT, "articulated inertia (00 01 02 11 12 22)"), ("bias", 3, FLOAT, "articulated bias force"),
    ("U", 3, FLOAT, "U = I S"), ("dinv", 1, FLOAT, "1/D"), ("u", 1, FLOAT, "u"), ("acc", 3, FLOAT, "acceleration"),
    ("tau", 1, FLOAT, "applied generalised force"),
])
(W_COS, W_SIN, W_ANGLE, W_T, W_S, W_V, W_C, W_I, W_P, W_U, W_DINV, W_SMALL_U, W_A, W_TAU) = NODE_WORK.offsets()
WORK = NODE_WORK.size


# ----- the algorithms ----------------------------------------------------------------------------------

@njit(cache=True, inline="always")
def _articulated(p, y, v0, out, a0, w, applied, outward_only=False):
    """ABA: out[a0 + d] = qacc of node d, from the state y (q = y[0:n], qvel = y[v0:v0 + n], v0 < 0 at rest)
    and, when `applied`, the applied forces w[d * WORK + W_TAU]; passive forces included. With a0 > 0 it also
    copies qvel into out[0:n] (the rhs y' = (qvel, qacc)). Returns the first node whose pivot D is not positive
    beyond PIVOT_RTOL of its scale (its qacc is NaN), or -1.
    outward_only: stop after the outward pass (poses, motion subspaces, velocities, velocity products, rigid
    inertias and bias forces v x* I v of every node, into w), which is also RNEA's first pass; returns -1.

    Everything happens here, in one inlined call per kernel: a loop of the kernel before the call makes numba
    keep the reference counting of the kernel's array arguments (an NRT call each, every evaluation)."""
    n = int(p[P_NODES])
    # the outward pass, written here rather than as a function of its own: inlined, a separate pass makes
    # numba keep the reference counting of the array arguments
    for d in range(n):
        r = HEADER + d * NODE_SIZE
        k = d * WORK
        parent = int(p[r + N_PARENT])
        if parent >= 0:
            o = parent * WORK
            angle, cp, sp = w[o + W_ANGLE], w[o + W_COS], w[o + W_SIN]
            tx, ty = w[o + W_T], w[o + W_T + 1]
            vw, vx, vy = w[o + W_V], w[o + W_V + 1], w[o + W_V + 2]
        else:
            angle, cp, sp, tx, ty, vw, vx, vy = 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        x = y[d] - p[r + N_REF]
        qd = y[v0 + d] if v0 >= 0 else 0.0
        if a0 > 0:
            out[d] = qd
        kind = int(p[r + N_KIND])
        px, py = p[r + N_POINT], p[r + N_POINT + 1]
        extra_x, extra_y = 0.0, 0.0
        radius, lx, ly = 0.0, 0.0, 0.0
        if kind == PLANAR_SLIDE:
            sw = 0.0
            sx = cp * px - sp * py
            sy = sp * px + cp * py
            tx += sx * x
            ty += sy * x
            c, s_ = cp, sp
        else:
            sign = p[r + N_SIGN]
            # the anchor (roll: the centre, after the slide r x along l), moved by the parent's displacement
            if kind == PLANAR_ROLL:
                radius = p[r + N_RADIUS]
                lx = cp * p[r + N_LINE] - sp * p[r + N_LINE + 1]
                ly = sp * p[r + N_LINE] + cp * p[r + N_LINE + 1]
                ax = cp * px - sp * py + tx + radius * x * lx
                ay = sp * px + cp * py + ty + radius * x * ly
            else:
                ax = cp * px - sp * py + tx
                ay = sp * px + cp * py + ty
            angle += sign * x
            if abs(angle) < REDUCED_RANGE:  # a polynomial, no call (rbody.engine.spatial.sin_cos)
                s_, c = sin_cos(angle)
            else:
                c, s_ = np.cos(angle), np.sin(angle)
            tx = ax - (c * px - s_ * py)
            ty = ay - (s_ * px + c * py)
            sw, sx, sy = sign, sign * ay, -sign * ax
            if kind == PLANAR_ROLL:
                sx += radius * lx
                sy += radius * ly
                extra_x, extra_y = sign * radius * ly * qd * qd, -sign * radius * lx * qd * qd
        w[k + W_ANGLE], w[k + W_COS], w[k + W_SIN] = angle, c, s_
        w[k + W_T], w[k + W_T + 1] = tx, ty
        w[k + W_S], w[k + W_S + 1], w[k + W_S + 2] = sw, sx, sy
        # c = (v_parent x S) q' (+ the roll's own term)
        w[k + W_C] = 0.0
        w[k + W_C + 1] = (sw * vy - vw * sy) * qd + extra_x
        w[k + W_C + 2] = (vw * sx - sw * vx) * qd + extra_y
        vw += sw * qd
        vx += sx * qd
        vy += sy * qd
        w[k + W_V], w[k + W_V + 1], w[k + W_V + 2] = vw, vx, vy
        # rigid inertia about the origin at the current pose
        m = p[r + N_MASS]
        cx0, cy0 = p[r + N_COM], p[r + N_COM + 1]
        comx = c * cx0 - s_ * cy0 + tx
        comy = s_ * cx0 + c * cy0 + ty
        hx, hy = m * comx, m * comy
        inertia = p[r + N_MOMENT] + hx * comx + hy * comy
        w[k + W_I], w[k + W_I + 1], w[k + W_I + 2] = inertia, -hy, hx
        w[k + W_I + 3], w[k + W_I + 4], w[k + W_I + 5] = m, 0.0, m
        # I v (its in-plane force part: the moment does not enter v x* (I v)), then v x* (I v)
        fx = m * vx - hy * vw
        fy = m * vy + hx * vw
        w[k + W_P] = vx * fy - vy * fx
        w[k + W_P + 1] = -vw * fy
        w[k + W_P + 2] = vw * fx
    if outward_only:
        return -1
    bad = -1
    for d in range(n - 1, -1, -1):
        r = HEADER + d * NODE_SIZE
        k = d * WORK
        sw, sx, sy = w[k + W_S], w[k + W_S + 1], w[k + W_S + 2]
        i00, i01, i02 = w[k + W_I], w[k + W_I + 1], w[k + W_I + 2]
        i11, i12, i22 = w[k + W_I + 3], w[k + W_I + 4], w[k + W_I + 5]
        u0 = i00 * sw + i01 * sx + i02 * sy
        u1 = i01 * sw + i11 * sx + i12 * sy
        u2 = i02 * sw + i12 * sx + i22 * sy
        armature = p[r + N_ARMATURE]
        sIs = sw * u0 + sx * u1 + sy * u2
        D = sIs + armature
        scale = max(abs(sIs) + armature, abs(i00) * sw * sw, abs(i11) * sx * sx, abs(i22) * sy * sy)
        if not D > PIVOT_RTOL * scale or not D > 0.0:
            if bad < 0:
                bad = d
            D = np.inf
        qd = y[v0 + d] if v0 >= 0 else 0.0
        force = -p[r + N_DAMPING] * qd - p[r + N_STIFF] * (y[d] - p[r + N_SPRINGREF])
        if applied:
            force += w[k + W_TAU]
        u = force - (sw * w[k + W_P] + sx * w[k + W_P + 1] + sy * w[k + W_P + 2])
        inv = 1.0 / D
        w[k + W_U], w[k + W_U + 1], w[k + W_U + 2] = u0, u1, u2
        w[k + W_DINV], w[k + W_SMALL_U] = inv, u
        parent = int(p[r + N_PARENT])
        if parent < 0:
            continue
        # Ia = I - U U^T / D; pa = pA + Ia c + U u / D, added to the parent's
        i00 -= u0 * u0 * inv
        i01 -= u0 * u1 * inv
        i02 -= u0 * u2 * inv
        i11 -= u1 * u1 * inv
        i12 -= u1 * u2 * inv
        i22 -= u2 * u2 * inv
        c0, c1, c2 = w[k + W_C], w[k + W_C + 1], w[k + W_C + 2]
        ui = u * inv
        o = parent * WORK
        w[o + W_P] += w[k + W_P] + i00 * c0 + i01 * c1 + i02 * c2 + u0 * ui
        w[o + W_P + 1] += w[k + W_P + 1] + i01 * c0 + i11 * c1 + i12 * c2 + u1 * ui
        w[o + W_P + 2] += w[k + W_P + 2] + i02 * c0 + i12 * c1 + i22 * c2 + u2 * ui
        w[o + W_I] += i00
        w[o + W_I + 1] += i01
        w[o + W_I + 2] += i02
        w[o + W_I + 3] += i11
        w[o + W_I + 4] += i12
        w[o + W_I + 5] += i22
    for d in range(n):
        r = HEADER + d * NODE_SIZE
        k = d * WORK
        parent = int(p[r + N_PARENT])
        if parent >= 0:
            o = parent * WORK
            a0_, a1, a2 = w[o + W_A], w[o + W_A + 1], w[o + W_A + 2]
        else:
            a0_, a1, a2 = 0.0, p[P_GX], p[P_GY]  # gravity: the world accelerates upwards
        a0_ += w[k + W_C]
        a1 += w[k + W_C + 1]
        a2 += w[k + W_C + 2]
        qdd = (w[k + W_SMALL_U] - (w[k + W_U] * a0_ + w[k + W_U + 1] * a1 + w[k + W_U + 2] * a2)) * w[k + W_DINV]
        if d == bad:
            qdd = np.nan
        out[a0 + d] = qdd
        w[k + W_A] = a0_ + w[k + W_S] * qdd
        w[k + W_A + 1] = a1 + w[k + W_S + 1] * qdd
        w[k + W_A + 2] = a2 + w[k + W_S + 2] * qdd
    return bad


@njit(cache=True, error_model="numpy")
def planar_rhs(y, p, out):
    """y' = (qvel, qacc) for y = (qpos (n), qvel (n)) of a planar tree; p its planar row. A singular mass
    matrix gives NaN (the run fails). Every array is read through a raw pointer (rbody.engine.memory.address):
    numba's indexing would check each index for a negative value."""
    n = int(p[P_NODES])
    _articulated(address(p, 0), address(y, 0), n, address(out, 0), n, stack_floats(n * WORK), False)


@njit(cache=True, error_model="numpy")
def planar_accel(q, p, out):
    """q'' = a(q) (the tree at rest at q: the symplectic methods, where TreeScene.symplectic_applies)."""
    n = int(p[P_NODES])
    _articulated(address(p, 0), address(q, 0), -1, address(out, 0), 0, stack_floats(n * WORK), False)


# ----- the same algorithm on LANES states side by side -------------------------------------------------------
# A batch of one tree (one planar row) is stepped LANES elements at a time: their states held as structure of
# arrays (Y[k * LANES + l] is entry k of element l), every quantity of the algorithm one vector of LANES numbers
# (rbody.engine.simd), so that one instruction advances all of them. Each lane does exactly the operations of
# _articulated on one element (plain IEEE arithmetic in both, no fused multiply-add): a batch stepped in lanes
# has the bits of its elements stepped one by one (tests/rbody/engine/test_planar.py checks it).

LANES = WIDTH


@njit(cache=True, inline="always")
def _lane_sin_cos(angle):
    """(sin, cos) of every lane as _articulated forms them: the polynomial, or np.sin and np.cos beyond its range."""
    if largest_abs(angle) < REDUCED_RANGE:
        return sin_cos_lanes(angle)
    s = [0.0] * LANES
    c = [0.0] * LANES
    for l in range(LANES):
        x = lane(angle, l)
        if abs(x) < REDUCED_RANGE:
            s[l], c[l] = sin_cos(x)
        else:
            c[l], s[l] = np.cos(x), np.sin(x)
    return lanes(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7]), lanes(c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7])


@njit(cache=True, inline="always")
def _articulated_lanes(p, y, v0, out, a0, w):
    """_articulated (no applied forces, not outward_only) for LANES states: y, out structures of arrays (entry k of
    lane l at k * LANES + l), w the workspace (quantity q of node d at (d * WORK + q) * LANES); qvel from
    y[v0 * LANES:], v0 < 0 at rest; a0 > 0 copies qvel into out first. A lane whose pivot is not positive gets NaN
    at its first such node, as _articulated gives it."""
    n = int(p[P_NODES])
    L = LANES
    zero = splat(0.0)
    for d in range(n):
        r = HEADER + d * NODE_SIZE
        k = d * WORK * L
        parent = int(p[r + N_PARENT])
        if parent >= 0:
            o = parent * WORK * L
            angle, cp, sp = load(w, o + W_ANGLE * L), load(w, o + W_COS * L), load(w, o + W_SIN * L)
            tx, ty = load(w, o + W_T * L), load(w, o + (W_T + 1) * L)
            vw, vx, vy = load(w, o + W_V * L), load(w, o + (W_V + 1) * L), load(w, o + (W_V + 2) * L)
        else:
            angle, cp, sp, tx, ty, vw, vx, vy = zero, splat(1.0), zero, zero, zero, zero, zero, zero
        x = load(y, d * L) - p[r + N_REF]
        qd = load(y, (v0 + d) * L) if v0 >= 0 else zero
        if a0 > 0:
            store(out, d * L, qd)
        kind = int(p[r + N_KIND])
        px, py = p[r + N_POINT], p[r + N_POINT + 1]
        extra_x, extra_y = zero, zero
        radius, lx, ly = 0.0, zero, zero
        if kind == PLANAR_SLIDE:
            sw = 0.0
            sx = cp * px - sp * py
            sy = sp * px + cp * py
            tx = tx + sx * x
            ty = ty + sy * x
            c, s_ = cp, sp
        else:
            sign = p[r + N_SIGN]
            if kind == PLANAR_ROLL:
                radius = p[r + N_RADIUS]
                lx = cp * p[r + N_LINE] - sp * p[r + N_LINE + 1]
                ly = sp * p[r + N_LINE] + cp * p[r + N_LINE + 1]
                ax = cp * px - sp * py + tx + radius * x * lx
                ay = sp * px + cp * py + ty + radius * x * ly
            else:
                ax = cp * px - sp * py + tx
                ay = sp * px + cp * py + ty
            angle = angle + sign * x
            s_, c = _lane_sin_cos(angle)
            tx = ax - (c * px - s_ * py)
            ty = ay - (s_ * px + c * py)
            sw, sx, sy = sign, sign * ay, -sign * ax
            if kind == PLANAR_ROLL:
                sx = sx + radius * lx
                sy = sy + radius * ly
                extra_x, extra_y = sign * radius * ly * qd * qd, -sign * radius * lx * qd * qd
        store(w, k + W_ANGLE * L, angle)
        store(w, k + W_COS * L, c)
        store(w, k + W_SIN * L, s_)
        store(w, k + W_T * L, tx)
        store(w, k + (W_T + 1) * L, ty)
        store(w, k + W_S * L, splat(sw))
        store(w, k + (W_S + 1) * L, sx)
        store(w, k + (W_S + 2) * L, sy)
        store(w, k + W_C * L, zero)
        store(w, k + (W_C + 1) * L, (sw * vy - vw * sy) * qd + extra_x)
        store(w, k + (W_C + 2) * L, (vw * sx - sw * vx) * qd + extra_y)
        vw = vw + sw * qd
        vx = vx + sx * qd
        vy = vy + sy * qd
        store(w, k + W_V * L, vw)
        store(w, k + (W_V + 1) * L, vx)
        store(w, k + (W_V + 2) * L, vy)
        m = p[r + N_MASS]
        cx0, cy0 = p[r + N_COM], p[r + N_COM + 1]
        comx = c * cx0 - s_ * cy0 + tx
        comy = s_ * cx0 + c * cy0 + ty
        hx, hy = m * comx, m * comy
        inertia = p[r + N_MOMENT] + hx * comx + hy * comy
        store(w, k + W_I * L, inertia)
        store(w, k + (W_I + 1) * L, -hy)
        store(w, k + (W_I + 2) * L, hx)
        store(w, k + (W_I + 3) * L, splat(m))
        store(w, k + (W_I + 4) * L, zero)
        store(w, k + (W_I + 5) * L, splat(m))
        fx = m * vx - hy * vw
        fy = m * vy + hx * vw
        store(w, k + W_P * L, vx * fy - vy * fx)
        store(w, k + (W_P + 1) * L, -vw * fy)
        store(w, k + (W_P + 2) * L, vw * fx)
    bad = splat(-1.0)  # each lane's first node (in the inward sweep) whose pivot is not positive, or -1
    for d in range(n - 1, -1, -1):
        r = HEADER + d * NODE_SIZE
        k = d * WORK * L
        sw, sx, sy = load(w, k + W_S * L), load(w, k + (W_S + 1) * L), load(w, k + (W_S + 2) * L)
        i00, i01, i02 = load(w, k + W_I * L), load(w, k + (W_I + 1) * L), load(w, k + (W_I + 2) * L)
        i11, i12, i22 = load(w, k + (W_I + 3) * L), load(w, k + (W_I + 4) * L), load(w, k + (W_I + 5) * L)
        u0 = i00 * sw + i01 * sx + i02 * sy
        u1 = i01 * sw + i11 * sx + i12 * sy
        u2 = i02 * sw + i12 * sx + i22 * sy
        armature = p[r + N_ARMATURE]
        sIs = sw * u0 + sx * u1 + sy * u2
        D = sIs + armature
        scale = maximum(maximum(maximum(abs(sIs) + armature, abs(i00) * sw * sw), abs(i11) * sx * sx),
                        abs(i22) * sy * sy)
        good = greater(D, PIVOT_RTOL * scale) * greater(D, 0.0)
        bad = where(good, bad, where(greater(zero, bad), float(d), bad))
        D = where(good, D, np.inf)
        qd = load(y, (v0 + d) * L) if v0 >= 0 else zero
        force = -p[r + N_DAMPING] * qd - p[r + N_STIFF] * (load(y, d * L) - p[r + N_SPRINGREF])
        u = force - (sw * load(w, k + W_P * L) + sx * load(w, k + (W_P + 1) * L) + sy * load(w, k + (W_P + 2) * L))
        inv = 1.0 / D
        store(w, k + W_U * L, u0)
        store(w, k + (W_U + 1) * L, u1)
        store(w, k + (W_U + 2) * L, u2)
        store(w, k + W_DINV * L, inv)
        store(w, k + W_SMALL_U * L, u)
        parent = int(p[r + N_PARENT])
        if parent < 0:
            continue
        i00 = i00 - u0 * u0 * inv
        i01 = i01 - u0 * u1 * inv
        i02 = i02 - u0 * u2 * inv
        i11 = i11 - u1 * u1 * inv
        i12 = i12 - u1 * u2 * inv
        i22 = i22 - u2 * u2 * inv
        c0, c1, c2 = load(w, k + W_C * L), load(w, k + (W_C + 1) * L), load(w, k + (W_C + 2) * L)
        ui = u * inv
        o = parent * WORK * L
        store(w, o + W_P * L, load(w, o + W_P * L) + (load(w, k + W_P * L) + i00 * c0 + i01 * c1 + i02 * c2 + u0 * ui))
        store(w, o + (W_P + 1) * L, load(w, o + (W_P + 1) * L) + (load(w, k + (W_P + 1) * L) + i01 * c0 + i11 * c1
                                                                  + i12 * c2 + u1 * ui))
        store(w, o + (W_P + 2) * L, load(w, o + (W_P + 2) * L) + (load(w, k + (W_P + 2) * L) + i02 * c0 + i12 * c1
                                                                  + i22 * c2 + u2 * ui))
        store(w, o + W_I * L, load(w, o + W_I * L) + i00)
        store(w, o + (W_I + 1) * L, load(w, o + (W_I + 1) * L) + i01)
        store(w, o + (W_I + 2) * L, load(w, o + (W_I + 2) * L) + i02)
        store(w, o + (W_I + 3) * L, load(w, o + (W_I + 3) * L) + i11)
        store(w, o + (W_I + 4) * L, load(w, o + (W_I + 4) * L) + i12)
        store(w, o + (W_I + 5) * L, load(w, o + (W_I + 5) * L) + i22)
    for d in range(n):
        r = HEADER + d * NODE_SIZE
        k = d * WORK * L
        parent = int(p[r + N_PARENT])
        if parent >= 0:
            o = parent * WORK * L
            b0, b1, b2 = load(w, o + W_A * L), load(w, o + (W_A + 1) * L), load(w, o + (W_A + 2) * L)
        else:
            b0, b1, b2 = zero, splat(p[P_GX]), splat(p[P_GY])
        b0 = b0 + load(w, k + W_C * L)
        b1 = b1 + load(w, k + (W_C + 1) * L)
        b2 = b2 + load(w, k + (W_C + 2) * L)
        qdd = (load(w, k + W_SMALL_U * L) - (load(w, k + W_U * L) * b0 + load(w, k + (W_U + 1) * L) * b1
                                              + load(w, k + (W_U + 2) * L) * b2)) * load(w, k + W_DINV * L)
        qdd = where(greater(bad, float(d) - 0.5) * greater(float(d) + 0.5, bad), np.nan, qdd)
        store(out, (a0 + d) * L, qdd)
        store(w, k + W_A * L, b0 + load(w, k + W_S * L) * qdd)
        store(w, k + (W_A + 1) * L, b1 + load(w, k + (W_S + 1) * L) * qdd)
        store(w, k + (W_A + 2) * L, b2 + load(w, k + (W_S + 2) * L) * qdd)


@njit(cache=True, error_model="numpy")
def planar_rhs_lanes(y, p, out):
    """planar_rhs for LANES states side by side: y and out (2 n LANES,) structures of arrays (entry k of lane l at
    k * LANES + l), p the planar row (one tree for every lane)."""
    n = int(p[P_NODES])
    _articulated_lanes(address(p, 0), address(y, 0), n, address(out, 0), n, stack_floats(n * WORK * LANES))


@njit(cache=True, error_model="numpy")
def planar_accel_lanes(q, p, out):
    """planar_accel for LANES states side by side (q, out (n LANES,) structures of arrays)."""
    n = int(p[P_NODES])
    _articulated_lanes(address(p, 0), address(q, 0), -1, address(out, 0), 0, stack_floats(n * WORK * LANES))


# ----- the kernels as C function pointers, kept in numba's disk cache (rbody.engine.pointers) --------------

def _rhs_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def planar_rhs_c(y, p, out, n, m):
        planar_rhs(carray(y, n), carray(p, m), carray(out, n))
    return planar_rhs_c


def _accel_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def planar_accel_c(q, p, out, n, m):
        planar_accel(carray(q, n), carray(p, m), carray(out, n))
    return planar_accel_c


def _rhs_lanes_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def planar_rhs_lanes_c(y, p, out, n, m):
        planar_rhs_lanes(carray(y, n * LANES), carray(p, m), carray(out, n * LANES))
    return planar_rhs_lanes_c


pointers.register(planar_rhs, "rhs", _rhs_pointer)
pointers.register(planar_accel, "rhs", _accel_pointer)
pointers.register(planar_rhs_lanes, "lanes", _rhs_lanes_pointer)


@njit(cache=True)
def _inverse(p, q, v, qacc, gravity_on, out, w):
    """RNEA: out (n,) = M qacc + bias (gravity when gravity_on); passive forces not included."""
    n = int(p[P_NODES])
    y = np.empty(2 * n)
    for d in range(n):
        y[d] = q[d]
        y[n + d] = v[d]
    _articulated(p, y, n, out, 0, w, False, True)
    for d in range(n):
        r = HEADER + d * NODE_SIZE
        k = d * WORK
        parent = int(p[r + N_PARENT])
        if parent >= 0:
            o = parent * WORK
            a0_, a1, a2 = w[o + W_A], w[o + W_A + 1], w[o + W_A + 2]
        elif gravity_on:
            a0_, a1, a2 = 0.0, p[P_GX], p[P_GY]
        else:
            a0_, a1, a2 = 0.0, 0.0, 0.0
        a0_ += w[k + W_C] + w[k + W_S] * qacc[d]
        a1 += w[k + W_C + 1] + w[k + W_S + 1] * qacc[d]
        a2 += w[k + W_C + 2] + w[k + W_S + 2] * qacc[d]
        w[k + W_A], w[k + W_A + 1], w[k + W_A + 2] = a0_, a1, a2
        # f = I a + v x* I v, kept in W_P
        w[k + W_P] += w[k + W_I] * a0_ + w[k + W_I + 1] * a1 + w[k + W_I + 2] * a2
        w[k + W_P + 1] += w[k + W_I + 1] * a0_ + w[k + W_I + 3] * a1 + w[k + W_I + 4] * a2
        w[k + W_P + 2] += w[k + W_I + 2] * a0_ + w[k + W_I + 4] * a1 + w[k + W_I + 5] * a2
    for d in range(n - 1, -1, -1):
        r = HEADER + d * NODE_SIZE
        k = d * WORK
        out[d] = (w[k + W_S] * w[k + W_P] + w[k + W_S + 1] * w[k + W_P + 1] + w[k + W_S + 2] * w[k + W_P + 2]
                  + p[r + N_ARMATURE] * qacc[d])
        parent = int(p[r + N_PARENT])
        if parent >= 0:
            o = parent * WORK
            for a in range(3):
                w[o + W_P + a] += w[k + W_P + a]


@njit(cache=True)
def _forward_batch(p, Q, V, T, out):
    n = int(p[P_NODES])
    w = np.empty(n * WORK)
    y = np.empty(2 * n)
    bad = np.empty(Q.shape[0], dtype=np.int64)
    for b in range(Q.shape[0]):
        for d in range(n):
            y[d], y[n + d] = Q[b, d], V[b, d]
            w[d * WORK + W_TAU] = T[b, d]
        bad[b] = _articulated(p, y, n, out[b], 0, w, True)
    return bad


@njit(cache=True)
def _bias_batch(p, Q, V, out):
    n = int(p[P_NODES])
    w = np.empty(n * WORK)
    zero = np.zeros(n)
    for b in range(Q.shape[0]):
        _inverse(p, Q[b], V[b], zero, True, out[b], w)


@njit(cache=True)
def _mass_matrix_batch(p, Q, out):
    """M by columns: M e_k = RNEA at rest, gravity off, qacc = e_k."""
    n = int(p[P_NODES])
    w = np.empty(n * WORK)
    zero = np.zeros(n)
    unit = np.zeros(n)
    column = np.empty(n)
    for b in range(Q.shape[0]):
        for j in range(n):
            unit[j] = 1.0
            _inverse(p, Q[b], zero, unit, False, column, w)
            unit[j] = 0.0
            for i in range(n):
                out[b, i, j] = column[i]


# ----- the model, from the 3-D engine's row ----------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class PlanarModel:
    """A planar tree's model for the planar kernels (module docstring).

    row: (p,) the planar row (read-only); normal: (3,) unit n, world frame; basis: (3, 2) columns e1, e2
    (world frame) of the plane coordinates; nv: degrees of freedom (= nq).
    Methods take q (..., nv), v (..., nv) in the 3-D engine's (MuJoCo's) coordinates and return the same
    quantities as rbody.Multibody's methods of the same names.
    """

    row: np.ndarray
    normal: np.ndarray
    basis: np.ndarray
    nv: int
    multibody: mb.Multibody

    def _flat(self, *arrays):
        return self.multibody._batch(*((a, self.nv, name) for a, name in arrays))

    def mass_matrix(self, q) -> np.ndarray:
        """M (..., nv, nv) at q, armature on the diagonal."""
        shape, (Q,) = self._flat((q, "q"))
        out = np.empty((Q.shape[0], self.nv, self.nv))
        _mass_matrix_batch(self.row, Q, out)
        return out.reshape(shape + (self.nv, self.nv))

    def bias_forces(self, q, v) -> np.ndarray:
        """(..., nv) gravity, Coriolis and centrifugal generalised forces (MuJoCo's qfrc_bias)."""
        shape, (Q, V) = self._flat((q, "q"), (v, "v"))
        out = np.empty((Q.shape[0], self.nv))
        _bias_batch(self.row, Q, V, out)
        return out.reshape(shape + (self.nv,))

    def forward_dynamics(self, q, v, tau=None) -> np.ndarray:
        """qacc (..., nv) = M^-1 (tau + passive - bias) by the planar ABA; NaN where M is singular."""
        tau = np.zeros(self.nv) if tau is None else tau
        shape, (Q, V, T) = self._flat((q, "q"), (v, "v"), (tau, "tau"))
        out = np.empty((Q.shape[0], self.nv))
        _forward_batch(self.row, Q, V, T, out)
        return out.reshape(shape + (self.nv,))


def _rotations(row: np.ndarray, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """Position (nb, 3) relative to the origin of its tree (its root body's placement in the world) and world
    rotation (nb, 3, 3) of every body frame at the reference pose (all q = ref). Each tree is written about its
    own origin, as in the 3-D engine (rbody.engine.multibody, "Precision"): far from the world origin the nodes
    keep every digit."""
    from rbody.motion import quat_to_matrix

    bo = int(row[mb.H_BODY])
    pos, rot = np.zeros((nb, 3)), np.zeros((nb, 3, 3))
    for i in range(nb):
        b = bo + i * mb.BODY_SIZE
        parent = int(row[b + mb.B_PARENT])
        local = quat_to_matrix(row[b + mb.B_QUAT:b + mb.B_QUAT + 4])
        offset = row[b + mb.B_POS:b + mb.B_POS + 3]
        if parent >= 0:
            pos[i] = pos[parent] + rot[parent] @ offset
            rot[i] = rot[parent] @ local
        else:
            pos[i], rot[i] = 0.0, local
    return pos, rot


def _plane_basis(normal: np.ndarray) -> np.ndarray:
    """(3, 2) e1, e2 with (e1, e2, n) right-handed; e2 the in-plane part of z where n is not vertical."""
    up = np.array([0.0, 0.0, 1.0])
    e2 = up - normal * float(normal @ up)
    if np.linalg.norm(e2) < 1e-6:  # n vertical: any in-plane pair
        e2 = np.array([0.0, 1.0, 0.0]) - normal * normal[1]
    e2 /= np.linalg.norm(e2)
    e1 = np.cross(e2, normal)
    return np.column_stack([e1, e2])


def planar_structure(multibody: mb.Multibody) -> tuple[PlanarModel | None, str]:
    """(the planar model of the tree, "") when it is planar, else (None, why not). Decided from the structure
    at the reference pose: hinge, slide and roll joints only; every hinge and roll axis parallel to one unit n
    (world frame; rotations about n keep it so at every q); every slide perpendicular to n; welded bodies
    allowed. A tree of slides only is planar when its directions span at most a plane."""
    row = np.asarray(multibody.params)
    nb, nj, nv = int(row[mb.H_BODIES]), int(row[mb.H_JOINTS]), int(row[mb.H_DOFS])
    jo, do, bo = int(row[mb.H_JOINT]), int(row[mb.H_DOF]), int(row[mb.H_BODY])
    kinds = PLANAR_KINDS
    names = multibody.joint_names
    if nv == 0:
        return None, "the tree has no degree of freedom"
    pos, rot = _rotations(row, nb)
    axes, points, lines = {}, {}, {}
    for j in range(nj):
        r = jo + j * mb.JOINT_SIZE
        code = int(row[r + mb.J_KIND])
        if code not in kinds:
            kind = multibody.arrays.joint_kinds[j]
            return None, f"joint {names[j]!r} is a {kind} joint (planar trees have hinge, slide and roll joints only)"
        body = int(row[r + mb.J_BODY])
        axes[j] = rot[body] @ row[r + mb.J_AXIS:r + mb.J_AXIS + 3]
        points[j] = pos[body] + rot[body] @ row[r + mb.J_ANCHOR:r + mb.J_ANCHOR + 3]
        if kinds[code] == PLANAR_ROLL:
            lines[j] = rot[body] @ row[r + mb.J_LINE:r + mb.J_LINE + 3]
    turning = [j for j in range(nj) if kinds[int(row[jo + j * mb.JOINT_SIZE + mb.J_KIND])] != PLANAR_SLIDE]
    sliding = [j for j in range(nj) if j not in turning]
    if turning:
        normal = axes[turning[0]] / np.linalg.norm(axes[turning[0]])
        for j in turning[1:]:
            if np.linalg.norm(np.cross(axes[j], normal)) > PARALLEL_TOL:
                return None, (f"the axes of joints {names[turning[0]]!r} and {names[j]!r} are not parallel "
                              f"(world {np.round(normal, 6).tolist()} and {np.round(axes[j], 6).tolist()})")
        for j in sliding:
            if abs(float(axes[j] @ normal)) > PARALLEL_TOL:
                return None, (f"slide {names[j]!r} (world direction {np.round(axes[j], 6).tolist()}) is not "
                              f"perpendicular to the hinge axes {np.round(normal, 6).tolist()}")
    else:
        directions = np.array([axes[j] for j in sliding])
        _, sigma, vt = np.linalg.svd(directions)
        if directions.shape[0] >= 3 and sigma[2] > PARALLEL_TOL:
            return None, "the slides' directions span all of space (no plane holds them)"
        if directions.shape[0] >= 2 and sigma[1] > PARALLEL_TOL:
            normal = vt[2] if vt.shape[0] > 2 else np.cross(directions[0], directions[1])
        else:  # one direction: the plane through it and z (or any, when it is vertical)
            d = directions[0] / np.linalg.norm(directions[0])
            normal = np.cross(d, [0.0, 0.0, 1.0])
            if np.linalg.norm(normal) < 1e-6:
                normal = np.cross(d, [1.0, 0.0, 0.0])
        normal = normal / np.linalg.norm(normal)
    basis = _plane_basis(normal)

    # nodes: one per degree of freedom, the 3-D engine's order and parents
    planar = np.zeros(HEADER + nv * NODE_SIZE)
    planar[P_NODES] = nv
    planar[P_GX:P_GY + 1] = basis.T @ np.array([0.0, 0.0, multibody.gravity])
    carried: dict[int, list[int]] = {d: [] for d in range(nv)}  # node -> bodies whose inertia it carries
    last = {}
    for i in range(nb):
        b = bo + i * mb.BODY_SIZE
        parent = int(row[b + mb.B_PARENT])
        d0, nd = int(row[b + mb.B_DOF0]), int(row[b + mb.B_NDOF])
        last[i] = d0 + nd - 1 if nd else (last[parent] if parent >= 0 else -1)
        if last[i] >= 0:
            carried[last[i]].append(i)
    for j in range(nj):
        r = jo + j * mb.JOINT_SIZE
        code = kinds[int(row[r + mb.J_KIND])]
        d = int(row[r + mb.J_DADR])
        o = do + d * mb.DOF_SIZE
        n_ = HEADER + d * NODE_SIZE
        planar[n_ + N_PARENT] = row[o + mb.D_PARENT]
        planar[n_ + N_KIND] = code
        if code == PLANAR_SLIDE:
            planar[n_ + N_POINT:n_ + N_POINT + 2] = basis.T @ axes[j]
        else:
            planar[n_ + N_SIGN] = 1.0 if float(axes[j] @ normal) > 0 else -1.0
            planar[n_ + N_POINT:n_ + N_POINT + 2] = basis.T @ points[j]
        if code == PLANAR_ROLL:
            planar[n_ + N_RADIUS] = row[r + mb.J_RADIUS]
            planar[n_ + N_LINE:n_ + N_LINE + 2] = basis.T @ lines[j]
        planar[n_ + N_REF] = row[r + mb.J_REF]
        planar[n_ + N_STIFF] = row[r + mb.J_STIFF]
        planar[n_ + N_SPRINGREF] = row[r + mb.J_SPRINGREF]
        planar[n_ + N_DAMPING] = row[o + mb.D_DAMPING]
        planar[n_ + N_ARMATURE] = row[o + mb.D_ARMATURE]
        # the merged inertia of the bodies the node carries: mass, com and I_n, at the reference pose
        masses, coms, moments = [], [], []
        for i in carried[d]:
            b = bo + i * mb.BODY_SIZE
            tensor = rot[i] @ row[b + mb.B_TENSOR:b + mb.B_TENSOR + 9].reshape(3, 3) @ rot[i].T
            masses.append(row[b + mb.B_MASS])
            coms.append(basis.T @ (pos[i] + rot[i] @ row[b + mb.B_COM:b + mb.B_COM + 3]))
            moments.append(float(normal @ tensor @ normal))
        mass = float(np.sum(masses)) if masses else 0.0
        if mass > 0:
            com = np.sum([m * c for m, c in zip(masses, coms)], axis=0) / mass
            moment = sum(I + m * float((c - com) @ (c - com)) for m, c, I in zip(masses, coms, moments))
        else:
            com, moment = np.zeros(2), float(np.sum(moments)) if moments else 0.0
        planar[n_ + N_MASS] = mass
        planar[n_ + N_COM:n_ + N_COM + 2] = com
        planar[n_ + N_MOMENT] = moment
    PLANAR_HEADER.check(planar, 0, 1)
    NODE.check(planar, HEADER, nv)
    planar.setflags(write=False)
    return PlanarModel(row=planar, normal=normal, basis=basis, nv=nv, multibody=multibody), ""


def planar_model(multibody: mb.Multibody) -> PlanarModel | None:
    """The planar model of the tree, or None when it is not planar (planar_structure gives the reason)."""
    return planar_structure(multibody)[0]
