"""Fluid forces as MuJoCo computes them (engine_passive.c mj_inertiaBoxFluidModel, mj_ellipsoidFluidModel and their
helpers; the inertia box's velocity derivative: engine_derivative.c mjd_inertiaBoxFluid), a passive force.

Each model works in a local frame: a body's principal axes at its centre of mass (inertia box), or a geom's frame
at its centre (ellipsoid), with the local velocity lvel = (R^T omega, R^T v_point - R^T wind). The local force and
torque are rotated back and applied at that point through the point Jacobian.

Inertia box, box sides b_k = sqrt(6 (I_{k+1} + I_{k+2} - I_k) / m) from the principal moments, d = (b0 + b1 + b2)/3:
    torque -= pi d^3 viscosity omega + density b_k (b_{k+1}^4 + b_{k+2}^4) |omega_k| omega_k / 64
    force  -= 3 pi d viscosity v + density/2 b_{k+1} b_{k+2} |v_k| v_k
Ellipsoid (semiaxes s, coefficients: blunt, slender, angular drag, Kutta, Magnus lift; added mass factors), the
sum of the added-mass gyroscopic forces (p x omega, p x v + L x omega with p, L the fluid's virtual momenta) and
the viscous and lift forces of mj_viscousForces (Stokes drag of the equivalent sphere, quadratic drag on the
projected area, Kutta-Joukowski and Magnus lift), as written there.

The fluid section of the params row (rbody.engine.elements X_FLUID): nbox, nell, density, viscosity, wind (3),
offsets of the box and ellipsoid records; box record (body, axes quat (4), sides (3)); ellipsoid record (body,
pos (3), quat (4), semiaxes (3), virtual mass (3), virtual inertia (3), coefficients (5)).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.elements import BOX_SIZE, ELL_SIZE, FLUID_HEADER, X_FLUID, extension_start
from rbody.engine.multibody import B_MASS, BODY_SIZE, D_PARENT, DOF_SIZE, H_BODY, H_DOF
from rbody.engine.actuation import last_dof

F_NBOX, F_NELL, F_DENSITY, F_VISCOSITY, F_WIND, F_BOX, F_ELL = 0, 1, 2, 3, 4, 7, 8
MJ_MINVAL = 1e-15


@njit(cache=True, inline="always")
def _quat_matrix(p, at, R):
    """R (3, 3) of the unit quaternion p[at:at + 4] (w, x, y, z)."""
    w, x, y, z = p[at], p[at + 1], p[at + 2], p[at + 3]
    R[0, 0] = w * w + x * x - y * y - z * z
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = w * w - x * x + y * y - z * z
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = w * w - x * x - y * y + z * z


@njit(cache=True)
def add_wrench(p, S, body, point, force, torque, out):
    """out (nv,) += J^T (force at world `point`, torque) for a wrench on `body`: S_v + S_w x point, S_w."""
    do = int(p[H_DOF])
    d = last_dof(p, body)
    while d >= 0:
        w0, w1, w2 = S[d, 0], S[d, 1], S[d, 2]
        jx = S[d, 3] + w1 * point[2] - w2 * point[1]
        jy = S[d, 4] + w2 * point[0] - w0 * point[2]
        jz = S[d, 5] + w0 * point[1] - w1 * point[0]
        out[d] += force[0] * jx + force[1] * jy + force[2] * jz + torque[0] * w0 + torque[1] * w1 + torque[2] * w2
        d = int(p[do + d * DOF_SIZE + D_PARENT])


@njit(cache=True, inline="always")
def _frame(p, xpos, xmat, body, at_pos, at_quat, R, x, work):
    """World rotation R (3, 3) = xmat[body] R(quat) and origin x (3,) = xpos[body] + xmat[body] pos of a frame fixed in
    the body; at_pos < 0: the origin is set by the caller."""
    _quat_matrix(p, at_quat, work)
    for a in range(3):
        for c in range(3):
            R[a, c] = xmat[body, a, 0] * work[0, c] + xmat[body, a, 1] * work[1, c] + xmat[body, a, 2] * work[2, c]
    if at_pos >= 0:
        for a in range(3):
            x[a] = xpos[body, a] + xmat[body, a, 0] * p[at_pos] + xmat[body, a, 1] * p[at_pos + 1] + xmat[
                body, a, 2] * p[at_pos + 2]


@njit(cache=True, inline="always")
def _local_velocity(p, F, vel, body, R, x, lvel):
    """lvel (6,) = (R^T omega, R^T (v at x) - R^T wind), vel (nb, 6) the bodies' spatial velocities (world, origin)."""
    w0, w1, w2 = vel[body, 0], vel[body, 1], vel[body, 2]
    v0 = vel[body, 3] + w1 * x[2] - w2 * x[1]
    v1 = vel[body, 4] + w2 * x[0] - w0 * x[2]
    v2 = vel[body, 5] + w0 * x[1] - w1 * x[0]
    for k in range(3):
        lvel[k] = R[0, k] * w0 + R[1, k] * w1 + R[2, k] * w2
        lwind = R[0, k] * p[F + F_WIND] + R[1, k] * p[F + F_WIND + 1] + R[2, k] * p[F + F_WIND + 2]
        lvel[3 + k] = (R[0, k] * v0 + R[1, k] * v1 + R[2, k] * v2) - lwind


@njit(cache=True)
def _box_motion(p, F, k, xpos, xmat, vel, h, R, x, work, lvel):
    """(body, record) of inertia box k, with its frame R (3, 3), its centre of mass x (3,) and its local velocity lvel
    (6,) (_frame, _local_velocity); body -1 for a massless body, which feels no fluid force (MuJoCo's mjMINVAL)."""
    r = int(p[F + F_BOX]) + k * BOX_SIZE
    i = int(p[r])
    mass = p[int(p[H_BODY]) + i * BODY_SIZE + B_MASS]
    if mass < MJ_MINVAL:
        return -1, r
    for a in range(3):
        x[a] = h[i, a] / mass
    _frame(p, xpos, xmat, i, -1, r + 1, R, x, work)
    _local_velocity(p, F, vel, i, R, x, lvel)
    return i, r


@njit(cache=True)
def fluid_forces(p, S, xpos, xmat, vel, h, out):
    """out (nv,) += MuJoCo's qfrc_fluid (module docstring), from the tree's workspace: S (nv, 6), xpos (nb, 3), xmat
    (nb, 3, 3), vel (nb, 6), h (nb, 3) = m c."""
    F = int(p[extension_start(p) + X_FLUID])
    if F < 0:
        return
    bo = int(p[H_BODY])
    density, viscosity = p[F + F_DENSITY], p[F + F_VISCOSITY]
    R, work = np.empty((3, 3)), np.empty((3, 3))
    x, lvel, lfrc = np.empty(3), np.empty(6), np.empty(6)
    force, torque = np.empty(3), np.empty(3)
    for k in range(int(p[F + F_NBOX])):
        i, r = _box_motion(p, F, k, xpos, xmat, vel, h, R, x, work, lvel)
        if i < 0:
            continue
        b0, b1, b2 = p[r + 5], p[r + 6], p[r + 7]
        for a in range(6):
            lfrc[a] = 0.0
        if viscosity > 0:
            diam = (b0 + b1 + b2) / 3.0
            for a in range(3):
                lfrc[a] = lvel[a] * (-np.pi * diam * diam * diam * viscosity)
                lfrc[3 + a] = lvel[3 + a] * (-3.0 * np.pi * diam * viscosity)
        if density > 0:
            lfrc[3] -= 0.5 * density * b1 * b2 * abs(lvel[3]) * lvel[3]
            lfrc[4] -= 0.5 * density * b0 * b2 * abs(lvel[4]) * lvel[4]
            lfrc[5] -= 0.5 * density * b0 * b1 * abs(lvel[5]) * lvel[5]
            lfrc[0] -= density * b0 * (b1 * b1 * b1 * b1 + b2 * b2 * b2 * b2) * abs(lvel[0]) * lvel[0] / 64.0
            lfrc[1] -= density * b1 * (b0 * b0 * b0 * b0 + b2 * b2 * b2 * b2) * abs(lvel[1]) * lvel[1] / 64.0
            lfrc[2] -= density * b2 * (b0 * b0 * b0 * b0 + b1 * b1 * b1 * b1) * abs(lvel[2]) * lvel[2] / 64.0
        for a in range(3):
            torque[a] = R[a, 0] * lfrc[0] + R[a, 1] * lfrc[1] + R[a, 2] * lfrc[2]
            force[a] = R[a, 0] * lfrc[3] + R[a, 1] * lfrc[4] + R[a, 2] * lfrc[5]
        add_wrench(p, S, i, x, force, torque, out)
    for k in range(int(p[F + F_NELL])):
        r = int(p[F + F_ELL]) + k * ELL_SIZE
        i = int(p[r])
        if p[bo + i * BODY_SIZE + B_MASS] < MJ_MINVAL:
            continue
        _frame(p, xpos, xmat, i, r + 1, r + 4, R, x, work)
        _local_velocity(p, F, vel, i, R, x, lvel)
        for a in range(6):
            lfrc[a] = 0.0
        _added_mass_forces(p, r, lvel, density, lfrc)
        _viscous_forces(p, r, lvel, density, viscosity, lfrc)
        for a in range(3):
            torque[a] = R[a, 0] * lfrc[0] + R[a, 1] * lfrc[1] + R[a, 2] * lfrc[2]
            force[a] = R[a, 0] * lfrc[3] + R[a, 1] * lfrc[4] + R[a, 2] * lfrc[5]
        add_wrench(p, S, i, x, force, torque, out)


@njit(cache=True, inline="always")
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def _added_mass_forces(p, r, lvel, density, lfrc):
    """MuJoCo's mj_addedMassForces without the acceleration term (its local_accels is NULL)."""
    w0, w1, w2 = lvel[0], lvel[1], lvel[2]
    v0, v1, v2 = lvel[3], lvel[4], lvel[5]
    m0, m1, m2 = (density * p[r + 11] * v0, density * p[r + 12] * v1, density * p[r + 13] * v2)
    i0, i1, i2 = (density * p[r + 14] * w0, density * p[r + 15] * w1, density * p[r + 16] * w2)
    f0, f1, f2 = _cross(m0, m1, m2, w0, w1, w2)
    t0, t1, t2 = _cross(m0, m1, m2, v0, v1, v2)
    u0, u1, u2 = _cross(i0, i1, i2, w0, w1, w2)
    lfrc[0] += t0
    lfrc[1] += t1
    lfrc[2] += t2
    lfrc[0] += u0
    lfrc[1] += u1
    lfrc[2] += u2
    lfrc[3] += f0
    lfrc[4] += f1
    lfrc[5] += f2


@njit(cache=True, inline="always")
def _max_moment(s0, s1, s2):
    """MuJoCo's mji_ellipsoid_max_moment(size, dir) with size[dir] = s0 and the other two s1, s2."""
    d = max(s1, s2)
    return 8.0 / 15.0 * np.pi * s0 * (d * d) * (d * d)


@njit(cache=True)
def _viscous_forces(p, r, lvel, density, viscosity, lfrc):
    """MuJoCo's mj_viscousForces (module docstring), term for term."""
    s0, s1, s2 = p[r + 8], p[r + 9], p[r + 10]
    blunt, slender, angular, kutta, magnus = p[r + 17], p[r + 18], p[r + 19], p[r + 20], p[r + 21]
    w0, w1, w2 = lvel[0], lvel[1], lvel[2]
    v0, v1, v2 = lvel[3], lvel[4], lvel[5]
    volume = 4.0 / 3.0 * np.pi * s0 * s1 * s2
    d_max = max(max(s0, s1), s2)
    d_min = min(min(s0, s1), s2)
    d_mid = s0 + s1 + s2 - d_max - d_min
    A_max = np.pi * d_max * d_mid
    g0, g1, g2 = _cross(w0, w1, w2, v0, v1, v2)
    scale = magnus * density * volume
    g0, g1, g2 = g0 * scale, g1 * scale, g2 * scale
    a, b, c = s1 * s2, s2 * s0, s0 * s1
    proj_denom = (a * a) * (a * a) * (v0 * v0) + (b * b) * (b * b) * (v1 * v1) + (c * c) * (c * c) * (v2 * v2)
    proj_num = (a * v0) * (a * v0) + (b * v1) * (b * v1) + (c * v2) * (c * v2)
    A_proj = np.pi * np.sqrt(proj_denom / max(MJ_MINVAL, proj_num))
    n0, n1, n2 = (a * a) * v0, (b * b) * v1, (c * c) * v2
    speed = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    cos_alpha = proj_num / max(MJ_MINVAL, speed * proj_denom)
    k0, k1, k2 = _cross(n0, n1, n2, v0, v1, v2)
    scale = kutta * density * cos_alpha * A_proj
    k0, k1, k2 = k0 * scale, k1 * scale, k2 * scale
    kf0, kf1, kf2 = _cross(k0, k1, k2, v0, v1, v2)
    sphere = 2.0 / 3.0 * (s0 + s1 + s2)
    lin_visc_force = 3.0 * np.pi * sphere
    lin_visc_torque = np.pi * sphere * sphere * sphere
    I_max = 8.0 / 15.0 * np.pi * d_mid * (d_max * d_max) * (d_max * d_max)
    II0, II1, II2 = _max_moment(s0, s1, s2), _max_moment(s1, s2, s0), _max_moment(s2, s0, s1)
    mv0 = w0 * (angular * II0 + slender * (I_max - II0))
    mv1 = w1 * (angular * II1 + slender * (I_max - II1))
    mv2 = w2 * (angular * II2 + slender * (I_max - II2))
    drag_lin = viscosity * lin_visc_force + density * speed * (A_proj * blunt + slender * (A_max - A_proj))
    drag_ang = viscosity * lin_visc_torque + density * np.sqrt(mv0 * mv0 + mv1 * mv1 + mv2 * mv2)
    lfrc[0] -= drag_ang * w0
    lfrc[1] -= drag_ang * w1
    lfrc[2] -= drag_ang * w2
    lfrc[3] += g0 + kf0 - drag_lin * v0
    lfrc[4] += g1 + kf1 - drag_lin * v1
    lfrc[5] += g2 + kf2 - drag_lin * v2


@njit(cache=True)
def box_velocity_derivative(p, S, xpos, xmat, vel, h, D):
    """D (nv, nv) += d qfrc_fluid / d qvel of the inertia-box bodies (MuJoCo's mjd_inertiaBoxFluid): J^T B J with J
    the body's Jacobian at its centre of mass in its principal frame (rows: rotation, translation) and B the
    derivative of each local force component with respect to its own velocity component."""
    F = int(p[extension_start(p) + X_FLUID])
    if F < 0:
        return
    do = int(p[H_DOF])
    density, viscosity = p[F + F_DENSITY], p[F + F_VISCOSITY]
    nv = D.shape[0]
    R, work = np.empty((3, 3)), np.empty((3, 3))
    x, lvel, B = np.empty(3), np.empty(6), np.empty(6)
    J = np.zeros((6, nv))
    for k in range(int(p[F + F_NBOX])):
        i, r = _box_motion(p, F, k, xpos, xmat, vel, h, R, x, work, lvel)
        if i < 0:
            continue
        b0, b1, b2 = p[r + 5], p[r + 6], p[r + 7]
        for a in range(6):
            B[a] = 0.0
        if viscosity > 0:
            diam = (b0 + b1 + b2) / 3.0
            for a in range(3):
                B[a] += -np.pi * diam * diam * diam * viscosity
                B[3 + a] += -3.0 * np.pi * diam * viscosity
        if density > 0:
            B[0] += -density * b0 * (b1 * b1 * b1 * b1 + b2 * b2 * b2 * b2) * 2 * abs(lvel[0]) / 64.0
            B[1] += -density * b1 * (b0 * b0 * b0 * b0 + b2 * b2 * b2 * b2) * 2 * abs(lvel[1]) / 64.0
            B[2] += -density * b2 * (b0 * b0 * b0 * b0 + b1 * b1 * b1 * b1) * 2 * abs(lvel[2]) / 64.0
            B[3] += -0.5 * density * b1 * b2 * 2 * abs(lvel[3])
            B[4] += -0.5 * density * b0 * b2 * 2 * abs(lvel[4])
            B[5] += -0.5 * density * b0 * b1 * 2 * abs(lvel[5])
        for a in range(6):
            for c in range(nv):
                J[a, c] = 0.0
        d = last_dof(p, i)
        while d >= 0:
            w0, w1, w2 = S[d, 0], S[d, 1], S[d, 2]
            jx = S[d, 3] + w1 * x[2] - w2 * x[1]
            jy = S[d, 4] + w2 * x[0] - w0 * x[2]
            jz = S[d, 5] + w0 * x[1] - w1 * x[0]
            for a in range(3):  # rows in the principal frame: R^T (rotation; translation at the com)
                J[a, d] = R[0, a] * w0 + R[1, a] * w1 + R[2, a] * w2
                J[3 + a, d] = R[0, a] * jx + R[1, a] * jy + R[2, a] * jz
            d = int(p[do + d * DOF_SIZE + D_PARENT])
        for a in range(6):
            if B[a] == 0.0:
                continue
            for e in range(nv):
                if J[a, e] == 0.0:
                    continue
                for c in range(nv):
                    D[e, c] += J[a, e] * B[a] * J[a, c]


__all__ = ["fluid_forces", "box_velocity_derivative", "add_wrench", "FLUID_HEADER", "BOX_SIZE", "ELL_SIZE"]
