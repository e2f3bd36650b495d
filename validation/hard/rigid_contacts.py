"""Hard case 10: contacts in the rigid limit, each closed form run in rbody, MuJoCo and pymunk.

Every run is measured against the closed form by the same function (never against another simulator):

- a sphere thrown sliding without spin on a plane (v0, friction mu): its slip v - r w = v0 - (7/2) mu g t falls to
  0 at t* = 2 v0 / (7 mu g), then it rolls at 5/7 v0 for ever, its centre at height r. Measures: the rolling speed's
  error at the end, the error of the time sliding ends, the largest |z - r| (sinking or hopping);
- a block on an incline (alpha, friction mu = factor tan(alpha)): it sticks exactly when tan(alpha) <= mu (the
  boundary factors 1 -+ 1e-6 included), and slides as x = g (sin alpha - mu cos alpha) t^2 / 2 otherwise. Measures:
  the largest displacement where it should stick, the largest |x - x*| where it should slide;
- a ball dropped from height H onto a plane with restitution e: impacts at T_k = T0 (1 + 2e + ... + 2e^(k-1)),
  T0 = sqrt(2 H / g), bounce k reaching e^(2k) H; e = 0 rests on the plane from T0 on. Measures: the largest error
  of the first three impact times (e = 0: the one), the first bounce's height error (e = 0: the largest |z - r|
  after T0);
- Painleve's rod: a thin rod tilted 0.8 rad, sliding at 1 m/s on its lower end (the end leading) with mu = 2 above
  the rod's mu_P = 1.63, where sliding has no consistent contact force: a tangential impact stops the end at t = 0,
  then the end's sphere rolls on the floor as the rod turns. Measures: how far the end slid beyond that rolling by
  the end of the run, and its slip one step after t = 0;
- a box resting on a floor, and a stack of five boxes: nothing moves. Measures: the largest horizontal drift and
  the largest height change (sinking) of any box over the run.

The engines, each at its documented default settings and at a finer step:

- rbody: its default scheme for contacts, Moreau-Jean time-stepping (method "moreau", order 1: it holds rolling,
  sticking, resting and the surfaces exactly, and locates the transition and the impacts within a step), and on the
  one-body cases its event-driven scheme (method "rk4"), which root-finds every event;
- MuJoCo: its documented defaults, what a bare MJCF file compiles to (timestep 2 ms, Euler, pyramidal cone,
  impratio 1, solref 0.02 1, solimp 0.9 0.95 0.001: the runs equal such a file's bit for bit, tests/validation/
  test_hard_rigid_contacts.py), and the settings rbody.to_mjcf writes for contacts in the rigid limit (the
  validation backend's: solref (2 dt, 1), solimp 0.99, elliptic cone, impratio 100, restitution as a spring-damper
  of 30 steps; rbody/mjcf/export.py). Its contacts are soft: each number is its divergence from rigid mechanics;
- pymunk: 2-D, the planar version of each scene (the body on x and z slides and a y hinge above the plane, the
  incline a tilted plane), at the backend's documented defaults (10 iterations, pymunk's own; collision slop 1e-6
  of the smallest contact shape, pymunk's 0.1 being meant in pixels), and on the incline at 100 iterations too.

Steps: STEP = 2 ms (MuJoCo's default timestep; pymunk and rbody have none) and FINE = 0.2 ms, for every engine;
the rests run their whole time at STEP and a tenth of it at FINE; rbody's stack of boxes (2.3 ms of work a step)
runs at 10 ms over the whole rest and at 2 ms over a tenth of it.

A row's outcome is "exact" where the value is within validation.tolerances' round-off bound of its unit (the closed
form met), "error" otherwise. rbody's rows carry its verdict against what its scheme guarantees (round-off; the
time-stepping's transition within the step holding t*, impact k within 2k steps, the bounce within 2 sqrt(2 g H)
dt, a slide within a t dt / 2 of a t^2 / 2 and on its own discrete closed form a t (t + dt) / 2 to round-off: the
bounds of tests/rbody/engine/test_contact_closed_forms.py). The other simulators' errors are findings, with their
value: never judged against a loose bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

import validation
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.inertia import Inertia
from rbody.motion import quat_to_matrix
from validation.hard.rows import CaseResult, HardRow, attempt, error_outcome, short
from validation.tolerances import tolerance

G = 9.81
STEP = 2e-3                 # [s] MuJoCo's documented default timestep: every engine's first step
FINE = 2e-4                 # [s] the finer step
REST_TIME = 100.0           # [s] the resting box and stack at STEP (at FINE: a tenth of it)
REST_TIME_QUICK = 10.0      # [s] the same under --quick
STACK_STEPS = (1e-2, 2e-3)  # [s] rbody's stack: over the whole rest, and over a tenth of it

# The scenes' numbers: the closed-form tests' own (tests/rbody/engine/test_contact_closed_forms.py).
RADIUS = 0.1                     # [m] the thrown sphere and the dropped ball (1 kg)
THROW_SPEED, THROW_MU = 2.0, 0.3  # [m/s], [-]
ALPHA = 0.3                      # [rad] the incline
BLOCK_HALF = (0.1, 0.1, 0.05)    # [m] the block's half sizes (1 kg), its faces along the incline
DROP_HEIGHT, DROP_MU = 1.0, 0.5  # [m] the dropped ball's lowest point above the plane; its friction [-]
BOX_HALF, BOX_MASS, BOX_MU = (0.2, 0.1, 0.05), 2.0, 0.8  # [m], [kg], [-]
ROD_HALF, ROD_RADIUS, ROD_TILT = 0.5, 1e-3, 0.8  # [m], [m], [rad] Painleve's rod (1 kg): half length, end radius, tilt
ROD_MU, ROD_SPEED = 2.0, 1.0     # [-] above the rod's mu_P = 1.63; [m/s] its slide, the lower end leading
DURATIONS = {"thrown": 1.0, "incline": 2.0, "drop": 1.5, "painleve": 0.2}  # [s]; the drop covers three impacts

# MuJoCo: its documented defaults (a bare MJCF file's), and rbody.to_mjcf's rigid-limit settings (none given).
MUJOCO_DEFAULTS = {"integrator": "Euler", "solref": (0.02, 1.0), "solimp": (0.9, 0.95, 0.001), "cone": "pyramidal",
                   "impratio": 1.0}
MUJOCO_SETTINGS = (("defaults", MUJOCO_DEFAULTS), ("to_mjcf", {}))
PYMUNK_CONVERGED = 100  # pymunk's iterations on the incline's extra run (its default is 10)


def bound(metric: str) -> float:
    """A value of validation.tolerances' table for this case (family "rigid_contacts", any backend)."""
    found = tolerance("rigid_contacts", "*", metric)
    if found is None:
        raise KeyError(f"validation.tolerances has no ('rigid_contacts', '*', {metric!r}) entry")
    return found.value


def roundoff(measure: str) -> float:
    """The round-off bound of a measure, by the unit its name ends with: [m], [m/s] or [s]."""
    for unit, kind in (("[m/s]", "speed"), ("[s]", "time"), ("[m]", "position")):
        if measure.endswith(unit):
            return bound(f"roundoff_{kind}")
    raise ValueError(f"measure {measure!r}: expected a name ending in [m], [m/s] or [s]")


# ----- the scenes: Layouts, 3-D (free joints) for rbody and MuJoCo, planar for pymunk ---------------------------

def _joints(body: str, planar: bool) -> tuple[Joint, ...]:
    """A free joint, or the planar set: slides along the body's x and z and a hinge about its y (world y)."""
    if not planar:
        return (Joint(f"{body}_free", "free", body),)
    return (Joint(f"{body}_x", "slide", body, axis=(1.0, 0.0, 0.0)),
            Joint(f"{body}_z", "slide", body, axis=(0.0, 0.0, 1.0)),
            Joint(f"{body}_phi", "hinge", body, axis=(0.0, 1.0, 0.0)))


def ball_scene(*, height: float, friction: float, restitution: float, speed: float, planar: bool,
               t_end: float) -> Scene:
    """A solid sphere (1 kg, radius RADIUS [m]) whose lowest point is `height` [m] above the plane z = 0, moving along
    x at `speed` [m/s] without spin; its contact has `friction` and `restitution`."""
    ball = Body("ball", Inertia.solid_sphere(1.0, RADIUS), shapes=(Shape("s", "sphere", (RADIUS,)),),
                pos=(0.0, 0.0, RADIUS + height))
    layout = Layout(bodies=(ball,), joints=_joints("ball", planar), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=(Contact("floor", "s", friction=friction, restitution=restitution),))
    qvel0 = [speed, 0.0, 0.0] if planar else [speed, 0.0, 0.0, 0.0, 0.0, 0.0]
    return Scene.from_layout(layout, t_end=t_end, qvel0=qvel0, name="ball")


def incline_rotation() -> np.ndarray:
    """(3, 3) the incline's axes in the world: x down the slope (it dips), y across it, z its normal."""
    return quat_to_matrix(np.array((math.cos(ALPHA / 2), 0.0, math.sin(ALPHA / 2), 0.0)))


def incline_scene(friction: float, *, planar: bool, t_end: float) -> Scene:
    """A block (1 kg, half sizes BLOCK_HALF [m]) at rest on a plane turned by ALPHA about y, its faces along it."""
    q = (math.cos(ALPHA / 2), 0.0, math.sin(ALPHA / 2), 0.0)
    block = Body("block", Inertia.box(1.0, 2 * np.array(BLOCK_HALF)), shapes=(Shape("b", "box", BLOCK_HALF),),
                 pos=tuple(incline_rotation()[:, 2] * BLOCK_HALF[2]), quat=q)
    layout = Layout(bodies=(block,), joints=_joints("block", planar), fixed=(Shape("ramp", "plane", (0, 0), quat=q),),
                    contacts=(Contact("ramp", "b", friction=friction),))
    return Scene.from_layout(layout, t_end=t_end, name="incline")


def box_scene(*, planar: bool, t_end: float) -> Scene:
    """A box (BOX_MASS kg, half sizes BOX_HALF [m]) resting on the floor."""
    box = Body("box0", Inertia.box(BOX_MASS, 2 * np.array(BOX_HALF)), shapes=(Shape("b0", "box", BOX_HALF),),
               pos=(0.3, -0.2, BOX_HALF[2]))
    layout = Layout(bodies=(box,), joints=_joints("box0", planar), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=(Contact("floor", "b0", friction=BOX_MU),))
    return Scene.from_layout(layout, t_end=t_end, name="box")


def stack_scene(*, planar: bool, t_end: float) -> Scene:
    """Five boxes, each narrower than the one below (half sizes 0.3 - 0.04 k, 0.25 - 0.04 k, 0.05 m, masses 1 + k
    kg), stacked from the floor, offset 0.01 k, -0.005 k m sideways; friction 0.5 at every interface."""
    bodies, joints, contacts, z = [], [], [Contact("floor", "b0", friction=0.5)], 0.0
    for k in range(5):
        half = (0.3 - 0.04 * k, 0.25 - 0.04 * k, 0.05)
        z += half[2]
        bodies.append(Body(f"box{k}", Inertia.box(1.0 + k, 2 * np.array(half)), shapes=(Shape(f"b{k}", "box", half),),
                           pos=(0.01 * k, -0.005 * k, z)))
        z += half[2]
        joints += _joints(f"box{k}", planar)
        if k:
            contacts.append(Contact(f"b{k - 1}", f"b{k}", friction=0.5))
    layout = Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=tuple(contacts))
    return Scene.from_layout(layout, t_end=t_end, name="stack")


def rod_scene(*, planar: bool, t_end: float) -> Scene:
    """Painleve's rod: a thin rod (1 kg, length 2 ROD_HALF [m]; its collision shape a capsule of radius ROD_RADIUS)
    tilted ROD_TILT from the floor, its lower end's sphere on it, sliding at ROD_SPEED [m/s] towards -x (the lower
    end leading) with friction ROD_MU. Planar in every engine (slides x, z and a hinge about y: its three
    coordinates); `planar` is accepted for the variants' common signature."""
    del planar
    phi = math.pi / 2 - ROD_TILT
    shape = Shape("end", "capsule", (ROD_RADIUS, ROD_HALF), quat=(math.cos(phi / 2), 0.0, math.sin(phi / 2), 0.0))
    rod = Body("rod", Inertia.rod(1.0, 2 * ROD_HALF), shapes=(shape,),
               pos=(0.0, 0.0, ROD_HALF * math.sin(ROD_TILT) + ROD_RADIUS))
    layout = Layout(bodies=(rod,), joints=_joints("rod", True), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=(Contact("floor", "end", friction=ROD_MU),))
    return Scene.from_layout(layout, t_end=t_end, qvel0=[-ROD_SPEED, 0.0, 0.0], name="rod")


def rod_closed_form() -> dict[str, float]:
    """The rod's tangential impact (tests/rbody/engine/test_painleve.py): d = A - c (A its contact point), W the
    change of A's (tangential, normal) velocity per impulse, mu_P = (I/m + dx^2) / (dx dz) above which sliding has
    no consistent force, the stick impulse P = -W^-1 (v, 0) (in the cone: Pt/Pn = mu_P), the angular velocity after
    it [rad/s] and the kinetic energy it takes [J]."""
    inertia = (2 * ROD_HALF) ** 2 / 12
    dx, dz = -ROD_HALF * math.cos(ROD_TILT), -ROD_HALF * math.sin(ROD_TILT) - ROD_RADIUS
    W = np.array([[1 + dz * dz / inertia, -dx * dz / inertia], [-dx * dz / inertia, 1 + dx * dx / inertia]])
    P = np.linalg.solve(W, [ROD_SPEED, 0.0])
    omega = (dz * P[0] - dx * P[1]) / inertia
    return {"dx": dx, "dz": dz, "mu_P": (inertia + dx * dx) / (dx * dz), "Pt": P[0], "Pn": P[1], "omega": omega,
            "energy lost": ROD_SPEED ** 2 / 2 - (inertia + dx * dx + dz * dz) * omega ** 2 / 2}


# ----- the measures: one trajectory's observables against the closed form ----------------------------------------

@dataclass
class Measured:
    """What a measure found: values (measure name -> value; the name ends with its unit), extras (numbers the
    verdicts use: "impact errors" (k,) [s], "scheme error" [m]) and notes (words for the row)."""

    values: dict[str, float]
    notes: str = ""
    extras: dict = field(default_factory=dict)


def thrown_measures(t: np.ndarray, com: np.ndarray, velocity: np.ndarray, omega: np.ndarray) -> Measured:
    """The thrown sphere, from t (T,) [s] and the ball's com, velocity, omega (T, 3) [m, m/s, rad/s]:
    rolling speed error |v_x(T) - 5/7 v0| [m/s], transition time error |t_roll - t*| [s], height error max |z - r| [m].

    t_roll is where the slip's sliding line reaches 0: the line through the last two samples whose slip exceeds the
    sliding bound (validation.tolerances), exact for an exact sliding phase (slip linear in t) whatever the
    sampling; inf where the slip never falls below that bound."""
    slip = velocity[:, 0] - RADIUS * omega[:, 1]
    t_star = 2 * THROW_SPEED / (7 * THROW_MU * G)
    below = np.flatnonzero(np.abs(slip) <= bound("sliding_slip"))
    t_roll = math.inf
    if below.size and below[0] >= 2:
        i = below[0] - 1
        rate = (slip[i - 1] - slip[i]) / (t[i] - t[i - 1])
        t_roll = float(t[i] + slip[i] / rate) if rate > 0 else math.inf
    rolling = np.flatnonzero(np.abs(slip) <= bound("rolling_slip"))
    when = (f"|slip| <= {bound('rolling_slip'):g} m/s from the sample at {t[rolling[0]]:.6g} s" if rolling.size else
            f"|slip| never <= {bound('rolling_slip'):g} m/s")
    gap = com[:, 2] - RADIUS
    return Measured({"rolling speed error [m/s]": abs(float(velocity[-1, 0]) - 5 / 7 * THROW_SPEED),
                     "transition time error [s]": abs(t_roll - t_star),
                     "height error [m]": float(np.max(np.abs(gap)))},
                    f"t* = {t_star:.9g} s, sliding ends at {t_roll:.9g} s; {when}; final slip {slip[-1]:.3g} m/s; "
                    f"z - r from {np.min(gap):.3g} to {np.max(gap):.3g} m")


def incline_acceleration(friction: float) -> float:
    """g (sin alpha - mu cos alpha) [m/s^2] where the block slides (tan(alpha) > mu), else 0: it sticks."""
    return G * (math.sin(ALPHA) - friction * math.cos(ALPHA)) if math.tan(ALPHA) > friction else 0.0


def incline_measures(t: np.ndarray, com: np.ndarray, friction: float, dt: float) -> Measured:
    """The block, from t (T,) [s] and its com (T, 3) [m]: where it should stick, displacement max |com - com0| [m];
    else position error max |x - a t^2 / 2| [m] along the slope, and as extra "scheme error" max |x - a t (t + dt)
    / 2| [m], the time-stepping's own closed form (symplectic Euler under a constant force)."""
    R = incline_rotation()
    moved = com - com[0]
    x, normal = moved @ R[:, 0], moved @ R[:, 2]
    a = incline_acceleration(friction)
    lift = f"normal displacement up to {np.max(np.abs(normal)):.3g} m"
    if a == 0.0:
        return Measured({"displacement [m]": float(np.max(np.linalg.norm(moved, axis=1)))},
                        f"should stick (tan(alpha) <= mu); moved {x[-1]:.3g} m down the slope in {t[-1]:g} s; {lift}")
    scheme = float(np.max(np.abs(x - a * t * (t + dt) / 2)))
    return Measured({"position error [m]": float(np.max(np.abs(x - a * t**2 / 2)))},
                    f"slides at a = {a:.6g} m/s^2: x* = {a * t[-1] ** 2 / 2:.6g} m at {t[-1]:g} s, moved "
                    f"{x[-1]:.6g} m; |x - a t (t + dt)/2| up to {scheme:.3g} m; {lift}", {"scheme error": scheme})


def impact_times_closed(restitution: float, count: int) -> np.ndarray:
    """(count,) the closed form's impact times [s]: T0 (1 + 2e + ... + 2e^(k-1)), T0 = sqrt(2 H / g)."""
    t0 = math.sqrt(2 * DROP_HEIGHT / G)
    return t0 * np.array([1 + 2 * sum(restitution**j for j in range(1, k)) for k in range(1, count + 1)])


def impacts_measured(t: np.ndarray, z: np.ndarray, vz: np.ndarray, count: int) -> list[float]:
    """The first `count` impact times [s] from samples of the gap z = height - r [m] and vz [m/s]: at each reversal of
    vz (negative to >= 0), the free fall's parabola from the last sample clear of the plane (z >= 0, vz < 0),
    continued to z = 0: t_j + (vz_j + sqrt(vz_j^2 + 2 g z_j)) / g, exact for an exact flight whatever the sampling."""
    out = []
    for i in np.flatnonzero((vz[:-1] < 0) & (vz[1:] >= 0))[:count]:
        clear = np.flatnonzero((z[:i + 1] >= 0) & (vz[:i + 1] < 0))
        if clear.size:
            j = clear[-1]
            out.append(float(t[j] + (vz[j] + math.sqrt(vz[j] ** 2 + 2 * G * z[j])) / G))
    return out


def peak(z: np.ndarray, mask: np.ndarray) -> float:
    """The largest z over the samples in mask, refined by the parabola through that sample and its neighbours
    (exact for a free flight sampled at equal intervals anywhere)."""
    index = np.flatnonzero(mask)
    i = int(index[np.argmax(z[index])])
    if i == 0 or i == len(z) - 1:
        return float(z[i])
    a, b, c = z[i - 1], z[i], z[i + 1]
    curvature = a - 2 * b + c
    return float(b - (c - a) ** 2 / (8 * curvature)) if curvature < 0 else float(b)


def drop_measures(t: np.ndarray, com: np.ndarray, velocity: np.ndarray, restitution: float) -> Measured:
    """The dropped ball, from t (T,) [s] and its com and velocity (T, 3) [m, m/s]: impact time error [s], the largest
    of the first three impacts' (e = 0: the first's; extra "impact errors" (k,) [s], inf where fewer were found);
    e > 0: bounce height error |first bounce - e^2 H| [m]; e = 0: max |z - r| after T0 [m] (the closed form rests
    on the plane from the impact on)."""
    z, vz = com[:, 2] - RADIUS, velocity[:, 2]
    count = 1 if restitution == 0 else 3
    closed = impact_times_closed(restitution, count)
    found = impacts_measured(t, z, vz, count)
    errors = np.full(count, math.inf)
    errors[:len(found)] = np.abs(np.array(found) - closed[:len(found)])
    notes = (f"impacts at {', '.join(f'{x:.6g}' for x in found) or 'none found'} s (closed form "
             f"{', '.join(f'{x:.6g}' for x in closed)}); z - r down to {np.min(z):.3g} m")
    values = {"impact time error [s]": float(np.max(errors))}
    if restitution == 0:
        after = t > closed[0]
        values["max |z - r| after T0 [m]"] = float(np.max(np.abs(z[after])))
        notes += (f"; after T0 z - r from {np.min(z[after]):.3g} to {np.max(z[after]):.3g} m, final speed "
                  f"{np.linalg.norm(velocity[-1]):.3g} m/s")
    else:
        reversals = np.flatnonzero((vz[:-1] < 0) & (vz[1:] >= 0))
        start = t[reversals[0] + 1] if reversals.size else closed[0]
        end = t[reversals[1]] if reversals.size > 1 else t[-1]
        height = peak(z, (t >= start) & (t <= end))
        values["bounce height error [m]"] = abs(height - restitution**2 * DROP_HEIGHT)
        notes += f"; first bounce {height:.6g} m (closed form {restitution ** 2 * DROP_HEIGHT:g} m)"
    return Measured(values, notes, {"impact errors": errors})


def painleve_measures(t: np.ndarray, qpos: np.ndarray, qvel: np.ndarray) -> Measured:
    """Painleve's rod, from t (T,) [s] and its qpos, qvel (T, 3) (x [m], z [m], angle a about y [rad]): the rigid
    closed form stops the lower end at t = 0 by a tangential impact; after it the end's sphere rolls on the floor
    without slip (its centre E moves by r a). Measures: end slide |x_E(T) - x_E(0) - r a(T)| [m], how far the end
    slid in all; slip one step after [m/s], the contact point's tangential velocity at the first sample after t = 0
    (0 after the impact)."""
    closed = rod_closed_form()
    ex, ez = closed["dx"], closed["dz"] + ROD_RADIUS          # E - c at the start
    x, z, a = qpos[:, 0], qpos[:, 1], qpos[:, 2]
    x_e = x + ex * np.cos(a) + ez * np.sin(a)
    z_e = z - ex * np.sin(a) + ez * np.cos(a) - ez
    slide = x_e - ex - ROD_RADIUS * a
    contact_z = -ex * np.sin(a[1]) + ez * np.cos(a[1]) - ROD_RADIUS   # the contact point P - c, z component
    slip = qvel[1, 0] + qvel[1, 2] * contact_z
    return Measured({"end slide [m]": abs(float(slide[-1])), "slip one step after [m/s]": abs(float(slip))},
                    f"mu_P = {closed['mu_P']:.4g} < mu = {ROD_MU:g}: the tangential impact at t = 0 takes "
                    f"{closed['energy lost']:.6g} J and turns the rod at {closed['omega']:.6g} rad/s; the end slid "
                    f"{-slide[-1]:.3g} m by {t[-1]:g} s, at {float(slip):.3g} m/s one "
                    f"step after t = 0; its sphere's height r from {np.min(z_e):.3g} to {np.max(z_e):.3g} m off")


def rest_measures(t: np.ndarray, coms: list[np.ndarray]) -> Measured:
    """Boxes at rest, from t (T,) [s] and each box's com (T, 3) [m]: drift, the largest horizontal |com - com0| [m],
    and sinking, the largest |z - z0| [m], over the boxes and samples."""
    moved = [com - com[0] for com in coms]
    drift = max(float(np.max(np.linalg.norm(m[:, :2], axis=1))) for m in moved)
    sink = max(float(np.max(np.abs(m[:, 2]))) for m in moved)
    lowest = min(range(len(moved)), key=lambda k: float(np.min(moved[k][:, 2])))
    i = int(np.argmin(moved[lowest][:, 2]))
    return Measured({"drift [m]": drift, "sinking [m]": sink},
                    f"lowest: box {lowest}, {moved[lowest][i, 2]:.3g} m at {t[i]:.4g} s; at the end the top box "
                    f"{moved[-1][-1, 2]:.3g} m and {np.linalg.norm(moved[-1][-1, :2]):.3g} m sideways")


# ----- what rbody's schemes guarantee ------------------------------------------------------------------------------

def rbody_requirements(kind: str, measured: Measured, dt: float, method: str, t_end: float,
                       friction: float = 0.0) -> dict[str, tuple[bool, str]]:
    """Per measure, (met, what was required) for an rbody run: round-off for the event-driven scheme and for what
    the time-stepping holds exactly; the time-stepping's order-1 bounds for what it locates within a step."""
    out = {m: (v <= roundoff(m), f"round-off, {roundoff(m):g}") for m, v in measured.values.items()}
    if kind == "painleve":  # the end held at the velocity level: its position follows the scheme's integration
        closed = rod_closed_form()
        arm, turn = math.hypot(closed["dx"], closed["dz"]), abs(closed["omega"])  # |d| [m], the fastest turn [rad/s]
        slide = measured.values["end slide [m]"]
        if method == "moreau":  # J(q_k) v_k+1 = 0: the lever arm turns by omega h in a step
            allowed = 0.5 * turn ** 2 * arm * dt * t_end + roundoff("end slide [m]")
            out["end slide [m]"] = (slide <= allowed, f"order 1, omega^2 |d| h t_end / 2 = {allowed:.3g} m")
            allowed = turn ** 2 * arm * dt + roundoff("slip one step after [m/s]")
            out["slip one step after [m/s]"] = (measured.values["slip one step after [m/s]"] <= allowed,
                                                f"order 1, omega^2 |d| h = {allowed:.3g} m/s")
        else:  # RK4's local error of a turn at omega, (omega h)^5 |d| a step, ten times over
            allowed = max(10 * arm * (turn * dt) ** 5 * t_end / dt, roundoff("end slide [m]"))
            out["end slide [m]"] = (slide <= allowed, f"RK4's order 4, 10 |d| (omega h)^5 a step = {allowed:.3g} m")
        return out
    if method != "moreau":
        return out
    if kind == "thrown":  # rolling begins in the step that holds t*
        value = measured.values["transition time error [s]"]
        out["transition time error [s]"] = (value <= dt, f"within the step holding t*, {dt:g} s")
    elif kind == "incline" and "position error [m]" in measured.values:
        a = incline_acceleration(friction)
        allowed = a * t_end * dt / 2 + roundoff("position error [m]")
        scheme = measured.extras["scheme error"]
        met = measured.values["position error [m]"] <= allowed and scheme <= roundoff("position error [m]")
        out["position error [m]"] = (met, f"a t dt / 2 = {allowed:.3g} m from a t^2/2 (order 1), the scheme's own "
                                          f"a t (t + dt)/2 to round-off (here {scheme:.3g} m)")
    elif kind == "drop":  # impact k within 2k steps, the bounce within 2 sqrt(2 g H) dt
        errors = measured.extras["impact errors"]
        steps = 2 * dt * np.arange(1, errors.size + 1)
        out["impact time error [s]"] = (bool(np.all(errors <= steps)), f"impact k within 2k steps ({dt:g} s each)")
        if "bounce height error [m]" in measured.values:
            allowed = 2 * math.sqrt(2 * G * DROP_HEIGHT) * dt
            out["bounce height error [m]"] = (measured.values["bounce height error [m]"] <= allowed,
                                              f"2 sqrt(2 g H) dt = {allowed:.3g} m (order 1)")
    return out


# ----- the variants and their runs ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Variant:
    """One closed form: its label and short label, kind (thrown, incline, drop, rest), scene(planar, t_end) -> Scene,
    duration [s], measure(trajectory, dt) -> Measured, the contact's friction and restitution, whether rbody's
    event-driven scheme runs it (one body, isolated contacts), and whether it is the stack (rbody's STACK_STEPS)."""

    name: str
    short: str
    kind: str
    scene: Callable[[bool, float], Scene]
    t_end: float
    measure: Callable[..., Measured]
    friction: float = 0.0
    restitution: float = 0.0
    events: bool = True
    stack: bool = False


def variants(quick: bool) -> list[Variant]:
    """The case's closed forms in the order of its table (--quick: the incline at the boundary only and over 1 s,
    the rests over 10 s)."""
    rest = REST_TIME_QUICK if quick else REST_TIME
    out = [Variant(f"sphere thrown sliding, v0 = {THROW_SPEED:g} m/s, mu = {THROW_MU:g}", "sphere", "thrown",
                   lambda planar, t_end: ball_scene(height=0.0, friction=THROW_MU, restitution=0.0, speed=THROW_SPEED,
                                                    planar=planar, t_end=t_end), DURATIONS["thrown"],
                   lambda tr, dt: thrown_measures(tr.t, tr["ball.com"], tr["ball.velocity"], tr["ball.omega"]),
                   THROW_MU)]
    for factor in ((1 - 1e-6, 1 + 1e-6) if quick else (0.5, 1 - 1e-6, 1.0, 1 + 1e-6)):
        mu = math.tan(ALPHA) * factor
        out.append(Variant(f"block on incline, alpha = {ALPHA:g}, mu = tan(alpha) x {factor:.7g}",
                           f"incline x {factor:.7g}", "incline",
                           lambda planar, t_end, mu=mu: incline_scene(mu, planar=planar, t_end=t_end),
                           DURATIONS["incline"] / (2 if quick else 1),
                           lambda tr, dt, mu=mu: incline_measures(tr.t, tr["block.com"], mu, dt), mu))
    for e in (0.5, 0.0):
        out.append(Variant(f"ball dropped from {DROP_HEIGHT:g} m, e = {e:g}", f"drop e = {e:g}", "drop",
                           lambda planar, t_end, e=e: ball_scene(height=DROP_HEIGHT, friction=DROP_MU, restitution=e,
                                                                 speed=0.0, planar=planar, t_end=t_end),
                           DURATIONS["drop"],
                           lambda tr, dt, e=e: drop_measures(tr.t, tr["ball.com"], tr["ball.velocity"], e),
                           DROP_MU, e))
    out.append(Variant(f"Painleve's rod, mu = {ROD_MU:g}, sliding at {ROD_SPEED:g} m/s", "Painleve rod", "painleve",
                       lambda planar, t_end: rod_scene(planar=planar, t_end=t_end), DURATIONS["painleve"],
                       lambda tr, dt: painleve_measures(tr.t, tr["qpos"], tr["qvel"]), ROD_MU))
    out.append(Variant("box resting on a floor", "box", "rest",
                       lambda planar, t_end: box_scene(planar=planar, t_end=t_end), rest,
                       lambda tr, dt: rest_measures(tr.t, [tr["box0.com"]]), BOX_MU, events=False))
    out.append(Variant("stack of five boxes", "stack", "rest",
                       lambda planar, t_end: stack_scene(planar=planar, t_end=t_end), rest,
                       lambda tr, dt: rest_measures(tr.t, [tr[f"box{k}.com"] for k in range(5)]), 0.5,
                       events=False, stack=True))
    return out


@dataclass(frozen=True)
class Run:
    """One engine's run of a variant: backend, setting (its label; the step follows " dt="), step dt [s], duration
    [s], planar scene or not, the backend's keyword settings, and why it is refused before any work ("" if not)."""

    backend: str
    setting: str
    dt: float
    t_end: float
    planar: bool = False
    settings: tuple = ()
    refused: str = ""


def runs(variant: Variant) -> list[Run]:
    """Every run of a variant: rbody (moreau at STEP and FINE, rk4 at STEP where events apply), MuJoCo (its defaults
    and to_mjcf's settings, at STEP and FINE), pymunk (planar, at STEP and FINE; the incline also at STEP with
    PYMUNK_CONVERGED iterations). The rests run their whole time at the first step, a tenth of it at the finer."""
    def duration(k: int) -> float:
        return variant.t_end / 10 if variant.kind == "rest" and k else variant.t_end

    out = [Run("rbody", f"moreau dt={dt:g}", dt, duration(k), settings=(("method", "moreau"),))
           for k, dt in enumerate(STACK_STEPS if variant.stack else (STEP, FINE))]
    if variant.events:
        out.append(Run("rbody", f"rk4 (events) dt={STEP:g}", STEP, variant.t_end, settings=(("method", "rk4"),)))
    for label, settings in MUJOCO_SETTINGS:
        refused = ""
        if label == "defaults" and variant.restitution > 0:
            refused = (f"MuJoCo has no restitution: its default contact (solref 0.02 1, critically damped) cannot "
                       f"express e = {variant.restitution:g}; the to_mjcf rows give it as a spring-damper lasting 30 "
                       "steps")
        out += [Run("mujoco", f"{label} dt={dt:g}", dt, duration(k), settings=tuple(settings.items()), refused=refused)
                for k, dt in enumerate((STEP, FINE))]
    out += [Run("pymunk", f"planar dt={dt:g}", dt, duration(k), planar=True) for k, dt in enumerate((STEP, FINE))]
    if variant.kind == "incline":
        out.append(Run("pymunk", f"planar, {PYMUNK_CONVERGED} iterations dt={STEP:g}", STEP, variant.t_end, planar=True,
                       settings=(("iterations", PYMUNK_CONVERGED),)))
    return out


def run_variant(variant: Variant) -> list[HardRow]:
    """The rows of one variant: per run and measure, its value against the closed form. A row's time is the run's
    (meta run_seconds: rbody's whole simulate call after compiling, MuJoCo's and pymunk's stepping with the
    recording of what is observed), on its first measure only."""
    rows = []
    for run in runs(variant):
        label = variant.name if variant.kind != "rest" else f"{variant.name}, {run.t_end:g} s"
        if run.refused:
            rows.append(HardRow(label, run.backend, run.setting, "refused", None, "-", 0.0, note=run.refused))
            continue
        scene = variant.scene(run.planar, run.t_end)
        # every step saved: the sinks' largest values are transients of the first steps
        trajectory, error, seconds = attempt(validation.run, scene, run.backend, dt=run.dt, t_end=run.t_end,
                                             **dict(run.settings))
        rbody_run = run.backend == "rbody"
        if error is not None:
            rows.append(HardRow(label, run.backend, run.setting, error_outcome(error), None, "-", seconds,
                                "FAIL" if rbody_run else "", short(error)))
            continue
        seconds = float(trajectory.meta.get("run_seconds", seconds))
        measured = variant.measure(trajectory, run.dt)
        required = (rbody_requirements(variant.kind, measured, run.dt, dict(run.settings)["method"], run.t_end,
                                       variant.friction) if rbody_run else {})
        for k, (measure, value) in enumerate(measured.values.items()):
            outcome = "exact" if value <= roundoff(measure) else "error"
            verdict, why = "", ""
            if rbody_run:
                met, what = required[measure]
                verdict, why = ("pass" if met else "FAIL"), f"required: {what}"
            note = "; ".join(x for x in (why, measured.notes if k == 0 else "") if x)
            rows.append(HardRow(label, run.backend, run.setting, outcome, value, measure, seconds if k == 0 else 0.0,
                                verdict, note))
    return rows


# ----- the case ----------------------------------------------------------------------------------------------------

def _group(row: HardRow) -> str:
    """A row's setting without its step: the rows of one engine's setting at every step."""
    return row.setting.split(" dt=")[0]


def findings(rows: list[HardRow], shorts: dict[str, str]) -> list[str]:
    """Per simulator and setting (all its steps): its errors beyond round-off, the value at each step and the ratio
    first step / finer step (where both ran as long); its measures at round-off at every step; its refusals. Then what explains them. shorts: variant
    label (without a rest's duration) -> short label."""
    def short_label(row: HardRow) -> str:
        return shorts.get(row.variant.rsplit(", ", 1)[0] if row.variant not in shorts else row.variant, row.variant)

    out = []
    for backend, group in dict.fromkeys((r.backend, _group(r)) for r in rows if r.backend != "rbody"):
        mine = [r for r in rows if r.backend == backend and _group(r) == group]
        errors: dict[tuple[str, str], list[tuple[str, float]]] = {}
        exact = []
        for r in mine:
            key = (short_label(r), r.measure)
            if r.outcome == "error":
                over = f" over {r.variant.rsplit(', ', 1)[1]}" if r.variant not in shorts else ""
                errors.setdefault(key, []).append((f"dt={r.setting.split(' dt=')[-1]}{over}", r.value))
            elif r.outcome == "exact":
                exact.append(key)
        parts = []
        for (variant, measure), values in errors.items():
            text = f"{variant} {measure} " + ", ".join(f"{v:.3g} at {how}" for how, v in values)
            if len(values) == 2 and values[1][1] > 0 and " over " not in values[0][0]:  # same duration
                text += f" (ratio {values[0][1] / values[1][1]:.3g})"
            parts.append(text)
        text = f"{backend} [{group}]: " + ("; ".join(parts) if parts else "no error beyond round-off")
        exact = [f"{v} {m}" for v, m in dict.fromkeys(exact) if (v, m) not in errors]  # at every step
        if exact and parts:
            text += f". At round-off at every step: {', '.join(exact)}"
        refused = [r for r in mine if r.outcome == "refused"]
        if refused:
            text += (f". Refused: {', '.join(dict.fromkeys(short_label(r) for r in refused))} "
                     f"({refused[0].note})")
        out.append(text + ".")
    out += [
        "MuJoCo's contacts are soft: its contact force is a spring-damper in constraint space (solref, solimp) that "
        "pushes only where the surfaces overlap, so a resting body sinks until that spring carries its weight, an "
        "impact sinks deep into the floor, and friction holds a sticking contact only as a stiff damper, so the "
        "block creeps and the stack drifts. At the defaults the time constant is 0.02 s whatever the step, so the "
        "finer step leaves the sinks and the creep of the same order (the ratios above). to_mjcf ties the time "
        "constant to the step (2 dt): the resting sinks fall as dt^2 (the box's and the stack's sinking, largest in "
        "the first steps: a hundredth at the finer step) and the block's creep about as dt; "
        "its critically damped contact, asked for e = 0, throws the ball back off the floor (the e = 0 rows' "
        "max |z - r| after T0; a linear critically damped spring that only pushes returns e^-2 = 0.14 of the "
        "speed, rbody.mjcf.export.pushing_restitution: a rebound of 1.8 cm), where the closed form rests; its "
        "e = 0.5 is a spring-damper lasting 30 steps, so the impacts fall late by part of that contact time.",
        "pymunk's velocities are exact under constant forces and its contact holds rolling exactly (the sphere's "
        "rows), but positions advance with the velocity before each step: a falling ball lands up to a step late "
        "and overlaps the floor by up to its speed times dt before the contact pushes it out. Bodies touching "
        "exactly (the stack's boxes on each other) are not in contact until they overlap, so each box falls g dt^2 "
        "in its first steps and the stack sinks until the overlaps are corrected (a hundredth at the finer "
        "step). Its 10 iterations of sequential impulses leave the block's friction short of its load, so a "
        "block that should stick creeps; at 100 iterations (the incline's last pymunk rows) it holds.",
        "Painleve's rod: sliding on its leading end with mu above mu_P it has no consistent contact force; the rigid "
        "answer is a tangential impact that stops the end at t = 0. MuJoCo's soft friction stops it over its contact "
        "time instead: at its defaults (time constant 0.02 s) the end slides about 13 mm and sinks 1.3 mm at either "
        "step; to_mjcf's 2 dt time constant shortens the slide with the step (3 mm at 2 ms, 0.3 mm at 0.2 ms). pymunk's "
        "iterations stop it within a few steps (2.4 mm, 0.4 mm). rbody's time-stepping takes the impulse within its "
        "first step (the end's slide then comes from the step's lever arm turning, order 1).",
    ]
    return out


def case_rigid_contacts(quick: bool, out: Path) -> CaseResult:
    rest = REST_TIME_QUICK if quick else REST_TIME
    result = CaseResult(
        10, "Contacts in the rigid limit",
        "each closed form run in every engine and measured against the closed form: a sphere thrown sliding rolls "
        "from t* = 2 v0 / (7 mu g) at 5/7 v0 at height r; a block on an incline sticks exactly when tan(alpha) <= "
        "mu (mu = tan(alpha)(1 -+ 1e-6) included) and otherwise slides as g (sin alpha - mu cos alpha) t^2 / 2; a "
        "ball dropped with restitution e meets the floor at T0 (1 + 2e + ...) and bounces to e^(2k) H, e = 0 rests "
        "at once; Painleve's rod (mu above its mu_P) stops sliding at once by a tangential impact; a box and a stack of five boxes rest {rest:g} s (at the finer step {rest / 10:g} s) without drift "
        "or sinking. rbody's time-stepping (moreau, its default) holds each to round-off, the transition within the "
        "step holding t*, impact k within 2k steps, the bounce within 2 sqrt(2 g H) dt and a slide within a t dt / 2 "
        "(on its own a t (t + dt) / 2 to round-off); its event-driven scheme (rk4) holds each to round-off. "
        f"MuJoCo at its documented defaults (timestep {STEP:g} s, Euler, pyramidal cone, impratio 1, solref 0.02 1, "
        "solimp 0.9 0.95 0.001) and at rbody.to_mjcf's rigid-limit settings, pymunk (planar) at its backend's "
        f"defaults, every engine at {STEP:g} s and {FINE:g} s: findings. rbody's stack runs at {STACK_STEPS[0]:g} s "
        f"over the rest and {STACK_STEPS[1]:g} s over a tenth of it (2.3 ms of work a step)."
        + (" --quick: the incline at mu = tan(alpha)(1 -+ 1e-6) only and over 1 s, the rests over 10 s (the full "
           "case: the incline also at x 0.5 and x 1, over 2 s; the rests over 100 s)." if quick else ""))
    chosen = variants(quick)
    for variant in chosen:
        result.rows += run_variant(variant)
    result.findings += findings(result.rows, {v.name: v.short for v in chosen})
    return result


__all__ = ["case_rigid_contacts", "variants", "runs", "run_variant", "findings", "rbody_requirements", "Measured",
           "thrown_measures", "incline_measures", "drop_measures", "rest_measures", "impacts_measured",
           "impact_times_closed", "peak", "ball_scene", "incline_scene", "box_scene", "stack_scene", "rod_scene",
           "rod_closed_form", "painleve_measures", "STEP", "FINE",
           "MUJOCO_DEFAULTS"]
