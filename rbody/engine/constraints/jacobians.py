"""Each constraint unit's rows at a state: residual g, Jacobian J (dg/dt = J v) and J' v, compiled.

All quantities are in the world frame, from the tree's workspace (rbody.engine.multibody) after its kinematics,
motion subspaces and velocities at (q, v):

- a body point p = x + R a moves with v_p = sum over the dofs d above the body of (S_d,lin + S_d,ang x p) v_d
  (S_d the dof's spatial motion about the origin of its tree, xorigin), so a column of J_p is S_d,lin + S_d,ang x p;
- with every qacc = 0 the bodies still accelerate: their spatial accelerations acc_i = acc_parent + sum S_d' v_d
  (the tree's bias terms, gravity left out), and a body point's classical acceleration is then
  a_p = a_O + alpha x p + omega x v_p: that is J_p' v (the terms of d(J_p v)/dt that do not multiply qacc);
- a ball's rotation angle theta = 2 atan2(|vec|, |w|) about the unit axis u turns at theta' = u . omega (omega its
  body-frame angular velocity, the ball's qvel; u is the same in the body and the parent frame), and with
  omega' = 0, theta'' = (|omega|^2 - theta'^2) cot(theta / 2) / 2 (from the inverse right Jacobian of SO(3));
- a weld's orientation error E = q1 qrel q2^-1 (world frame, identity when held) turns at omega1 - omega2, so its
  rows are J_omega1 - J_omega2, J' v = alpha1 - alpha2, and its residual is E's rotation vector;
- a joint coupling's residual (q1 - ref1) - P(d), d = q2 - ref2, has J = e1 - P'(d) e2 and J' v = -P''(d) v2^2;
- a tendon's rows (its limits, its dry friction) are its length's: J = +-dL/dq and J' v = +-L'' without qacc
  (rbody.engine.constraints.tendon_rows); a tendon equality (L1 - L1_0) - P(d), d = L2 - L2_0, has
  J = J1 - P'(d) J2 and J' v = J1' v - P'(d) J2' v - P''(d) (J2 v)^2.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.elements import block_offset
from rbody.engine.multibody import (B_DOF0, B_NDOF, B_PARENT, BODY_SIZE, H_BODIES, H_BODY, _views)
from rbody.engine.contacts.geometry import tangents
from rbody.engine.contacts.broadphase import contact0, pair_at, pair_count, pair_span
from rbody.engine.contacts.rows import contact_geometry
from rbody.engine.contacts.kinematics import contact_bias
from rbody.engine.constraints.tendon_rows import tendon_row
from rbody.engine.constraints.kinds import is_dof_kind
from rbody.engine.constraints.table import (C_MODE, C_ROWS, C_UNIT, C_UNITS, CONE, CONTACT, CONTACT1, COUPLING,
                                            FRICTION,
                                            LOWER, TENDON_EQUALITY, TENDON_FRICTION, TENDON_LOWER, TENDON_UPPER,
                                            U_A1, U_A2, U_BOUND, U_BODY1, U_BODY2, U_DOF, U_DOF2, U_KIND,
                                            U_POLY, U_QADR, U_QADR2, U_QUAT, U_REF1, U_REF2, U_ROW0, U_ROWS,
                                            U_TENDON, U_TENDON2, UNIT_SIZE, UPPER, WELD)


@njit(cache=True, inline="always")
def unit_count(p):
    return int(p[block_offset(p) + C_UNITS])


@njit(cache=True, inline="always")
def row_count(p):
    return int(p[block_offset(p) + C_ROWS])


@njit(cache=True, inline="always")
def unit_at(p, k):
    """Offset of unit k's record in the params row."""
    return int(p[block_offset(p) + C_UNIT]) + k * UNIT_SIZE


@njit(cache=True, inline="always")
def mode_at(p):
    """Offset of the mode array (one float per unit) in the params row."""
    return int(p[block_offset(p) + C_MODE])


@njit(cache=True)
def bias_accelerations(p, w, acc):
    """acc (nb, 6): each body's spatial acceleration (world axes, about the origin) with every qacc = 0 and no
    gravity, from the workspace's bias terms S' v (after the tree's velocities)."""
    ws = _views(p, w)
    bias = ws.bias
    nb = int(p[H_BODIES])
    bo = int(p[H_BODY])
    for i in range(nb):
        b = bo + i * BODY_SIZE
        parent = int(p[b + B_PARENT])
        for a in range(6):
            acc[i, a] = acc[parent, a] if parent >= 0 else 0.0
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            for a in range(6):
                acc[i, a] += bias[d, a]


@njit(cache=True, inline="always")
def _origin(p, w, body, a):
    """Coordinate a of the origin of body's tree in the world (rbody.engine.multibody: each tree is computed about
    its own origin, xorigin), 0 for the world itself (body < 0)."""
    return _views(p, w).xorigin[body, a] if body >= 0 else 0.0


@njit(cache=True, inline="always")
def _world_point(p, w, body, local, out):
    """out = x_body + R_body local about the origin of body's tree, where the tree's motion subspaces and
    velocities are written (the world's own point when body < 0: the world's origin is its origin)."""
    ws = _views(p, w)
    if body < 0:
        for a in range(3):
            out[a] = local[a]
        return
    for a in range(3):
        out[a] = ws.xpos[body, a] + ws.xmat[body, a, 0] * local[0] + ws.xmat[body, a, 1] * local[1] \
            + ws.xmat[body, a, 2] * local[2]


@njit(cache=True)
def _add_point_rows(p, w, body, point, sign, J, row, angular):
    """J[row:row + 3] += sign * dv/dqvel of the world point `point` fixed on `body` (angular: its angular velocity
    instead); the dofs of the body and of every body above it."""
    if body < 0:
        return
    ws = _views(p, w)
    S = ws.S
    bo = int(p[H_BODY])
    i = body
    while i >= 0:
        b = bo + i * BODY_SIZE
        d0, nd = int(p[b + B_DOF0]), int(p[b + B_NDOF])
        for d in range(d0, d0 + nd):
            if angular:
                for a in range(3):
                    J[row + a, d] += sign * S[d, a]
            else:
                J[row, d] += sign * (S[d, 3] + S[d, 1] * point[2] - S[d, 2] * point[1])
                J[row + 1, d] += sign * (S[d, 4] + S[d, 2] * point[0] - S[d, 0] * point[2])
                J[row + 2, d] += sign * (S[d, 5] + S[d, 0] * point[1] - S[d, 1] * point[0])
        i = int(p[b + B_PARENT])


@njit(cache=True, inline="always")
def _point_bias(p, w, acc, body, point, out, sign):
    """out += sign * the classical acceleration of the world point `point` fixed on `body` when qacc = 0:
    a_O + alpha x p + omega x (v_O + omega x p)."""
    if body < 0:
        return
    ws = _views(p, w)
    vel = ws.vel[body]
    wx, wy, wz = vel[0], vel[1], vel[2]
    vx = vel[3] + wy * point[2] - wz * point[1]
    vy = vel[4] + wz * point[0] - wx * point[2]
    vz = vel[5] + wx * point[1] - wy * point[0]
    a = acc[body]
    out[0] += sign * (a[3] + a[1] * point[2] - a[2] * point[1] + wy * vz - wz * vy)
    out[1] += sign * (a[4] + a[2] * point[0] - a[0] * point[2] + wz * vx - wx * vz)
    out[2] += sign * (a[5] + a[0] * point[1] - a[1] * point[0] + wx * vy - wy * vx)


@njit(cache=True, inline="always")
def _quat_mul(a, b, out):
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]


@njit(cache=True, inline="always")
def rotation_vector(quat, out):
    """out (3,) = the rotation vector (axis times angle in [0, pi]) of a unit quaternion (w, x, y, z)."""
    s = np.sqrt(quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3])
    if s == 0.0:
        for a in range(3):
            out[a] = 0.0
        return
    angle = 2.0 * np.arctan2(s, abs(quat[0]))
    scale = angle / s if quat[0] >= 0.0 else -angle / s
    for a in range(3):
        out[a] = scale * quat[1 + a]


@njit(cache=True)
def _contact_rows(p, w, acc, u, r, J, jdot, g, row, with_bias):
    """A contact unit's r rows (1: the normal; 3: the normal and the tangents t1, t2 of the contact frame; 4 and 6:
    then the spin about n and the rolling about t1, t2): g the signed distance of its candidate, J = (n; t1; t2) .
    (J_b - J_a) the relative velocity of geom b's material point at the contact point with respect to geom a's (then
    (n; t1; t2) . (W_b - W_a), the relative angular velocity), J' v the gap's second derivative without qacc (normal)
    and the sticking contact point's (tangents), rbody.engine.contacts.kinematics; with_bias False: J' v left 0
    (the time-stepping reads no J' v; the spin and rolling rows, run by the time-stepping only, have none)."""
    normal, point = np.empty(3), np.empty(3)
    g[row] = contact_geometry(p, w, u, normal, point)
    if g[row] == np.inf:  # APART: not a contact point in this configuration, no rows (its normal and point unset)
        return
    _contact_frame_rows(p, w, acc, u, r, J, jdot, g, row, with_bias, normal, point,
                        np.empty(contact_work_size(J.shape[1])))


@njit(cache=True, inline="always")
def contact_work_size(nv):
    """The floats _contact_frame_rows' scratch holds: the frame (3, 3), a bias (3) and a point (3), then the rows of
    the contact point's velocity and of the bodies' relative angular velocity (3, nv) each."""
    return 15 + 6 * nv


@njit(cache=True)
def contact_unit_rows(p, k, w, J, g, row, gap, normal, point, work):
    """unit_rows of the contact unit k without J' v (the time-stepping's) from its candidate's gap [m], normal (3,)
    and point (3,) [m] as a pass over its pair's candidates found them (rbody.engine.contacts.rows.pair_candidates),
    not from its geometry again: J[row:row + r] (zeroed here), g[row] = gap. work: scratch of contact_work_size(nv)
    floats, which a caller forming many contacts allocates once."""
    u = unit_at(p, k)
    r = int(p[u + U_ROWS])
    for a in range(r):
        for c in range(J.shape[1]):
            J[row + a, c] = 0.0
        g[row + a] = 0.0
    g[row] = gap
    if gap == np.inf:
        return
    # without the bias (with_bias False) its arrays are not read: empty views of the scratch stand for them
    _contact_frame_rows(p, w, work[0:0].reshape((0, 6)), u, r, J, work[0:0], g, row, False, normal, point, work)


@njit(cache=True)
def _contact_frame_rows(p, w, acc, u, r, J, jdot, g, row, with_bias, normal, point, work):
    """_contact_rows after its geometry: the rows in the frame of the normal (3,) at the point (3,); work: scratch
    of contact_work_size(nv) floats."""
    nv = J.shape[1]
    frame = work[0:9].reshape((3, 3))
    frame[0] = normal
    tangents(normal, frame[1], frame[2])
    bias, local = work[9:12], work[12:15]
    Jp = work[15:15 + 3 * nv].reshape((3, nv))
    for a in range(3):
        bias[a] = 0.0
        for c in range(nv):
            Jp[a, c] = 0.0
    for body, sign in ((int(p[u + U_BODY2]), 1.0), (int(p[u + U_BODY1]), -1.0)):
        if body < 0:
            continue
        for a in range(3):  # the point about the origin of the body's tree, where its subspaces are written
            local[a] = point[a] - _origin(p, w, body, a)
        _add_point_rows(p, w, body, local, sign, Jp, 0, False)
        if with_bias:
            _point_bias(p, w, acc, body, local, bias, sign)
    for e in range(min(r, 3)):
        for c in range(nv):
            J[row + e, c] = frame[e, 0] * Jp[0, c] + frame[e, 1] * Jp[1, c] + frame[e, 2] * Jp[2, c]
        if with_bias:
            jdot[row + e] = frame[e, 0] * bias[0] + frame[e, 1] * bias[1] + frame[e, 2] * bias[2]
    if r > 3:  # spin (n) and rolling (t1, t2): (n; t1; t2) . (W_b - W_a), the relative angular velocity
        Jw = work[15 + 3 * nv:15 + 6 * nv].reshape((3, nv))
        for a in range(3):
            for c in range(nv):
                Jw[a, c] = 0.0
        for body, sign in ((int(p[u + U_BODY2]), 1.0), (int(p[u + U_BODY1]), -1.0)):
            if body >= 0:
                _add_point_rows(p, w, body, local, sign, Jw, 0, True)
        for e in range(3, r):
            f = frame[e - 3]
            for c in range(nv):
                J[row + e, c] = f[0] * Jw[0, c] + f[1] * Jw[1, c] + f[2] * Jw[2, c]
    if with_bias:
        contact_bias(p, w, acc, u, g[row], frame, r, jdot, row)  # the gap's and the rolling point's own terms


@njit(cache=True, inline="always")
def dof_row(kind, bound, position):
    """(J's entry on its dof, g) of a joint's stop or dry friction (its row is 0 elsewhere, its J' v 0), bound its
    stop's position or its frictionloss, position the joint's q [m or rad]: LOWER (1, q - lower), UPPER (-1,
    upper - q), FRICTION (1, 0)."""
    if kind == LOWER:
        return 1.0, position - bound
    if kind == UPPER:
        return -1.0, bound - position
    return 1.0, 0.0


@njit(cache=True)
def unit_rows(p, k, q, v, w, acc, J, jdot, g, row, with_bias=True):
    """Rows of unit k into J[row:row + r] (zeroed here, r its rows, over all nv columns), jdot[row:] (J' v) and
    g[row:] (residual: >= 0 feasible for limits, 0 held for equalities, 0 for friction), at the effective qpos q
    (nq,) and qvel v (nv,), the workspace w holding the tree's frames at (q, v) and acc (nb, 6) its
    bias_accelerations (with_bias False: a contact's J' v is left 0, acc unread by it). Returns r."""
    u = unit_at(p, k)
    kind = int(p[u + U_KIND])
    r = int(p[u + U_ROWS])
    nv = J.shape[1]
    for a in range(r):
        for c in range(nv):
            J[row + a, c] = 0.0
        jdot[row + a] = 0.0
        g[row + a] = 0.0
    d = int(p[u + U_DOF])
    qa = int(p[u + U_QADR])
    if is_dof_kind(kind):
        J[row, d], g[row] = dof_row(kind, p[u + U_BOUND], q[qa])
    elif kind == CONE:
        qw, qx, qy, qz = q[qa], q[qa + 1], q[qa + 2], q[qa + 3]
        norm = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        s = np.sqrt(qx * qx + qy * qy + qz * qz) / norm
        theta = 2.0 * np.arctan2(s, abs(qw) / norm)
        g[row] = p[u + U_BOUND] - theta
        if s > 1e-12:
            sign = 1.0 if qw >= 0.0 else -1.0
            ux, uy, uz = sign * qx / (norm * s), sign * qy / (norm * s), sign * qz / (norm * s)
            J[row, d], J[row, d + 1], J[row, d + 2] = -ux, -uy, -uz
            rate = ux * v[d] + uy * v[d + 1] + uz * v[d + 2]
            spin = v[d] * v[d] + v[d + 1] * v[d + 1] + v[d + 2] * v[d + 2]
            jdot[row] = -0.5 * (spin - rate * rate) / np.tan(0.5 * theta)
    elif kind == COUPLING:
        J[row, d] = 1.0
        x = 0.0
        value = p[u + U_POLY]
        d2 = int(p[u + U_DOF2])
        if d2 >= 0:
            x = q[int(p[u + U_QADR2])] - p[u + U_REF2]
            c1, c2, c3, c4 = p[u + U_POLY + 1], p[u + U_POLY + 2], p[u + U_POLY + 3], p[u + U_POLY + 4]
            value += x * (c1 + x * (c2 + x * (c3 + x * c4)))
            slope = c1 + x * (2.0 * c2 + x * (3.0 * c3 + x * 4.0 * c4))
            curvature = 2.0 * c2 + x * (6.0 * c3 + x * 12.0 * c4)
            J[row, d2] -= slope
            jdot[row] = -curvature * v[d2] * v[d2]
        g[row] = q[qa] - p[u + U_REF1] - value
    elif kind == CONTACT or kind == CONTACT1:
        _contact_rows(p, w, acc, u, r, J, jdot, g, row, with_bias)
    elif kind == TENDON_LOWER or kind == TENDON_UPPER or kind == TENDON_FRICTION:
        length, curvature = tendon_row(p, int(p[u + U_TENDON]), q, w, acc, J[row])
        sign = -1.0 if kind == TENDON_UPPER else 1.0
        if sign < 0.0:
            for c in range(nv):
                J[row, c] = -J[row, c]
        jdot[row] = sign * curvature
        if kind == TENDON_LOWER:
            g[row] = length - p[u + U_BOUND]
        elif kind == TENDON_UPPER:
            g[row] = p[u + U_BOUND] - length
    elif kind == TENDON_EQUALITY:
        length, curvature = tendon_row(p, int(p[u + U_TENDON]), q, w, acc, J[row])
        jdot[row] = curvature
        value = p[u + U_POLY]
        t2 = int(p[u + U_TENDON2])
        if t2 >= 0:
            row2 = np.empty(nv)
            length2, curvature2 = tendon_row(p, t2, q, w, acc, row2)
            x = length2 - p[u + U_REF2]
            c1, c2, c3, c4 = p[u + U_POLY + 1], p[u + U_POLY + 2], p[u + U_POLY + 3], p[u + U_POLY + 4]
            value += x * (c1 + x * (c2 + x * (c3 + x * c4)))
            slope = c1 + x * (2.0 * c2 + x * (3.0 * c3 + x * 4.0 * c4))
            bend = 2.0 * c2 + x * (6.0 * c3 + x * 12.0 * c4)
            rate = 0.0
            for c in range(nv):
                J[row, c] -= slope * row2[c]
                rate += row2[c] * v[c]
            jdot[row] -= slope * curvature2 + bend * rate * rate
        g[row] = length - p[u + U_REF1] - value
    else:  # CONNECT or WELD: body1's point p1 on body2's point p2
        body1, body2 = int(p[u + U_BODY1]), int(p[u + U_BODY2])
        p1 = np.empty(3)
        p2 = np.empty(3)
        _world_point(p, w, body1, p[u + U_A1:u + U_A1 + 3], p1)
        _world_point(p, w, body2, p[u + U_A2:u + U_A2 + 3], p2)
        for a in range(3):  # the trees' origins apart first: within one tree they cancel exactly
            g[row + a] = (_origin(p, w, body1, a) - _origin(p, w, body2, a)) + (p1[a] - p2[a])
        _add_point_rows(p, w, body1, p1, 1.0, J, row, False)
        _add_point_rows(p, w, body2, p2, -1.0, J, row, False)
        _point_bias(p, w, acc, body1, p1, jdot[row:row + 3], 1.0)
        _point_bias(p, w, acc, body2, p2, jdot[row:row + 3], -1.0)
        if kind == WELD:
            ws = _views(p, w)
            q1 = np.array([1.0, 0.0, 0.0, 0.0])
            q2 = np.array([1.0, 0.0, 0.0, 0.0])
            if body1 >= 0:
                q1[:] = ws.xquat[body1]
            if body2 >= 0:
                q2[:] = ws.xquat[body2]
            turned = np.empty(4)
            error = np.empty(4)
            _quat_mul(q1, p[u + U_QUAT:u + U_QUAT + 4], turned)
            q2[1], q2[2], q2[3] = -q2[1], -q2[2], -q2[3]
            _quat_mul(turned, q2, error)
            rotation_vector(error, g[row + 3:row + 6])
            _add_point_rows(p, w, body1, p1, 1.0, J, row + 3, True)
            _add_point_rows(p, w, body2, p2, -1.0, J, row + 3, True)
            for a in range(3):
                if body1 >= 0:
                    jdot[row + 3 + a] += acc[body1, a]
                if body2 >= 0:
                    jdot[row + 3 + a] -= acc[body2, a]
    return r


@njit(cache=True)
def all_rows(p, q, v, w, acc, J, jdot, g, with_bias=True, contacts=True):
    """Every unit's rows, in unit order, into J (rows, nv), jdot (rows,), g (rows,) (see unit_rows); contacts
    False: the units before the contacts only (their rows are the first; the contacts' rows are left as they were)."""
    row = 0
    nv = J.shape[1]
    units = unit_at(p, 0)  # (unit k's record from the first's: unit_at's reads from the header, redone each pass)
    for k in range(unit_count(p) if contacts else contact0(p)):
        u = units + k * UNIT_SIZE
        kind = int(p[u + U_KIND])
        if is_dof_kind(kind):  # written here: a call per unit (or a helper given the arrays) costs numba's reference
            for c in range(nv):  # counts of its eight arrays, more than the row (a quadruped's 36 such units)
                J[row, c] = 0.0
            J[row, int(p[u + U_DOF])], g[row] = dof_row(kind, p[u + U_BOUND], q[int(p[u + U_QADR])])
            jdot[row] = 0.0
            row += 1
        else:
            row += unit_rows(p, k, q, v, w, acc, J, jdot, g, row, with_bias)


@njit(cache=True)
def some_rows(p, q, v, w, acc, J, jdot, g, rows_wanted, with_bias=True):
    """As all_rows for the units with a row flagged in rows_wanted (rows,); the other rows are left as they were.
    The contacts pair by pair, by their rows' flags (a model's many far candidates: no unit record read)."""
    for k in range(contact0(p)):
        row = int(p[unit_at(p, k) + U_ROW0])
        if rows_wanted[row] != 0.0:
            unit_rows(p, k, q, v, w, acc, J, jdot, g, row, with_bias)
    for i in range(pair_count(p)):
        first, slots, row0, width = pair_span(p, pair_at(p, i))
        for j in range(slots):
            if rows_wanted[row0 + j * width] != 0.0:
                unit_rows(p, first + j, q, v, w, acc, J, jdot, g, row0 + j * width, with_bias)


__all__ = ["block_offset", "unit_count", "row_count", "unit_at", "mode_at", "bias_accelerations", "unit_rows",
           "contact_unit_rows", "contact_work_size",
           "all_rows", "some_rows", "rotation_vector", "C_MODE"]
