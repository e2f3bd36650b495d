"""MuJoCo as a backend: the scene's MJCF (rbody.to_mjcf), stepped by mujoco.rollout, observed by the scene.

The pipeline:

    xml      = rbody.to_mjcf(scene, dt=dt, ...)       # joints, explicit inertials, contact pairs, keyframe
    model    = mujoco.MjModel.from_xml_string(xml)
    states   = rollout(model, data, state0, nstep)    # the stepping, in C: meta["step_seconds"]
    sensors  = rollout(model + sensors, ...)          # the same run again, with MuJoCo's own sensors:
                                                      # com, quat, com velocity, world omega, contacts
    data     = scene.observe(t, bodies, joints)       # the same observables as every backend

The second rollout must reproduce the first bit for bit (sensors do not act on the physics); it is
checked. Rollout's sensordata row j belongs to the state before step j. meta["run_seconds"] is the
work that produces the observables: the rollout with sensors (the same steps, recording what is
observed), the contact onsets and scene.observe; the benchmark charges MuJoCo that, as it charges
rbody its whole simulate call.

A model without contact pairs is compiled with contacts and, when it has no equality or limit either,
the constraint solver disabled (MuJoCo's <flag contact="disable" constraint="disable"/>): nothing
changes in the motion, the pipeline skips collision detection and the solver.

Conventions at this edge: MuJoCo's free-joint qvel holds the angular velocity in the BODY frame (the
keyframe written by to_mjcf converts the scene's world omega); hinge and slide qpos are measured from
the reference pose, as in rbody. The body sensors (framepos and framelinvel of objtype "body", i.e.
the inertial frame; framequat of "xbody"; frameangvel) give the centre of mass, its velocity, the
body-frame orientation and the world angular velocity: checked equal to xipos, xquat and
mj_objectVelocity(mjOBJ_BODY, flg_local=0), which returns (omega, v) at the centre of mass.

Impacts (contacts with restitution > 0): MuJoCo resolves them as springs lasting some steps. A
collision is counted when a pair goes from no contact to contact between two steps (an onset), from
MuJoCo's contact sensor on every step: ``collisions`` (T,) counts onsets over all pairs,
``ball_collisions`` (T,) over pairs of two moving bodies, both cumulative.

Roll joints (rolling without slipping, one coordinate): to_mjcf writes each as a slide <name>_slide and a
hinge <name> tied by a stiff joint equality (rbody.mjcf.export). The joint's history (qpos, qvel) is the
hinge's; how far the soft equality let the two apart is reported in meta["roll_slip"][name] as the largest
|slide - a hinge| [m] ("max_position") and |slide' - a hinge'| [m/s] ("max_rate") over the saved states.
The constraint solver stays on for them (disable_unused keeps it for any model with an equality).

Scenes with a varying mass or applied forces (body_mass, slide_force, pair_force) run in a plain
mj_step loop instead (see _Run.drive); scenes whose class sets applies_gravity = False get no gravity.
"""

from __future__ import annotations

import math
import time
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from rbody.checks import run_times, whole_number
from rbody.errors import SimulationError
from rbody.mjcf import INITIAL_KEY, ROLL_SLIDE_SUFFIX, has_impacts, to_mjcf
from rbody.layout import JOINTS
from rbody.progress import Reporter
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
        layout = scene.layout
    except NotImplementedError as reason:
        raise NotImplementedError(f"MuJoCo needs the scene's bodies and joints: {reason}") from None
    _drive_plan(scene, layout)


def preflight(scene: Scene) -> None:
    """Build the scene's model as run() would at its default settings (MJCF export and MuJoCo's compiler),
    without stepping: raises ValueError for what they refuse (a body with a principal moment MuJoCo
    rejects, ...). validation.backends.supports calls it."""
    check(scene)
    build(scene, min(1e-3, scene.t_end))


def _drive_plan(scene: Scene, layout) -> dict | None:
    """What must be set before every step for a scene MuJoCo's model alone does not hold, or None.

    body_mass(t, distance) and slide_force(t, distance, speed): a body of varying mass on one slide
    (the rocket, the avalanche); pair_force(x1, x2): a force between two bodies (the two-body problem)."""
    hooks = [h for h in ("body_mass", "slide_force", "pair_force") if callable(getattr(scene, h, None))]
    if not hooks:
        return None
    slides = [j for j in layout.joints if j.kind == "slide"]
    if ("body_mass" in hooks or "slide_force" in hooks) and (len(layout.bodies) != 1 or len(slides) != 1):
        raise NotImplementedError(f"scene {scene.name!r}: a varying mass or slide force is applied to one body on "
                                  f"one slide; the layout has {len(layout.bodies)} bodies and {len(slides)} slides")
    if "pair_force" in hooks and len(layout.bodies) != 2:
        raise NotImplementedError(f"scene {scene.name!r}: a pair force acts between two bodies; the layout has "
                                  f"{len(layout.bodies)}")
    return {"hooks": hooks, "slide": slides[0].name if slides else None,
            "bodies": [b.name for b in layout.bodies]}


def build(scene: Scene, dt: float, **settings) -> tuple[mujoco.MjModel, str]:
    """The compiled MjModel of `scene` at step dt [s], and its MJCF text (settings as rbody.to_mjcf);
    contacts and constraints disabled where the model has none (disable_unused)."""
    xml = to_mjcf(scene, dt=dt, **settings)
    return disable_unused(mujoco.MjModel.from_xml_string(xml)), xml


def disable_unused(model: mujoco.MjModel) -> mujoco.MjModel:
    """The model with collision detection disabled when it has no contact pair (to_mjcf excludes every
    other contact), and the constraint solver too when it also has no equality, joint or tendon limit, nor
    joint or tendon frictionloss (MuJoCo's dry friction is a constraint too): MJCF's <flag contact="disable"
    constraint="disable"/>, the same motion at less cost."""
    if model.npair == 0:
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        if (model.neq == 0 and not np.any(model.jnt_limited) and not np.any(model.tendon_limited)
                and not np.any(model.dof_frictionloss > 0) and not np.any(model.tendon_frictionloss > 0)):
            model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    return model


def run(scene: Scene, dt: float, t_end: float | None = None, *, integrator: str | None = None,
        solref=None, solimp=None, condim: int | None = None, cone: str | None = None,
        impratio: float | None = None, noslip_iterations: int | None = None, min_inertia: float | None = None,
        save_every: int = 1, progress: bool | None = None) -> Trajectory:
    """Run `scene` in MuJoCo with step dt [s] for t_end [s] (default scene.t_end).

    integrator: "Euler", "RK4", "implicit", "implicitfast" (default: Euler when the scene has impacts,
    else RK4); solref, solimp, condim, cone, impratio, noslip_iterations, min_inertia: as rbody.to_mjcf.
    save_every: keep every n-th step. progress: a line on stderr with the time left (rbody.progress: True, False,
    or None: in an interactive session, for runs longer than a few seconds). Returns a Trajectory with the scene's observables (plus
    ``collisions`` and ``ball_collisions`` for scenes with impacts); meta holds the backend, the
    effective settings, the MuJoCo version, ``step_seconds``, the wall time of the stepping alone, and
    ``run_seconds``, that of the stepping with the recording of the observables (module docstring).
    Raises NotImplementedError for what MuJoCo cannot run, ValueError for bad arguments,
    SimulationError when MuJoCo reports an unstable state (it would reset the state and go on).
    """
    check(scene)
    dt, t_end = run_times(scene.t_end, dt, t_end)
    whole_number(save_every, "save_every")
    settings = {"integrator": integrator, "solref": solref, "solimp": solimp, "condim": condim, "cone": cone,
                "impratio": impratio, "noslip_iterations": noslip_iterations, "min_inertia": min_inertia}
    model, xml = build(scene, dt, **{k: v for k, v in settings.items() if v is not None})
    layout = scene.layout
    observer = disable_unused(mujoco.MjModel.from_xml_string(_with_sensors(xml, layout)))
    nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
    nsteps = -(-nsteps // save_every) * save_every
    run_ = _Run(model, observer, layout, save_every)
    plan = _drive_plan(scene, layout)
    if plan is None:
        run_.step(nsteps, Reporter(progress, f"mujoco {_integrator_name(model)} {scene.name}", nsteps))
    else:
        run_.drive(scene, plan, nsteps)

    extraction = time.perf_counter()
    t = np.arange(run_.states.shape[0]) * (dt * save_every)
    nq, nv = model.nq, model.nv
    qpos, qvel = run_.states[:, 1:1 + nq], run_.states[:, 1 + nq:1 + nq + nv]  # (time, qpos, qvel, ...)
    bodies = {}
    for i, body in enumerate(layout.bodies):
        values = run_.sensors[:, 13 * i:13 * (i + 1)]
        bodies[body.name] = BodyStates(com=values[:, 0:3].copy(), quat=values[:, 3:7].copy(),
                                       velocity=values[:, 7:10].copy(), omega=values[:, 10:13].copy())
    joints, roll_slip = {}, {}
    for joint in layout.joints:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.name)
        qa, da = model.jnt_qposadr[j], model.jnt_dofadr[j]
        if joint.kind == "roll":  # MuJoCo's hinge <name> holds q; its slide should hold a q (the equality)
            joints[joint.name] = (qpos[:, qa].copy(), qvel[:, da].copy())
            roll_slip[joint.name] = _roll_slip(model, joint, qpos, qvel)
        elif JOINTS[joint.kind].scalar:
            joints[joint.name] = (qpos[:, qa].copy(), qvel[:, da].copy())
        else:  # ball (T, 4), (T, 3); free (T, 7), (T, 6): MuJoCo's qpos and qvel (body-frame angular velocity)
            size = JOINTS[joint.kind]
            joints[joint.name] = (qpos[:, qa:qa + size.nq].copy(), qvel[:, da:da + size.nv].copy())
    observables = dict(scene.observe(t, bodies, joints))
    if has_impacts(layout):
        observables["collisions"] = run_.collisions
        observables["ball_collisions"] = run_.ball_collisions
    step_seconds = run_.seconds
    run_seconds = run_.observed_seconds + (time.perf_counter() - extraction)

    meta = {"scene": scene.name, "description": scene.describe(), "backend": name, "dt": dt, "t_end": t_end,
            "nsteps": nsteps, "save_every": save_every, "integrator": _integrator_name(model),
            "settings": _effective_settings(model), "mujoco_version": mujoco.__version__,
            "step_seconds": step_seconds, "run_seconds": run_seconds,
            **({"roll_slip": roll_slip} if roll_slip else {}),
            "stepping": ("mujoco.rollout" if plan is None else
                         f"mj_step loop, setting {', '.join(plan['hooks'])} from the scene before every step "
                         "(timed with that Python work and MuJoCo's sensors)")}
    return Trajectory(t, observables, meta=meta)


def _roll_slip(model: mujoco.MjModel, joint, qpos: np.ndarray, qvel: np.ndarray) -> dict[str, float]:
    """How far MuJoCo's soft equality lets a roll joint slip (rbody.mjcf.export: slide <name>_slide = a hinge
    <name>): the largest |slide - a hinge| [m] and |slide' - a hinge'| [m/s] over the saved states."""
    hinge = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.name)
    slide = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.name + ROLL_SLIDE_SUFFIX)
    position = qpos[:, model.jnt_qposadr[slide]] - joint.radius * qpos[:, model.jnt_qposadr[hinge]]
    rate = qvel[:, model.jnt_dofadr[slide]] - joint.radius * qvel[:, model.jnt_dofadr[hinge]]
    return {"max_position": float(np.max(np.abs(position))), "max_rate": float(np.max(np.abs(rate)))}


# ----- stepping and observing ----------------------------------------------------------------------

def _with_sensors(xml: str, layout) -> str:
    """The model with sensors that record what the scene observes, computed by MuJoCo at every step:
    per body (layout order) the centre of mass (framepos of the body's inertial frame), the body-frame
    orientation (framequat of xbody), the centre-of-mass velocity and the world angular velocity (13
    numbers); then per contact pair the number of contacts found (0 when apart)."""
    lines = ["  <sensor>"]
    for body in layout.bodies:
        name = quoteattr(body.name)
        lines += [f'    <framepos objtype="body" objname={name}/>', f'    <framequat objtype="xbody" objname={name}/>',
                  f'    <framelinvel objtype="body" objname={name}/>',
                  f'    <frameangvel objtype="body" objname={name}/>']
    for contact in layout.contacts:
        geoms = f"geom1={quoteattr(contact.shape_a)} geom2={quoteattr(contact.shape_b)}"
        lines.append(f'    <contact {geoms} data="found"/>')
    lines.append("  </sensor>")
    head, tail = xml.rsplit("</worldbody>", 1)
    return head + "</worldbody>\n" + "\n".join(lines) + tail


class _Run:
    """Steps the model in chunks of rollout calls (only these are timed), then replays each chunk in the
    observer model (the same physics plus sensors: its states must come out identical) for the sensors.

    Rollout's sensordata row j belongs to the state before step j (checked against mj_kinematics,
    mj_comVel and mj_objectVelocity on the recorded states, for Euler and RK4)."""

    def __init__(self, model, observer, layout, save_every: int) -> None:
        self.model, self.observer, self.save_every = model, observer, save_every
        self.data, self.odata = mujoco.MjData(model), mujoco.MjData(observer)
        if model.nkey:
            key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, INITIAL_KEY)
            mujoco.mj_resetDataKeyframe(model, self.data, key)
        self.nbody = len(layout.bodies)
        moving = model.body_weldid[model.geom_bodyid] != 0
        self.ball = np.array([moving[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, c.shape_a)]
                              and moving[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, c.shape_b)]
                              for c in layout.contacts], dtype=bool)
        self.seconds = 0.0           # the stepping alone
        self.observed_seconds = 0.0  # the stepping with sensors and the contact onsets: what gives the observables

    def step(self, nsteps: int, reporter: Reporter | None = None) -> None:
        model, nstate = self.model, mujoco.mj_stateSize(self.model, _FULL)
        state = np.empty(nstate)
        mujoco.mj_getState(model, self.data, state, _FULL)
        width = 2 * nstate + self.observer.nsensordata  # numbers per step held by the two rollouts
        chunk = max(self.save_every, (_CHUNK_BYTES // (8 * width)) // self.save_every * self.save_every)
        states, sensors, onsets = [], [], []
        touching = None
        done = 0
        while done < nsteps:
            n = min(chunk, nsteps - done)
            warmstart = self.data.qacc_warmstart.copy()[None]
            start = time.perf_counter()
            out, _ = mj_rollout.rollout(model, self.data, state[None], nstep=n, initial_warmstart=warmstart)
            self.seconds += time.perf_counter() - start
            out = out[0]
            _check_stable(model, self.data, out, done)
            start = time.perf_counter()
            replay, sensed = mj_rollout.rollout(self.observer, self.odata, state[None], nstep=n,
                                                initial_warmstart=warmstart)
            self.observed_seconds += time.perf_counter() - start
            if not np.array_equal(replay[0], out):
                raise SimulationError("MuJoCo gave different states for the same model with sensors added: the "
                                      "observed run is not the timed one")
            start = time.perf_counter()
            sensed = sensed[0]                       # sensors of states done .. done + n - 1
            keep = np.arange(0, n, self.save_every)  # chunk starts on a multiple of save_every
            states += [state[None], out[keep[1:] - 1]]  # state done + j is out[j - 1]
            sensors.append(sensed[keep])
            found = sensed[:, 13 * self.nbody:] > 0
            previous = np.zeros((1, found.shape[1]), dtype=bool) if touching is None else touching[None]
            onsets.append(found & ~np.vstack([previous, found[:-1]]))
            touching = found[-1] if found.shape[0] else touching
            state = out[-1].copy()
            done += n
            self.observed_seconds += time.perf_counter() - start
            if reporter is not None:
                reporter.update(done)
        if reporter is not None:
            reporter.finish()
        start = time.perf_counter()
        # the final state and its sensors
        mujoco.mj_setState(self.observer, self.odata, state, _FULL)
        mujoco.mj_forward(self.observer, self.odata)
        final = self.odata.sensordata.copy()
        found = final[None, 13 * self.nbody:] > 0
        onsets.append(found & ~touching[None] if touching is not None else found)
        self.states = np.vstack(states + [state[None]])
        self.sensors = np.vstack(sensors + [final[None]])
        onset = np.vstack(onsets)
        every = np.cumsum(onset.sum(axis=1))
        balls = np.cumsum(onset[:, self.ball].sum(axis=1))
        self.collisions = every[::self.save_every]
        self.ball_collisions = balls[::self.save_every]
        self.observed_seconds += time.perf_counter() - start

    def drive(self, scene: Scene, plan: dict, nsteps: int) -> None:
        """A plain mj_step loop on the observer model for scenes with a varying mass or applied forces.

        Forces are MuJoCo passive forces (mjcb_passive), evaluated at every stage of the integrator from
        that stage's state: slide_force(t, distance, speed) on the slide, pair_force(x1, x2) at the two
        centres of mass (equal and opposite). The mass is a model constant, so body_mass(t, distance) is
        set before each step (its moments in proportion: the same uniform body) and MuJoCo holds it over
        the step: a first-order error where the mass changes."""
        model, data = self.observer, self.odata
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, data, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, INITIAL_KEY))
        hooks, dt, every = plan["hooks"], model.opt.timestep, self.save_every
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in plan["bodies"]]
        qadr = dadr = None
        if plan["slide"] is not None:
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, plan["slide"])
            qadr, dadr = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
        torque = np.zeros(3)

        def passive(m, d) -> None:
            if "slide_force" in hooks:
                d.qfrc_passive[dadr] += float(scene.slide_force([d.time], [d.qpos[qadr]], [d.qvel[dadr]])[0])
            if "pair_force" in hooks:
                force = np.asarray(scene.pair_force(d.xipos[ids[0]], d.xipos[ids[1]])[0], dtype=float)
                mujoco.mj_applyFT(m, d, force, torque, d.xipos[ids[0]].copy(), ids[0], d.qfrc_passive)
                mujoco.mj_applyFT(m, d, -force, torque, d.xipos[ids[1]].copy(), ids[1], d.qfrc_passive)

        mass0, moments0 = float(model.body_mass[ids[0]]), model.body_inertia[ids[0]].copy()
        nstate = mujoco.mj_stateSize(model, _FULL)
        count = nsteps // every + 1
        states, sensors = np.empty((count, nstate)), np.empty((count, model.nsensordata))
        found = np.empty((nsteps + 1, len(self.ball)), dtype=bool)
        first = 13 * self.nbody
        forces = "slide_force" in hooks or "pair_force" in hooks
        previous = mujoco.get_mjcb_passive()
        if forces:
            mujoco.set_mjcb_passive(passive)
        try:
            start = time.perf_counter()
            for k in range(nsteps):
                if "body_mass" in hooks:
                    mass = float(scene.body_mass([k * dt], [data.qpos[qadr]])[0])
                    model.body_mass[ids[0]] = mass
                    model.body_inertia[ids[0]] = moments0 * (mass / mass0)
                if k % every == 0:
                    mujoco.mj_getState(model, data, states[k // every], _FULL)
                mujoco.mj_step(model, data)
                if k % every == 0:
                    sensors[k // every] = data.sensordata  # computed by the step for its starting state
                found[k] = data.sensordata[first:] > 0
                if any(data.warning[int(w)].number for w in _UNSTABLE):
                    raise SimulationError(
                        f"MuJoCo reported an unstable state (NaN, inf or huge qpos/qvel/qacc) at t={k * dt:.6g} s "
                        f"with dt={dt} and integrator {_integrator_name(model)}; try a smaller dt or another "
                        "integrator")
            self.seconds = time.perf_counter() - start
            self.observed_seconds = self.seconds  # the loop ran the model with sensors
            mujoco.mj_getState(model, data, states[-1], _FULL)
            mujoco.mj_forward(model, data)
        finally:
            mujoco.set_mjcb_passive(previous)
        sensors[-1] = data.sensordata
        found[nsteps] = data.sensordata[first:] > 0
        self.states, self.sensors = states, sensors
        self._count(found)

    def _count(self, found: np.ndarray) -> None:
        """Cumulative contact onsets (T,) from found (steps + 1, pairs): all pairs, and body-body pairs."""
        onset = found & ~np.vstack([np.zeros((1, found.shape[1]), dtype=bool), found[:-1]])
        self.collisions = np.cumsum(onset.sum(axis=1))[::self.save_every]
        self.ball_collisions = np.cumsum(onset[:, self.ball].sum(axis=1))[::self.save_every]


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


_DISABLE_BITS = (mujoco.mjtDisableBit.mjDSBL_CONTACT, mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
_MJCF_INTEGRATOR = {"EULER": "Euler", "RK4": "RK4", "IMPLICIT": "implicit", "IMPLICITFAST": "implicitfast"}


def _integrator_name(model: mujoco.MjModel) -> str:
    """The integrator as MJCF spells it (Euler, RK4, implicit, implicitfast)."""
    name = mujoco.mjtIntegrator(model.opt.integrator).name.removeprefix("mjINT_")
    return _MJCF_INTEGRATOR.get(name, name)


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
            "disabled": [bit.name.removeprefix("mjDSBL_").lower() for bit in _DISABLE_BITS
                         if model.opt.disableflags & int(bit)],
            "solver": mujoco.mjtSolver(model.opt.solver).name.removeprefix("mjSOL_"),
            "iterations": int(model.opt.iterations), "tolerance": float(model.opt.tolerance), "pairs": pairs}
