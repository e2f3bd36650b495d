"""A tendon's length, Jacobian and curvature at a state: the rows of the tendon units of the constraint layer.

For a tendon t (rbody.engine.elements: its record and path in the force-element section), at the state whose
tree quantities are in the workspace (poses, motion subspaces, velocities: rbody.engine.multibody) and whose bias
accelerations (every qacc = 0, rbody.engine.constraints.jacobians.bias_accelerations) are in acc:

- fixed:   L = sum coef_k q_k, J = dL/dq = coef_k at each joint's degree of freedom, J' v = 0 (L is linear in q);
- spatial: L = sum_k |d_k|, d_k = x_{k+1} - x_k the segment between consecutive sites (world frame), u_k = d_k/|d_k|,
           J = sum_k u_k^T (J_{k+1} - J_k) (J_k the point Jacobian of site k; a segment whose two sites are on one
           body has a constant length and no row, as MuJoCo's), and the exact curvature term
           J' v = sum_k [ u_k . (a_{k+1} - a_k) + (|w_k|^2 - (u_k . w_k)^2) / |d_k| ],
           w_k = v_{k+1} - v_k the sites' relative velocity and a_k a site's classical acceleration with qacc = 0
           (d/dt (u . w) = u' . w + u . w', u' = (w - (u . w) u) / |d|): the second derivative of L without qacc.

Sites are written about the origin of their body's tree (rbody.engine.multibody: each tree about its own point);
a segment's difference adds the two origins' difference first, so that a rope between the world and a body, or
between two trees, has its world length.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.actuation import add_point_jacobian, site_position
from rbody.engine.elements import MJ_MINVAL, PATH_SIZE, T_KIND, T_N, T_PATH, TEN_FIXED, TEN_SIZE, X_TEN, extension_start
from rbody.engine.multibody import _views


@njit(cache=True, inline="always")
def _site_motion(ws, acc, body, x, vel_out, acc_out):
    """vel_out, acc_out (3,) = the velocity and the classical acceleration with qacc = 0 of the point x (3,) fixed on
    `body`, about its tree's origin (0 for the world)."""
    if body < 0:
        for a in range(3):
            vel_out[a] = 0.0
            acc_out[a] = 0.0
        return
    v = ws.vel[body]
    wx, wy, wz = v[0], v[1], v[2]
    vx = v[3] + wy * x[2] - wz * x[1]
    vy = v[4] + wz * x[0] - wx * x[2]
    vz = v[5] + wx * x[1] - wy * x[0]
    vel_out[0], vel_out[1], vel_out[2] = vx, vy, vz
    s = acc[body]
    acc_out[0] = s[3] + s[1] * x[2] - s[2] * x[1] + wy * vz - wz * vy
    acc_out[1] = s[4] + s[2] * x[0] - s[0] * x[2] + wz * vx - wx * vz
    acc_out[2] = s[5] + s[0] * x[1] - s[1] * x[0] + wx * vy - wy * vx


@njit(cache=True)
def tendon_row(p, t, q, w, acc, row):
    """Tendon t's length L and J' v (the module docstring) at qpos q (nq,), the workspace w holding the tree's frames
    and velocities and acc (nb, 6) its bias accelerations; row (nv,) gets J = dL/dq (overwritten). Returns
    (L, J' v)."""
    E = extension_start(p)
    r = int(p[E + X_TEN]) + t * TEN_SIZE
    n, path = int(p[r + T_N]), int(p[r + T_PATH])
    for d in range(row.shape[0]):
        row[d] = 0.0
    length = 0.0
    curvature = 0.0
    if int(p[r + T_KIND]) == TEN_FIXED:
        for k in range(n):
            e = path + k * PATH_SIZE
            coef = p[e + 2]
            length += coef * q[int(p[e])]
            row[int(p[e + 1])] += coef
        return length, 0.0
    ws = _views(p, w)
    x0, x1, u = np.empty(3), np.empty(3), np.empty(3)
    v0, v1, a0, a1 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for k in range(n - 1):
        e0, e1 = path + k * PATH_SIZE, path + (k + 1) * PATH_SIZE
        b0, b1 = int(p[e0]), int(p[e1])
        site_position(p, ws.xpos, ws.xmat, b0, p[e0 + 1:e0 + 4], x0)
        site_position(p, ws.xpos, ws.xmat, b1, p[e1 + 1:e1 + 4], x1)
        for a in range(3):  # the trees' origins apart first: within one tree they cancel exactly
            o0 = ws.xorigin[b0, a] if b0 >= 0 else 0.0
            o1 = ws.xorigin[b1, a] if b1 >= 0 else 0.0
            u[a] = (o1 - o0) + (x1[a] - x0[a])
        distance = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
        length += distance
        if b0 == b1:
            continue
        if distance < MJ_MINVAL:  # MuJoCo's mju_normalize3 of a vanishing difference: (1, 0, 0)
            u[0], u[1], u[2] = 1.0, 0.0, 0.0
        else:
            for a in range(3):
                u[a] /= distance
        add_point_jacobian(p, ws.S, b1, x1, u, 1.0, row)
        add_point_jacobian(p, ws.S, b0, x0, u, -1.0, row)
        _site_motion(ws, acc, b0, x0, v0, a0)
        _site_motion(ws, acc, b1, x1, v1, a1)
        along = 0.0
        across = 0.0
        for a in range(3):
            along += u[a] * (v1[a] - v0[a])
            across += (v1[a] - v0[a]) * (v1[a] - v0[a])
            curvature += u[a] * (a1[a] - a0[a])
        if distance >= MJ_MINVAL:
            curvature += (across - along * along) / distance
    return length, curvature


__all__ = ["tendon_row"]
