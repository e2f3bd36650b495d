"""Tendons and actuators of a tree, as MuJoCo computes them (engine_core_smooth.c mj_tendon and mj_transmission,
engine_forward.c mj_fwdActuation), over the force-element section of the params row (rbody.engine.elements).

Tendon length L and Jacobian J (dL/dq as a row over the degrees of freedom, L' = J qvel):
- fixed: L = sum coef_k q_k (q itself, not q - ref), J = coef_k at each joint's degree of freedom;
- spatial (sites only): L = sum |x_{k+1} - x_k| over consecutive sites, world positions x = xorigin + xpos + xmat
  point (xpos about the origin of the body's tree);
  where two consecutive sites lie on different bodies, J += u^T (J_{k+1} - J_k), u the unit vector from x_k to
  x_{k+1} and J_k the point Jacobian of x_k (MuJoCo skips pairs on one body: their distance is constant).
Actuator length, moment (its row of dL/dq) and velocity L' = moment . qvel (transmission):
- hinge, slide (and roll): L = gear[0] q, moment gear[0] at the joint's degree of freedom;
- ball: L = gear[:3] . r, r the rotation vector of the (normalised) quaternion (MuJoCo's mju_quat2Vel, angle
  wrapped to (-pi, pi]); moment gear[:3] at its three degrees of freedom (body-frame torque);
- free: L = 0, moment gear (6: world force, body-frame torque);
- tendon: L = gear[0] L_tendon, moment gear[0] J.
Force (rbody.layout.Actuator): the control clamped to ctrlrange; act' = u (integrator), (u - act) / max(1e-15,
tau) (filter, filterexact); force = gain * (u | act | act_next) + bias, clamped to forcerange; act_next =
act + h act' (filterexact: act + act' tau (1 - exp(-h / tau)), MuJoCo's mj_nextActivation), clamped to actrange
(actearly; h the run's step). Generalised force qfrc_actuator = moment^T force. A disabled actuator's force is 0 before
the clamp (as MuJoCo, which clamps every force) and its activation does not move.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.elements import (A_ACTADR, A_ACTEARLY, A_ACTLIM, A_ACTRANGE, A_BIAS, A_BIASPRM, A_CTRLLIM,
                                   A_CTRLRANGE, A_DADR, A_DISABLED, A_DYN, A_DYNPRM, A_FORCELIM, A_FORCERANGE,
                                   A_GAIN, A_GAINPRM, A_GEAR, A_ID, A_JKIND, A_QADR, A_TRN, ACT_SIZE, BIAS_AFFINE,
                                   DYN_FILTER, DYN_FILTEREXACT, DYN_INTEGRATOR, DYN_NONE, GAIN_AFFINE, MJ_MINVAL,
                                   A_SITEPOS, A_SITEQUAT, PATH_SIZE, T_KIND, T_N, T_PATH, TEN_FIXED, TEN_SIZE,
                                   TRN_JOINT, TRN_SITE, X_ACT, X_CTRL,
                                   X_NTEN, X_NU, X_STEP, X_TEN, extension_start)
from rbody.engine.multibody import (B_DOF0, B_NDOF, B_PARENT, BALL, BODY_SIZE, D_PARENT, DOF_SIZE, FREE, H_BODY,
                                    H_DOF, H_DOFS, _views)


# ----- tendons -------------------------------------------------------------------------------------------

@njit(cache=True, inline="always")
def last_dof(p, body):
    """The last degree of freedom moving `body` (its own, else its nearest moving ancestor's), -1 for none."""
    bo = int(p[H_BODY])
    while body >= 0:
        b = bo + body * BODY_SIZE
        if p[b + B_NDOF] > 0:
            return int(p[b + B_DOF0] + p[b + B_NDOF]) - 1
        body = int(p[b + B_PARENT])
    return -1


@njit(cache=True)
def add_point_jacobian(p, S, body, x, direction, scale, row):
    """row (nv,) += scale * direction . (dx/dqvel), x (3,) a world point fixed on `body` (-1: the world, nothing),
    S (nv, 6) the motion subspaces: column d of the point Jacobian is S_v + S_w x x for every d moving the body."""
    do = int(p[H_DOF])
    d = last_dof(p, body) if body >= 0 else -1
    while d >= 0:
        w0, w1, w2 = S[d, 0], S[d, 1], S[d, 2]
        jx = S[d, 3] + w1 * x[2] - w2 * x[1]
        jy = S[d, 4] + w2 * x[0] - w0 * x[2]
        jz = S[d, 5] + w0 * x[1] - w1 * x[0]
        row[d] += scale * (direction[0] * jx + direction[1] * jy + direction[2] * jz)
        d = int(p[do + d * DOF_SIZE + D_PARENT])


@njit(cache=True, inline="always")
def site_position(p, xpos, xmat, body, point, out):
    """Position (3,) of `point` (3,) fixed in `body`'s frame (-1: the world frame), about the origin of body's tree
    (rbody.engine.multibody: xpos is; add xorigin for the world position)."""
    if body < 0:
        for a in range(3):
            out[a] = point[a]
        return
    for a in range(3):
        out[a] = xpos[body, a] + xmat[body, a, 0] * point[0] + xmat[body, a, 1] * point[1] + xmat[body, a, 2] * point[2]


@njit(cache=True)
def tendon_kinematics(p, q, v, w, length, velocity, J):
    """length (nten,), velocity (nten,) and Jacobian J (nten, nv) of every tendon at qpos q, qvel v (module
    docstring), the tree's workspace w already holding the poses and motion subspaces of the state (_frames)."""
    E = extension_start(p)
    nten, nv = int(p[E + X_NTEN]), int(p[H_DOFS])
    if nten == 0:
        return
    ws = _views(p, w)
    S, xpos, xmat, scratch = ws.S, ws.xpos, ws.xmat, ws.scratch
    x0, x1, u = scratch[0:3], scratch[3:6], scratch[6:9]
    for t in range(nten):
        r = int(p[E + X_TEN]) + t * TEN_SIZE
        n, path = int(p[r + T_N]), int(p[r + T_PATH])
        for d in range(nv):
            J[t, d] = 0.0
        total = 0.0
        if int(p[r + T_KIND]) == TEN_FIXED:
            for k in range(n):
                e = path + k * PATH_SIZE
                coef = p[e + 2]
                total += coef * q[int(p[e])]
                J[t, int(p[e + 1])] += coef
        else:
            for k in range(n - 1):
                e0, e1 = path + k * PATH_SIZE, path + (k + 1) * PATH_SIZE
                b0, b1 = int(p[e0]), int(p[e1])
                site_position(p, xpos, xmat, b0, p[e0 + 1:e0 + 4], x0)
                site_position(p, xpos, xmat, b1, p[e1 + 1:e1 + 4], x1)
                for a in range(3):  # sites about their trees' origins: the origins' difference first
                    u[a] = ((ws.xorigin[b1, a] if b1 >= 0 else 0.0) - (ws.xorigin[b0, a] if b0 >= 0 else 0.0)) \
                        + (x1[a] - x0[a])
                distance = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
                total += distance
                if b0 != b1:
                    if distance < MJ_MINVAL:  # MuJoCo's mju_normalize3 of a vanishing difference: (1, 0, 0)
                        u[0], u[1], u[2] = 1.0, 0.0, 0.0
                    else:
                        for a in range(3):
                            u[a] /= distance
                    add_point_jacobian(p, S, b1, x1, u, 1.0, J[t])
                    add_point_jacobian(p, S, b0, x0, u, -1.0, J[t])
        length[t] = total
        rate = 0.0
        for d in range(nv):
            rate += J[t, d] * v[d]
        velocity[t] = rate


# ----- actuators -----------------------------------------------------------------------------------------

@njit(cache=True, inline="always")
def clip(value, low, high):
    return low if value < low else (high if value > high else value)


@njit(cache=True)
def transmission(p, q, v, w, ten_length, ten_J, length, velocity, moment):
    """length (nu,), velocity (nu,) and moment (nu, nv) of every actuator (module docstring) at qpos q (the
    quaternions as used: unit or made unit here), qvel v, from the tendons' lengths and Jacobians and the tree's
    workspace w (poses and motion subspaces: site transmissions)."""
    E = extension_start(p)
    nu, nv = int(p[E + X_NU]), int(p[H_DOFS])
    for i in range(nu):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        for d in range(nv):
            moment[i, d] = 0.0
        gear0 = p[r + A_GEAR]
        if int(p[r + A_TRN]) == TRN_JOINT:
            kind, qa, da = int(p[r + A_JKIND]), int(p[r + A_QADR]), int(p[r + A_DADR])
            if kind == BALL:
                qw, qx, qy, qz = q[qa], q[qa + 1], q[qa + 2], q[qa + 3]
                norm = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
                if norm >= MJ_MINVAL and abs(norm - 1.0) > MJ_MINVAL:  # mju_normalize4
                    qw, qx, qy, qz = qw / norm, qx / norm, qy / norm, qz / norm
                sine = np.sqrt(qx * qx + qy * qy + qz * qz)
                if sine < MJ_MINVAL:  # mju_normalize3 of a zero axis: (1, 0, 0)
                    ax, ay, az = 1.0, 0.0, 0.0
                else:
                    ax, ay, az = qx / sine, qy / sine, qz / sine
                angle = 2.0 * np.arctan2(sine, qw)
                if angle > np.pi:
                    angle -= 2.0 * np.pi
                length[i] = angle * (ax * p[r + A_GEAR] + ay * p[r + A_GEAR + 1] + az * p[r + A_GEAR + 2])
                for k in range(3):
                    moment[i, da + k] = p[r + A_GEAR + k]
            elif kind == FREE:
                length[i] = 0.0
                for k in range(6):
                    moment[i, da + k] = p[r + A_GEAR + k]
            else:  # hinge, slide, roll: one coordinate
                length[i] = q[qa] * gear0
                moment[i, da] = gear0
        elif int(p[r + A_TRN]) == TRN_SITE:
            _site_moment(p, r, w, moment[i])
            length[i] = 0.0
        else:
            t = int(p[r + A_ID])
            length[i] = ten_length[t] * gear0
            for d in range(nv):
                moment[i, d] = ten_J[t, d] * gear0
        rate = 0.0
        for d in range(nv):
            rate += moment[i, d] * v[d]
        velocity[i] = rate


@njit(cache=True)
def _site_moment(p, r, w, row):
    """row (nv,) = J_pos^T (R gear[:3]) + J_rot^T (R gear[3:]) at a site (MuJoCo's site transmission without
    refsite), R the site's world axes, J its point and rotation Jacobians."""
    ws = _views(p, w)
    S, xpos, xmat, scratch = ws.S, ws.xpos, ws.xmat, ws.scratch
    body = int(p[r + A_ID])
    x, force, torque, local = scratch[9:12], scratch[12:15], scratch[15:18], scratch[18:27]
    at = r + A_SITEQUAT
    qw, qx, qy, qz = p[at], p[at + 1], p[at + 2], p[at + 3]
    ww, xx, yy, zz = qw * qw, qx * qx, qy * qy, qz * qz
    local[0], local[1], local[2] = ww + xx - yy - zz, 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)
    local[3], local[4], local[5] = 2 * (qx * qy + qw * qz), ww - xx + yy - zz, 2 * (qy * qz - qw * qx)
    local[6], local[7], local[8] = 2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), ww - xx - yy + zz
    for a in range(3):
        x[a] = xpos[body, a]
        force[a] = 0.0
        torque[a] = 0.0
        for c in range(3):
            x[a] += xmat[body, a, c] * p[r + A_SITEPOS + c]
            axis = (xmat[body, a, 0] * local[c] + xmat[body, a, 1] * local[3 + c] + xmat[body, a, 2] * local[6 + c])
            force[a] += axis * p[r + A_GEAR + c]
            torque[a] += axis * p[r + A_GEAR + 3 + c]
    for d in range(row.shape[0]):
        row[d] = 0.0
    do = int(p[H_DOF])
    d = last_dof(p, body)
    while d >= 0:
        w0, w1, w2 = S[d, 0], S[d, 1], S[d, 2]
        jx = S[d, 3] + w1 * x[2] - w2 * x[1]
        jy = S[d, 4] + w2 * x[0] - w0 * x[2]
        jz = S[d, 5] + w0 * x[1] - w1 * x[0]
        row[d] = force[0] * jx + force[1] * jy + force[2] * jz + torque[0] * w0 + torque[1] * w1 + torque[2] * w2
        d = int(p[do + d * DOF_SIZE + D_PARENT])


@njit(cache=True, inline="always")
def next_activation(p, r, act, act_dot, h):
    """MuJoCo's mj_nextActivation: the activation after a step h [s] at rate act_dot, clamped to actrange: a
    "filterexact" actuator by the filter's exact solution act + act_dot tau (1 - exp(-h/tau)), any other by
    act + h act_dot."""
    if int(p[r + A_DYN]) == DYN_FILTEREXACT:
        tau = max(MJ_MINVAL, p[r + A_DYNPRM])
        value = act + act_dot * tau * (1.0 - np.exp(-h / tau))
    else:
        value = act + act_dot * h
    if p[r + A_ACTLIM] != 0.0:
        value = clip(value, p[r + A_ACTRANGE], p[r + A_ACTRANGE + 1])
    return value


@njit(cache=True)
def actuator_forces(p, act, length, velocity, moment, ctrl, force, act_dot, qfrc):
    """MuJoCo's mj_fwdActuation after the transmission: ctrl (nu,) the controls as applied (clamped to ctrlrange
    here), act_dot (na,), force (nu,) MuJoCo's actuator_force, qfrc (nv,) its qfrc_actuator (module docstring);
    act (na,) the activations. actearly uses MuJoCo's next activation (next_activation), h the run's step."""
    E = extension_start(p)
    nu, nv = int(p[E + X_NU]), int(p[H_DOFS])
    h = p[E + X_STEP]
    ctrl_at = int(p[E + X_CTRL])
    for i in range(nu):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        u = p[ctrl_at + i]
        if p[r + A_CTRLLIM] != 0.0:
            u = clip(u, p[r + A_CTRLRANGE], p[r + A_CTRLRANGE + 1])
        ctrl[i] = u
    for i in range(nu):  # act_dot of every stateful actuator (MuJoCo computes it for disabled ones too)
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        adr = int(p[r + A_ACTADR])
        if adr < 0:
            continue
        dyn = int(p[r + A_DYN])
        if dyn == DYN_INTEGRATOR:
            act_dot[adr] = ctrl[i]
        elif dyn == DYN_FILTER or dyn == DYN_FILTEREXACT:
            act_dot[adr] = (ctrl[i] - act[adr]) / max(MJ_MINVAL, p[r + A_DYNPRM])
        else:
            act_dot[adr] = 0.0
    for i in range(nu):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        value = 0.0
        if p[r + A_DISABLED] == 0.0:
            gain = p[r + A_GAINPRM]
            if int(p[r + A_GAIN]) == GAIN_AFFINE:
                gain += p[r + A_GAINPRM + 1] * length[i] + p[r + A_GAINPRM + 2] * velocity[i]
            adr = int(p[r + A_ACTADR])
            if adr < 0 or int(p[r + A_DYN]) == DYN_NONE:
                value = gain * ctrl[i]
            elif p[r + A_ACTEARLY] != 0.0:
                value = gain * next_activation(p, r, act[adr], act_dot[adr], h)
            else:
                value = gain * act[adr]
            if int(p[r + A_BIAS]) == BIAS_AFFINE:
                value += p[r + A_BIASPRM] + p[r + A_BIASPRM + 1] * length[i] + p[r + A_BIASPRM + 2] * velocity[i]
        if p[r + A_FORCELIM] != 0.0:
            value = clip(value, p[r + A_FORCERANGE], p[r + A_FORCERANGE + 1])
        force[i] = value
    for d in range(nv):
        qfrc[d] = 0.0
    for i in range(nu):
        if force[i] != 0.0:
            for d in range(nv):
                qfrc[d] += moment[i, d] * force[i]


@njit(cache=True)
def actuator_velocity_derivative(p, act, act_dot, ctrl_raw, force, moment, D):
    """D (nv, nv) += d qfrc_actuator / d qvel as MuJoCo's mjd_actuator_vel: per actuator whose force is not at a
    forcerange bound, moment^T (biasprm[2] [affine bias] + gainprm[2] [affine gain] * (u | act | act_next))
    moment, with u the control as given (ctrl_raw, not clamped: MuJoCo reads d->ctrl there)."""
    E = extension_start(p)
    nu, nv = int(p[E + X_NU]), int(p[H_DOFS])
    h = p[E + X_STEP]
    for i in range(nu):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        if p[r + A_DISABLED] != 0.0:
            continue
        if p[r + A_FORCELIM] != 0.0 and (force[i] <= p[r + A_FORCERANGE] or force[i] >= p[r + A_FORCERANGE + 1]):
            continue
        slope = p[r + A_BIASPRM + 2] if int(p[r + A_BIAS]) == BIAS_AFFINE else 0.0
        if int(p[r + A_GAIN]) == GAIN_AFFINE and p[r + A_GAINPRM + 2] != 0.0:
            adr = int(p[r + A_ACTADR])
            if adr < 0 or int(p[r + A_DYN]) == DYN_NONE:
                slope += p[r + A_GAINPRM + 2] * ctrl_raw[i]
            elif p[r + A_ACTEARLY] != 0.0:
                slope += p[r + A_GAINPRM + 2] * next_activation(p, r, act[adr], act_dot[adr], h)
            else:
                slope += p[r + A_GAINPRM + 2] * act[adr]
        if slope == 0.0:
            continue
        for a in range(nv):
            if moment[i, a] == 0.0:
                continue
            for c in range(nv):
                D[a, c] += moment[i, a] * slope * moment[i, c]


__all__ = ["tendon_kinematics", "transmission", "actuator_forces", "next_activation", "actuator_velocity_derivative",
           "add_point_jacobian", "last_dof"]
