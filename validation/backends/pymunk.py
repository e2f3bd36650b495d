"""pymunk as a backend: planar scenes, stepped by pymunk (Chipmunk2D).

pymunk is 2-D. A planar scene lives in the world x-z plane; here world (x, z) is pymunk's (x, y)
and gravity is (0, -g). The conversion happens at this module's edge only:

- A rotation about world +y by phi takes +x toward -z (R_y(phi) x = (cos, 0, -sin)), so in pymunk's
  plane (x right, y up = world z) it is the rotation by -phi: body.angle = -phi and
  body.angular_velocity = -omega_y.
- A body's pymunk local coordinates of a body point p are the (x, z) components of R0 p, R0 its
  orientation in the reference pose (every joint coordinate zero): a body at pymunk angle -phi is its
  reference pose turned by phi about world y.
- The mass is the body's, the moment its Inertia about the hinge normal through the centre of mass,
  n^T I n with n = R0^T y (world y in the body frame); body.center_of_gravity is the centre of mass.

Joints, modelled with what each needs and nothing more:
- one hinge, to the world or to another body: a PivotJoint at the anchor;
- slides along directions in the plane (to the world) with at most one hinge: a free planar body when
  the slides span the plane (a rolling body's x, z, phi); one slide: a GrooveJoint along the axis to
  the static body, pivoting at the hinge's anchor if a hinge follows the slide. Without a hinge the
  moment is infinite: the slides do not turn the body.
- any planar tree (hinge axes along y, slide axes in the x-z plane), each body held to its parent by
  its joints in order: one slide to a moving body is a GrooveJoint fixed in the parent (then a hinge
  pivots at its anchor); a hinge then a slide (a telescoping arm) is a GrooveJoint fixed in the body,
  along the turned slide, through the pivot on the parent; two slides (and a hinge after them) leave the
  body free relative to its parent. A body without a hinge whose parent turns turns with it: a GearJoint
  of ratio 1 keeps their angles together. Joint coordinates are read back from the body's motion
  relative to its parent's (_observe_states). A body without a joint on a moving parent (MJCF's parts) is
  welded to it: one pymunk body carries both, with their summed mass, their centre of mass and the moment
  about it by the parallel-axis theorem (_merge_welded), and each is read back from that body's motion.
  Hinge stiffness and damping are a DampedRotarySpring. Refused, with the reason: two hinges on one body, a
  hinge before one of two slides, ball and free joints, slide springs, armature.
- balls on a horizontal line: free bodies and no gravity, when every moving body slides on one
  horizontal line and every contact acts along it (circles centred on the line, walls facing along
  it). Gravity is then balanced by the line's reaction and does no work, and nothing pushes a ball
  off the line, so no groove is needed. (Circles on a line amplify any sideways offset at every
  impact, so the contact geometry must be exactly aligned; otherwise the balls get grooves.)

Shapes seen from the side: spheres, and cylinders or capsules along y, are Circles; a capsule across
y is a Segment with its radius, a cylinder across y a rectangle; a box with one axis along y is a
Poly; a plane is a thin static Poly lying behind the surface, whose face gives contact normals
exactly along the plane's normal. Only the pairs listed in layout.contacts collide (ShapeFilter
category bits). pymunk multiplies the two shapes' elasticities and frictions: each shape gets sqrt(e)
and sqrt(mu) when that gives every pair its values, else a pre_solve callback sets the arbiter's.
Collisions are counted as contact onsets (a begin callback per pair).

Scenes with a varying mass or applied forces (the optional Scene hooks, see rbody.scene.Scene): before
every space.step the backend sets, from the state at the start of the step,
- body_mass(t, distance): body.mass of the one body on one slide (rocket, avalanche); the slide alone
  holds it, so its moment stays infinite and needs no update;
- slide_force(t, distance, speed): a force along the slide axis at the centre of mass (world (x, z)
  -> pymunk (x, y));
pymunk then moves the positions with the velocity before the step and the velocity with these forces:
explicit Euler in the applied forces, first order in dt (measured in tests/validation/test_pymunk_backend.py).
- pair_force(x1, x2): the force on body 1 and its opposite on body 2 (two-body), evaluated in each body's
  velocity update from the positions pymunk has just moved (a velocity_func; no rotation, no gravity):
  symplectic Euler, first order with bounded energy error.

Not corrected (the comparison reports them): positions advance with the velocity before the step,
x = a t (t - dt) / 2 under a constant force; a PivotJoint pendulum loses energy at a rate ~ dt.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pymunk

from rbody.checks import nonnegative, run_times, whole_number
from rbody.errors import SimulationError
from rbody.motion import quat_from_axis_angle, quat_from_matrix, quat_multiply, quat_to_matrix
from rbody.layout import WORLD, tree_order, Body, Joint, Layout, Shape
from rbody.progress import Reporter
from rbody.scene import BodyStates, Scene, TreeScene
from rbody.trajectory import Trajectory

name = "pymunk"

Y_AXIS = np.array([0.0, 1.0, 0.0])
# |cos| between a direction and world y within which it counts as along y (or across it).
AXIS_TOL = 1e-9
# Entries of a rotation matrix below this are round-off of the quaternion (a quarter turn about y leaves
# 2.2e-16 where 0 is meant): set to zero, so that a wall meant to face along x faces exactly along x.
ROUNDOFF = 1e-14
# Default collision slop as a fraction of the smallest contact shape (pymunk's own 0.1 is in pixels).
SLOP_FRACTION = 1e-6
# Depth of a plane's Poly behind its surface, as a fraction of the smallest contact shape.
PLANE_DEPTH_FRACTION = 0.1
# Solver iterations: pymunk's default, enough for every scene measured (see default_settings).
ITERATIONS = 10
# Optional Scene hooks for physics a Layout cannot hold, applied before every step (see _drive_plan).
HOOKS = ("body_mass", "slide_force", "pair_force")
# ShapeFilter categories are 32 bits: one per shape that takes part in a contact.
MAX_CONTACT_SHAPES = 32


# ----- planar rigid motions in world (x, z) ----------------------------------------------------------

def _rot(phi):
    """(..., 2, 2) rotation about world +y by phi [rad], acting on (x, z): [[c, s], [-s, c]]."""
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)], axis=-2)


def _apply(phi, tau, r):
    """Motion (phi, tau) on points r: R(phi) r + tau, broadcasting over leading axes."""
    return np.einsum("...ab,...b->...a", _rot(phi), r) + tau


def _cross_y(omega, r):
    """omega y x r in (x, z): omega (r_z, -r_x)."""
    r = np.asarray(r)
    return np.asarray(omega)[..., None] * np.stack([r[..., 1], -r[..., 0]], axis=-1)


def _xz(v) -> np.ndarray:
    return np.asarray(v, dtype=float)[..., [0, 2]]


def _snap(rotation: np.ndarray) -> np.ndarray:
    return np.where(np.abs(rotation) < ROUNDOFF, 0.0, rotation)


# ----- the plan: what pymunk is given, worked out without pymunk ----------------------------------------

@dataclass
class _JointPlan:
    joint: Joint
    sign: float = 1.0                      # hinge: the world turns about +y by sign * angle
    anchor: np.ndarray | None = None       # hinge: (2,) anchor in the reference pose, world (x, z)
    axis: np.ndarray | None = None         # slide: (2,) direction, world (x, z)


@dataclass
class _BodyPlan:
    body: Body
    rot0: np.ndarray                       # (3, 3) orientation in the reference pose, world
    origin0: np.ndarray                    # (3,) body origin in the reference pose, world
    joints: list[_JointPlan] = field(default_factory=list)
    kind: str = ""                         # static, pivot, free, groove, line
    moment: float = math.inf               # about world y through the centre of mass [kg m^2]
    cog: np.ndarray = field(default_factory=lambda: np.zeros(2))  # centre of mass, pymunk local
    com_y: float = 0.0                     # world y of the centre of mass (constant)
    phi: float = 0.0                       # initial motion from the reference pose: r -> R(phi) r + tau
    tau: np.ndarray = field(default_factory=lambda: np.zeros(2))
    omega: float = 0.0                     # initial omega_y [rad/s]
    com: np.ndarray = field(default_factory=lambda: np.zeros(2))  # initial centre of mass, world (x, z)
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))  # of the centre of mass

    # The pymunk body that carries this one: itself, or for a body welded to a moving one (no joint) the
    # nearest ancestor with joints; that body then holds the sum of their masses (see _merge_welded).
    carrier: str = ""
    frame0: np.ndarray = field(default_factory=lambda: np.zeros(3))  # carrier's origin0 (zeros for static)
    total_mass: float = 0.0                # carrier: mass of it and the bodies welded to it [kg]
    total_cog: np.ndarray = field(default_factory=lambda: np.zeros(2))  # their centre of mass, pymunk local
    total_moment: float = math.inf         # their moment about world y through total_cog [kg m^2]

    @property
    def name(self) -> str:
        return self.body.name

    @property
    def parent(self) -> str:
        return self.body.parent


@dataclass
class _ShapePlan:
    """A side view, in the owner's pymunk coordinates (world ones for the static body)."""

    name: str
    owner: str                             # body name, or WORLD
    moving: bool
    kind: str                              # circle, segment, poly, plane
    radius: float = 0.0                    # circle, segment
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # circle centre, segment ends, poly
    normal: np.ndarray = field(default_factory=lambda: np.zeros(2))        # plane
    half: float = 0.0                      # plane half length, 0 unbounded
    size: float = 0.0                      # smallest dimension [m]
    world_z: float = 0.0                   # circle: world z of the centre at t = 0


@dataclass
class _Plan:
    layout: Layout
    bodies: list[_BodyPlan]
    shapes: list[_ShapePlan]
    line_mode: bool                        # balls on a horizontal line: free bodies, no gravity
    scale: float                           # length scale of the scene [m]
    smallest: float                        # smallest contact shape (else any shape) [m]
    hooks: list[str] = field(default_factory=list)  # Scene hooks applied before every step
    scene: Scene | None = None


def _check_scene(scene) -> None:
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    if scene.batch_shape:
        raise NotImplementedError(
            f"scene {scene.name!r} is a batch of shape {scene.batch_shape}: pymunk runs one scene at a time; "
            "use scene.item(i)")
    if not scene.planar and not isinstance(scene, TreeScene):  # a user's tree: its joints decide (_joint_plan)
        raise NotImplementedError(
            f"scene {scene.name!r} is not planar: pymunk is 2-D and cannot express 3-D rotation or motion "
            "out of its plane")


def _hooks(scene: Scene) -> list[str]:
    """The optional Scene hooks `scene` defines (body_mass, slide_force, pair_force)."""
    return [h for h in HOOKS if callable(getattr(scene, h, None))]


def _drive_plan(scene: Scene, plan: "_Plan") -> list[str]:
    """The hooks to apply before every step, after checking the bodies they act on: body_mass and
    slide_force act on one body held by one slide alone (a groove, or a free body on a horizontal line
    without contacts; infinite moment), pair_force between two bodies."""
    hooks = _hooks(scene)
    moving = [p for p in plan.bodies if p.kind != "static"]
    if "body_mass" in hooks or "slide_force" in hooks:
        if len(moving) != 1 or moving[0].kind not in ("groove", "line") or len(moving[0].joints) != 1:
            raise NotImplementedError(
                f"scene {scene.name!r}: a varying mass or slide force is applied to one body on one slide; the "
                f"layout has {len(moving)} moving bodies held by {[p.kind for p in moving]}")
    if "pair_force" in hooks and len(moving) != 2:
        raise NotImplementedError(f"scene {scene.name!r}: a pair force acts between two bodies; the layout has "
                                  f"{len(moving)} moving bodies")
    return hooks


def _joint_plan(joint: Joint, rot0: np.ndarray, origin0: np.ndarray) -> _JointPlan:
    direction = rot0 @ np.array(joint.axis)
    if joint.kind == "free":
        raise NotImplementedError(f"joint {joint.name!r} is free: pymunk is 2-D and cannot express 3-D rotation")
    if joint.kind == "roll":
        raise NotImplementedError(
            f"joint {joint.name!r} is a roll joint (rolling without slipping, one coordinate): pymunk has no joint "
            "that ties a body's rotation to its translation (a GearJoint ties two rotations, a GrooveJoint or "
            "SlideJoint positions), only a contact with friction does that, so it cannot be modelled exactly; "
            "the rolling scenes give pymunk their contact layout (scene.layout) instead")
    if joint.kind not in ("hinge", "slide"):
        raise NotImplementedError(f"joint {joint.name!r} is a {joint.kind} joint: pymunk's plane has hinges about "
                                  "its normal and slides along it only")
    if joint.armature:
        raise NotImplementedError(f"joint {joint.name!r} has armature {joint.armature:g}: pymunk has no inertia "
                                  "added to a joint's coordinate")
    if joint.kind == "slide" and (joint.stiffness or joint.damping):
        raise NotImplementedError(f"slide {joint.name!r} has stiffness {joint.stiffness:g} and damping "
                                  f"{joint.damping:g}: pymunk's springs act between points, not along a slide")
    if joint.kind == "hinge":
        if abs(abs(direction[1]) - 1.0) > AXIS_TOL:
            raise NotImplementedError(
                f"hinge {joint.name!r} turns about {direction.round(12).tolist()} in the world: pymunk turns "
                "bodies only about the normal of its plane (world y)")
        return _JointPlan(joint, sign=float(np.sign(direction[1])),
                          anchor=_xz(origin0 + rot0 @ np.array(joint.anchor)))
    if abs(direction[1]) > AXIS_TOL:
        raise NotImplementedError(f"slide {joint.name!r} moves along {direction.round(12).tolist()}, out of the "
                                  "x-z plane that pymunk models")
    axis = _xz(direction)
    return _JointPlan(joint, axis=axis / np.linalg.norm(axis))


def _classify(plan: _BodyPlan) -> str:
    """How pymunk holds the body to its parent (the world or a moving body), from its joints in order:
    pivot (one hinge), groove (one slide, then at most one hinge), rail (a hinge, then a slide along a
    direction that turns with it), free (two slides spanning the plane, at most one hinge: every planar
    motion relative to the parent)."""
    hinges = [j for j in plan.joints if j.joint.kind == "hinge"]
    slides = [j for j in plan.joints if j.joint.kind == "slide"]
    if not plan.joints:
        return "static" if plan.parent == WORLD else "welded"
    if len(hinges) > 1:
        raise NotImplementedError(f"body {plan.name!r} has {len(hinges)} hinges to its parent: pymunk turns a body "
                                  "about one axis; give each hinge its own body")
    if not slides:
        return "pivot"
    if len(slides) > 2:
        raise NotImplementedError(f"body {plan.name!r} has {len(slides)} slides: a planar body moves along two "
                                  "directions at most")
    if len(slides) == 2:
        if hinges and plan.joints.index(hinges[0]) < max(plan.joints.index(j) for j in slides):
            raise NotImplementedError(f"body {plan.name!r}: hinge {hinges[0].joint.name!r} comes before a slide "
                                      "of its two and turns its axis; give the hinge after the slides")
        if np.linalg.matrix_rank(np.array([j.axis for j in slides]), tol=1e-9) < len(slides):
            raise NotImplementedError(f"body {plan.name!r} has parallel slides {[j.joint.name for j in slides]}")
        return "free"
    if hinges and plan.joints.index(hinges[0]) < plan.joints.index(slides[0]):
        return "rail"  # the slide's direction turns with the hinge: a groove on the body through the pivot
    return "groove"


def _turns(plan: _BodyPlan, parent: _BodyPlan | None) -> bool:
    """The body can turn in the plane: it has a hinge, or it hangs from a body that turns (and then turns
    with it: a body on slides alone keeps its orientation relative to its parent)."""
    return (any(j.joint.kind == "hinge" for j in plan.joints)
            or (parent is not None and parent.kind != "static" and math.isfinite(parent.moment)))


def _locked(p: _BodyPlan, parent: _BodyPlan | None) -> bool:
    """True when the body has no hinge but its parent turns: a GearJoint keeps their angles together."""
    return (not any(j.joint.kind == "hinge" for j in p.joints) and parent is not None
            and parent.kind != "static" and math.isfinite(parent.moment))


def _initial_state(plan: _BodyPlan, parent: _BodyPlan | None) -> None:
    """Compose the parent's motion with the joints in order (as MJCF: each acts in the frame the ones
    before it left) and add the joint rates up into the velocity of the centre of mass."""
    phi = 0.0 if parent is None else parent.phi
    tau = np.zeros(2) if parent is None else parent.tau.copy()
    omega = 0.0 if parent is None else parent.omega
    hinge_rates, slide_velocity = [], np.zeros(2)
    for jp in plan.joints:
        # the displacement from the reference pose is q - ref (MJCF's ref: the coordinate of the reference pose)
        q, rate = float(jp.joint.qpos0) - jp.joint.ref, float(np.asarray(jp.joint.qvel0, dtype=float))
        if jp.joint.kind == "hinge":
            alpha = jp.sign * q
            hinge_rates.append((jp.sign * rate, _apply(phi, tau, jp.anchor)))
            tau = _rot(phi) @ (jp.anchor - _rot(alpha) @ jp.anchor) + tau  # turn by alpha about the anchor
            phi += alpha
            omega += jp.sign * rate
        else:
            axis = _rot(phi) @ jp.axis
            tau = tau + q * axis
            slide_velocity += rate * axis
    plan.phi, plan.tau, plan.omega = phi, tau, omega
    plan.com = _apply(phi, tau, _xz(plan.origin0 + plan.rot0 @ plan.body.inertia.com))
    velocity = slide_velocity
    if parent is not None:
        velocity = velocity + parent.velocity + _cross_y(parent.omega, plan.com - parent.com)
    for rate, anchor in hinge_rates:
        velocity = velocity + _cross_y(rate, plan.com - anchor)
    plan.velocity = velocity


def _side_view(shape: Shape, rot0: np.ndarray, origin0: np.ndarray, owner: str, moving: bool) -> _ShapePlan:
    """The shape seen along y, in the owner's pymunk coordinates: origin0 is zero for a moving body, the
    reference position for the static body (whose coordinates are the world's)."""
    rotation = _snap(rot0 @ quat_to_matrix(np.array(shape.quat)))
    centre = _xz(origin0 + rot0 @ np.array(shape.pos))
    axis = rotation[:, 2]  # local z: cylinder and capsule axis, plane normal
    plan = _ShapePlan(shape.name, owner, moving, "", size=min([s for s in shape.size if s > 0], default=0.0))

    def along_y(v) -> bool:
        return abs(abs(v[1]) - 1.0) <= AXIS_TOL

    def across_y(v) -> bool:
        return abs(v[1]) <= AXIS_TOL

    def poly(corners) -> _ShapePlan:
        plan.kind, plan.points = "poly", np.array(corners)
        return plan

    if shape.kind == "sphere" or (shape.kind in ("cylinder", "capsule") and along_y(axis)):
        plan.kind, plan.radius, plan.points = "circle", shape.size[0], centre[None, :]
        return plan
    if shape.kind in ("cylinder", "capsule") and across_y(axis):
        radius, half = shape.size[0], shape.size[1]
        d = _xz(axis) / np.linalg.norm(_xz(axis))
        if shape.kind == "capsule":
            plan.kind, plan.radius, plan.points = "segment", radius, np.array([centre - half * d, centre + half * d])
            return plan
        n = np.array([-d[1], d[0]])
        return poly([centre + sx * half * d + sy * radius * n for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))])
    if shape.kind == "box":
        for k in range(3):
            if along_y(rotation[:, k]):
                i, j = [m for m in range(3) if m != k]
                a, b = shape.size[i] * _xz(rotation[:, i]), shape.size[j] * _xz(rotation[:, j])
                return poly([centre + a + b, centre - a + b, centre - a - b, centre + a - b])
    if shape.kind == "plane" and across_y(axis):
        plan.kind, plan.points, plan.normal = "plane", centre[None, :], _xz(axis) / np.linalg.norm(_xz(axis))
        for k in (0, 1):  # the plane's local axis that lies in the x-z plane gives its half length
            if across_y(rotation[:, k]):
                plan.half = shape.size[k] if len(shape.size) > k else 0.0
        return plan
    if shape.kind == "mesh":
        raise NotImplementedError(f"shape {shape.name!r} is a mesh: this backend draws primitives only")
    raise NotImplementedError(f"shape {shape.name!r} ({shape.kind}, local z along {axis.round(12).tolist()} in the "
                              "world) has no side view in pymunk's plane")


def _aligned_with_line(plan: _Plan) -> bool:
    """Every contact acts exactly along x: two circles centred at the same height, or a circle and a
    static face that faces along x (a plane with normal +-x, a poly whose edges are all axis-aligned)."""
    by_name = {s.name: s for s in plan.shapes}
    for contact in plan.layout.contacts:
        a, b = by_name[contact.shape_a], by_name[contact.shape_b]
        if a.kind != "circle":
            a, b = b, a
        if a.kind != "circle" or not a.moving:
            return False
        if b.kind == "circle":
            if not (b.moving and a.world_z == b.world_z):
                return False
        elif b.moving:
            return False
        elif b.kind == "plane":
            if b.normal[1] != 0.0:
                return False
        elif b.kind == "poly":
            edges = np.roll(b.points, -1, axis=0) - b.points
            if not np.all((edges[:, 0] == 0.0) | (edges[:, 1] == 0.0)):
                return False
        else:
            return False
    return True


def _plan(scene: Scene) -> _Plan:
    """Check that pymunk can model `scene`; place every body in its initial state; see every shape
    from the side."""
    _check_scene(scene)
    layout = scene.layout
    elements = [what for what, present in (("actuators", layout.actuators), ("tendons", layout.tendons),
                                           ("fluid forces", layout.fluid is not None),
                                           ("gravity compensation", any(b.gravcomp for b in layout.bodies)))
                if present]
    if elements:
        raise NotImplementedError(f"pymunk has no {', '.join(elements)} (its bodies feel only gravity, joints and "
                                  "contacts)")
    joints_of: dict[str, list[Joint]] = {b.name: [] for b in layout.bodies}
    for joint in layout.joints:
        if joint.body not in joints_of:
            raise ValueError(f"joint {joint.name!r} moves body {joint.body!r}, which the layout does not have")
        joints_of[joint.body].append(joint)

    bodies: dict[str, _BodyPlan] = {}
    shapes: list[_ShapePlan] = []
    in_contact = {n for c in layout.contacts for n in (c.shape_a, c.shape_b)}
    for body in tree_order(layout):
        parent = bodies.get(body.parent)
        rot_p = np.eye(3) if parent is None else parent.rot0
        origin_p = np.zeros(3) if parent is None else parent.origin0
        rot0 = _snap(rot_p @ quat_to_matrix(np.array(body.quat)))
        plan = _BodyPlan(body, rot0, origin_p + rot_p @ np.array(body.pos))
        plan.joints = [_joint_plan(joint, rot0, plan.origin0) for joint in joints_of[body.name]]
        plan.kind = _classify(plan)
        if plan.kind == "welded" and parent.kind == "static":
            plan.kind = "static"  # welded to a body welded to the world
        carrier = plan if plan.kind != "welded" else bodies[parent.carrier]
        plan.carrier = carrier.name
        plan.frame0 = np.zeros(3) if plan.kind == "static" else carrier.origin0
        plan.cog = _xz(plan.origin0 + rot0 @ body.inertia.com - plan.frame0)  # in the pymunk body's coordinates
        plan.com_y = float((plan.origin0 + rot0 @ body.inertia.com)[1])
        if _turns(plan, parent):  # else the body does not turn: moment inf
            plan.moment = body.inertia.moment(rot0.T @ Y_AXIS)
            if not plan.moment > 0:
                raise NotImplementedError(f"body {body.name!r} turns about world y but has no moment about it")
        _initial_state(plan, parent)
        bodies[body.name] = plan
        moving = plan.kind != "static"
        for shape in body.shapes:
            try:
                side = _side_view(shape, rot0, plan.origin0 - plan.frame0, carrier.name if moving else body.name,
                                  moving)
            except NotImplementedError:
                if shape.name in in_contact:
                    raise
                continue  # a shape that touches nothing does not act: no side view needed
            side.world_z = float((plan.origin0 + rot0 @ np.array(shape.pos))[2] + plan.tau[1])
            shapes.append(side)
    _merge_welded(bodies)
    shapes += [_side_view(s, np.eye(3), np.zeros(3), WORLD, False) for s in layout.fixed]
    if len({s.name for s in shapes}) != len(shapes):
        raise ValueError("layout has two shapes of the same name: contacts name shapes, so names must be unique")
    names = {s.name for s in shapes}
    for contact in layout.contacts:
        for n in (contact.shape_a, contact.shape_b):
            if n not in names:
                raise ValueError(f"a contact names shape {n!r}, which the layout does not have")

    sizes = [s.size for s in shapes if s.name in in_contact and s.size > 0] or [s.size for s in shapes if s.size > 0]
    scale = max(sizes + [float(np.linalg.norm(p.origin0)) for p in bodies.values()] + [float(np.finfo(float).tiny)])
    plan = _Plan(layout, list(bodies.values()), shapes, False, scale, min(sizes, default=scale), scene=scene)

    moving = [p for p in plan.bodies if p.kind != "static"]
    on_line = bool(moving) and all(p.kind == "groove" and p.parent == WORLD and len(p.joints) == 1
                                   and p.joints[0].axis[1] == 0.0 for p in moving)
    if on_line and _aligned_with_line(plan):
        plan.line_mode = True
        for p in moving:
            p.kind = "line"
    plan.hooks = _drive_plan(scene, plan)
    return plan


def _merge_welded(bodies: dict[str, _BodyPlan]) -> None:
    """Each moving body with the bodies welded to it as one pymunk body: the mass summed, the centre of mass
    the mass-weighted mean, the moment about world y through it by the parallel-axis theorem,
    sum (I_k + m_k |c_k - c|^2) (infinite when the carrier does not turn)."""
    for carrier in bodies.values():
        if carrier.kind in ("static", "welded"):
            continue
        parts = [p for p in bodies.values() if p.carrier == carrier.name]
        masses = np.array([p.body.inertia.mass for p in parts])
        carrier.total_mass = float(masses.sum())
        cogs = np.stack([p.cog for p in parts])
        carrier.total_cog = masses @ cogs / carrier.total_mass if carrier.total_mass > 0 else carrier.cog
        if math.isfinite(carrier.moment):
            carrier.total_moment = float(sum(p.moment + m * np.sum((c - carrier.total_cog) ** 2)
                                             for p, m, c in zip(parts, masses, cogs)))


def _reach(plan: _Plan, gravity: float, t_end: float) -> float:
    """Half length [m] of an unbounded plane and of a groove: beyond where any body can get in t_end. No
    body is faster than sqrt(2 K / m_min), K the initial kinetic energy; gravity adds g t^2 / 2 (none
    on a horizontal line). Not much longer: round-off in pymunk's geometry grows with the coordinates."""
    moving = [p for p in plan.bodies if p.kind != "static"]
    if not moving:
        return 10 * plan.scale
    kinetic = sum(0.5 * p.body.inertia.mass * float(p.velocity @ p.velocity)
                  + (0.5 * p.moment * p.omega**2 if math.isfinite(p.moment) else 0.0) for p in moving)
    fastest = math.sqrt(2 * kinetic / min(p.body.inertia.mass for p in moving))
    fall = 0.0 if plan.line_mode else 0.5 * gravity * t_end**2
    return 10 * plan.scale + fastest * t_end + fall + _push(plan, t_end)


def _push(plan: _Plan, t_end: float) -> float:
    """Distance [m] a slide force can add in t_end: the largest |force| on a body at rest at its start,
    over the smallest mass it reaches, times t_end^2 / 2 (drag and picked-up snow only slow it)."""
    if "slide_force" not in plan.hooks:
        return 0.0
    scene, slide = plan.scene, plan.bodies[0].joints[0].joint
    t = np.linspace(0.0, t_end, 101)
    start = np.full_like(t, float(slide.qpos0))
    force = np.max(np.abs(scene.slide_force(t, start, np.zeros_like(t))))
    mass = np.min(scene.body_mass(t, start)) if "body_mass" in plan.hooks else plan.bodies[0].body.inertia.mass
    return float(force / mass) * 0.5 * t_end**2 if mass > 0 else math.inf


# ----- check and run ----------------------------------------------------------------------------------

def check(scene: Scene) -> None:
    """Raise NotImplementedError when pymunk cannot model `scene` (a batch, 3-D rotation, joints or
    shapes without a planar counterpart), ValueError when `scene` is not a Scene or its layout is
    inconsistent."""
    layout = getattr(scene, "tree", None)
    # contacts are pymunk's own (its shapes collide: the layout's contacts are built below); joint limits, dry
    # friction and equalities are not built
    if layout is not None and (any(j.range is not None or j.frictionloss > 0 for j in layout.joints)
                               or any(e.active for e in layout.equalities)):
        raise NotImplementedError(f"pymunk backend: scene {scene.name!r} has joint limits, dry friction or equality "
                                  "constraints, which this backend does not build")
    _plan(scene)


def default_settings(scene: Scene) -> dict:
    """The settings run() uses when none are given.

    iterations:     10, pymunk's default: at dt = 1e-3, 100 iterations change the swinging rod by 6e-15 rad,
                    a 3-rod chain at large angles by 3.5e-5 rad in 2 s (its error from dt is 2.5e-2 rad),
                    and neither the rolling nor the pi counts
    collision_slop: 1e-6 of the smallest contact shape [m] (pymunk's 0.1 is meant in pixels)
    """
    return _defaults(_plan(scene))


def _defaults(plan: _Plan) -> dict:
    return {"iterations": ITERATIONS, "collision_slop": float(SLOP_FRACTION * plan.smallest)}


def run(scene: Scene, dt: float, t_end: float | None = None, *, iterations: int | None = None,
        collision_slop: float | None = None, save_every: int = 1, progress: bool | None = None) -> Trajectory:
    """Step `scene` in pymunk with step dt [s] up to t_end [s] (default scene.t_end).

    iterations:     solver iterations per step (default: default_settings(scene))
    collision_slop: overlap pymunk leaves uncorrected [m] (default: default_settings(scene))
    save_every:     keep every n-th step (n >= 1)
    progress:       a line on stderr with the time left (rbody.progress: True, False, or None: in an interactive
                    session, for runs longer than a few seconds)
    Returns a Trajectory with the scene's observables (scene.observe) and, for scenes with elastic
    contacts, `collisions` (T,) contact onsets so far over all pairs and `ball_collisions` (T,) over
    pairs of two moving bodies. meta: scene, backend, dt, settings, pymunk version, model (how each
    body is held), line_mode, step_seconds (time spent in space.step only) [s], run_seconds (the step loop
    with the reading of every saved body state and their translation into the observables) [s].
    Raises ValueError for bad arguments, NotImplementedError when pymunk cannot model the scene,
    SimulationError when the state becomes non-finite.
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    dt, t_end = run_times(scene.t_end, dt, t_end)
    whole_number(save_every, "save_every")
    whole_number(1 if iterations is None else iterations, "iterations")
    if collision_slop is not None:
        nonnegative(collision_slop, "collision_slop")
    plan = _plan(scene)
    defaults = _defaults(plan)
    iterations = defaults["iterations"] if iterations is None else int(iterations)
    slop = defaults["collision_slop"] if collision_slop is None else float(collision_slop)
    # As rbody.simulate: t_end/dt steps rounded up (to round-off), then up to a multiple of save_every.
    nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
    nsteps = -(-nsteps // save_every) * save_every

    gravity = scene.gravity if scene.applies_gravity else 0.0
    space, handles, counter = _build(plan, gravity, int(iterations), slop, _reach(plan, gravity, t_end))
    nsave, nb = nsteps // save_every + 1, len(plan.bodies)
    position, angle = np.empty((nsave, nb, 2)), np.empty((nsave, nb))
    velocity, angular = np.empty((nsave, nb, 2)), np.empty((nsave, nb))
    collisions = np.zeros(nsave, dtype=np.int64)
    ball_collisions = np.zeros(nsave, dtype=np.int64)

    def record(k: int) -> None:
        for i, b in enumerate(handles):
            position[k, i] = b.position
            angle[k, i] = b.angle
            velocity[k, i] = b.velocity
            angular[k, i] = b.angular_velocity
        collisions[k], ball_collisions[k] = counter.total, counter.between_bodies

    started = time.perf_counter()
    record(0)
    step, seconds = space.step, 0.0
    if plan.hooks:
        drive = _driver(scene, plan, handles, dt)
        n = 0

        def step(dt: float) -> None:  # noqa: F811 - the hooks first, then pymunk's step
            nonlocal n
            drive(n)
            space.step(dt)
            n += 1
    reporter = Reporter(progress, f"pymunk {scene.name}", nsteps)
    for k in range(1, nsave):
        start = time.perf_counter()
        for _ in range(save_every):
            step(dt)
        seconds += time.perf_counter() - start
        record(k)
        if k % 1024 == 0:
            reporter.update(k * save_every)
    reporter.finish()
    finite = np.all(np.isfinite(np.concatenate([position.reshape(nsave, -1), velocity.reshape(nsave, -1),
                                                angle, angular], axis=1)), axis=1)
    if not np.all(finite):
        raise SimulationError(f"scene {scene.describe()}: pymunk with dt={dt} gave a non-finite state by "
                              f"t={np.argmin(finite) * save_every * dt:.6g} s; try a smaller dt")

    t = np.arange(nsave) * (dt * save_every)
    bodies, joints = _observe_states(plan, position, angle, velocity, angular)
    data = dict(scene.observe(t, bodies, joints))
    if counter.elastic:
        data["collisions"], data["ball_collisions"] = collisions, ball_collisions
    run_seconds = time.perf_counter() - started
    meta = {"scene": scene.name, "backend": name, "dt": dt, "pymunk": pymunk.version,
            "settings": {"iterations": int(iterations), "collision_slop": slop, "save_every": int(save_every)},
            "model": {p.name: p.kind for p in plan.bodies}, "line_mode": plan.line_mode, "step_seconds": seconds,
            "run_seconds": run_seconds}
    if plan.hooks:
        meta["stepping"] = (f"space.step loop, setting {', '.join(plan.hooks)} from the scene before every step "
                            "(timed with that Python work): explicit Euler in the applied forces")
    return Trajectory(t, data, meta=meta)


def _driver(scene: Scene, plan: _Plan, handles: list, dt: float):
    """drive(n): before step n (at t = n dt) set the mass and apply the forces of the scene's hooks from
    the state at the start of the step. pymunk clears applied forces after every step."""
    hooks = plan.hooks
    if "pair_force" in hooks:
        (p1, b1), (p2, b2) = [(p, b) for p, b in zip(plan.bodies, handles) if p.kind != "static"]

        def centre(p: _BodyPlan, b: pymunk.Body) -> tuple[np.ndarray, tuple]:
            x, z = b.local_to_world(tuple(p.cog))
            return np.array([x, p.com_y, z]), (x, z)

        # In the velocity update (pymunk's velocity_func, as in its planet example), after every position
        # has moved: v += F(x_new) / m dt with x_new = x + v dt, the symplectic Euler method. The same force
        # applied before the step would be explicit Euler, F(x_old): 0.84 m against 2.9e-3 m of orbit error
        # over 3 periods of the e = 0.3 two-body case at dt = 1e-3 (measured).
        def force() -> np.ndarray:
            return np.asarray(scene.pair_force(centre(p1, b1)[0], centre(p2, b2)[0]), dtype=float).reshape(3)

        def update(sign: float):
            def velocity_func(body: pymunk.Body, gravity, damping: float, step: float) -> None:
                f = sign * force()
                body.velocity = (body.velocity[0] + f[0] / body.mass * step, body.velocity[1] + f[2] / body.mass * step)
            return velocity_func

        b1.velocity_func, b2.velocity_func = update(1.0), update(-1.0)
        return lambda n: None

    # One body on one slide: its coordinate is qpos0 plus the travel of the centre of mass along the axis
    # (the body does not turn), its rate the velocity along the axis.
    p, b = next((p, b) for p, b in zip(plan.bodies, handles) if p.kind != "static")
    slide = p.joints[0]
    axis, q0 = slide.axis, float(slide.joint.qpos0)
    start = np.asarray(b.local_to_world(tuple(p.cog)))
    local = tuple(p.cog)

    def drive(n: int) -> None:
        t = [n * dt]
        distance = [q0 + float((np.asarray(b.local_to_world(local)) - start) @ axis)]
        if "body_mass" in hooks:
            b.mass = float(scene.body_mass(t, distance)[0])
        if "slide_force" in hooks:
            speed = [float(np.asarray(b.velocity) @ axis)]
            f = float(scene.slide_force(t, distance, speed)[0])
            b.apply_force_at_local_point((f * axis[0], f * axis[1]), local)
    return drive


# ----- building the space -------------------------------------------------------------------------------

class _Counter:
    """Contact onsets over all pairs, and over pairs of two moving bodies."""

    def __init__(self, elastic: bool) -> None:
        self.elastic = elastic
        self.total = 0
        self.between_bodies = 0

    def begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, between_bodies: bool) -> None:
        self.total += 1
        self.between_bodies += between_bodies


def _build(plan: _Plan, gravity: float, iterations: int, slop: float, reach: float):
    """The space, the pymunk body of each plan body (the static body for static ones), the counter."""
    space = pymunk.Space()
    space.gravity = (0.0, 0.0) if plan.line_mode else (0.0, -gravity)
    space.iterations = iterations
    space.collision_slop = slop
    handles: dict[str, pymunk.Body] = {WORLD: space.static_body}
    for p in plan.bodies:
        if p.kind == "static":
            handles[p.name] = space.static_body
            continue
        if p.kind == "welded":
            handles[p.name] = handles[p.carrier]
            continue
        body = pymunk.Body(p.total_mass, p.total_moment)
        body.center_of_gravity = tuple(p.total_cog)
        body.angle = -p.phi  # before the position: pymunk turns a body about its centre of mass
        body.position = tuple(_apply(p.phi, p.tau, _xz(p.origin0)))
        # pymunk's velocity is that of its centre of mass, the welded bodies' included
        body.velocity = tuple(p.velocity + _cross_y(p.omega, _rot(p.phi) @ (p.total_cog - p.cog)))
        body.angular_velocity = -p.omega
        space.add(body)
        handles[p.name] = body
    made = {s.name: _make_shape(s, handles[s.owner], plan.smallest, slop, reach) for s in plan.shapes}
    space.add(*made.values())
    for p in plan.bodies:
        _constrain(space, p, handles, plan, reach)
    counter = _contacts(space, plan, made)
    return space, [handles[p.name] for p in plan.bodies], counter


def _make_shape(s: _ShapePlan, body: pymunk.Body, smallest: float, slop: float, reach: float) -> pymunk.Shape:
    if s.kind == "circle":
        return pymunk.Circle(body, s.radius, tuple(s.points[0]))
    if s.kind == "segment":
        return pymunk.Segment(body, tuple(s.points[0]), tuple(s.points[1]), s.radius)
    if s.kind == "poly":
        return pymunk.Poly(body, [tuple(c) for c in s.points])
    # A plane: a Poly from slop/2 in front of the surface to a depth behind it. pymunk sees a contact only
    # where shapes overlap and corrects only overlap beyond the slop, so a body resting on the plane touches
    # it from t = 0 (exactly touching, it would first fall freely for a step) and is not pushed off it.
    n, half = s.normal, s.half if s.half > 0 else reach
    tangent = np.array([n[1], -n[0]])
    front, back = s.points[0] + 0.5 * slop * n, s.points[0] - PLANE_DEPTH_FRACTION * smallest * n
    return pymunk.Poly(body, [tuple(front + half * tangent), tuple(front - half * tangent),
                              tuple(back - half * tangent), tuple(back + half * tangent)])


def _constrain(space: pymunk.Space, p: _BodyPlan, handles: dict, plan: _Plan, reach: float) -> None:
    """The joints of body p to its parent (the static body for the world), placed in the initial state:
    pivot a PivotJoint at the hinge's anchor; groove a GrooveJoint along the slide, fixed in the parent,
    through the hinge's anchor (or the centre of mass); rail a GrooveJoint along the slide fixed in the
    body, through the hinge's anchor on the parent; free nothing. A body without a hinge on a parent that
    turns also gets a GearJoint (ratio 1) that keeps their angles together."""
    if p.kind in ("static", "welded"):
        return  # the world holds it, or it is part of its carrier's pymunk body
    body, parent = handles[p.name], handles[p.parent]
    parent_plan = next((q for q in plan.bodies if q.name == p.parent), None)
    motion = (0.0, np.zeros(2)) if parent_plan is None else (parent_plan.phi, parent_plan.tau)
    if p.kind == "pivot":
        hinge = p.joints[0]
        joint = pymunk.PivotJoint(parent, body, tuple(_apply(*motion, hinge.anchor)))  # anchor at t = 0
        joint.collide_bodies = False
        space.add(joint)
    elif p.kind == "groove" and p.parent == WORLD:
        slide = next(j for j in p.joints if j.joint.kind == "slide")
        hinge = next((j for j in p.joints if j.joint.kind == "hinge"), None)
        local = p.cog if hinge is None else hinge.anchor - _xz(p.origin0)  # the pivot, pymunk local
        point = np.asarray(body.local_to_world(tuple(local)))
        space.add(pymunk.GrooveJoint(space.static_body, body, tuple(point - reach * slide.axis),
                                     tuple(point + reach * slide.axis), tuple(local)))
    elif p.kind == "groove":  # on a moving parent: the groove is fixed in the parent, along its turned axis
        slide = next(j for j in p.joints if j.joint.kind == "slide")
        hinge = next((j for j in p.joints if j.joint.kind == "hinge"), None)
        local = p.cog if hinge is None else hinge.anchor - _xz(p.origin0)
        point = np.asarray(body.local_to_world(tuple(local)))
        axis = _rot(motion[0]) @ slide.axis  # the slide's direction at t = 0, world (x, z)
        ends = [tuple(parent.world_to_local(tuple(point + sign * reach * axis))) for sign in (-1, 1)]
        joint = pymunk.GrooveJoint(parent, body, ends[0], ends[1], tuple(local))
        joint.collide_bodies = False
        space.add(joint)
    elif p.kind == "rail":  # hinge, then slide: the body's line through the pivot turns with it
        hinge = next(j for j in p.joints if j.joint.kind == "hinge")
        slide = next(j for j in p.joints if j.joint.kind == "slide")
        pivot = _apply(*motion, hinge.anchor)                 # on the parent, world at t = 0
        axis = _rot(p.phi) @ slide.axis                        # the body's slide direction at t = 0
        ends = [tuple(body.world_to_local(tuple(pivot + sign * reach * axis))) for sign in (-1, 1)]
        joint = pymunk.GrooveJoint(body, parent, ends[0], ends[1], tuple(parent.world_to_local(tuple(pivot))))
        joint.collide_bodies = False
        space.add(joint)
    hinge = next((j for j in p.joints if j.joint.kind == "hinge"), None)
    if hinge is not None and (hinge.joint.stiffness or hinge.joint.damping):
        # torque -k (q - springref) - c q' on the body, its opposite on the parent. Chipmunk's spring angle is
        # a.angle - b.angle (parent minus body) = sign (q - ref) (body.angle = -phi), so it rests at
        # sign (springref - ref).
        rest = hinge.sign * (hinge.joint.springref - hinge.joint.ref)
        spring = pymunk.DampedRotarySpring(parent, body, rest, hinge.joint.stiffness, hinge.joint.damping)
        space.add(spring)
    if _locked(p, parent_plan):
        gear = pymunk.GearJoint(parent, body, body.angle - parent.angle, 1.0)
        gear.collide_bodies = False
        space.add(gear)


def _contacts(space: pymunk.Space, plan: _Plan, made: dict) -> _Counter:
    """Only the listed pairs collide; each pair gets its restitution and friction; onsets are counted."""
    contacts = plan.layout.contacts
    names = list(dict.fromkeys(n for c in contacts for n in (c.shape_a, c.shape_b)))
    if len(names) > MAX_CONTACT_SHAPES:
        raise NotImplementedError(f"{len(names)} shapes take part in contacts: pymunk's collision filter has "
                                  f"{MAX_CONTACT_SHAPES} categories")
    bit = {n: 1 << i for i, n in enumerate(names)}
    mask = dict.fromkeys(names, 0)
    for c in contacts:
        mask[c.shape_a] |= bit[c.shape_b]
        mask[c.shape_b] |= bit[c.shape_a]
    for n, shape in made.items():
        shape.filter = pymunk.ShapeFilter(categories=bit.get(n, 0), mask=mask.get(n, 0))
        shape.collision_type = names.index(n) + 1 if n in bit else 0

    # sqrt(e) and sqrt(mu) on both shapes give each pair its values when all pairs agree or no shape is
    # in two pairs; otherwise a pre_solve callback sets the arbiter's values.
    uses = {n: sum(n in (c.shape_a, c.shape_b) for c in contacts) for n in names}
    factorable = len({(c.restitution, c.friction) for c in contacts}) <= 1 or max(uses.values(), default=0) <= 1
    for c in contacts:
        for n in (c.shape_a, c.shape_b):
            made[n].elasticity, made[n].friction = math.sqrt(c.restitution), math.sqrt(c.friction)

    moving = {s.name: s.moving for s in plan.shapes}
    counter = _Counter(elastic=any(c.restitution > 0 for c in contacts))
    for c in contacts:
        callbacks = {}
        if counter.elastic:
            callbacks.update(begin=counter.begin, data=moving[c.shape_a] and moving[c.shape_b])
        if not factorable:
            def pre_solve(arbiter, space, data, e=c.restitution, mu=c.friction):
                arbiter.restitution, arbiter.friction = e, mu
            callbacks["pre_solve"] = pre_solve
        if callbacks:
            space.on_collision(names.index(c.shape_a) + 1, names.index(c.shape_b) + 1, **callbacks)
    return counter


# ----- back to the world ------------------------------------------------------------------------------------

def _observe_states(plan: _Plan, position, angle, velocity, angular):
    """BodyStates of every body and (qpos, qvel) of every hinge and slide joint from pymunk's history:
    position (T, nb, 2) of the body origins, angle (T, nb), velocity (T, nb, 2) of the centres of mass,
    angular (T, nb), all pymunk's."""
    phi, omega = -angle, -angular                               # (T, nb): rotation about world +y
    cog = np.stack([p.cog for p in plan.bodies])                 # (nb, 2)
    com = position + np.einsum("tbij,bj->tbi", _rot(phi), cog)  # pymunk local -> world (x, z)
    # pymunk's velocity is its body's centre of mass's (the welded bodies' included): each body's own com moves
    # with v + omega y x (com - c), c that centre of mass
    by_name = {p.name: p for p in plan.bodies}
    total = np.stack([by_name[p.carrier].total_cog if p.kind != "static" else p.cog for p in plan.bodies])
    velocity = velocity + _cross_y(omega, com - position - np.einsum("tbij,bj->tbi", _rot(phi), total))
    index = {p.name: i for i, p in enumerate(plan.bodies)}
    zeros = np.zeros(position.shape[0])
    bodies, joints = {}, {}
    for i, p in enumerate(plan.bodies):
        bodies[p.name] = BodyStates(
            com=np.stack([com[:, i, 0], zeros + p.com_y, com[:, i, 1]], axis=1),
            quat=quat_multiply(quat_from_axis_angle(Y_AXIS, phi[:, i]), quat_from_matrix(p.rot0)),
            velocity=np.stack([velocity[:, i, 0], zeros, velocity[:, i, 1]], axis=1),
            omega=np.stack([zeros, omega[:, i], zeros], axis=1))
        if p.kind == "pivot":
            hinge, j = p.joints[0], index.get(p.parent)
            relative = phi[:, i] - (0.0 if j is None else phi[:, j])
            rate = omega[:, i] - (0.0 if j is None else omega[:, j])
            joints[hinge.joint.name] = (hinge.sign * relative + hinge.joint.ref, hinge.sign * rate)
        elif p.kind in ("static", "welded"):
            continue  # no joint of its own
        elif p.parent not in index:
            joints.update(_slide_coordinates(p, phi[:, i], omega[:, i], position[:, i], com[:, i], velocity[:, i]))
        else:
            # Relative to the parent's motion r -> R(phi_j) r + tau_j: the joints move the body as if the parent
            # stood in its reference pose. Position x -> R(-phi_j)(x - tau_j); velocity: that of the parent's
            # point at x taken away, turned back, v_rel = R(-phi_j)(v - v_j - omega_j y x (x - com_j)).
            j = index[p.parent]
            back = _rot(-phi[:, j])
            # position j is the origin of the parent's pymunk body (its carrier's, when it is welded)
            tau_j = position[:, j] - np.einsum("tij,j->ti", _rot(phi[:, j]), _xz(plan.bodies[j].frame0))

            def relative(x):
                return np.einsum("tij,tj->ti", back, x - tau_j)

            carried = velocity[:, j] + _cross_y(omega[:, j], com[:, i] - com[:, j])
            joints.update(_slide_coordinates(p, phi[:, i] - phi[:, j], omega[:, i] - omega[:, j],
                                             relative(position[:, i]), relative(com[:, i]),
                                             np.einsum("tij,tj->ti", back, velocity[:, i] - carried)))
    return bodies, joints


def _slide_coordinates(p: _BodyPlan, phi, omega, origin, com, velocity) -> dict:
    """Joint coordinates of a body on slides (and at most one hinge) to the world: replay the joints in
    order with the slides at zero, then solve for the displacements along the slide axes (turned by a
    hinge before them), and likewise for the rates from the velocity of the centre of mass."""
    T = phi.shape[0]
    psi, tau0 = np.zeros(T), np.zeros((T, 2))
    axes, hinges, out = [], [], {}
    for jp in p.joints:
        if jp.joint.kind == "hinge":  # the one hinge carries the whole rotation phi
            hinges.append((jp, _apply(psi, tau0, jp.anchor), len(axes)))
            tau0 = _apply(psi, tau0, jp.anchor) - np.einsum("tij,j->ti", _rot(psi + phi), jp.anchor)
            psi = psi + phi
            out[jp.joint.name] = (jp.sign * phi + jp.joint.ref, jp.sign * omega)
        else:
            axes.append((jp, np.einsum("tij,j->ti", _rot(psi), jp.axis)))
    W = np.stack([w for _jp, w in axes], axis=-1)  # (T, 2, k)
    d = _solve(W, origin - np.einsum("tij,j->ti", _rot(phi), _xz(p.origin0)) - tau0)
    # v_com = omega y x (com - anchor) + sum of rate x axis, the anchor moved by the slides before it
    rhs = velocity.copy()
    for _jp, anchor, before in hinges:
        anchor = anchor + sum(d[:, m, None] * W[:, :, m] for m in range(before))
        rhs = rhs - _cross_y(omega, com - anchor)
    rate = _solve(W, rhs)
    for m, (jp, _w) in enumerate(axes):
        out[jp.joint.name] = (d[:, m] + jp.joint.ref, rate[:, m])
    return out


def _solve(W: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """(T, k) solution of W x = rhs for W (T, 2, k), k = 1 (projection onto the axis) or 2."""
    if W.shape[-1] == 1:
        w = W[:, :, 0]
        return (np.sum(w * rhs, axis=1) / np.sum(w * w, axis=1))[:, None]
    return np.linalg.solve(W, rhs[:, :, None])[:, :, 0]
