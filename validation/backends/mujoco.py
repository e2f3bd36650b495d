"""MuJoCo as a backend: the scene's MJCF (rbody.to_mjcf), stepped by mujoco.rollout, observed by the scene.

The pipeline:

    xml    = rbody.to_mjcf(scene, dt=dt, ...)       # joints, explicit inertials, contact pairs, keyframe
    model  = mujoco.MjModel.from_xml_string(xml)
    states = rollout(model, data, state0, nstep)    # the stepping, in C; the only thing timed
    bodies = replay(states)                         # com, quat, com velocity, world omega of each body
    data   = scene.observe(t, bodies, joints)       # the same observables as every backend

Conventions at this edge: MuJoCo's free-joint qvel holds the angular velocity in the BODY frame (the
keyframe written by to_mjcf converts the scene's world omega); hinge and slide qpos are measured from
the reference pose, as in rbody. mj_objectVelocity on a body (mjOBJ_BODY) gives (omega, v) at the
body's centre of mass (xipos), world axes with flg_local = 0 — checked against w x (com - pivot).

Impacts (contacts with restitution > 0): MuJoCo resolves them as stiff springs lasting a few steps.
A collision is counted when a pair goes from no contact to contact between two steps (an onset), from
MuJoCo's own collision detection replayed on every step's positions: ``collisions`` (T,) counts onsets
over all pairs, ``ball_collisions`` (T,) over pairs of two moving bodies, both cumulative.
"""

from __future__ import annotations

import math
import time

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from rbody._checks import finite_array
from rbody.errors import SimulationError
from rbody.mjcf import INITIAL_KEY, has_impacts, to_mjcf
from rbody.scene import BodyStates, Scene
from rbody.trajectory import Trajectory

name = "mujoco"

# Steps per rollout call when the run is long: bounds the memory of the recorded states.
_CHUNK_BYTES = 64 * 2**20
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
_UNSTABLE = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)


def check(scene: Scene) -> None:
    """MuJoCo runs every unbatched scene with a physical layout (bodies, joints, contacts)."""
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    if scene.batch_shape:
        raise NotImplementedError(f"MuJoCo runs one scene at a time; use scene.item(i) (scene {scene.name!r} is a "
                                  f"batch of shape {scene.batch_shape})")
    try:
        scene.layout
    except NotImplementedError as reason:
        raise NotImplementedError(f"MuJoCo needs the scene's bodies and joints: {reason}") from None


def build(scene: Scene, dt: float, **settings) -> tuple[mujoco.MjModel, str]:
    """The compiled MjModel of `scene` at step dt [s], and its MJCF text (settings as rbody.to_mjcf)."""
    xml = to_mjcf(scene, dt=dt, **settings)
    return mujoco.MjModel.from_xml_string(xml), xml


def run(scene: Scene, dt: float, t_end: float | None = None, *, integrator: str | None = None,
        solref=None, solimp=None, condim: int | None = None, cone: str | None = None,
        impratio: float | None = None, noslip_iterations: int | None = None, min_inertia: float | None = None,
        save_every: int = 1) -> Trajectory:
    """Run `scene` in MuJoCo with step dt [s] for t_end [s] (default scene.t_end).

    integrator: "Euler", "RK4", "implicit", "implicitfast" (default: Euler when the scene has impacts,
    else RK4); solref, solimp, condim, cone, impratio, noslip_iterations, min_inertia: as rbody.to_mjcf.
    save_every: keep every n-th step. Returns a Trajectory with the scene's observables (plus
    ``collisions`` and ``ball_collisions`` for scenes with impacts); meta holds the backend, the
    effective settings, the MuJoCo version and ``step_seconds``, the wall time of the stepping alone.
    Raises NotImplementedError for what MuJoCo cannot run, ValueError for bad arguments,
    SimulationError when MuJoCo reports an unstable state (it would reset the state and go on).
    """
    check(scene)
    t_end = scene.t_end if t_end is None else float(finite_array(t_end, "t_end"))
    if not t_end > 0:
        raise ValueError(f"t_end={t_end!r}: must be > 0 [s]")
    dt = float(finite_array(dt, "dt"))
    if not 0 < dt <= t_end:
        raise ValueError(f"dt={dt!r}: must satisfy 0 < dt <= t_end={t_end} [s]")
    if not isinstance(save_every, (int, np.integer)) or isinstance(save_every, bool) or save_every < 1:
        raise ValueError(f"save_every={save_every!r}: expected a whole number >= 1")
    settings = {"integrator": integrator, "solref": solref, "solimp": solimp, "condim": condim, "cone": cone,
                "impratio": impratio, "noslip_iterations": noslip_iterations, "min_inertia": min_inertia}
    model, _xml = build(scene, dt, **{k: v for k, v in settings.items() if v is not None})
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, INITIAL_KEY))

    layout = scene.layout
    impacts = has_impacts(layout)
    nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
    nsteps = -(-nsteps // save_every) * save_every
    states, step_seconds = _step(model, data, nsteps, save_every, keep_all=impacts)

    nq, nv = model.nq, model.nv
    qpos_all, qvel_all = states[:, 1:1 + nq], states[:, 1 + nq:1 + nq + nv]
    stride = save_every if impacts else 1  # with impacts every step was kept, for the contact onsets
    qpos, qvel = qpos_all[::stride], qvel_all[::stride]
    t = np.arange(qpos.shape[0]) * (dt * save_every)

    bodies = _replay_bodies(model, qpos, qvel, [b.name for b in layout.bodies])
    joints = {}
    for joint in layout.joints:
        if joint.kind in ("hinge", "slide"):
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.name)
            joints[joint.name] = (qpos[:, model.jnt_qposadr[j]].copy(), qvel[:, model.jnt_dofadr[j]].copy())
    observables = dict(scene.observe(t, bodies, joints))
    if impacts:
        all_pairs, ball_pairs = _collision_onsets(model, qpos_all)
        observables["collisions"] = all_pairs[::save_every]
        observables["ball_collisions"] = ball_pairs[::save_every]

    meta = {"scene": scene.name, "description": scene.describe(), "backend": name, "dt": dt, "t_end": t_end,
            "nsteps": nsteps, "save_every": save_every, "integrator": _integrator_name(model),
            "settings": _effective_settings(model), "mujoco_version": mujoco.__version__,
            "step_seconds": step_seconds}
    return Trajectory(t, observables, meta=meta)


# ----- stepping -----------------------------------------------------------------------------------

def _step(model: mujoco.MjModel, data: mujoco.MjData, nsteps: int, save_every: int,
          keep_all: bool) -> tuple[np.ndarray, float]:
    """Full physics states (T, nstate) from the initial one, every step (keep_all) or every save_every-th,
    and the wall time [s] of the rollout calls alone."""
    nstate = mujoco.mj_stateSize(model, _FULL)
    state = np.empty(nstate)
    mujoco.mj_getState(model, data, state, _FULL)
    kept = [state[None].copy()]
    chunk = max(save_every, (_CHUNK_BYTES // (8 * nstate)) // save_every * save_every)
    seconds = 0.0
    done = 0
    while done < nsteps:
        n = min(chunk, nsteps - done)
        warmstart = data.qacc_warmstart.copy()[None]
        start = time.perf_counter()
        out, _ = mj_rollout.rollout(model, data, state[None], nstep=n, initial_warmstart=warmstart)
        seconds += time.perf_counter() - start
        out = out[0]
        _check_stable(model, data, out, done)
        kept.append(out if keep_all else out[save_every - 1::save_every])
        state = out[-1].copy()
        done += n
    return np.concatenate(kept, axis=0), seconds


def _check_stable(model: mujoco.MjModel, data: mujoco.MjData, out: np.ndarray, done: int) -> None:
    """MuJoCo resets an unstable state (huge or NaN qpos, qvel, qacc) and goes on; rbody stops there."""
    unstable = sum(data.warning[int(w)].number for w in _UNSTABLE)
    if unstable or not np.all(np.isfinite(out)):
        dt = model.opt.timestep
        backwards = np.flatnonzero(np.diff(out[:, 0]) < 0)
        step = done + (int(backwards[0]) + 1 if backwards.size else 0)
        raise SimulationError(
            f"MuJoCo reported an unstable state (NaN, inf or huge qpos/qvel/qacc) near t={step * dt:.6g} s with "
            f"dt={dt} and integrator {_integrator_name(model)}; try a smaller dt or another integrator")


# ----- what the steps mean ------------------------------------------------------------------------------

def _replay_bodies(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray,
                   names: list[str]) -> dict[str, BodyStates]:
    """World-frame BodyStates of each named body, from recorded (qpos, qvel) (T, nq), (T, nv)."""
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in names]
    count = qpos.shape[0]
    com = np.empty((count, len(ids), 3))
    quat = np.empty((count, len(ids), 4))
    twist = np.empty((count, len(ids), 6))
    body = mujoco.mjtObj.mjOBJ_BODY
    for k in range(count):
        data.qpos[:] = qpos[k]
        data.qvel[:] = qvel[k]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        com[k] = data.xipos[ids]
        quat[k] = data.xquat[ids]
        for i, b in enumerate(ids):
            mujoco.mj_objectVelocity(model, data, body, b, twist[k, i], 0)  # (omega, v) at the com, world
    return {n: BodyStates(com=com[:, i].copy(), quat=quat[:, i].copy(), velocity=twist[:, i, 3:].copy(),
                          omega=twist[:, i, :3].copy()) for i, n in enumerate(names)}


def _collision_onsets(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative onsets (T,) over all contact pairs and over pairs of two moving bodies.

    The contacts at step k are MuJoCo's own (mj_collision on qpos_k: the set the step from k uses);
    a pair's onset is a step where it is in contact and was not at the step before."""
    data = mujoco.MjData(model)
    moving = model.body_weldid[model.geom_bodyid] != 0
    pair_index = {}
    for p in range(model.npair):
        g1, g2 = int(model.pair_geom1[p]), int(model.pair_geom2[p])
        pair_index[(min(g1, g2), max(g1, g2))] = p
    ball = np.array([moving[model.pair_geom1[p]] and moving[model.pair_geom2[p]] for p in range(model.npair)],
                    dtype=bool)
    touching = np.zeros((qpos.shape[0], model.npair), dtype=bool)
    for k in range(qpos.shape[0]):
        data.qpos[:] = qpos[k]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        for c in range(data.ncon):
            g1, g2 = int(data.contact.geom1[c]), int(data.contact.geom2[c])
            p = pair_index.get((min(g1, g2), max(g1, g2)))
            if p is not None:
                touching[k, p] = True
    onset = np.zeros_like(touching)
    onset[1:] = touching[1:] & ~touching[:-1]
    onset[0] = touching[0]
    return np.cumsum(onset.sum(axis=1)), np.cumsum(onset[:, ball].sum(axis=1))


def _integrator_name(model: mujoco.MjModel) -> str:
    return mujoco.mjtIntegrator(model.opt.integrator).name.removeprefix("mjINT_")


def _effective_settings(model: mujoco.MjModel) -> dict:
    """The solver settings MuJoCo compiled: option values and each contact pair's parameters."""
    pairs = []
    for p in range(model.npair):
        pairs.append({
            "geom1": model.geom(model.pair_geom1[p]).name, "geom2": model.geom(model.pair_geom2[p]).name,
            "condim": int(model.pair_dim[p]), "friction": model.pair_friction[p].tolist(),
            "solref": model.pair_solref[p].tolist(), "solimp": model.pair_solimp[p].tolist()})
    return {"integrator": _integrator_name(model), "timestep": float(model.opt.timestep),
            "cone": mujoco.mjtCone(model.opt.cone).name.removeprefix("mjCONE_"),
            "impratio": float(model.opt.impratio), "noslip_iterations": int(model.opt.noslip_iterations),
            "solver": mujoco.mjtSolver(model.opt.solver).name.removeprefix("mjSOL_"),
            "iterations": int(model.opt.iterations), "tolerance": float(model.opt.tolerance), "pairs": pairs}
