"""Sliding contacts in the event-driven scheme: Coulomb's force along the slip, as a column of the held problem.

A contact held on its surface and sliding (mode 2, rbody.engine.constraints.table) has its normal row held (g'' = 0)
and a friction force mu lambda_n against its slip velocity s (in the tangent plane): the force on the tree is
(J_n - mu s_hat . J_t)^T lambda_n, a column F that differs from the row J_n it holds. The held rows then solve
W lambda = r with W = J M^-1 F^T, not symmetric (Painleve's paradox lives here: W can lose its positive diagonal
for large mu; such a problem is refused by the caller through its residual).

The slip direction s_hat is the slip's own, s / |s|, wherever s points within 90 degrees of the direction the mode
began with (kept in the unit's record, U_SLIP); beyond that (only after the slip has passed through 0, i.e. past
the event that ends the mode) it is that initial direction, so that the flow is continued smoothly through the
event for the root search (a slip reversing within one RK stage would otherwise make the guard jump).

A face sliding on a face in one direction (several candidates of one pair of bodies sliding at once, their slips
parallel: a box's corners on a plane, translating) takes one direction for all its candidates, the one its slip
had when the mode began, held until the next event (mode SLIDING_HELD). Why: with each corner's own s / |s| the rigid Coulomb model is stiff as the slip tends to 0
(a yaw rate w turns each corner's friction by w r / |s|, a torque response of mu N r^2 / |s|), and an explicit step
is unstable long before the slip is measurable (a block released at mu = tan(alpha) (1 - 1e-6) spun up at
0.6 rad/s^2 from round-off). Exact for a face that translates (the incline); a face that slides and turns keeps
each candidate's own s / |s| (exact, and stiff again where a candidate's slip nears 0: method="moreau" there)."""

from __future__ import annotations

import numpy as np
from numba import njit

from rbody.engine.contacts.geometry import tangents
from rbody.engine.contacts.rows import contact_geometry
from rbody.engine.constraints.jacobians import mode_at, unit_at, unit_count
from rbody.engine.constraints.solver import RANK_RTOL, lower_solve_rows, upper_solve
from rbody.engine.constraints.table import CONTACT, U_BOUND, U_KIND, U_ROW0, U_SLIP

SLIDING = 2.0        # a contact sliding along its own slip
SLIDING_HELD = 3.0   # a contact of a sliding face: along the direction the face's slip had when its mode began


@njit(cache=True)
def slip_direction(p, w, k, u, J, v, out):
    """out (3,) the unit slip direction s_hat of contact unit k (its record at u; module docstring) in the world, and
    returns
    (c1, c2) its components along the contact frame's tangents; w the workspace after the tree's kinematics."""
    normal, point, t1, t2 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    contact_geometry(p, w, u, normal, point)
    tangents(normal, t1, t2)
    r0 = int(p[u + U_ROW0])
    s1, s2 = 0.0, 0.0
    for d in range(v.shape[0]):
        s1 += J[r0 + 1, d] * v[d]
        s2 += J[r0 + 2, d] * v[d]
    along = 0.0
    for a in range(3):
        out[a] = s1 * t1[a] + s2 * t2[a]
        along += out[a] * p[u + U_SLIP + a]
    length = np.sqrt(s1 * s1 + s2 * s2)
    if not (along > 0.0 and length > 0.0) or p[mode_at(p) + k] == SLIDING_HELD:  # the mode's initial direction, in today's tangent plane
        dot = 0.0
        for a in range(3):
            dot += p[u + U_SLIP + a] * normal[a]
        for a in range(3):
            out[a] = p[u + U_SLIP + a] - dot * normal[a]
        length = np.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
    for a in range(3):
        out[a] = out[a] / length if length > 0.0 else 0.0
    c1 = out[0] * t1[0] + out[1] * t1[1] + out[2] * t1[2]
    c2 = out[0] * t2[0] + out[1] * t2[1] + out[2] * t2[2]
    return c1, c2


@njit(cache=True)
def sliding_columns(p, w, J, v, F, share):
    """F (rows, nv) = J with each sliding contact's normal row replaced by its force column J_n - mu s_hat . J_t;
    share (rows,) on its tangent rows -mu (c1, c2) (the tangent forces per unit normal force), 0 elsewhere. Returns
    the number of sliding contacts."""
    rows, nv = J.shape
    for a in range(rows):
        share[a] = 0.0
        for d in range(nv):
            F[a, d] = J[a, d]
    modes = mode_at(p)
    count = 0
    direction = np.empty(3)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        if int(p[u + U_KIND]) != CONTACT or p[modes + k] < SLIDING:
            continue
        count += 1
        r0 = int(p[u + U_ROW0])
        mu = p[u + U_BOUND]
        c1, c2 = slip_direction(p, w, k, u, J, v, direction)
        share[r0 + 1], share[r0 + 2] = -mu * c1, -mu * c2
        for d in range(nv):
            F[r0, d] = J[r0, d] - mu * (c1 * J[r0 + 1, d] + c2 * J[r0 + 2, d])
    return count


@njit(cache=True)
def general_held_solve(L, J, F, held, r, correction, lam_rows):
    """As dynamics.held_solve with force columns F apart from the rows J: lambda on the held rows of least norm
    with (J_h M^-1 F_h^T) lambda = r (least squares, singular values below RANK_RTOL of the largest dropped: the
    redundant corners of a face), correction (nv,) = M^-1 F_h^T lambda. Returns |W lambda - r|_inf."""
    rows, nv = J.shape
    index = np.empty(rows, dtype=np.int64)
    m = 0
    for a in range(rows):
        lam_rows[a] = 0.0
        if held[a] != 0.0:
            index[m] = a
            m += 1
    for d in range(nv):
        correction[d] = 0.0
    if m == 0:
        return 0.0
    AJ = lower_solve_rows(L, J, index, m)
    AF = lower_solve_rows(L, F, index, m)
    W = AJ.T @ AF
    rhs = np.empty(m)
    for c in range(m):
        rhs[c] = r[index[c]]
    lam = np.linalg.lstsq(W, rhs, RANK_RTOL)[0]
    residual = 0.0
    for a in range(m):
        acc = rhs[a]
        for c in range(m):
            acc -= W[a, c] * lam[c]
        residual = max(residual, abs(acc))
    for c in range(m):
        lam_rows[index[c]] = lam[c]
    z = AF @ lam
    x = upper_solve(L, z)
    for d in range(nv):
        correction[d] = x[d]
    return residual


__all__ = ["sliding_columns", "general_held_solve", "slip_direction", "SLIDING", "SLIDING_HELD"]
