"""PyBullet as a backend (Bullet's Featherstone multibodies, rigid contact through its sequential-impulse LCP
solver), in DIRECT mode: no window, one physics client per run.

The model:

- a scene read from a URDF file (rbody.from_urdf) is loaded by Bullet itself, pybullet.loadURDF of the same
  file, with URDF_USE_INERTIA_FROM_FILE and URDF_MERGE_FIXED_LINKS (module traps below), useFixedBase unless
  floating_base; joints mapped by name;
- any other scene is built with createMultiBody from its Layout: one multibody per free body (its base, the
  centre of mass, principal axes) and one for the rest, on a fixed massless base at the world origin: one link
  per hinge (JOINT_REVOLUTE), slide (JOINT_PRISMATIC) or ball (JOINT_SPHERICAL), several joints on one body a
  chain of massless links (MuJoCo's composition: each joint at its anchor, in the body's axes), a body without
  joints a JOINT_FIXED link; each body's mass and principal moments set explicitly (changeDynamics
  localInertiaDiagonal) with its inertial frame at the centre of mass along the principal axes;
- contacts: the Layout's pairs only (every other pair filtered out), shapes sphere, box, cylinder, capsule, plane
  (a plane as a large thin box); friction and restitution per body (Bullet multiplies the two bodies' values:
  each gets sqrt(e) and sqrt(mu), which needs every pair of a body to agree, else the scene is refused).

Bullet's traps, each undone here (and stated in the design notes):

- bodies get linear and angular damping 0.04 by default (btMultiBody's m_linearDamping, m_angularDamping): a
  pendulum loses energy at ~4 % per second. Set to 0 (changeDynamics linearDamping, angularDamping);
- every joint has a velocity motor at target 0 enabled by default (loadURDF and createMultiBody), a brake that
  acts like friction: disabled (setJointMotorControlArray VELOCITY_CONTROL force 0; for spherical joints
  setJointMotorControlMultiDof force (0, 0, 0));
- joint velocities are clamped to maxJointVelocity = 100 rad/s by default: raised to 1e4;
- gravity is 0 by default, and the default step is 1/240 s: both set from the scene and the run;
- loadURDF recomputes each link's inertia from its collision shapes unless URDF_USE_INERTIA_FROM_FILE; and a
  base link of mass 0 in a URDF makes Bullet's base static even with useFixedBase=False (the floating base then
  does not move): refused here (its rbody model has a free base of the merged mass);
- URDF_MERGE_FIXED_LINKS merges fixed links' inertias and centres of mass wrongly (measured: a 0.8 kg link with a
  0.2 kg tool 0.3 m below got principal moments (0.034, 0.035, 0.011) for (0.011, 0.025, 0.026) kg m^2 and its
  centre of mass 0.13 m off): not used; fixed links stay Bullet links and the observables merge them;
- a URDF joint axis that is not unit: Bullet's stepping uses it as written (calculateMassMatrix normalises it),
  so the joint's acceleration is wrong (measured 2 % on a (0.2, 1, 0) hinge, a 7.7e-3 rad offset after 0.5 s
  that does not shrink with dt); named in meta["notes"];
- loadURDF applies the file's joint limits itself (a limit constraint with ERP: measured 2e-3 rad past a stop at
  dt = 1 ms); a URDF scene read with constraints=False (the bare tree) has them removed here, one read with
  constraints (the default) keeps them, holds <dynamics friction> by a velocity motor at target 0 whose maximum force
  is the friction (Bullet's rigid Coulomb friction per joint, in its LCP) and a <mimic> by a gear constraint (Bullet's
  loadURDF ignores mimics); limits, friction and equalities of scenes built from a Layout are not built (refused);
- restitution needs restitutionVelocityThreshold lowered (default 0.2 m/s: slower impacts are inelastic) and
  ERP-based position correction (default on: penetration recovery adds energy): here splitImpulse on with
  the threshold at 1e-6 m/s.

Settings (run keywords): solver_iterations (numSolverIterations, default here 200; Bullet's 50), erp
(contact ERP; Bullet's default), restitution_threshold [m/s]. The integrator is Bullet's only one, semi-implicit
(symplectic) Euler: first order, so rbody's closed forms measure its error at O(dt).

Observables: every body's centre of mass, orientation, centre-of-mass velocity and world angular velocity from
getLinkState / getBasePositionAndOrientation / getBaseVelocity, joint histories from getJointState(MultiDof), then
scene.observe; for scenes with impacts, ``collisions`` and ``ball_collisions`` count contact onsets (a pair that
goes from no contact point to some) after every step, as MuJoCo's backend counts them.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pybullet as pb

from rbody.checks import run_times, whole_number
from rbody.layout import JOINTS, WORLD
from rbody.mjcf import has_impacts
from rbody.scene import BodyStates, Scene
from rbody.trajectory import Trajectory

name = "bullet"
SOLVER_ITERATIONS = 200
MAX_JOINT_VELOCITY = 1e4
PLANE_HALF = 50.0        # [m] a plane is a box this wide (Bullet's static plane needs its own shape type)
PLANE_THICKNESS = 0.5    # [m] its half depth, below the surface
_KINDS = {"hinge": pb.JOINT_REVOLUTE, "slide": pb.JOINT_PRISMATIC, "ball": pb.JOINT_SPHERICAL}


def check(scene: Scene) -> None:
    """Bullet runs an unbatched scene of hinges, slides, balls and free bodies, with contacts between spheres,
    boxes, cylinders, capsules and planes; not roll joints (no rolling constraint), not varying masses or applied
    forces, not a URDF planar or floating inner joint."""
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    if scene.batch_shape:
        raise NotImplementedError(f"Bullet runs one scene at a time; use scene.item(i) (scene {scene.name!r} is a "
                                  f"batch of shape {scene.batch_shape})")
    try:
        layout = scene.layout
    except NotImplementedError as reason:
        raise NotImplementedError(f"Bullet needs the scene's bodies and joints: {reason}") from None
    hooks = [h for h in ("body_mass", "slide_force", "pair_force") if callable(getattr(scene, h, None))]
    if hooks:
        raise NotImplementedError(f"scene {scene.name!r} sets {', '.join(hooks)} during the run: not built for "
                                  "Bullet here")
    rolls = [j.name for j in layout.joints if j.kind == "roll"]
    if rolls:
        raise NotImplementedError(f"roll joints {rolls}: Bullet has no joint that ties a translation to a rotation")
    if _from_file(scene):
        if getattr(scene, "constraints", False):
            still = [f for f, (_, multiplier, _) in getattr(scene, "mimics", {}).items() if multiplier == 0]
            if still:
                raise NotImplementedError(f"mimic joints {still} with multiplier 0: Bullet's gear constraint ties "
                                          "two joints' rates, it cannot hold one joint still")
        planar = [j.name for j in layout.joints if j.name.endswith("_TX")]
        inner_free = [j.name for j in layout.joints if j.kind == "free" and j.name != "root_joint"]
        if planar or inner_free:
            raise NotImplementedError(f"joints {planar + inner_free}: Bullet's URDF loader has no planar or floating "
                                      "joint between links")
        return
    if layout.joint_constraints:  # contacts are built below
        raise NotImplementedError(f"scene {scene.name!r} has joint limits, dry friction or equalities: built for "
                                  "Bullet from a URDF file only (loadURDF's limits, velocity motors as friction, gear "
                                  "constraints as mimics)")
    for body in layout.bodies:
        for shape in body.shapes:
            if shape.kind == "mesh" and any(shape.name in (c.shape_a, c.shape_b) for c in layout.contacts):
                raise NotImplementedError(f"shape {shape.name!r}: mesh contacts are not built for Bullet here")
    _coefficients(layout)


def _from_file(scene: Scene) -> bool:
    return getattr(scene, "source", None) is not None and hasattr(scene, "floating_base")


def _coefficients(layout) -> dict[str, tuple[float, float]]:
    """shape -> (sqrt(restitution), sqrt(friction)): Bullet multiplies the two bodies' values."""
    out: dict[str, tuple[float, float]] = {}
    for contact in layout.contacts:
        pair = (math.sqrt(contact.restitution), math.sqrt(contact.friction))
        for shape in (contact.shape_a, contact.shape_b):
            if out.setdefault(shape, pair) != pair:
                raise NotImplementedError(f"shape {shape!r} is in contacts with different friction or restitution: "
                                          "Bullet gives a body one value of each and multiplies the pair's")
    return out


# ----- building -------------------------------------------------------------------------------------------

def _xyzw(quat) -> list[float]:
    w, x, y, z = (float(c) for c in quat)
    return [x, y, z, w]


def _wxyz(quat) -> np.ndarray:
    x, y, z, w = quat
    return np.array([w, x, y, z])


def _principal(inertia):
    moments, axes = np.linalg.eigh(np.asarray(inertia.tensor, dtype=float))
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    from rbody.motion import quat_from_matrix

    return np.maximum(moments, 0.0), quat_from_matrix(axes)


def _shape(client, shape, coefficients):
    """(collision shape id, its frame (pos, quat xyzw) in the link frame it is attached to)."""
    kind, size = shape.kind, shape.size
    if kind == "sphere":
        sid = pb.createCollisionShape(pb.GEOM_SPHERE, radius=size[0], physicsClientId=client)
    elif kind == "box":
        sid = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(size), physicsClientId=client)
    elif kind == "cylinder":
        sid = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=size[0], height=2 * size[1], physicsClientId=client)
    elif kind == "capsule":
        sid = pb.createCollisionShape(pb.GEOM_CAPSULE, radius=size[0], height=2 * size[1], physicsClientId=client)
    elif kind == "plane":
        sid = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[PLANE_HALF, PLANE_HALF, PLANE_THICKNESS],
                                      physicsClientId=client)
        from rbody.motion import quat_to_matrix

        below = np.asarray(shape.pos) - quat_to_matrix(np.asarray(shape.quat)) @ np.array([0, 0, PLANE_THICKNESS])
        return sid, (below.tolist(), _xyzw(shape.quat))
    else:
        raise NotImplementedError(f"shape {shape.name!r} of kind {kind!r} is not built for Bullet here")
    return sid, (list(shape.pos), _xyzw(shape.quat))


class _Built:
    """The Bullet world of a scene: ids, and where each rbody body and joint lives."""

    def __init__(self, scene: Scene, dt: float, solver_iterations: int, erp, restitution_threshold: float) -> None:
        self.client = pb.connect(pb.DIRECT)
        self.scene, self.layout = scene, scene.layout
        client = self.client
        g = float(scene.gravity) if type(scene).applies_gravity else 0.0
        pb.setGravity(0, 0, -g, physicsClientId=client)
        params = dict(fixedTimeStep=dt, numSolverIterations=int(solver_iterations), numSubSteps=0,
                      restitutionVelocityThreshold=restitution_threshold, enableConeFriction=1)
        if erp is not None:
            params["contactERP"] = float(erp)
        if self.layout.contacts:
            params["useSplitImpulse"] = 1
        pb.setPhysicsEngineParameter(**params, physicsClientId=client)
        self.bodies: dict[str, tuple] = {}    # rbody body -> (multibody id, link index or -1, com in body frame, quat)
        self.joints: dict[str, tuple] = {}    # rbody joint -> (multibody id, joint index, kind)
        self.shapes: dict[str, tuple] = {}    # shape name -> (multibody id, link index)
        self.members: dict[str, list] = {}    # URDF: body -> [(Bullet link, its mass)] merged into it
        self.notes: list[str] = []
        if _from_file(scene):
            self._load(scene)
        else:
            self._build()
        self._free_everything()
        if _from_file(scene):
            self._urdf_constraints(scene)

    def _load(self, scene) -> None:
        client = self.client
        flags = pb.URDF_USE_INERTIA_FROM_FILE | pb.URDF_MAINTAIN_LINK_ORDER
        with _quiet():  # Bullet's URDF importer prints its progress on the process's stdout
            uid = pb.loadURDF(scene.source, useFixedBase=not scene.floating_base, flags=flags, physicsClientId=client)
        self.ids = [uid]
        links, fixed_children = {}, {}
        for j in range(pb.getNumJoints(uid, physicsClientId=client)):
            info = pb.getJointInfo(uid, j, physicsClientId=client)
            joint_name, link_name = info[1].decode(), info[12].decode()
            links[link_name] = j
            if info[2] == pb.JOINT_FIXED:
                fixed_children.setdefault(info[16], []).append(j)
            if info[2] in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC, pb.JOINT_SPHERICAL):
                self.joints[joint_name] = (uid, j, info[2])
                length = float(np.linalg.norm(info[13]))
                if info[2] != pb.JOINT_SPHERICAL and abs(length - 1) > 1e-9:
                    self.notes.append(f"joint {joint_name!r}: the file's axis has length {length:.6g}; Bullet steps "
                                      "with it as written (its mass matrix API normalises it, its forward dynamics "
                                      "do not), so its accelerations differ from the normalised joint's")
        for body in self.layout.bodies:
            link = -1 if body.name == scene.root else links.get(body.name)
            if link is None:
                raise NotImplementedError(f"Bullet's model of {scene.source} has no link {body.name!r}")
            mass = pb.getDynamicsInfo(uid, link, physicsClientId=client)[0]
            if link == -1 and mass == 0:
                raise NotImplementedError(f"the root link {body.name!r} has mass 0 in Bullet's reading of the file: "
                                          "Bullet makes a massless base static even with a floating base")
            self.bodies[body.name] = (uid, link, None, None)
            members, stack = [], [link]
            while stack:  # the links Bullet keeps apart that rbody merged into this body (fixed joints)
                member = stack.pop()
                members.append((member, pb.getDynamicsInfo(uid, member, physicsClientId=client)[0]))
                stack += fixed_children.get(member, [])
            self.members[body.name] = members
        missing = [j.name for j in self.layout.joints if j.kind != "free" and j.name not in self.joints]
        if missing:
            raise NotImplementedError(f"Bullet's model of {scene.source} has no moving joints {missing}")

    def _build(self) -> None:
        client, layout = self.client, self.layout
        from rbody.layout import joint_order, tree_order

        coefficients = _coefficients(layout)
        by_body: dict[str, list] = {}
        for joint in joint_order(layout):
            by_body.setdefault(joint.body, []).append(joint)
        order = tree_order(layout)
        free = [b for b in order if [j.kind for j in by_body.get(b.name, [])] == ["free"]]
        # one multibody per subtree hanging from the world (Bullet does not collide the links of one multibody)
        self.ids = []
        roots: dict[str, str] = {}
        for body in order:
            roots[body.name] = body.name if body.parent == WORLD else roots[body.parent]
        groups: dict[str, list] = {}
        for body in order:
            if body not in free:
                groups.setdefault(roots[body.name], []).append(body)
        for group in groups.values():
            links = dict(masses=[], shapes=[], positions=[], orientations=[], inertial_pos=[], inertial_orn=[],
                         parents=[], types=[], axes=[])
            where: dict[str, tuple] = {WORLD: (0, np.zeros(3))}  # body -> (link index + 1 holding it, body origin in it)
            link_of_shape: dict[str, int] = {}
            pending_dynamics = []
            from rbody.motion import quat_multiply, quat_to_matrix

            for body in group:
                parent_link, parent_origin = where[body.parent]
                joints = by_body.get(body.name, [])
                moments, principal = _principal(body.inertia)
                position = parent_origin + np.asarray(body.pos, dtype=float)
                orientation = np.asarray(body.quat, dtype=float)
                # Bullet's link frames here are turned by orientation only on the first link of a body
                previous_anchor = None
                parent = parent_link
                joints_here = joints or [None]
                for k, joint in enumerate(joints_here):
                    anchor = np.zeros(3) if joint is None else np.asarray(joint.anchor, dtype=float)
                    if k == 0:
                        pos = position + quat_to_matrix(orientation) @ anchor
                        orn = orientation
                    else:
                        pos, orn = anchor - previous_anchor, np.array([1.0, 0, 0, 0])
                    previous_anchor = anchor
                    last = k == len(joints_here) - 1
                    links["positions"].append(pos.tolist())
                    links["orientations"].append(_xyzw(orn))
                    links["parents"].append(parent)
                    links["types"].append(pb.JOINT_FIXED if joint is None else _KINDS[joint.kind])
                    links["axes"].append([0.0, 0.0, 1.0] if joint is None or joint.kind == "ball" else list(joint.axis))
                    if last:
                        com = np.asarray(body.inertia.com, dtype=float) - anchor
                        links["masses"].append(float(body.inertia.mass))
                        links["inertial_pos"].append(com.tolist())
                        links["inertial_orn"].append(_xyzw(principal))
                        pending_dynamics.append((len(links["masses"]) - 1, moments))
                    else:
                        links["masses"].append(0.0)
                        links["inertial_pos"].append([0.0, 0.0, 0.0])
                        links["inertial_orn"].append([0.0, 0.0, 0.0, 1.0])
                        pending_dynamics.append((len(links["masses"]) - 1, np.zeros(3)))
                    links["shapes"].append(-1)
                    index = len(links["masses"])  # Bullet's parent index of the next link (1-based)
                    if joint is not None:
                        self.joints[joint.name] = (None, index - 1, _KINDS[joint.kind])
                    parent = index
                where[body.name] = (parent, -previous_anchor)
                self.bodies[body.name] = (None, parent - 1, np.asarray(body.inertia.com, dtype=float), None)
                for shape in body.shapes:
                    link_of_shape[shape.name] = parent - 1
            compound: dict[int, list] = {}
            for body in group:
                origin = where[body.name][1]
                for shape in body.shapes:
                    if shape.name in coefficients:  # in the frame of the body's last link: shifted by -anchor
                        moved = dataclasses.replace(shape, pos=tuple((np.asarray(shape.pos) + origin).tolist()))
                        compound.setdefault(link_of_shape[shape.name], []).append(moved)
            for link, shapes in compound.items():
                links["shapes"][link] = pb.createCollisionShapeArray([_geom(s) for s in shapes], **_geom_args(shapes),
                                                                     physicsClientId=client)
                for shape in shapes:
                    self.shapes[shape.name] = (None, link)
            if links["masses"]:
                uid = pb.createMultiBody(0.0, -1, -1, [0, 0, 0], [0, 0, 0, 1], linkMasses=links["masses"],
                                         linkCollisionShapeIndices=links["shapes"],
                                         linkVisualShapeIndices=[-1] * len(links["masses"]),
                                         linkPositions=links["positions"], linkOrientations=links["orientations"],
                                         linkInertialFramePositions=links["inertial_pos"],
                                         linkInertialFrameOrientations=links["inertial_orn"],
                                         linkParentIndices=links["parents"], linkJointTypes=links["types"],
                                         linkJointAxis=links["axes"], physicsClientId=client)
                self.ids.append(uid)
                for index, moments in pending_dynamics:
                    pb.changeDynamics(uid, index, localInertiaDiagonal=moments.tolist(), physicsClientId=client)
                for table in (self.joints, self.bodies, self.shapes):
                    for key, value in table.items():
                        if value[0] is None:
                            table[key] = (uid,) + tuple(value[1:])
        for body in free:  # a multibody whose base is the body, at its centre of mass along its principal axes
            moments, principal = _principal(body.inertia)
            shapes = [s for s in body.shapes if s.name in coefficients]
            cid = -1
            if shapes:
                inverse_com = [dataclasses.replace(s, pos=tuple(_in_principal(s.pos, body.inertia, principal)),
                                                   quat=tuple(quat_multiply(_conj(principal), np.asarray(s.quat)).tolist()))
                               for s in shapes]
                cid = pb.createCollisionShapeArray([_geom(s) for s in inverse_com], **_geom_args(inverse_com),
                                                   physicsClientId=client)
            uid = pb.createMultiBody(float(body.inertia.mass), cid, -1, [0, 0, 0], [0, 0, 0, 1],
                                     physicsClientId=client)
            pb.changeDynamics(uid, -1, localInertiaDiagonal=moments.tolist(), physicsClientId=client)
            self.ids.append(uid)
            self.bodies[body.name] = (uid, -1, np.asarray(body.inertia.com, dtype=float), principal)
            for s in shapes:
                self.shapes[s.name] = (uid, -1)
        fixed = [s for s in layout.fixed if s.name in coefficients]
        for shape in fixed:
            sid, (pos, orn) = _shape(client, shape, coefficients)
            uid = pb.createMultiBody(0.0, sid, -1, pos, orn, useMaximalCoordinates=1, physicsClientId=client)
            self.ids.append(uid)
            self.shapes[shape.name] = (uid, -1)
        self.coefficients = coefficients

    def _free_everything(self) -> None:
        """Bullet's defaults undone (module docstring): damping 0, joint motors off, no velocity clamp; contact
        filtering to the layout's pairs, their friction and restitution."""
        client = self.client
        for uid in self.ids:
            for link in range(-1, pb.getNumJoints(uid, physicsClientId=client)):
                pb.changeDynamics(uid, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                                  maxJointVelocity=MAX_JOINT_VELOCITY, lateralFriction=0.0, restitution=0.0,
                                  rollingFriction=0.0, spinningFriction=0.0, physicsClientId=client)
                pb.setCollisionFilterGroupMask(uid, link, 0, 0, physicsClientId=client)
                if link >= 0:
                    kind = pb.getJointInfo(uid, link, physicsClientId=client)[2]
                    if kind == pb.JOINT_SPHERICAL:
                        pb.setJointMotorControlMultiDof(uid, link, pb.POSITION_CONTROL, targetPosition=[0, 0, 0, 1],
                                                        positionGain=0, velocityGain=0, force=[0, 0, 0],
                                                        physicsClientId=client)
                    elif kind in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
                        pb.setJointMotorControl2(uid, link, pb.VELOCITY_CONTROL, force=0, physicsClientId=client)
        for joint in self.layout.joints:
            if joint.name in self.joints and joint.damping:
                uid, index, _ = self.joints[joint.name]
                pb.changeDynamics(uid, index, jointDamping=float(joint.damping), physicsClientId=client)
        coefficients = getattr(self, "coefficients", {})
        for shape, (restitution, friction) in coefficients.items():
            if shape in self.shapes:
                uid, link = self.shapes[shape]
                pb.changeDynamics(uid, link, restitution=restitution, lateralFriction=friction, physicsClientId=client)
        self.pairs = []
        for contact in self.layout.contacts:
            a, b = self.shapes[contact.shape_a], self.shapes[contact.shape_b]
            pb.setCollisionFilterPair(a[0], b[0], a[1], b[1], 1, physicsClientId=client)
            self.pairs.append((a, b))

    def _urdf_constraints(self, scene) -> None:
        """The file's limits, dry friction and mimics as Bullet holds them when the scene applies them
        (from_urdf(constraints=True)): loadURDF's own joint limit constraints (kept), a velocity motor at target 0
        with maximum force = friction on each joint with dry friction (Bullet's rigid Coulomb friction in its LCP),
        a gear constraint per mimic (q_leader - q_follower / m = -offset / m, position error corrected by ERP 0.2).
        When the scene does not apply them (constraints=False, the bare tree): loadURDF's limits removed."""
        client = self.client
        if not getattr(scene, "constraints", False):
            for uid, index, kind in self.joints.values():
                if kind in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
                    pb.changeDynamics(uid, index, jointLowerLimit=-1e10, jointUpperLimit=1e10, physicsClientId=client)
            return
        for joint in self.layout.joints:
            if joint.frictionloss > 0 and joint.name in self.joints:
                uid, index, kind = self.joints[joint.name]
                if kind == pb.JOINT_SPHERICAL:
                    pb.setJointMotorControlMultiDof(uid, index, pb.VELOCITY_CONTROL, targetVelocity=[0, 0, 0],
                                                    force=[joint.frictionloss] * 3, physicsClientId=client)
                else:
                    pb.setJointMotorControl2(uid, index, pb.VELOCITY_CONTROL, targetVelocity=0,
                                             force=joint.frictionloss, physicsClientId=client)
        for follower, (leader, multiplier, offset) in scene.mimics.items():
            (uid, lead, _), (_, follow, _) = self.joints[leader], self.joints[follower]
            gear = pb.createConstraint(uid, lead, uid, follow, jointType=pb.JOINT_GEAR, jointAxis=[0, 0, 1],
                                       parentFramePosition=[0, 0, 0], childFramePosition=[0, 0, 0],
                                       physicsClientId=client)
            pb.changeConstraint(gear, gearRatio=-1.0 / multiplier, relativePositionTarget=-offset / multiplier,
                                erp=0.2, maxForce=1e10, physicsClientId=client)

    # ----- state -----

    def set_state(self, qpos: np.ndarray, qvel: np.ndarray) -> None:
        client, model = self.client, self.scene_model()
        for joint in self.layout.joints:
            qa, da = model[joint.name]
            if joint.kind == "free":
                uid, _, com_local, principal = self.bodies[joint.body]
                if principal is None:  # a URDF base: Bullet's base frame is its inertial frame
                    principal, com_local = self._urdf_base_frame(uid)
                from rbody.motion import quat_multiply, quat_to_matrix

                quat = qpos[qa + 3:qa + 7]
                rotation = quat_to_matrix(quat)
                com = qpos[qa:qa + 3] + rotation @ com_local
                omega = rotation @ qvel[da + 3:da + 6]
                velocity = qvel[da:da + 3] + np.cross(omega, rotation @ com_local)
                pb.resetBasePositionAndOrientation(uid, com.tolist(), _xyzw(quat_multiply(quat, principal)),
                                                   physicsClientId=client)
                pb.resetBaseVelocity(uid, velocity.tolist(), omega.tolist(), physicsClientId=client)
                continue
            uid, index, kind = self.joints[joint.name]
            if kind == pb.JOINT_SPHERICAL:
                pb.resetJointStateMultiDof(uid, index, _xyzw(qpos[qa:qa + 4]), list(qvel[da:da + 3]),
                                           physicsClientId=client)
            else:
                pb.resetJointState(uid, index, float(qpos[qa] - joint.ref), float(qvel[da]), physicsClientId=client)

    def _urdf_base_frame(self, uid):
        info = pb.getDynamicsInfo(uid, -1, physicsClientId=self.client)
        return _wxyz(info[4]), np.asarray(info[3], dtype=float)

    def scene_model(self) -> dict:
        from rbody.layout import coordinate_addresses, joint_order

        order = joint_order(self.layout)
        qposadr, dofadr, _, _ = coordinate_addresses(order)
        return {j.name: (q, d) for j, q, d in zip(order, qposadr, dofadr)}

    def read(self) -> tuple[dict, dict]:
        """(body -> (com, quat wxyz, com velocity, omega)), (joint -> (qpos, qvel)) now."""
        client = self.client
        from rbody.motion import quat_multiply, quat_to_matrix

        bodies = {}
        for body, (uid, link, com_local, principal) in self.bodies.items():
            if link == -1:
                pos, orn = pb.getBasePositionAndOrientation(uid, physicsClientId=client)
                velocity, omega = pb.getBaseVelocity(uid, physicsClientId=client)
                if principal is None:
                    principal, com_local = self._urdf_base_frame(uid)
                quat = quat_multiply(_wxyz(orn), _conj(principal))
                bodies[body] = (np.asarray(pos), quat, np.asarray(velocity), np.asarray(omega))
            else:
                state = pb.getLinkState(uid, link, computeLinkVelocity=1, computeForwardKinematics=1,
                                        physicsClientId=client)
                bodies[body] = (np.asarray(state[0]), _wxyz(state[5]), np.asarray(state[6]), np.asarray(state[7]))
            members = self.members.get(body, ())
            if len(members) > 1:  # the centre of mass and its velocity of the links merged into the body
                com, velocity, total = np.zeros(3), np.zeros(3), 0.0
                for member, mass in members:
                    if member == -1:
                        pos, _ = pb.getBasePositionAndOrientation(uid, physicsClientId=client)
                        vel, _ = pb.getBaseVelocity(uid, physicsClientId=client)
                    else:
                        state = pb.getLinkState(uid, member, computeLinkVelocity=1, computeForwardKinematics=1,
                                                physicsClientId=client)
                        pos, vel = state[0], state[6]
                    com, velocity, total = com + mass * np.asarray(pos), velocity + mass * np.asarray(vel), total + mass
                _, quat, _, omega = bodies[body]
                bodies[body] = (com / total, quat, velocity / total, omega)
        joints = {}
        for joint in self.layout.joints:
            if joint.kind == "free":
                com, quat, velocity, omega = bodies[joint.body]
                uid, _, com_local, principal = self.bodies[joint.body]
                if principal is None:
                    _, com_local = self._urdf_base_frame(uid)
                rotation = quat_to_matrix(quat)
                origin = com - rotation @ com_local
                joints[joint.name] = (np.concatenate([origin, quat]),
                                      np.concatenate([velocity - np.cross(omega, rotation @ com_local),
                                                      rotation.T @ omega]))
                continue
            uid, index, kind = self.joints[joint.name]
            if kind == pb.JOINT_SPHERICAL:
                position, velocity, _, _ = pb.getJointStateMultiDof(uid, index, physicsClientId=client)
                joints[joint.name] = (_wxyz(position), np.asarray(velocity))
            else:
                position, velocity, _, _ = pb.getJointState(uid, index, physicsClientId=client)
                joints[joint.name] = (np.array([position + joint.ref]), np.array([velocity]))
        return bodies, joints

    def touching(self) -> np.ndarray:
        client = self.client
        return np.array([len(pb.getContactPoints(a[0], b[0], a[1], b[1], physicsClientId=client)) > 0
                         for a, b in self.pairs], dtype=bool)


class _quiet:
    """Redirect the process's stdout (file descriptor 1, where Bullet's C++ code prints) to /dev/null."""

    def __enter__(self):
        import os
        import sys

        sys.stdout.flush()
        self.saved = os.dup(1)
        self.null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(self.null, 1)

    def __exit__(self, *exc):
        import os

        os.dup2(self.saved, 1)
        os.close(self.saved)
        os.close(self.null)


def _conj(quat) -> np.ndarray:
    q = np.asarray(quat, dtype=float)
    return np.array([q[0], -q[1], -q[2], -q[3]])


def _in_principal(pos, inertia, principal):
    from rbody.motion import quat_to_matrix

    return (quat_to_matrix(principal).T @ (np.asarray(pos) - np.asarray(inertia.com))).tolist()


def _geom(shape) -> int:
    if shape.kind not in ("sphere", "box", "cylinder", "capsule"):
        raise NotImplementedError(f"shape {shape.name!r} of kind {shape.kind!r} on a moving body is not built for "
                                  "Bullet here")
    return {"sphere": pb.GEOM_SPHERE, "box": pb.GEOM_BOX, "cylinder": pb.GEOM_CYLINDER,
            "capsule": pb.GEOM_CAPSULE}[shape.kind]


def _geom_args(shapes) -> dict:
    radii, halves, lengths, positions, orientations = [], [], [], [], []
    for s in shapes:
        size = s.size
        radii.append(size[0] if s.kind in ("sphere", "cylinder", "capsule") else 0.0)
        halves.append(list(size) if s.kind == "box" else [0.0, 0.0, 0.0])
        lengths.append(2 * size[1] if s.kind in ("cylinder", "capsule") else 0.0)
        positions.append(list(s.pos))
        orientations.append(_xyzw(s.quat))
    return dict(radii=radii, halfExtents=halves, lengths=lengths, collisionFramePositions=positions,
                collisionFrameOrientations=orientations)


# ----- the run ---------------------------------------------------------------------------------------------

def run(scene: Scene, dt: float, t_end: float | None = None, *, solver_iterations: int = SOLVER_ITERATIONS,
        erp: float | None = None, restitution_threshold: float = 1e-6, save_every: int = 1) -> Trajectory:
    """Run `scene` in Bullet with step dt [s] for t_end [s] (default scene.t_end); settings as the module
    docstring. Returns a Trajectory with the scene's observables (plus collisions and ball_collisions for scenes
    with impacts); meta holds the settings, pybullet's API version, step_seconds (stepSimulation alone) and
    run_seconds (with the reads)."""
    check(scene)
    dt, t_end = run_times(scene.t_end, dt, t_end)
    whole_number(save_every, "save_every")
    whole_number(solver_iterations, "solver_iterations")
    built = _Built(scene, dt, solver_iterations, erp, restitution_threshold)
    try:
        qpos0 = getattr(scene, "qpos0", None)
        from rbody.engine.multibody import Multibody

        model = getattr(scene, "multibody", None) or Multibody(scene.layout, gravity=scene.gravity)
        if not (isinstance(qpos0, np.ndarray) and qpos0.shape == (model.nq,)):
            qpos0, qvel0 = np.asarray(model.qpos0), np.asarray(model.qvel0)
        else:
            qvel0 = np.asarray(scene.qvel0)
        built.set_state(np.asarray(qpos0, dtype=float), np.asarray(qvel0, dtype=float))
        nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
        nsteps = -(-nsteps // save_every) * save_every
        impacts = has_impacts(scene.layout)
        moving = [scene.layout.contacts[k] for k in range(len(scene.layout.contacts))]
        fixed_names = {s.name for s in scene.layout.fixed}
        ball = np.array([c.shape_a not in fixed_names and c.shape_b not in fixed_names for c in moving], dtype=bool)
        samples, onsets = [built.read()], np.zeros(nsteps + 1, dtype=int)
        ball_onsets = np.zeros(nsteps + 1, dtype=int)
        touching = built.touching() if impacts else None
        stepping = 0.0
        started = time.perf_counter()
        for k in range(1, nsteps + 1):
            start = time.perf_counter()
            pb.stepSimulation(physicsClientId=built.client)
            stepping += time.perf_counter() - start
            if impacts:
                now = built.touching()
                new = now & ~touching
                onsets[k], ball_onsets[k] = int(new.sum()), int(new[ball].sum())
                touching = now
            if k % save_every == 0:
                samples.append(built.read())
        run_seconds = time.perf_counter() - started
    finally:
        pb.disconnect(built.client)
    t = np.arange(len(samples)) * (dt * save_every)
    names = list(samples[0][0])
    bodies = {b: BodyStates(com=np.array([s[0][b][0] for s in samples]), quat=np.array([s[0][b][1] for s in samples]),
                            velocity=np.array([s[0][b][2] for s in samples]),
                            omega=np.array([s[0][b][3] for s in samples])) for b in names}
    joints = {}
    for joint in scene.layout.joints:
        position = np.array([s[1][joint.name][0] for s in samples])
        velocity = np.array([s[1][joint.name][1] for s in samples])
        joints[joint.name] = (position[:, 0], velocity[:, 0]) if JOINTS[joint.kind].scalar else (position, velocity)
    observables = dict(scene.observe(t, bodies, joints))
    if impacts:
        observables["collisions"] = np.cumsum(onsets)[::save_every]
        observables["ball_collisions"] = np.cumsum(ball_onsets)[::save_every]
    meta = {"scene": scene.name, "description": scene.describe(), "backend": name, "dt": dt, "t_end": t_end,
            "nsteps": nsteps, "save_every": save_every, "integrator": "semi-implicit Euler",
            "settings": {"solver_iterations": solver_iterations, "erp": erp,
                         "restitution_threshold": restitution_threshold, "model": "file" if _from_file(scene) else
                         "layout"},
            "pybullet_api": pb.getAPIVersion(), "step_seconds": stepping, "run_seconds": run_seconds,
            "notes": list(built.notes)}
    return Trajectory(t, observables, meta=meta)
