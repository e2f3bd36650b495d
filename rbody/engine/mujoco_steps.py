"""MuJoCo's integrators as one-step maps of a tree: the methods "mujoco_euler", "implicitfast" and "implicit".

Published models run at their own step with their own integrator (MJCF's default is Euler); with the same scheme
on both sides, rbody and MuJoCo differ by their models only. Each step, from (qpos, qvel, act) at t
(engine_forward.c mj_Euler, mj_implicit, mj_advance; engine_derivative.c mjd_smooth_vel):

    f    = qfrc_passive + qfrc_actuator - qfrc_bias         (the smooth forces at the step's start)
    H    = M + h B                     mujoco_euler: B the joints' damping (diagonal): the damping is implicit
         = M - h D                     implicitfast: D = d(qfrc_passive + qfrc_actuator)/d qvel: joint and tendon
                                       damping, the actuators' kv and affine-gain terms (none where a force sits
                                       at its forcerange bound); its lower triangle mirrored; for a free body
                                       alone in its tree (no child), the full block with its bias derivative
         = M - h (D - d qfrc_bias / d qvel)   implicit: with the Coriolis and centrifugal derivative, not symmetric
    qacc = H^-1 f
    act  <- MuJoCo's next activation (act + h act', "filterexact": act + act' tau (1 - e^{-h/tau})), clamped
    qvel <- qvel + h qacc
    qpos <- qpos integrated with the new qvel (hinge, slide: q + h v; ball and free rotations: q (x) exp(h w / 2))

D and the bias derivative keep only the pairs of degrees of freedom of which one moves the other (MuJoCo's
sparsity: a tendon or actuator coupling two branches or two trees contributes nothing off the diagonal blocks).
The bias derivative is formed by polarisation: the bias is a quadratic form in qvel plus gravity, so
d bias/d qvel e_j = (bias(v + s e_j) - bias(v - s e_j)) / 2s exactly (RNEA without gravity), s = max|v|.
Euler's H has M's pattern (each dof coupled only with its ancestors and descendants) and is factored along the tree
(rbody.engine.mass_factor: H = L^T L, no fill-in, as MuJoCo's mj_factorI factors it L^T D L); implicitfast's and
implicit's are dense and solved by Gaussian elimination with partial pivoting (MuJoCo: a sparse LDL^T or LU): the
two differ by round-off. Order 1 each; stable on an undamped oscillation while h w < 2 (semi-implicit Euler).
"""

from __future__ import annotations

import numpy as np
from numba import carray, njit

from rbody.engine import multibody as mb
from rbody.engine.actuation import actuator_velocity_derivative, next_activation
from rbody.engine.elements import A_ACTADR, A_DISABLED, ACT_SIZE, X_ACT, X_CTRL, X_NA, X_NU, extension_start
from rbody.engine.mass_factor import ancestors_into, factor_in_place, tree_solve, tree_solve_transposed
from rbody.engine.memory import address, keep_alive
from rbody.engine.fluid import box_velocity_derivative
from rbody.engine.passive import tendon_damping_derivative
from rbody.engine.system import _force_views, act_offset, element_forces, force_size, next_control

EULER, IMPLICITFAST, IMPLICIT = 0, 1, 2
MJ_MINVAL = 1e-15
MUJOCO_METHODS = ("mujoco_euler", "implicitfast", "implicit")


@njit(cache=True, inline="always")
def _quat_integrate(q, at, w0, w1, w2, h):
    """MuJoCo's mju_quatIntegrate: q[at:at + 4] <- normalise(q) (x) (rotation by h |w| about w), w body frame."""
    norm = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if norm < MJ_MINVAL:
        a0, a1, a2 = 1.0, 0.0, 0.0
    else:
        a0, a1, a2 = w0 / norm, w1 / norm, w2 / norm
    angle = h * norm
    if angle == 0.0:
        r0, r1, r2, r3 = 1.0, 0.0, 0.0, 0.0
    else:
        s = np.sin(angle * 0.5)
        r0, r1, r2, r3 = np.cos(angle * 0.5), a0 * s, a1 * s, a2 * s
    x0, x1, x2, x3 = q[at], q[at + 1], q[at + 2], q[at + 3]
    length = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2 + x3 * x3)
    if length < MJ_MINVAL:
        x0, x1, x2, x3 = 1.0, 0.0, 0.0, 0.0
    elif abs(length - 1.0) > MJ_MINVAL:
        x0, x1, x2, x3 = x0 / length, x1 / length, x2 / length, x3 / length
    q[at] = x0 * r0 - x1 * r1 - x2 * r2 - x3 * r3
    q[at + 1] = x0 * r1 + x1 * r0 + x2 * r3 - x3 * r2
    q[at + 2] = x0 * r2 - x1 * r3 + x2 * r0 + x3 * r1
    q[at + 3] = x0 * r3 + x1 * r2 - x2 * r1 + x3 * r0


@njit(cache=True)
def integrate_positions(p, q, v, h):
    """MuJoCo's mj_integratePos: q (nq,) advanced by qvel v (nv,) over h [s]."""
    nj = int(p[mb.H_JOINTS])
    jo = int(p[mb.H_JOINT])
    for j in range(nj):
        r = jo + j * mb.JOINT_SIZE
        kind = int(p[r + mb.J_KIND])
        qa, da = int(p[r + mb.J_QADR]), int(p[r + mb.J_DADR])
        if kind == mb.FREE:
            for a in range(3):
                q[qa + a] += h * v[da + a]
            _quat_integrate(q, qa + 3, v[da + 3], v[da + 4], v[da + 5], h)
        elif kind == mb.BALL:
            _quat_integrate(q, qa, v[da], v[da + 1], v[da + 2], h)
        else:
            q[qa] += h * v[da]


@njit(cache=True)
def _related(p, related):
    """related (nv, nv): 1 where one degree of freedom is the other or one of its ancestors (MuJoCo's D sparsity)."""
    nv = int(p[mb.H_DOFS])
    do = int(p[mb.H_DOF])
    for a in range(nv):
        for c in range(nv):
            related[a, c] = 0.0
    for d in range(nv):
        k = d
        while k >= 0:
            related[d, k] = 1.0
            related[k, d] = 1.0
            k = int(p[do + k * mb.DOF_SIZE + mb.D_PARENT])


@njit(cache=True)
def _lone_free(p, dof):
    """The first dof of the free joint of a body alone in its tree (one free joint, no child) when `dof` is one of
    its six, else -1 (MuJoCo's mj_isFreeBody: implicitfast treats that block fully)."""
    nb = int(p[mb.H_BODIES])
    bo, jo, do = int(p[mb.H_BODY]), int(p[mb.H_JOINT]), int(p[mb.H_DOF])
    j = int(p[do + dof * mb.DOF_SIZE + mb.D_JOINT])
    r = jo + j * mb.JOINT_SIZE
    if int(p[r + mb.J_KIND]) != mb.FREE:
        return -1
    body = int(p[r + mb.J_BODY])
    for i in range(nb):
        if int(p[bo + i * mb.BODY_SIZE + mb.B_PARENT]) == body:
            return -1
    return int(p[r + mb.J_DADR])


@njit(cache=True)
def _bias_derivative(p, q, v, columns_from, columns_to, out, w, zero, vplus, plus, minus):
    """out[:, j] = d qfrc_bias / d qvel e_j for j in [columns_from, columns_to), by polarisation (module docstring)."""
    nv = int(p[mb.H_DOFS])
    s = 1e-3
    for d in range(nv):
        s = max(s, abs(v[d]))
        zero[d] = 0.0
    for j in range(columns_from, columns_to):
        for d in range(nv):
            vplus[d] = v[d]
        vplus[j] = v[j] + s
        mb.inverse_one(p, q, vplus, zero, False, plus, w)
        vplus[j] = v[j] - s
        mb.inverse_one(p, q, vplus, zero, False, minus, w)
        for d in range(nv):
            out[d, j] = (plus[d] - minus[d]) / (2.0 * s)


@njit(cache=True)
def solve_general(H, b, x, nv):
    """x (nv,) = H^-1 b by Gaussian elimination with partial pivoting (H and b are overwritten)."""
    for k in range(nv):
        pivot = k
        for i in range(k + 1, nv):
            if abs(H[i, k]) > abs(H[pivot, k]):
                pivot = i
        if pivot != k:
            for c in range(nv):
                H[k, c], H[pivot, c] = H[pivot, c], H[k, c]
            b[k], b[pivot] = b[pivot], b[k]
        for i in range(k + 1, nv):
            factor = H[i, k] / H[k, k]
            if factor != 0.0:
                for c in range(k, nv):
                    H[i, c] -= factor * H[k, c]
                b[i] -= factor * b[k]
    for i in range(nv - 1, -1, -1):
        acc = b[i]
        for c in range(i + 1, nv):
            acc -= H[i, c] * x[c]
        x[i] = acc / H[i, i]


@njit(cache=True)
def dof_parents(p, parent):
    """parent (nv,) int64 <- each dof's parent dof (-1 at a root), as the params row p holds them."""
    do = int(p[mb.H_DOF])
    for d in range(parent.shape[0]):
        parent[d] = int(p[do + d * mb.DOF_SIZE + mb.D_PARENT])


@njit(cache=True)
def euler_factor(p, M, h, parent, L):
    """L (nv, nv) <- the tree's factor of Euler's H = M + h diag(damping) (H = L^T L, L's entries on each dof's
    ancestors only: mass_factor), M (nv, nv) the mass matrix, h [s], parent (nv,) the dofs' parents (dof_parents).
    Returns False (L partly written) where a pivot is not positive."""
    do = int(p[mb.H_DOF])
    ancestors_into(M, parent, L)
    for d in range(M.shape[0]):  # (D = -diag(damping): H = M - h D)
        L[d, d] = M[d, d] - h * -p[do + d * mb.DOF_SIZE + mb.D_DAMPING]
    return factor_in_place(L, parent)


@njit(cache=True)
def mujoco_step(y, p, h, mode, elements):
    """One step of MuJoCo's integrator `mode` (EULER, IMPLICITFAST, IMPLICIT) on y = (qpos, qvel, phi = 0, act[,
    steps]) in place (module docstring); elements: whether the row holds force elements (rbody.engine.elements)."""
    _mujoco_step(y, p, h, mode, elements, np.empty((0, 0, 0)))


@njit(cache=True)
def step_matrices(y, p, mode, elements, out):
    """out (2, nv, nv) <- (M, D) of the step of `mode` from y (module docstring: H = M - h D), y unchanged."""
    _mujoco_step(y.copy(), p, 0.0, mode, elements, out)


@njit(cache=True)
def _mujoco_step(y, p, h, mode, elements, matrices):
    """mujoco_step; with matrices of shape (2, nv, nv), M and D are written there and y is left as it is."""
    nq, nv = int(p[mb.H_NQ]), int(p[mb.H_DOFS])
    do = int(p[mb.H_DOF])
    tree = mb.workspace_size(p)
    forces = force_size(p) if elements else 0
    size = tree + forces + 5 * nv * nv + 9 * nv
    w = np.empty(size)
    at = tree + forces
    M, D = carray(address(w, at), (nv, nv)), carray(address(w, at + nv * nv), (nv, nv))
    H, related = carray(address(w, at + 2 * nv * nv), (nv, nv)), carray(address(w, at + 3 * nv * nv), (nv, nv))
    B = carray(address(w, at + 4 * nv * nv), (nv, nv))
    at += 5 * nv * nv
    qfrc, bias, qacc = carray(address(w, at), nv), carray(address(w, at + nv), nv), carray(address(w, at + 2 * nv), nv)
    zero, vplus, plus = (carray(address(w, at + 3 * nv), nv), carray(address(w, at + 4 * nv), nv),
                         carray(address(w, at + 5 * nv), nv))
    minus, v, lone = (carray(address(w, at + 6 * nv), nv), carray(address(w, at + 7 * nv), nv),
                      carray(address(w, at + 8 * nv), nv))
    q = y[:nq]
    for d in range(nv):
        v[d] = y[nq + d]
        zero[d] = 0.0
    na = int(p[extension_start(p) + X_NA]) if elements else 0
    a0 = act_offset(p)
    act = y[a0:a0 + na]

    ws = mb._views(p, w)
    mb._frames(p, q, v, w)  # one outward pass: M, the forces and the bias all read its frames
    mb.mass_matrix_at_frames(p, w, M)
    mb.passive(p, q, v, ws.tau)
    if elements:
        element_forces(p, q, v, act, w, tree)
    for d in range(nv):
        qfrc[d] = ws.tau[d]
    mb.inverse_at_frames(p, zero, True, bias, w)
    for d in range(nv):
        qfrc[d] -= bias[d]

    # D = d(qfrc_passive + qfrc_actuator)/d qvel (the joints' damping only, for Euler)
    for a in range(nv):
        for c in range(nv):
            D[a, c] = 0.0
            B[a, c] = 0.0
    for d in range(nv):
        D[d, d] = -p[do + d * mb.DOF_SIZE + mb.D_DAMPING]
    if mode != EULER:
        if elements:
            E = extension_start(p)
            fw = _force_views(p, w, tree)
            ctrl_at = int(p[E + X_CTRL])
            actuator_velocity_derivative(p, act, fw.act_dot, p[ctrl_at:ctrl_at + int(p[E + X_NU])], fw.force,
                                         fw.moment, D)
            tendon_damping_derivative(p, fw.ten_J, D)
            box_velocity_derivative(p, ws.S, ws.xpos, ws.xmat, ws.vel, ws.h, D)
        _related(p, related)
        if mode == IMPLICIT:  # B = d qfrc_bias / d qvel: D - B on MuJoCo's sparsity
            _bias_derivative(p, q, v, 0, nv, B, w, zero, vplus, plus, minus)
            for a in range(nv):
                for c in range(nv):
                    D[a, c] = (D[a, c] - B[a, c]) * related[a, c]
        else:  # the lower triangle mirrored; a lone free body's block in full, with its bias derivative
            for d in range(nv):
                lone[d] = _lone_free(p, d)
            d = 0
            while d < nv:
                if lone[d] < 0:
                    d += 1
                    continue
                first = int(lone[d])
                _bias_derivative(p, q, v, first, first + 6, B, w, zero, vplus, plus, minus)
                d = first + 6
            for a in range(nv):
                for c in range(nv):
                    if lone[a] >= 0 and lone[a] == lone[c]:
                        H[a, c] = D[a, c] - B[a, c]
                    else:
                        H[a, c] = (D[a, c] if a >= c else D[c, a]) * related[a, c]
            for a in range(nv):
                for c in range(nv):
                    D[a, c] = H[a, c]
    if matrices.shape[0] == 2:
        for a in range(nv):
            for c in range(nv):
                matrices[0, a, c] = M[a, c]
                matrices[1, a, c] = D[a, c]
        keep_alive(w)
        return
    along_tree = False
    if mode == EULER:  # qacc = L^-1 L^-T qfrc (H = L^T L)
        parent = np.empty(nv, np.int64)
        dof_parents(p, parent)
        along_tree = euler_factor(p, M, h, parent, H)
        if along_tree:
            for d in range(nv):
                qacc[d] = qfrc[d]
            tree_solve_transposed(H, parent, qacc)
            tree_solve(H, parent, qacc)
    if not along_tree:
        for a in range(nv):
            for c in range(nv):
                H[a, c] = M[a, c] - h * D[a, c]
        solve_general(H, qfrc, qacc, nv)

    if elements:  # activations first (mj_advance), from the act' of the step's start
        E = extension_start(p)
        fw = _force_views(p, w, tree)
        for i in range(int(p[E + X_NU])):
            r = int(p[E + X_ACT]) + i * ACT_SIZE
            adr = int(p[r + A_ACTADR])
            if adr >= 0:
                rate = 0.0 if p[r + A_DISABLED] != 0.0 else fw.act_dot[adr]
                act[adr] = next_activation(p, r, act[adr], rate, h)
    keep_alive(w)  # read through views only above: the heap workspace must outlive them
    for d in range(nv):
        y[nq + d] = v[d] + h * qacc[d]
    integrate_positions(p, q, y[nq:nq + nv], h)
    for k in range(nq + nv, a0):
        y[k] = 0.0
    if elements:
        next_control(y, p)


@njit(cache=True)
def euler_tree(y, p, h):
    mujoco_step(y, p, h, EULER, False)


@njit(cache=True)
def implicitfast_tree(y, p, h):
    mujoco_step(y, p, h, IMPLICITFAST, False)


@njit(cache=True)
def implicit_tree(y, p, h):
    mujoco_step(y, p, h, IMPLICIT, False)


@njit(cache=True)
def euler_system(y, p, h):
    mujoco_step(y, p, h, EULER, True)


@njit(cache=True)
def implicitfast_system(y, p, h):
    mujoco_step(y, p, h, IMPLICITFAST, True)


@njit(cache=True)
def implicit_system(y, p, h):
    mujoco_step(y, p, h, IMPLICIT, True)


ONE = np.ones(1)


def mujoco_steps(elements: bool) -> dict:
    """The NativeModel.split entries of a tree (with force elements or not): method name -> (step, weights)."""
    steps = (euler_system, implicitfast_system, implicit_system) if elements else (euler_tree, implicitfast_tree,
                                                                                   implicit_tree)
    return {name: (step, ONE) for name, step in zip(MUJOCO_METHODS, steps)}


__all__ = ["mujoco_step", "dof_parents", "euler_factor", "step_matrices", "mujoco_steps", "integrate_positions",
           "solve_general", "MUJOCO_METHODS"]
