"""Where every body of a scene is at every saved time of a run: body poses from a trajectory's observables.

A run reports a scene's own observables (a pendulum's theta, the race's distances, the balls' positions on
their line), the same names from every engine (rbody, MuJoCo, pymunk). To draw the run, or to check it
against a body's position, each body's pose is needed. Every family knows the inverse of its ``observe``:
``Scene.joint_coordinates(trajectory)`` gives the coordinates of the joints of its ``layout`` (the model
MuJoCo and pymunk build) at every saved time, and the layout's forward kinematics (rbody.Multibody, the
engine's one tree walk) place the bodies:

    poses = scene.body_poses(trajectory)     # body name -> BodyPose
    poses["body"].com                        # (T, 3) centre of mass, world frame [m]

The body frame and the centre of mass differ: a Body's ``pos`` places its frame, in which its Inertia gives
the centre of mass ``inertia.com`` and its Shapes their geometry. BodyPose carries both: ``pos`` the frame's
origin, ``com`` = pos + R(quat) inertia.com. A general tree (Scene.from_layout, rbody.from_mjcf) reports each
body's ``"<body>.com"`` and ``"<body>.quat"``: its poses are those, where the engine put the body (pymunk's
pivot joints let a body drift from its joint by up to ~1e-2 m, which a pose from the joint angles would hide);
a trajectory of a tree with ``qpos`` alone is placed from it.

Coordinates a family does not observe stay at their initial value: the rolling layouts' slide along the
incline's normal (a soft contact sinks by ~1e-6 m, invisible), and a rolling body's spin angle is
(distance - integral of slip) / radius, the slip integrated by the trapezoid rule (exact where the body
rolls, and where slip is linear in time, as in every closed form here).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from rbody.layout import JOINTS

from rbody.trajectory import Trajectory

# A scene (rbody.scene.Scene) is read here through what every scene has (name, layout, batch_shape,
# joint_coordinates): this module sits below the scene layer, which calls it.
Scene = Any



@dataclass(frozen=True)
class BodyPose:
    """One body over a run, world frame.

    pos:  (T, 3) origin of the body frame [m]; quat: (T, 4) its orientation (w, x, y, z), body to world;
    com:  (T, 3) centre of mass [m] (pos + R(quat) inertia.com)."""

    pos: np.ndarray
    quat: np.ndarray
    com: np.ndarray


def check_trajectory(scene: "Scene", trajectory: "Trajectory") -> None:
    """ValueError when `trajectory` cannot be a run of `scene`: not a Trajectory, no samples, times not finite or
    decreasing, or a run recorded for another scene (meta["scene"], set by every backend, names another)."""
    if not isinstance(trajectory, Trajectory):
        raise ValueError(f"trajectory={type(trajectory).__name__}: expected an rbody.Trajectory (a run of scene "
                         f"{scene.name!r})")
    t = trajectory.t
    if t.size == 0:
        raise ValueError(f"the trajectory has no samples (t has shape {t.shape})")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise ValueError("the trajectory's times t are not finite and non-decreasing: expected the saved times "
                         "of a run [s]")
    recorded = trajectory.meta.get("scene")
    if recorded is not None and recorded != scene.name:
        raise ValueError(f"the trajectory is a run of scene {recorded!r} (its meta['scene']), not of scene "
                         f"{scene.name!r}")


def observed(scene: "Scene", trajectory: "Trajectory", name: str, shape: tuple[int, ...] = ()) -> np.ndarray:
    """trajectory[name] as a (T, *shape) float array, or ValueError naming what is missing or misshapen (a run of
    another scene, or of a batch): what family joint_coordinates hooks read their observables with."""
    if name not in trajectory:
        raise ValueError(f"the trajectory has no observable {name!r}, which scene {scene.name!r} places its bodies "
                         f"from: is it a run of another scene? It has {sorted(trajectory.observables)}")
    value = np.asarray(trajectory[name], dtype=np.float64)
    expected = (trajectory.t.size,) + tuple(shape)
    if value.shape != expected:
        raise ValueError(f"observable {name!r} has shape {value.shape}, expected {expected} for scene "
                         f"{scene.describe()}: is the trajectory a run of another scene, or of a batch?")
    return value


def integrated(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """(T, ...) integral of rate (T, ...) from t[0] by the trapezoid rule (exact for a rate linear in t)."""
    steps = 0.5 * (rate[1:] + rate[:-1]) * np.diff(t).reshape((-1,) + (1,) * (rate.ndim - 1))
    return np.concatenate([np.zeros_like(rate[:1]), np.cumsum(steps, axis=0)])


def body_poses(scene: "Scene", trajectory: "Trajectory") -> dict[str, BodyPose]:
    """Every body of scene.layout at every saved time of `trajectory`, from the family's
    joint_coordinates (module docstring), in the layout's body order. Raises ValueError (before any work) for a
    batched scene, a scene with no layout, or a trajectory that is not a run of this scene."""
    from rbody.engine.multibody import Multibody

    check_trajectory(scene, trajectory)
    scene.require_single("drawing its bodies")
    try:
        layout = scene.layout
    except NotImplementedError as error:
        raise ValueError(f"scene {scene.name!r} has no bodies to place: {error}") from None
    reported = _reported_poses(scene, trajectory, layout)
    if reported is not None:
        return reported
    coordinates = scene.joint_coordinates(trajectory)
    model = Multibody(layout, gravity=scene.gravity)
    qpos = layout_qpos(model, coordinates, trajectory.t.size)
    if not np.all(np.isfinite(qpos)):
        k = int(np.argmax(~np.all(np.isfinite(qpos), axis=1)))
        raise ValueError(f"the trajectory's coordinates of scene {scene.name!r} are not finite from t = "
                         f"{trajectory.t[k]:.6g} s (a run that blew up): its bodies cannot be placed")
    com, quat = model.body_poses(qpos)
    inertia = {body.name: body.inertia for body in layout.bodies}
    from rbody.motion import quat_to_matrix

    poses = {}
    for i, name in enumerate(model.body_names):
        q = quat[:, i]
        pos = com[:, i] - np.einsum("tab,b->ta", quat_to_matrix(q), inertia[name].com)
        poses[name] = BodyPose(pos=pos, quat=q, com=com[:, i])
    return {body.name: poses[body.name] for body in layout.bodies}


def _reported_poses(scene: "Scene", trajectory: "Trajectory", layout) -> dict[str, BodyPose] | None:
    """The poses from the run's own "<body>.com" and "<body>.quat" (a general tree's observables), where it has
    them for every body: where the engine put each body, whatever its joints say (pymunk's pivots let a body
    drift from its joint by a little); None where it has not."""
    from rbody.motion import quat_to_matrix

    names = [body.name for body in layout.bodies]
    if not all(f"{n}.com" in trajectory and f"{n}.quat" in trajectory for n in names):
        return None
    poses = {}
    for body in layout.bodies:
        com = observed(scene, trajectory, f"{body.name}.com", (3,))
        quat = observed(scene, trajectory, f"{body.name}.quat", (4,))
        if not (np.all(np.isfinite(com)) and np.all(np.isfinite(quat))):
            k = int(np.argmax(~(np.all(np.isfinite(com), axis=1) & np.all(np.isfinite(quat), axis=1))))
            raise ValueError(f"body {body.name!r} of scene {scene.name!r} has no finite pose from t = "
                             f"{trajectory.t[k]:.6g} s (a run that blew up): it cannot be placed")
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        pos = com - np.einsum("tab,b->ta", quat_to_matrix(quat), body.inertia.com)
        poses[body.name] = BodyPose(pos=pos, quat=quat, com=com)
    return poses


def layout_qpos(model, coordinates: Mapping[str, np.ndarray], count: int) -> np.ndarray:
    """(T, nq) qpos of `model` (rbody.Multibody) from joint name -> (T,) or (T, k) coordinates; joints not named
    stay at their initial coordinates. ValueError for a name that is no joint or a misshapen value."""
    qpos = np.repeat(np.asarray(model.qpos0, dtype=np.float64)[None, :], count, axis=0)
    joints = {name: (kind, int(address)) for name, kind, address in
              zip(model.joint_names, model.arrays.joint_kinds, model.arrays.qposadr)}
    for name, value in coordinates.items():
        if name not in joints:
            raise ValueError(f"joint_coordinates names {name!r}, which is no joint of the layout "
                             f"({', '.join(joints)})")
        kind, address = joints[name]
        size = JOINTS[kind].nq
        value = np.asarray(value, dtype=np.float64)
        if value.shape not in ((count, size), (count,) if size == 1 else ()):
            raise ValueError(f"joint {name!r} ({kind}): expected ({count},{'' if size == 1 else f' {size}'}) "
                             f"coordinates, got shape {value.shape}")
        qpos[:, address:address + size] = value.reshape(count, size)
    return qpos
