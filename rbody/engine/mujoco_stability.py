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
    y: (B, n) the 3-D engine's states, params: (B, m) its rows (the model mujoco_steps steps).
    A tree whose dofs fall into groups that nothing couples (free bodies side by side: M, H and the Jacobians
    block-diagonal) has the union of its groups' eigenvalues: each group is linearised on its own, the groups of one
    size together, under the whole tree's growth and starting step (coupled_groups); the rate is the largest."""
    mode = MODES[method]
    batch, nv = jq.shape[0], jq.shape[1]
    matrices = np.empty((batch, 2, nv, nv))
    for b in range(batch):
        step_matrices(np.ascontiguousarray(y[b]), np.ascontiguousarray(params[b]), mode, elements, matrices[b])
    mass, derivative = matrices[:, 0], matrices[:, 1]
    if not np.all(np.isfinite(jq)):
        return np.full(batch, np.inf)
    damping = -mass @ jv  # d qfrc / d qvel: its symmetric part damps, the rest (gyroscopic) only turns
    jv = -np.linalg.solve(mass, 0.5 * (damping + np.swapaxes(damping, 1, 2)))
    if not np.all(np.isfinite(jv)):
        return np.full(batch, np.inf)
    groups = [coupled_groups(jq[b], jv[b], mass[b], derivative[b]) for b in range(batch)]
    whole = np.array([len(found) == 1 for found in groups])
    rates = np.zeros(batch)
    if np.any(whole):  # (a batch of trees that couple every dof: linearised together)
        pick = np.flatnonzero(whole)
        rates[pick] = _rate(jq[pick], jv[pick], mass[pick], derivative[pick],
                            np.max(np.abs(np.linalg.eigvals(jq[pick])), axis=-1), _growth(jq[pick], jv[pick]))
    for b in np.flatnonzero(~whole):
        blocks = [[m[np.ix_(g, g)] for m in (jq[b], jv[b], mass[b], derivative[b])] for g in groups[b]]
        w2 = max(float(np.max(np.abs(np.linalg.eigvals(block[0])))) for block in blocks)  # the whole tree's
        growth = max(float(_growth(block[0][None], block[1][None])[0]) for block in blocks)
        by_size: dict[int, list] = {}
        for block in blocks:
            by_size.setdefault(block[0].shape[0], []).append(block)
        for same in by_size.values():  # the groups of one size as one batch
            parts = [np.stack([block[k] for block in same]) for k in range(4)]
            count = len(same)
            rates[b] = max(rates[b], float(np.max(_rate(*parts, np.full(count, w2), np.full(count, growth)))))
    return rates


def coupled_groups(jq: np.ndarray, jv: np.ndarray, mass: np.ndarray, derivative: np.ndarray) -> list[np.ndarray]:
    """The dofs (nv,) in groups that no entry of jq, jv, M or H's derivative couples (each ascending, in order of
    their first dof): the connected components of those matrices' joint pattern."""
    from scipy.sparse.csgraph import connected_components

    pattern = (jq != 0.0) | (jv != 0.0) | (mass != 0.0) | (derivative != 0.0)
    count, labels = connected_components(pattern | pattern.T, directed=False)
    return [np.flatnonzero(labels == k) for k in np.unique(labels)] if count > 1 else [np.arange(jq.shape[0])]


def _growth(jq: np.ndarray, jv: np.ndarray) -> np.ndarray:
    """(B,) sigma >= 0: the largest real part of the linearised motion's eigenvalues, [[0, I], [jq, jv]]."""
    nv = jq.shape[1]
    motion = np.zeros((jq.shape[0], 2 * nv, 2 * nv))
    motion[:, :nv, nv:] = np.eye(nv)
    motion[:, nv:, :nv] = jq
    motion[:, nv:, nv:] = jv
    return np.maximum(np.max(np.linalg.eigvals(motion).real, axis=-1), 0.0)


def _rate(jq: np.ndarray, jv: np.ndarray, mass: np.ndarray, derivative: np.ndarray, w2: np.ndarray,
          growth: np.ndarray) -> np.ndarray:
    """(B,) 2 / h* of each element (jq, jv damping only, M, H's derivative (B, k, k)), its step bracketed from
    2 / sqrt(w2) and held against the motion's growth (step_rate)."""
    batch, nv = jq.shape[0], jq.shape[1]
    eye = np.eye(nv)

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

    if not np.all(np.isfinite(w2)):
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
