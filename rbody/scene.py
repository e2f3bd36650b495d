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
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar, Iterable, Mapping

import numpy as np

from rbody.checks import finite_array, nonnegative
from rbody.engine.native import NativeModel, any_batch
from rbody.layout import JOINTS, Layout


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
    # The methods a scene prefers, its default first (simulate takes verlet where it applies, else the first
    # method of `methods`); the methods that apply follow from its native model (Scene.methods).
    preferred_methods: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name={self.name!r}: a scene needs a non-empty name")
        t_end = finite_array(self.t_end, "t_end")
        if t_end.ndim != 0 or t_end <= 0:
            raise ValueError(f"t_end={self.t_end!r}: must be a single duration > 0 [s]")
        object.__setattr__(self, "t_end", float(t_end))
        gravity = nonnegative(self.gravity, "gravity")
        if np.ndim(gravity) != 0:
            raise ValueError(f"gravity={self.gravity!r}: expected one number, the magnitude g >= 0 [m/s^2] along -z")
        object.__setattr__(self, "gravity", float(gravity))

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

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """The inverse of observe(): joint name of `layout` -> its coordinates (T,) (ball (T, 4), free (T, 7),
        MuJoCo's qpos) at every saved time of a run of this scene, from the run's observables; joints not named
        stay at their initial coordinates (rbody.poses). ValueError for a run of another scene."""
        raise NotImplementedError(f"{type(self).__name__} does not place its bodies from its observables")

    def body_poses(self, trajectory) -> dict:
        """Body name -> rbody.poses.BodyPose (frame origin pos (T, 3) [m], quat (T, 4), centre of mass com
        (T, 3) [m], world frame) of every body of `layout` over a run of this scene, from any engine
        (rbody.poses). ValueError, before any work, for a batch or a trajectory of another scene."""
        from rbody.poses import body_poses

        return body_poses(self, trajectory)

    @cached_property
    def native_model(self) -> NativeModel:
        """self.native(), built once per scene (a scene is frozen, so its model never changes); simulate
        and the stability check use it, so repeated runs of one scene skip rebuilding its arrays.
        A scene built on a Multibody (self.multibody) whose model names no diagnose gets one: the body and joint
        whose mass-matrix pivot vanished at a state (Multibody.check_pivots)."""
        model = self.native()
        if model.diagnose is None and getattr(type(self), "multibody", None) is not None:
            model = dataclasses.replace(model, diagnose=self.multibody.diagnosis())
        return model

    def run_events(self, t_end: float, sample_dt: float | None):
        """Event-driven scenes: the exact event-by-event run (see rbody.engine.events)."""
        raise NotImplementedError(f"{type(self).__name__} is not event-driven")

    @property
    def methods(self) -> tuple[str, ...]:
        """Names of the native methods that apply: those whose needs the native model meets (rbody.engine.methods),
        preferred_methods first; () for event-driven scenes."""
        if self.event_driven:
            return ()
        from rbody.engine.methods import applicable

        try:
            model = self.native_model
        except NotImplementedError:  # a scene with no native model: nothing runs it here
            return ()
        return applicable(model, self.preferred_methods)

    def why_not(self, method: str) -> str:
        """Why `method` does not apply to this scene (for the error message): what its record needs that the
        native model does not provide."""
        from rbody.engine.methods import method as record

        if self.event_driven:
            return "the scene is event-driven (its impacts are found exactly; there is no integrator to choose)"
        return record(method).missing(self.native_model) or f"{method!r} applies to this scene"

    def describe(self) -> str:
        """One line naming the scene and its parameters, for reports and error messages."""
        return self.name

    @classmethod
    def from_layout(cls, layout: Layout, *, t_end: float, name: str = "model", qpos0=None, qvel0=None,
                    gravity: float = 9.81, act0=None, ctrl0=None, timestep: float | None = None) -> "TreeScene":
        """Any Layout (a tree of Body and Joint) as a Scene that simulate runs natively: a TreeScene.

        qpos0 (..., nq), qvel0 (..., nv): initial coordinates in MuJoCo's layout (rbody.Multibody), default
        the joints' qpos0/qvel0; leading axes make a batch. act0 (..., na), ctrl0 (..., nu): the actuators'
        initial activations and the control a run holds when given none (default 0); timestep [s]: the model's
        step (actearly's h outside a run). Observables: qpos, qvel, energy, and for every body "<body>.com",
        "<body>.quat", "<body>.velocity", "<body>.omega" (world frame); with actuators ctrl, act, actuator_force.
        Raises ValueError (before any work) for a layout that is not a tree rbody can run.
        """
        return TreeScene(name=name, t_end=t_end, gravity=gravity, tree=layout, qpos0=qpos0, qvel0=qvel0, act0=act0,
                         ctrl0=ctrl0, timestep=timestep)


# ----- any tree of bodies and joints, as a scene -------------------------------------------------------

TREE_GENERAL_METHODS = ("rk4", "gauss6", "euler", "mujoco_euler", "implicitfast", "implicit", "reference")
TREE_SYMPLECTIC_METHODS = ("verlet", "symplectic_euler", "yoshida6")


@dataclass(frozen=True, kw_only=True, eq=False)
class TreeScene(Scene):
    """A user's tree of bodies and joints, simulated by the general engine (rbody.Multibody).

    tree:   the Layout (bodies, joints, limits, equalities, contacts: rbody.engine.constraints)
    qpos0:  (..., nq) initial qpos, MuJoCo's layout, or None (the joints' own qpos0); leading axes: a batch
    qvel0:  (..., nv) initial qvel (free joints: world linear velocity of the body-frame origin, then the
            body-frame angular velocity; ball: body-frame angular velocity), or None (the joints' qvel0)
    act0:   (..., na) initial activations of the actuators with dynamics (MuJoCo's act), default 0
    ctrl0:  (..., nu) the control a run holds when simulate is given none (a keyframe's ctrl), default 0
    import_notes, integrator: what an MJCF importer records (no effect on the dynamics)
    timestep: the model's time step [s] (MJCF's option timestep), or None; the h that actearly's next activation
            uses outside a run (rbody.Multibody.actuation); a run uses its own dt

    Observables: qpos (T, *batch, nq), qvel (T, *batch, nv), energy (T, *batch) [J] (kinetic + gravity +
    springs), and per body "<body>.com" (T, *batch, 3) [m], "<body>.quat" (T, *batch, 4),
    "<body>.velocity" (T, *batch, 3) [m/s] of the centre of mass, "<body>.omega" (T, *batch, 3) [rad/s],
    world frame; with actuators also ctrl (T, *batch, nu) (the control held through the step that starts at each
    saved time; at the last, the last step's), actuator_force (T, *batch, nu) [N or N m] (MuJoCo's
    actuator_force at that state and control) and act (T, *batch, na). The native state is (qpos, qvel, phi[,
    act]): each ball or free joint's rotation within a step is q_n (x) exp(phi) (Runge-Kutta-Munthe-Kaas),
    folded into q_n after every step, so quaternions stay unit by construction and every method keeps its
    order. A tree with tendons or actuators runs on the 3-D path (rbody.engine.system), never the planar one.
    """

    tree: Layout
    qpos0: Any = None
    qvel0: Any = None
    act0: Any = None
    ctrl0: Any = None
    import_notes: tuple[str, ...] = ()
    timestep: float | None = None
    integrator: str | None = None

    main_observable: ClassVar[str] = "qpos"
    planar: ClassVar[bool] = False

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.tree, Layout):
            raise ValueError(f"layout={self.tree!r}: expected an rbody.Layout")
        model = self.multibody  # validates the tree (ValueError before any work)
        qpos0, qvel0 = self._checked_state(self.qpos0, self.qvel0, model.qpos0, model.qvel0)
        object.__setattr__(self, "qpos0", qpos0)
        object.__setattr__(self, "qvel0", qvel0)
        for field_name, size in (("act0", model.na), ("ctrl0", model.nu)):
            value = getattr(self, field_name)
            array = np.zeros(size) if value is None else np.array(value, dtype=np.float64)
            if array.ndim == 0 or array.shape[-1] != size:
                raise ValueError(f"{field_name} has shape {array.shape}: expected (..., {size}) for this tree "
                                 f"(na={model.na}, nu={model.nu})")
            if not np.all(np.isfinite(array)):
                raise ValueError(f"{field_name} holds NaN or inf: expected finite numbers")
            array.setflags(write=False)
            object.__setattr__(self, field_name, array)
        try:
            np.broadcast_shapes(*(getattr(self, name).shape[:-1] for name in ("qpos0", "qvel0", "act0", "ctrl0")))
        except ValueError:
            raise ValueError(f"qpos0 {self.qpos0.shape}, qvel0 {self.qvel0.shape}, act0 {self.act0.shape} and ctrl0 "
                             f"{self.ctrl0.shape} do not broadcast to one batch") from None
        _ = self.constraint_table  # validates the limits, friction and equalities (ValueError before any work)

    def _checked_state(self, qpos0: Any, qvel0: Any, qpos_default: np.ndarray,
                       qvel_default: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """qpos0 (..., nq) and qvel0 (..., nv) as read-only float64 arrays (None: the default), checked: shapes
        that broadcast to one batch, finite numbers, unit quaternions, a mass matrix regular there."""
        model = self.multibody
        arrays = []
        for field_name, value, size, default in (("qpos0", qpos0, model.nq, qpos_default),
                                                 ("qvel0", qvel0, model.nv, qvel_default)):
            array = default.copy() if value is None else np.array(value, dtype=np.float64)
            if array.ndim == 0 or array.shape[-1] != size:
                raise ValueError(f"{field_name} has shape {array.shape}: expected (..., {size}) for this tree "
                                 f"(nq={model.nq}, nv={model.nv})")
            if not np.all(np.isfinite(array)):
                raise ValueError(f"{field_name} holds NaN or inf: expected finite numbers")
            array.setflags(write=False)
            arrays.append(array)
        qpos0, qvel0 = arrays
        try:
            np.broadcast_shapes(qpos0.shape[:-1], qvel0.shape[:-1])
        except ValueError:
            raise ValueError(f"qpos0 of shape {qpos0.shape} and qvel0 of shape {qvel0.shape} do not "
                             "broadcast to one batch") from None
        quats = self._quaternion_columns()
        if quats:
            norms = np.stack([np.linalg.norm(qpos0[..., c:c + 4], axis=-1) for c in quats])
            if np.any(np.abs(norms - 1.0) > 1e-9):
                raise ValueError(f"qpos0: the quaternions at qpos columns {quats} have lengths "
                                 f"{np.unique(np.round(norms, 12)).tolist()}: expected unit quaternions")
        from rbody.engine.precision import angle_spacing_problem

        count = int(np.prod(qpos0.shape[:-1])) if qpos0.ndim > 1 else 1  # explicit: nq may be 0
        problem = angle_spacing_problem(model, qpos0.reshape(count, model.nq))
        if problem:
            raise ValueError(f"tree {self.name!r} cannot be carried in float64 by this engine: {problem}")
        model.check_pivots(qpos0)
        return qpos0, qvel0

    def precision_problem(self, dt: float, t_end: float) -> str | None:
        """Why float64 cannot carry this tree over a run of t_end [s] at step dt [s] (str), or None: a hinge angle whose
        rounding passes a millionth of what a step moves it (rbody.engine.precision). simulate asks before any step.
        (Coordinates far from the origin lose no digits: each tree is computed about its own origin.)"""
        from rbody.engine import stability
        from rbody.engine.precision import angle_step_problem

        qpos, qvel = self._state0()
        return angle_step_problem(self.multibody, qpos, qvel, dt, lambda: float(np.max(stability.fastest_rate(self, None))))

    @cached_property
    def multibody(self):
        """rbody.Multibody of the tree with its tendons and actuators (validated on first use)."""
        from rbody.engine.system import DEFAULT_TIMESTEP, Multibody

        return Multibody(self.tree, gravity=self.gravity, timestep=self.timestep or DEFAULT_TIMESTEP)

    def _quaternion_columns(self) -> list[int]:
        model = self.multibody
        columns = []
        for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
            if kind == "ball":
                columns.append(int(address))
            elif kind == "free":
                columns.append(int(address) + 3)
        return columns

    # ----- batches ---------------------------------------------------------------------------------

    @cached_property
    def batch_shape(self) -> tuple[int, ...]:
        return tuple(np.broadcast_shapes(*(getattr(self, name).shape[:-1]
                                           for name in ("qpos0", "qvel0", "act0", "ctrl0"))))

    def _rows(self, value: np.ndarray, size: int) -> np.ndarray:
        """value (..., size) broadcast to the batch, as (B, size) (B explicit: size may be 0)."""
        count = int(np.prod(self.batch_shape)) if self.batch_shape else 1
        return np.broadcast_to(value, self.batch_shape + (size,)).reshape(count, size)

    def _state0(self) -> tuple[np.ndarray, np.ndarray]:
        """qpos0 (B, nq), qvel0 (B, nv)."""
        model = self.multibody
        return self._rows(self.qpos0, model.nq), self._rows(self.qvel0, model.nv)

    def _controls0(self) -> tuple[np.ndarray, np.ndarray]:
        """act0 (B, na), ctrl0 (B, nu)."""
        model = self.multibody
        return self._rows(self.act0, model.na), self._rows(self.ctrl0, model.nu)

    def native_start(self, qpos0: Any = None, qvel0: Any = None, method: str | None = None) -> np.ndarray:
        """y0 (B, n) of the native model a run by `method` integrates (native_model_for) from qpos0 (..., nq) and
        qvel0 (..., nv) (None: the scene's own), checked as the scene's own are; its batch is their broadcast shape
        flattened (rbody.simulation.PreparedRun.run); the activations are the scene's act0."""
        from rbody.engine.mujoco_steps import MUJOCO_METHODS

        qpos0, qvel0 = self._checked_state(qpos0, qvel0, self.qpos0, self.qvel0)
        shape = np.broadcast_shapes(qpos0.shape[:-1], qvel0.shape[:-1])
        qpos = np.broadcast_to(qpos0, shape + qpos0.shape[-1:]).reshape(-1, qpos0.shape[-1])
        qvel = np.broadcast_to(qvel0, shape + qvel0.shape[-1:]).reshape(-1, qvel0.shape[-1])
        planar = self._planar is not None and method not in MUJOCO_METHODS
        return self._native_state(qpos, qvel, planar=planar)

    def _native_state(self, qpos: np.ndarray, qvel: np.ndarray, planar: bool = False) -> np.ndarray:
        """y (B, n) from qpos (B, nq), qvel (B, nv): (qpos, qvel) on the planar path, (qpos, qvel, phi = 0) on the
        3-D engine's (a rotation vector per ball or free joint), then the activations act0 where the actuators have
        some (rbody.engine.system), then the energy dissipated so far (0) on a constrained tree's."""
        if planar:
            return np.concatenate([qpos, qvel], axis=1)
        model = self.multibody
        count = qpos.shape[0]
        parts = [qpos, qvel, np.zeros((count, 3 * model.nrot))]
        if model.na:
            act0 = np.asarray(self.act0)
            if act0.ndim > 1 and count != int(np.prod(act0.shape[:-1])):
                raise ValueError(f"act0 of shape {act0.shape} has another batch than the {count} states given")
            parts.append(np.broadcast_to(act0.reshape(-1, model.na), (count, model.na)))
        if self.tree.constrained:
            parts.append(np.zeros((count, 1)))
        return np.concatenate(parts, axis=1)

    @cached_property
    def _planar(self):
        """The planar kernels' model of the tree (rbody.engine.planar.planar_model), or None when it is 3-D (or has
        force elements: rbody.engine.system runs those on the 3-D path)."""
        from rbody.engine.planar import planar_model

        if self.multibody.has_elements or self.tree.constrained:
            return None
        return planar_model(self.multibody)

    def item(self, index: int | tuple = ()) -> "TreeScene":
        if not self.batch_shape:
            return self
        qpos0, qvel0 = self._state0()
        act0, ctrl0 = self._controls0()
        flat = np.arange(qpos0.shape[0]).reshape(self.batch_shape)[index]
        if np.ndim(flat) != 0:
            raise ValueError(f"index={index!r} picks {np.shape(flat)} trees from batch {self.batch_shape}: expected one")
        k = int(flat)
        return dataclasses.replace(self, qpos0=qpos0[k].copy(), qvel0=qvel0[k].copy(), act0=act0[k].copy(),
                                   ctrl0=ctrl0[k].copy())

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return (self.name, self.t_end, self.gravity, self.tree, self.import_notes, self.timestep, self.integrator) == (
            other.name, other.t_end, other.gravity, other.tree, other.import_notes, other.timestep,
            other.integrator) and all(np.array_equal(getattr(self, name), getattr(other, name))
                                      for name in ("qpos0", "qvel0", "act0", "ctrl0"))

    __hash__ = None  # type: ignore[assignment]

    # ----- observables ------------------------------------------------------------------------------

    @property
    def observables(self) -> tuple[str, ...]:  # type: ignore[override]
        model = self.multibody
        names = ["qpos", "qvel", "energy"]
        if self.tree.constrained:
            names += ["constraint_force", "constraint_error", "active_limits", "sticking", "dissipated"]
        if self.tree.contacts:
            names += ["contacts", "contact_distance", "contact_point", "contact_normal", "contact_normal_force",
                      "contact_friction_force", "contact_spin_torque", "contact_rolling_torque"]
        if model.nu:
            names += ["ctrl", "actuator_force"] + (["act"] if model.na else [])
        for body in model.body_names:
            names += [f"{body}.com", f"{body}.quat", f"{body}.velocity", f"{body}.omega"]
        return tuple(names)

    def _observables(self, qpos: np.ndarray, qvel: np.ndarray, act: np.ndarray | None = None,
                     ctrl: np.ndarray | None = None, step: float | None = None) -> dict[str, Any]:
        """From qpos (T, B, nq) and qvel (T, B, nv) (with actuators, act (T, B, na), ctrl (T, B, nu) and the run's
        step [s]): qpos, qvel, act and ctrl as given, the rest lazily (callables)."""
        model = self.multibody
        states: dict[str, np.ndarray] = {}

        def body_states():
            if not states:
                states.update(model.body_states(qpos, qvel))
            return states

        def energy():
            return model.kinetic_energy(qpos, qvel) + model.potential_energy(qpos)

        data: dict[str, Any] = {"qpos": qpos, "qvel": qvel, "energy": energy}
        if model.nu and ctrl is not None:
            act = np.zeros(qpos.shape[:-1] + (0,)) if act is None else act

            def actuator_force():
                return model.actuation(qpos, qvel, ctrl, act, timestep=step)["force"]

            data.update(ctrl=ctrl, actuator_force=actuator_force)
            if model.na:
                data["act"] = act
        for i, body in enumerate(model.body_names):
            for what in ("com", "quat", "velocity", "omega"):
                data[f"{body}.{what}"] = (lambda i=i, what=what: body_states()[what][..., i, :])
        return data

    def exact(self, t) -> dict[str, np.ndarray]:
        raise NotImplementedError(
            f"scene {self.name!r} is a user's tree of bodies and joints: it has no closed-form motion; check a run by "
            "its energy and against simulate(scene, dt=..., method='reference') (scipy DOP853 at rtol 1e-13)")

    # ----- native model ----------------------------------------------------------------------------

    @cached_property
    def symplectic_applies(self) -> str:
        """"" when q'' = a(q) with a constant mass matrix (the explicit symplectic methods apply), else why not.

        Decided from the structure: no ball or free joint (their rotations make M and the gyroscopic forces
        depend on the state), no damping, and every hinge alone in its part of the tree (no other degree of
        freedom above or below it: a hinge with a moving ancestor or descendant couples them through the
        angle). Chains of slides alone keep M constant too."""
        from rbody.engine.multibody import BALL, D_PARENT, DOF_SIZE, FREE, H_DOF, HINGE, KIND_CODE, ROLL

        model = self.multibody
        if model.has_elements:
            return "the tree has tendons or actuators (forces that depend on velocities and controls)"
        kinds = [KIND_CODE[k] for k in model.arrays.joint_kinds]
        if any(k in (BALL, FREE) for k in kinds):
            return "the tree has a ball or free joint (its mass matrix and gyroscopic forces depend on the state)"
        if any(j.damping != 0 for j in self.tree.joints):
            return "a joint has damping (the force depends on the velocity)"
        p = model.params
        parent = [int(p[int(p[H_DOF]) + d * DOF_SIZE + D_PARENT]) for d in range(model.nv)]
        related = [set() for _ in range(model.nv)]
        for d in range(model.nv):
            k = parent[d]
            while k >= 0:
                related[d].add(k)
                related[k].add(d)
                k = parent[k]
        for d in range(model.nv):
            kind = kinds[model.arrays.dof_joint[d]]
            joint = model.joint_names[model.arrays.dof_joint[d]]
            if kind in (HINGE, ROLL) and related[d]:
                return (f"{model.arrays.joint_kinds[model.arrays.dof_joint[d]]} {joint!r} shares its branch of the "
                        "tree with other joints, so the mass matrix depends on its angle")
            if kind == ROLL and not self._roll_inertia_constant(d):
                return (f"roll {joint!r} carries its centre of mass off its axis, so the mass matrix depends on its "
                        "angle")
        return ""

    def _roll_inertia_constant(self, dof: int) -> bool:
        """True when M of a roll degree of freedom alone in its branch is the same at every angle. That entry is
        m a^2 + I_axis + 2 m a (l . (n x r)), r the centre of mass from the axis turned by the angle: a
        trigonometric polynomial of degree 1, constant exactly when it takes one value at three angles."""
        model = self.multibody
        q = np.repeat(np.asarray(model.qpos0)[None], 3, axis=0)
        q[:, int(model.arrays.qposadr[model.arrays.dof_joint[dof]])] += (0.0, 2.0, 4.0)
        values = model.mass_matrix(q)[:, dof, dof]
        return bool(np.ptp(values) <= 1e-12 * np.max(np.abs(values)))

    preferred_methods: ClassVar[tuple[str, ...]] = TREE_SYMPLECTIC_METHODS + TREE_GENERAL_METHODS

    @property
    def _ellipsoid_fluid(self) -> bool:
        """Whether a geom feels MuJoCo's ellipsoid fluid model (whose velocity derivative rbody does not form)."""
        return bool(self.tree.fluid is not None and self.tree.fluid.ellipsoids)

    def why_not(self, method: str) -> str:
        if method in ("implicit", "implicitfast") and self._ellipsoid_fluid:
            return (f"{method!r} differentiates MuJoCo's ellipsoid fluid model analytically (engine_derivative.c "
                    "mjd_ellipsoidFluid), which rbody does not (the inertia-box model's it does): use mujoco_euler or "
                    "rk4")
        if method in TREE_SYMPLECTIC_METHODS:
            return f"{method!r} needs q'' = a(q) with a constant mass matrix, and {self.symplectic_applies}"
        if self.tree.constrained:  # the constraint layer's own reason (rbody.engine.methods.Method.missing)
            from rbody.engine.methods import method as record

            missing = record(method).missing(self.native_model)
            if missing:
                return missing
        return f"{method!r} is not a method of a general tree (no splitting into exact flows)"

    def native(self) -> NativeModel:
        """The compiled model of the tree: the planar kernels (rbody.engine.planar: 3-component spatial
        algebra) when the tree is planar, decided from its structure, else the 3-D engine's. Observables and
        energies use the 3-D Multibody either way (once per saved sample, not per evaluation). MuJoCo's
        integrators (mujoco_euler, implicitfast, implicit: rbody.engine.mujoco_steps) run the 3-D rows
        (native_model_for); their stability rate is the stiffness's (rates_for)."""
        model = self.multibody
        if self.tree.constrained:  # the constraint layer's own schemes and stability check (rbody.engine.constraints)
            return self._constrained_native()
        native = self._native_with_elements() if model.has_elements else self._native_tree()
        return dataclasses.replace(native, rate=self.rates_for(native))

    def family_native(self) -> NativeModel:
        """native() for a chapter family that runs this tree inside a model of its own (rbody.scenes: chains,
        pendulums, rolling): without MuJoCo's integrators where the model is planar, because those step the 3-D
        engine's rows, which only a TreeScene's own runs swap in (native_model_for)."""
        from rbody.engine.mujoco_steps import MUJOCO_METHODS
        from rbody.engine.planar import planar_rhs

        model = self.native()
        if model.rhs is planar_rhs:
            model = dataclasses.replace(model, split={name: step for name, step in model.split.items()
                                                      if name not in MUJOCO_METHODS})
        return model

    def native_model_for(self, method: str | None) -> NativeModel:
        """The native model a run by `method` integrates: native_model, except that a planar tree runs MuJoCo's
        integrators on the 3-D engine's rows (rbody.engine.mujoco_steps reads those)."""
        from rbody.engine.mujoco_steps import MUJOCO_METHODS
        from rbody.engine.planar import planar_rhs

        model = self.native_model
        if method in MUJOCO_METHODS and model.rhs is planar_rhs:
            return dataclasses.replace(self._native_tree(planar=False), rate=model.rate)
        return model

    def rates_for(self, native: NativeModel):
        """rate(method) -> (B,) [1/s] for the stability check of `native` (this tree's native model, or one whose y0 a
        prepared run replaced): the spectral radius of df/dy at its y0 (every method but
        MuJoCo's); for MuJoCo's integrators, whose damping is implicit where they solve for it, 2 / h* with h* the
        largest step their linearised one-step map stays stable at (rbody.engine.mujoco_stability), from the blocks
        d qacc / d q and d qacc / d qvel of the same Jacobian (q the coordinates tangent to the configuration:
        hinge, slide and free translations, each ball and free rotation's phi)."""
        from rbody.engine.mujoco_stability import step_rate, unclamped
        from rbody.engine.mujoco_steps import MUJOCO_METHODS
        from rbody.engine.planar import planar_rhs
        from rbody.engine.stability import jacobian_matrices, jacobian_rate

        model = self.multibody
        if native.rhs is planar_rhs:
            rows, columns = np.arange(model.nv, 2 * model.nv), np.arange(model.nv)
            velocities = np.arange(model.nv, 2 * model.nv)
        else:
            rows, columns = np.arange(model.nq, model.nq + model.nv), self._tangent_columns()
            velocities = np.arange(model.nq, model.nq + model.nv)

        def rate(method):
            if model.nv == 0:  # nothing moves (a model of fixed bodies): no rate, any step
                return np.zeros(native.y0.shape[0])
            if method not in MUJOCO_METHODS:
                source = self._starting_motion(native)
                return jacobian_rate(source.rhs, source.y0, source.params)
            source = native
            if native.constraints is not None:  # the time-stepping's free motion is the tree's own MuJoCo step, its
                # constraints impulses and projections (which take no energy in): that step's stability is the run's
                source = self._free_motion(native)
            stepped = self._native_tree(planar=False) if source.rhs is planar_rhs else source
            rates = []
            for params in (source.params, unclamped(source.params)) if model.has_elements else (source.params,):
                jacobians = jacobian_matrices(source.rhs, source.y0, params)[:, rows]
                rates.append(step_rate(method, jacobians[:, :, columns], jacobians[:, :, velocities], stepped.y0,
                                       params if model.has_elements else stepped.params, model.has_elements))
            return np.max(rates, axis=0)
        return rate

    def _free_motion(self, native: NativeModel) -> NativeModel:
        """The tree's own native model (its force elements included) at a constrained native's initial states: y0
        without the dissipated energy, the constrained params row (the tree's kernels read its head only)."""
        free = self._native_with_elements() if self.multibody.has_elements else self._native_tree(planar=False)
        return dataclasses.replace(free, y0=np.ascontiguousarray(native.y0[:, :free.y0.shape[1]]), params=native.params)

    def _starting_motion(self, native: NativeModel) -> NativeModel:
        """The model whose Jacobian at y0 gives a constrained native's rate: its motion in the starting mode (the
        equalities held, every contact apart: ConstraintTable.mode0), read without the contacts' candidates
        (ConstraintTable.without_contacts), and the free tree's own model where no other unit is left. The same
        motion, so the same rate, at the cost of the tree's: a layer of 400 spheres (80,200 candidates) took 560 s
        and 9.5 GB in the check that read them all."""
        table = native.constraints
        if table is None or table.contact0 == len(table.units):
            return native
        if np.any(native.params[:, table.mode_slice()][:, table.contact0:] != 0.0):  # a contact held: read them all
            return native
        if table.contact0 == 0:  # (the tree's rhs leaves entries past phi and act unwritten: y0 without the energy)
            return dataclasses.replace(self._free_motion(native), y0=np.ascontiguousarray(native.y0[:, :-1]))
        return dataclasses.replace(native, params=table.without_contacts(native.params))

    def _tangent_columns(self) -> np.ndarray:
        """(nv,) the columns of the 3-D state y that move each degree of freedom's coordinate (module docstring of
        rbody.engine.multibody: hinge, slide, roll and free translations in qpos, rotations as phi)."""
        model = self.multibody
        columns, slot = [], 0
        for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
            if kind == "free":
                columns += [int(address) + k for k in range(3)]
            if kind in ("free", "ball"):
                columns += [model.nq + model.nv + 3 * slot + k for k in range(3)]
                slot += 1
            elif kind != "free":
                columns.append(int(address))
        return np.array(columns, dtype=np.int64)

    def _native_tree(self, planar: bool = True) -> NativeModel:
        """The compiled model of a tree without force elements: planar where it can be (and `planar`), else 3-D."""
        from rbody.engine import multibody as mb
        from rbody.engine.mujoco_steps import mujoco_steps
        from rbody.engine.planar import planar_accel, planar_rhs, planar_rhs_lanes

        model = self.multibody
        qpos0, qvel0 = self._state0()
        planar = self._planar if planar else None
        y0 = self._native_state(qpos0, qvel0, planar=planar is not None)
        if planar is not None:
            nv = model.nv

            @any_batch
            def observe_planar(t, y):
                return self._observables(y[..., :nv], y[..., nv:])

            return NativeModel(y0=y0, params=np.tile(planar.row, (qpos0.shape[0], 1)), rhs=planar_rhs,
                               observe=observe_planar, accel=None if self.symplectic_applies else planar_accel,
                               rate_from_jacobian=True, rhs_lanes=planar_rhs_lanes, split=mujoco_steps(False))
        params = np.tile(np.asarray(model.params), (qpos0.shape[0], 1))
        nq, nv = model.nq, model.nv

        @any_batch
        def observe(t, y):
            return self._observables(y[..., :nq], y[..., nq:nq + nv])

        return NativeModel(y0=y0, params=params, rhs=mb.tree_rhs, observe=observe,
                           accel=None if self.symplectic_applies else mb.tree_accel,
                           finish=mb.tree_finish if model.nrot else None, rate_from_jacobian=True,
                           rhs_lanes=mb.tree_rhs_lanes if mb.runs_in_lanes(model) else None,
                           split=mujoco_steps(False))

    def _native_with_elements(self) -> NativeModel:
        """The compiled model of a tree with tendons or actuators (rbody.engine.system): y = (qpos, qvel, phi,
        act), the controls ctrl0 written into every params row; the observables take the controls a run held
        (rbody.control passes them, with the run's step), else read them from the rows."""
        from rbody.engine import system
        from rbody.engine.mujoco_steps import mujoco_steps

        model = self.multibody
        qpos0, qvel0 = self._state0()
        act0, ctrl0 = self._controls0()
        slots = model.control_slots()
        y0 = np.concatenate([qpos0, qvel0, np.zeros((qpos0.shape[0], 3 * model.nrot)), act0], axis=1)
        params = np.tile(np.asarray(model.params), (qpos0.shape[0], 1))
        params[:, slots.ctrl:slots.ctrl + model.nu] = ctrl0
        nq, nv, a0, na = model.nq, model.nv, slots.act, model.na

        def observe(t, y, ctrl=None, step=None):
            if ctrl is None:
                ctrl = np.broadcast_to(params[None, :, slots.ctrl:slots.ctrl + model.nu], y.shape[:-1] + (model.nu,))
            return self._observables(y[..., :nq], y[..., nq:nq + nv], y[..., a0:a0 + na], ctrl, step)

        return NativeModel(y0=y0, params=params, rhs=system.system_rhs, observe=observe, accel=None,
                           finish=system.system_finish, rate_from_jacobian=True, controls=slots,
                           split={name: step for name, step in mujoco_steps(True).items()
                                  if name == "mujoco_euler" or not self._ellipsoid_fluid})

    @cached_property
    def constraint_table(self):
        """The compiled constraints of the tree (rbody.engine.constraints.table), or None when it has none."""
        from rbody.engine.constraints.table import build_table

        return build_table(self.tree, self.multibody) if self.tree.constrained else None

    def _constrained_native(self) -> NativeModel:
        """The tree with its limits, dry friction and equalities: state (qpos, qvel, phi, act, dissipated), params the
        tree's row, its force elements (actuators with the controls ctrl0 written in, tendons, gravity
        compensation, fluid: part of the smooth forces) and the constraint table, run by the constraint layer
        (rbody.engine.constraints). Its stability rate (rates_for): the Jacobian's of the motion in the starting mode
        (the equalities held), and for MuJoCo's integrators, the time-stepping's free motion, their step's."""
        from rbody.engine.constraints.dynamics import constrained_rhs

        model, table = self.multibody, self.constraint_table
        qpos0, qvel0 = self._state0()
        act0, _ctrl0 = self._controls0()
        count = qpos0.shape[0]
        y0 = np.concatenate([qpos0, qvel0, np.zeros((count, 3 * model.nrot)), act0, np.zeros((count, 1))], axis=1)
        params = np.tile(table.row(model.params), (count, 1))
        nq, nv, na = model.nq, model.nv, model.na
        a0 = nq + nv + 3 * model.nrot
        slots = model.control_slots() if model.nu else None
        if slots is not None:
            _act0, ctrl0 = self._controls0()
            params[:, slots.ctrl:slots.ctrl + model.nu] = ctrl0

        def observe(t, y, ctrl=None, step=None):
            if slots is not None and ctrl is None:
                ctrl = np.broadcast_to(params[None, :, slots.ctrl:slots.ctrl + model.nu], y.shape[:-1] + (model.nu,))
            return self._observables(y[..., :nq], y[..., nq:nq + nv], y[..., a0:a0 + na], ctrl, step)

        if self._ellipsoid_fluid:  # as for a free tree: implicit and implicitfast need its velocity derivative
            table = dataclasses.replace(table, methods=tuple(name for name in table.methods
                                                             if name not in ("implicit", "implicitfast")))
        native = NativeModel(y0=y0, params=params, rhs=constrained_rhs, observe=observe, rate_from_jacobian=True,
                             constraints=table, controls=slots)
        return dataclasses.replace(native, rate=self.rates_for(native))

    # ----- what other simulators build -----------------------------------------------------------------

    def _layout(self) -> Layout:
        """The tree with the first batch element's initial state in its joints (and free bodies' pos/quat)."""
        model = self.multibody
        qpos, qvel = (a[0] for a in self._state0())
        from rbody.motion import quat_to_matrix

        joints, bodies = [], {b.name: b for b in self.tree.bodies}
        by_name = dict(zip(model.joint_names, zip(model.arrays.joint_kinds, model.arrays.qposadr, model.arrays.dofadr)))
        for joint in self.tree.joints:
            kind, qa, da = by_name[joint.name]
            if kind in ("hinge", "slide", "roll"):
                joints.append(dataclasses.replace(joint, qpos0=float(qpos[qa]), qvel0=float(qvel[da])))
            elif kind == "ball":
                joints.append(dataclasses.replace(joint, qpos0=tuple(qpos[qa:qa + 4].tolist()),
                                                  qvel0=tuple(qvel[da:da + 3].tolist())))
            else:
                quat = qpos[qa + 3:qa + 7]
                omega_world = quat_to_matrix(quat) @ qvel[da + 3:da + 6]
                joints.append(dataclasses.replace(joint, qvel0=tuple(qvel[da:da + 3].tolist() + omega_world.tolist())))
                bodies[joint.body] = dataclasses.replace(bodies[joint.body], pos=tuple(qpos[qa:qa + 3].tolist()),
                                                         quat=tuple(quat.tolist()))
        return dataclasses.replace(self.tree, bodies=tuple(bodies[b.name] for b in self.tree.bodies),
                                   joints=tuple(joints))

    def observe(self, t, bodies, joints) -> dict[str, np.ndarray]:
        """From a backend's joint histories (hinge, slide: (qpos (T,), qvel (T,)); ball, free: (qpos (T, 4|7),
        qvel (T, 3|6)), MuJoCo's conventions) and body states: the same observables as the native run."""
        model = self.multibody
        count = np.asarray(t).shape[0]
        qpos, qvel = np.empty((count, model.nq)), np.empty((count, model.nv))
        for name, kind, qa, da in zip(model.joint_names, model.arrays.joint_kinds, model.arrays.qposadr,
                                      model.arrays.dofadr):
            if name not in joints:
                raise ValueError(f"the backend reported no history for joint {name!r}")
            position, velocity = (np.asarray(a, dtype=np.float64).reshape(count, -1) for a in joints[name])
            nq_j, nv_j = JOINTS[kind].nq, JOINTS[kind].nv
            qpos[:, qa:qa + nq_j], qvel[:, da:da + nv_j] = position, velocity
        data = {"qpos": qpos, "qvel": qvel,
                "energy": model.kinetic_energy(qpos, qvel) + model.potential_energy(qpos)}
        for body in model.body_names:
            states = bodies[body]
            data.update({f"{body}.com": states.com, f"{body}.quat": states.quat,
                         f"{body}.velocity": states.velocity, f"{body}.omega": states.omega})
        return data

    def joint_coordinates(self, trajectory) -> dict[str, np.ndarray]:
        """Each joint's columns of the run's qpos (T, nq)."""
        from rbody.poses import observed

        model = self.multibody
        qpos = observed(self, trajectory, "qpos", (model.nq,))
        return {name: qpos[:, int(a):int(a) + JOINTS[kind].nq] for name, kind, a in
                zip(model.joint_names, model.arrays.joint_kinds, model.arrays.qposadr)}

    def describe(self) -> str:
        model = self.multibody
        batch = f", batch {self.batch_shape}" if self.batch_shape else ""
        return f"{self.name}({len(model.body_names)} bodies, nq={model.nq}, nv={model.nv}{batch})"
