"""Scene: one experiment, described once, backend-neutral, validated on construction.

A Scene holds the parameters of a textbook experiment. From them it derives

- the physical model every simulator needs: ``bodies`` (each with its Inertia and shapes),
  ``joints``, ``fixed`` world geometry and ``contacts`` (which pairs touch, with friction and
  restitution), gravity along -z, the initial state, the duration;
- ``exact(t)``: the closed-form observables at any times;
- ``observe(t, bodies, joints)``: the same observables from the world-frame states of the bodies
  and joint coordinates, so that every backend reports the same names in the same frame;
- ``native()``: how rbody's own engine simulates it, in the fewest coordinates.

Each family of scenes (rbody.scenes) is a subclass. Numeric parameters of the continuous scenes
may be arrays: they broadcast to ``batch_shape`` and one ``simulate`` call runs the whole batch;
``item(index)`` picks one element, which is what MuJoCo and pymunk are given.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, Iterable, Mapping

import numpy as np

from rbody._checks import finite_array, nonnegative, in_interval
from rbody.inertia import Inertia, unit_axis

WORLD = "world"

SHAPE_KINDS = ("sphere", "cylinder", "box", "capsule", "plane", "mesh")


@dataclass(frozen=True)
class Shape:
    """Collision and drawing geometry, in the frame of the body that carries it (or the world).

    kind:   one of SHAPE_KINDS
    size:   sphere (radius,); cylinder and capsule (radius, half_length) along the local z;
            box (half sizes x, y, z); plane (half sizes x, y, or 0 for infinite); mesh: ()
    pos:    (3,) centre of the shape [m]; quat: (4,) its orientation (w, x, y, z)
    mesh:   path of the mesh file for kind="mesh" (vertices in the body frame)
    """

    name: str
    kind: str
    size: tuple[float, ...] = ()
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    mesh: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in SHAPE_KINDS:
            raise ValueError(f"shape {self.name!r}: kind={self.kind!r}, expected one of {SHAPE_KINDS}")
        object.__setattr__(self, "size", tuple(float(s) for s in nonnegative(np.atleast_1d(self.size), "size")))
        object.__setattr__(self, "pos", tuple(finite_array(self.pos, "pos", shape=(3,)).tolist()))
        quat = finite_array(self.quat, "quat", shape=(4,))
        if np.linalg.norm(quat) == 0:
            raise ValueError(f"shape {self.name!r}: quat={quat.tolist()} must be non-zero")
        object.__setattr__(self, "quat", tuple((quat / np.linalg.norm(quat)).tolist()))


@dataclass(frozen=True)
class Body:
    """A rigid body: its mass properties (body frame), its shapes, its parent and where it starts.

    pos (3,) [m] and quat (4,) place the body frame in the parent's frame in the reference pose,
    where every hinge and slide coordinate is zero (as MJCF's body pos/quat); the joints' qpos0 then
    set the initial state. A free body starts at pos/quat.
    """

    name: str
    inertia: Inertia
    shapes: tuple[Shape, ...] = ()
    parent: str = WORLD
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)


JOINT_KINDS = ("hinge", "slide", "ball", "free")


@dataclass(frozen=True)
class Joint:
    """A joint between `body` and its parent.

    kind:   "hinge" (angle about axis through anchor), "slide" (distance along axis), "free"
    axis:   (3,) direction in the body frame; anchor: (3,) point in the body frame [m]
    qpos0, qvel0: initial coordinate [rad or m] and rate [rad/s or m/s] (hinge and slide);
            free joints start from the body's pos/quat with qvel0 = (v (3,) of the body-frame origin,
            omega (3,)), both in the world frame.
    A hinge turns the body by +angle about `axis` (right-handed); a slide moves it by +distance along
    `axis`. Backends report hinge and slide joints as (qpos (T,), qvel (T,)) under the joint's name.
    """

    name: str
    kind: str
    body: str
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    anchor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    qpos0: float = 0.0
    qvel0: Any = 0.0
    damping: float = 0.0
    stiffness: float = 0.0
    springref: float = 0.0
    armature: float = 0.0
    ref: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in JOINT_KINDS:
            raise ValueError(f"joint {self.name!r}: kind={self.kind!r}, expected one of {JOINT_KINDS}")
        object.__setattr__(self, "axis", tuple(unit_axis(self.axis, "axis").tolist()))


@dataclass(frozen=True)
class Contact:
    """Two pieces of geometry that may touch: shape names (world shapes or body shapes).

    friction [-] is the Coulomb coefficient of the pair; restitution in [0, 1] the coefficient of
    restitution of the pair (1 elastic). Pairs not listed never collide.
    """

    shape_a: str
    shape_b: str
    friction: float = 0.0
    restitution: float = 1.0

    def __post_init__(self) -> None:
        nonnegative(self.friction, "friction")
        in_interval(self.restitution, "restitution", 0.0, 1.0, closed=True)


@dataclass(frozen=True)
class Layout:
    """The physical model of an unbatched scene: what MuJoCo, pymunk and the MJCF exporter build."""

    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    fixed: tuple[Shape, ...] = ()
    contacts: tuple[Contact, ...] = ()


@dataclass(frozen=True)
class BodyStates:
    """World-frame history of one body, as any backend reports it.

    com (T, 3) centre of mass [m]; quat (T, 4) orientation (w, x, y, z);
    velocity (T, 3) of the centre of mass [m/s]; omega (T, 3) angular velocity, world frame [rad/s].
    """

    com: np.ndarray
    quat: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray


@dataclass(frozen=True)
class NativeModel:
    """How rbody integrates a continuous scene in minimal coordinates (see rbody.engine).

    y0:        (B, n) initial state, batch flattened
    params:    (B, p) parameters the kernels read
    rhs:       compiled f(y (n,), params (p,), out (n,)): y' = f(y), for every general method
    accel:     compiled a(q (m,), params, out (m,)) when y = (q, q') and q'' depends on q only
               (enables the symplectic methods); None otherwise
    split:     name -> (step, weights): the scene's own symmetric one-step map step(y, p, h) and the
               composition weights (free rotation: "splitting" and its 6th-order "yoshida6")
    rhs, accel and step must be numba @njit functions over C-contiguous float64 arrays: the engine
    calls them through C function pointers (see rbody/engine/integrators.py)
    observe:   function (t (T,), y (T, B, n)) -> dict of observables (T, B, ...)
    """

    y0: np.ndarray
    params: np.ndarray
    rhs: Any
    observe: Any
    accel: Any = None
    split: Mapping[str, Any] = field(default_factory=dict)
    # A time [s] at which rhs jumps (a rocket's burn-out), shared by the batch, and the params column
    # that tells rhs which side it is on (1 before, 0 after, -1 decide from the state). simulate splits
    # the step that straddles it at the break, so that no step integrates across the jump.
    break_time: float | None = None
    break_column: int | None = None


@dataclass(frozen=True, kw_only=True)
class Scene:
    """Base of every experiment. Subclasses add their parameters and the methods below.

    name:    the scene's identifier (used in file names and reports)
    t_end:   duration [s]
    gravity: magnitude g [m/s^2] along -z (9.81, MuJoCo's default)

    Optional hooks, for physics a Layout cannot hold. The base class does not define them: a backend
    looks them up with getattr and applies those a scene defines (validation.backends.mujoco and
    .pymunk); all are for an unbatched scene and take and return float64 arrays.

    body_mass(t, distance) -> (T,) mass [kg] of the layout's one body, held by one slide joint, at
        times t (T,) [s] and slide coordinates distance (T,) [m] (the rocket, the avalanche). Backends
        set it before every step and hold it over the step.
    slide_force(t, distance, speed) -> (T,) force [N] along that slide axis besides gravity, from t (T,)
        [s], distance (T,) [m] and speed (T,) [m/s] (thrust, drag, momentum given to picked-up mass),
        so that m(t) v' = slide_force + m g . axis.
    pair_force(x1, x2) -> (T, 3) force [N] on body 1 of the layout's two bodies from their centres of
        mass x1, x2 (T, 3) [m], world frame; body 2 feels its opposite (the two-body problem).
    applies_gravity (class flag): False when the scene accepts `gravity` but no body feels it;
        backends then switch gravity off.
    """

    name: str
    t_end: float
    gravity: float = 9.81

    observables: ClassVar[tuple[str, ...]] = ()
    main_observable: ClassVar[str] = ""
    planar: ClassVar[bool] = True          # lives in the x-z plane
    event_driven: ClassVar[bool] = False   # impacts found exactly; no time step in the dynamics
    applies_gravity: ClassVar[bool] = True  # False: the scene accepts `gravity` but no body feels it
                                            # (a table carries the weight, or only internal forces act)
    methods: ClassVar[tuple[str, ...]] = ()  # native methods that apply (empty for event-driven)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name={self.name!r}: a scene needs a non-empty name")
        t_end = finite_array(self.t_end, "t_end")
        if t_end.ndim != 0 or t_end <= 0:
            raise ValueError(f"t_end={self.t_end!r}: must be a single duration > 0 [s]")
        object.__setattr__(self, "t_end", float(t_end))
        object.__setattr__(self, "gravity", float(nonnegative(self.gravity, "gravity")))

    # ----- batches -------------------------------------------------------------------------------

    batch_fields: ClassVar[tuple[str, ...]] = ()  # parameters that may be arrays

    @cached_property
    def batch_shape(self) -> tuple[int, ...]:
        """Broadcast shape of the array-valued parameters; () for a single scene."""
        shapes = [np.shape(getattr(self, name)) for name in self.batch_fields]
        try:
            return tuple(np.broadcast_shapes(*shapes)) if shapes else ()
        except ValueError:
            raise ValueError(
                f"scene {self.name!r}: parameters {dict(zip(self.batch_fields, shapes))} do not broadcast "
                "to one batch shape") from None

    def batched(self, name: str) -> np.ndarray:
        """Parameter `name` broadcast to the batch and flattened to (B,)."""
        return np.broadcast_to(np.asarray(getattr(self, name), dtype=np.float64),
                               self.batch_shape).reshape(-1)

    def unflatten(self, flat) -> Any:
        """A per-element value (B, ...) shaped back to (*batch_shape, ...); a Python scalar when unbatched."""
        shaped = np.asarray(flat).reshape(self.batch_shape + np.shape(flat)[1:])
        return shaped.item() if shaped.ndim == 0 else shaped

    def require_single(self, what: str) -> None:
        """Raise ValueError when the scene is a batch: `what` is defined for one scene only."""
        if self.batch_shape:
            raise ValueError(f"scene {self.name!r} is a batch of shape {self.batch_shape}: {what} is for one "
                             "scene, use scene.item(i)")

    def item(self, index: int | tuple = ()) -> "Scene":
        """One element of a batched scene, as an unbatched scene."""
        if not self.batch_shape:
            return self
        changes = {}
        for name in self.batch_fields:
            value = np.broadcast_to(np.asarray(getattr(self, name), dtype=np.float64), self.batch_shape)
            changes[name] = float(value[index])
        return dataclasses.replace(self, **changes)

    # ----- what each family provides ---------------------------------------------------------------

    @cached_property
    def layout(self) -> Layout:
        """Bodies, joints, fixed shapes and contacts (unbatched scenes only)."""
        self.require_single("the physical layout other simulators build")
        return self._layout()

    def _layout(self) -> Layout:
        raise NotImplementedError(f"{type(self).__name__} has no physical layout")

    def exact(self, t: Iterable[float] | float) -> dict[str, np.ndarray]:
        """Closed-form observables at times t (T,) [s]: each (T, *batch_shape, ...)."""
        raise NotImplementedError(f"{type(self).__name__} has no closed form")

    def observe(self, t: np.ndarray, bodies: Mapping[str, BodyStates],
                joints: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, np.ndarray]:
        """Observables from world-frame body states and joint (qpos, qvel) histories (unbatched)."""
        raise NotImplementedError(f"{type(self).__name__} cannot be observed from body states")

    def native(self) -> NativeModel:
        """The minimal-coordinate model rbody integrates (continuous scenes)."""
        raise NotImplementedError(f"{type(self).__name__} has no time-stepped native model")

    @cached_property
    def native_model(self) -> NativeModel:
        """self.native(), built once per scene (a scene is frozen, so its model never changes); simulate
        and the stability check use it, so repeated runs of one scene skip rebuilding its arrays."""
        return self.native()

    def run_events(self, t_end: float, sample_dt: float | None):
        """Event-driven scenes: the exact event-by-event run (see rbody.engine.events)."""
        raise NotImplementedError(f"{type(self).__name__} is not event-driven")

    def why_not(self, method: str) -> str:
        """Why `method` does not apply to this scene (for the error message)."""
        return f"{type(self).__name__} does not provide what {method!r} needs"

    def describe(self) -> str:
        """One line naming the scene and its parameters, for reports and error messages."""
        return self.name
