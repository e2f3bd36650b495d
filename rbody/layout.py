"""The description of a model: shapes, bodies, joints, contacts, and the Layout that holds them.

This is the floor every other layer reads: the engine compiles a Layout (rbody.engine.multibody), the MJCF
exporter writes one (rbody.mjcf), the backends build one in MuJoCo and pymunk (validation.backends). Two
facts live here once, so that no layer computes them again:

- JOINTS, the one joint table: each kind's code in the compiled model, its qpos and qvel sizes (MuJoCo's
  nq and nv per joint) and its MJCF name;
- tree_order, the one body order: depth first from the world, children in the order the Layout lists them
  (MuJoCo's body ids 1, 2, ...); joint_order and coordinate addresses follow from it.

Units are SI; positions and axes of a body's parts are in its own frame; quaternions are (w, x, y, z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rbody.checks import finite_array, in_interval, nonnegative
from rbody.inertia import Inertia, unit_axis

WORLD = "world"

SHAPE_KINDS = ("sphere", "cylinder", "box", "capsule", "plane", "ellipsoid", "mesh", "hfield")


def _check_dry_friction(element, what: str) -> None:
    """A joint's or a tendon's frictionloss (>= 0, [N or N m]) and its stops' restitution (Newton's, in [0, 1]),
    checked and set as floats on the frozen `element`."""
    friction = finite_array(element.frictionloss, f"{what}: frictionloss", shape=())
    object.__setattr__(element, "frictionloss", float(nonnegative(friction, f"{what}: frictionloss")))
    restitution = finite_array(element.restitution, f"{what}: restitution", shape=())
    object.__setattr__(element, "restitution", float(in_interval(restitution, f"{what}: restitution", 0.0, 1.0,
                                                                 closed=True)))


@dataclass(frozen=True)
class Shape:
    """Collision and drawing geometry, in the frame of the body that carries it (or the world).

    kind:   one of SHAPE_KINDS
    size:   sphere (radius,); cylinder and capsule (radius, half_length) along the local z;
            box (half sizes x, y, z); plane (half sizes x, y, or 0 for infinite); ellipsoid (semi-axes x, y,
            z); mesh: (); hfield (sx, sy, sz, base): MuJoCo's height field over [-sx, sx] x [-sy, sy], its
            elevations scaled by sz, its base sz below 0 (a world-fixed shape only: Layout.fixed)
    pos:    (3,) centre of the shape [m]; quat: (4,) its orientation (w, x, y, z)
    mesh:   path of the mesh file for kind="mesh" (drawing; vertices in the shape's frame)
    vertices: (V, 3) points in the shape's frame [m] whose convex hull is a mesh shape's collision geometry (as
            MuJoCo collides a mesh by its convex hull; from_mjcf gives the hull's vertices, scaled as the file
            says); () for other kinds. A mesh shape in a Contact needs them.
    heights: (nrow, ncol) a height field's elevations in [0, 1] (MuJoCo's normalised data: vertex (r, c) at x =
            -sx + 2 sx c / (ncol - 1), y = -sy + 2 sy r / (nrow - 1), z = sz heights[r][c]), nrow, ncol >= 2;
            () for other kinds (rbody.engine.contacts.terrain collides it)
    """

    name: str
    kind: str
    size: tuple[float, ...] = ()
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    mesh: str | None = None
    vertices: tuple[tuple[float, float, float], ...] = ()
    heights: tuple[tuple[float, ...], ...] = ()

    def __post_init__(self) -> None:
        _name(self.name, "shape", "name")
        if self.kind not in SHAPE_KINDS:
            raise ValueError(f"shape {self.name!r}: kind={self.kind!r}, expected one of {SHAPE_KINDS}")
        if len(self.vertices):
            if self.kind != "mesh":
                raise ValueError(f"shape {self.name!r}: vertices are given for a {self.kind}: only a mesh shape has "
                                 "them")
            points = finite_array(self.vertices, f"shape {self.name!r}: vertices")
            if points.ndim != 2 or points.shape[1] != 3 or len(points) < 4:
                raise ValueError(f"shape {self.name!r}: vertices have shape {points.shape}: expected (V, 3) points "
                                 "[m], V >= 4 (a solid's convex hull)")
            object.__setattr__(self, "vertices", tuple(map(tuple, points.tolist())))
        if self.kind == "hfield" or len(self.heights):
            self._check_field()
        object.__setattr__(self, "size", tuple(float(s) for s in nonnegative(np.atleast_1d(self.size), "size")))
        object.__setattr__(self, "pos", tuple(finite_array(self.pos, "pos", shape=(3,)).tolist()))
        quat = finite_array(self.quat, "quat", shape=(4,))
        if np.linalg.norm(quat) == 0:
            raise ValueError(f"shape {self.name!r}: quat={quat.tolist()} must be non-zero")
        object.__setattr__(self, "quat", tuple((quat if already_unit(quat) else quat / np.linalg.norm(quat)).tolist()))


    def _check_field(self) -> None:
        """A height field's size (4 positive numbers) and heights ((nrow, ncol) >= 2 each, in [0, 1])."""
        if self.kind != "hfield":
            raise ValueError(f"shape {self.name!r}: heights are given for a {self.kind}: only a hfield shape has them")
        size = finite_array(self.size, f"shape {self.name!r}: size")
        if size.shape != (4,) or not np.all(size > 0):
            raise ValueError(f"shape {self.name!r}: a hfield's size={tuple(np.atleast_1d(size).tolist())!r}: expected "
                             "4 positive numbers (sx, sy, sz, base) [m]")
        heights = finite_array(self.heights, f"shape {self.name!r}: heights")
        if heights.ndim != 2 or heights.shape[0] < 2 or heights.shape[1] < 2:
            raise ValueError(f"shape {self.name!r}: heights of shape {heights.shape}: expected (nrow, ncol), each "
                             ">= 2")
        if heights.min() < 0.0 or heights.max() > 1.0:
            raise ValueError(f"shape {self.name!r}: heights span [{heights.min():g}, {heights.max():g}]: expected "
                             "values in [0, 1] (scaled by size[2], as MuJoCo's normalised elevation)")
        object.__setattr__(self, "heights", tuple(map(tuple, heights.tolist())))


@dataclass(frozen=True)
class Body:
    """A rigid body: its mass properties (body frame), its shapes, its parent and where it starts.

    pos (3,) [m] and quat (4,) place the body frame in the parent's frame in the reference pose,
    where every hinge and slide coordinate is zero (as MJCF's body pos/quat); the joints' qpos0 then
    set the initial state. A free body starts at pos/quat.
    gravcomp: the fraction of the body's weight that an upward force at its centre of mass cancels (MuJoCo's
    body gravcomp: 1 floats it; a passive force, or an actuator force on joints with actuatorgravcomp).
    """

    name: str
    inertia: Inertia
    shapes: tuple[Shape, ...] = ()
    parent: str = WORLD
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    gravcomp: float = 0.0

    def __post_init__(self) -> None:
        """Every field checked at construction (ValueError naming the body and the field), so that a wrong type
        never surfaces later as an AttributeError inside the engine; shapes, pos and quat kept as tuples."""
        _name(self.name, "body", "name")
        what = f"body {self.name!r}"
        if not isinstance(self.inertia, Inertia):
            raise ValueError(f"{what}: inertia={_short(self.inertia)} is a {type(self.inertia).__name__}: expected an "
                             "rbody.Inertia (mass, centre of mass and tensor, e.g. Inertia.rod(1.0, 0.5, 'z'))")
        object.__setattr__(self, "shapes", _items(self.shapes, Shape, f"{what}: shapes"))
        for shape in self.shapes:
            if shape.kind == "hfield":
                raise ValueError(f"{what}: shape {shape.name!r} is a hfield: a height field is world-fixed terrain "
                                 "(Layout.fixed), not a moving body's shape")
        _name(self.parent, what, "parent")
        object.__setattr__(self, "pos", tuple(finite_array(self.pos, f"{what}: pos", shape=(3,)).tolist()))
        quat = finite_array(self.quat, f"{what}: quat", shape=(4,))
        if not np.any(quat):
            raise ValueError(f"{what}: quat={quat.tolist()} must be non-zero (w, x, y, z)")
        object.__setattr__(self, "quat", tuple(quat.tolist()))


def _short(value: Any, limit: int = 80) -> str:
    """repr(value) cut to `limit` characters, for messages."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _name(value: Any, owner: str, field: str) -> str:
    """`value` checked to be a non-empty str (a name, or the name a field refers to)."""
    if not isinstance(value, str) or not value:
        raise ValueError(f"{owner}: {field}={_short(value)} ({type(value).__name__}): expected a non-empty str")
    return value


def _items(values: Any, kind: type, what: str) -> tuple:
    """`values` (a tuple or list) checked to hold only `kind`, as a tuple."""
    if isinstance(values, (str, bytes)) or not isinstance(values, (tuple, list)):
        raise ValueError(f"{what}={_short(values)} ({type(values).__name__}): expected a tuple of rbody.{kind.__name__}")
    for k, value in enumerate(values):
        if not isinstance(value, kind):
            raise ValueError(f"{what}[{k}]={_short(value)} is a {type(value).__name__}: expected an rbody.{kind.__name__}")
    return tuple(values)


def already_unit(vector: np.ndarray) -> bool:
    """True when |vector| is 1 to 2 eps, its squared norm summed exactly (math.fsum): such a vector is kept
    as given, since dividing it by a norm whose last bit depends on the CPU's SIMD kernels would change it,
    and every model exported from it, from one machine to another."""
    return abs(math.sqrt(math.fsum(float(v) * float(v) for v in vector)) - 1.0) <= 2 * np.finfo(float).eps


def _direction(axis) -> np.ndarray:
    """(3,) unit joint axis: unit_axis, except that an axis already unit is kept as given (already_unit)."""
    if not isinstance(axis, str):
        vector = finite_array(axis, "axis", shape=(3,))
        if already_unit(vector):
            return vector
    return unit_axis(axis, "axis")


@dataclass(frozen=True)
class JointKind:
    """One row of the joint table: a kind's code in the compiled model, its sizes and its MJCF name.

    nq: coordinates in qpos (hinge, slide, roll 1; ball 4, a quaternion; free 7, position and quaternion)
    nv: degrees of freedom in qvel (ball 3, free 6)
    scalar: one coordinate whose displacement is q - ref (hinge, slide, roll)
    mjcf: the element's type in MJCF, or None where rbody writes the kind as several MJCF joints (a roll
          joint: a slide and a hinge tied by a joint equality, rbody.mjcf.export)
    """

    name: str
    code: int
    nq: int
    nv: int
    scalar: bool
    mjcf: str | None


JOINTS: dict[str, JointKind] = {kind.name: kind for kind in (
    JointKind("hinge", 0, 1, 1, True, "hinge"),
    JointKind("slide", 1, 1, 1, True, "slide"),
    JointKind("ball", 2, 4, 3, False, "ball"),
    JointKind("free", 3, 7, 6, False, "free"),
    JointKind("roll", 4, 1, 1, True, None),
)}
JOINT_KINDS = tuple(JOINTS)
ROLL_PERPENDICULAR_TOL = 1e-9  # |axis . normal| of a roll joint above this: the two are not perpendicular


@dataclass(frozen=True)
class Joint:
    """A joint between `body` and its parent.

    kind:   "hinge" (angle about axis through anchor), "slide" (distance along axis), "ball" (any
            rotation about anchor), "free", "roll" (a round body of radius `radius` rolling without slipping
            on a line: one coordinate, the angle turned about `axis` through anchor, the body's centre)
    axis:   (3,) direction in the body frame; anchor: (3,) point in the body frame [m]
    qpos0, qvel0: initial coordinate [rad or m] and rate [rad/s or m/s] (hinge and slide);
            ball: qpos0 a quaternion (w, x, y, z) (0.0: identity), qvel0 (3,) the angular velocity in
            the BODY frame [rad/s] (MuJoCo's ball qvel; 0.0: at rest);
            free joints start from the body's pos/quat with qvel0 = (v (3,) of the body-frame origin,
            omega (3,)), both in the world frame.
    damping [N m s/rad or N s/m], stiffness [N m/rad or N/m], springref [rad or m], armature
    [kg m^2 or kg], ref [rad or m]: MJCF's joint attributes of the same names. Passive force
    -stiffness (q - springref) - damping qvel (stiffness on hinge and slide only); armature adds to the
    diagonal of the mass matrix; ref is the coordinate at which the body sits at its reference pose
    (the displacement applied is q - ref).
    A hinge turns the body by +angle about `axis` (right-handed); a slide moves it by +distance along
    `axis`; several joints on one body compose in the order given (as MJCF). Backends report hinge,
    slide and roll joints as (qpos (T,), qvel (T,)) under the joint's name.
    roll:   radius a [m] > 0 and normal e (3,), the unit normal of the surface rolled on, pointing from the
            contact point to the centre, body frame, perpendicular to `axis`. The body first slides by
            a (q - ref) along l = axis x normal, then turns by q - ref about `axis` through anchor: the
            contact point anchor - a e is at rest (v_centre = a q' l). Exported to MJCF as a slide and a
            hinge tied by a joint equality.
    Constraints (rbody.engine.constraints; rigid: they hold to round-off, MuJoCo's solref/solimp do not apply):
    range:  None (no limit), or (lo, hi) with lo < hi: hinge, slide and roll keep lo <= qpos <= hi [rad or m]
            (qpos itself, not q - ref, as MJCF's range); ball: (0, theta_max), the rotation angle of the joint's
            quaternion stays <= theta_max [rad], 0 < theta_max <= pi (MJCF's ball range, whose first number is
            ignored). A free joint has no range.
    frictionloss: dry friction of each degree of freedom [N m or N], MJCF's frictionloss: a degree of freedom
            at rest sticks while the force needed to hold it stays within frictionloss, else slides against a
            force of exactly frictionloss (Coulomb's law per degree of freedom, no smoothing).
    restitution: Newton's coefficient e in [0, 1] of an impact on the joint's limit: the joint leaves its stop
            at e times the speed it hit it with (0: it stays at the stop, the rigid limit of MuJoCo's critically
            damped limit; 1: elastic).
    actuatorgravcomp: the gravity compensation of the bodies it moves reaches this joint as an actuator force
            (MuJoCo's qfrc_actuator, subject to actuatorfrcrange) instead of a passive one.
    actuatorfrcrange: (low, high) [N or N m] the clamp of the actuators' total generalised force on the joint's
            (first) degree of freedom (MuJoCo's actuatorfrcrange), or None.
    """

    name: str
    kind: str
    body: str
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    anchor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    qpos0: Any = 0.0
    qvel0: Any = 0.0
    damping: float = 0.0
    stiffness: float = 0.0
    springref: float = 0.0
    armature: float = 0.0
    ref: float = 0.0
    radius: float = 0.0
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    range: tuple[float, float] | None = None
    frictionloss: float = 0.0
    restitution: float = 0.0
    actuatorgravcomp: bool = False
    actuatorfrcrange: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        _name(self.name, "joint", "name")
        _name(self.body, f"joint {self.name!r}", "body")
        object.__setattr__(self, "actuatorgravcomp", bool(self.actuatorgravcomp))
        object.__setattr__(self, "actuatorfrcrange", _range(self.actuatorfrcrange,
                                                            f"joint {self.name!r}: actuatorfrcrange"))
        if self.kind not in JOINT_KINDS:
            raise ValueError(f"joint {self.name!r}: kind={self.kind!r}, expected one of {JOINT_KINDS}")
        self._check_constraints()
        object.__setattr__(self, "axis", tuple(_direction(self.axis).tolist()))
        object.__setattr__(self, "normal", tuple(_direction(self.normal).tolist()))
        radius = float(finite_array(self.radius, f"joint {self.name!r}: radius", shape=()))
        object.__setattr__(self, "radius", radius)
        if self.kind == "roll":
            if not radius > 0:
                raise ValueError(f"joint {self.name!r}: radius={self.radius!r}: a roll joint needs a rolling radius > 0 [m]")
            if abs(float(np.dot(self.axis, self.normal))) > ROLL_PERPENDICULAR_TOL:
                raise ValueError(f"joint {self.name!r}: axis={self.axis!r} and normal={self.normal!r} are not "
                                 "perpendicular: a roll joint turns about an axis lying in the surface it rolls on")
        elif radius != 0.0:
            raise ValueError(f"joint {self.name!r}: radius={self.radius!r} is only for roll joints (kind={self.kind!r})")
        for name in ("damping", "stiffness", "armature"):
            value = finite_array(getattr(self, name), f"joint {self.name!r}: {name}", shape=())
            object.__setattr__(self, name, float(nonnegative(value, f"joint {self.name!r}: {name}")))
        for name in ("springref", "ref"):
            object.__setattr__(self, name, float(finite_array(getattr(self, name), f"joint {self.name!r}: {name}",
                                                              shape=())))

    def _check_constraints(self) -> None:
        """range, frictionloss and restitution (the class docstring), each checked and stored as plain floats."""
        what = f"joint {self.name!r}"
        if self.range is not None:
            bounds = finite_array(self.range, f"{what}: range", shape=(2,))
            low, high = float(bounds[0]), float(bounds[1])
            if self.kind == "free":
                raise ValueError(f"{what}: range={self.range!r}: a free joint has no range (MuJoCo's rule)")
            if self.kind == "ball":
                if low != 0.0 or not 0.0 < high <= math.pi:
                    raise ValueError(f"{what}: range={self.range!r}: a ball joint's range is (0, theta_max) with 0 < "
                                     "theta_max <= pi, the largest rotation angle [rad]")
            elif not low < high:
                raise ValueError(f"{what}: range={self.range!r}: expected (lo, hi) with lo < hi")
            object.__setattr__(self, "range", (low, high))
        _check_dry_friction(self, what)

    @property
    def line(self) -> np.ndarray:
        """(3,) unit l = axis x normal, body frame: the direction a roll joint's centre moves for q' > 0 (roll
        joints only: their axis and normal are perpendicular)."""
        line = np.cross(self.axis, self.normal)
        return line / np.linalg.norm(line)


@dataclass(frozen=True)
class Contact:
    """Two pieces of geometry that may touch: shape names (world shapes or body shapes).

    friction [-] is the Coulomb coefficient of the pair; restitution in [0, 1] the coefficient of
    restitution of the pair (Newton's: 1 elastic, 0 plastic, the default); condim 3 (Coulomb's circular cone), 1
    (frictionless), 4 (and torsional friction: the torque about the normal |T_s| <= torsion N, torsion [m]) or 6 (and
    rolling friction: the torque about the tangents |T_r| <= rolling N, rolling [m]); MuJoCo's friction="friction
    torsion rolling" and condim. Each law is Coulomb's, against its own velocity, sharing the normal force N
    (rbody.engine.constraints.cone). margin [m] >= 0: the surfaces are held this far apart, each pair's distance
    >= margin (MuJoCo's margin since 3.9, the geometric inflation of the surfaces; 0 by default: they touch). Pairs
    not listed never collide. In a tree (Scene.from_layout) the constraint layer holds them rigidly
    (rbody.engine.constraints; the pairs rbody.engine.contacts.geometry computes).
    """

    shape_a: str
    shape_b: str
    friction: float = 0.0
    restitution: float = 0.0
    condim: int = 3
    torsion: float = 0.0
    rolling: float = 0.0
    margin: float = 0.0

    def __post_init__(self) -> None:
        _name(self.shape_a, "contact", "shape_a")
        _name(self.shape_b, "contact", "shape_b")
        nonnegative(self.friction, "friction")
        nonnegative(self.margin, "margin")
        nonnegative(self.torsion, "torsion")
        nonnegative(self.rolling, "rolling")
        in_interval(self.restitution, "restitution", 0.0, 1.0, closed=True)
        if isinstance(self.condim, bool) or self.condim not in (1, 3, 4, 6):
            raise ValueError(f"contact {self.shape_a!r}/{self.shape_b!r}: condim={self.condim!r}, expected 1 "
                             "(frictionless), 3 (Coulomb's cone), 4 (and torsional friction) or 6 (and rolling "
                             "friction)")


EQUALITY_KINDS = ("connect", "weld", "joint", "tendon")


@dataclass(frozen=True)
class Equality:
    """An equality constraint (MJCF's <equality>), held rigidly: to round-off, never by a spring.

    kind "connect": a point of body1 stays on a point of body2 (a ball joint closing a loop). anchor (3,) the
            point in body1's frame [m]; anchor2 (3,) the same point in body2's frame, or None: where `anchor`
            sits at the reference pose (every scalar joint at its ref, balls at identity, free bodies at their
            pos/quat: MuJoCo's qpos0), as MuJoCo computes it.
    kind "weld": body1 is fixed to body2 (position and orientation). anchor (3,) a point of body2, its frame
            [m] (MuJoCo's weld anchor); relpose None (the relative pose at the reference pose) or (x, y, z, w, qx,
            qy, qz): the anchor's position in body1's frame [m] and body2's orientation relative to body1's
            (q1 (x) quat = q2), MuJoCo's relpose.
    kind "joint": qpos[joint1] - ref1 = c0 + c1 d + c2 d^2 + c3 d^3 + c4 d^4, d = qpos[joint2] - ref2, with
            polycoef (c0, ..., c4) [m or rad, then per unit]; joint2 None: qpos[joint1] - ref1 = c0. Hinge,
            slide and roll joints (ref: the joint's ref, MuJoCo's qpos0).
    kind "tendon": L1 - L1_0 = c0 + c1 d + c2 d^2 + c3 d^3 + c4 d^4, d = L2 - L2_0, L1 and L2 the lengths of
            tendons tendon1 and tendon2 and L1_0, L2_0 their lengths at the reference pose (MuJoCo's qpos0 and
            tendon_length0); tendon2 None: L1 - L1_0 = c0 (MuJoCo's convention, engine_core_constraint.c).
    body2 defaults to the world. active False: the constraint is declared but does nothing (MJCF's active).
    Constraint forces are reported per equality (rbody.engine.constraints): connect 3 rows (force on body1,
    world frame [N]), weld 6 (force [N], then moment [N m], world frame), joint 1 (generalised force on joint1), tendon
    1 (force along tendon1).
    """

    name: str
    kind: str
    body1: str | None = None
    body2: str = WORLD
    anchor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    anchor2: tuple[float, float, float] | None = None
    relpose: tuple[float, ...] | None = None
    joint1: str | None = None
    joint2: str | None = None
    tendon1: str | None = None
    tendon2: str | None = None
    polycoef: tuple[float, float, float, float, float] = (0.0, 1.0, 0.0, 0.0, 0.0)
    active: bool = True

    def __post_init__(self) -> None:
        what = f"equality {self.name!r}"
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"equality name={self.name!r}: expected a non-empty string")
        if self.kind not in EQUALITY_KINDS:
            raise ValueError(f"{what}: kind={self.kind!r}, expected one of {EQUALITY_KINDS}")
        object.__setattr__(self, "anchor", tuple(finite_array(self.anchor, f"{what}: anchor", shape=(3,)).tolist()))
        if self.anchor2 is not None:
            object.__setattr__(self, "anchor2", tuple(finite_array(self.anchor2, f"{what}: anchor2",
                                                                   shape=(3,)).tolist()))
        if self.relpose is not None:
            pose = finite_array(self.relpose, f"{what}: relpose", shape=(7,))
            if np.linalg.norm(pose[3:]) == 0:
                raise ValueError(f"{what}: relpose={self.relpose!r}: its quaternion (last four numbers) is zero")
            pose[3:] = pose[3:] / np.linalg.norm(pose[3:])
            object.__setattr__(self, "relpose", tuple(pose.tolist()))
        coefficients = finite_array(self.polycoef, f"{what}: polycoef", shape=(5,))
        object.__setattr__(self, "polycoef", tuple(coefficients.tolist()))
        object.__setattr__(self, "active", bool(self.active))
        needs = {"connect": ("body1",), "weld": ("body1",), "joint": ("joint1",), "tendon": ("tendon1",)}[self.kind]
        for field_name in needs:
            if not getattr(self, field_name):
                raise ValueError(f"{what}: a {self.kind} equality needs {field_name}")
        if self.kind in ("connect", "weld") and self.body1 == self.body2:
            raise ValueError(f"{what}: body1 and body2 are both {self.body1!r}: a {self.kind} joins two bodies")
        if self.kind == "joint" and self.joint1 == self.joint2:
            raise ValueError(f"{what}: joint1 and joint2 are both {self.joint1!r}")
        if self.kind == "tendon" and self.tendon1 == self.tendon2:
            raise ValueError(f"{what}: tendon1 and tendon2 are both {self.tendon1!r}")


TENDON_KINDS = ("fixed", "spatial")


@dataclass(frozen=True)
class Tendon:
    """A tendon: a length L(q) that springs, dampers and actuators act along (MuJoCo's <tendon>).

    kind:    "fixed": L = sum coef_i q_i over `joints`, ((joint name, coef), ...), hinge and slide joints only
             (MuJoCo's <fixed>: q itself, not q - ref);
             "spatial": the length of the straight path through `sites`, ((body name or "world", point (3,) in
             that body's frame [m]), ...), at least two (MuJoCo's <spatial> with sites only, no wrapping)
    stiffness [N/m], damping [N s/m]: passive force along the tendon -stiffness x - damping L', x the distance
             of L outside [springlength[0], springlength[1]] (a dead band; equal ends: a plain spring);
             springlength None: both ends at the length in the reference pose at the joints' springref
             (MuJoCo's springlength="-1 -1")
    range:   None, or (lower, upper) with lower < upper: the tendon's length is held within it rigidly (a unilateral
             constraint of the constraint layer on each side, rbody.engine.constraints: a rope that goes taut at
             its upper end, a fixed tendon coupling joints to a stop) [m, or the units of L]
    frictionloss: dry friction along the tendon [N, or the units of force dual to L], >= 0: the tendon sticks
             while the force it needs stays within it, and slides against it otherwise (Coulomb)
    restitution: Newton's coefficient e in [0, 1] of an impact on the tendon's range (0: it stays at its limit)
    Units: L in m for a spatial tendon, in the units of coef * q for a fixed one.
    """

    name: str
    kind: str = "fixed"
    joints: tuple[tuple[str, float], ...] = ()
    sites: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    stiffness: float = 0.0
    damping: float = 0.0
    springlength: tuple[float, float] | None = None
    range: tuple[float, float] | None = None
    frictionloss: float = 0.0
    restitution: float = 0.0

    def __post_init__(self) -> None:
        what = f"tendon {self.name!r}"
        if self.kind not in TENDON_KINDS:
            raise ValueError(f"{what}: kind={self.kind!r}, expected one of {TENDON_KINDS}")
        joints = tuple((str(name), float(finite_array(coef, f"{what}: coef of joint {name!r}", shape=())))
                       for name, coef in self.joints)
        sites = tuple((str(body), tuple(finite_array(point, f"{what}: site point on {body!r}", shape=(3,)).tolist()))
                      for body, point in self.sites)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "sites", sites)
        if self.kind == "fixed" and (not joints or sites):
            raise ValueError(f"{what}: a fixed tendon needs joints=((joint, coef), ...) and no sites")
        if self.kind == "spatial" and (len(sites) < 2 or joints):
            raise ValueError(f"{what}: a spatial tendon needs at least two sites=((body, point), ...) and no joints")
        for name in ("stiffness", "damping"):
            value = finite_array(getattr(self, name), f"{what}: {name}", shape=())
            object.__setattr__(self, name, float(nonnegative(value, f"{what}: {name}")))
        if self.springlength is not None:
            low, high = finite_array(self.springlength, f"{what}: springlength", shape=(2,)).tolist()
            if low > high:
                raise ValueError(f"{what}: springlength={self.springlength!r}: expected (low, high) with low <= high")
            object.__setattr__(self, "springlength", (low, high))
        if self.range is not None:
            low, high = finite_array(self.range, f"{what}: range", shape=(2,)).tolist()
            if not low < high:
                raise ValueError(f"{what}: range={self.range!r}: expected (lower, upper) with lower < upper")
            object.__setattr__(self, "range", (low, high))
        _check_dry_friction(self, what)


ACTUATOR_DYNAMICS = ("none", "integrator", "filter", "filterexact")
ACTUATOR_GAINS = ("fixed", "affine")
ACTUATOR_BIASES = ("none", "affine")
TRANSMISSIONS = ("joint", "tendon", "site")


def _range(value, what: str) -> tuple[float, float] | None:
    if value is None:
        return None
    low, high = finite_array(value, what, shape=(2,)).tolist()
    if not low <= high:
        raise ValueError(f"{what}={value!r}: expected (low, high) with low <= high")
    return (low, high)


@dataclass(frozen=True)
class Actuator:
    """MuJoCo's general actuator (its XML reference, <general>; engine_forward.c mj_fwdActuation).

    One control u [-] per actuator. The force along the transmission (N or N m) is
        force = gain * (u, or the activation act where dynamics != "none") + bias,
        gain  = gainprm[0]                                   ("fixed")
              = gainprm[0] + gainprm[1] L + gainprm[2] L'    ("affine")
        bias  = 0 ("none") or biasprm[0] + biasprm[1] L + biasprm[2] L' ("affine"),
    clamped to forcerange, with u first clamped to ctrlrange. L is the actuator length: gear[0] q for a hinge
    or slide (q itself, not q - ref), gear . (the rotation vector of the ball's quaternion) for a ball, 0 for a
    free joint, gear[0] times the tendon length for a tendon, 0 for a site; L' = moment . qvel. The generalised
    force is moment^T force, the moment being gear[0] (hinge, slide, tendon: times the tendon's coefficients),
    gear[:3] (ball: body-frame torque), gear (free: world force, then body-frame torque), and for a site
    (transmission "site": target the body, `site` = (pos (3), quat (4)) the site's frame in it) the wrench of force
    gear[:3] and torque gear[3:] in the site's axes, applied at the site (MuJoCo's site transmission without refsite).
    Activation dynamics, act' = u ("integrator"), (u - act) / dynprm ("filter", "filterexact": the same
    equation; MuJoCo's own integrators advance "filterexact" by its exact solution over a step), clamped to
    actrange after every step. actearly: the force uses the activation at the end of the step, act + h act'
    (clamped; MuJoCo's rule), h the run's time step.
    ctrlrange, forcerange, actrange: (low, high), or None for no limit (MuJoCo's ctrllimited="false").
    disabled: the actuator applies no force and its activation stays (MuJoCo's <flag actuation="disable"/>
    and actuatorgroupdisable).
    """

    name: str
    target: str
    transmission: str = "joint"
    gear: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dynamics: str = "none"
    dynprm: float = 1.0
    gain: str = "fixed"
    gainprm: tuple[float, float, float] = (1.0, 0.0, 0.0)
    bias: str = "none"
    biasprm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ctrlrange: tuple[float, float] | None = None
    forcerange: tuple[float, float] | None = None
    actrange: tuple[float, float] | None = None
    actearly: bool = False
    disabled: bool = False
    site: tuple | None = None

    def __post_init__(self) -> None:
        what = f"actuator {self.name!r}"
        if (self.transmission == "site") != (self.site is not None):
            raise ValueError(f"{what}: a site transmission needs site=(pos (3), quat (4)) in the target body's frame, "
                             "and only it")
        if self.site is not None:
            pos = finite_array(self.site[0], f"{what}: site pos", shape=(3,))
            quat = finite_array(self.site[1], f"{what}: site quat", shape=(4,))
            if np.linalg.norm(quat) == 0:
                raise ValueError(f"{what}: site quat {quat.tolist()} must be non-zero")
            object.__setattr__(self, "site", (tuple(pos.tolist()), tuple((quat / np.linalg.norm(quat)).tolist())))
        for field_name, choices in (("transmission", TRANSMISSIONS), ("dynamics", ACTUATOR_DYNAMICS),
                                    ("gain", ACTUATOR_GAINS), ("bias", ACTUATOR_BIASES)):
            if getattr(self, field_name) not in choices:
                raise ValueError(f"{what}: {field_name}={getattr(self, field_name)!r}, expected one of {choices}")
        gear = finite_array(self.gear, f"{what}: gear", ndim=1)
        if gear.size > 6 or gear.size == 0:
            raise ValueError(f"{what}: gear={self.gear!r}: expected 1 to 6 numbers")
        object.__setattr__(self, "gear", tuple(np.concatenate([gear, np.zeros(6 - gear.size)]).tolist()))
        for field_name in ("gainprm", "biasprm"):
            values = finite_array(getattr(self, field_name), f"{what}: {field_name}", ndim=1)
            if values.size > 3:
                if np.any(values[3:] != 0):
                    raise ValueError(f"{what}: {field_name}={getattr(self, field_name)!r}: only the first three "
                                     "(const, kp, kv) are read by fixed and affine gains and biases")
                values = values[:3]
            object.__setattr__(self, field_name, tuple(np.concatenate([values, np.zeros(3 - values.size)]).tolist()))
        dynprm = float(finite_array(self.dynprm, f"{what}: dynprm (time constant)", shape=()))
        if self.dynamics in ("filter", "filterexact") and not dynprm >= 0:
            raise ValueError(f"{what}: dynprm={self.dynprm!r}: a filter's time constant must be >= 0 [s]")
        object.__setattr__(self, "dynprm", dynprm)
        for field_name in ("ctrlrange", "forcerange", "actrange"):
            object.__setattr__(self, field_name, _range(getattr(self, field_name), f"{what}: {field_name}"))
        object.__setattr__(self, "actearly", bool(self.actearly))
        object.__setattr__(self, "disabled", bool(self.disabled))

    @property
    def stateful(self) -> bool:
        """True when the actuator has an activation state (dynamics other than "none")."""
        return self.dynamics != "none"


FLUID_COEFFICIENTS = (0.5, 0.25, 1.5, 1.0, 1.0)  # MuJoCo's fluidcoef: blunt, slender, angular drag, Kutta, Magnus


@dataclass(frozen=True)
class FluidBox:
    """A body under MuJoCo's inertia-box fluid model: the box of its mass with its principal moments, axes `axes`
    (4,) (the quaternion of its principal axes in the body frame, MuJoCo's body_iquat; which axes matter where two
    moments are equal)."""

    body: str
    axes: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class FluidEllipsoid:
    """A geom under MuJoCo's ellipsoid fluid model (fluidshape="ellipsoid"): frame pos (3,) [m], quat (4,) in its
    body's frame; semiaxes (3,) [m]; coefficients (blunt drag, slender drag, angular drag, Kutta lift, Magnus
    lift) (MJCF's fluidcoef); virtual_mass (3,) [m^3] and virtual_inertia (3,) [m^5] the added-mass factors (times
    the density), as MuJoCo's compiler forms them from the semiaxes (rbody.mjcf.fluid)."""

    body: str
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    semiaxes: tuple[float, float, float]
    virtual_mass: tuple[float, float, float]
    virtual_inertia: tuple[float, float, float]
    coefficients: tuple[float, float, float, float, float] = FLUID_COEFFICIENTS


@dataclass(frozen=True)
class Fluid:
    """MuJoCo's fluid forces (<option density viscosity wind>, engine_passive.c mj_fluid): a passive force on every
    body of `boxes` (the inertia-box model: linear viscous and quadratic drag forces and torques of the box of its
    inertia) and every geom of `ellipsoids` (added mass, viscous and quadratic drag, Kutta and Magnus lift).
    density [kg/m^3], viscosity [Pa s], wind (3,) [m/s] the fluid's velocity (world frame)."""

    density: float = 0.0
    viscosity: float = 0.0
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    boxes: tuple[FluidBox, ...] = ()
    ellipsoids: tuple[FluidEllipsoid, ...] = ()

    def __post_init__(self) -> None:
        for name in ("density", "viscosity"):
            value = finite_array(getattr(self, name), f"fluid {name}", shape=())
            object.__setattr__(self, name, float(nonnegative(value, f"fluid {name}")))
        object.__setattr__(self, "wind", tuple(finite_array(self.wind, "fluid wind", shape=(3,)).tolist()))


@dataclass(frozen=True)
class Layout:
    """The physical model of an unbatched scene: what MuJoCo, pymunk and the MJCF exporter build.

    equalities: equality constraints (Equality) closing loops and coupling joints; joints carry their own
    limits and dry friction (Joint.range, Joint.frictionloss). Both default to none, the tree alone.
    tendons and actuators: MuJoCo's tendons and general actuators, in MuJoCo's order (the controls u of a run
    follow the order of `actuators`; the activations that of the actuators with dynamics).
    fluid: MuJoCo's fluid forces (Fluid), or None.
    """

    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    fixed: tuple[Shape, ...] = ()
    contacts: tuple[Contact, ...] = ()
    equalities: tuple[Equality, ...] = ()
    tendons: tuple[Tendon, ...] = ()
    actuators: tuple[Actuator, ...] = ()
    fluid: Fluid | None = None

    @property
    def joint_constraints(self) -> bool:
        """True when a joint or a tendon has a range or frictionloss or an equality is active (the constraints
        between joints, tendons and bodies, contacts aside)."""
        return (any(j.range is not None or j.frictionloss > 0 for j in self.joints)
                or any(t.range is not None or t.frictionloss > 0 for t in self.tendons)
                or any(e.active for e in self.equalities))

    @property
    def constrained(self) -> bool:
        """True when a joint or a tendon has a range or frictionloss, an equality is active or contacts are listed:
        the model then runs through the constraint layer (rbody.engine.constraints)."""
        return self.joint_constraints or bool(self.contacts)

    def __post_init__(self) -> None:
        """Each field checked to be a tuple (or list) of its kind (ValueError naming the field and the item)."""
        for field, kind in (("bodies", Body), ("joints", Joint), ("fixed", Shape), ("contacts", Contact),
                            ("equalities", Equality), ("tendons", Tendon), ("actuators", Actuator)):
            object.__setattr__(self, field, _items(getattr(self, field), kind, f"Layout {field}"))
        if self.fluid is not None and not isinstance(self.fluid, Fluid):
            raise ValueError(f"Layout fluid={_short(self.fluid)} is a {type(self.fluid).__name__}: expected an "
                             "rbody.layout.Fluid or None")


# ----- the one tree order ------------------------------------------------------------------------------

def depth_first(layout: Layout) -> tuple[Body, ...]:
    """The bodies reached from the world, depth first, children in layout order (MuJoCo's body ids 1, 2, ...),
    without checks: a body whose parent is missing, or that sits on a cycle, is simply not reached."""
    children: dict[str, list[Body]] = {}
    for body in layout.bodies:
        children.setdefault(body.parent, []).append(body)
    order: list[Body] = []
    stack = list(reversed(children.get(WORLD, [])))
    while stack:
        body = stack.pop()
        order.append(body)
        stack.extend(reversed(children.get(body.name, [])))
    return tuple(order)


def tree_order(layout: Layout) -> tuple[Body, ...]:
    """Bodies depth first from the world, children in layout order (MuJoCo's body ids 1, 2, ...): the order of
    the engine's bodies, of the exported MJCF and of every backend. Raises ValueError for a body called "world",
    repeated names, a parent that is no body, or a cycle."""
    names = [body.name for body in layout.bodies]
    if WORLD in names:
        raise ValueError(f"a body is called {WORLD!r}: that name is the fixed world")
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise ValueError(f"two bodies are called {name!r}: body names must be unique")
        seen.add(name)
    for body in layout.bodies:
        if body.parent != WORLD and body.parent not in seen:
            raise ValueError(f"body {body.name!r}: parent={body.parent!r} is neither {WORLD!r} nor a body of the "
                             "layout")
    order = depth_first(layout)
    if len(order) != len(names):
        lost = sorted(seen - {b.name for b in order})
        raise ValueError(f"bodies {lost} are not reached from the world: their parents form a cycle")
    return order


def joint_order(layout: Layout) -> tuple[Joint, ...]:
    """Joints in MuJoCo's order (their qpos and qvel addresses follow it): by body in tree order, then in the
    order the layout lists a body's joints."""
    by_body: dict[str, list[Joint]] = {}
    for joint in layout.joints:
        by_body.setdefault(joint.body, []).append(joint)
    return tuple(j for body in depth_first(layout) for j in by_body.get(body.name, ()))


def coordinate_addresses(joints: tuple[Joint, ...]) -> tuple[tuple[int, ...], tuple[int, ...], int, int]:
    """(qposadr, dofadr, nq, nv) of joints in joint_order: where each joint's coordinates start in qpos and in
    qvel, and the totals (the JOINTS table's sizes, summed in order)."""
    qposadr, dofadr, nq, nv = [], [], 0, 0
    for joint in joints:
        qposadr.append(nq)
        dofadr.append(nv)
        nq += JOINTS[joint.kind].nq
        nv += JOINTS[joint.kind].nv
    return tuple(qposadr), tuple(dofadr), nq, nv
