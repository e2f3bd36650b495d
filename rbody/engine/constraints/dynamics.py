"""The constrained dynamics of a tree in one mode, compiled: accelerations and forces, the right-hand side, a
Runge-Kutta step, and the projection of a state onto the constraint manifold.

A mode (rbody.engine.constraints.table) fixes which rows hold: every equality, each limit held at its stop, each
sticking degree of freedom or tendon; a sliding one feels the constant force -frictionloss sign (along its row
J for a tendon: -frictionloss sign J^T). With M(q) the mass matrix
(CRBA, armature included), f = passive - bias (RNEA: gravity, Coriolis, centrifugal; springs, dampers; the sliding
friction) and the held rows J (m, nv) with their J' v, the accelerations and forces solve

    M qacc = f + J^T lambda,     J qacc + J' v = 0,

by the Cholesky factor M = L L^T: a0 = M^-1 f, A = L^-1 J^T, W = A^T A (the Delassus matrix J M^-1 J^T),
W lambda = -(J a0 + J' v), qacc = a0 + L^-T A lambda. A redundant set of rows (a closed loop with more rows than
it needs) makes W singular: lambda is then W's minimum-norm solution (rbody.engine.constraints.solver), which
gives the one qacc every solution gives; rows that contradict each other leave a residual |W lambda - r| that the
caller reports (SimulationError). Cost: O(nv^3 + m^3) per evaluation, dense: fit for trees of tens of degrees of
freedom, which is what the event-driven scheme is for.

The native state of a constrained tree is the tree's (qpos, qvel, phi), the actuators' activations act (na, none
without activation dynamics) and one more entry, the energy dissipated
so far by dry friction, impacts and the joints' dampers [J] (its rate here: the power of the sliding friction,
frictionloss s v, and of the dampers, damping v^2).
"""

from __future__ import annotations

import numpy as np
from numba import carray, cfunc, njit

from rbody.engine.multibody import (D_DAMPING, DOF_SIZE, FREE, H_BODIES, H_DOF, H_DOFS, H_JOINT, H_JOINTS, H_NQ,
                                    H_ROT, HINGE, J_DADR, J_KIND, J_QADR, JOINT_SIZE, ROLL, SLIDE, _effective_qpos, _frames,
                                    STACK_FLOATS, coordinate_rates, inverse_one, mass_matrix_at_frames, passive,
                                    tree_finish, workspace_size)
from rbody.engine import pointers
from rbody.engine.spatial import quat_exp, quat_multiply
from rbody.engine.elements import X_ACTIVE, X_NA, X_NTEN, extension_start
from rbody.engine.memory import cut, keep_alive, stack_floats, unowned
from rbody.engine.system import actuator_rates, add_element_forces, clamp_activations
from rbody.engine.constraints.jacobians import (all_rows, bias_accelerations, dof_row, some_rows, mode_at, row_count,
                                                unit_at, unit_count)
from rbody.engine.contacts.broadphase import (contact0, contact_row0, first_unit_at, kept_neighbours, pair_at,
                                              pair_count, pair_reaches, pair_span)
from rbody.engine.contacts.rows import (GEOMETRY_WORK, candidate, exact_within, forget_geometry, keep_geometry,
                                       keep_poses, kept_candidate, kept_exact, moved_within_round_off,
                                       pair_candidates)
from rbody.engine.constraints.solver import (RANK_RTOL, cholesky_factor, lower_solve, lower_solve_rows,
                                            symmetric_solve, upper_solve)
from rbody.engine.constraints.sliding import general_held_solve, sliding_columns
from rbody.engine.constraints.kinds import (is_dof_kind, is_equality_kind, is_friction_kind, is_limit_kind,
                                           is_tendon_kind)
from rbody.engine.constraints.table import (CONE, CONTACT, CONTACT1, FRICTION, PAIR_SIZE, TENDON_FRICTION, U_BOUND,
                                            U_DOF, U_KIND, U_QADR, U_ROW0, U_ROWS, U_TENDON, UNIT_SIZE)

PROJECTION_TOLERANCE = 1e-13   # |g| [m or rad] a projection aims for on the held rows (round-off of metre-scale trees)
PROJECTION_ITERATIONS = 8      # Newton iterations of a projection at most


@njit(cache=True, inline="always")
def sizes(p):
    """(nq, nv, n): the tree's sizes and the length of the native state (qpos, qvel, phi, act, dissipated)."""
    nq, nv = int(p[H_NQ]), int(p[H_DOFS])
    return nq, nv, nq + nv + 3 * int(p[H_ROT]) + int(p[extension_start(p) + X_NA]) + 1


@njit(cache=True, inline="always")
def act_range(p):
    """(a0, na): where the actuators' activations sit in the native state, and how many (after qpos, qvel, phi)."""
    return int(p[H_NQ]) + int(p[H_DOFS]) + 3 * int(p[H_ROT]), int(p[extension_start(p) + X_NA])


@njit(cache=True)
def snapshot(p, q, v, act, M, f, J, jdot, g, w, acc, rows_wanted=None, with_bias=True, contacts=True, rates=None):
    """At qpos q (nq,) and qvel v (nv,): M (nv, nv); f (nv,) = passive - bias (gravity included; with force elements
    also the actuators' forces at the controls written in p, the tendons', fluid and gravity compensation:
    rbody.engine.system.add_element_forces); every unit's rows
    J (rows, nv), jdot (rows,) and g (rows,) (rbody.engine.constraints.jacobians), or only the units with a row
    flagged in rows_wanted (rows,). w: the tree's workspace; acc (nb, 6) scratch. with_bias False: the contacts'
    J' v are left 0 (what the time-stepping and the projection read is J and g only). contacts False (rows_wanted
    None): every unit's rows but the contacts' (the time-stepping forms those of the near ones itself). rates
    (na,) or None: also the activations' rates act' at (q, v, act) (rbody.engine.system.actuator_rates), from
    the force elements' one evaluation. One outward pass gives M, the bias and the rows (M reads its positions)."""
    nv = int(p[H_DOFS])
    owned = carray(stack_floats(2 * nv), 2 * nv) if 2 * nv <= STACK_FLOATS else np.empty(2 * nv)
    zero, held = cut(owned, 0, nv), cut(owned, nv, nv)  # (one buffer, on the stack where small)
    zero[:] = 0.0
    inverse_one(p, q, v, zero, True, f, w)  # f = bias, and the workspace's frames at (q, v)
    mass_matrix_at_frames(p, w, M)
    if with_bias:
        bias_accelerations(p, w, acc)
    if rows_wanted is None:
        all_rows(p, q, v, w, acc, J, jdot, g, with_bias, contacts)
    else:
        some_rows(p, q, v, w, acc, J, jdot, g, rows_wanted, with_bias)
    passive(p, q, v, held)
    if p[extension_start(p) + X_ACTIVE] != 0.0:  # actuators, tendons, gravity compensation, fluid
        add_element_forces(p, q, v, act, held, rates)
    elif rates is not None:
        actuator_rates(p, q, v, act, rates)
    for d in range(nv):
        f[d] = held[d] - f[d]
    keep_alive(owned)  # read through views only


@njit(cache=True)
def add_sliding_friction(p, f, J):
    """f (nv,) += -frictionloss s on every dof whose friction unit slides (mode s = +-1), and -frictionloss s J^T
    for every sliding tendon friction (J (rows, nv): its row formed at the state)."""
    modes = mode_at(p)
    for k in range(contact0(p)):  # the contacts follow every other unit
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        if kind == FRICTION and p[modes + k] != 0.0:
            f[int(p[u + U_DOF])] -= p[u + U_BOUND] * p[modes + k]
        elif kind == TENDON_FRICTION and p[modes + k] != 0.0:
            force = p[u + U_BOUND] * p[modes + k]
            row = int(p[u + U_ROW0])
            for d in range(f.shape[0]):
                f[d] -= force * J[row, d]


@njit(cache=True, inline="always")
def coordinate_key(p, u):
    """What a stop or a dry friction unit acts along, as one index: its dof (joints), nv + its tendon (tendons)."""
    if is_tendon_kind(int(p[u + U_KIND])):
        return int(p[H_DOFS]) + int(p[u + U_TENDON])
    return int(p[u + U_DOF])


@njit(cache=True)
def dof_states(p):
    """(stop_held (nv + ntendon,), sticking (nv + ntendon,)): per dof, then per tendon (coordinate_key), 1 where a
    stop (LOWER, UPPER; TENDON_LOWER, TENDON_UPPER) on it is held, and its frictionloss where its friction sticks
    (0 elsewhere), in the mode written in p."""
    size = int(p[H_DOFS]) + int(p[extension_start(p) + X_NTEN])
    stop_held = np.zeros(size)
    sticking = np.zeros(size)
    modes = mode_at(p)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        if not (is_limit_kind(kind) or is_friction_kind(kind)):
            continue
        d = coordinate_key(p, u)
        if is_limit_kind(kind) and p[modes + k] == 1.0:
            stop_held[d] = 1.0
        elif is_friction_kind(kind) and p[modes + k] == 0.0:
            sticking[d] = p[u + U_BOUND]
    return stop_held, sticking


@njit(cache=True)
def sticking_friction_on(p, dof):
    """The frictionloss of dof `dof` when its friction sticks in the mode written in p, else 0."""
    return dof_states(p)[1][dof]


@njit(cache=True)
def held_rows(p, rows_held):
    """rows_held (rows,) = 1 where the mode holds the row (equalities, limits held, sticking dofs), else 0; returns
    their count. Two held rows that would say the same thing are held once, so that each force is defined: a
    sticking dof (or tendon) whose stop is held (the stop carries the load; the friction then does nothing), and a
    ball's cone when all three of its dofs stick (the ball is locked by its friction)."""
    stop_held, sticking = dof_states(p)
    modes = mode_at(p)
    count = 0
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        mode = p[modes + k]
        d = coordinate_key(p, u)
        on = (is_equality_kind(kind) or
              (is_limit_kind(kind) and mode == 1.0) or
              (kind == CONE and mode == 1.0 and not (sticking[d] > 0.0 and sticking[d + 1] > 0.0
                                                     and sticking[d + 2] > 0.0)) or
              (is_friction_kind(kind) and mode == 0.0 and stop_held[d] == 0.0))
        r0, r = int(p[u + U_ROW0]), int(p[u + U_ROWS])
        if (kind == CONTACT or kind == CONTACT1) and mode != 0.0:  # sticking: every row; sliding: the normal
            for a in range(r0, r0 + r):
                rows_held[a] = 1.0 if (mode == 1.0 or a == r0) else 0.0
            count += r if mode == 1.0 else 1
            continue
        for a in range(r0, r0 + r):
            rows_held[a] = 1.0 if on else 0.0
        if on:
            count += r
    return count


@njit(cache=True)
def definite_solve(W, r, x):
    """x = W^-1 r by Cholesky when W (m, m) is positive definite beyond round-off (every pivot above 1e-10 of its
    diagonal entry and above RANK_RTOL of W's largest diagonal entry), returning True; False (x untouched) when it is
    not: the caller then takes the minimum-norm solution (redundant rows). The second bound refuses a row whose whole
    Jacobian is round-off (a connect's component across a planar loop: 1e-17 where the others are 0.05), whose pivot
    is its own diagonal entry: solved, it would turn a residual of round-off into a step of order one."""
    m = r.shape[0]
    L = np.empty((m, m))
    top = 0.0
    for i in range(m):
        top = max(top, W[i, i])
    if not cholesky_factor(W, L, 1e-10, RANK_RTOL * top):
        return False
    z = lower_solve(L, r)
    out = upper_solve(L, z)
    for i in range(m):
        x[i] = out[i]
    return True


@njit(cache=True)
def held_solve(L, J, held, r, correction, lam_rows):
    """The minimum-norm lambda of the held rows with W lambda = r (W = J_h M^-1 J_h^T, M = L L^T, r (rows,) read on
    the held rows), and correction (nv,) = M^-1 J_h^T lambda; lam_rows (rows,) gets lambda on the held rows, 0
    elsewhere. Returns the residual |W lambda - r|_inf (0 when the held rows are consistent)."""
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
    A = lower_solve_rows(L, J, index, m)
    W = A.T @ A
    rhs = np.empty(m)
    for c in range(m):
        rhs[c] = r[index[c]]
    lam = np.empty(m)
    if definite_solve(W, rhs, lam):
        residual = 0.0
    else:
        residual = symmetric_solve(W, rhs, lam)
    for c in range(m):
        lam_rows[index[c]] = lam[c]
    z = A @ lam
    x = upper_solve(L, z)
    for d in range(nv):
        correction[d] = x[d]
    return residual


@njit(cache=True)
def mode_accel(p, q, v, act, qacc, lam_rows, g, every_row=True, power=None, rates=None):
    """qacc (nv,) and the force of every row lam_rows (rows,) (held rows: their lambda; sliding friction: -F s;
    others 0) in the mode written in p, at the effective qpos q and qvel v; g (rows,) gets every row's residual
    (every_row False: only the held rows' are formed, the others left as they were: the right-hand side needs no
    more). Sliding contacts (rbody.engine.constraints.sliding) push along their force columns, their tangent rows
    reporting their friction; power (1,), when given, gets the power their friction and the sliding tendons'
    friction take [W]; rates (rows,), when given, every row's J v. Returns (residual, scale): |W lambda - r|_inf of
    the held rows and |r|_inf (the caller judges it)."""
    nv = int(p[H_DOFS])
    rows = row_count(p)
    w = np.empty(workspace_size(p))
    M = np.empty((nv, nv))
    f = np.empty(nv)
    J = np.zeros((rows, nv))
    jdot = np.zeros(rows)
    acc = np.empty((int(p[H_BODIES]), 6))
    held = np.empty(rows)
    held_rows(p, held)
    if every_row:
        snapshot(p, q, v, act, M, f, J, jdot, g, w, acc)
    else:  # the held rows, and the sliding tendons' (their friction acts along their row)
        wanted = held.copy()
        sliding_tendon_rows(p, wanted)
        snapshot(p, q, v, act, M, f, J, jdot, g, w, acc, wanted)
    add_sliding_friction(p, f, J)
    if rates is not None:
        for a in range(rows):
            rate = 0.0
            for d in range(nv):
                rate += J[a, d] * v[d]
            rates[a] = rate
    L = np.linalg.cholesky(M)
    a0 = upper_solve(L, lower_solve(L, f))
    r = np.zeros(rows)
    for a in range(rows):
        if held[a] != 0.0:
            acc_r = jdot[a]
            for d in range(nv):
                acc_r += J[a, d] * a0[d]
            r[a] = -acc_r
    scale = 0.0
    for a in range(rows):
        if held[a] != 0.0:
            scale = max(scale, abs(r[a]))
    correction = np.empty(nv)
    F = np.empty((rows, nv))
    share = np.empty(rows)
    if sliding_columns(p, w, J, v, F, share) > 0:
        residual = general_held_solve(L, J, F, held, r, correction, lam_rows)
        slip_power = 0.0
        for k in range(unit_count(p)):
            u = unit_at(p, k)
            if share[int(p[u + U_ROW0]) + 1] != 0.0 or share[int(p[u + U_ROW0]) + 2] != 0.0:
                r0 = int(p[u + U_ROW0])
                for a in (r0 + 1, r0 + 2):
                    lam_rows[a] = share[a] * lam_rows[r0]
                    speed = 0.0
                    for d in range(nv):
                        speed += J[a, d] * v[d]
                    slip_power -= lam_rows[a] * speed
        if power is not None:
            power[0] = slip_power + tendon_friction_power(p, J, v)
    else:
        residual = held_solve(L, J, held, r, correction, lam_rows)
        if power is not None:
            power[0] = tendon_friction_power(p, J, v)
    for d in range(nv):
        qacc[d] = a0[d] + correction[d]
    modes = mode_at(p)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        if is_friction_kind(kind) and p[modes + k] != 0.0:
            lam_rows[int(p[u + U_ROW0])] = -p[u + U_BOUND] * p[modes + k]
    return residual, scale


@njit(cache=True)
def sliding_tendon_rows(p, wanted):
    """wanted (rows,) = 1 on the row of every sliding tendon friction unit (the rest left as it was)."""
    modes = mode_at(p)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        if int(p[u + U_KIND]) == TENDON_FRICTION and p[modes + k] != 0.0:
            wanted[int(p[u + U_ROW0])] = 1.0


@njit(cache=True)
def tendon_friction_power(p, J, v):
    """Power [W] the sliding tendons lose to dry friction: frictionloss s (J v) over their units (J their rows)."""
    modes = mode_at(p)
    power = 0.0
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        if int(p[u + U_KIND]) == TENDON_FRICTION and p[modes + k] != 0.0:
            row = int(p[u + U_ROW0])
            rate = 0.0
            for d in range(v.shape[0]):
                rate += J[row, d] * v[d]
            power += p[u + U_BOUND] * p[modes + k] * rate
    return power


@njit(cache=True)
def friction_power(p, v):
    """Power [W] the sliding dofs lose to dry friction: sum of frictionloss s v over the sliding units."""
    modes = mode_at(p)
    power = 0.0
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        if int(p[u + U_KIND]) == FRICTION and p[modes + k] != 0.0:
            power += p[u + U_BOUND] * p[modes + k] * v[int(p[u + U_DOF])]
    return power


@njit(cache=True)
def damping_power(p, v):
    """Power [W] the joints' dampers take: sum of damping v^2 over the dofs."""
    power = 0.0
    do = int(p[H_DOF])
    for d in range(int(p[H_DOFS])):
        power += p[do + d * DOF_SIZE + D_DAMPING] * v[d] * v[d]
    return power


@njit(cache=True)
def constrained_rhs(y, p, out):
    """y' for y = (qpos (nq), qvel (nv), phi (3 per ball/free joint), act (na), dissipated (1)) in the mode written
    in p: as the tree's right-hand side (rbody.engine.multibody.tree_rhs) with qvel' the constrained accelerations
    (mode_accel), act' the actuators' activation dynamics (rbody.engine.system.actuator_rates), and dissipated' the
    power the sliding friction and the dampers take (not the actuators' or the fluid's work: with those, energy +
    dissipated is not constant)."""
    nq, nv = int(p[H_NQ]), int(p[H_DOFS])
    n = y.shape[0]
    q = np.empty(nq)
    _effective_qpos(p, y, q, 0)
    rows = row_count(p)
    lam = np.empty(rows)
    g = np.zeros(rows)
    a0, na = act_range(p)
    slip_power = np.zeros(1)
    mode_accel(p, q, y[nq:nq + nv], y[a0:a0 + na], out[nq:nq + nv], lam, g, False, slip_power)
    if na:  # the actuators' activations (rbody.engine.system)
        actuator_rates(p, q, y[nq:nq + nv], y[a0:a0 + na], out[a0:a0 + na])
    coordinate_rates(p, y, out)  # qpos' and phi' as the tree's right-hand side forms them
    out[n - 1] = friction_power(p, y[nq:nq + nv]) + damping_power(p, y[nq:nq + nv]) + slip_power[0]


def _constrained_rhs_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def constrained_rhs_c(y, p, out, n, m):
        constrained_rhs(carray(y, n), carray(p, m), carray(out, n))
    return constrained_rhs_c


pointers.register(constrained_rhs, "rhs", _constrained_rhs_pointer)  # (its wrapper compiled once, not every process)


@njit(cache=True)
def rk4_step(y, p, h, out):
    """out = one classical Runge-Kutta step of constrained_rhs from y over h [s], rotations folded in after it."""
    n = y.shape[0]
    k1, k2, k3, k4, stage = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    constrained_rhs(y, p, k1)
    for i in range(n):
        stage[i] = y[i] + 0.5 * h * k1[i]
    constrained_rhs(stage, p, k2)
    for i in range(n):
        stage[i] = y[i] + 0.5 * h * k2[i]
    constrained_rhs(stage, p, k3)
    for i in range(n):
        stage[i] = y[i] + h * k3[i]
    constrained_rhs(stage, p, k4)
    for i in range(n):
        out[i] = y[i] + h / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
    tree_finish(out, p)
    a0, na = act_range(p)
    if na:
        clamp_activations(p, out[a0:a0 + na])


@njit(cache=True)
def displace(p, y, delta):
    """Move the configuration of y by the generalised displacement delta (nv,) (the qvel space): scalar joints and
    free positions add it, ball and free rotations turn by q (x) exp(delta) (body frame, as their qvel)."""
    nj, nq = int(p[H_JOINTS]), int(p[H_NQ])
    jo = int(p[H_JOINT])
    turn = np.empty(4)
    old = np.empty(4)
    for j in range(nj):
        r = jo + j * JOINT_SIZE
        kind = int(p[r + J_KIND])
        qa, da = int(p[r + J_QADR]), int(p[r + J_DADR])
        if kind == HINGE or kind == SLIDE or kind == ROLL:
            y[qa] += delta[da]
            continue
        if kind == FREE:
            for a in range(3):
                y[qa + a] += delta[da + a]
            qa, da = qa + 3, da + 3
        quat_exp(delta[da:da + 3], turn)
        for a in range(4):
            old[a] = y[qa + a]
        quat_multiply(old, turn, y[qa:qa + 4])
    return nq


@njit(cache=True)
def project(p, y, position_rows, velocity_rows):
    """Project the state y (phi folded: all zero) onto the manifold of the rows flagged in position_rows (rows,)
    (g = 0: equalities, held limits; a flagged limit row also where it is violated) and its velocities onto that
    of velocity_rows (J v = 0: the same and the sticking dofs), each in the metric of M (the smallest change of
    kinetic energy): positions by Newton's method delta = -M^-1 J^T W^+ g until |g| <= PROJECTION_TOLERANCE,
    velocities in one step. Returns (|g|_inf, |J v|_inf) on the flagged rows after it."""
    nq, nv, _n = sizes(p)
    a0, na = act_range(p)
    rows = row_count(p)
    w = np.empty(workspace_size(p))
    M = np.empty((nv, nv))
    f = np.empty(nv)
    J = np.empty((rows, nv))  # the rows flagged are computed, and only they are read
    jdot = np.zeros(rows)
    g = np.zeros(rows)
    acc = np.empty((int(p[H_BODIES]), 6))
    lam = np.empty(rows)
    delta = np.empty(nv)
    v = y[nq:nq + nv]
    flagged = np.zeros(rows)
    for a in range(rows):
        if position_rows[a] != 0.0 or velocity_rows[a] != 0.0:
            flagged[a] = 1.0
    worst = 0.0
    for iteration in range(PROJECTION_ITERATIONS + 1):
        snapshot(p, y[:nq], v, y[a0:a0 + na], M, f, J, jdot, g, w, acc, flagged, False)
        worst = 0.0
        for a in range(rows):
            if position_rows[a] != 0.0 and not np.isfinite(g[a]):  # no longer a contact point (geometry.APART)
                position_rows[a] = 0.0
                velocity_rows[a] = 0.0
            if position_rows[a] != 0.0:
                worst = max(worst, abs(g[a]))
        if worst <= PROJECTION_TOLERANCE or iteration == PROJECTION_ITERATIONS:
            break
        L = np.linalg.cholesky(M)
        held_solve(L, J, position_rows, -g, delta, lam)
        displace(p, y, delta)
    L = np.linalg.cholesky(M)
    jv = _held_rates(J, velocity_rows, v)
    held_solve(L, J, velocity_rows, -jv, delta, lam)
    for d in range(nv):
        v[d] += delta[d]
    jv = _held_rates(J, velocity_rows, v)
    speed = 0.0
    for a in range(rows):
        if velocity_rows[a] != 0.0:
            speed = max(speed, abs(jv[a]))
    return worst, speed


@njit(cache=True)
def _held_rates(J, held, v):
    """(rows,) J v on the rows flagged in held, 0 elsewhere (a model's far contact rows are not formed): the held
    rows gathered, their product taken at once."""
    rows, nv = J.shape
    index = np.flatnonzero(held)
    out = np.zeros(rows)
    if index.size == 0:
        return out
    gathered = np.empty((index.size, nv))
    for c in range(index.size):
        gathered[c] = J[index[c]]
    rates = gathered @ v
    for c in range(index.size):
        out[index[c]] = rates[c]
    return out


@njit(cache=True)
def guards(p, y, out):
    """out (units,): each unit's guard in the mode written in p, >= 0 while the mode is right (an event where one
    crosses 0): a free limit its distance g; a held limit its force lambda; a sticking dof frictionloss - |lambda|;
    a sliding one s v (its velocity in the direction it slides; a tendon's s L'); equalities +inf. Returns
    (residual, scale) of the held rows' forces (mode_accel)."""
    nq, nv, _n = sizes(p)
    rows = row_count(p)
    q = np.empty(nq)
    _effective_qpos(p, y, q, 0)
    lam = np.empty(rows)
    g = np.empty(rows)
    qacc = np.empty(nv)
    a0, na = act_range(p)
    rates = np.empty(rows)
    residual, scale = mode_accel(p, q, y[nq:nq + nv], y[a0:a0 + na], qacc, lam, g, True, None, rates)
    modes = mode_at(p)
    _stop_held, sticking = dof_states(p)
    for k in range(unit_count(p)):
        u = unit_at(p, k)
        kind = int(p[u + U_KIND])
        row = int(p[u + U_ROW0])
        mode = p[modes + k]
        if is_limit_kind(kind):
            # a held stop with friction on its dof (tendon): friction can pull up to F too
            out[k] = lam[row] + sticking[coordinate_key(p, u)] if mode == 1.0 else g[row]
        elif kind == CONE:
            out[k] = lam[row] if mode == 1.0 else g[row]
        elif is_friction_kind(kind):
            out[k] = p[u + U_BOUND] - abs(lam[row]) if mode == 0.0 else mode * rates[row]
        else:
            out[k] = np.inf
    return residual, scale


@njit(cache=True)
def state_gaps(p, y, g, beyond=np.inf, kept=None, least=None):
    """g (rows,) every row's residual at the state y (phi folded in) as state_rows gives it, from the tree's
    kinematics alone: a contact by its candidate's signed distance (no Jacobian; a pair the broad phase finds apart
    by its bound, broadphase.pair_reaches, a positive lower bound), the other units by their rows. beyond [m]: a caller
    that reads no contact gap above it (the projection's flags, the errors' min(g, 0)) lets a pair whose least gap
    is above it give that (rows.pair_candidates). kept (broadphase.kept_size(p),) or None: the contacts' geometry
    found here, kept for the next step's start at the same configuration, and the broad phase's neighbour list (read
    and kept: a far pair's bound is then a lower bound above TIGHTEN_BELOW, not its spheres' own); a flat-faced pair
    found exactly before and moved since by less than its poses' round-off (rows.moved_within_round_off) is read
    from it, not found again (the stack at rest moves 2e-18 m a step). least (pairs,) or
    None: each contact pair's least gap [m] (a bound where its spheres are apart), that a caller reads in place of
    its rows: only its candidates' normal rows are then written, and not even those where the broad phase's bound
    is above `beyond` (the rest are left as they were: a quadruped's far candidates, 24,822 rows each step)."""
    # p, w, g and the scratch, handed to helpers for each near pair, as views numba does not count (memory.unowned)
    p, y, g = unowned(p), unowned(y), unowned(g)
    nq, nv, _n = sizes(p)
    nb, r0, npairs, ws = int(p[H_BODIES]), contact_row0(p), pair_count(p), workspace_size(p)
    units = unit_count(p)
    if npairs == 0 and _dof_units_only(p):  # joints' stops and dry friction alone: their gaps from qpos, no frames
        _dof_gaps(p, y, g, kept)
        return
    size = nq + ws + r0 * (nv + 1) + 6 * nb + 2 * npairs  # the arrays below, one buffer (on the stack where small)
    owned = carray(stack_floats(size), size) if size <= STACK_FLOATS else np.empty(size)
    q, w = cut(owned, 0, nq), cut(owned, nq, ws)
    _effective_qpos(p, y, q, 0)
    _frames(p, q, y[nq:nq + nv], w)
    J = cut(owned, nq + ws, (r0, nv))  # the rows of the units before the contacts (their gaps come without J)
    jdot = cut(owned, nq + ws + r0 * nv, r0)
    acc = cut(owned, nq + ws + r0 * (nv + 1), (nb, 6))
    normal, point = carray(stack_floats(3), 3), carray(stack_floats(3), 3)
    work = carray(stack_floats(GEOMETRY_WORK), GEOMETRY_WORK)
    if kept is not None:
        kept[0] = 1.0
        kept[1:1 + nq] = q
    all_rows(p, q, y[nq:nq + nv], w, acc, J, jdot, g, False, False)  # the units before the contacts
    reach, motion = cut(owned, size - 2 * npairs, npairs), cut(owned, size - npairs, npairs)
    neighbours = g[:0]  # (a caller that keeps nothing: every pair bounded)
    if kept is not None:
        neighbours = kept_neighbours(p, kept)
    pair_reaches(p, w, 0.0, reach, motion, neighbours)
    if least is None:
        g[contact_row0(p):] = 0.0  # the contacts' rows (one fill: a far pair's tangent rows are then set)
    pairs = pair_at(p, 0)
    for i in range(npairs):
        at = pairs + i * PAIR_SIZE  # (from the first record: pair_at's reads from the header, redone each pass)
        first, slots, row0, width = pair_span(p, at)
        if reach[i] > 0.0:  # apart by the broad phase's bound: a lower bound will do, one per pair
            if least is None or reach[i] <= beyond:
                for j in range(slots):  # (a range with a step costs numba's sign test on every iteration)
                    g[row0 + j * width] = reach[i]
            if kept is not None:
                forget_geometry(kept, nq, first)
            if least is not None:
                least[i] = reach[i]
            continue
        u = first_unit_at(p, at)
        lowest = np.inf
        if kept is not None and kept_exact(kept, nq, first) and moved_within_round_off(p, w, u, kept, nq, units,
                                                                                       i, work):
            for j in range(slots):  # found exactly where the pair was to the round-off of its poses: read
                row = row0 + j * width
                g[row] = kept_candidate(kept, nq, first + j, normal, point)
                lowest = min(lowest, g[row])
        else:
            count = pair_candidates(p, w, u, work, beyond)  # its geoms posed once
            exact = exact_within(p, u, count, work, beyond)
            for j in range(slots):
                row = row0 + j * width
                g[row] = candidate(work, j, normal, point)
                lowest = min(lowest, g[row])
                if kept is not None:
                    keep_geometry(kept, nq, first + j, exact, g[row], normal, point)
            if kept is not None:
                keep_poses(kept, nq, units, i, work)
        if least is not None:
            least[i] = lowest
    keep_alive(owned)  # read through views only


@njit(cache=True)
def _dof_units_only(p):
    """Whether every unit is a joint's stop or dry friction (is_dof_kind): rows whose gaps are qpos's alone."""
    units = unit_at(p, 0)
    for k in range(unit_count(p)):
        if not is_dof_kind(int(p[units + k * UNIT_SIZE + U_KIND])):
            return False
    return True


@njit(cache=True)
def _dof_gaps(p, y, g, kept):
    """state_gaps of a model whose units are all joints' stops and dry friction (_dof_units_only): each row's g as
    dof_row gives it from the effective qpos (kept, where given, records that qpos as state_gaps does)."""
    nq = int(p[H_NQ])
    owned = carray(stack_floats(nq), nq) if nq <= STACK_FLOATS else np.empty(nq)
    _effective_qpos(p, y, owned, 0)
    if kept is not None:
        kept[0] = 1.0
        kept[1:1 + nq] = owned
    units = unit_at(p, 0)
    for k in range(unit_count(p)):
        u = units + k * UNIT_SIZE
        _entry, g[int(p[u + U_ROW0])] = dof_row(int(p[u + U_KIND]), p[u + U_BOUND], owned[int(p[u + U_QADR])])
    keep_alive(owned)


@njit(cache=True)
def state_rows(p, y, M, f, J, jdot, g, with_bias=True):
    """snapshot at the state y (phi folded in): M, f (passive - bias, sliding friction of the mode included), rows
    (with_bias: as snapshot's)."""
    nq, nv, _n = sizes(p)
    q = np.empty(nq)
    _effective_qpos(p, y, q, 0)
    w = np.empty(workspace_size(p))
    acc = np.empty((int(p[H_BODIES]), 6))
    a0, na = act_range(p)
    snapshot(p, q, y[nq:nq + nv], y[a0:a0 + na], M, f, J, jdot, g, w, acc, None, with_bias)
    add_sliding_friction(p, f, J)


__all__ = ["sizes", "snapshot", "mode_accel", "constrained_rhs", "rk4_step", "project", "guards", "state_rows", "state_gaps",
           "held_rows", "held_solve", "lower_solve", "upper_solve", "displace", "friction_power",
           "PROJECTION_TOLERANCE"]
