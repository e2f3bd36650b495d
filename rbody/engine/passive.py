"""Passive forces of the force elements, as MuJoCo's engine_passive.c adds them to qfrc_passive (the joints' own
springs and dampers are the tree's: rbody.engine.multibody.passive).

Tendon spring-damper (mj_springdamper): with x the distance of the tendon length L outside its dead band
[low, high] (0 inside), the force along the tendon is -stiffness x - damping L', applied as J^T f.
"""

from __future__ import annotations

from numba import njit

from rbody.engine.elements import T_DAMP, T_HIGH, T_LOW, T_STIFF, TEN_SIZE, X_NTEN, X_TEN, extension_start
from rbody.engine.multibody import H_DOFS


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


__all__ = ["tendon_passive", "tendon_damping_derivative"]
