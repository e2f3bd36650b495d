"""The contact observables of a constrained run: how many contacts hold, and where and how hard each pushes.

Columns: one per candidate contact of the constraint table (meta["contacts"]: "<geom a>/<geom b>" and the
candidate's slot, e.g. "floor/box[3]" for a box's fourth corner), geoms in MuJoCo's order (type codes ascending).

    contacts (T, *batch)                       the number of candidates whose normal force is > 0
    contact_distance (T, *batch, k) [m]        signed distance less the pair's margin (Contact.margin; < 0:
                                               overlap, round-off in the rigid limit);
                                               +inf where the candidate is not a contact point in that
                                               configuration (geometry.APART: a capsule's end at its closest point)
    contact_point (T, *batch, k, 3) [m]        the candidate's point, world frame: on the face where the nearest
                                               feature is flat (a plane, a box's face, a cylinder's cap), else
                                               midway between the surfaces (MuJoCo's con.pos is midway: the two
                                               differ by half the distance, 0 at touch)
    contact_normal (T, *batch, k, 3)           its unit normal, from geom a towards geom b, world frame; point
                                               and normal NaN where contact_distance is +inf
    contact_normal_force (T, *batch, k) [N]    the force geom a exerts on geom b along the normal (>= 0)
    contact_friction_force (T, *batch, k, 2) [N]  the friction force on geom b along the contact frame's
                                               tangents (rbody.engine.contacts.geometry.tangents); 0 for condim 1
    contact_spin_torque (T, *batch, k) [N m]   the torsional friction torque on geom b about the normal; 0 below
                                               condim 4
    contact_rolling_torque (T, *batch, k, 2) [N m]  the rolling friction torque on geom b about the tangents; 0
                                               below condim 6

Forces are those of the constraint_force observable (time-stepping: the step's impulse over dt, its mean force).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.jacobians import row_count, unit_at
from rbody.engine.contacts.geometry import APART
from rbody.engine.contacts.rows import GEOMETRY_WORK, candidate, pair_candidates
from rbody.engine.constraints.table import U_DOF
from rbody.engine.multibody import H_BODIES, _effective_qpos, workspace_size


@njit(cache=True)
def contact_frames(p, y, units, dist, point, normal):
    """At the state y (n,): dist (k,), point (k, 3), normal (k, 3) of the contact units listed in units (k,)."""
    nq, nv, _n = dyn.sizes(p)
    q = np.empty(nq)
    _effective_qpos(p, y, q, 0)
    from_rows = row_count(p)
    w = np.empty(workspace_size(p))
    M = np.empty((nv, nv))
    f = np.empty(nv)
    J = np.zeros((from_rows, nv))
    jdot, g = np.zeros(from_rows), np.zeros(from_rows)
    acc = np.empty((int(p[H_BODIES]), 6))
    wanted = np.zeros(from_rows)
    a0, na = dyn.act_range(p)
    dyn.snapshot(p, q, y[nq:nq + nv], y[a0:a0 + na], M, f, J, jdot, g, w, acc, wanted)  # the frames, no rows
    work = np.empty(GEOMETRY_WORK)  # a pair's candidates, computed once for all its units (they follow each other)
    pair = -1
    for i in range(units.shape[0]):
        u = unit_at(p, units[i])
        k = int(p[u + U_DOF])
        if pair < 0 or units[i] - k != pair:
            pair_candidates(p, w, u, work)
            pair = units[i] - k
        dist[i] = candidate(work, k, normal[i], point[i])
        if dist[i] == APART:  # not a contact point: the pair's work holds nothing of it (was left unwritten there)
            point[i, :] = np.nan
            normal[i, :] = np.nan


def contact_observables(table, params: np.ndarray, out: np.ndarray, rows_force, units: np.ndarray,
                        pushing=None) -> dict:
    """The observables of the module docstring of the contact units `units` (k,) from the saved states out (S, B,
    n) and rows_force(which) -> (S, B, len(which)) the forces of rows `which` of a run; pushing(which) -> (S, B) how
    many of rows `which` push (> 0) at each sample, or None (from rows_force). Every per-candidate one (S, B,
    candidates, ...) is computed on first access (a hand's 3,954 candidates over 10 s at 2 ms: gigabytes, where a
    user may read none): the geometric ones (contact_distance, contact_point, contact_normal) all three at once, the
    forces all four at once, `contacts` alone."""
    S, B = out.shape[:2]
    k = len(units)
    index = np.array(units, dtype=np.int64)
    frames: dict = {}

    def geometry(name: str):
        def value():
            if not frames:
                dist, point, normal = np.empty((S, B, k)), np.empty((S, B, k, 3)), np.empty((S, B, k, 3))
                for b in range(B):
                    p = np.array(params[b], dtype=np.float64)
                    for s in range(S):
                        contact_frames(p, out[s, b], index, dist[s, b], point[s, b], normal[s, b])
                frames.update(contact_distance=dist, contact_point=point, contact_normal=normal)
            return frames[name]
        return value

    first = table.first_rows[index]
    counts = table.unit_rows[index]  # condim: normal, tangents, spin, rolling
    loads: dict = {}

    def load(name: str):
        def value():
            if not loads:
                # each contact's rows padded to 6 (a row past its condim: the normal's again, zeroed below)
                which = first[:, None] + np.where(np.arange(6)[None, :] < counts[:, None], np.arange(6)[None, :], 0)
                forces = rows_force(which.ravel()).reshape(S, B, k, 6)
                forces = np.where((np.arange(6)[None, :] < counts[:, None])[None, None], forces, 0.0)
                loads.update(contact_normal_force=forces[..., 0], contact_friction_force=forces[..., 1:3],
                             contact_spin_torque=forces[..., 3], contact_rolling_torque=forces[..., 4:6])
            return loads[name]
        return value

    def touching():
        return pushing(first) if pushing is not None else (rows_force(first) > 0).sum(axis=-1)

    return {"contacts": touching, "contact_distance": geometry("contact_distance"),
            "contact_point": geometry("contact_point"), "contact_normal": geometry("contact_normal"),
            **{name: load(name) for name in ("contact_normal_force", "contact_friction_force", "contact_spin_torque",
                                             "contact_rolling_torque")}}


__all__ = ["contact_observables", "contact_frames"]
