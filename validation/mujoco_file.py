"""MuJoCo running a user's own MJCF file, as the user runs it: the file compiled by MuJoCo itself (never rbody's
re-export), its own integrator and time step unless told otherwise, from its reference pose, a keyframe or a given
state, under the same controls rbody is given.

    run = run_file("robot.xml", t_end=2.0, keyframe="home", ctrl=schedule, scene=rbody_scene)

The observables are named as rbody names them (validation.comparison compares them pair by pair): qpos, qvel
(MuJoCo's layout, which rbody's from_mjcf keeps), act, ctrl (the control held through the step that starts at each
saved time), actuator_force, and per body "<body>.com", ".quat", ".velocity" (of the centre of mass) and ".omega"
(world frame), bodies named as rbody names them (an unnamed body: body<id>); energy where the rbody scene of the file
is given (its definition: kinetic without armature, gravity and joint springs, from MuJoCo's qpos and qvel).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from rbody.trajectory import Trajectory

INTEGRATORS = {"Euler": mujoco.mjtIntegrator.mjINT_EULER, "RK4": mujoco.mjtIntegrator.mjINT_RK4,
               "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT, "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}


def integrator_name(model: mujoco.MjModel) -> str:
    """The model's integrator as MJCF spells it (Euler, RK4, implicit, implicitfast)."""
    return {int(v): k for k, v in INTEGRATORS.items()}[int(model.opt.integrator)]


def load(path: str | Path) -> mujoco.MjModel:
    """MuJoCo's compiled model of the file (ValueError naming the file and MuJoCo's message when it refuses)."""
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except Exception as error:  # mujoco raises ValueError, or its own error types
        raise ValueError(f"MuJoCo cannot compile {str(path)!r}: {error}") from None


def initial_state(model: mujoco.MjModel, data: mujoco.MjData, keyframe=None, qpos0=None, qvel0=None) -> None:
    """data at the reference pose (qpos0 at rest), or keyframe (an index or a name), then qpos0 / qvel0 over it."""
    mujoco.mj_resetData(model, data)
    if keyframe is not None:
        index = keyframe if isinstance(keyframe, (int, np.integer)) else mujoco.mj_name2id(
            model, mujoco.mjtObj.mjOBJ_KEY, str(keyframe))
        if not 0 <= index < model.nkey:
            raise ValueError(f"keyframe={keyframe!r}: the model has {model.nkey} keyframes "
                             f"{[model.key(i).name for i in range(model.nkey)]}")
        mujoco.mj_resetDataKeyframe(model, data, int(index))
    for value, target, what in ((qpos0, data.qpos, "qpos0"), (qvel0, data.qvel, "qvel0")):
        if value is not None:
            array = np.asarray(value, dtype=np.float64)
            if array.shape != target.shape:
                raise ValueError(f"{what} has shape {array.shape}: the model needs {target.shape}")
            target[:] = array


def body_names(model: mujoco.MjModel) -> list[str]:
    """The bodies' names as rbody's from_mjcf gives them (an unnamed body: body<id>), world excluded."""
    return [model.body(i).name or f"body{i}" for i in range(1, model.nbody)]


def run_file(path: str | Path, *, t_end: float, dt: float | None = None, integrator: str | None = None,
             keyframe=None, qpos0=None, qvel0=None, ctrl: Any = None, scene=None) -> Trajectory:
    """Step the file in MuJoCo for t_end [s] at dt (default the file's timestep) with `integrator` (default the
    file's), from its reference pose, `keyframe`, or qpos0/qvel0 (MuJoCo's layout). ctrl: None (the keyframe's
    controls, else 0), a constant (nu,), a schedule (n_steps, nu) whose row k is held during step k, or a callable
    ctrl(t, qpos, qvel) -> (nu,) called before every step (as rbody.simulate takes them). scene: rbody's scene of
    the file, for the energy observable. Returns a Trajectory (module docstring); meta holds the settings and
    step_seconds (the stepping loop with the recording)."""
    model = load(path)
    data = mujoco.MjData(model)
    if dt is not None:
        model.opt.timestep = float(dt)
    if integrator is not None:
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator={integrator!r}: expected one of {list(INTEGRATORS)}")
        model.opt.integrator = INTEGRATORS[integrator]
    initial_state(model, data, keyframe, qpos0, qvel0)
    h = float(model.opt.timestep)
    nsteps = max(1, int(np.ceil(t_end / h * (1 - 1e-12))))
    schedule, function = _controls(ctrl, model, nsteps, data)
    names = body_names(model)
    count = nsteps + 1
    qpos, qvel = np.empty((count, model.nq)), np.empty((count, model.nv))
    act, ctrls, force = np.empty((count, model.na)), np.empty((count, model.nu)), np.empty((count, model.nu))
    com, quat = np.empty((count, model.nbody - 1, 3)), np.empty((count, model.nbody - 1, 4))
    velocity, omega = np.empty((count, model.nbody - 1, 3)), np.empty((count, model.nbody - 1, 3))
    motion = np.empty(6)
    start = time.perf_counter()
    failure = ""
    for k in range(count):
        if k < nsteps:
            data.ctrl[:] = schedule[k] if schedule is not None else function(data.time, data.qpos.copy(),
                                                                           data.qvel.copy())
        mujoco.mj_forward(model, data)  # the recorded quantities at this state and control
        qpos[k], qvel[k], act[k], ctrls[k], force[k] = data.qpos, data.qvel, data.act, data.ctrl, data.actuator_force
        com[k], quat[k] = data.xipos[1:], data.xquat[1:]
        for i in range(1, model.nbody):
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, i, motion, 0)
            omega[k, i - 1], velocity[k, i - 1] = motion[:3], motion[3:]
        if k == nsteps:
            break
        mujoco.mj_step(model, data)
        warnings = [int(data.warning[w].number) for w in (mujoco.mjtWarning.mjWARN_BADQPOS,
                                                         mujoco.mjtWarning.mjWARN_BADQVEL,
                                                         mujoco.mjtWarning.mjWARN_BADQACC)]
        if any(warnings) or not np.all(np.isfinite(data.qpos)):
            failure = f"MuJoCo reported an unstable state at t={data.time:.6g} s (it resets such a state and goes on)"
            break
    seconds = time.perf_counter() - start
    if failure:
        raise RuntimeError(failure)
    t = np.arange(count) * h
    observables: dict[str, Any] = {"qpos": qpos, "qvel": qvel}
    if model.nu:
        observables.update(ctrl=ctrls, actuator_force=force)
    if model.na:
        observables["act"] = act
    for i, name in enumerate(names):
        observables.update({f"{name}.com": com[:, i], f"{name}.quat": quat[:, i], f"{name}.velocity": velocity[:, i],
                            f"{name}.omega": omega[:, i]})
    if scene is not None:
        body = scene.multibody
        observables["energy"] = body.kinetic_energy(qpos, qvel) + body.potential_energy(qpos)
    meta = {"backend": "mujoco", "source": str(path), "dt": h, "t_end": float(t[-1]), "nsteps": nsteps,
            "integrator": integrator_name(model), "mujoco_version": mujoco.__version__, "step_seconds": seconds,
            "settings": {"integrator": integrator_name(model), "timestep": h, "own file": True}}
    return Trajectory(t, observables, meta=meta)


def _controls(ctrl, model: mujoco.MjModel, nsteps: int, data: mujoco.MjData):
    """(schedule (nsteps, nu) or None, callable or None) for run_file's ctrl (the keyframe's controls for None)."""
    nu = model.nu
    if callable(ctrl):
        def function(t, qpos, qvel):
            value = np.asarray(ctrl(t, qpos, qvel), dtype=np.float64)
            if value.shape != (nu,) or not np.all(np.isfinite(value)):
                raise ValueError(f"ctrl(t={t:.6g}, qpos, qvel) returned {value.shape}: expected ({nu},) finite")
            return value
        return None, function
    if ctrl is None:
        return np.repeat(np.array(data.ctrl)[None], nsteps, axis=0), None
    array = np.asarray(ctrl, dtype=np.float64)
    if array.shape == (nu,):
        return np.repeat(array[None], nsteps, axis=0), None
    if array.ndim == 2 and array.shape[1] == nu and array.shape[0] >= nsteps:
        return array[:nsteps], None
    raise ValueError(f"ctrl has shape {array.shape}: expected ({nu},) or (n_steps >= {nsteps}, {nu})")


__all__ = ["run_file", "load", "initial_state", "body_names", "integrator_name", "INTEGRATORS"]
