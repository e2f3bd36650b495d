"""Pinocchio as a backend: the same model's dynamics from the reference implementation of the rigid-body
algorithms, integrated with the same scheme and step as rbody's run, so that two implementations of the
dynamics (rbody's ABA, RNEA and CRBA against Pinocchio's aba, rnea and crba) are compared on the user's model.

The model:

- a scene read from a URDF file (rbody.from_urdf) is built from the SAME FILE by Pinocchio's own parser,
  pin.buildModelFromUrdf (with JointModelFreeFlyer "root_joint" for floating_base): Pinocchio's reading of the
  file's masses, frames and axes, not rbody's;
- any other scene (the chapter's, an MJCF model, a user's Layout) is built through Pinocchio's model API from the
  scene's Layout: each hinge a JointModelRevoluteUnaligned, each slide a JointModelPrismaticUnaligned, a ball a
  JointModelSpherical, a free joint a JointModelFreeFlyer, several joints on one body a chain of joints with no
  mass between them (MuJoCo's composition: each joint at its anchor, in the body's axes), every body's Inertia
  appended to its last joint.

Conventions at this edge (rbody's and MuJoCo's qpos/qvel on one side, Pinocchio's on the other, mapped by joint
name: Pinocchio orders a URDF link's children by joint name, rbody and MuJoCo by their place in the file):

- continuous joints: Pinocchio's qpos is (cos q, sin q); the angle is unwrapped step by step;
- free joints: Pinocchio's qpos is the joint frame's placement relative to the joint's origin, quaternion
  (x, y, z, w); its qvel is (v, omega) both in the BODY frame; rbody's is (v world, omega body). With
  v_pin = T v_rbody (T orthogonal: blockdiag(R^T, 1) per free joint) and a_pin = T a_rbody + Tdot v_rbody
  (Tdot v = (-omega x v_lin, 0)), the mass matrix, bias forces and accelerations compared are
  T^T M_pin T, T^T (b_pin + M_pin Tdot v) and T^T (a_pin - Tdot v);
- a URDF planar joint: Pinocchio's JointModelPlanar (x, y, cos, sin) with (vx, vy) in the turned frame, rbody's
  two slides and a hinge (MuJoCo's loader's): the same map with R the planar rotation. Pinocchio builds the plane
  as its frame's x-y plane whatever the file's axis; a planar axis other than z is refused here;
- damping (and for Layout scenes stiffness and armature): Pinocchio's aba applies no passive force, so the
  backend hands it tau = T (-damping v - stiffness (q - springref)) (damping from Pinocchio's own parse of
  the file), and model.armature;
- balance_inertia=True: the same rule (MuJoCo's balanceinertia) is applied to Pinocchio's inertias.

Integration ("rk4", the default, or "euler"): classical Runge-Kutta on (q_pin, v_pin), with q' the configuration
derivative of each joint in its embedding (unit quaternions and (cos, sin) as vectors, q' = 1/2 q (x) omega, the
position's derivative R v) and v' = aba at the configuration made unit: a smooth extension of the dynamics off
the manifold, so the method keeps its order; unit parts are renormalised after every step. On hinges and slides
alone this is exactly rbody's rk4; with continuous joints ((cos, sin) embedded), free or ball joints both are
fourth order (rbody's is Runge-Kutta-Munthe-Kaas on rotations, an angle on a continuous joint) and differ at the
truncation error (measured 3.6e-11 in qvel after 0.5 s at dt = 1e-3 on a three-joint arm).

Observables: every body's centre of mass, orientation, centre-of-mass velocity and angular velocity from
Pinocchio's own kinematics (forwardKinematics, the frames' placements and velocities), the joints' histories in
MuJoCo's conventions, then scene.observe. meta["dynamics"] holds, at up to five of the saved states, the largest
difference between rbody's mass matrix, bias forces and forward dynamics (scene.multibody or a Multibody of the
scene's layout) and Pinocchio's, relative to the largest entry of each: how far the two implementations agree.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rbody.checks import run_times, whole_number
from rbody.layout import JOINTS, WORLD, Layout
from rbody.scene import BodyStates, Scene
from rbody.trajectory import Trajectory

name = "pinocchio"
METHODS = ("rk4", "euler")
DYNAMICS_SAMPLES = 5   # saved states at which meta["dynamics"] compares rbody's and Pinocchio's dynamics


def check(scene: Scene) -> None:
    """Pinocchio runs an unbatched tree of bodies and joints (hinge, slide, ball, free) with no contact, no
    varying mass and no applied force; its forward dynamics (aba) have no contacts, no rolling constraint, and no
    joint limits, dry friction or equalities (a URDF read with constraints=False runs as aba runs it)."""
    _check_tree(scene)
    if scene.layout.constrained:
        way = (" (rbody.from_urdf(path, constraints=False), or compare --no-constraints, runs the file as aba does)"
               if hasattr(scene, "floating_base") else "")
        raise NotImplementedError(f"scene {scene.name!r} holds joint limits, dry friction or equalities: Pinocchio's "
                                  f"aba has none of them{way}")


def _check_tree(scene: Scene) -> None:
    """What build() needs: a tree Pinocchio's model can hold (its dynamics comparable, constraints aside)."""
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    if scene.batch_shape:
        raise NotImplementedError(f"Pinocchio runs one scene at a time; use scene.item(i) (scene {scene.name!r} is "
                                  f"a batch of shape {scene.batch_shape})")
    try:
        layout = scene.layout
    except NotImplementedError as reason:
        raise NotImplementedError(f"Pinocchio needs the scene's bodies and joints: {reason}") from None
    hooks = [h for h in ("body_mass", "slide_force", "pair_force") if callable(getattr(scene, h, None))]
    if hooks:
        raise NotImplementedError(f"scene {scene.name!r} sets {', '.join(hooks)} during the run: Pinocchio's "
                                  "forward dynamics here take a fixed model and no applied force")
    if layout.contacts:
        raise NotImplementedError(f"scene {scene.name!r} has contacts: Pinocchio's forward dynamics (aba) have no "
                                  "contact model")
    rolls = [j.name for j in layout.joints if j.kind == "roll"]
    if rolls:
        raise NotImplementedError(f"roll joints {rolls}: Pinocchio has no joint that ties a translation to a "
                                  "rotation (rolling without slipping)")


def preflight(scene: Scene) -> None:
    """Build the model as run() would (Pinocchio's parser of the scene's file, or its model API)."""
    check(scene)
    build(scene)


# ----- the model and the map between the two sets of coordinates ----------------------------------------------

@dataclass
class _Joint:
    """One Pinocchio joint and the rbody coordinates it holds."""

    kind: str                  # "scalar", "circle", "ball", "free", "planar"
    names: tuple               # rbody joint names (planar: _TX, _TY, _RZ)
    rq: int                    # rbody qpos address; planar: of _TX (the three are consecutive)
    rv: int
    pq: int                    # Pinocchio idx_q, idx_v
    pv: int
    placement: object = None   # free: the joint's placement in its parent (world)


class PinocchioModel:
    """A Pinocchio model of a scene and the map between rbody's (MuJoCo's) coordinates and Pinocchio's.

    model, data: Pinocchio's; origin: "file" (pin.buildModelFromUrdf of the scene's URDF) or "layout";
    bodies: rbody body name -> (Pinocchio frame id, centre of mass in the body frame (3,) [m]);
    damping (nv,), stiffness (nv,), springref (nv,): passive coefficients in rbody's coordinates."""

    def __init__(self, scene: Scene) -> None:
        layout = scene.layout
        self.scene, self.layout = scene, layout
        from rbody.engine.multibody import Multibody

        self.rbody = getattr(scene, "multibody", None) or Multibody(layout, gravity=_gravity(scene))
        self.names = list(self.rbody.joint_names)
        kinds = list(self.rbody.arrays.joint_kinds)
        self.qposadr = dict(zip(self.names, (int(a) for a in self.rbody.arrays.qposadr)))
        self.dofadr = dict(zip(self.names, (int(a) for a in self.rbody.arrays.dofadr)))
        self.kinds = dict(zip(self.names, kinds))
        self.nq, self.nv = self.rbody.nq, self.rbody.nv
        self.notes: list[str] = []
        source = getattr(scene, "source", None)
        if source is not None and hasattr(scene, "floating_base"):
            self.origin = "file"
            self._from_file(scene, source)
        else:
            self.origin = "layout"
            self._from_layout(layout)
        self.model.gravity.linear = np.array([0.0, 0.0, -_gravity(scene)])
        self.data = self.model.createData()
        covered = sorted(n for j in self.joints for n in j.names)
        if covered != sorted(self.names):
            raise ValueError(f"Pinocchio's model has joints {covered}, rbody's {sorted(self.names)}: not the same model")

    # ----- from the user's URDF file, through Pinocchio's parser -----

    def _from_file(self, scene, source: str) -> None:
        if scene.floating_base:
            model = pin.buildModelFromUrdf(source, pin.JointModelFreeFlyer())
        else:
            model = pin.buildModelFromUrdf(source)
        self.model = model
        self.joints = []
        self.damping = np.zeros(self.nv)
        for j in range(1, model.njoints):
            joint, jname = model.joints[j], model.names[j]
            short = joint.shortname()
            pq, pv = joint.idx_q, joint.idx_v
            if short == "JointModelPlanar":
                names = tuple(jname + s for s in ("_TX", "_TY", "_RZ"))
                axes = [np.asarray(scene.tree.joints[[x.name for x in scene.tree.joints].index(n)].axis) for n in names]
                if not np.allclose(axes[2], (0.0, 0.0, 1.0), atol=1e-14):
                    raise NotImplementedError(f"planar joint {jname!r}: Pinocchio's planar joint is the x-y plane of "
                                              f"its frame; the file's axis {axes[2].tolist()} is not z")
                entry = _Joint("planar", names, self.qposadr[names[0]], self.dofadr[names[0]], pq, pv)
                self.damping[entry.rv:entry.rv + 3] = model.damping[pv:pv + 3]
            else:
                if jname not in self.qposadr:
                    raise ValueError(f"Pinocchio's joint {jname!r} is not a joint of rbody's model")
                kind = {"JointModelFreeFlyer": "free", "JointModelSpherical": "ball"}.get(
                    short, "circle" if short.startswith(("JointModelRUB", "JointModelRevoluteUnbounded")) else "scalar")
                entry = _Joint(kind, (jname,), self.qposadr[jname], self.dofadr[jname], pq, pv,
                               model.jointPlacements[j] if kind == "free" else None)
                width = JOINTS[self.kinds[jname]].nv
                self.damping[entry.rv:entry.rv + width] = model.damping[pv:pv + width]
            self.joints.append(entry)
        self.stiffness, self.springref = np.zeros(self.nv), np.zeros(self.nv)
        if getattr(scene, "balance_inertia", False):
            for j in range(1, model.njoints):
                inertia = model.inertias[j]
                moments = np.linalg.eigvalsh(inertia.inertia)
                if moments[0] + moments[1] < moments[2]:
                    model.inertias[j] = pin.Inertia(inertia.mass, inertia.lever, np.eye(3) * float(np.sum(moments)) / 3)
                    self.notes.append(f"joint {model.names[j]!r}: balance_inertia applied to Pinocchio's inertia too")
        self.bodies = {}
        for body in scene.tree.bodies:
            frame = model.getFrameId(body.name, pin.BODY)
            if frame >= model.nframes:
                raise ValueError(f"Pinocchio's model has no body frame {body.name!r}")
            placement = model.frames[frame].placement
            lever = model.inertias[model.frames[frame].parentJoint].lever
            self.bodies[body.name] = (frame, placement.actInv(lever) if hasattr(placement, "actInv") else
                                      placement.inverse().act(lever))

    # ----- from the scene's Layout, through Pinocchio's model API -----

    def _from_layout(self, layout: Layout) -> None:
        from rbody.layout import joint_order, tree_order

        model = pin.Model()
        self.joints, self.bodies = [], {}
        self.damping, self.stiffness, self.springref = (np.zeros(self.nv) for _ in range(3))
        armature = np.zeros(self.nv)
        frames = {WORLD: (0, pin.SE3.Identity(), 0)}   # body -> (carrying joint, body frame in it, frame id)
        by_body: dict[str, list] = {}
        for joint in joint_order(layout):
            by_body.setdefault(joint.body, []).append(joint)
        for body in tree_order(layout):
            parent_joint, parent_in_joint, parent_frame = frames[body.parent]
            placement = parent_in_joint * pin.SE3(_matrix(body.quat), np.asarray(body.pos, dtype=float))
            current, previous_anchor = parent_joint, None
            for joint in by_body.get(body.name, []):
                anchor = np.asarray(joint.anchor, dtype=float)
                if joint.kind == "free":
                    jmodel, at, kind = pin.JointModelFreeFlyer(), pin.SE3.Identity(), "free"
                else:
                    shift = anchor if previous_anchor is None else anchor - previous_anchor
                    at = (placement if previous_anchor is None else pin.SE3.Identity()) * pin.SE3(np.eye(3), shift)
                    axis = np.asarray(joint.axis, dtype=float)
                    jmodel, kind = {"hinge": (pin.JointModelRevoluteUnaligned(axis), "scalar"),
                                    "slide": (pin.JointModelPrismaticUnaligned(axis), "scalar"),
                                    "ball": (pin.JointModelSpherical(), "ball")}[joint.kind]
                    previous_anchor = anchor
                current = model.addJoint(current, jmodel, at, joint.name)
                rv = self.dofadr[joint.name]
                width = JOINTS[joint.kind].nv
                self.damping[rv:rv + width] = joint.damping
                armature[rv:rv + width] = joint.armature
                if JOINTS[joint.kind].scalar:
                    self.stiffness[rv], self.springref[rv] = joint.stiffness, joint.springref
                j = current
                self.joints.append(_Joint(kind, (joint.name,), self.qposadr[joint.name], rv, model.joints[j].idx_q,
                                          model.joints[j].idx_v, at if kind == "free" else None))
                placement = None
            if current == parent_joint:   # welded to its parent
                in_joint = placement
            elif previous_anchor is not None:
                in_joint = pin.SE3(np.eye(3), -previous_anchor)
            else:
                in_joint = pin.SE3.Identity()
            inertia = body.inertia
            model.appendBodyToJoint(current, pin.Inertia(float(inertia.mass), np.asarray(inertia.com, dtype=float),
                                                          np.asarray(inertia.tensor, dtype=float)), in_joint)
            frame = model.addFrame(pin.Frame(body.name, current, parent_frame, in_joint, pin.FrameType.BODY))
            frames[body.name] = (current, in_joint, frame)
            self.bodies[body.name] = (frame, np.asarray(inertia.com, dtype=float))
        model.armature = _pin_order(self, armature, model.nv)
        self.model = model

    # ----- coordinates -----

    def to_pin(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio's (q, v) of rbody's qpos (nq,), qvel (nv,)."""
        q, v = np.zeros(self.model.nq), np.zeros(self.model.nv)
        for j in self.joints:
            if j.kind == "scalar":
                q[j.pq], v[j.pv] = qpos[j.rq], qvel[j.rv]
            elif j.kind == "circle":
                q[j.pq:j.pq + 2] = math.cos(qpos[j.rq]), math.sin(qpos[j.rq])
                v[j.pv] = qvel[j.rv]
            elif j.kind == "ball":
                w, x, y, z = qpos[j.rq:j.rq + 4]
                q[j.pq:j.pq + 4], v[j.pv:j.pv + 3] = (x, y, z, w), qvel[j.rv:j.rv + 3]
            elif j.kind == "free":
                w, x, y, z = qpos[j.rq + 3:j.rq + 7]
                world = pin.SE3(pin.Quaternion(w, x, y, z).normalized().matrix(), qpos[j.rq:j.rq + 3].copy())
                local = j.placement.inverse() * world
                quat = pin.Quaternion(local.rotation).coeffs()
                q[j.pq:j.pq + 3], q[j.pq + 3:j.pq + 7] = local.translation, quat
                v[j.pv:j.pv + 3] = world.rotation.T @ qvel[j.rv:j.rv + 3]
                v[j.pv + 3:j.pv + 6] = qvel[j.rv + 3:j.rv + 6]
            else:  # planar
                x, y, theta = qpos[j.rq:j.rq + 3]
                c, s = math.cos(theta), math.sin(theta)
                q[j.pq:j.pq + 4] = x, y, c, s
                dx, dy, w = qvel[j.rv:j.rv + 3]
                v[j.pv:j.pv + 3] = c * dx + s * dy, -s * dx + c * dy, w
        return q, v

    def from_pin(self, q: np.ndarray, v: np.ndarray, previous: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """rbody's qpos, qvel of Pinocchio's (q, v); angles of continuous and planar joints unwrapped to within
        pi of `previous` (an rbody qpos)."""
        qpos, qvel = np.zeros(self.nq), np.zeros(self.nv)

        def angle(c, s, address):
            theta = math.atan2(s, c)
            if previous is not None:
                theta += 2 * math.pi * round((previous[address] - theta) / (2 * math.pi))
            return theta

        for j in self.joints:
            if j.kind == "scalar":
                qpos[j.rq], qvel[j.rv] = q[j.pq], v[j.pv]
            elif j.kind == "circle":
                qpos[j.rq], qvel[j.rv] = angle(q[j.pq], q[j.pq + 1], j.rq), v[j.pv]
            elif j.kind == "ball":
                x, y, z, w = q[j.pq:j.pq + 4]
                qpos[j.rq:j.rq + 4], qvel[j.rv:j.rv + 3] = (w, x, y, z), v[j.pv:j.pv + 3]
            elif j.kind == "free":
                x, y, z, w = q[j.pq + 3:j.pq + 7]
                local = pin.SE3(pin.Quaternion(w, x, y, z).normalized().matrix(), q[j.pq:j.pq + 3].copy())
                world = j.placement * local
                quat = pin.Quaternion(world.rotation).coeffs()
                qpos[j.rq:j.rq + 3] = world.translation
                qpos[j.rq + 3:j.rq + 7] = quat[3], quat[0], quat[1], quat[2]
                qvel[j.rv:j.rv + 3] = world.rotation @ v[j.pv:j.pv + 3]
                qvel[j.rv + 3:j.rv + 6] = v[j.pv + 3:j.pv + 6]
            else:
                c, s = q[j.pq + 2], q[j.pq + 3]
                norm = math.hypot(c, s)
                c, s = c / norm, s / norm
                qpos[j.rq:j.rq + 3] = q[j.pq], q[j.pq + 1], angle(c, s, j.rq + 2)
                vx, vy, w = v[j.pv:j.pv + 3]
                qvel[j.rv:j.rv + 3] = c * vx - s * vy, s * vx + c * vy, w
        return qpos, qvel

    def tangent(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T (nv_pin, nv), drift (nv_pin,)) at Pinocchio's (q, v): v_pin = T v_rbody, and d/dt v_pin =
        T a_rbody + drift. T is orthogonal."""
        T, drift = np.zeros((self.model.nv, self.nv)), np.zeros(self.model.nv)
        for j in self.joints:
            width = {"scalar": 1, "circle": 1, "ball": 3, "free": 6, "planar": 3}[j.kind]
            T[j.pv:j.pv + width, j.rv:j.rv + width] = np.eye(width)
            if j.kind == "free":
                x, y, z, w = q[j.pq + 3:j.pq + 7]
                rotation = j.placement.rotation @ pin.Quaternion(w, x, y, z).normalized().matrix()
                T[j.pv:j.pv + 3, j.rv:j.rv + 3] = rotation.T
                drift[j.pv:j.pv + 3] = -np.cross(v[j.pv + 3:j.pv + 6], v[j.pv:j.pv + 3])
            elif j.kind == "planar":
                c, s = q[j.pq + 2], q[j.pq + 3]
                norm = math.hypot(c, s)
                c, s = c / norm, s / norm
                T[j.pv:j.pv + 2, j.rv:j.rv + 2] = ((c, s), (-s, c))
                w = v[j.pv + 2]
                drift[j.pv:j.pv + 2] = w * v[j.pv + 1], -w * v[j.pv]
        return T, drift

    def unit(self, q: np.ndarray) -> np.ndarray:
        """q with every quaternion and (cos, sin) pair made unit."""
        q = q.copy()
        for j in self.joints:
            for start, width in {"circle": ((0, 2),), "ball": ((0, 4),), "free": ((3, 4),),
                                 "planar": ((2, 2),)}.get(j.kind, ()):
                part = q[j.pq + start:j.pq + start + width]
                q[j.pq + start:j.pq + start + width] = part / np.linalg.norm(part)
        return q

    def configuration_rate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """dq/dt (nq_pin,) of Pinocchio's configuration as a vector (quaternions and (cos, sin) embedded)."""
        rate = np.zeros(self.model.nq)
        for j in self.joints:
            if j.kind == "scalar":
                rate[j.pq] = v[j.pv]
            elif j.kind == "circle":
                rate[j.pq:j.pq + 2] = -q[j.pq + 1] * v[j.pv], q[j.pq] * v[j.pv]
            elif j.kind in ("ball", "free"):
                at, omega = (j.pq, v[j.pv:j.pv + 3]) if j.kind == "ball" else (j.pq + 3, v[j.pv + 3:j.pv + 6])
                x, y, z, w = q[at:at + 4]
                ox, oy, oz = omega
                rate[at:at + 4] = 0.5 * np.array([w * ox + y * oz - z * oy, w * oy + z * ox - x * oz,
                                                  w * oz + x * oy - y * ox, -x * ox - y * oy - z * oz])
                if j.kind == "free":
                    norm = math.sqrt(x * x + y * y + z * z + w * w)
                    rotation = pin.Quaternion(w / norm, x / norm, y / norm, z / norm).matrix()
                    rate[j.pq:j.pq + 3] = rotation @ v[j.pv:j.pv + 3]
            else:
                c, s = q[j.pq + 2], q[j.pq + 3]
                norm = math.hypot(c, s)
                vx, vy, w = v[j.pv:j.pv + 3]
                rate[j.pq:j.pq + 4] = (c * vx - s * vy) / norm, (s * vx + c * vy) / norm, -s * w, c * w
        return rate

    def passive(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Pinocchio's generalised passive force tau_pin = T (-damping v_rbody - stiffness (q - springref))."""
        T, _ = self.tangent(q, v)
        v_rbody = T.T @ v
        tau = -self.damping * v_rbody
        if np.any(self.stiffness):
            qpos, _ = self.from_pin(q, v)
            for j in self.joints:
                if j.kind in ("scalar", "circle"):
                    tau[j.rv] -= self.stiffness[j.rv] * (qpos[j.rq] - self.springref[j.rv])
        return T @ tau

    def acceleration(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """dv/dt (nv_pin,) = aba at the configuration made unit, with the passive forces."""
        q = self.unit(q)
        return pin.aba(self.model, self.data, q, v, self.passive(q, v)).copy()

    def dynamics(self, qpos: np.ndarray, qvel: np.ndarray) -> dict[str, np.ndarray]:
        """Pinocchio's mass matrix (nv, nv), bias forces (nv,) (gravity, Coriolis, centrifugal: MuJoCo's
        qfrc_bias) and forward dynamics (nv,) (with the passive forces) at rbody's qpos (nq,), qvel (nv,), in
        rbody's coordinates."""
        q, v = self.to_pin(np.asarray(qpos, dtype=float), np.asarray(qvel, dtype=float))
        T, drift = self.tangent(q, v)
        M = pin.crba(self.model, self.data, q).copy()
        M = np.triu(M) + np.triu(M, 1).T
        bias = pin.rnea(self.model, self.data, q, v, np.zeros(self.model.nv)).copy()
        acc = self.acceleration(q, v)
        return {"mass_matrix": T.T @ M @ T, "bias": T.T @ (bias + M @ drift), "qacc": T.T @ (acc - drift)}

    def body_states(self, q: np.ndarray, v: np.ndarray) -> dict[str, tuple]:
        """body -> (com (3,), quat (4,) (w, x, y, z), com velocity (3,), omega (3,)), world frame, from Pinocchio's
        kinematics at its (q, v)."""
        model, data = self.model, self.data
        q = self.unit(q)
        pin.forwardKinematics(model, data, q, v)
        pin.updateFramePlacements(model, data)
        out = {}
        for body, (frame, com_local) in self.bodies.items():
            placement = data.oMf[frame]
            velocity = pin.getFrameVelocity(model, data, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            rotation = placement.rotation
            arm = rotation @ com_local
            omega = velocity.angular.copy()
            x, y, z, w = pin.Quaternion(rotation).coeffs()
            out[body] = (placement.translation + arm, np.array([w, x, y, z]), velocity.linear + np.cross(omega, arm),
                         omega)
        return out


def _matrix(quat) -> np.ndarray:
    w, x, y, z = (float(c) for c in quat)
    return pin.Quaternion(w, x, y, z).normalized().matrix()


def _pin_order(model: PinocchioModel, values: np.ndarray, nv: int) -> np.ndarray:
    """A per-degree-of-freedom vector in rbody's order as Pinocchio's (the same joints, other addresses)."""
    out = np.zeros(nv)
    for j in model.joints:
        width = {"scalar": 1, "circle": 1, "ball": 3, "free": 6, "planar": 3}[j.kind]
        out[j.pv:j.pv + width] = values[j.rv:j.rv + width]
    return out


def _gravity(scene: Scene) -> float:
    return float(scene.gravity) if type(scene).applies_gravity else 0.0


def build(scene: Scene) -> PinocchioModel:
    """The PinocchioModel of `scene` (module docstring): its tree, whatever limits, friction or equalities the scene
    holds (run() refuses those). Raises NotImplementedError for a tree Pinocchio cannot hold, ValueError when
    Pinocchio's model is not rbody's (other joints)."""
    _check_tree(scene)
    return PinocchioModel(scene)


# ----- the run ---------------------------------------------------------------------------------------------

def run(scene: Scene, dt: float, t_end: float | None = None, *, method: str = "rk4", save_every: int = 1) -> Trajectory:
    """Run `scene` through Pinocchio's aba with step dt [s] for t_end [s] (default scene.t_end).

    method: "rk4" (default, rbody's and MuJoCo's RK4 scheme) or "euler" (explicit); save_every: keep every
    n-th step. Returns a Trajectory with the scene's observables; meta holds the backend, the model's origin
    ("file" or "layout"), Pinocchio's version, step_seconds (the stepping alone), run_seconds (with the
    observing) and "dynamics" (rbody against Pinocchio at sampled states, module docstring)."""
    if method not in METHODS:
        raise ValueError(f"method={method!r}: expected one of {METHODS}")
    dt, t_end = run_times(scene.t_end, dt, t_end)
    whole_number(save_every, "save_every")
    check(scene)
    model = build(scene)
    layout = scene.layout
    qpos0, qvel0 = _initial(scene, model)
    q, v = model.to_pin(qpos0, qvel0)
    nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
    nsteps = -(-nsteps // save_every) * save_every
    saved_q, saved_v = [q.copy()], [v.copy()]
    rate, acc, integrate = model.configuration_rate, model.acceleration, model.unit
    start = time.perf_counter()
    for k in range(1, nsteps + 1):
        if method == "rk4":
            k1q, k1v = rate(q, v), acc(q, v)
            q2, v2 = q + 0.5 * dt * k1q, v + 0.5 * dt * k1v
            k2q, k2v = rate(q2, v2), acc(q2, v2)
            q3, v3 = q + 0.5 * dt * k2q, v + 0.5 * dt * k2v
            k3q, k3v = rate(q3, v3), acc(q3, v3)
            q4, v4 = q + dt * k3q, v + dt * k3v
            k4q, k4v = rate(q4, v4), acc(q4, v4)
            q = q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        else:
            q, v = q + dt * rate(q, v), v + dt * acc(q, v)
        q = integrate(q)
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            from rbody.errors import SimulationError
            raise SimulationError(f"Pinocchio's run of {scene.name!r} became non-finite at t={k * dt:.6g} s")
        if k % save_every == 0:
            saved_q.append(q.copy())
            saved_v.append(v.copy())
    step_seconds = time.perf_counter() - start

    observing = time.perf_counter()
    count = len(saved_q)
    t = np.arange(count) * (dt * save_every)
    qpos, qvel = np.zeros((count, model.nq)), np.zeros((count, model.nv))
    previous = qpos0
    states = {b: [np.zeros((count, 3)), np.zeros((count, 4)), np.zeros((count, 3)), np.zeros((count, 3))]
              for b in model.bodies}
    for i, (qi, vi) in enumerate(zip(saved_q, saved_v)):
        qpos[i], qvel[i] = model.from_pin(qi, vi, previous)
        previous = qpos[i]
        for body, values in model.body_states(qi, vi).items():
            for store, value in zip(states[body], values):
                store[i] = value
    bodies = {b: BodyStates(com=s[0], quat=s[1], velocity=s[2], omega=s[3]) for b, s in states.items()}
    joints = {}
    for joint in layout.joints:
        qa, da, kind = model.qposadr[joint.name], model.dofadr[joint.name], JOINTS[joint.kind]
        if kind.scalar:
            joints[joint.name] = (qpos[:, qa].copy(), qvel[:, da].copy())
        else:
            joints[joint.name] = (qpos[:, qa:qa + kind.nq].copy(), qvel[:, da:da + kind.nv].copy())
    observables = dict(scene.observe(t, bodies, joints))
    run_seconds = step_seconds + time.perf_counter() - observing
    meta = {"scene": scene.name, "description": scene.describe(), "backend": name, "dt": dt, "t_end": t_end,
            "nsteps": nsteps, "save_every": save_every, "method": method, "model_origin": model.origin,
            "pinocchio_version": pin.__version__, "step_seconds": step_seconds, "run_seconds": run_seconds,
            "dynamics": dynamics_agreement(model, qpos, qvel), "notes": list(model.notes)}
    return Trajectory(t, observables, meta=meta)


def _initial(scene: Scene, model: PinocchioModel) -> tuple[np.ndarray, np.ndarray]:
    """rbody's initial qpos, qvel of the scene (a TreeScene's own, else the layout's joints')."""
    qpos0, qvel0 = getattr(scene, "qpos0", None), getattr(scene, "qvel0", None)
    if isinstance(qpos0, np.ndarray) and qpos0.shape == (model.nq,) and isinstance(qvel0, np.ndarray):
        return qpos0.astype(float), qvel0.astype(float)
    return np.asarray(model.rbody.qpos0, dtype=float), np.asarray(model.rbody.qvel0, dtype=float)


def dynamics_agreement(model: PinocchioModel, qpos: np.ndarray, qvel: np.ndarray) -> dict:
    """At up to DYNAMICS_SAMPLES saved states (evenly spread): the largest |rbody - Pinocchio| of the mass matrix,
    the bias forces and the forward dynamics, each relative to the largest |entry| of rbody's (rbody's Multibody of
    the scene against Pinocchio's model, in rbody's coordinates)."""
    picks = np.unique(np.linspace(0, len(qpos) - 1, min(DYNAMICS_SAMPLES, len(qpos))).round().astype(int))
    worst = {"mass_matrix": 0.0, "bias": 0.0, "qacc": 0.0}
    rbody = model.rbody
    for i in picks:
        theirs = model.dynamics(qpos[i], qvel[i])
        ours = {"mass_matrix": rbody.mass_matrix(qpos[i]), "bias": rbody.bias_forces(qpos[i], qvel[i]),
                "qacc": rbody.forward_dynamics(qpos[i], qvel[i])}
        for key in worst:
            scale = max(float(np.max(np.abs(ours[key]))), 1e-300)
            worst[key] = max(worst[key], float(np.max(np.abs(ours[key] - theirs[key]))) / scale)
    return {"states": int(len(picks)), **{f"{k}_relative": v for k, v in worst.items()}}
