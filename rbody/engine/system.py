"""A tree with its force elements (tendons, actuators, controls): the right-hand side a run integrates, and
rbody.Multibody, the public model whose dynamics equal MuJoCo's qfrc_passive, qfrc_actuator and qacc.

The tree's own algorithms (rbody.engine.multibody) read the front of the params row; the force elements
(rbody.engine.elements) follow it. An evaluation of the right-hand side at y = (qpos, qvel, phi, act):

    poses, motion subspaces, velocities, inertias      (the tree's _frames)
    joint springs and dampers                         (multibody.passive)
    tendon lengths, velocities, Jacobians              (actuation.tendon_kinematics)
    tendon springs and dampers                        (passive.tendon_passive)
    actuator lengths, moments, forces, act'            (actuation.transmission, actuation.actuator_forces)
    qacc by the articulated-body algorithm             (multibody.articulated_body)

and y' = (coordinate rates, qacc, phi', act'); entries of y past act (a run's step counter: rbody.control) have
rate 0. After every whole step (finish): phi folded into the quaternions, the activations clamped to their
ranges (MuJoCo clamps them after each step), and the next row of a control schedule written into the controls.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import carray, cfunc, njit

from rbody.engine import multibody as mb, pointers
from rbody.engine.actuation import actuator_forces, clip, tendon_kinematics, transmission
from rbody.engine.elements import (A_ACTADR, A_ACTLIM, A_ACTRANGE, A_DISABLED, ACT_SIZE, T_HIGH, T_LOW, TEN_SIZE,
                                   X_ACT, X_ACTGC, X_CTRL, X_JNTLIM, X_NA, X_NSCHED, X_NTEN, X_NU, X_SCHED, X_STEP,
                                   X_TEN, build_elements, extension_start, has_elements)
from rbody.engine.memory import address, keep_alive, stack_floats
from rbody.engine.fluid import fluid_forces
from rbody.engine.passive import gravity_compensation, tendon_passive

DEFAULT_TIMESTEP = 0.002  # [s] MuJoCo's default step: what actearly's next activation assumes outside a run

# The force elements' arrays of one evaluation (_force_views): per tendon length, velocity (nten,), J (nten, nv);
# per actuator length, velocity, ctrl (as applied), force (nu,), moment (nu, nv); act_dot (na,); qfrc (nv,) the
# actuators' generalised force.
ForceWork = namedtuple("ForceWork", ["ten_length", "ten_velocity", "ten_J", "length", "velocity", "ctrl", "force",
                                     "moment", "act_dot", "qfrc", "gravcomp"])


@njit(cache=True)
def force_size(p) -> int:
    """Floats of the force elements' workspace of one evaluation (_force_views)."""
    E = extension_start(p)
    nu, na, nten, nv = int(p[E + X_NU]), int(p[E + X_NA]), int(p[E + X_NTEN]), int(p[mb.H_DOFS])
    return nten * (2 + nv) + nu * (4 + nv) + na + 2 * nv


@njit(cache=True)
def _force_views(p, w, at):
    """The force elements' arrays, cut from w[at:] (w at least at + force_size(p) floats)."""
    E = extension_start(p)
    nu, na, nten, nv = int(p[E + X_NU]), int(p[E + X_NA]), int(p[E + X_NTEN]), int(p[mb.H_DOFS])
    ten_length, ten_velocity = carray(address(w, at), nten), carray(address(w, at + nten), nten)
    at += 2 * nten
    ten_J = carray(address(w, at), (nten, nv))
    at += nten * nv
    length, velocity = carray(address(w, at), nu), carray(address(w, at + nu), nu)
    ctrl, force = carray(address(w, at + 2 * nu), nu), carray(address(w, at + 3 * nu), nu)
    at += 4 * nu
    moment = carray(address(w, at), (nu, nv))
    at += nu * nv
    act_dot, qfrc, gravcomp = carray(address(w, at), na), carray(address(w, at + na), nv), carray(
        address(w, at + na + nv), nv)
    return ForceWork(ten_length, ten_velocity, ten_J, length, velocity, ctrl, force, moment, act_dot, qfrc, gravcomp)


@njit(cache=True)
def element_forces(p, q, v, act, w, at):
    """At a state whose tree quantities are in the workspace w (_frames): tendon kinematics, tendon passive forces
    added to the workspace's tau, and the actuators' forces, act' and qfrc (also added to tau), into the force
    views at w[at:]."""
    ws = mb._views(p, w)
    fw = _force_views(p, w, at)
    tendon_kinematics(p, q, v, w, fw.ten_length, fw.ten_velocity, fw.ten_J)
    tendon_passive(p, fw.ten_length, fw.ten_velocity, fw.ten_J, ws.tau)
    transmission(p, q, v, w, fw.ten_length, fw.ten_J, fw.length, fw.velocity, fw.moment)
    actuator_forces(p, act, fw.length, fw.velocity, fw.moment, fw.ctrl, fw.force, fw.act_dot, fw.qfrc)
    E = extension_start(p)
    nv, nj = int(p[mb.H_DOFS]), int(p[mb.H_JOINTS])
    fluid_forces(p, ws.S, ws.xpos, ws.xmat, ws.vel, ws.h, ws.tau)
    gravity_compensation(p, ws.S, ws.h, ws.scratch, fw.gravcomp)
    actgc = int(p[E + X_ACTGC])
    for d in range(nv):  # MuJoCo: a passive force, or an actuator force where the joint says so
        if p[actgc + d] != 0.0:
            fw.qfrc[d] += fw.gravcomp[d]
        else:
            ws.tau[d] += fw.gravcomp[d]
    limits = int(p[E + X_JNTLIM])
    jo = int(p[mb.H_JOINT])
    for j in range(nj):  # the joints' clamp of the actuators' force (on each joint's first degree of freedom)
        if p[limits + 3 * j] != 0.0:
            d = int(p[jo + j * mb.JOINT_SIZE + mb.J_DADR])
            fw.qfrc[d] = clip(fw.qfrc[d], p[limits + 3 * j + 1], p[limits + 3 * j + 2])
    for d in range(nv):
        ws.tau[d] += fw.qfrc[d]


@njit(cache=True)
def _element_workspace(p, q, v, act):
    """A workspace with the tree's quantities at (q, v) and the force elements' at act (tau: the elements' alone)."""
    tree = mb.workspace_size(p)
    w = np.empty(tree + force_size(p))
    ws = mb._views(p, w)
    mb._frames(p, q, v, w)
    for d in range(ws.tau.shape[0]):
        ws.tau[d] = 0.0
    element_forces(p, q, v, act, w, tree)
    return w


@njit(cache=True)
def add_element_forces(p, q, v, act, tau, rates=None):
    """tau (nv,) += the force elements' generalised forces at the effective qpos q, qvel v and activations act (na,),
    with the controls written in p: tendon springs and dampers, fluid forces, gravity compensation and the
    actuators' qfrc (element_forces): the smooth forces the constraint layer adds to a constrained tree's
    (rbody.engine.constraints.dynamics.snapshot). rates (na,) or None: also act' as actuator_rates gives it, from
    the same evaluation (one outward pass and one of the elements, not two)."""
    w = _element_workspace(p, q, v, act)
    ws = mb._views(p, w)
    for d in range(tau.shape[0]):
        tau[d] += ws.tau[d]
    if rates is not None:
        _rates_from(p, w, rates)
    keep_alive(w)  # read through views only: the workspace must outlive them


@njit(cache=True)
def actuator_rates(p, q, v, act, out):
    """out (na,) = act' at (q, v, act) with the controls written in p, 0 for a disabled actuator's activation (as
    system_rhs forms it): a constrained tree's activations (rbody.engine.constraints.dynamics)."""
    w = _element_workspace(p, q, v, act)
    _rates_from(p, w, out)
    keep_alive(w)


@njit(cache=True)
def _rates_from(p, w, out):
    """out (na,) = act' from an element workspace (_element_workspace), 0 for a disabled actuator's activation."""
    fw = _force_views(p, w, mb.workspace_size(p))
    E = extension_start(p)
    for i in range(int(p[E + X_NU])):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        adr = int(p[r + A_ACTADR])
        if adr >= 0:
            out[adr] = 0.0 if p[r + A_DISABLED] != 0.0 else fw.act_dot[adr]


@njit(cache=True, inline="always")
def act_offset(p) -> int:
    """Where act starts in the native state y: after qpos (nq), qvel (nv) and phi (3 per ball or free joint)."""
    return int(p[mb.H_NQ]) + int(p[mb.H_DOFS]) + 3 * int(p[mb.H_ROT])


@njit(cache=True)
def system_rhs(y, p, out):
    """y' for y = (qpos, qvel, phi, act[, steps]) of a tree with force elements (module docstring)."""
    nq, nv = int(p[mb.H_NQ]), int(p[mb.H_DOFS])
    E = extension_start(p)
    na = int(p[E + X_NA])
    tree = mb.workspace_size(p)
    size = tree + force_size(p)
    w = carray(stack_floats(size), size) if size <= mb.STACK_FLOATS else np.empty(size)
    ws = mb._views(p, w)
    q = ws.q
    mb._effective_qpos(p, y, w, mb._offsets(p).q)  # q: the workspace's qpos, quaternions turned by phi
    v = y[nq:nq + nv]
    a0 = act_offset(p)
    act = y[a0:a0 + na]
    mb._frames(p, q, v, w)
    mb.passive(p, q, v, ws.tau)
    element_forces(p, q, v, act, w, tree)
    mb.articulated_body(p, w, out[nq:nq + nv])
    mb.coordinate_rates(p, y, out)
    fw = _force_views(p, w, tree)
    for i in range(int(p[E + X_NU])):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        adr = int(p[r + A_ACTADR])
        if adr >= 0:
            out[a0 + adr] = 0.0 if p[r + A_DISABLED] != 0.0 else fw.act_dot[adr]
    for j in range(a0 + na, out.shape[0]):
        out[j] = 0.0
    keep_alive(w)  # on the heap for huge trees, read through views only: it must outlive them


def _system_rhs_pointer():
    @cfunc(pointers.RHS_SIGNATURE, cache=True)
    def system_rhs_c(y, p, out, n, m):
        system_rhs(carray(y, n), carray(p, m), carray(out, n))
    return system_rhs_c


pointers.register(system_rhs, "rhs", _system_rhs_pointer)  # (its wrapper compiled once, not every process)


@njit(cache=True)
def clamp_activations(p, act):
    """act (na,) clamped to each actuator's actrange (MuJoCo, after every step)."""
    E = extension_start(p)
    for i in range(int(p[E + X_NU])):
        r = int(p[E + X_ACT]) + i * ACT_SIZE
        adr = int(p[r + A_ACTADR])
        if adr >= 0 and p[r + A_ACTLIM] != 0.0:
            act[adr] = clip(act[adr], p[r + A_ACTRANGE], p[r + A_ACTRANGE + 1])


@njit(cache=True)
def next_control(y, p):
    """With a control schedule (rbody.control): count the step just taken in y's last entry and write the
    schedule's row for the next step into the controls (the last row held once the schedule ends)."""
    E = extension_start(p)
    at = int(p[E + X_SCHED])
    if at < 0:
        return
    n = y.shape[0]
    steps = y[n - 1] + 1.0
    y[n - 1] = steps
    nu, rows = int(p[E + X_NU]), int(p[E + X_NSCHED])
    row = min(int(steps), rows - 1)
    ctrl = int(p[E + X_CTRL])
    for i in range(nu):
        p[ctrl + i] = p[at + row * nu + i]


@njit(cache=True)
def system_finish(y, p):
    """After every whole step: phi folded into the quaternions (multibody.tree_finish), activations clamped,
    the next scheduled control written (next_control)."""
    if int(p[mb.H_ROT]) > 0:
        mb.tree_finish(y, p)
    E = extension_start(p)
    a0 = act_offset(p)
    clamp_activations(p, y[a0:a0 + int(p[E + X_NA])])
    next_control(y, p)


# ----- batches of states ---------------------------------------------------------------------------------

@njit(cache=True)
def _actuation_batch(p, Q, V, C, A, qfrc, force, act_dot, length, velocity, ctrl, moment):
    """Per state b: the controls C[b] written into a copy of the row, then the actuators' quantities."""
    nu = int(p[extension_start(p) + X_NU])
    tree = mb.workspace_size(p)
    w = np.empty(tree + force_size(p))
    row = p.copy()
    at = int(p[extension_start(p) + X_CTRL])
    for b in range(Q.shape[0]):
        for i in range(nu):
            row[at + i] = C[b, i]
        mb._frames(row, Q[b], V[b], w)
        element_forces(row, Q[b], V[b], A[b], w, tree)
        fw = _force_views(row, w, tree)
        qfrc[b] = fw.qfrc
        force[b], act_dot[b], length[b], velocity[b], ctrl[b] = fw.force, fw.act_dot, fw.length, fw.velocity, fw.ctrl
        moment[b] = fw.moment
    keep_alive(w)


@njit(cache=True)
def _passive_batch(p, Q, V, out):
    """MuJoCo's qfrc_passive: the joints' springs and dampers and the tendons'."""
    tree = mb.workspace_size(p)
    w = np.empty(tree + force_size(p))
    for b in range(Q.shape[0]):
        ws = mb._views(p, w)
        mb._frames(p, Q[b], V[b], w)
        mb.passive(p, Q[b], V[b], ws.tau)
        fw = _force_views(p, w, tree)
        tendon_kinematics(p, Q[b], V[b], w, fw.ten_length, fw.ten_velocity, fw.ten_J)
        tendon_passive(p, fw.ten_length, fw.ten_velocity, fw.ten_J, ws.tau)
        fluid_forces(p, ws.S, ws.xpos, ws.xmat, ws.vel, ws.h, ws.tau)
        gravity_compensation(p, ws.S, ws.h, ws.scratch, fw.gravcomp)
        actgc = int(p[extension_start(p) + X_ACTGC])
        for d in range(ws.tau.shape[0]):
            if p[actgc + d] == 0.0:
                ws.tau[d] += fw.gravcomp[d]
        out[b] = ws.tau
    keep_alive(w)


@njit(cache=True)
def _tendon_batch(p, Q, V, length, velocity, J):
    tree = mb.workspace_size(p)
    w = np.empty(tree + force_size(p))
    for b in range(Q.shape[0]):
        mb._frames(p, Q[b], V[b], w)
        fw = _force_views(p, w, tree)
        tendon_kinematics(p, Q[b], V[b], w, fw.ten_length, fw.ten_velocity, fw.ten_J)
        length[b], velocity[b], J[b] = fw.ten_length, fw.ten_velocity, fw.ten_J
    keep_alive(w)


@njit(cache=True)
def _forward_batch(p, Q, V, T, C, A, out, act_dot):
    """qacc of every state with every force element at controls C and activations A; act_dot (B, na)."""
    nu, nv = int(p[extension_start(p) + X_NU]), int(p[mb.H_DOFS])
    tree = mb.workspace_size(p)
    w = np.empty(tree + force_size(p))
    row = p.copy()
    at = int(p[extension_start(p) + X_CTRL])
    bad = np.full(Q.shape[0], -1, dtype=np.int64)
    for b in range(Q.shape[0]):
        for i in range(nu):
            row[at + i] = C[b, i]
        ws = mb._views(row, w)
        mb._frames(row, Q[b], V[b], w)
        mb.passive(row, Q[b], V[b], ws.tau)
        element_forces(row, Q[b], V[b], A[b], w, tree)
        for d in range(nv):
            ws.tau[d] += T[b, d]
        bad[b] = mb.articulated_body(row, w, out[b])
        act_dot[b] = _force_views(row, w, tree).act_dot
    keep_alive(w)
    return bad


# ----- the public model ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ControlSlots:
    """Where a run writes its controls into a NativeModel (rbody.control): in every params row, the controls at
    `ctrl` (nu), the time step at `step`, the schedule's offset and rows at `schedule` and `rows` (the schedule
    itself appended to the row); in y, the activations at `act` (na)."""

    nu: int
    na: int
    ctrl: int
    step: int
    schedule: int
    rows: int
    act: int


class Multibody(mb.Multibody):
    """The dynamics of the tree of a Layout with its tendons and actuators (rbody.engine.multibody.Multibody for the
    tree's own algorithms, module docstring of rbody.engine.actuation for the elements).

    Multibody(layout, *, gravity=9.81 [m/s^2], timestep=0.002 [s]): timestep is the h of actearly's next
    activation (MuJoCo's opt.timestep; a run uses its own dt). Attributes besides the tree's: nu (actuators and
    controls), na (activations), ntendon, actuator_names, tendon_names, elements (rbody.engine.elements).
    Every method takes leading batch axes: q (..., nq), v (..., nv), ctrl (..., nu), act (..., na).
    passive_forces, forward_dynamics and inverse_dynamics include the tendons and actuators (MuJoCo's
    qfrc_passive and qacc).
    """

    def __init__(self, layout, *, gravity: float = 9.81, timestep: float = DEFAULT_TIMESTEP) -> None:
        super().__init__(layout, gravity=gravity)
        timestep = float(timestep)
        if not (np.isfinite(timestep) and timestep > 0):
            raise ValueError(f"timestep={timestep!r}: expected a time step > 0 [s]")
        self.timestep = timestep
        self.elements = None
        self.nu, self.na, self.ntendon = 0, 0, 0
        self.actuator_names: tuple[str, ...] = ()
        self.tendon_names: tuple[str, ...] = ()
        if not has_elements(layout):
            return
        tree_row = self.arrays.row
        elements = build_elements(layout, self.arrays, tree_row.size)
        row = np.concatenate([tree_row, elements.row])
        E = tree_row.size
        row[E + X_STEP] = timestep
        self.elements = elements
        self.nu, self.na, self.ntendon = elements.nu, elements.na, len(elements.tendon_names)
        self.actuator_names, self.tendon_names = elements.actuator_names, elements.tendon_names
        self._kernel_params = row
        if elements.spring_pending:  # spring lengths at the reference pose (joints at springref)
            length = self.tendons(self.spring_pose(), np.zeros(self.nv))["length"]
            for t in elements.spring_pending:
                r = int(row[E + X_TEN]) + t * TEN_SIZE
                row[r + T_LOW] = row[r + T_HIGH] = length[t]
        self.params = row.copy()
        self.params.setflags(write=False)

    @property
    def has_elements(self) -> bool:
        """Whether the model has force elements (tendons, actuators): its right-hand side is system_rhs."""
        return self.elements is not None

    def control_slots(self) -> ControlSlots:
        """Where a run writes its controls and time step (rbody.control)."""
        E = self.arrays.row.size
        row = self.params
        return ControlSlots(nu=self.nu, na=self.na, ctrl=int(row[E + X_CTRL]), step=E + X_STEP, schedule=E + X_SCHED,
                            rows=E + X_NSCHED, act=self.nq + self.nv + 3 * self.nrot)

    def spring_pose(self) -> np.ndarray:
        """(nq,) MuJoCo's qpos_spring: hinge and slide joints at springref, ball joints at identity, free bodies
        at their pos/quat."""
        q = np.array(self.qpos0, dtype=np.float64)
        joints = {j.name: j for j in self.layout.joints}
        for name, kind, qa in zip(self.joint_names, self.arrays.joint_kinds, self.arrays.qposadr):
            if kind in ("hinge", "slide", "roll"):
                q[qa] = joints[name].springref
            elif kind == "ball":
                q[qa:qa + 4] = (1.0, 0.0, 0.0, 0.0)
        return q

    # ----- arguments ---------------------------------------------------------------------------------

    def _controls(self, ctrl, act, shape) -> tuple[np.ndarray, np.ndarray]:
        """(C (B, nu), A (B, na)) broadcast to the batch `shape` of the states (zeros where not given)."""
        count = int(np.prod(shape)) if shape else 1
        out = []
        for value, size, what in ((ctrl, self.nu, "ctrl"), (act, self.na, "act")):
            if value is None:
                out.append(np.zeros((count, size)))
                continue
            if size == 0 and np.size(value) != 0:
                raise ValueError(f"{what} has shape {np.shape(value)}: the model has no {what} (size 0)")
            array = self._state(value, size, what) if size else np.zeros(tuple(shape) + (0,))
            try:
                array = np.broadcast_to(array, tuple(shape) + (size,))
            except ValueError:
                raise ValueError(f"{what} has shape {np.shape(value)}: expected (..., {size}) broadcasting to the "
                                 f"states' batch {tuple(shape)}") from None
            out.append(np.ascontiguousarray(array.reshape(count, size)))
        return out[0], out[1]

    # ----- the force elements ------------------------------------------------------------------------

    def actuation(self, q, v, ctrl=None, act=None, *, timestep: float | None = None) -> dict[str, np.ndarray]:
        """The actuators at states (q, v), controls ctrl (..., nu) (default 0) and activations act (..., na)
        (default 0), as MuJoCo's mj_fwdActuation (timestep [s]: the h of actearly, default the model's):
        "qfrc" (..., nv) qfrc_actuator, "force" (..., nu) actuator_force [N or N m], "act_dot" (..., na),
        "length" (..., nu) actuator_length, "velocity" (..., nu) actuator_velocity, "ctrl" (..., nu) the controls as
        applied (clamped to ctrlrange), "moment" (..., nu, nv) actuator_moment (d length / d qvel)."""
        shape, (Q, V) = self._batch((q, self.nq, "q"), (v, self.nv, "v"))
        C, A = self._controls(ctrl, act, shape)
        count, nu, na, nv = Q.shape[0], self.nu, self.na, self.nv
        out = {"qfrc": np.zeros((count, nv)), "force": np.zeros((count, nu)), "act_dot": np.zeros((count, na)),
               "length": np.zeros((count, nu)), "velocity": np.zeros((count, nu)), "ctrl": np.zeros((count, nu)),
               "moment": np.zeros((count, nu, nv))}
        row = self._kernel_params
        if timestep is not None:
            row = row.copy()
            row[self.arrays.row.size + X_STEP] = float(timestep)
        if nu:
            _actuation_batch(row, Q, V, C, A, out["qfrc"], out["force"], out["act_dot"],
                             out["length"], out["velocity"], out["ctrl"], out["moment"])
        return {name: value.reshape(shape + value.shape[1:]) for name, value in out.items()}

    def actuator_forces(self, q, v, ctrl=None, act=None) -> np.ndarray:
        """(..., nv) MuJoCo's qfrc_actuator at states (q, v), controls ctrl (..., nu) and activations act (..., na)
        (both default 0): moment^T actuator_force (actuation() gives the rest)."""
        return self.actuation(q, v, ctrl, act)["qfrc"]

    def tendons(self, q, v) -> dict[str, np.ndarray]:
        """"length" (..., nten) MuJoCo's ten_length, "velocity" (..., nten) ten_velocity, "jacobian" (..., nten,
        nv) ten_J, at states (q, v)."""
        shape, (Q, V) = self._batch((q, self.nq, "q"), (v, self.nv, "v"))
        count, nten = Q.shape[0], self.ntendon
        length, velocity, J = np.zeros((count, nten)), np.zeros((count, nten)), np.zeros((count, nten, self.nv))
        if nten:
            _tendon_batch(self._kernel_params, Q, V, length, velocity, J)
        return {"length": length.reshape(shape + (nten,)), "velocity": velocity.reshape(shape + (nten,)),
                "jacobian": J.reshape(shape + (nten, self.nv))}

    # ----- the tree's algorithms with the elements ------------------------------------------------------

    def passive_forces(self, q, v) -> np.ndarray:
        """(..., nv) MuJoCo's qfrc_passive: joint and tendon springs and dampers, fluid forces, gravity compensation
        (but on the joints with actuatorgravcomp)."""
        if not self.has_elements:
            return super().passive_forces(q, v)
        shape, (Q, V) = self._batch((q, self.nq, "q"), (v, self.nv, "v"))
        out = np.empty((Q.shape[0], self.nv))
        _passive_batch(self._kernel_params, Q, V, out)
        return out.reshape(shape + (self.nv,))

    def forward_dynamics(self, q, v, tau=None, ctrl=None, act=None) -> np.ndarray:
        """qacc (..., nv) = M^-1 (tau + qfrc_passive + qfrc_actuator - bias) (MuJoCo's qacc with constraints off);
        tau (..., nv) applied generalised forces (default 0), ctrl (..., nu) and act (..., na) the actuators'
        controls and activations (default 0). Raises ValueError where M is singular."""
        if not self.has_elements:
            if ctrl is not None or act is not None:
                self._controls(ctrl, act, ())  # the model has no actuators: a control of size > 0 is an error
            return super().forward_dynamics(q, v, tau)
        tau = np.zeros(self.nv) if tau is None else tau
        shape, (Q, V, T) = self._batch((q, self.nq, "q"), (v, self.nv, "v"), (tau, self.nv, "tau"))
        C, A = self._controls(ctrl, act, shape)
        out, act_dot = np.empty((Q.shape[0], self.nv)), np.empty((Q.shape[0], self.na))
        bad = _forward_batch(self._kernel_params, Q, V, T, C, A, out, act_dot)
        if np.any(bad >= 0):
            self.check_pivots(Q[int(np.argmax(bad >= 0))])
        return out.reshape(shape + (self.nv,))

    def inverse_dynamics(self, q, v, a, ctrl=None, act=None) -> np.ndarray:
        """tau (..., nv) with forward_dynamics(q, v, tau, ctrl, act) = a: M a + bias - qfrc_passive - qfrc_actuator."""
        if not self.has_elements:
            return super().inverse_dynamics(q, v, a)
        shape, (Q, V, A) = self._batch((q, self.nq, "q"), (v, self.nv, "v"), (a, self.nv, "a"))
        out = np.empty((Q.shape[0], self.nv))
        mb._inverse_batch(self._kernel_params, Q, V, A, True, out)
        out -= self.passive_forces(Q, V) + self.actuator_forces(Q, V, *self._controls(ctrl, act, shape))
        return out.reshape(shape + (self.nv,))

    def __repr__(self) -> str:
        base = super().__repr__()
        if not self.has_elements:
            return base
        return base[:-1] + f", nu={self.nu}, na={self.na}, tendons={self.ntendon})"


__all__ = ["Multibody", "ControlSlots", "system_rhs", "system_finish", "element_forces", "add_element_forces", "actuator_rates",
           "clamp_activations",
           "force_size",
           "DEFAULT_TIMESTEP"]
