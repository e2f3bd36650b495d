"""Passive forces of the force elements, as MuJoCo's engine_passive.c adds them to qfrc_passive (the joints' own
springs and dampers are the tree's: rbody.engine.multibody.passive).

Tendon spring-damper (mj_springdamper): with x the distance of the tendon length L outside its dead band
[low, high] (0 inside), the force along the tendon is -stiffness x - damping L', applied as J^T f.
Gravity compensation (mj_gravcomp): an upward force gravcomp m g at each body's centre of mass, applied as
J_com^T f (a passive force, or an actuator force on the degrees of freedom of joints with actuatorgravcomp:
rbody.engine.system).
"""

from __future__ import annotations

from numba import njit

from rbody.engine.actuation import add_point_jacobian
from rbody.engine.elements import (T_DAMP, T_HIGH, T_LOW, T_STIFF, TEN_SIZE, X_GRAVCOMP, X_NTEN, X_TEN,
                                   extension_start)
from rbody.engine.multibody import B_MASS, BODY_SIZE, H_BODIES, H_BODY, H_DOFS, H_GRAVITY


@njit(cache=True)
def tendon_passive(p, length, velocity, J, qfrc):
    """qfrc (nv,) += J^T (-stiffness x - damping L') over the tendons (module docstring); length, velocity (nten,),
    J (nten, nv) from rbody.engine.actuation.tendon_kinematics."""
    E = extension_start(p)
    nten, nv = int(p[E + X_NTEN]), int(p[H_DOFS])
    for t in range(nten):
        r = int(p[E + X_TEN]) + t * TEN_SIZE
        stiffness, damping = p[r + T_STIFF], p[r + T_DAMP]
        if stiffness == 0.0 and damping == 0.0:
            continue
        value, low, high = length[t], p[r + T_LOW], p[r + T_HIGH]
        x = value - high if value > high else (value - low if value < low else 0.0)
        force = -stiffness * x - damping * velocity[t]
        if force != 0.0:
            for d in range(nv):
                qfrc[d] += J[t, d] * force


@njit(cache=True)
def tendon_damping_derivative(p, J, D):
    """D (nv, nv) += d(tendon damper force)/d qvel = -damping J^T J (MuJoCo's mjd_passive_vel)."""
    E = extension_start(p)
    nten, nv = int(p[E + X_NTEN]), int(p[H_DOFS])
    for t in range(nten):
        damping = p[int(p[E + X_TEN]) + t * TEN_SIZE + T_DAMP]
        if damping == 0.0:
            continue
        for a in range(nv):
            if J[t, a] == 0.0:
                continue
            for c in range(nv):
                D[a, c] -= damping * J[t, a] * J[t, c]


@njit(cache=True)
def gravity_compensation(p, S, h, scratch, out):
    """out (nv,) = sum over bodies of J_com^T (0, 0, gravcomp m g): S (nv, 6) the motion subspaces, h (nb, 3) each
    body's m c (world), both from the tree's workspace; scratch (6,) temporary."""
    E = extension_start(p)
    nb, nv = int(p[H_BODIES]), int(p[H_DOFS])
    bo = int(p[H_BODY])
    at = int(p[E + X_GRAVCOMP])
    g = p[H_GRAVITY]
    up, point = scratch[0:3], scratch[3:6]
    up[0], up[1], up[2] = 0.0, 0.0, 1.0
    for d in range(nv):
        out[d] = 0.0
    for i in range(nb):
        coefficient = p[at + i]
        if coefficient == 0.0 or g == 0.0:
            continue
        mass = p[bo + i * BODY_SIZE + B_MASS]
        for a in range(3):
            point[a] = h[i, a] / mass
        add_point_jacobian(p, S, i, point, up, coefficient * mass * g, out)


__all__ = ["tendon_passive", "tendon_damping_derivative", "gravity_compensation"]
