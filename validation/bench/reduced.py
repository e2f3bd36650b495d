"""MuJoCo on the reduction rbody runs: a body rolling down an incline in one or two coordinates.

rbody integrates a rolling body in its rolling coordinate, the rolling constraint solved beforehand;
MuJoCo's own model of the scene is a body on an incline held by a contact. To compare like with like
the benchmark also gives MuJoCo the same reduction, built here from the scene's Layout (one body per
rolling body, its slide "x" down the slope and hinge "phi" about y; mass M, moment I about the rolling
axis, rolling radius R):

    slide        one slide joint x along the slope with armature I / R^2: the effective mass M + I/R^2
                 under the force M g sin(alpha) gives x'' = g sin(alpha) / (1 + I/(M R^2)), exactly the
                 rolling acceleration; phi = x / R by construction (no slip can exist).
    slide+hinge  the scene's rolling tree (one roll joint per body: Rolling.rolling_tree) as rbody.to_mjcf
                 writes it: a slide a q along the slope and the hinge q, tied by MuJoCo's joint equality
                 slide = R hinge (a soft constraint, solved each step; solref (2 dt, 1), solimp
                 rbody.mjcf.EQUALITY_SOLIMP): the rolling constraint kept by the solver, not by the
                 coordinates; contacts disabled (the incline is drawn, touching nothing).

Observables, from the joint coordinates (distance, speed, spin, slip, energy, and a race's
arrival_time), with the energy of the reduced model:
slide E = (M + I/R^2) v^2 / 2 - M g x sin(alpha); slide+hinge E = M v^2 / 2 + I w^2 / 2 - M g x sin(alpha).
Timed as the MuJoCo backend is (meta["run_seconds"]): the rollout and the translation into observables.
"""

from __future__ import annotations

import math
import time

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from rbody.checks import run_times, whole_number
from rbody.errors import SimulationError
from rbody.mjcf import to_mjcf
from rbody.scene import Scene
from rbody.trajectory import Trajectory

VARIANTS = ("slide", "slide+hinge")
# The joint equality of slide+hinge is rbody.to_mjcf's for a roll joint, at its stiffest (as the benchmark's
# best contact): time constant 2 dt, critically damped, impedance EQUALITY_SOLIMP. With MuJoCo's defaults
# (0.02 s; 0.9, 0.95) the disc slips by 0.088 m/s and the distance error stays at 2.5e-3 m for every dt; with
# these it falls to 4.2e-10 m at RK4, dt = 1e-4.
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _rolling_bodies(scene: Scene) -> list[dict]:
    """Per rolling body of the scene's layout: its name suffix, mass M [kg], moment I about the rolling
    axis [kg m^2], the slide axis (3,) and the body's reference position (3,) [m]."""
    layout = scene.layout
    joints = {j.name: j for j in layout.joints}
    out = []
    for body in layout.bodies:
        suffix = body.name.removeprefix("body")
        slide, hinge = joints.get(f"x{suffix}"), joints.get(f"phi{suffix}")
        if slide is None or hinge is None or slide.kind != "slide" or hinge.kind != "hinge":
            raise NotImplementedError(f"scene {scene.name!r}: body {body.name!r} has no slide x{suffix} and hinge "
                                      f"phi{suffix}: not a rolling body")
        axis = np.asarray(hinge.axis, dtype=float)
        moment = float(axis @ np.asarray(body.inertia.tensor) @ axis)
        out.append({"suffix": suffix, "mass": float(body.inertia.mass), "moment": moment,
                    "axis": np.asarray(slide.axis, dtype=float), "hinge": axis})
    return out


def reduced_mjcf(scene: Scene, variant: str, dt: float, integrator: str) -> str:
    """MJCF of the reduced rolling model (module docstring); run() disables contacts (and constraints too for
    'slide', which has none)."""
    if variant not in VARIANTS:
        raise ValueError(f"variant={variant!r}: expected one of {VARIANTS}")
    if variant == "slide+hinge":
        tree = Scene.from_layout(scene.rolling_tree(), t_end=scene.t_end, gravity=scene.gravity,
                                 name=f"{scene.name}_rolling_tree")
        return to_mjcf(tree, dt=dt, integrator=integrator)
    radius = float(scene.radius)
    bodies = []
    for b in _rolling_bodies(scene):
        s = b["suffix"]
        axis = " ".join(f"{v:.17g}" for v in b["axis"])
        inertial = (f'<inertial pos="0 0 0" mass="{b["mass"]:.17g}" '
                    f'diaginertia="{b["moment"]:.17g} {b["moment"]:.17g} {b["moment"]:.17g}"/>')
        joints = f'<joint name="x{s}" type="slide" axis="{axis}" armature="{b["moment"] / radius**2:.17g}"/>'
        bodies.append(f'<body name="body{s}">{joints}{inertial}</body>')
    return (f'<mujoco><option timestep="{dt:.17g}" integrator="{integrator}" gravity="0 0 {-scene.gravity:.17g}">'
            f'<flag contact="disable" constraint="disable"/></option><worldbody>{"".join(bodies)}</worldbody>'
            "</mujoco>")


def run(scene: Scene, dt: float, t_end: float | None = None, *, variant: str = "slide", integrator: str = "RK4",
        save_every: int = 1) -> Trajectory:
    """The rolling scene (rbody.scenes.rolling or rolling_race) in MuJoCo's reduced model `variant` with
    step dt [s]; observables as the scene's (T, n) for a race, (T,) for one body; meta as the MuJoCo
    backend's (step_seconds: the rollout; run_seconds: the rollout and the observables)."""
    dt, t_end = run_times(scene.t_end, dt, t_end)
    whole_number(save_every, "save_every")
    model = mujoco.MjModel.from_xml_string(reduced_mjcf(scene, variant, dt, integrator))
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)  # nothing touches: the incline is drawn only
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    nsteps = max(1, math.ceil(t_end / dt * (1 - 1e-12)))
    nsteps = -(-nsteps // save_every) * save_every
    state = np.empty(mujoco.mj_stateSize(model, _FULL))
    mujoco.mj_getState(model, data, state, _FULL)
    start = time.perf_counter()
    out, _ = mj_rollout.rollout(model, data, state[None], nstep=nsteps)
    step_seconds = time.perf_counter() - start
    states = np.vstack([state[None], out[0][save_every - 1::save_every]])
    observables = _observe(scene, model, variant, states)
    run_seconds = time.perf_counter() - start
    if not all(np.all(np.isfinite(v)) for k, v in observables.items() if k != "arrival_time"):
        raise SimulationError(f"MuJoCo's reduced model {variant!r} with dt={dt} and {integrator} gave a non-finite "
                              "state; try a smaller dt")
    t = np.arange(states.shape[0]) * (dt * save_every)
    meta = {"scene": scene.name, "backend": "mujoco", "model": f"reduced: {variant}", "dt": dt,
            "integrator": integrator, "mujoco_version": mujoco.__version__, "step_seconds": step_seconds,
            "run_seconds": run_seconds}
    return Trajectory(t, observables, meta=meta)


def _observe(scene: Scene, model: mujoco.MjModel, variant: str, states: np.ndarray) -> dict[str, np.ndarray]:
    """The scene's observables from the saved FULLPHYSICS states (T, nstate) of the reduced model."""
    from rbody.scenes.rolling import arrival_times

    radius, g, sin = float(scene.radius), float(scene.gravity), math.sin(float(scene.incline))
    qpos, qvel = states[:, 1:1 + model.nq], states[:, 1 + model.nq:1 + model.nq + model.nv]
    bodies = _rolling_bodies(scene)
    per = 1 if variant == "slide" else 2  # coordinates per body: x, or x and phi
    x, speed = qpos[:, 0::per], qvel[:, 0::per]
    mass = np.array([b["mass"] for b in bodies])
    moment = np.array([b["moment"] for b in bodies])
    if variant == "slide":
        spin = speed / radius
        energy = 0.5 * (mass + moment / radius**2) * speed**2 - mass * g * sin * x
    else:
        spin = qvel[:, 1::2]
        energy = 0.5 * mass * speed**2 + 0.5 * moment * spin**2 - mass * g * sin * x
    values = {"distance": x, "speed": speed, "spin": spin, "slip": speed - radius * spin, "energy": energy}
    if "arrival_time" in scene.observables:
        t = states[:, 0]  # MuJoCo's time of each saved state
        arrival = arrival_times(Trajectory(t, {"distance": x, "speed": speed}), float(scene.length))
        values["arrival_time"] = np.broadcast_to(arrival, x.shape).copy()
    if len(bodies) == 1 and "arrival_time" not in scene.observables:  # one body: (T,)
        values = {k: v[:, 0] for k, v in values.items()}
    return values
