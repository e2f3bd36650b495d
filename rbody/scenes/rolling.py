"""A round body on an incline: rolling without slipping, sliding, and the chapter's race.

A body of mass M, radius a and moment I about its rolling axis (through the centre of mass) starts
from rest on a slope of angle alpha. x is the distance of the centre down the slope, phi the spin
angle (positive when rolling down), k = I / (M a^2).

Rolling (the chapter's rolling disc). Friction at the contact point does no work, so
E = 1/2 (I/a^2 + M) x'^2 - M g x sin(alpha) is conserved and

    x'' = g sin(alpha) / (1 + k),    phi'' = x'' / a:

2/3 g sin(alpha) for the disc (k = 1/2), 1/2 for the thin-walled cylinder (k = 1), 5/7 for the
solid sphere (k = 2/5), 3/5 for the spherical shell (k = 2/3). The friction force needed is
F = M g sin(alpha) k / (1 + k) against a normal force M g cos(alpha), so the body rolls while

    friction >= mu_min = tan(alpha) / (1 + M a^2 / I) = tan(alpha) k / (1 + k)

(the boundary rolls: there both cases below give the same motion).

Sliding (friction mu < mu_min): kinetic friction mu M g cos(alpha) acts up the slope at the contact,

    x'' = g (sin(alpha) - mu cos(alpha)),    phi'' = mu M g cos(alpha) a / I,

and the energy falls by the friction force times the slipped distance:
E(t) = -mu M g cos(alpha) (x - a phi) = -mu M g cos(alpha) (x'' - a phi'') t^2 / 2.

Both cases have constant accelerations, so from rest x = x'' t^2 / 2, x' = x'' t, phi' = phi'' t,
and a body reaches the distance L at t = sqrt(2 L / x''): the chapter's race, in which the solid
cylinder beats the hollow one (and the solid sphere beats both, the spherical shell comes between).

Coordinates (layout for other simulators): the incline's top point at the world origin, the slope
descending toward +x: down-slope d = (cos(alpha), 0, -sin(alpha)), normal n = (sin(alpha), 0,
cos(alpha)). The centre starts at a n; phi is the rotation about world +y (v_centre = a phi' y x n
= a phi' d when rolling).

Two descriptions. `layout` is the contact model every simulator can run: the body on slides x (along d)
and z (along n) and the hinge phi, held on the incline by a contact with friction (MuJoCo, pymunk).
`rolling_tree()` is the reduced one, valid while the body rolls: the body on one roll joint (rbody.Joint
kind "roll": axis +y, normal n, anchor the centre of mass, radius a; l = y x n = d, so a positive angle q
rolls it down the slope), x = a q, phi = q. The general engine runs it (engine_native(): Scene.from_layout
of the tree, one tree per distinct element of a batch; the race is one tree of n roll joints), and
rbody.to_mjcf writes it for MuJoCo as a slide and a hinge tied by a joint equality. A sliding body
(friction < mu_min) has no such tree: kinetic friction is a force of the contact's slip, which no joint of
a tree holds, so sliding runs on the hand kernel (kernel_native(): the constant accelerations above).

The hand kernel rolling_rhs is the engine's oracle in the tests, and runs the rolling case too while it is
more than 1.5x cheaper per step than the engine (FAST_PATH; DESIGN.md's rule). Measured with
`python benchmarks/rolling_fast_path.py --repeats 5` (AMD EPYC, 2 cores, idle; numpy 2.4.6, numba 0.68.1;
commit a920624, the engine's planar kernels), ns per step of the compiled loop, engine / kernel: disc rk4
272 / 59.1 (4.6x), verlet 76.0 / 18.9 (4.0x); race of four rk4 911 / 73.6 (12x), verlet 284 / 30.2 (9.4x).
The engine pays its tree walk (kinematics, articulated-body
recursion) for what the kernel holds as two constants. (Before the planar kernels: 24x to 115x.)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np
from numba import njit

from rbody.checks import finite_array, in_interval, nonnegative, positive, representable, scene_arguments
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix
from rbody.layout import Body, Contact, Joint, Layout, Shape
from rbody.engine.native import NativeModel
from rbody.poses import integrated, observed
from rbody.scene import BodyStates, Scene
from rbody.trajectory import Trajectory

# k = I / (M a^2) of the named bodies, about the rolling axis through the centre.
BODY_RATIOS: dict[str, float] = {
    "disc": 1.0 / 2.0,             # solid cylinder
    "hollow_cylinder": 1.0,        # thin-walled: I = M a^2
    "solid_sphere": 2.0 / 5.0,
    "spherical_shell": 2.0 / 3.0,
}
BODY_NAMES = tuple(BODY_RATIOS)

ROLLING_METHODS = ("euler", "symplectic_euler", "verlet", "rk4", "yoshida6", "gauss6", "reference")

# Cylinder shapes of the layout: half length along the axis, as a fraction of the radius.
HALF_LENGTH_FRACTION = 0.5
# Relative size of a product of inertia with y below which y counts as a principal axis.
PRINCIPAL_RTOL = 1e-9
# True: the hand kernel runs the rolling case too, being measurably > 1.5x cheaper per step than the general
# engine (4.0x to 12x: module docstring). False: rolling runs on the general engine, the kernel is the oracle.
FAST_PATH = True

# The hand kernel, the general engine's oracle: y = (x, phi, x', phi'); params = (x'' [m/s^2], phi'' [rad/s^2]),
# both constant.


@njit(cache=True)
def rolling_rhs(y, p, out):
    out[0] = y[2]
    out[1] = y[3]
    out[2] = p[0]
    out[3] = p[1]


@njit(cache=True)
def rolling_accel(q, p, out):
    out[0] = p[0]
    out[1] = p[1]


# ----- the bodies ----------------------------------------------------------------------------------

def _check_body(body: Any, name: str = "body") -> str | Inertia:
    """A named body or an Inertia that can roll about its y axis through the centre of mass."""
    if isinstance(body, str):
        if body not in BODY_RATIOS:
            raise ValueError(f"{name}={body!r}: expected one of {', '.join(map(repr, BODY_NAMES))} "
                             "or an rbody.Inertia")
        return body
    if not isinstance(body, Inertia):
        raise ValueError(f"{name}={body!r}: expected one of {', '.join(map(repr, BODY_NAMES))} "
                         "or an rbody.Inertia")
    tensor = body.tensor
    if not tensor[1, 1] > 0:
        raise ValueError(f"{name}: the Inertia's moment about its y axis is {tensor[1, 1]!r} kg m^2; a body "
                         "rolls about its y axis and needs a moment > 0 about it")
    products = max(abs(tensor[0, 1]), abs(tensor[1, 2]))
    if products > PRINCIPAL_RTOL * np.trace(tensor):
        raise ValueError(f"{name}: the Inertia has products of inertia I_xy={tensor[0, 1]!r}, "
                         f"I_yz={tensor[1, 2]!r} kg m^2; the rolling axis (body y) must be a principal axis "
                         "(rotate the Inertia so that its symmetry axis is y)")
    return body


def _label(body: str | Inertia) -> str:
    return body if isinstance(body, str) else f"Inertia(m={body.mass:g} kg, I_yy={body.tensor[1, 1]:g} kg m^2)"


def _ratio(body: str | Inertia, mass: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """k = I / (M a^2) [-], broadcast over mass and radius."""
    if isinstance(body, str):
        return np.full(np.broadcast(mass, radius).shape, BODY_RATIOS[body])
    return body.tensor[1, 1] / (mass * radius**2)


def _body_inertia(body: str | Inertia, mass: float, radius: float) -> Inertia:
    """Mass properties in the body frame, rolling axis along y (cylinders of half length a/2)."""
    if isinstance(body, Inertia):
        return body
    length = 2 * HALF_LENGTH_FRACTION * radius
    if body == "disc":
        return Inertia.solid_cylinder(mass, radius, length, axis="y")
    if body == "hollow_cylinder":
        return Inertia.hollow_cylinder(mass, radius, radius, length, axis="y")
    if body == "solid_sphere":
        return Inertia.solid_sphere(mass, radius)
    return Inertia.spherical_shell(mass, radius)


def _body_shape(body: str | Inertia, radius: float, name: str, centre: np.ndarray) -> Shape:
    """Spheres for the spheres; a cylinder along body y (local z turned onto y) for everything else."""
    if isinstance(body, str) and body in ("solid_sphere", "spherical_shell"):
        return Shape(name, "sphere", (radius,), pos=tuple(centre.tolist()))
    half = np.sqrt(0.5)
    return Shape(name, "cylinder", (radius, HALF_LENGTH_FRACTION * radius), pos=tuple(centre.tolist()),
                 quat=(half, -half, 0.0, 0.0))


def _slope_frame(incline: float) -> tuple[np.ndarray, np.ndarray]:
    """Down-slope direction d (3,) and outward normal n (3,) of the incline."""
    return (np.array([np.cos(incline), 0.0, -np.sin(incline)]),
            np.array([np.sin(incline), 0.0, np.cos(incline)]))


def _incline_shape(incline: float, travel: float, half_width: float, radius: float) -> Shape:
    """The slope as a finite plane through the origin, tilted by alpha about +y (local z -> n), centred
    on the middle of the travel and reaching 4 radii beyond both ends."""
    down, _normal = _slope_frame(incline)
    return Shape("incline", "plane", (travel / 2 + 4 * radius, half_width),
                 pos=tuple((travel / 2 * down).tolist()),
                 quat=(float(np.cos(incline / 2)), 0.0, float(np.sin(incline / 2)), 0.0))


def rolled_angle(t: np.ndarray, distance: np.ndarray, slip: np.ndarray, radius: float) -> np.ndarray:
    """(T, ...) spin angle phi [rad] from the start, (distance - integral of slip) / radius, with distance and
    slip (T, ...) [m, m/s] of a run at times t (T,) [s]: x' - a phi' = slip. Exact where the body rolls (slip 0)
    and where slip is linear in time (sliding from rest): the trapezoid rule integrates it."""
    return (distance - distance[:1] - integrated(t, slip)) / radius


def _accelerations(ratio, mass, radius, incline, friction, gravity):
    """x'' [m/s^2], phi'' [rad/s^2], rolls (bool) and mu_min, all broadcast."""
    sin, cos = np.sin(incline), np.cos(incline)
    mu_min = np.tan(incline) * ratio / (1 + ratio)
    rolls = friction >= mu_min
    rolling = gravity * sin / (1 + ratio)
    sliding = gravity * (sin - friction * cos)
    x_dd = np.where(rolls, rolling, sliding)
    # phi'' = mu M g cos(alpha) a / I = mu g cos(alpha) / (k a) while sliding.
    phi_dd = np.where(rolls, rolling / radius, friction * gravity * cos / (ratio * radius))
    return x_dd, phi_dd, rolls, mu_min


def _energy_from_states(states: BodyStates, inertia: Inertia, height0: float, gravity: float) -> np.ndarray:
    """E = 1/2 M |v|^2 + 1/2 w . (R I R^T) w + M g (z - z0) [J], (T,): kinetic plus potential energy
    from the start, including any motion along the slope normal."""
    velocity, omega = np.asarray(states.velocity), np.asarray(states.omega)
    rotation = quat_to_matrix(np.asarray(states.quat))
    omega_body = np.einsum("tba,tb->ta", rotation, omega)  # R^T w
    rotational = 0.5 * np.einsum("ta,ab,tb->t", omega_body, inertia.tensor, omega_body)
    height = np.asarray(states.com)[:, 2] - height0
    return 0.5 * inertia.mass * np.sum(velocity**2, axis=1) + rotational + inertia.mass * gravity * height


# ----- one body --------------------------------------------------------------------------------------

@dataclass(frozen=True, kw_only=True)
class Rolling(Scene):
    """A round body released from rest on an incline: rolls when friction >= mu_min, else slides.

    body:     "disc", "hollow_cylinder", "solid_sphere", "spherical_shell", or an Inertia that rolls
              about its y axis through its centre of mass (its mass is `mass`)
    radius:   rolling radius a [m]; mass M [kg]; incline alpha [rad] in (0, pi/2); friction mu [-] >= 0.
              These four may be arrays (a batch).
    Observables (T, *batch): distance x of the centre down the slope [m], speed x' [m/s], spin
    phi' [rad/s] (positive rolling down), slip x' - a phi' [m/s], energy (kinetic + potential from the
    start) [J].
    """

    body: Any = "disc"
    radius: Any
    mass: Any = 1.0
    incline: Any
    friction: Any = 1.0

    observables: ClassVar[tuple[str, ...]] = ("distance", "speed", "spin", "slip", "energy")
    main_observable: ClassVar[str] = "distance"
    preferred_methods: ClassVar[tuple[str, ...]] = ROLLING_METHODS
    batch_fields: ClassVar[tuple[str, ...]] = ("radius", "mass", "incline", "friction")

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_body(self.body)
        positive(self.radius, "radius")
        positive(self.mass, "mass")
        in_interval(self.incline, "incline", 0.0, np.pi / 2)
        nonnegative(self.friction, "friction")
        if isinstance(self.body, Inertia) and np.any(np.asarray(self.mass, dtype=float) != self.body.mass):
            raise ValueError(f"mass={self.mass!r}: the Inertia body carries its own mass {self.body.mass!r} kg; "
                             "leave mass out or give the same value")
        self.batch_shape  # noqa: B018 - checks that the parameters broadcast

    # --- the physics, as flat (B,) arrays -------------------------------------------------------------

    def _flat(self) -> tuple[np.ndarray, ...]:
        """k, M, a, alpha, mu (B,) and x'', phi'', rolls, mu_min (B,)."""
        mass, radius = self.batched("mass"), self.batched("radius")
        incline, friction = self.batched("incline"), self.batched("friction")
        ratio = _ratio(self.body, mass, radius)
        return (ratio, mass, radius, incline, friction) + _accelerations(
            ratio, mass, radius, incline, friction, self.gravity)

    @property
    def inertia_ratio(self):
        """k = I / (M a^2) [-] (float, or an array of the batch shape)."""
        return self.unflatten(self._flat()[0])

    @property
    def acceleration(self):
        """x'' [m/s^2]: g sin(alpha)/(1 + k) rolling, g (sin(alpha) - mu cos(alpha)) sliding."""
        return self.unflatten(self._flat()[5])

    @property
    def angular_acceleration(self):
        """phi'' [rad/s^2]: x''/a rolling, mu M g cos(alpha) a / I sliding."""
        return self.unflatten(self._flat()[6])

    @property
    def rolls(self):
        """True where friction >= mu_min (rolling without slipping), False where the body slides."""
        return self.unflatten(self._flat()[7])

    @property
    def mu_min(self):
        """Least friction coefficient for rolling, tan(alpha) / (1 + M a^2 / I) [-]."""
        return self.unflatten(self._flat()[8])

    def _energy(self, x, phi, speed, spin) -> np.ndarray:
        """E = 1/2 M x'^2 + 1/2 I phi'^2 - M g x sin(alpha) [J]; arguments (..., B)."""
        ratio, mass, radius, incline = self._flat()[:4]
        moment = ratio * mass * radius**2
        return 0.5 * mass * speed**2 + 0.5 * moment * spin**2 - mass * self.gravity * np.sin(incline) * x

    # --- closed form ---------------------------------------------------------------------------------

    def exact(self, t) -> dict[str, np.ndarray]:
        t = finite_array(t, "t").reshape(-1)[:, None]  # (T, 1) against (B,)
        _ratio_, mass, radius, incline, friction, x_dd, phi_dd, rolls, _mu = self._flat()
        slip_rate = np.where(rolls, 0.0, x_dd - radius * phi_dd)  # exactly 0 while rolling
        values = {
            "distance": 0.5 * x_dd * t**2,
            "speed": x_dd * t,
            "spin": phi_dd * t,
            "slip": slip_rate * t,
            # friction mu M g cos(alpha) times the slipped distance (x'' - a phi'') t^2 / 2
            "energy": -friction * mass * self.gravity * np.cos(incline) * slip_rate * 0.5 * t**2,
        }
        shape = (t.shape[0],) + self.batch_shape
        return {name: value.reshape(shape) for name, value in values.items()}

    # --- native model -----------------------------------------------------------------------------------

    def native(self) -> NativeModel:
        """The general engine on the rolling tree when every element rolls (engine_native), else the hand kernel
        (kernel_native): a sliding body is driven by kinetic friction, a force of the contact's slip, which no
        joint of a tree holds; a batch that mixes the two cases runs on the hand kernel as one call. With
        FAST_PATH the hand kernel runs every case (module docstring: measured cost)."""
        if FAST_PATH or not np.all(self._flat()[7]):
            return self.kernel_native()
        return self.engine_native()

    def kernel_native(self) -> NativeModel:
        """The hand kernel: y = (x, phi, x', phi') with the closed form's constant accelerations."""
        x_dd, phi_dd = self._flat()[5:7]
        radius = self.batched("radius")

        def observe(t, y):
            x, phi, speed, spin = y[..., 0], y[..., 1], y[..., 2], y[..., 3]
            return {"distance": x, "speed": speed, "spin": spin, "slip": speed - radius * spin,
                    "energy": self._energy(x, phi, speed, spin)}

        return NativeModel(y0=np.zeros((x_dd.size, 4)), params=np.stack([x_dd, phi_dd], axis=1),
                           rhs=rolling_rhs, accel=rolling_accel, observe=observe)

    def engine_native(self) -> NativeModel:
        """The general engine (rbody.engine.multibody) on rolling_tree(): y = (q, q'), q the roll angle; one
        tree per distinct (radius, mass, incline) of the batch. distance a q, speed a q', spin q', slip 0
        (held by the coordinate). Raises ValueError where a body slides (friction < mu_min)."""
        rolls = self._flat()[7]
        if not np.all(rolls):
            raise ValueError(f"scene {self.describe()}: friction below mu_min at batch elements "
                             f"{np.flatnonzero(~rolls).tolist()}: the body slides there, which the rolling tree "
                             "(a roll joint) cannot hold; use kernel_native()")
        columns = np.stack([self.batched(name) for name in ("radius", "mass", "incline")], axis=1)
        _unique, first, which = np.unique(columns, axis=0, return_index=True, return_inverse=True)
        trees = [self.item(np.unravel_index(int(b), self.batch_shape) if self.batch_shape else ()).rolling_tree()
                 for b in first]
        model = _stacked_tree_native(trees, self.gravity, self.t_end, which.reshape(-1))
        radius = self.batched("radius")

        def observe(t, y):
            angle, rate = y[..., 0], y[..., 1]
            distance, speed = radius * angle, radius * rate
            return {"distance": distance, "speed": speed, "spin": rate, "slip": np.zeros_like(rate),
                    "energy": self._energy(distance, angle, speed, rate)}

        return dataclasses.replace(model, observe=observe)

    def why_not(self, method: str) -> str:
        return f"{method!r} is not a rolling method"

    # --- what other simulators build ------------------------------------------------------------------

    def _layout(self) -> Layout:
        radius, mass, incline = float(self.radius), float(self.mass), float(self.incline)
        inertia = _body_inertia(self.body, mass, radius)
        travel = float(self.exact([self.t_end])["distance"][0])
        incline_shape = _incline_shape(incline, travel, 4 * radius, radius)
        body, joints = _rolling_body(self.body, inertia, radius, incline, np.zeros(3), "body", "")
        contact = Contact(body.shapes[0].name, "incline", friction=float(self.friction), restitution=0.0)
        return Layout(bodies=(body,), joints=joints, fixed=(incline_shape,), contacts=(contact,))

    def rolling_tree(self) -> Layout:
        """The reduced description (unbatched scenes): the body on one roll joint "roll" (rbody.layout.Joint),
        the rolling constraint held by the coordinate; the incline drawn but touching nothing (no contacts).
        Valid while the body rolls (self.rolls); `layout` is the contact model every simulator can run."""
        self.require_single("the rolling tree")
        radius, mass, incline = float(self.radius), float(self.mass), float(self.incline)
        inertia = _body_inertia(self.body, mass, radius)
        travel = float(self.exact([self.t_end])["distance"][0])
        part, joint = _roll_body(self.body, inertia, radius, incline, np.zeros(3), "body", "roll")
        return Layout(bodies=(part,), joints=(joint,), fixed=(_incline_shape(incline, travel, 4 * radius, radius),))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        radius, incline = float(self.radius), float(self.incline)
        x, speed = (np.asarray(v, dtype=float) for v in joints["x"])
        spin = np.asarray(joints["phi"][1], dtype=float)
        inertia = _body_inertia(self.body, float(self.mass), radius)
        energy = _energy_from_states(bodies["body"], inertia, radius * np.cos(incline), self.gravity)
        return {"distance": x, "speed": speed, "spin": spin, "slip": speed - radius * spin, "energy": energy}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Slide "x" = distance, hinge "phi" = the spin angle (rolled_angle); slide "z" stays 0."""
        distance = observed(self, trajectory, "distance")
        return {"x": distance, "phi": rolled_angle(trajectory.t, distance, observed(self, trajectory, "slip"),
                                                    float(self.radius))}

    def describe(self) -> str:
        return (f"{self.name}({_label(self.body)}, radius={self.radius!r} m, mass={self.mass!r} kg, "
                f"incline={self.incline!r} rad, friction={self.friction!r})")


def _placed_body(body: str | Inertia, inertia: Inertia, radius: float, incline: float, offset: np.ndarray,
                 name: str) -> Body:
    """The body with its centre of mass at a n + offset (reference pose, body axes = world axes)."""
    _down, normal = _slope_frame(incline)
    com = inertia.com
    shape = _body_shape(body, radius, f"{name}_shape", com)
    return Body(name, inertia, shapes=(shape,), pos=tuple((radius * normal + offset - com).tolist()))


def _roll_body(body: str | Inertia, inertia: Inertia, radius: float, incline: float, offset: np.ndarray,
               name: str, joint: str) -> tuple[Body, Joint]:
    """The placed body on one roll joint `joint`: axis +y, normal n = (sin(alpha), 0, cos(alpha)), anchor the
    centre of mass. Then l = y x n = (cos(alpha), 0, -sin(alpha)) = d: a positive angle rolls it down the slope."""
    _down, normal = _slope_frame(incline)
    return (_placed_body(body, inertia, radius, incline, offset, name),
            Joint(joint, "roll", name, axis=(0.0, 1.0, 0.0), anchor=tuple(inertia.com.tolist()), radius=radius,
                  normal=tuple(normal.tolist())))


def _rolling_body(body: str | Inertia, inertia: Inertia, radius: float, incline: float, offset: np.ndarray,
                  name: str, suffix: str) -> tuple[Body, tuple[Joint, ...]]:
    """The placed body and its joints: slide "x" along d, slide "z" along n, hinge "phi" about +y through the
    centre of mass."""
    down, normal = _slope_frame(incline)
    com = inertia.com
    joints = (
        Joint(f"x{suffix}", "slide", name, axis=tuple(down.tolist()), anchor=tuple(com.tolist())),
        Joint(f"z{suffix}", "slide", name, axis=tuple(normal.tolist()), anchor=tuple(com.tolist())),
        Joint(f"phi{suffix}", "hinge", name, axis=(0.0, 1.0, 0.0), anchor=tuple(com.tolist())),
    )
    return _placed_body(body, inertia, radius, incline, offset, name), joints


def _stacked_tree_native(trees: Sequence[Layout], gravity: float, t_end: float, which: np.ndarray) -> NativeModel:
    """The general engine's model of each tree (rbody.Scene.from_layout), one row per batch element: element
    b runs trees[which[b]] (trees of one structure, so their params rows have one length). Its stability rate
    is 0, as the hand kernel's (constant accelerations: any step is stable), not the tree's Jacobian."""
    models = [Scene.from_layout(tree, t_end=t_end, gravity=gravity).family_native() for tree in trees]
    if len({m.params.shape[1] for m in models}) != 1 or len({m.y0.shape[1] for m in models}) != 1:
        raise ValueError("the rolling trees of this batch differ in structure; they cannot run as one batch")
    params = np.vstack([m.params for m in models])[which]
    y0 = np.vstack([m.y0 for m in models])[which]
    return dataclasses.replace(models[0], y0=np.ascontiguousarray(y0), params=np.ascontiguousarray(params),
                               rate_from_jacobian=False)


# ----- the race ---------------------------------------------------------------------------------------

def _arrival(t: np.ndarray, distance: np.ndarray, speed: np.ndarray, length: float) -> np.ndarray:
    """Time each column of distance (T, n) first reaches `length` (n,) [s], NaN where it never does.

    On the step [t_k, t_k+1] where it is crossed, x(t_k + s) = x_k + v_k s + 1/2 a s^2 with
    a = (v_k+1 - v_k) / (t_k+1 - t_k) (exact under a constant acceleration); the root is taken in the
    form s = 2 (L - x_k) / (v_k + sqrt(v_k^2 + 2 a (L - x_k))), free of cancellation."""
    t = np.asarray(t, dtype=float)
    distance = np.asarray(distance, dtype=float).reshape(t.size, -1)
    speed = np.asarray(speed, dtype=float).reshape(t.size, -1)
    arrival = np.full(distance.shape[1], np.nan)
    for j in range(distance.shape[1]):
        reached = np.flatnonzero(distance[:, j] >= length)
        if reached.size == 0:
            continue
        k1 = int(reached[0])
        if k1 == 0:
            arrival[j] = t[0]
            continue
        k = k1 - 1
        h = t[k1] - t[k]
        accel = (speed[k1, j] - speed[k, j]) / h
        remaining = length - distance[k, j]
        root = np.sqrt(max(speed[k, j] ** 2 + 2 * accel * remaining, 0.0))
        arrival[j] = t[k] + 2 * remaining / (speed[k, j] + root)
    return arrival


def arrival_times(trajectory: Trajectory, length: float) -> np.ndarray:
    """Time each body reaches `length` [m] down the slope, from a trajectory's distance and speed.

    trajectory: distance and speed (T, ...) (a race, or a batch of rolling scenes)
    Returns (...) arrival times [s]; NaN for a body that has not reached `length` by the end of the run.
    """
    length = positive(length, "length")
    distance, speed = np.asarray(trajectory["distance"]), np.asarray(trajectory["speed"])
    arrival = _arrival(trajectory.t, distance, speed, length)
    return arrival.reshape(distance.shape[1:])


@dataclass(frozen=True, kw_only=True)
class RollingRace(Scene):
    """Bodies released together from rest, side by side on one incline, racing a distance `length`.

    bodies: n names or Inertia (as for rolling); radius [m], incline [rad], length [m], mass [kg],
    friction [-] are single values shared by every body.
    Observables (T, n): distance, speed, spin, slip, energy of each body (as for rolling), and
    arrival_time: the time each body reaches `length` [s], found from the whole run and repeated at
    every sample (NaN for a body that has not arrived by the end). The bodies are independent: the
    native engine runs them as a batch of n in one call.
    """

    bodies: tuple
    radius: float
    incline: float
    length: float
    mass: float = 1.0
    friction: float = 1.0

    observables: ClassVar[tuple[str, ...]] = ("distance", "speed", "spin", "slip", "energy", "arrival_time")
    main_observable: ClassVar[str] = "distance"
    preferred_methods: ClassVar[tuple[str, ...]] = ROLLING_METHODS

    def __post_init__(self) -> None:
        super().__post_init__()
        bodies = self.bodies
        if isinstance(bodies, (str, Inertia)):
            bodies = (bodies,)
        try:
            bodies = tuple(bodies)
        except TypeError:
            raise ValueError(f"bodies={self.bodies!r}: expected a sequence of body names or Inertia") from None
        if not bodies:
            raise ValueError("bodies=(): a race needs at least one body")
        for i, body in enumerate(bodies):
            _check_body(body, f"bodies[{i}]")
        object.__setattr__(self, "bodies", bodies)
        for name in ("radius", "incline", "length", "mass", "friction"):
            if np.ndim(getattr(self, name)) != 0:
                raise ValueError(f"{name}={getattr(self, name)!r}: a race takes a single value")
        object.__setattr__(self, "radius", positive(self.radius, "radius"))
        object.__setattr__(self, "incline", in_interval(self.incline, "incline", 0.0, np.pi / 2))
        object.__setattr__(self, "length", positive(self.length, "length"))
        object.__setattr__(self, "mass", positive(self.mass, "mass"))
        object.__setattr__(self, "friction", nonnegative(self.friction, "friction"))
        for i, body in enumerate(bodies):
            if isinstance(body, Inertia) and body.mass != self.mass:
                raise ValueError(f"mass={self.mass!r}: bodies[{i}] is an Inertia of mass {body.mass!r} kg; in a "
                                 "race every body has the one mass (give Inertia bodies of equal mass and "
                                 "leave mass out, or give that mass)")

    # --- the physics, (n,) arrays ---------------------------------------------------------------------

    def _flat(self) -> tuple[np.ndarray, ...]:
        """k, x'', phi'', rolls, mu_min (n,)."""
        ratio = np.array([_ratio(b, np.float64(self.mass), np.float64(self.radius)) for b in self.bodies],
                         dtype=float)
        return (ratio,) + _accelerations(ratio, self.mass, self.radius, self.incline, self.friction,
                                         self.gravity)

    @property
    def labels(self) -> tuple[str, ...]:
        """Name of each body, for tables and plots."""
        return tuple(_label(b) for b in self.bodies)

    @property
    def acceleration(self) -> np.ndarray:
        """x'' (n,) of each body [m/s^2]."""
        return self._flat()[1]

    @property
    def rolls(self) -> np.ndarray:
        """(n,) True where the body rolls without slipping."""
        return self._flat()[3]

    @property
    def mu_min(self) -> np.ndarray:
        """(n,) least friction coefficient for rolling [-]."""
        return self._flat()[4]

    @property
    def arrival_time(self) -> np.ndarray:
        """Exact arrival time (n,) [s]: t = sqrt(2 L / x'') (inf for a body that does not accelerate)."""
        with np.errstate(divide="ignore"):
            return np.sqrt(2 * self.length / self.acceleration)

    @property
    def finishing_order(self) -> np.ndarray:
        """Indices of the bodies, first to arrive first (n,)."""
        return np.argsort(self.arrival_time, kind="stable")

    def _energy(self, x, speed, spin) -> np.ndarray:
        """E = 1/2 M x'^2 + 1/2 I phi'^2 - M g x sin(alpha) [J]; arguments (..., n)."""
        moment = self._flat()[0] * self.mass * self.radius**2
        return (0.5 * self.mass * speed**2 + 0.5 * moment * spin**2
                - self.mass * self.gravity * np.sin(self.incline) * x)

    def arrival_times(self, trajectory: Trajectory) -> np.ndarray:
        """Arrival time (n,) [s] of each body in a run of this race (NaN where it has not arrived)."""
        return arrival_times(trajectory, self.length)

    # --- closed form ---------------------------------------------------------------------------------

    def exact(self, t) -> dict[str, np.ndarray]:
        t = finite_array(t, "t").reshape(-1)[:, None]  # (T, 1) against (n,)
        _ratio_, x_dd, phi_dd, rolls, _mu = self._flat()
        slip_rate = np.where(rolls, 0.0, x_dd - self.radius * phi_dd)
        loss_rate = self.friction * self.mass * self.gravity * np.cos(self.incline) * slip_rate
        return {
            "distance": 0.5 * x_dd * t**2,
            "speed": x_dd * t,
            "spin": phi_dd * t,
            "slip": slip_rate * t,
            "energy": -loss_rate * 0.5 * t**2,
            "arrival_time": np.broadcast_to(self.arrival_time, (t.shape[0], len(self.bodies))).copy(),
        }

    # --- native model: the n bodies as a batch of n -------------------------------------------------

    def native(self) -> NativeModel:
        """The general engine on the race's rolling tree when every body rolls (engine_native), else the hand
        kernel (kernel_native; a sliding body's kinetic friction is no force a tree's joints hold). With
        FAST_PATH the hand kernel runs every race (module docstring: measured cost)."""
        if FAST_PATH or not np.all(self.rolls):
            return self.kernel_native()
        return self.engine_native()

    def _race_observables(self, t, x, speed, spin, slip) -> dict[str, np.ndarray]:
        """(T, n) arrays of the race -> each observable as (T, 1, n), which becomes (T, n) for batch shape ()."""
        arrival = np.broadcast_to(_arrival(t, x, speed, self.length), x.shape)
        values = {"distance": x, "speed": speed, "spin": spin, "slip": slip,
                  "energy": self._energy(x, speed, spin), "arrival_time": arrival}
        return {name: np.ascontiguousarray(value)[:, None, :] for name, value in values.items()}

    def kernel_native(self) -> NativeModel:
        """The hand kernel, the n bodies as a batch of n: y (n, 4) = (x, phi, x', phi') each."""
        x_dd, phi_dd = self._flat()[1:3]

        def observe(t, y):
            x, speed, spin = y[..., 0], y[..., 2], y[..., 3]  # y (T, n, 4): the bodies are the batch
            return self._race_observables(t, x, speed, spin, speed - self.radius * spin)

        return NativeModel(y0=np.zeros((x_dd.size, 4)), params=np.stack([x_dd, phi_dd], axis=1),
                           rhs=rolling_rhs, accel=rolling_accel, observe=observe)

    def engine_native(self) -> NativeModel:
        """The general engine on rolling_tree(), one tree of n bodies each on its roll joint: y (1, 2n) =
        (q_1..q_n, q_1'..q_n'). Raises ValueError where a body slides."""
        if not np.all(self.rolls):
            raise ValueError(f"race {self.describe()}: bodies {np.flatnonzero(~self.rolls).tolist()} slide "
                             f"(friction {self.friction!r} < mu_min {self.mu_min.tolist()}), which the rolling tree "
                             "cannot hold; use kernel_native()")
        n = len(self.bodies)
        model = _stacked_tree_native([self.rolling_tree()], self.gravity, self.t_end, np.zeros(1, dtype=int))

        def observe(t, y):
            angle, rate = y[:, 0, :n], y[:, 0, n:2 * n]  # y (T, 1, 2n)
            return self._race_observables(t, self.radius * angle, self.radius * rate, rate, np.zeros_like(rate))

        return dataclasses.replace(model, observe=observe)

    def why_not(self, method: str) -> str:
        return f"{method!r} is not a rolling method"

    # --- what other simulators build ------------------------------------------------------------------

    def _spacing(self) -> float:
        """Distance between neighbouring centres across the slope: 3 a (a gap of at least a)."""
        return 3 * self.radius

    def _placements(self) -> list[tuple[int, Any, Inertia, np.ndarray]]:
        """(i, body spec, its Inertia, offset of its centre across the slope) of every body, side by side."""
        n = len(self.bodies)
        return [(i, spec, _body_inertia(spec, self.mass, self.radius),
                 np.array([0.0, (i - (n - 1) / 2) * self._spacing(), 0.0])) for i, spec in enumerate(self.bodies)]

    def _incline(self) -> Shape:
        """The incline, long enough for the farthest body's travel and wide enough for all of them."""
        travel = float(np.max(self.exact([self.t_end])["distance"]))
        return _incline_shape(self.incline, travel, len(self.bodies) * self._spacing() / 2 + 2 * self.radius,
                              self.radius)

    def _layout(self) -> Layout:
        parts, joints, contacts = [], [], []
        for i, spec, inertia, offset in self._placements():
            part, body_joints = _rolling_body(spec, inertia, self.radius, self.incline, offset, f"body_{i}", f"_{i}")
            parts.append(part)
            joints.extend(body_joints)
            contacts.append(Contact(part.shapes[0].name, "incline", friction=self.friction, restitution=0.0))
        return Layout(bodies=tuple(parts), joints=tuple(joints), fixed=(self._incline(),), contacts=tuple(contacts))

    def rolling_tree(self) -> Layout:
        """The reduced description: body_i on roll joint "roll_i" (rbody.layout.Joint), side by side as in the
        layout, the incline drawn but touching nothing. Valid for the bodies that roll (self.rolls); `layout`
        is the contact model every simulator can run."""
        parts, joints = [], []
        for i, spec, inertia, offset in self._placements():
            part, joint = _roll_body(spec, inertia, self.radius, self.incline, offset, f"body_{i}", f"roll_{i}")
            parts.append(part)
            joints.append(joint)
        return Layout(bodies=tuple(parts), joints=tuple(joints), fixed=(self._incline(),))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        n = len(self.bodies)
        x = np.stack([np.asarray(joints[f"x_{i}"][0], dtype=float) for i in range(n)], axis=1)
        speed = np.stack([np.asarray(joints[f"x_{i}"][1], dtype=float) for i in range(n)], axis=1)
        spin = np.stack([np.asarray(joints[f"phi_{i}"][1], dtype=float) for i in range(n)], axis=1)
        height0 = self.radius * np.cos(self.incline)
        energy = np.stack([
            _energy_from_states(bodies[f"body_{i}"], _body_inertia(spec, self.mass, self.radius), height0,
                                self.gravity)
            for i, spec in enumerate(self.bodies)], axis=1)
        arrival = np.broadcast_to(_arrival(t, x, speed, self.length), x.shape).copy()
        return {"distance": x, "speed": speed, "spin": spin, "slip": speed - self.radius * spin,
                "energy": energy, "arrival_time": arrival}

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Slides "x_<i>" = distance[:, i], hinges "phi_<i>" = each spin angle (rolled_angle); "z_<i>" stay 0."""
        n = len(self.bodies)
        distance = observed(self, trajectory, "distance", (n,))
        angle = rolled_angle(trajectory.t, distance, observed(self, trajectory, "slip", (n,)), self.radius)
        out = {}
        for i in range(n):
            out[f"x_{i}"], out[f"phi_{i}"] = distance[:, i], angle[:, i]
        return out

    def describe(self) -> str:
        return (f"{self.name}({', '.join(self.labels)}; radius={self.radius!r} m, incline={self.incline!r} rad, "
                f"length={self.length!r} m, friction={self.friction!r})")


# ----- factories ----------------------------------------------------------------------------------------

def _mass_of(body: Any, mass: Any) -> Any:
    """mass=None: 1 kg for a named body, the Inertia's own mass for an Inertia."""
    if mass is not None:
        return mass
    return body.mass if isinstance(body, Inertia) else 1.0


def rolling(body: str | Inertia = "disc", *, radius, mass=None, incline, friction=1.0, t_end: float = 1.0,
            gravity: float = 9.81) -> Rolling:
    """A body released from rest on an incline: it rolls when friction >= mu_min, else slides.

    body:     "disc" (solid cylinder), "hollow_cylinder" (thin-walled, I = M a^2), "solid_sphere",
              "spherical_shell", or an Inertia rolling about its y axis through its centre of mass
    radius [m], mass [kg] (default 1 kg, or the Inertia's mass), incline [rad] in (0, pi/2), friction [-]:
    numbers or arrays that broadcast to a batch.
    Observables distance [m], speed [m/s], spin [rad/s], slip [m/s], energy [J]; scene.acceleration,
    scene.mu_min and scene.rolls give the closed form.
    """
    scene_arguments(gravity, t_end)
    return representable(Rolling(name="rolling", t_end=t_end, gravity=gravity, body=_check_body(body),
                   radius=radius, mass=_mass_of(body, mass), incline=incline, friction=friction))


def rolling_race(bodies: Sequence[str | Inertia] = ("disc", "hollow_cylinder"), *, radius, incline, length,
                 mass=None, friction=1.0, gravity: float = 9.81, t_end: float | None = None) -> RollingRace:
    """The chapter's race: bodies released together down an incline of length `length` [m].

    bodies:  names or Inertia as for `rolling` (default: the chapter's solid against hollow cylinder)
    radius [m], incline [rad], length [m], mass [kg] (default 1 kg, or the Inertias' mass), friction [-]:
    single values shared by all bodies. t_end [s] defaults to 1.1 times the slowest exact arrival.
    Observables (T, n): distance, speed, spin, slip, energy, arrival_time; scene.arrival_time is exact.
    """
    if mass is None:
        masses = {b.mass for b in (bodies if not isinstance(bodies, (str, Inertia)) else (bodies,))
                  if isinstance(b, Inertia)}
        mass = masses.pop() if len(masses) == 1 else 1.0
    scene_arguments(gravity, t_end)
    if t_end is None:
        probe = RollingRace(name="rolling_race", t_end=1.0, gravity=gravity, bodies=bodies, radius=radius,
                            incline=incline, length=length, mass=mass, friction=friction)
        slowest = float(np.max(probe.arrival_time))
        if not np.isfinite(slowest):
            raise ValueError(f"gravity={gravity!r}: the bodies do not accelerate down the slope "
                             f"(accelerations {probe.acceleration.tolist()} m/s^2), so they never arrive; "
                             "give gravity > 0 or an explicit t_end")
        t_end = 1.1 * slowest
    return representable(RollingRace(name="rolling_race", t_end=t_end, gravity=gravity, bodies=bodies, radius=radius,
                       incline=incline, length=length, mass=mass, friction=friction))
