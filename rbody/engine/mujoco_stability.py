"""The largest step at which MuJoCo's integrators stay stable on a tree, from their linearised one-step map.

MuJoCo's integrators (rbody.engine.mujoco_steps) take the damping they treat implicitly out of the explicit
stability limit: the Euler step solves H = M + h B (B the joints' damping), implicitfast and implicit
H = M - h D (D the velocity derivative of the passive and actuator forces, implicit: with the bias's). A
position servo's stiffness stays explicit. Linearised about a state, with qacc ~ Jq dq + Jv dv (the
acceleration's derivatives along the configuration's tangent and the velocity) and W = (M - h D)^-1 M:

    dv+ = dv + h W (Jq dq + Jv dv)          dq+ = dq + h dv+

Of Jv only the damping counts: M Jv's symmetric part (the gyroscopic and Coriolis part, which turns the velocity
without changing its energy, is left to the run's own check of non-finite states, as for every explicit term of
a rotation: Euler's method on a free body's wobble grows by (1 + (h w)^2)^(1/2) a step at any h).
A step h is stable while the spectral radius of this map grows no faster than the motion itself does, within a
factor: ln(radius) <= 2 sigma h (sigma >= 0 the largest real part of the linearised motion's eigenvalues; a
first-order step's growth on a growing mode differs from exp(sigma h) at second order in sigma h). On one mode
q'' = -w^2 q - c q' this is, in closed form:
- c implicit (the joint's damping under mujoco_euler, kv under implicitfast): h < (c + sqrt(c^2 + 4 w^2)) / w^2;
- c explicit (an actuator's kv under mujoco_euler): h < (sqrt(c^2 + 4 w^2) - c) / w^2;
- c = 0: h < 2 / w, the limit of semi-implicit Euler.
A servo whose force sits at its forcerange bound at the state has neither stiffness nor damping there, but gains
both back as it nears its target: the scene's rate is the larger of the rates with the force clamps as they are
and with them lifted (unclamped). The largest stable step h* is found by doubling from 2 / w (w^2 the spectral
radius of Jq) and bisection; an unstable equilibrium (sigma > 0) also bounds it by 2 / sigma. The rate handed to
the stability check is 2 / h*, so that its rule h <= 2 / rate (the records' interval beta = 2) reads h <= h*.
"""

from __future__ import annotations

import numpy as np

from rbody.engine.elements import A_FORCELIM, ACT_SIZE, X_ACT, X_JNTLIM, X_NU, extension_start
from rbody.engine.mujoco_steps import EULER, IMPLICIT, IMPLICITFAST, step_matrices
from rbody.engine import multibody as mb

MODES = {"mujoco_euler": EULER, "implicitfast": IMPLICITFAST, "implicit": IMPLICIT}
# A step is stable while the map's spectral radius is within this relative margin of the motion's own growth
# (an undamped mode's eigenvalues lie on the unit circle, computed to round-off of the matrix's size).
RADIUS_MARGIN = 1e-6
# On a growing mode a first-order step's growth differs from the motion's at second order in h sigma: a step is
# stable while its growth does not exceed this many times the motion's.
GROWTH_FACTOR = 2.0
BISECTIONS = 30
DOUBLINGS = 40


def step_rate(method: str, jq: np.ndarray, jv: np.ndarray, y: np.ndarray, params: np.ndarray,
              elements: bool) -> np.ndarray:
    """(B,) 2 / h* [1/s] (module docstring), 0 where no step is unstable within 2^DOUBLINGS times 2 / w.

    jq, jv: (B, nv, nv) d qacc / d q (tangent coordinates) and d qacc / d qvel at y [1/s^2, 1/s];
    y: (B, n) the 3-D engine's states, params: (B, m) its rows (the model mujoco_steps steps)."""
    mode = MODES[method]
    batch, nv = jq.shape[0], jq.shape[1]
    matrices = np.empty((batch, 2, nv, nv))
    for b in range(batch):
        step_matrices(np.ascontiguousarray(y[b]), np.ascontiguousarray(params[b]), mode, elements, matrices[b])
    mass, derivative = matrices[:, 0], matrices[:, 1]
    eye = np.eye(nv)
    damping = -mass @ jv  # d qfrc / d qvel: its symmetric part damps, the rest (gyroscopic) only turns
    jv = -np.linalg.solve(mass, 0.5 * (damping + np.swapaxes(damping, 1, 2)))
    motion = np.zeros((batch, 2 * nv, 2 * nv))
    motion[:, :nv, nv:] = eye
    motion[:, nv:, :nv] = jq
    motion[:, nv:, nv:] = jv
    growth = np.maximum(np.max(np.linalg.eigvals(motion).real, axis=-1), 0.0)

    def stable(h: np.ndarray) -> np.ndarray:
        w = np.linalg.solve(mass - h[:, None, None] * derivative, mass)
        aq, av = h[:, None, None] * w @ jq, h[:, None, None] * w @ jv
        step = np.empty((batch, 2 * nv, 2 * nv))
        step[:, nv:, :nv] = aq
        step[:, nv:, nv:] = eye + av
        step[:, :nv, :nv] = eye + h[:, None, None] * aq
        step[:, :nv, nv:] = h[:, None, None] * (eye + av)
        with np.errstate(all="ignore"):
            radius = np.max(np.abs(np.linalg.eigvals(step)), axis=-1)
        return np.isfinite(radius) & (np.log(radius) <= GROWTH_FACTOR * growth * h + RADIUS_MARGIN)

    w2 = np.max(np.abs(np.linalg.eigvals(jq)), axis=-1)
    if not (np.all(np.isfinite(w2)) and np.all(np.isfinite(jv))):
        return np.full(batch, np.inf)
    moving = w2 > 0.0
    h0 = np.where(moving, 2.0 / np.sqrt(np.where(moving, w2, 1.0)), 1.0)
    low, high = np.zeros(batch), np.full(batch, np.inf)
    h = h0.copy()
    for _ in range(DOUBLINGS):  # bracket: low stable, high unstable
        ok = stable(h)
        low = np.where(ok, np.maximum(low, h), low)
        high = np.where(ok, high, np.minimum(high, h))
        if np.all(np.isfinite(high) | ~moving) and np.all(low > 0.0):
            break
        h = np.where(np.isfinite(high), np.where(low > 0.0, low, high / 2.0), h * 2.0)
    for _ in range(BISECTIONS):
        bounded = np.isfinite(high)
        mid = np.where(bounded, 0.5 * (low + high), low)
        ok = stable(mid)
        low, high = np.where(ok & bounded, mid, low), np.where(~ok & bounded, mid, high)
    limit = np.where(np.isfinite(high), low, np.inf)
    limit = np.where(growth > 0.0, np.minimum(limit, 2.0 / np.where(growth > 0.0, growth, 1.0)), limit)
    return np.where(moving & np.isfinite(limit) & (limit > 0.0), 2.0 / np.where(limit > 0.0, limit, 1.0),
                    np.where(moving & (limit == 0.0), np.inf, 0.0))


def unclamped(params: np.ndarray) -> np.ndarray:
    """(B, m) a copy of the 3-D engine's rows with every actuator's forcerange and every joint's actuatorfrcrange
    lifted (rbody.engine.elements); the rows themselves are not changed."""
    rows = np.array(params, dtype=np.float64, copy=True)
    for row in rows:
        start = extension_start(row)
        if start >= row.shape[0]:
            continue
        first = int(row[start + X_ACT])
        for i in range(int(row[start + X_NU])):
            row[first + i * ACT_SIZE + A_FORCELIM] = 0.0
        limits = int(row[start + X_JNTLIM])
        for j in range(int(row[mb.H_JOINTS])):
            row[limits + 3 * j] = 0.0
    return rows


__all__ = ["step_rate", "unclamped"]
