"""URDF -> rbody: ``from_urdf(path)`` reads a robot description into a Scene that rbody runs natively.

``layout_from_urdf(source)`` does the reading and returns a URDFModel (the Layout, the initial state in MuJoCo's
qpos/qvel layout, declared limits, mimics, friction, notes); ``from_urdf`` makes it a URDFScene, a TreeScene of
the general engine. `source` is a path or a URDF XML string. Every error is a URDFError (a ValueError) naming
the file, the line and the element, raised before any run.

The model is the one Pinocchio's parser (pin.buildModelFromUrdf) and MuJoCo's URDF loader build from the file:

- links: one rbody Body per link on a moving joint, named after the link; its <inertial> (origin xyz and rpy,
  mass, the six moments ixx iyy izz ixy ixz iyz given in the inertial frame) becomes the Body's Inertia in the
  link frame (tensor R I R^T about the centre of mass at xyz);
- joints: revolute and continuous -> hinge (a continuous joint is an unbounded hinge: one angle, where Pinocchio
  keeps (cos, sin)); prismatic -> slide; floating -> free (only from the world: the root link called "world",
  or a link fixed to it); planar -> two slides and a hinge on the child, as MuJoCo's loader builds it:
  <name>_TX and <name>_TY along the x and y of the frame whose z is the joint's axis (MuJoCo's z-to-quaternion
  frame) and <name>_RZ about the axis; spherical (Bullet's and MuJoCo's extension) -> ball; fixed -> merged:
  the child's mass properties added to its parent by the parallel-axis theorem, its geometry kept, its own
  children attached to the parent (Pinocchio's appendBodyToJoint, MuJoCo's fusestatic). The joint frame
  is <origin> in the parent link's frame (rpy: roll, pitch, yaw about the FIXED axes x, y, z, R = Rz Ry Rx);
  the child link's frame is the joint frame; <axis xyz> (default 1 0 0) is in it, made unit;
- the root link is welded to the world (MuJoCo's loader, Pinocchio's default): its mass is not simulated
  and its geometry is the world's. ``floating_base=True`` gives it a free joint called "root_joint" instead
  (Pinocchio's JointModelFreeFlyer root joint);
- links without <inertial> are massless, as Pinocchio reads them (Inertia zero). A massless link merged into
  a parent changes nothing. A massless link on a moving joint whose only moving child is one link is folded
  into that child: the child body carries both joints, the massless link's first, its anchor and axis in the
  child's frame (the same motion: a massless link has no dynamics of its own; MuJoCo's loader refuses such a
  body, Pinocchio keeps a body of zero inertia). A massless link on a moving joint with no moving child (its
  joint moves nothing: the mass matrix is singular, Pinocchio's ABA divides by zero) or with several is refused.

Joint order (qpos and qvel): MuJoCo's loader's, depth first from the root link, a link's children in the order
their joints appear in the file. Pinocchio orders a link's children by joint name instead (urdfdom keeps
joints in a sorted map); validation.backends.pinocchio maps the two by joint name.

Limits, friction and mimics, applied through rbody's constraint layer (rbody.engine.constraints, rigid) when
``constraints=True`` (the default; what MuJoCo's loader applies, softly there), recorded only when False (the bare
tree, as Pinocchio's aba runs the file; validation's pinocchio backend compares like with like on such a scene):

- <limit lower upper> of revolute and prismatic joints -> Joint.range (lower < upper; lower = upper is no range
  and is ignored, as MuJoCo's loader ignores it) and ``limits`` (as MJCFScene.limits: validation reports an
  engine's run that leaves one); limit impacts are plastic (restitution 0, the rigid limit of MuJoCo's critically
  damped limit); effort and velocity -> ``effort_limits``, ``velocity_limits`` [N m | N, rad/s | m/s], recorded
  only (MuJoCo's loader sets effort as an actuator force range; no actuator here);
- <dynamics damping> is joint damping (applied: -damping qvel); <dynamics friction> -> Joint.frictionloss of each
  degree of freedom the joint makes (Coulomb's law, as MuJoCo's loader's frictionloss) and ``joint_friction``;
- <mimic joint multiplier offset> -> a joint Equality "mimic_<follower>": qpos[follower] = offset + multiplier
  qpos[leader] (MuJoCo's loader makes the same equality, polycoef (offset, multiplier, 0, 0, 0)), and ``mimics``:
  joint -> (leader, multiplier, offset). Follower and leader must be revolute, continuous or prismatic. The default
  initial state puts each follower where its mimic does.

Inertias that no body has (negative moments, or principal moments breaking A + B >= C) are loaded as the file
gives them (Inertia.as_given: the dynamics a user compares are the file's, and Pinocchio loads them so), each
named in import_notes with the size of its violation. ``balance_inertia=True`` applies MuJoCo's rule instead
(compiler balanceinertia: a body whose principal moments break the triangle inequality gets all three set to
their mean), to each body after fixed links are merged, as MuJoCo balances its fused bodies.

Geometry: <collision> elements are the Layout's shapes (box, cylinder, sphere, capsule, mesh: box sizes halved,
cylinder length halved, along the local z); <visual> elements are kept in ``visuals`` (body -> shapes, "world"
for the root's), as MuJoCo's loader discards them by default. A collision mesh MuJoCo cannot read (not .stl,
.obj, .msh) goes to ``visuals`` too, noted. Mesh paths: package://NAME/PATH through ``package_dirs`` and the
environment variable ROS_PACKAGE_PATH, file://, or relative to the URDF's folder; a missing file is refused.
Mesh scale is noted (no mass comes from meshes). Shapes are named "<link>_collision_<i>" / "<link>_visual_<i>".

Ignored with a note: <material>, <transmission>, <gazebo>, <ros2_control>, <mujoco> (MuJoCo's own compiler
options), <sensor>, joints' <calibration>, <safety_controller> and <joint_properties> (early URDF's, ignored by
urdfdom, Pinocchio and Bullet; non-zero damping or friction there is named in a note), links' <contact> (Bullet's), <self_filter>,
<collision_checking>, <kinematic> and a stray <origin>, collisions' <material> and <verbose>. Refused (URDFError):
anything else, unknown joint types, a link with two parents (a loop), several root links, a joint naming a
missing link, repeated names, malformed numbers or XML, a missing mesh, mass < 0, a mass of 0 with moments.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from rbody.inertia import Inertia
from rbody.layout import WORLD, Body, Equality, Joint, Layout, Shape
from rbody.mjcf.frames import quat_matrix, quat_product, z_to_quat
from rbody.mjcf.parse import DEFAULT_T_END, MJCFScene
from rbody.urdf.document import Element, URDFError, read_source, rpy_quaternion
from rbody.urdf.geometry import MUJOCO_MESH_SUFFIXES, read_geometry

ROOT_JOINT = "root_joint"      # the free joint of floating_base=True (Pinocchio's name)
MIMIC_PREFIX = "mimic_"        # the joint equality of a <mimic> is called mimic_<follower joint>
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar", "spherical")
PLANAR_SUFFIXES = ("_TX", "_TY", "_RZ")   # MuJoCo's loader's names of a planar joint's three joints
IGNORED_ROBOT_ELEMENTS = {
    "material": "<material> ignored (appearance only)",
    "transmission": "<transmission> ignored (actuators and gear ratios; no actuator is modelled)",
    "gazebo": "<gazebo> ignored (Gazebo's simulator settings)",
    "ros2_control": "<ros2_control> ignored (controller settings)",
    "mujoco": "<mujoco> ignored (MuJoCo's own compiler options for its URDF loader)",
    "sensor": "<sensor> ignored (sensor descriptions measure, they add no mass or joint)",
}
# Annotations of planners and simulators found in published links: no mass, joint or shape of their own.
IGNORED_LINK_ELEMENTS = {
    "contact": "links' <contact> ignored (Bullet's contact parameters; contacts are not modelled)",
    "self_filter": "links' <self_filter> ignored (a perception filter's padding)",
    "collision_checking": "links' <collision_checking> ignored (a planner's collision shapes)",
    "kinematic": "links' <kinematic> ignored (a simulator's flag)",
    "origin": "an <origin> directly in a <link> ignored (URDF gives it no meaning; urdfdom ignores it)",
}
_IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


@dataclass
class _Link:
    element: Element
    name: str
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tensor: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))   # about com, link axes
    geometries: list = field(default_factory=list)
    unmassed: Element | None = None   # an <inertial> with moments but mass 0 (refused if the link moves)


@dataclass
class _Carrier:
    """A body of the Layout: the links merged into it (with their pose in its frame) and its joints."""

    name: str
    parent: str
    pos: np.ndarray
    quat: np.ndarray
    joints: list            # rbody Joints (body set later)
    parts: list = field(default_factory=list)      # (link, pos, quat) of each merged link in this frame
    element: Element | None = None                 # the joint element that made it (for errors)

    @property
    def mass(self) -> float:
        return math.fsum(link.mass for link, _, _ in self.parts)


@dataclass(frozen=True)
class URDFModel:
    """What layout_from_urdf read: everything a TreeScene needs, and what was declared but not applied.

    layout:          bodies (links on moving joints, merged), joints in MuJoCo's loader's order, fixed shapes
    name:            <robot name>
    root:            the root link's name; floating_base: whether it got the free joint "root_joint"
    qpos0, qvel0:    (nq,), (nv,) initial state in MuJoCo's layout
    limits:          joint -> (lower, upper) [rad | m] declared position limits
    effort_limits, velocity_limits: joint -> declared effort [N m | N] and velocity [rad/s | m/s] limits
    joint_friction:  joint -> declared dry friction [N m | N] (Joint.frictionloss with constraints on)
    mimics:          joint -> (leader joint, multiplier, offset) (layout.equalities with constraints on)
    visuals:         body name (or "world") -> visual shapes in that body's frame
    notes:           what was ignored, recorded or changed, one line each
    source:          the file read, or "<string>"
    """

    layout: Layout
    name: str
    root: str
    floating_base: bool
    qpos0: np.ndarray
    qvel0: np.ndarray
    limits: dict
    effort_limits: dict
    velocity_limits: dict
    joint_friction: dict
    mimics: dict
    visuals: dict
    notes: tuple
    source: str


def _compose(pos_a, quat_a, pos_b, quat_b) -> tuple[np.ndarray, np.ndarray]:
    """Frame b given in frame a, itself given in some frame: b in that frame."""
    return pos_a + quat_matrix(quat_a) @ pos_b, quat_product(quat_a, quat_b)


def _conjugate(quat: np.ndarray) -> np.ndarray:
    return np.array([quat[0], -quat[1], -quat[2], -quat[3]])


class _Reader:
    def __init__(self, root: Element, folder: Path | None, package_dirs, floating_base: bool,
                 balance_inertia: bool, constraints: bool = True) -> None:
        self.root, self.folder, self.package_dirs = root, folder, package_dirs
        self.constraints = constraints
        self.floating_base, self.balance_inertia = floating_base, balance_inertia
        self.notes: list[str] = []
        self.limits: dict = {}
        self.effort: dict = {}
        self.velocity: dict = {}
        self.friction: dict = {}
        self.mimics: dict = {}
        self.mimic_elements: dict = {}

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)

    # ----- links -----

    def read_link(self, element: Element) -> _Link:
        element.check_children({"inertial": None, "visual": None, "collision": None, **IGNORED_LINK_ELEMENTS},
                               self.notes)
        link = _Link(element, element.text_attribute("name"))
        inertial = element.one("inertial")
        if inertial is not None:
            self.read_inertial(link, inertial)
        for kind in ("collision", "visual"):
            for i, child in enumerate(element.all(kind)):
                link.geometries.append(read_geometry(child, f"{link.name}_{kind}_{i}", kind == "collision",
                                                     self.folder, self.package_dirs, self.notes))
        return link

    def read_inertial(self, link: _Link, inertial: Element) -> None:
        inertial.check_children({"origin": None, "mass": None, "inertia": None}, self.notes)
        origin = inertial.one("origin")
        com = origin.numbers("xyz", 3, (0.0, 0.0, 0.0)) if origin is not None else np.zeros(3)
        rotation = quat_matrix(rpy_quaternion(origin.numbers("rpy", 3, (0.0, 0.0, 0.0)))) if origin is not None \
            else np.eye(3)
        mass = inertial.one("mass", required=True).number("value")
        moments = inertial.one("inertia", required=True)
        ixx, iyy, izz, ixy, ixz, iyz = (moments.number(k) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz"))
        given = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        if mass < 0:
            raise inertial.error(f"mass={mass!r}: a mass must be >= 0 [kg]")
        if mass == 0 and np.any(given != 0):
            link.unmassed = inertial  # moments without mass: added to a moving body that has mass, else refused
        tensor = given if np.array_equal(rotation, np.eye(3)) else rotation @ given @ rotation.T
        link.mass, link.com, link.tensor = float(mass), com, tensor
        if mass > 0:
            violation = _violation(given)
            if violation:
                self.note(f"link {link.name!r} (line {inertial.line}): {violation}; loaded as the file gives it"
                          + (" (balance_inertia=True balances its body)" if self.balance_inertia else
                             " (balance_inertia=True applies MuJoCo's balanceinertia rule)"))

    # ----- joints -----

    def read_joint(self, element: Element) -> dict:
        element.check_children({"parent": None, "child": None, "origin": None, "axis": None, "limit": None,
                                "dynamics": None, "mimic": None,
                                "calibration": "joints' <calibration> ignored (sensor calibration)",
                                "safety_controller": "joints' <safety_controller> ignored (controller "
                                                     "soft limits)",
                                "joint_properties": "joints' <joint_properties> ignored (an element of early URDF that "
                                                    "urdfdom, Pinocchio and Bullet ignore; <dynamics> is URDF's)"},
                               self.notes)
        name = element.text_attribute("name")
        legacy = element.one("joint_properties")
        if legacy is not None and any(legacy.number(key, 0.0) != 0 for key in ("damping", "friction")
                                      if key in legacy.attrib):
            self.note(f"joint {name!r}: <joint_properties> damping/friction NOT applied (ignored as urdfdom, Pinocchio "
                      "and Bullet ignore them; write them in <dynamics>)")
        kind = element.text_attribute("type")
        if kind not in JOINT_TYPES:
            raise element.error(f"type={kind!r}: unknown joint type (URDF's are revolute, continuous, prismatic, "
                                "fixed, floating, planar)")
        if kind == "spherical":
            self.note(f"joint {name!r}: type 'spherical' (Bullet's and MuJoCo's extension, not standard URDF) read "
                      "as a ball joint")
        origin = element.one("origin")
        pos = origin.numbers("xyz", 3, (0.0, 0.0, 0.0)) if origin is not None else np.zeros(3)
        quat = rpy_quaternion(origin.numbers("rpy", 3, (0.0, 0.0, 0.0))) if origin is not None else _IDENTITY.copy()
        axis_element = element.one("axis")
        axis = axis_element.numbers("xyz", 3, (1.0, 0.0, 0.0)) if axis_element is not None else np.array([1.0, 0, 0])
        if kind not in ("fixed", "floating") and not np.any(axis != 0):
            raise (axis_element or element).error("axis xyz=\"0 0 0\": a joint axis must be non-zero")
        return {"element": element, "name": name, "kind": kind,
                "parent": element.one("parent", required=True).text_attribute("link"),
                "child": element.one("child", required=True).text_attribute("link"),
                "pos": pos, "quat": quat, "axis": axis}

    def declared(self, joint: dict) -> dict:
        """Read <limit>, <dynamics> and <mimic> of a moving joint: the keywords of its rbody Joints (damping, and with
        constraints on, range and frictionloss); the mimic is recorded in self.mimics (its Equality made in build)."""
        element, kind, name = joint["element"], joint["kind"], joint["name"]
        out: dict = {}
        limit = element.one("limit")
        if limit is not None:
            limit.check_children({}, self.notes)
            for key, table in (("effort", self.effort), ("velocity", self.velocity)):
                if key in limit.attrib:
                    table[name] = limit.number(key)
            if any(key in limit.attrib for key in ("effort", "velocity")):
                self.note("joint effort and velocity limits recorded (effort_limits, velocity_limits), not applied "
                          "(no actuator is modelled)")
            if kind in ("revolute", "prismatic") and ("lower" in limit.attrib or "upper" in limit.attrib):
                lower, upper = limit.number("lower", 0.0), limit.number("upper", 0.0)
                if lower < upper:
                    self.limits[name] = (lower, upper)
                    if self.constraints:
                        out["range"] = (lower, upper)
                        self.note("joint position limits applied (Joint.range, held rigidly by the constraint layer; "
                                  "MuJoCo's loader applies them as soft limits)")
                    else:
                        self.note("joint position limits recorded (limits), NOT applied (constraints=False: as "
                                  "Pinocchio's aba runs the file); validation reports a run that leaves one")
                else:
                    self.note(f"joint {name!r}: <limit lower={lower:g} upper={upper:g}> is no range (lower >= upper): "
                              "ignored (MuJoCo's loader ignores it too, with a warning)")
            elif kind not in ("revolute", "prismatic") and ("lower" in limit.attrib or "upper" in limit.attrib):
                self.note(f"joint {name!r}: position limits of a {kind} joint ignored (URDF gives a {kind} joint "
                          "none)")
        dynamics = element.one("dynamics")
        if dynamics is not None:
            dynamics.check_children({}, self.notes)
            damping = dynamics.number("damping", 0.0)
            if damping < 0:
                raise dynamics.error(f"damping={damping!r}: must be >= 0")
            out["damping"] = damping
            friction = dynamics.number("friction", 0.0)
            if friction < 0:
                raise dynamics.error(f"friction={friction!r}: a dry friction force must be >= 0 [N m | N]")
            if friction != 0:
                self.friction[name] = friction
                if self.constraints:
                    out["frictionloss"] = friction
                    self.note("joint dry friction (<dynamics friction>) applied as Joint.frictionloss (Coulomb's law "
                              "per degree of freedom, held rigidly; MuJoCo's loader applies it as frictionloss)")
                else:
                    self.note("joint dry friction (<dynamics friction>) recorded (joint_friction), NOT applied "
                              "(constraints=False: as Pinocchio's aba runs the file)")
        mimic = element.one("mimic")
        if mimic is not None:
            mimic.check_children({}, self.notes)
            self.mimics[name] = (mimic.text_attribute("joint"), mimic.number("multiplier", 1.0),
                                 mimic.number("offset", 0.0))
            self.mimic_elements[name] = mimic
            if self.constraints:
                self.note(f"joint {name!r} mimics {mimic.attrib.get('joint')!r}: held by a joint equality "
                          f"'{MIMIC_PREFIX}{name}' (follower = multiplier * leader + offset, as MuJoCo's loader "
                          "makes it)")
            else:
                self.note(f"joint {name!r} mimics {mimic.attrib.get('joint')!r} in the file (mimics): run as an "
                          "independent joint (constraints=False: as Pinocchio's default parse runs it)")
        return out

    def joints_of(self, joint: dict, body: str) -> list[Joint]:
        """The rbody joints of one moving URDF joint, in the child's (the body's) frame."""
        name, kind, axis = joint["name"], joint["kind"], joint["axis"]
        declared = self.declared(joint)
        damping, friction = declared.get("damping", 0.0), declared.get("frictionloss", 0.0)
        common = dict(damping=damping, frictionloss=friction)
        if kind in ("revolute", "continuous"):
            return [Joint(name, "hinge", body, axis=tuple(axis.tolist()), range=declared.get("range"), **common)]
        if kind == "prismatic":
            return [Joint(name, "slide", body, axis=tuple(axis.tolist()), range=declared.get("range"), **common)]
        if kind == "spherical":
            return [Joint(name, "ball", body, **common)]
        if kind == "floating":
            return [Joint(name, "free", body, **common)]
        frame = quat_matrix(z_to_quat(axis))   # planar: MuJoCo's loader's frame whose z is the axis
        return [Joint(name + "_TX", "slide", body, axis=tuple(frame[:, 0].tolist()), **common),
                Joint(name + "_TY", "slide", body, axis=tuple(frame[:, 1].tolist()), **common),
                Joint(name + "_RZ", "hinge", body, axis=tuple(axis.tolist()), **common)]

    def mimic_equalities(self, kinds: dict[str, str]) -> tuple[Equality, ...]:
        """The joint equalities of the file's <mimic> elements (constraints on): qpos[follower] = offset +
        multiplier qpos[leader] (MuJoCo's joint equality, polycoef (offset, multiplier, 0, 0, 0)). kinds: URDF
        joint name -> type. A mimic of or by a joint other than revolute, continuous or prismatic is refused."""
        out = []
        for follower, (leader, multiplier, offset) in self.mimics.items():
            if leader not in kinds:
                raise self.mimic_elements[follower].error(
                    f"joint {follower!r} mimics joint {leader!r}, which is not a joint of the robot; "
                    "constraints=False loads the file with the mimic recorded only")
            for joint in (follower, leader):
                if kinds[joint] not in ("revolute", "continuous", "prismatic"):
                    raise self.mimic_elements[follower].error(
                        f"joint {joint!r} is {kinds[joint]}: a mimic ties revolute, continuous or prismatic joints "
                        "(one coordinate each); constraints=False loads the file with the mimic recorded only")
            out.append(Equality(MIMIC_PREFIX + follower, "joint", joint1=follower, joint2=leader,
                                polycoef=(offset, multiplier, 0.0, 0.0, 0.0)))
        return tuple(out)

    # ----- the tree -----

    def read(self) -> tuple[dict, dict, list[dict]]:
        root = self.root
        if root.tag != "robot":
            raise root.error("the root element of a URDF document must be <robot>")
        self.name = root.attrib.get("name", "robot") or "robot"
        links: dict[str, _Link] = {}
        joints: list[dict] = []
        for child in root.children:
            if child.tag == "link":
                link = self.read_link(child)
                if link.name in links:
                    raise child.error(f"two links are called {link.name!r}")
                links[link.name] = link
            elif child.tag == "joint":
                joints.append(child)
            elif child.tag in IGNORED_ROBOT_ELEMENTS:
                self.note(IGNORED_ROBOT_ELEMENTS[child.tag])
            else:
                raise child.error(f"unknown element <{child.tag}> in <robot> (rbody reads link and joint, and "
                                  f"ignores {', '.join(sorted(IGNORED_ROBOT_ELEMENTS))}; it refuses what it does not "
                                  "know, which could change the dynamics)")
        if not links:
            raise root.error("the robot has no <link>")
        read_joints, names, parent_joint = [], set(), {}
        for element in joints:
            joint = self.read_joint(element)
            if joint["name"] in names:
                raise element.error(f"two joints are called {joint['name']!r}")
            names.add(joint["name"])
            for end in ("parent", "child"):
                if joint[end] not in links:
                    raise element.one(end).error(f"link {joint[end]!r} is not a <link> of the robot")
            if joint["parent"] == joint["child"]:
                raise element.error(f"joins link {joint['child']!r} to itself")
            if joint["child"] in parent_joint:
                first = parent_joint[joint["child"]]
                raise element.error(f"link {joint['child']!r} already has a parent through joint {first['name']!r} "
                                    f"(line {first['element'].line}): two parents make a loop, and URDF describes "
                                    "trees")
            parent_joint[joint["child"]] = joint
            read_joints.append(joint)
        return links, parent_joint, read_joints

    def build(self, qpos0, qvel0) -> URDFModel:
        links, parent_joint, joints = self.read()
        roots = [name for name in links if name not in parent_joint]
        if not roots:
            raise self.root.error("no root link (every link has a parent): the joints form a loop")
        if len(roots) > 1:
            raise links[roots[1]].element.error(f"links {roots} have no parent joint: a URDF robot has one root link")
        root = roots[0]
        children: dict[str, list[dict]] = {}
        for joint in joints:
            children.setdefault(joint["parent"], []).append(joint)
        if self.floating_base and root == WORLD:
            raise links[root].element.error("floating_base=True, but the root link is 'world': the file's own joints "
                                            "from 'world' say how the robot is attached; leave floating_base False")
        world = _Carrier(WORLD, "", np.zeros(3), _IDENTITY.copy(), [])
        carriers: list[_Carrier] = []
        if self.floating_base:
            base = _Carrier(root, WORLD, np.zeros(3), _IDENTITY.copy(), [Joint(ROOT_JOINT, "free", root)],
                            element=links[root].element)
            carriers.append(base)
        else:
            base = world
        reached: set[str] = set()

        def visit(link: _Link, carrier: _Carrier, pos: np.ndarray, quat: np.ndarray) -> None:
            reached.add(link.name)
            carrier.parts.append((link, pos, quat))
            for joint in children.get(link.name, []):
                child = links[joint["child"]]
                jpos, jquat = _compose(pos, quat, joint["pos"], joint["quat"])
                if joint["kind"] == "fixed":
                    self.declared_fixed(joint)
                    visit(child, carrier, jpos, jquat)
                    continue
                if joint["kind"] == "floating" and carrier is not world:
                    raise joint["element"].error("a floating joint below a moving link: rbody's free joints join a "
                                                 "body to the world only")
                body = _Carrier(child.name, carrier.name, jpos, jquat, self.joints_of(joint, child.name),
                                element=joint["element"])
                carriers.append(body)
                visit(child, body, np.zeros(3), _IDENTITY.copy())

        visit(links[root], base, np.zeros(3), _IDENTITY.copy())
        lost = sorted(set(links) - reached)
        if lost:
            raise links[lost[0]].element.error(f"links {lost} are not reached from the root link {root!r}: their "
                                               "joints form a loop")
        carriers = self.fold_massless(carriers)
        if not carriers:
            raise links[root].element.error("nothing moves: the robot's links are all welded to the world (no moving "
                                            "joint); floating_base=True makes the root link a free body")
        for link in links.values():
            if link.unmassed is not None and not any(link is part for c in carriers for part, _, _ in c.parts):
                self.note(f"link {link.name!r} (welded to the world) has mass 0 and non-zero moments: not simulated")
        equalities = self.mimic_equalities({j["name"]: j["kind"] for j in joints}) if self.constraints else ()
        layout, visuals = self.layout(world, carriers, equalities)
        qpos, qvel = _initial_state(layout, qpos0, qvel0, self.root.file)
        return URDFModel(layout=layout, name=self.name, root=root, floating_base=self.floating_base, qpos0=qpos,
                         qvel0=qvel, limits=self.limits, effort_limits=self.effort, velocity_limits=self.velocity,
                         joint_friction=self.friction, mimics=self.mimics, visuals=visuals, notes=tuple(self.notes),
                         source=self.root.file)

    def declared_fixed(self, joint: dict) -> None:
        element = joint["element"]
        for tag in ("limit", "dynamics", "mimic"):
            if element.one(tag) is not None:
                self.note(f"joint {joint['name']!r}: <{tag}> of a fixed joint ignored")

    def fold_massless(self, carriers: list[_Carrier]) -> list[_Carrier]:
        """Fold every massless body on a moving joint into its only moving child (see the module docstring)."""
        out = list(carriers)
        k = 0
        while k < len(out):
            body = out[k]
            if body.mass > 0:
                k += 1
                continue
            for link, _, _ in body.parts:
                if link.unmassed is not None:
                    raise link.unmassed.error(f"link {link.name!r} moves, with mass 0 and non-zero moments: rbody's "
                                              "bodies need a mass > 0 for moments of inertia")
            below = [c for c in out if c.parent == body.name]
            kinds = [j.kind for j in body.joints]
            if len(below) != 1:
                what = ("no moving child: its joint moves nothing, so the mass matrix is singular (Pinocchio's ABA "
                        "divides by zero there and MuJoCo refuses the body)") if not below else (
                        f"{len(below)} moving children ({', '.join(c.name for c in below)}): rbody can fold a "
                        "massless link only into a single moving child")
                raise body.element.error(f"link {body.name!r} has no mass (no <inertial>, or mass 0) and {what}; give "
                                         "it an <inertial>")
            child = below[0]
            if "free" in kinds or any(j.kind == "free" for j in child.joints):
                raise body.element.error(f"link {body.name!r} has no mass and a free joint on it or its child: a "
                                         "free joint must be a body's only joint; give the link an <inertial>")
            # the child's frame in the massless body's frame, and the body's joints moved into the child's frame
            rotation = quat_matrix(child.quat)
            moved = []
            for joint in body.joints:
                axis = rotation.T @ np.asarray(joint.axis)
                anchor = rotation.T @ (np.asarray(joint.anchor) - child.pos)
                moved.append(dataclasses.replace(joint, body=child.name, axis=tuple(axis.tolist()),
                                                 anchor=tuple(anchor.tolist())))
            inverse = _conjugate(child.quat)
            parts = []
            for link, pos, quat in body.parts:  # massless links: geometry only
                parts.append((link, inverse_pos(child.pos, inverse, pos), quat_product(inverse, quat)))
            pos, quat = _compose(body.pos, body.quat, child.pos, child.quat)
            merged = dataclasses.replace(child, parent=body.parent, pos=pos, quat=quat,
                                         joints=moved + [dataclasses.replace(j) for j in child.joints],
                                         parts=parts + child.parts)
            self.note(f"link {body.name!r} has no mass: folded into its only moving child {child.name!r}, which "
                      f"carries both joints ({', '.join(j.name for j in merged.joints)})")
            out[out.index(child)] = merged
            del out[k]
        return out

    def layout(self, world: _Carrier, carriers: list[_Carrier], equalities: tuple = ()) -> tuple[Layout, dict]:
        fixed, visuals = [], {}
        for shape, collision in self.shapes(world):
            (fixed if collision else visuals.setdefault(WORLD, [])).append(shape)
        bodies, joints = [], []
        for carrier in carriers:
            shapes = []
            for shape, collision in self.shapes(carrier):
                (shapes if collision else visuals.setdefault(carrier.name, [])).append(shape)
            bodies.append(Body(carrier.name, self.inertia(carrier), tuple(shapes), parent=carrier.parent,
                               pos=tuple(carrier.pos.tolist()), quat=tuple(carrier.quat.tolist())))
            joints += carrier.joints
        return (Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=tuple(fixed), equalities=equalities),
                {name: tuple(shapes) for name, shapes in visuals.items()})

    def shapes(self, carrier: _Carrier) -> list[tuple[Shape, bool]]:
        out = []
        for link, pos, quat in carrier.parts:
            for geometry in link.geometries:
                shape = geometry.shape
                spos, squat = _compose(pos, quat, np.array(shape.pos), np.array(shape.quat))
                moved = dataclasses.replace(shape, pos=tuple(spos.tolist()), quat=tuple(squat.tolist()))
                collision = geometry.collision
                if collision and shape.kind == "mesh" and Path(shape.mesh).suffix.lower() not in MUJOCO_MESH_SUFFIXES:
                    self.note(f"collision meshes in formats MuJoCo cannot read ({Path(shape.mesh).suffix}) kept with "
                              "the visuals (drawing only)")
                    collision = False
                out.append((moved, collision))
        return out

    def inertia(self, carrier: _Carrier) -> Inertia:
        """The merged mass properties of a body's links, in its frame (parallel-axis theorem)."""
        parts = [(link, pos, quat) for link, pos, quat in carrier.parts if link.mass > 0 or link.unmassed is not None]
        mass = math.fsum(link.mass for link, _, _ in parts)
        unmassed = [link.name for link, _, _ in parts if link.unmassed is not None]
        if unmassed:
            self.note(f"body {carrier.name!r}: links {unmassed} have moments of inertia but mass 0: their moments are "
                      "added (as Pinocchio adds them)")
        if len(parts) == 1 and not np.any(parts[0][1]) and np.array_equal(parts[0][2], _IDENTITY):
            com, tensor = parts[0][0].com, parts[0][0].tensor  # the link's own frame: its numbers as given
        else:
            coms = [pos + quat_matrix(quat) @ link.com for link, pos, quat in parts]
            com = sum(link.mass * c for (link, _, _), c in zip(parts, coms)) / mass if mass > 0 else np.zeros(3)
            tensor = np.zeros((3, 3))
            for (link, pos, quat), c in zip(parts, coms):
                rotation = quat_matrix(quat)
                d = c - com
                tensor = tensor + rotation @ link.tensor @ rotation.T + link.mass * (d @ d * np.eye(3) - np.outer(d, d))
            if len(parts) > 1:
                self.note(f"body {carrier.name!r}: links {[link.name for link, _, _ in parts]} merged (fixed joints)")
        if self.balance_inertia and _violation(tensor):
            moments = np.linalg.eigvalsh(0.5 * (tensor + tensor.T))
            mean = float(np.sum(moments)) / 3
            self.note(f"body {carrier.name!r}: principal moments {np.round(moments, 12).tolist()} replaced by their "
                      f"mean {mean:.6g} kg m^2 (balance_inertia=True, MuJoCo's balanceinertia rule)")
            tensor = mean * np.eye(3)
        try:
            return Inertia.as_given(mass, com, tensor)
        except ValueError as error:
            raise (carrier.element or self.root).error(f"mass properties of body {carrier.name!r} refused: {error}") \
                from None


def inverse_pos(pos: np.ndarray, inverse_quat: np.ndarray, point: np.ndarray) -> np.ndarray:
    """`point` (in a frame A) in the frame B at (pos, quat) in A, given quat's conjugate."""
    return quat_matrix(inverse_quat) @ (point - pos)


def _violation(tensor: np.ndarray) -> str:
    """'' for a physical tensor, else how far its principal moments are from one (a negative moment, or
    A + B < C), in kg m^2 and relative to C."""
    moments = np.linalg.eigvalsh(0.5 * (tensor + tensor.T))
    scale = max(float(np.max(np.abs(moments))), np.finfo(float).tiny)
    a, b, c = moments
    parts = []
    if a < -1e-12 * scale:
        parts.append(f"a negative principal moment {a:.6g} kg m^2")
    if a + b < c - 1e-12 * scale:
        gap = c - a - b
        relative = f" ({100 * gap / c:.3g} % of C)" if c > 0 else ""
        parts.append(f"principal moments {a:.6g}, {b:.6g}, {c:.6g} break the triangle inequality A + B >= C by "
                     f"{gap:.3g} kg m^2{relative}")
    return "; ".join(parts)


def _initial_state(layout: Layout, qpos0, qvel0, file: str) -> tuple[np.ndarray, np.ndarray]:
    """qpos0 (nq,), qvel0 (nv,) in MuJoCo's layout: the arguments, or the reference pose at rest with every mimic
    follower where its equality puts it (offset + multiplier leader; a given qpos0 off a mimic is projected onto it
    at the run's start, its first event)."""
    from rbody.engine.multibody import Multibody

    try:
        model = Multibody(layout)
    except ValueError as error:
        raise URDFError(f"{file}: the robot's tree cannot be built: {error}") from None
    out = []
    for value, default, what in ((qpos0, model.qpos0, "qpos0"), (qvel0, model.qvel0, "qvel0")):
        if value is None:
            array = np.array(default, dtype=float)
            if what == "qpos0" and layout.equalities:
                address = dict(zip(model.joint_names, (int(a) for a in model.arrays.qposadr)))
                for _ in layout.equalities:  # a follower may lead another: settle the chain, one link per pass
                    for tie in layout.equalities:
                        array[address[tie.joint1]] = tie.polycoef[0] + tie.polycoef[1] * array[address[tie.joint2]]
            out.append(array)
            continue
        try:
            array = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise URDFError(f"{what}={value!r}: expected {len(default)} numbers (MuJoCo's layout)") from None
        if array.shape != (len(default),) or not np.all(np.isfinite(array)):
            raise URDFError(f"{what} has shape {array.shape}: expected ({len(default)},) finite numbers in MuJoCo's "
                            f"layout (joints {', '.join(model.joint_names)})")
        out.append(array)
    return out[0], out[1]


# ----- public -------------------------------------------------------------------------------------------

def layout_from_urdf(source, *, package_dirs=None, floating_base: bool = False, qpos0=None, qvel0=None,
                     balance_inertia: bool = False, constraints: bool = True) -> URDFModel:
    """Read a URDF robot (a path or an XML string) into a URDFModel (see the module docstring).

    package_dirs: a folder or folders holding the packages that package:// mesh paths name (ROS_PACKAGE_PATH
    is searched after them); floating_base: the root link gets a free joint "root_joint" (else it is welded to
    the world); qpos0 (nq,), qvel0 (nv,): the initial state in MuJoCo's layout (default: the reference pose,
    at rest); balance_inertia: MuJoCo's balanceinertia rule for bodies whose moments break A + B >= C;
    constraints: True (default) applies the file's position limits, dry friction and mimics through rbody's
    constraint layer (as MuJoCo's loader applies them, rigidly here); False records them only and runs the bare
    tree, as Pinocchio's aba runs the file (module docstring).
    """
    for flag, value in (("floating_base", floating_base), ("balance_inertia", balance_inertia),
                        ("constraints", constraints)):
        if not isinstance(value, (bool, np.bool_)):
            raise URDFError(f"{flag}={value!r}: expected True or False")
    root, folder = read_source(source)
    reader = _Reader(root, folder, package_dirs, bool(floating_base), bool(balance_inertia), bool(constraints))
    return reader.build(qpos0, qvel0)


def from_urdf(source, *, package_dirs=None, floating_base: bool = False, t_end: float | None = None, qpos0=None,
              qvel0=None, balance_inertia: bool = False, constraints: bool = True) -> "URDFScene":
    """The Scene of a URDF robot (a path or an XML string), run natively by rbody's general engine.

    t_end: duration [s] (default 1 s); the rest as layout_from_urdf. The scene is a URDFScene (a TreeScene
    with the declared limits, friction, mimics, visual shapes and import_notes). Gravity is 9.81 m/s^2 along
    -z (URDF has none of its own).

    constraints=True (the default) holds the file's <limit lower upper> (revolute, prismatic), <dynamics friction>
    and <mimic> rigidly (rbody.engine.constraints: a joint never passes its stop beyond round-off, friction sticks
    exactly, a follower stays at multiplier * leader + offset), where MuJoCo's loader holds the same three softly.
    constraints=False runs the file as Pinocchio's plain aba does (the three recorded on the scene, not applied):
    use it to compare with Pinocchio like with like.
    """
    model = layout_from_urdf(source, package_dirs=package_dirs, floating_base=floating_base, qpos0=qpos0,
                             qvel0=qvel0, balance_inertia=balance_inertia, constraints=constraints)
    dirs = () if package_dirs is None else ((str(package_dirs),) if isinstance(package_dirs, (str, Path))
                                            else tuple(str(d) for d in package_dirs))
    return URDFScene(name=model.name, t_end=DEFAULT_T_END if t_end is None else t_end, tree=model.layout,
                     qpos0=model.qpos0, qvel0=model.qvel0, import_notes=model.notes, limits=dict(model.limits),
                     source=None if model.source == "<string>" else str(Path(model.source).resolve()),
                     root=model.root, floating_base=model.floating_base, package_dirs=dirs,
                     balance_inertia=bool(balance_inertia), effort_limits=dict(model.effort_limits),
                     velocity_limits=dict(model.velocity_limits), joint_friction=dict(model.joint_friction),
                     mimics=dict(model.mimics), visuals=dict(model.visuals), constraints=bool(constraints))


@dataclass(frozen=True, kw_only=True, eq=False)
class URDFScene(MJCFScene):
    """A TreeScene read from URDF: MJCFScene's declared position limits, and the rest of what the file declares.

    source:          the URDF file's absolute path (None for an XML string): validation's Pinocchio and Bullet
                     backends load the same file with their own parsers
    root, floating_base, package_dirs, balance_inertia, constraints: how it was read (the root link's name)
    effort_limits, velocity_limits, joint_friction, mimics, visuals: see URDFModel (limits, joint_friction and
                     mimics are applied through tree's Joint.range, Joint.frictionloss and equalities when
                     constraints is True, recorded only when False)
    """

    source: str | None = None
    root: str = ""
    floating_base: bool = False
    package_dirs: tuple = ()
    balance_inertia: bool = False
    effort_limits: Mapping[str, float] = field(default_factory=dict)
    velocity_limits: Mapping[str, float] = field(default_factory=dict)
    joint_friction: Mapping[str, float] = field(default_factory=dict)
    mimics: Mapping[str, tuple] = field(default_factory=dict)
    visuals: Mapping[str, tuple] = field(default_factory=dict)
    constraints: bool = True
