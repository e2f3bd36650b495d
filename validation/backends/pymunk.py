"""pymunk as a backend: planar scenes, stepped by pymunk (Chipmunk2D).

pymunk is 2-D. A planar scene lives in the world x-z plane; here world (x, z) is pymunk's (x, y)
and gravity is (0, -g). The conversion happens at this module's edge only:

- A rotation about world +y by phi takes x toward -z, so in pymunk's plane (x right, y up = world z)
  it is the rotation by -phi: pymunk's body.angle is -phi, its angular_velocity -omega_y.
- Each body keeps its reference pose (all joint coordinates zero): its pymunk local coordinates of a
  body point p are the (x, z) components of R0 p, with R0 the reference orientation in the world, so
  that a body at pymunk angle -phi is its reference pose turned by phi about world y.
- The mass is the body's, the moment its Inertia about the hinge normal (world y) through the
  centre of mass, n^T I n with n = R0^T y; body.center_of_gravity is the centre of mass.

Joints, modelled with what each needs and nothing more:
- one hinge (to the world or to another body): a PivotJoint at the anchor;
- slides along world directions (to the world), with at most one hinge: the free planar body when
  the slides span the plane (a rolling body's x, z, phi); one slide: a GrooveJoint along the axis,
  pivoting at the hinge's anchor when a hinge follows the slide; without a hinge the moment is
  infinite (the slide does not turn the body);
- bodies that only slide along horizontal lines (balls on a line): free bodies and zero gravity. On
  a horizontal line gravity is balanced by the line's reaction and does no work; contacts between
  balls centred on the line act along it, so nothing moves the balls off it and no groove is needed.

Shapes seen from the side: spheres, and cylinders or capsules whose axis is along y, are Circles; a
capsule across y is a Segment with its radius; a box with one axis along y is a Poly; a plane is a
static Segment whose rounded thickness lies behind the surface, so the surface is exactly the plane.
Only the pairs listed in layout.contacts collide (ShapeFilter category bits). Elasticity and
friction of a pair are products of the two shapes' values in pymunk: each shape gets sqrt(e) and
sqrt(mu) when that gives every pair its value, else a pre_solve callback sets the arbiter's
restitution and friction. Collision events are counted from contact onsets (a begin callback).

Not corrected (the comparison reports them): positions advance with the velocity before the step,
x = a t (t - dt) / 2 under a constant force; a PivotJoint pendulum loses energy at a rate ~ dt.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pymunk

from rbody._checks import finite_array, nonnegative
from rbody.errors import SimulationError
from rbody.motion import quat_from_axis_angle, quat_from_matrix, quat_multiply, quat_to_matrix
from rbody.scene import WORLD, Body, BodyStates, Joint, Layout, Scene, Shape
from rbody.trajectory import Trajectory

name = "pymunk"

Y_AXIS = np.array([0.0, 1.0, 0.0])
# |cos| between a direction and world y above which it counts as along y, below which as across.
AXIS_TOL = 1e-9
# Default collision slop as a fraction of the smallest contact shape: pymunk's 0.1 is in pixels.
SLOP_FRACTION = 1e-6
# Thickness of a plane's segment, as a fraction of the smallest contact shape (it lies behind the
# surface: only keeps fast bodies from passing through in one step).
PLANE_THICKNESS_FRACTION = 0.1
# Solver iterations per constraint or contact pair by default (pymunk's default is 10 in all).
ITERATIONS_PER_ROW = 10
MIN_ITERATIONS = 10
# ShapeFilter categories are 32 bits: one per shape that takes part in a contact.
MAX_CONTACT_SHAPES = 32


# ----- planar rigid motions in world (x, z) ------------------------------------------------------------

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


# ----- the plan: what pymunk is given, computed without pymunk -------------------------------------------

@dataclass
class _JointPlan:
    joint: Joint
    sign: float = 1.0                      # hinge: world rotation about +y is sign * angle
    anchor: np.ndarray | None = None       # hinge: (2,) anchor in the reference pose, world (x, z)
    axis: np.ndarray | None = None         # slide: (2,) direction, world (x, z)


@dataclass
class _BodyPlan:
    body: Body
    kind: str                              # static, pivot, free, groove, line
    rot0: np.ndarray                       # (3, 3) reference orientation in the world
    origin0: np.ndarray                    # (3,) reference position of the body origin, world
    joints: list[_JointPlan] = field(default_factory=list)
    moment: float = math.inf
    cog: np.ndarray = field(default_factory=lambda: np.zeros(2))    # pymunk local centre of mass
    com_y: float = 0.0
    phi: float = 0.0                       # initial motion from the reference pose (phi, tau)
    tau: np.ndarray = field(default_factory=lambda: np.zeros(2))
    omega: float = 0.0                     # initial omega_y [rad/s]
    com: np.ndarray = field(default_factory=lambda: np.zeros(2))    # initial centre of mass, (x, z)
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))

    @property
    def name(self) -> str:
        return self.body.name

    @property
    def parent(self) -> str:
        return self.body.parent


@dataclass
class _Plan:
    layout: Layout
    bodies: list[_BodyPlan]
    line_mode: bool                        # every moving body slides on a horizontal line: no gravity
    scale: float                           # length scale of the scene [m]
    smallest: float                        # smallest contact shape size [m]
    reach: float                           # half length of an unbounded plane [m]


def _check_scene(scene) -> None:
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    if scene.batch_shape:
        raise NotImplementedError(
            f"scene {scene.name!r} is a batch of shape {scene.batch_shape}: pymunk runs one scene at a time; "
            "use scene.item(i)")
    if not scene.planar:
        raise NotImplementedError(
            f"scene {scene.name!r} is not planar: pymunk is 2-D and cannot express 3-D rotation "
            "(a body turning about more than one axis)")


def _order(layout: Layout) -> list[Body]:
    """Bodies with every parent before its children."""
    by_name = {b.name: b for b in layout.bodies}
    if len(by_name) != len(layout.bodies):
        raise ValueError("layout has two bodies of the same name: body names must be unique")
    ordered, placed = [], {WORLD}
    pending = list(layout.bodies)
    while pending:
        ready = [b for b in pending if b.parent in placed]
        if not ready:
            missing = sorted({b.parent for b in pending} - set(by_name) - {WORLD})
            raise ValueError(f"bodies {[b.name for b in pending]} have parents {missing or 'in a cycle'}: "
                             "every parent must be 'world' or a body of the layout")
        for b in ready:
            ordered.append(b)
            placed.add(b.name)
        pending = [b for b in pending if b.name not in placed]
    return ordered


def _classify(plan: _BodyPlan) -> str:
    hinges = [j for j in plan.joints if j.joint.kind == "hinge"]
    slides = [j for j in plan.joints if j.joint.kind == "slide"]
    name = plan.name
    if not plan.joints:
        if plan.parent != WORLD:
            raise NotImplementedError(f"body {name!r} is welded to body {plan.parent!r}: this backend does not "
                                      "merge welded bodies")
        return "static"
    if len(hinges) > 1:
        raise NotImplementedError(f"body {name!r} has {len(hinges)} hinges to its parent: pymunk turns a body "
                                  "about one axis, give each hinge its own body")
    if not slides:
        return "pivot"
    if plan.parent != WORLD:
        raise NotImplementedError(f"body {name!r} slides on body {plan.parent!r}: this backend models slides "
                                  "to the world only")
    axes = np.array([j.axis for j in slides])
    rank = np.linalg.matrix_rank(axes, tol=1e-9)
    if rank < len(slides):
        raise NotImplementedError(f"body {name!r} has parallel slide joints {[j.joint.name for j in slides]}")
    if rank == 2:
        return "free"
    if hinges and plan.joints.index(hinges[0]) < plan.joints.index(slides[0]):
        raise NotImplementedError(f"body {name!r}: hinge {hinges[0].joint.name!r} before slide "
                                  f"{slides[0].joint.name!r} turns the slide's axis; this backend models a "
                                  "slide along a fixed direction")
    return "groove"


def _plan(scene: Scene) -> _Plan:
    """Check that pymunk can model `scene` and place every body in its initial state."""
    _check_scene(scene)
    layout = scene.layout
    bodies = _order(layout)
    joints_of: dict[str, list[Joint]] = {b.name: [] for b in bodies}
    for joint in layout.joints:
        if joint.body not in joints_of:
            raise ValueError(f"joint {joint.name!r} moves body {joint.body!r}, which the layout does not have")
        joints_of[joint.body].append(joint)

    plans: dict[str, _BodyPlan] = {}
    for body in bodies:
        parent = plans.get(body.parent)
        rot_p = np.eye(3) if parent is None else parent.rot0
        origin_p = np.zeros(3) if parent is None else parent.origin0
        rot0 = rot_p @ quat_to_matrix(np.array(body.quat))
        origin0 = origin_p + rot_p @ np.array(body.pos)
        plan = _BodyPlan(body, "", rot0, origin0)
        for joint in joints_of[body.name]:
            plan.joints.append(_joint_plan(joint, rot0, origin0))
        plan.kind = _classify(plan)
        com0 = origin0 + rot0 @ body.inertia.com
        plan.cog = _xz(rot0 @ body.inertia.com)
        plan.com_y = float(com0[1])
        if any(j.joint.kind == "hinge" for j in plan.joints):  # else the body does not turn: moment inf
            plan.moment = body.inertia.moment(rot0.T @ Y_AXIS)
            if not plan.moment > 0:
                raise NotImplementedError(f"body {body.name!r} turns about world y but has no moment about it")
        _initial_state(plan, parent)
        plans[body.name] = plan

    moving = [p for p in plans.values() if p.kind != "static"]
    line_mode = bool(moving) and all(
        p.kind == "groove" and len(p.joints) == 1 and abs(p.joints[0].axis[1]) <= AXIS_TOL for p in moving)
    if line_mode:
        for p in moving:
            p.kind = "line"

    sizes = [s for s in _contact_shape_sizes(layout) if s > 0]
    positions = [np.linalg.norm(p.origin0) for p in plans.values()]
    scale = max([1e-300] + sizes + positions)
    smallest = min(sizes) if sizes else scale
    speed = max([0.0] + [float(np.linalg.norm(p.velocity)) for p in plans.values()])
    reach = 10 * (scale + speed * scene.t_end + scene.gravity * scene.t_end**2)
    for shape in _all_shapes(layout):
        if shape.kind == "mesh":
            raise NotImplementedError(f"shape {shape.name!r} is a mesh: this backend draws primitives only")
    return _Plan(layout, list(plans.values()), line_mode, scale, smallest, reach)


def _joint_plan(joint: Joint, rot0: np.ndarray, origin0: np.ndarray) -> _JointPlan:
    direction = rot0 @ np.array(joint.axis)
    if joint.kind == "free":
        raise NotImplementedError(f"joint {joint.name!r} is free: pymunk is 2-D and cannot express 3-D rotation")
    if joint.kind == "hinge":
        if abs(abs(direction[1]) - 1.0) > AXIS_TOL:
            raise NotImplementedError(
                f"hinge {joint.name!r} turns about {direction.round(12).tolist()} in the world: pymunk turns "
                "bodies only about the normal of its plane (world y)")
        return _JointPlan(joint, sign=float(np.sign(direction[1])),
                          anchor=_xz(origin0 + rot0 @ np.array(joint.anchor)))
    if abs(direction[1]) > AXIS_TOL:
        raise NotImplementedError(
            f"slide {joint.name!r} moves along {direction.round(12).tolist()}, out of the x-z plane that pymunk models")
    axis = _xz(direction)
    return _JointPlan(joint, axis=axis / np.linalg.norm(axis))


def _initial_state(plan: _BodyPlan, parent: _BodyPlan | None) -> None:
    """Compose the parent's motion with the joints, in order (as MJCF: each joint acts in the frame the
    previous ones left), and add up the joint rates into the body's velocity at its centre of mass."""
    phi = 0.0 if parent is None else parent.phi
    tau = np.zeros(2) if parent is None else parent.tau.copy()
    omega = 0.0 if parent is None else parent.omega
    hinge_rates, slide_rates = [], []
    for jp in plan.joints:
        q, qd = float(jp.joint.qpos0), float(np.asarray(jp.joint.qvel0, dtype=float))
        if jp.joint.kind == "hinge":
            alpha = jp.sign * q
            anchor = _apply(phi, tau, jp.anchor)
            tau = _rot(phi) @ (jp.anchor - _rot(alpha) @ jp.anchor) + tau
            phi += alpha
            omega += jp.sign * qd
            hinge_rates.append((jp.sign * qd, anchor))
        else:
            w = _rot(phi) @ jp.axis
            tau = tau + q * w
            slide_rates.append(qd * w)
    plan.phi, plan.tau, plan.omega = phi, tau, omega
    plan.com = _apply(phi, tau, _xz(plan.origin0 + plan.rot0 @ plan.body.inertia.com))
    velocity = np.zeros(2)
    if parent is not None:
        velocity += parent.velocity + _cross_y(parent.omega, plan.com - parent.com)
    for rate, anchor in hinge_rates:
        velocity += _cross_y(rate, plan.com - anchor)
    for v in slide_rates:
        velocity += v
    plan.velocity = velocity


def _all_shapes(layout: Layout) -> list[Shape]:
    return list(layout.fixed) + [s for b in layout.bodies for s in b.shapes]


def _shape_size(shape: Shape) -> float:
    """Smallest dimension that matters in the plane [m] (0 for an unbounded plane)."""
    sizes = [s for s in shape.size if s > 0]
    return min(sizes) if sizes else 0.0


def _contact_shape_sizes(layout: Layout) -> list[float]:
    names = {n for c in layout.contacts for n in (c.shape_a, c.shape_b)}
    return [_shape_size(s) for s in _all_shapes(layout) if s.name in names and s.kind != "plane"]


# ----- check and run ----------------------------------------------------------------------------------------

def check(scene: Scene) -> None:
    """Raise NotImplementedError when pymunk cannot model `scene` (batches, 3-D rotation, joints or
    shapes without a planar counterpart), ValueError when `scene` is not a Scene."""
    _plan(scene)


def default_settings(scene: Scene) -> dict:
    """The settings run() uses when none are given: iterations 10 per constraint and contact pair
    (at least 10, pymunk's default), collision_slop 1e-6 of the smallest contact shape [m]."""
    plan = _plan(scene)
    return _defaults(plan)


def _defaults(plan: _Plan) -> dict:
    rows = sum(1 for p in plan.bodies if p.kind in ("pivot", "groove")) + len(plan.layout.contacts)
    return {"iterations": max(MIN_ITERATIONS, ITERATIONS_PER_ROW * rows),
            "collision_slop": SLOP_FRACTION * plan.smallest}


def run(scene: Scene, dt: float, t_end: float | None = None, *, iterations: int | None = None,
        collision_slop: float | None = None, save_every: int = 1) -> Trajectory:
    """Step `scene` in pymunk with step dt [s] until t_end [s] (default scene.t_end).

    iterations:     solver iterations per step (default: default_settings(scene))
    collision_slop: overlap pymunk leaves uncorrected [m] (default: default_settings(scene))
    save_every:     keep every n-th step (n >= 1)
    Returns a Trajectory with the scene's observables (scene.observe), plus for scenes with elastic
    contacts `collisions` (T,) (cumulative contact onsets over all pairs) and `ball_collisions` (T,)
    (over pairs of two moving bodies). meta: backend, scene, dt, settings, pymunk version, the model
    choices and step_seconds (the time spent in space.step only).
    Raises ValueError for bad arguments, NotImplementedError when pymunk cannot model the scene,
    SimulationError when the state becomes non-finite.
    """
    plan = _plan(scene)
    t_end = scene.t_end if t_end is None else float(finite_array(t_end, "t_end"))
    if not t_end > 0:
        raise ValueError(f"t_end={t_end!r}: must be > 0 [s]")
    dt = float(finite_array(dt, "dt"))
    if not 0 < dt <= t_end:
        raise ValueError(f"dt={dt!r}: must satisfy 0 < dt <= t_end={t_end} [s]")
    if not isinstance(save_every, (int, np.integer)) or isinstance(save_every, bool) or save_every < 1:
        raise ValueError(f"save_every={save_every!r}: expected a whole number >= 1")
    defaults = _defaults(plan)
    if iterations is None:
        iterations = defaults["iterations"]
    if not isinstance(iterations, (int, np.integer)) or isinstance(iterations, bool) or iterations < 1:
        raise ValueError(f"iterations={iterations!r}: expected a whole number >= 1")
    slop = defaults["collision_slop"] if collision_slop is None else float(nonnegative(collision_slop,
                                                                                         "collision_slop"))
    # Same number of steps as rbody.simulate: t_end/dt rounded up, then to a multiple of save_every.
    nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
    nsteps = -(-nsteps // save_every) * save_every

    space, pm_bodies, counter = _build(plan, scene.gravity, int(iterations), slop)
    nsave = nsteps // save_every + 1
    nb = len(plan.bodies)
    position, angle = np.empty((nsave, nb, 2)), np.empty((nsave, nb))
    velocity, angular = np.empty((nsave, nb, 2)), np.empty((nsave, nb))
    collisions = np.zeros(nsave, dtype=np.int64)
    ball_collisions = np.zeros(nsave, dtype=np.int64)

    def record(k: int) -> None:
        for i, b in enumerate(pm_bodies):
            position[k, i] = b.position
            angle[k, i] = b.angle
            velocity[k, i] = b.velocity
            angular[k, i] = b.angular_velocity
        collisions[k] = counter.total
        ball_collisions[k] = counter.bodies

    record(0)
    step = space.step
    seconds = 0.0
    for k in range(1, nsave):
        start = time.perf_counter()
        for _ in range(save_every):
            step(dt)
        seconds += time.perf_counter() - start
        record(k)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(velocity))
            and np.all(np.isfinite(angle)) and np.all(np.isfinite(angular))):
        bad = int(np.argmin(np.all(np.isfinite(position.reshape(nsave, -1)), axis=1)))
        raise SimulationError(f"scene {scene.describe()}: pymunk with dt={dt} gave a non-finite state by "
                              f"t={bad * save_every * dt:.6g} s; try a smaller dt or more iterations")

    t = np.arange(nsave) * (dt * save_every)
    states, joint_states = _observe_states(plan, position, angle, velocity, angular)
    data = dict(scene.observe(t, states, joint_states))
    if counter.elastic:
        data["collisions"] = collisions
        data["ball_collisions"] = ball_collisions
    meta = {"scene": scene.name, "backend": name, "dt": dt, "pymunk": pymunk.version,
            "settings": {"iterations": int(iterations), "collision_slop": slop, "save_every": int(save_every)},
            "model": {p.name: p.kind for p in plan.bodies}, "gravity_along_line_removed": plan.line_mode,
            "step_seconds": seconds}
    return Trajectory(t, data, meta=meta)


# ----- building the space -------------------------------------------------------------------------------------

class _Counter:
    """Contact onsets: over all pairs, and over pairs of two moving bodies."""

    def __init__(self) -> None:
        self.total = 0
        self.bodies = 0
        self.elastic = False

    def begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, between_bodies: bool) -> None:
        self.total += 1
        if between_bodies:
            self.bodies += 1


def _build(plan: _Plan, gravity: float, iterations: int, slop: float):
    space = pymunk.Space()
    space.gravity = (0.0, 0.0) if plan.line_mode else (0.0, -gravity)
    space.iterations = iterations
    space.collision_slop = slop
    static = space.static_body
    handles: dict[str, pymunk.Body] = {WORLD: static}
    pm_bodies = []
    shapes: dict[str, tuple[pymunk.Shape, bool]] = {}  # name -> (shape, on a moving body)

    for p in plan.bodies:
        if p.kind == "static":
            body = static
        else:
            body = pymunk.Body(p.body.inertia.mass, p.moment)
            body.center_of_gravity = tuple(p.cog)
            body.angle = -p.phi  # before the position: pymunk turns a body about its centre of mass
            body.position = tuple(_apply(p.phi, p.tau, _xz(p.origin0)))
            body.velocity = tuple(p.velocity)
            body.angular_velocity = -p.omega
            space.add(body)
        handles[p.name] = body
        pm_bodies.append(body)
        for shape in p.body.shapes:
            if p.kind == "static":  # world coordinates of the reference pose
                made = _shape(shape, p.rot0, p.origin0, static, plan, slop)
            else:
                made = _shape(shape, p.rot0, np.zeros(3), body, plan, slop)
            shapes[shape.name] = (made, p.kind != "static")
    for shape in plan.layout.fixed:
        shapes[shape.name] = (_shape(shape, np.eye(3), np.zeros(3), static, plan, slop), False)
    if len(shapes) != len(_all_shapes(plan.layout)):
        raise ValueError("layout has two shapes of the same name: contacts name shapes, so names must be unique")
    space.add(*(s for s, _moving in shapes.values()))

    for p in plan.bodies:
        _constrain(space, p, handles, plan)
    counter = _filter_contacts(space, plan.layout, shapes)
    return space, pm_bodies, counter


def _constrain(space: pymunk.Space, p: _BodyPlan, handles: dict, plan: _Plan) -> None:
    body, parent = handles[p.name], handles[p.parent]
    if p.kind == "pivot":
        hinge = p.joints[0]
        # the anchor's initial world position, from the parent's motion (or the world's, none)
        parent_plan = next((q for q in plan.bodies if q.name == p.parent), None)
        phi, tau = (0.0, np.zeros(2)) if parent_plan is None else (parent_plan.phi, parent_plan.tau)
        joint = pymunk.PivotJoint(parent, body, tuple(_apply(phi, tau, hinge.anchor)))
        joint.collide_bodies = False
        space.add(joint)
    elif p.kind == "groove":
        slide = next(j for j in p.joints if j.joint.kind == "slide")
        hinge = next((j for j in p.joints if j.joint.kind == "hinge"), None)
        local = p.cog if hinge is None else hinge.anchor - _xz(p.origin0)  # pivot, pymunk local
        point = np.asarray(body.local_to_world(tuple(local)))
        groove = pymunk.GrooveJoint(space.static_body, body, tuple(point - plan.reach * slide.axis),
                                    tuple(point + plan.reach * slide.axis), tuple(local))
        space.add(groove)


def _shape(shape: Shape, rot0: np.ndarray, origin0: np.ndarray, body: pymunk.Body, plan: _Plan,
           slop: float) -> pymunk.Shape:
    """The side view of `shape`, in `body`'s pymunk coordinates (world ones for the static body)."""
    rotation = rot0 @ quat_to_matrix(np.array(shape.quat))
    centre = _xz(origin0 + rot0 @ np.array(shape.pos))
    axis = rotation[:, 2]  # local z: cylinder and capsule axis, plane normal

    def along_y(v) -> bool:
        return abs(abs(v[1]) - 1.0) <= AXIS_TOL

    def across_y(v) -> bool:
        return abs(v[1]) <= AXIS_TOL

    if shape.kind == "sphere":
        return pymunk.Circle(body, shape.size[0], tuple(centre))
    if shape.kind in ("cylinder", "capsule"):
        radius, half = shape.size[0], shape.size[1]
        if along_y(axis):
            return pymunk.Circle(body, radius, tuple(centre))
        if across_y(axis):
            d = _xz(axis)
            if shape.kind == "capsule":
                return pymunk.Segment(body, tuple(centre - half * d), tuple(centre + half * d), radius)
            n = np.array([-d[1], d[0]])
            corners = [centre + sx * half * d + sy * radius * n for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
            return pymunk.Poly(body, [tuple(c) for c in corners])
    if shape.kind == "box":
        for k in range(3):
            if along_y(rotation[:, k]):
                i, j = [m for m in range(3) if m != k]
                a, b = shape.size[i] * _xz(rotation[:, i]), shape.size[j] * _xz(rotation[:, j])
                corners = [centre + a + b, centre - a + b, centre - a - b, centre + a - b]
                return pymunk.Poly(body, [tuple(c) for c in corners])
    if shape.kind == "plane" and across_y(axis):
        normal = _xz(axis)
        tangent = np.array([normal[1], -normal[0]])  # y x n in (x, z)
        half = 0.0
        for k, size in zip((0, 1), shape.size[:2]):
            if across_y(rotation[:, k]):
                half = size
        half = half if half > 0 else plan.reach
        thickness = PLANE_THICKNESS_FRACTION * plan.smallest
        # The surface stands slop/2 in front of the plane: pymunk sees a contact only where shapes overlap
        # and corrects only overlap beyond the slop, so a body resting on the plane touches it from t = 0
        # (exactly touching, it would fall freely for a step) and is not pushed off it.
        middle = centre - (thickness - slop / 2) * normal
        return pymunk.Segment(body, tuple(middle - half * tangent), tuple(middle + half * tangent), thickness)
    raise NotImplementedError(f"shape {shape.name!r} ({shape.kind}, local z along {axis.round(12).tolist()} in the "
                              "world) has no side view in pymunk's plane")


def _filter_contacts(space: pymunk.Space, layout: Layout, shapes: dict) -> _Counter:
    """Only the listed pairs collide; each pair gets its restitution and friction; onsets are counted."""
    names = []
    for contact in layout.contacts:
        for n in (contact.shape_a, contact.shape_b):
            if n not in shapes:
                raise ValueError(f"contact names shape {n!r}, which the layout does not have")
            if n not in names:
                names.append(n)
    if len(names) > MAX_CONTACT_SHAPES:
        raise NotImplementedError(f"{len(names)} shapes take part in contacts: pymunk's collision filter has "
                                  f"{MAX_CONTACT_SHAPES} categories")
    bit = {n: 1 << i for i, n in enumerate(names)}
    mask = dict.fromkeys(names, 0)
    for contact in layout.contacts:
        mask[contact.shape_a] |= bit[contact.shape_b]
        mask[contact.shape_b] |= bit[contact.shape_a]
    for n, (shape, _moving) in shapes.items():
        shape.filter = pymunk.ShapeFilter(categories=bit.get(n, 0), mask=mask.get(n, 0))
        shape.collision_type = names.index(n) + 1 if n in bit else 0

    # Per-shape factors whose products are the pairs' values: sqrt on both shapes works when all pairs
    # agree, or when no shape is in two pairs.
    values = {(c.restitution, c.friction) for c in layout.contacts}
    uses = {n: sum(n in (c.shape_a, c.shape_b) for c in layout.contacts) for n in names}
    factorable = len(values) <= 1 or max(uses.values(), default=0) <= 1
    for contact in layout.contacts:
        for n in (contact.shape_a, contact.shape_b):
            shapes[n][0].elasticity = math.sqrt(contact.restitution)
            shapes[n][0].friction = math.sqrt(contact.friction)

    counter = _Counter()
    counter.elastic = any(c.restitution > 0 for c in layout.contacts)
    for contact in layout.contacts:
        between_bodies = shapes[contact.shape_a][1] and shapes[contact.shape_b][1]
        kwargs = {}
        if counter.elastic:
            kwargs.update(begin=counter.begin, data=between_bodies)
        if not factorable:
            def pre_solve(arbiter, space, data, e=contact.restitution, mu=contact.friction):
                arbiter.restitution = e
                arbiter.friction = mu
            kwargs["pre_solve"] = pre_solve
        if kwargs:
            space.on_collision(names.index(contact.shape_a) + 1, names.index(contact.shape_b) + 1, **kwargs)
    return counter


# ----- back to the world ------------------------------------------------------------------------------------

def _observe_states(plan: _Plan, position, angle, velocity, angular):
    """BodyStates per body and (qpos, qvel) per hinge and slide joint from pymunk's history."""
    phi, omega = -angle, -angular                              # (T, nb): rotation about world +y
    cog = np.stack([p.cog for p in plan.bodies])                # (nb, 2)
    com = position + np.einsum("tbij,bj->tbi", _rot(phi), cog)  # pymunk local -> world (x, z)
    states, joints = {}, {}
    index = {p.name: i for i, p in enumerate(plan.bodies)}
    T = position.shape[0]
    for i, p in enumerate(plan.bodies):
        com3 = np.stack([com[:, i, 0], np.full(T, p.com_y), com[:, i, 1]], axis=1)
        vel3 = np.stack([velocity[:, i, 0], np.zeros(T), velocity[:, i, 1]], axis=1)
        omega3 = np.stack([np.zeros(T), omega[:, i], np.zeros(T)], axis=1)
        quat = quat_multiply(quat_from_axis_angle(Y_AXIS, phi[:, i]), quat_from_matrix(p.rot0))
        states[p.name] = BodyStates(com=com3, quat=quat, velocity=vel3, omega=omega3)
        if p.kind == "static":
            continue
        if p.kind == "pivot":
            hinge = p.joints[0]
            j = index.get(p.parent)
            phi_p = 0.0 if j is None else phi[:, j]
            omega_p = 0.0 if j is None else omega[:, j]
            joints[hinge.joint.name] = (hinge.sign * (phi[:, i] - phi_p), hinge.sign * (omega[:, i] - omega_p))
            continue
        joints.update(_slide_coordinates(p, phi[:, i], omega[:, i], position[:, i], com[:, i], velocity[:, i]))
    return states, joints


def _slide_coordinates(p: _BodyPlan, phi, omega, origin, com, velocity) -> dict:
    """Joint coordinates of a body on slides (and at most one hinge) to the world: replay the joints in
    order with the slides at zero, then solve for the displacements along the (turned) slide axes."""
    T = phi.shape[0]
    psi, tau0 = np.zeros(T), np.zeros((T, 2))
    axes, anchors, out = [], [], {}
    for jp in p.joints:
        if jp.joint.kind == "hinge":
            anchors.append((jp, psi.copy(), tau0.copy(), len(axes)))
            alpha = phi  # the one hinge carries all of the rotation
            tau0 = np.einsum("tij,j->ti", _rot(psi), jp.anchor) + tau0 - np.einsum(
                "tij,tj->ti", _rot(psi + alpha), np.broadcast_to(jp.anchor, (T, 2)))
            psi = psi + alpha
            out[jp.joint.name] = (jp.sign * phi, jp.sign * omega)
        else:
            axes.append((jp, np.einsum("tij,j->ti", _rot(psi), jp.axis)))
    tau = origin - np.einsum("tij,j->ti", _rot(phi), _xz(p.origin0))
    W = np.stack([w for _jp, w in axes], axis=-1)  # (T, 2, k)
    d = _solve(W, tau - tau0)
    # velocity of the centre of mass = hinge rate y x (com - anchor) + sum of slide rates along their axes
    rhs = velocity.copy()
    for jp, psi_h, tau_h, before in anchors:
        anchor = np.einsum("tij,j->ti", _rot(psi_h), jp.anchor) + tau_h
        for m in range(before):
            anchor = anchor + d[:, m, None] * W[:, :, m]
        rhs = rhs - _cross_y(omega, com - anchor)
    d_rate = _solve(W, rhs)
    for m, (jp, _w) in enumerate(axes):
        out[jp.joint.name] = (d[:, m], d_rate[:, m])
    return out


def _solve(W: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """(T, k) solution of W x = rhs for W (T, 2, k), k = 1 (projection) or 2."""
    if W.shape[-1] == 1:
        w = W[:, :, 0]
        return (np.sum(w * rhs, axis=1) / np.sum(w * w, axis=1))[:, None]
    return np.linalg.solve(W, rhs[:, :, None])[:, :, 0]
