"""Contacts in the event-driven scheme: their guards and the acceleration-level problem of an event, compiled.

A contact unit (table.CONTACT, CONTACT1) has two guards, each >= 0 while its mode is right (an event where one
crosses 0; rbody.engine.constraints.events locates it):

    open (mode 0)      A: its gap g [m]                                         B: +inf
    sticking (mode 1)  A: min(lambda_n, mu lambda_n - |lambda_t|) [N]           B: +inf
    sliding (mode 2)   A: lambda_n [N]                                          B: s . s0 [m/s], the slip along
                                                                                   the direction it began with

A sticking face has more corners than it needs (four corners of a box on a plane: twelve rows of rank six), and
the rigid model leaves the distribution of the forces among them open; the guards read the distribution in which
the tangential load follows the normal load (rbody.engine.constraints.cone.stick_polish: least sum
|lambda_t|^2 / lambda_n), so that every corner is inside its cone exactly when the face as a whole can hold (a
block on an incline at mu = tan(alpha) (1 + 1e-6) sticks; the least-norm distribution would put the uphill corners
outside their cones).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.contacts.geometry import tangents
from rbody.engine.contacts.rows import contact_geometry
from rbody.engine.multibody import H_BODIES, _effective_qpos, workspace_size
from rbody.engine.constraints import dynamics as dyn
from rbody.engine.constraints.cone import NORMAL, TANGENT, TANGENT2, stick_polish
from rbody.engine.constraints.jacobians import mode_at, row_count, unit_at, unit_count
from rbody.engine.constraints.sliding import SLIDING, sliding_columns
from rbody.engine.constraints.solver import RANK_RTOL, lower_solve_rows
from rbody.engine.constraints.table import CONTACT, CONTACT1, U_BOUND, U_KIND, U_ROW0, U_SLIP


@njit(cache=True)
def _rows_state(p, y):
    """(M, f, J, jdot, g, F, share, w) at state y: M, f (sliding dofs' friction included), every row and the force
    columns F (sliding_columns); w keeps the tree's kinematics there."""
    nq, nv, _n = dyn.sizes(p)
    rows = row_count(p)
    M, f = np.empty((nv, nv)), np.empty(nv)
    J, F = np.empty((rows, nv)), np.empty((rows, nv))
    jdot, g, share = np.empty(rows), np.empty(rows), np.empty(rows)
    w = np.empty(workspace_size(p))
    q = np.empty(nq)
    _effective_qpos(p, y, q, 0)
    acc = np.empty((int(p[H_BODIES]), 6))
    a0, na = dyn.act_range(p)
    dyn.snapshot(p, q, y[nq:nq + nv], y[a0:a0 + na], M, f, J, jdot, g, w, acc)
    dyn.add_sliding_friction(p, f, J)
    sliding_columns(p, w, J, y[nq:nq + nv], F, share)
    return M, f, J, jdot, g, F, share, w


@njit(cache=True)
def event_problem(p, y, index, W, b):
    """The acceleration-level problem over the rows `index` (m,) at state y in the mode written in p: W (m, m) =
    J M^-1 F^T (F the force columns: a sliding contact's J_n - mu s_hat . J_t), b (m,) = J M^-1 f + J' v."""
    nq, nv, _n = dyn.sizes(p)
    M, f, J, jdot, g, F, share, w = _rows_state(p, y)
    L = np.linalg.cholesky(M)
    a0 = dyn.upper_solve(L, dyn.lower_solve(L, f))
    m = index.shape[0]
    AJ, AF = lower_solve_rows(L, J, index, m), lower_solve_rows(L, F, index, m)
    for c in range(m):
        acc = jdot[index[c]]
        for d in range(nv):
            acc += J[index[c], d] * a0[d]
        b[c] = acc
    W[:, :] = AJ.T @ AF


@njit(cache=True)
def contact_guards(p, y, out_a, out_b):
    """out_a, out_b (contact units,): the guards A and B of every contact unit, in unit order (module docstring)."""
    nq, nv, _n = dyn.sizes(p)
    rows = row_count(p)
    M, f, J, jdot, g, F, share, w = _rows_state(p, y)
    v = y[nq:nq + nv]
    held = np.empty(rows)
    dyn.held_rows(p, held)
    index = np.empty(rows, dtype=np.int64)
    m = 0
    for a in range(rows):
        if held[a] != 0.0:
            index[m] = a
            m += 1
    lam_rows = np.zeros(rows)
    modes = mode_at(p)
    if m > 0:
        L = np.linalg.cholesky(M)
        a0 = dyn.upper_solve(L, dyn.lower_solve(L, f))
        AJ, AF = lower_solve_rows(L, J, index, m), lower_solve_rows(L, F, index, m)
        b = np.empty(m)
        for c in range(m):
            acc = jdot[index[c]]
            for d in range(nv):
                acc += J[index[c], d] * a0[d]
            b[c] = acc
        W = AJ.T @ AF
        lam = np.linalg.lstsq(W, -b, RANK_RTOL)[0]
        role = np.zeros(m, dtype=np.int64)
        mu = np.zeros(m)
        lo, hi = np.full(m, -np.inf), np.full(m, np.inf)
        where = np.full(rows, -1, dtype=np.int64)
        for c in range(m):
            where[index[c]] = c
        cones = False
        for k in range(unit_count(p)):
            u = unit_at(p, k)
            kind = int(p[u + U_KIND])
            if (kind == CONTACT or kind == CONTACT1) and p[modes + k] != 0.0:
                r0 = int(p[u + U_ROW0])
                c = where[r0]
                role[c], lo[c] = NORMAL, 0.0
                if kind == CONTACT and p[modes + k] == 1.0:
                    role[c + 1], role[c + 2], mu[c + 1] = TANGENT, TANGENT2, p[u + U_BOUND]
                    cones = True
        if cones:
            stick_polish(W, b, lo, hi, role, mu, lam, 8)
        for c in range(m):
            lam_rows[index[c]] = lam[c]
    j = 0
    normal, point, t1, t2 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        if kind != CONTACT and kind != CONTACT1:
            continue
        r0 = int(p[u + U_ROW0])
        mode = p[modes + k]
        out_b[j] = np.inf
        if mode == 0.0:
            out_a[j] = g[r0]
        elif mode == 1.0:
            out_a[j] = lam_rows[r0]
            if kind == CONTACT:
                friction = np.sqrt(lam_rows[r0 + 1] ** 2 + lam_rows[r0 + 2] ** 2)
                out_a[j] = min(lam_rows[r0], p[u + U_BOUND] * lam_rows[r0] - friction)
        else:
            out_a[j] = lam_rows[r0]
            contact_geometry(p, w, u, normal, point)
            tangents(normal, t1, t2)
            s1, s2 = 0.0, 0.0
            for d in range(nv):
                s1 += J[r0 + 1, d] * v[d]
                s2 += J[r0 + 2, d] * v[d]
            along = 0.0
            for a in range(3):
                along += (s1 * t1[a] + s2 * t2[a]) * p[u + U_SLIP + a]
            out_b[j] = along
        j += 1


@njit(cache=True)
def slip_velocities(p, y, out):
    """out (units, 3): each contact unit's slip velocity [m/s, world] (the tangential velocity of geom b's material
    point at the contact point relative to geom a's); 0 for the other units."""
    nq, nv, _n = dyn.sizes(p)
    M, f, J, jdot, g, F, share, w = _rows_state(p, y)
    v = y[nq:nq + nv]
    normal, point, t1, t2 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        for a in range(3):
            out[k, a] = 0.0
        if int(p[u + U_KIND]) != CONTACT:
            continue
        r0 = int(p[u + U_ROW0])
        contact_geometry(p, w, u, normal, point)
        tangents(normal, t1, t2)
        s1, s2 = 0.0, 0.0
        for d in range(nv):
            s1 += J[r0 + 1, d] * v[d]
            s2 += J[r0 + 2, d] * v[d]
        for a in range(3):
            out[k, a] = s1 * t1[a] + s2 * t2[a]


@njit(cache=True)
def tangent_frames(p, y, out):
    """out (units, 3, 3): each contact unit's frame (normal, t1, t2 as rows) at state y."""
    nq, nv, _n = dyn.sizes(p)
    M, f, J, jdot, g, F, share, w = _rows_state(p, y)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        if kind != CONTACT and kind != CONTACT1:
            continue
        point = np.empty(3)
        contact_geometry(p, w, u, out[k, 0], point)
        tangents(out[k, 0], out[k, 1], out[k, 2])


__all__ = ["event_problem", "contact_guards", "slip_velocities", "tangent_frames", "SLIDING"]


@njit(cache=True)
def closing_time(p, y):
    """The earliest time [s] at which an open contact closes at its present rate (its gap over its approach speed;
    +inf when none approaches): the event-driven run steps no further than just past it, so that a fast body
    cannot pass through another within one step (its gap closing and opening again unseen)."""
    nq, nv, _n = dyn.sizes(p)
    M, f, J, jdot, g, F, share, w = _rows_state(p, y)
    v = y[nq:nq + nv]
    modes = mode_at(p)
    earliest = np.inf
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        if (kind != CONTACT and kind != CONTACT1) or p[modes + k] != 0.0:
            continue
        r0 = int(p[u + U_ROW0])
        rate = 0.0
        for d in range(nv):
            rate += J[r0, d] * v[d]
        if rate < 0.0 and g[r0] > 0.0:
            earliest = min(earliest, g[r0] / -rate)
    return earliest
